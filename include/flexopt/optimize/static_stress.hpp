#pragma once
/// \file A stress response of a static design (docs/theory.md section 5.1): the relaxed von
/// Mises stress of each element at its centroid, its aggregate, the adjoint load dR/du and the
/// explicit dR/d(rho), and the adaptive normalization's scale.
#include "flexopt/fem/element.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/stress_aggregate.hpp"

#include <petscvec.h>
#include <vector>

namespace flexopt::optimize {

/// The local elements of a stress response's aggregate: those of r.region, or all of `mesh`'s
/// when it is empty. Collective; a region without elements on any rank throws a collective
/// flexopt::Error naming the response.
std::vector<PetscInt> stress_elements(const mesh::DistributedMesh &mesh, const ResponseSettings &r);

/// summary.json's "stress": describe(name) of every stress response (null pointers skipped),
/// with the responses' names; null when there is none.
template <class Ptrs>
io::Json describe_stress(const Ptrs &stress, const std::vector<std::string> &names) {
  io::Json out = io::Json::array();
  bool any = false;
  for (std::size_t i = 0; i < stress.size(); ++i)
    if (stress[i]) {
      out.push_back(stress[i]->describe(names[i]));
      any = true;
    }
  return any ? out : io::Json();
}

/// summary.json's entry of a stress response `name` (r) from its last aggregate `a` and scale c:
/// "response", "body", "aggregate", "value" (c R), "unscaled_value", "scale", "peak",
/// "peak_element", "peak_time" (dynamic), "max" and "peak_over_max" (a constraint).
io::Json describe_stress_response(const std::string &name, const ResponseSettings &r,
                                  const StressAggregate &a, double scale);

class StaticStress {
public:
  /// The elements of r.region (all elements of `mesh` when empty). Collective (a missing
  /// region throws a collective error naming the response).
  StaticStress(const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &material,
               const ResponseSettings &r);
  /// The samples eta_e v_e at the displacement u (ghosted, ghosts current) and relaxation
  /// factors eta (all local elements); returns c R. Collective.
  double evaluate(Vec u, const std::vector<double> &eta);
  /// dR/du of the last evaluate (times c) into the ghosted vector rhs (overwritten, summed over
  /// the ranks that share a node). Collective.
  void adjoint_load(const std::vector<double> &eta, Vec rhs) const;
  /// Adds the explicit c g_e eta'(rho_e) v_e to g (one entry per local element), at the
  /// relaxation factors eta of the last evaluate and their derivatives deta.
  void add_explicit(const std::vector<double> &eta, const std::vector<double> &deta,
                    double *g) const;
  /// Adaptive normalization: c from the last evaluation, for the next (no-op without it).
  void end_iteration();
  double scale() const { return scale_; }
  /// The last evaluation's aggregate R (unscaled), peak and its place.
  const StressAggregate &aggregate() const { return aggregate_; }
  /// The elements the aggregate takes, over all ranks. Collective.
  long long global_elements() const;
  void set_scale(double c) { scale_ = c; }
  /// {"response", "aggregate", "peak", "element", "scale"} of the last evaluation.
  io::Json describe(const std::string &name) const;

private:
  const mesh::DistributedMesh &mesh_;
  fem::IsotropicMaterial material_;
  ResponseSettings r_;
  std::vector<PetscInt> elements_; ///< local elements of the aggregate
  StressAggregate aggregate_;
  std::vector<double> solid_; ///< von Mises v_e of the solid stress per aggregate element
  /// S_e^T dv/dsigma per aggregate element (elements_ order): the adjoint load of a unit dR/dv_e.
  std::vector<fem::ElementVector> dv_;
  double scale_ = 1.0; ///< adaptive normalization c
};

} // namespace flexopt::optimize
