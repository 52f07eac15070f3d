#include "flexopt/optimize/gradient_check.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>

namespace flexopt::optimize {

namespace {

/// A reproducible pseudo-random number in [0, 1) from an integer key (splitmix64), so that
/// directions and sample elements depend on Gmsh element tags, not on the partition.
double hash_uniform(std::uint64_t key) {
  std::uint64_t z = key + 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

/// All response values of an evaluation: objective first, then the constraints.
std::vector<double> response_values(const Evaluation &e) {
  std::vector<double> v{e.objective};
  v.insert(v.end(), e.constraints.begin(), e.constraints.end());
  return v;
}

/// The Taylor test's steps, the central differences' sample count, and the factor by which a
/// remainder must exceed the noise floor for its order to count.
const std::vector<double> kTaylorSteps{1e-1, 1e-2, 1e-3, 1e-4, 1e-5};
constexpr int kSamples = 5;
/// Noise of at most 1/kResolved of a remainder moves the order by at most log10(1.1) = 0.04 (a
/// remainder just above the floor carries noise of its own size, and an order near 1.88 for a
/// correct gradient).
constexpr double kResolved = 10;
/// Repeats of the first evaluation from random starts that measure the evaluations' noise.
constexpr int kNoiseRepeats = 2;

/// One line per evaluation: which, and the time so far.
struct Progress {
  MPI_Comm comm;
  int most;
  double t0 = wall_time();
  int count = 0;
  void operator()(const char *what) {
    ++count;
    print0(comm, "check-gradient: evaluation %d of at most %d (%s) done after %.1f s\n", count,
           most, what, wall_time() - t0);
  }
};

/// d_e uniform in [-1, 1] from the element's tag; a variable at the lower bound 0 (an optimized
/// design's void) is moved up only: below 0 the SIMP stiffness x^p turns negative. At the upper
/// bound the direction stays two-sided: the interpolations are smooth through 1, and a
/// one-sided direction at a design of density 1 everywhere (cases/spin_up_beam,
/// flexible_pendulum) lowers every density together by h/2 on average, whose third-order term
/// leaves the largest step pre-asymptotic (orders 0.92 and 1.76 at h = 0.1 where the two-sided
/// direction gives 2.0).
void taylor_direction(const DesignProblem &problem, Vec x0, Vec direction) {
  PetscScalar *d;
  const PetscScalar *a;
  FX_PETSC(VecGetArray(direction, &d));
  FX_PETSC(VecGetArrayRead(x0, &a));
  const auto &tags = problem.design_keys();
  for (std::size_t k = 0; k < tags.size(); ++k) {
    d[k] = 2.0 * hash_uniform(tags[k]) - 1.0;
    if (a[k] <= 0) d[k] = std::abs(d[k]);
  }
  FX_PETSC(VecRestoreArrayRead(x0, &a));
  FX_PETSC(VecRestoreArray(direction, &d));
}

/// The evaluations' noise, measured: the first evaluation repeated with its iterative solves
/// started from random vectors (none when the problem has no such start).
struct Noise {
  std::vector<double> value; ///< per response: largest change of its value in the repeats
  std::vector<double> slope; ///< per response: largest change of g . d in the repeats
  std::vector<std::unique_ptr<Evaluation>> repeats;
  /// Largest change of the gradient entry `local` (this rank's; -1: not here) of response i.
  double entry(std::size_t i, PetscInt local, const Evaluation &base) const {
    double change = 0;
    if (local < 0) return 0;
    for (const auto &e : repeats) {
      const PetscScalar *g, *g0;
      FX_PETSC(VecGetArrayRead(e->gradient(i), &g));
      FX_PETSC(VecGetArrayRead(base.gradient(i), &g0));
      change = std::max(change, std::abs(g[local] - g0[local]));
      FX_PETSC(VecRestoreArrayRead(base.gradient(i), &g0));
      FX_PETSC(VecRestoreArrayRead(e->gradient(i), &g));
    }
    return change;
  }
};

Noise measure_noise(DesignProblem &problem, Vec x0, Vec direction, const std::vector<double> &r0,
                    const std::vector<double> &slope, Progress &progress) {
  const std::size_t nr = r0.size();
  Noise n;
  n.value.assign(nr, 0.0);
  n.slope.assign(nr, 0.0);
  for (unsigned long seed = 1; seed <= kNoiseRepeats; ++seed) {
    if (!problem.set_random_start(seed)) break;
    auto e = std::make_unique<Evaluation>();
    problem.evaluate(x0, true, *e);
    progress("the first design again, its solves started at random");
    const std::vector<double> r = response_values(*e);
    for (std::size_t i = 0; i < nr; ++i) {
      PetscScalar s = 0;
      FX_PETSC(VecDot(e->gradient(i), direction, &s));
      n.value[i] = std::max(n.value[i], std::abs(r[i] - r0[i]));
      n.slope[i] = std::max(n.slope[i], std::abs(s - slope[i]));
    }
    n.repeats.push_back(std::move(e));
  }
  problem.set_random_start(0);
  return n;
}

/// The Taylor test of every response: |R(x0 + h d) - R(x0) - h g.d| = O(h^2) if g is the
/// gradient. A remainder's noise floor at step h is the largest of the problem's round-off
/// (noise_floor(i) |R|), the measured noise (2 n + h s: the two values and the slope) and the
/// remainders that stopped falling (only noise makes a remainder grow as h shrinks: a wrong
/// gradient leaves an O(h) remainder that still falls). An order is taken only between steps
/// whose smaller remainder exceeds kResolved times its floor, so it is never negative. A
/// response whose remainders all lie within their floors is linear in the design (the volume
/// fraction): exact. `above_round_off`: set when the measured noise of a response that is not
/// linear exceeds its round-off floor; `min_orders`, `linears`: per response.
io::Json taylor_test(DesignProblem &problem, Vec x0, Vec direction, const std::vector<double> &r0,
                     const std::vector<double> &slope, const Noise &noise, Progress &progress,
                     bool &above_round_off, std::vector<double> &min_orders,
                     std::vector<bool> &linears) {
  const MPI_Comm comm = problem.comm();
  const std::size_t nr = r0.size();
  const auto &steps = kTaylorSteps;
  std::vector<std::vector<double>> remainders(nr);
  Vec x;
  FX_PETSC(VecDuplicate(x0, &x));
  for (double h : steps) {
    FX_PETSC(VecWAXPY(x, h, direction, x0));
    Evaluation e;
    problem.evaluate(x, false, e);
    progress("Taylor test");
    const auto r = response_values(e);
    for (std::size_t i = 0; i < nr; ++i)
      remainders[i].push_back(std::abs(r[i] - r0[i] - h * slope[i]));
  }
  FX_PETSC(VecDestroy(&x));
  io::Json taylor = io::Json::array();
  for (std::size_t i = 0; i < nr; ++i) {
    const std::vector<double> &rem = remainders[i];
    const double round_off = problem.noise_floor(i) * std::max(std::abs(r0[i]), 1e-300);
    double stalled = 0;
    for (std::size_t k = 0; k + 1 < steps.size(); ++k)
      if (rem[k + 1] >= rem[k]) stalled = std::max(stalled, rem[k + 1]);
    std::vector<double> floors, orders;
    bool linear = true;
    for (std::size_t k = 0; k < steps.size(); ++k) {
      const double measured = 2 * noise.value[i] + steps[k] * noise.slope[i];
      floors.push_back(std::max({round_off, measured, stalled}));
      linear = linear && rem[k] <= std::max(round_off, measured);
    }
    above_round_off = above_round_off || (!linear && 2 * noise.value[i] > round_off);
    double min_order = 1e300;
    for (std::size_t k = 0; k + 1 < steps.size(); ++k) {
      orders.push_back(std::log10(rem[k] / rem[k + 1]) / std::log10(steps[k] / steps[k + 1]));
      if (rem[k + 1] > kResolved * floors[k + 1]) min_order = std::min(min_order, orders.back());
    }
    const bool resolved = min_order < 1e300;
    io::Json t = io::Json::object();
    t["response"] = problem.response_names()[i];
    t["value"] = r0[i];
    t["steps"] = steps;
    t["remainders"] = rem;
    t["orders"] = orders;
    t["noise_floor"] = std::max({round_off, 2 * noise.value[i], stalled});
    t["noise_floors"] = floors;
    t["round_off_floor"] = round_off;
    t["evaluation_noise"] = noise.value[i];
    t["slope_noise"] = noise.slope[i];
    t["linear"] = linear;
    t["min_order"] = linear || !resolved ? io::Json() : io::Json(min_order);
    min_orders.push_back(linear || !resolved ? std::numeric_limits<double>::quiet_NaN()
                                             : min_order);
    linears.push_back(linear);
    t["resolved"] = linear || resolved;
    taylor.push_back(t);
    print0(comm, "taylor %-28s value %.10g  remainders", problem.response_names()[i].c_str(),
           r0[i]);
    for (double v : rem) print0(comm, " %.3e", v);
    print0(comm, "  orders");
    for (double v : orders) print0(comm, " %.3f", v);
    if (linear)
      print0(comm, "  (linear: remainders within the noise floor)");
    else if (!resolved)
      print0(comm, "  no two remainders above %g x the noise floor: order not measured", kResolved);
    else
      print0(comm, "  min order above the noise floor %.3f", min_order);
    print0(comm, " (noise floor %.1e)\n", floors.back());
  }
  return taylor;
}

/// The keys of kSamples design elements of design field f (Design::design_keys), the same on
/// every rank and every partition, chosen by their keys' hashes among those whose objective
/// sensitivity is at least kSignificant of the field's largest: on the others a difference
/// quotient measures the evaluation's round-off (eps cond(K) |R| / step), not the gradient.
std::vector<unsigned long long> sample_field(const DesignProblem &problem, const Evaluation &base,
                                             std::size_t f, std::size_t samples) {
  const MPI_Comm comm = problem.comm();
  constexpr double kSignificant = 1e-2;
  const Design &d = problem.design();
  const auto begin = static_cast<std::size_t>(d.local_offset(f)),
             end = begin + static_cast<std::size_t>(d.local_size(f));
  // Significant against the field's largest entry, where that is itself above round-off of the
  // whole gradient: a body that the objective does not reach (a driven body's mass, say) gives
  // no samples.
  PetscReal whole = 0;
  FX_PETSC(VecNorm(base.d_objective, NORM_INFINITY, &whole));
  const PetscScalar *g;
  FX_PETSC(VecGetArrayRead(base.d_objective, &g));
  double gmax = 0;
  for (std::size_t k = begin; k < end; ++k) gmax = std::max(gmax, std::abs(g[k]));
  MPI_Allreduce(MPI_IN_PLACE, &gmax, 1, MPI_DOUBLE, MPI_MAX, comm);
  if (gmax <= 1e-8 * whole) gmax = std::numeric_limits<double>::infinity();
  std::vector<std::pair<double, unsigned long long>> mine;
  const auto &tags = problem.design_keys();
  for (std::size_t k = begin; k < end; ++k)
    if (std::abs(g[k]) >= kSignificant * gmax)
      mine.emplace_back(hash_uniform(tags[k] ^ 0x5bd1e995ULL), tags[k]);
  FX_PETSC(VecRestoreArrayRead(base.d_objective, &g));
  std::sort(mine.begin(), mine.end());
  mine.resize(std::min<std::size_t>(mine.size(), samples));
  std::vector<double> keys;
  for (auto &p : mine) keys.insert(keys.end(), {p.first, static_cast<double>(p.second)});
  int n_mine = static_cast<int>(keys.size());
  std::vector<int> counts(static_cast<std::size_t>(comm_size(comm))),
      displs(static_cast<std::size_t>(comm_size(comm)), 0);
  MPI_Allgather(&n_mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  for (int p = 1; p < comm_size(comm); ++p)
    displs[static_cast<std::size_t>(p)] =
        displs[static_cast<std::size_t>(p - 1)] + counts[static_cast<std::size_t>(p - 1)];
  std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(keys.data(), n_mine, MPI_DOUBLE, all.data(), counts.data(), displs.data(),
                 MPI_DOUBLE, comm);
  std::vector<std::pair<double, unsigned long long>> candidates;
  for (std::size_t k = 0; k < all.size(); k += 2)
    candidates.emplace_back(all[k], static_cast<unsigned long long>(all[k + 1]));
  std::sort(candidates.begin(), candidates.end());
  candidates.resize(std::min<std::size_t>(candidates.size(), samples));
  std::vector<unsigned long long> chosen;
  for (const auto &c : candidates) chosen.push_back(c.second);
  return chosen;
}

/// kSamples design elements (sample_field), or with several design bodies at least 3 of each
/// body's, so that every body's gradient is checked.
std::vector<unsigned long long> sample_elements(const DesignProblem &problem,
                                                const Evaluation &base) {
  const std::size_t fields = problem.design().size();
  const std::size_t each = fields == 1 ? kSamples : std::max<std::size_t>(3, kSamples / fields);
  std::vector<unsigned long long> chosen;
  for (std::size_t f = 0; f < fields; ++f) {
    const auto some = sample_field(problem, base, f, each);
    chosen.insert(chosen.end(), some.begin(), some.end());
  }
  return chosen;
}

/// "48", or with several design bodies "rod:48": a design variable's element (its key's field
/// and Gmsh tag, Design::design_keys).
std::string element_label(const Design &d, unsigned long long key) {
  const long long tag = Design::key_tag(key);
  if (d.size() == 1) return std::to_string(tag);
  return d.field(Design::key_field(key)).settings().body + ":" + std::to_string(tag);
}

/// Central differences c_k of every response in the design variable with Gmsh tag `tag`, at the
/// steps h 2^-k, k = 0 ... levels. Collective.
std::vector<std::vector<double>> central_differences(DesignProblem &problem, Vec x0, PetscInt local,
                                                     double h, int levels, Progress &progress) {
  PetscInt first = 0;
  FX_PETSC(VecGetOwnershipRange(x0, &first, nullptr));
  Vec x;
  FX_PETSC(VecDuplicate(x0, &x));
  std::vector<std::vector<double>> c;
  for (int k = 0; k <= levels; ++k) {
    const double hk = h * std::ldexp(1.0, -k);
    std::vector<std::vector<double>> sided;
    for (double delta : {hk, -hk}) {
      FX_PETSC(VecCopy(x0, x));
      if (local >= 0) FX_PETSC(VecSetValue(x, first + local, delta, ADD_VALUES));
      FX_PETSC(VecAssemblyBegin(x));
      FX_PETSC(VecAssemblyEnd(x));
      Evaluation e;
      problem.evaluate(x, false, e);
      progress("central differences");
      sided.push_back(response_values(e));
    }
    std::vector<double> ck;
    for (std::size_t i = 0; i < sided[0].size(); ++i)
      ck.push_back((sided[0][i] - sided[1][i]) / (2 * hk));
    c.push_back(ck);
  }
  FX_PETSC(VecDestroy(&x));
  return c;
}

/// The maxima over the differences of the relative disagreement, and of its part beyond the
/// difference's uncertainty.
struct FdSummary {
  io::Json rows = io::Json::array();
  double max_rel = 0, max_beyond = 0;
};

/// Fourth-order central differences D = (4 c(h/2) - c(h)) / 3 on the sample elements against
/// the adjoint gradient. With L = levels > 1 halvings, per response the extrapolation D_k that
/// agrees best with D_(k+1), where truncation and noise balance; its uncertainty is that gap
/// (none with L = 1) or the measured noise's effect on it, 3 n / h (each value within n of its
/// noise-free one), whichever is larger, plus the measured noise of the adjoint entry itself.
/// Only the part of a disagreement beyond it counts against the adjoint.
FdSummary finite_differences(DesignProblem &problem, Vec x0, const Evaluation &base,
                             const Noise &noise, double step, int levels, Progress &progress) {
  const MPI_Comm comm = problem.comm();
  const auto &names = problem.response_names();
  const std::size_t nr = names.size();
  FdSummary out;
  for (const unsigned long long tag : sample_elements(problem, base)) {
    const auto &tags = problem.design_keys();
    const auto it = std::find(tags.begin(), tags.end(), static_cast<std::uint64_t>(tag));
    const PetscInt local = it == tags.end() ? -1 : static_cast<PetscInt>(it - tags.begin());
    // The adjoint entries and their measured noise, from the rank that holds the variable.
    std::vector<double> adjoint(2 * nr, 0.0);
    for (std::size_t i = 0; i < nr && local >= 0; ++i) {
      const PetscScalar *g;
      FX_PETSC(VecGetArrayRead(base.gradient(i), &g));
      adjoint[i] = g[local];
      FX_PETSC(VecRestoreArrayRead(base.gradient(i), &g));
      adjoint[nr + i] = noise.entry(i, local, base);
    }
    MPI_Allreduce(MPI_IN_PLACE, adjoint.data(), static_cast<int>(2 * nr), MPI_DOUBLE, MPI_SUM,
                  comm);
    const auto c = central_differences(problem, x0, local, step, levels, progress);
    for (std::size_t i = 0; i < nr; ++i) {
      auto D = [&](int k) {
        return (4.0 * c[static_cast<std::size_t>(k + 1)][i] - c[static_cast<std::size_t>(k)][i]) /
               3.0;
      };
      int best = 0;
      double best_gap = 0;
      for (int k = 0; k + 1 < levels; ++k) {
        const double gap = std::abs(D(k) - D(k + 1));
        if (k == 0 || gap < best_gap) best_gap = gap, best = k;
      }
      const double f = D(best), h = step * std::ldexp(1.0, -best);
      // The values' noise over the step: measured in the repeats, and at least the evaluation's
      // own round-off (noise_floor |R|, as the Taylor test takes it): a response that does not
      // depend on this variable (another body's sensor) differs by that much, not by zero.
      const double round_off = problem.noise_floor(i) * std::abs(base.value(i));
      const double fd_noise = 3 * std::max(noise.value[i], round_off) / h;
      const double uncertainty = std::max(best_gap, fd_noise) + adjoint[nr + i];
      const double scale = std::max(std::abs(f), 1e-300);
      const double rel = std::abs(adjoint[i] - f) / scale;
      const double beyond = std::max(0.0, std::abs(adjoint[i] - f) - uncertainty) / scale;
      out.max_rel = std::max(out.max_rel, rel);
      out.max_beyond = std::max(out.max_beyond, beyond);
      io::Json row = io::Json::object();
      row["element"] = Design::key_tag(tag);
      if (problem.design().size() > 1)
        row["body"] = problem.design().field(Design::key_field(tag)).settings().body;
      row["response"] = names[i];
      row["adjoint"] = adjoint[i];
      row["fd"] = f;
      row["rel_err"] = rel;
      row["fd_uncertainty"] = uncertainty;
      row["rel_err_beyond_uncertainty"] = beyond;
      row["fd_noise"] = fd_noise;
      row["adjoint_noise"] = adjoint[nr + i];
      row["step"] = h;
      out.rows.push_back(row);
      print0(comm,
             "fd element %-8s %-28s adjoint % .10e  fd % .10e ± %.1e  rel err %.2e (beyond "
             "the fd's uncertainty %.2e)  (h %.3g)\n",
             element_label(problem.design(), tag).c_str(), names[i].c_str(), adjoint[i], f,
             uncertainty, rel, beyond, h);
    }
  }
  return out;
}

} // namespace

GradientCheckResult check_gradient(DesignProblem &problem, Vec x0,
                                   const GradientCheckOptions &options, Evaluation &base) {
  const MPI_Comm comm = problem.comm();
  const std::size_t nr = problem.response_names().size();
  Vec direction;
  FX_PETSC(VecDuplicate(x0, &direction));
  taylor_direction(problem, x0, direction);
  // Progress: 1 evaluation with gradients, its repeats, 5 Taylor steps and 2 (L + 1) per
  // checked element (L the finite-difference levels).
  const int fd_levels = options.fd_step > 0 ? 1 : problem.fd_levels();
  Progress progress{comm, 1 + kNoiseRepeats + static_cast<int>(kTaylorSteps.size()) +
                              kSamples * 2 * (fd_levels + 1)};
  problem.evaluate(x0, true, base);
  progress("responses and adjoint gradients");
  const std::vector<double> r0 = response_values(base);
  std::vector<double> slope(nr);
  for (std::size_t i = 0; i < nr; ++i) FX_PETSC(VecDot(base.gradient(i), direction, &slope[i]));
  const Noise noise = measure_noise(problem, x0, direction, r0, slope, progress);
  GradientCheckResult out;
  out.taylor = taylor_test(problem, x0, direction, r0, slope, noise, progress,
                           out.noise_above_round_off, out.min_order, out.linear);
  out.fd_step = options.fd_step > 0 ? options.fd_step : problem.fd_step();
  FdSummary fd = finite_differences(problem, x0, base, noise, out.fd_step, fd_levels, progress);
  out.fd = std::move(fd.rows);
  out.max_rel_err = fd.max_rel;
  out.max_rel_err_beyond_uncertainty = fd.max_beyond;
  out.noise_measured = !noise.repeats.empty();
  FX_PETSC(VecDestroy(&direction));
  return out;
}

} // namespace flexopt::optimize
