#pragma once
/// \file Density filters: rho_filtered = F rho on element fields, with the exact transpose for
/// the sensitivities (docs/theory.md, section 4). Two kinds:
///   - helmholtz: the PDE filter -r^2 lap(rho~) + rho~ = rho (Lazarov & Sigmund 2011);
///   - cone: the classical density filter with linearly decaying weights max(0, R - |x_e - x_i|)
///     times element volume (Bruns & Tortorelli 2001; Bourdin 2001), the filter of the
///     reference PETSc code of Aage, Andreassen & Lazarov (2015).
#include "flexopt/mesh/distributed_mesh.hpp"

#include <memory>
#include <petscvec.h>
#include <string>

namespace flexopt::optimize {

/// A linear filter on element vectors: one entry per local element of the mesh (local size
/// mesh.local_elements(), global order = element_start + local index).
class DensityFilter {
public:
  virtual ~DensityFilter() = default;
  /// A new element vector (caller destroys it). Collective.
  virtual Vec create_element_vector() const = 0;
  /// rho_filtered = F rho. Collective.
  virtual void apply(Vec rho, Vec rho_filtered) const = 0;
  /// g = F^T g_filtered (sensitivities through the filter). Collective.
  virtual void apply_transpose(Vec g_filtered, Vec g) const = 0;
  /// One line for the log, e.g. "Helmholtz filter r = 0.05".
  virtual std::string describe() const = 0;
  /// check-gradient: a filter that solves iteratively solves to round-off from now on, unless
  /// the options set its tolerance; returns what limits its accuracy, in words ("": nothing).
  /// Collective.
  virtual std::string solve_to_round_off() { return ""; }
  /// seed != 0: the later solves start from random vectors drawn with `seed`, until called with
  /// 0 (check-gradient's measurement of the evaluation noise). Returns whether the filter solves
  /// iteratively (else it has no start to perturb).
  virtual bool set_random_start(unsigned long seed) {
    (void)seed;
    return false;
  }
};

/// The density filter: the Helmholtz PDE filter or the classical cone filter.
enum class FilterType { Helmholtz, Cone };

/// The filter of `type` with its length `radius` [m] (> 0): the
/// Helmholtz length scale r, or the cone radius R (R = 2 sqrt(3) r gives the same variance of
/// the weights). `mesh` must outlive the filter. Collective.
std::unique_ptr<DensityFilter> create_density_filter(const mesh::DistributedMesh &mesh,
                                                     FilterType type, double radius);

} // namespace flexopt::optimize
