#include "flexopt/dynamics/ties.hpp"

#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>

namespace flexopt::dynamics {

double add_ties(const TieSet &ties, const double *x, const bodies::Vec3 &r, const bodies::Vec4 &p,
                const double *lambda, double bp, Mat A, Vec rhs) {
  using bodies::Mat3;
  using bodies::Vec3;
  const bodies::Mat3 R = bodies::rotation(p);
  const PetscInt rc[3] = {ties.coord0, ties.coord0 + 1, ties.coord0 + 2};
  const PetscInt pc[4] = {ties.coord0 + 3, ties.coord0 + 4, ties.coord0 + 5, ties.coord0 + 6};
  const double I3[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, mI3[9] = {-1, 0, 0, 0, -1, 0, 0, 0, -1};
  Eigen::Matrix4d hessian = Eigen::Matrix4d::Zero();
  Vec3 force_r = Vec3::Zero();
  Eigen::Vector4d force_p = Eigen::Vector4d::Zero();
  double violation = 0;
  for (std::size_t j = 0; j < ties.s.size(); ++j) {
    const Vec3 xj(x + 3 * j), lj(lambda + 3 * j), &s = ties.s[j];
    const PetscInt rows[3] = {ties.row0 + 3 * static_cast<PetscInt>(j),
                              ties.row0 + 3 * static_cast<PetscInt>(j) + 1,
                              ties.row0 + 3 * static_cast<PetscInt>(j) + 2};
    const PetscInt xc[3] = {ties.x_dof[j], ties.x_dof[j] + 1, ties.x_dof[j] + 2};
    // Rows and their transposes.
    const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> Dp = -bodies::rotate_jacobian(p, s);
    const Eigen::Matrix<double, 4, 3, Eigen::RowMajor> DpT = Dp.transpose();
    if (A) {
      FX_PETSC(MatSetValues(A, 3, rows, 3, xc, I3, ADD_VALUES));
      FX_PETSC(MatSetValues(A, 3, xc, 3, rows, I3, ADD_VALUES));
      FX_PETSC(MatSetValues(A, 3, rows, 3, rc, mI3, ADD_VALUES));
      FX_PETSC(MatSetValues(A, 3, rc, 3, rows, mI3, ADD_VALUES));
      FX_PETSC(MatSetValues(A, 3, rows, 4, pc, Dp.data(), ADD_VALUES));
      FX_PETSC(MatSetValues(A, 4, pc, 3, rows, DpT.data(), ADD_VALUES));
      // d/dp (Phi_p^T lambda) = -K(s, lambda).
      hessian -= bodies::rotate_hessian(s, lj);
    }
    // Right-hand side.
    const Vec3 phi = xj - r - R * s;
    violation = std::max(violation, phi.cwiseAbs().maxCoeff());
    const Vec3 mphi = -phi, fx = -lj / bp;
    FX_PETSC(VecSetValues(rhs, 3, rows, mphi.data(), ADD_VALUES));
    FX_PETSC(VecSetValues(rhs, 3, xc, fx.data(), ADD_VALUES));
    force_r += lj / bp;
    force_p -= Dp.transpose() * lj / bp;
  }
  if (!ties.s.empty()) {
    if (A) {
      const Eigen::Matrix<double, 4, 4, Eigen::RowMajor> H = hessian / bp;
      FX_PETSC(MatSetValues(A, 4, pc, 4, pc, H.data(), ADD_VALUES));
    }
    FX_PETSC(VecSetValues(rhs, 3, rc, force_r.data(), ADD_VALUES));
    FX_PETSC(VecSetValues(rhs, 4, pc, force_p.data(), ADD_VALUES));
  }
  return violation;
}

void tie_accelerations(const TieSet &ties, const bodies::Vec4 &p_dot, double *gamma) {
  for (std::size_t j = 0; j < ties.s.size(); ++j) {
    const bodies::Vec3 g = bodies::rotate_jacobian(p_dot, ties.s[j]) * p_dot;
    for (int k = 0; k < 3; ++k) gamma[3 * j + k] = g(k);
  }
}

} // namespace flexopt::dynamics
