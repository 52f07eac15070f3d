#pragma once
/// \file The classical density filter with cone weights (docs/theory.md, section 4.2).
#include "flexopt/optimize/density_filter.hpp"

#include <petscmat.h>

namespace flexopt::optimize {

/// rho~_e = sum_i w_ei V_i rho_i / sum_i w_ei V_i,  w_ei = max(0, R - |c_e - c_i|), over all
/// elements i of the mesh whose centroid c_i lies within R of the centroid c_e (on any rank).
/// Stored as a row-normalised sparse matrix H (MPIAIJ), so that the filter is H rho and its
/// transpose H^T g.
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
  Mat H_ = nullptr;
  PetscInt max_neighbours_ = 0;
};

} // namespace flexopt::optimize
