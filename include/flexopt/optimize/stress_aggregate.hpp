#pragma once
/// \file One smooth aggregate of many von Mises samples (elements, and time steps in a dynamic
/// analysis): the p-norm or the Kreisselmeier-Steinhauser function with the peak factored out,
/// its derivative with respect to each sample, and where the true peak lies (docs/theory.md
/// section 5.1). Shared by the static problem and the dynamic one.
#include <mpi.h>
#include <vector>

namespace flexopt::optimize {

enum class StressAggregateType { PNorm, Ks };

struct StressAggregateSettings {
  StressAggregateType type = StressAggregateType::PNorm;
  double p = 8;         ///< pnorm: the exponent P >= 1
  double ks = 20;       ///< ks: the parameter k, relative to `reference`
  double reference = 0; ///< ks: the stress that k is relative to [Pa] (> 0 for ks)
};

/// Samples sigma_i >= 0 with weights w_i > 0, added on each rank, reduced over a communicator:
///   pnorm  R = (sum_i w_i sigma_i^P)^(1/P),
///   ks     R = M + (reference / k) ln sum_i w_i exp(k (sigma_i - M) / reference),
/// M = max_i sigma_i, each sum accumulated relative to the running peak so that nothing
/// overflows.
class StressAggregate {
public:
  explicit StressAggregate(const StressAggregateSettings &settings) : s_(settings) {}
  /// Forgets every sample (the next evaluation's).
  void clear();
  /// One local sample: its value [Pa], weight, Gmsh element tag and time [s] (-1 static).
  void add(double sigma, double weight, long long tag, double time);
  /// The global aggregate and peak from every rank's samples. Collective.
  void reduce(MPI_Comm comm);
  /// After reduce(): R [Pa].
  double value() const { return value_; }
  /// After reduce(): the true peak M [Pa], its element's tag (lowest on ties) and time.
  double peak() const { return peak_; }
  long long peak_tag() const { return peak_tag_; }
  double peak_time() const { return peak_time_; }
  /// After reduce(): dR/d(sigma) of a sample of this value and weight.
  double derivative(double sigma, double weight) const;

private:
  /// The factor that re-expresses a sum taken relative to peak `from` relative to `to` >= from.
  double rescale(double from, double to) const;
  /// A sample's term relative to peak m: w (sigma/m)^P or w exp(k (sigma - m) / reference).
  double term(double sigma, double weight, double m) const;

  StressAggregateSettings s_;
  double local_peak_ = 0, local_sum_ = 0, local_time_ = -1;
  long long local_tag_ = -1;
  double value_ = 0, peak_ = 0, sum_ = 0, peak_time_ = -1;
  long long peak_tag_ = -1;
};

/// The stress responses of a problem, one pointer per response (null: not a stress response),
/// each with end_iteration(), scale() and set_scale(c) (the adaptive normalization, Le et al.
/// 2010, docs/theory.md 5.1): after an iteration, the scales kept in restart.h5, their restore.
template <class Ptrs> void end_iterations(const Ptrs &stress) {
  for (const auto &s : stress)
    if (s) s->end_iteration();
}
template <class Ptrs> std::vector<double> scales_of(const Ptrs &stress) {
  std::vector<double> c;
  for (const auto &s : stress)
    if (s) c.push_back(s->scale());
  return c;
}
template <class Ptrs> void restore_scales(const Ptrs &stress, const std::vector<double> &c) {
  std::size_t k = 0;
  for (const auto &s : stress)
    if (s && k < c.size()) s->set_scale(c[k++]);
}

/// The scale c of the adaptive normalization: c <- (M / R + c) / 2 after each iteration, M the
/// aggregate's true peak and R its value (alpha = 1/2 in Le et al.'s eq. 19).
inline double next_scale(double c, const StressAggregate &a) {
  return a.value() > 0 ? 0.5 * a.peak() / a.value() + 0.5 * c : c;
}

} // namespace flexopt::optimize
