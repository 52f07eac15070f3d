#include "flexopt/reduce/field_projection.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"

#include <algorithm>
#include <cmath>

namespace flexopt::reduce {

FieldProjection project_field(const mesh::DistributedMesh &mesh, double density,
                              const FlexibleReduction &reduction,
                              const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &u) {
  Mat M = fem::create_matrix(mesh);
  fem::assemble_mass(mesh, density, {}, M);
  Vec x, Mx;
  FX_PETSC(MatCreateVecs(M, &x, &Mx));
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  for (PetscInt i = 0; i < mesh.owned_nodes; ++i) {
    const auto k = static_cast<std::size_t>(3 * i);
    const Eigen::Vector3d v =
        u(Eigen::Vector3d(mesh.coordinates[k], mesh.coordinates[k + 1], mesh.coordinates[k + 2]));
    for (int c = 0; c < 3; ++c) a[3 * i + c] = v(c);
  }
  FX_PETSC(VecRestoreArray(x, &a));
  FX_PETSC(MatMult(M, x, Mx));
  FieldProjection out;
  const int n = reduction.size();
  out.coordinates.setZero(n);
  // Psi_k^T (M u): collective dot products, the same on every rank.
  for (int k = 0; k < n; ++k)
    FX_PETSC(VecDot(reduction.basis[static_cast<std::size_t>(k)], Mx, &out.coordinates(k)));
  double uMu = 0;
  FX_PETSC(VecDot(x, Mx, &uMu));
  out.norm = std::sqrt(std::max(uMu, 0.0));
  if (uMu > 0) out.residual = std::sqrt(std::max(0.0, 1.0 - out.coordinates.squaredNorm() / uMu));
  FX_PETSC(VecDestroy(&x));
  FX_PETSC(VecDestroy(&Mx));
  FX_PETSC(MatDestroy(&M));
  return out;
}

} // namespace flexopt::reduce
