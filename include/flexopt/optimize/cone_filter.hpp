#pragma once
/// \file The classical density filter with cone weights (docs/theory.md, section 4.2).
#include "flexopt/optimize/density_filter.hpp"

#include <petscmat.h>

namespace flexopt::optimize {

/// rho~_e = sum_i w_ei V_i rho_i / sum_i w_ei V_i,  w_ei = max(0, R - |c_e - c_i|), over all
/// elements i of the mesh whose centroid c_i lies within R of the centroid c_e (on any rank).
/// H = D^-1 W V with W_ei = w_ei symmetric, V = diag(V_i), D = diag(sum_i w_ei V_i): W's upper
/// triangle is stored once (MPISBAIJ), so that the filter is D^-1 W V rho and its transpose
/// V W D^-1 g.
class ConeFilter : public DensityFilter {
public:
  /// Builds H for radius R > 0 [m]. Collective.
  static std::unique_ptr<ConeFilter> create(const mesh::DistributedMesh &mesh, double radius);
  ~ConeFilter() override;
  ConeFilter(const ConeFilter &) = delete;
  ConeFilter &operator=(const ConeFilter &) = delete;

  Vec create_element_vector() const override;
  void apply(Vec rho, Vec rho_filtered) const override;
  void apply_transpose(Vec g_filtered, Vec g) const override;
  std::string describe() const override;
  /// Largest number of neighbours (including itself) of an element, over all ranks.
  PetscInt max_neighbours() const { return max_neighbours_; }

private:
  ConeFilter() = default;
  double radius_ = 0;
  Mat W_ = nullptr;                       ///< the symmetric weights w_ei, upper triangle
  Vec dinv_ = nullptr, volume_ = nullptr; ///< 1 / d_e and V_e
  Vec work_ = nullptr;                    ///< V rho or D^-1 g (apply's scratch)
  PetscInt max_neighbours_ = 0;
};

} // namespace flexopt::optimize
