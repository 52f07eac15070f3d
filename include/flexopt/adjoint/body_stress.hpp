#pragma once
/// \file A stress response on a flexible body in a dynamic analysis (docs/theory.md sections
/// 8.3 and 10.3): the space-time aggregate of the relaxed von Mises stress of the body's
/// elements over the main steps, what the adjoint needs of it, and the adaptive normalization.
/// BodyStress holds what every body model shares; FfrfStress (ffrf_stress.hpp) samples an FFRF
/// body through its stress shapes, AcfStress (here) an ACF body through its co-rotated elements.
#include "flexopt/fem/element.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/stress_aggregate.hpp"

#include <vector>

namespace flexopt::bodies {
class AcfBody;
}

namespace flexopt::adjoint {

class BodyStress {
public:
  virtual ~BodyStress() = default;
  /// Forgets the recorded steps (a new forward run).
  virtual void clear() = 0;
  /// After the forward run of main steps of size h: the aggregate R over every element and
  /// recorded step, with relaxation factors eta (per local element of the body; empty: 1), and
  /// with `gradients` what the backward sweep needs and the explicit gradient (with deta).
  /// Returns c R. Collective.
  virtual double finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                        bool gradients) = 0;
  /// The explicit dR/d(physical density) of every local element (sum_n g eta' v), after a
  /// finish with gradients.
  const std::vector<double> &explicit_gradient() const { return explicit_; }
  /// {"response", "body", "aggregate", "value", "peak", "peak_element", "peak_time", ...}.
  io::Json describe(const std::string &name) const;
  const optimize::StressAggregate &aggregate() const { return aggregate_; }
  /// Adaptive normalization (docs/theory.md 5.1): the value and its derivatives are c R; c
  /// follows the true peak after each optimization iteration (no-op without it).
  void end_iteration();
  double scale() const { return scale_; }
  void set_scale(double c) { scale_ = c; }

protected:
  /// The response r on the body meshed as `mesh` (which must outlive this) of material
  /// `material`, the elements of r.region (all when empty). Collective.
  BodyStress(const optimize::ResponseSettings &r, const mesh::DistributedMesh &mesh,
             const fem::IsotropicMaterial &material);
  /// The relaxation factor of aggregate element i (elements_ order).
  double eta_of(const std::vector<double> &eta, std::size_t i) const {
    return eta.empty() ? 1.0 : eta[static_cast<std::size_t>(elements_[i])];
  }
  /// The Gmsh tag of aggregate element i.
  long long tag_of(std::size_t i) const {
    return static_cast<long long>(mesh_.element_tags[static_cast<std::size_t>(elements_[i])]);
  }

  optimize::ResponseSettings r_;
  const mesh::DistributedMesh &mesh_;
  fem::IsotropicMaterial material_;
  std::vector<PetscInt> elements_; ///< the local elements of the aggregate
  optimize::StressAggregate aggregate_;
  std::vector<double> explicit_; ///< per local element
  double scale_ = 1.0;           ///< adaptive normalization c
};

/// A stress response on an ACF body (docs/theory.md section 8.3): the co-rotated centroid
/// stress sigma_e = S_e u~_e of each element at every main step, aggregated as the steps come
/// (nothing is kept per step); in the backward sweep the stress of step n is computed again at
/// its recomputed state, with the response's partial dR/dx_n and the relaxation's explicit part.
class AcfStress : public BodyStress {
public:
  /// The response r on `body` (which must outlive this). Collective.
  AcfStress(const optimize::ResponseSettings &r, const bodies::AcfBody &body);
  /// A new forward run of `steps` main steps of size h, with relaxation factors eta and their
  /// derivatives deta (per local element of the body; empty: 1 and 0, a body not designed).
  void start(std::size_t steps, double h, const std::vector<double> &eta,
             const std::vector<double> &deta);
  void clear() override { aggregate_.clear(); }
  /// Samples the next main step at the body's local displacements u (3 per local node, ghosts
  /// current). Not collective.
  void record(const double *u);
  /// The aggregate of the recorded steps (its arguments are start()'s). Collective.
  double finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                bool gradients) override;
  /// At main step n with the body's local displacements u: adds dR/dx into `force` (3 per local
  /// node; ghosts' shares to be added on their owners) and, if `explicit_gradient` is not null
  /// (the design body), sum_e g eta' v into it (one per local element). Not collective.
  void add_state_partial(std::size_t n, const double *u, double *force,
                         double *explicit_gradient) const;

private:
  const bodies::AcfBody &body_;
  std::vector<fem::StressMatrix> S_; ///< per aggregate element: S_e of the solid material
  std::vector<double> eta_, deta_;   ///< start()'s relaxation
  std::size_t steps_ = 0, recorded_ = 0;
  double h_ = 0;
};

} // namespace flexopt::adjoint
