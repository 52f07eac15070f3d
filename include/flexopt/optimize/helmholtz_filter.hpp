#pragma once
/// \file Helmholtz (PDE) density filter and its exact transpose (docs/theory.md, section 4).
#include "flexopt/optimize/density_filter.hpp"

#include <memory>
#include <petscksp.h>
#include <vector>

namespace flexopt::optimize {

/// rho_filtered = F rho, F = V^-1 T^T (r^2 K + M)^-1 T, on a P1 field over the corner nodes of
/// the mesh. Element vectors have one entry per local element (local size
/// mesh.local_elements(), global order = element_start + local index).
class HelmholtzFilter : public DensityFilter {
public:
  /// Assembles the filter operator for length scale `radius` [m] (> 0); `mesh` must outlive
  /// the filter. Collective.
  /// Solver options take the prefix `filter_` (e.g. -filter_ksp_rtol 1e-12).
  static std::unique_ptr<HelmholtzFilter> create(const mesh::DistributedMesh &mesh, double radius);
  ~HelmholtzFilter() override;
  HelmholtzFilter(const HelmholtzFilter &) = delete;
  HelmholtzFilter &operator=(const HelmholtzFilter &) = delete;

  /// A new element vector (caller destroys it). Collective.
  Vec create_element_vector() const override;
  /// rho_filtered = F rho. Collective.
  void apply(Vec rho, Vec rho_filtered) const override;
  /// g = F^T g_filtered (sensitivities through the filter). Collective.
  void apply_transpose(Vec g_filtered, Vec g) const override;
  std::string describe() const override;
  /// The filter's solves to a relative residual of 1e-12 (already the default) unless
  /// -filter_ksp_rtol is set.
  std::string solve_to_round_off() override;
  bool set_random_start(unsigned long seed) override;
  /// Krylov iterations of the last solve.
  int last_iterations() const { return iterations_; }
  double radius() const { return radius_; }

private:
  HelmholtzFilter() = default;
  /// b = T x for an element vector x (b ghosted, nodal).
  void element_to_nodes(Vec x, Vec b) const;
  /// y_e = sum_i w_ei phi_i (phi ghosted, ghosts updated here).
  void nodes_to_element(Vec phi, Vec y) const;
  void solve(Vec b, Vec phi) const;

  const mesh::DistributedMesh *mesh_ = nullptr;
  double radius_ = 0;
  int corners_ = 0;
  std::vector<double> weights_; ///< w_ei, corners_ per local element
  std::vector<double> volume_;  ///< V_e
  Mat A_ = nullptr;
  KSP ksp_ = nullptr;
  Vec rhs_ = nullptr, phi_ = nullptr, scaled_ = nullptr;
  mutable int iterations_ = 0;
  unsigned long random_start_ = 0;         ///< seed of random starts (0: start from zero)
  mutable unsigned long random_draws_ = 0; ///< random starts drawn with it so far
};

} // namespace flexopt::optimize
