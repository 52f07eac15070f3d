#include "flexopt/reduce/field_projection.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/element.hpp"
#include "flexopt/reduce/reduction_adjoint.hpp"

#include <algorithm>
#include <cmath>

namespace flexopt::reduce {

namespace {

/// The field u at the owned nodes, in a vector of M's layout.
void nodal_field(const mesh::DistributedMesh &mesh, const Field &u, Vec x) {
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  for (PetscInt i = 0; i < mesh.owned_nodes; ++i) {
    const auto k = static_cast<std::size_t>(3 * i);
    const Eigen::Vector3d v =
        u(Eigen::Vector3d(mesh.coordinates[k], mesh.coordinates[k + 1], mesh.coordinates[k + 2]));
    for (int c = 0; c < 3; ++c) a[3 * i + c] = v(c);
  }
  FX_PETSC(VecRestoreArray(x, &a));
}

/// The consistent mass matrix of the reduction's body (a design reduction's own M = sum_e w_e
/// M_e, kept with its adjoint data, or assembled with `density`) and M u.
struct MassAndField {
  Mat M = nullptr;
  bool owned = false;
  Vec x = nullptr, Mx = nullptr;
  MassAndField(const mesh::DistributedMesh &mesh, double density,
               const FlexibleReduction &reduction, const Field &u) {
    if (reduction.adjoint && reduction.adjoint->M) {
      M = reduction.adjoint->M;
    } else {
      M = fem::create_matrix(mesh);
      owned = true;
      fem::assemble_mass(mesh, density, {}, M);
    }
    FX_PETSC(MatCreateVecs(M, &x, &Mx));
    nodal_field(mesh, u, x);
    FX_PETSC(MatMult(M, x, Mx));
  }
  ~MassAndField() {
    VecDestroy(&x);
    VecDestroy(&Mx);
    if (owned) MatDestroy(&M);
  }
  MassAndField(const MassAndField &) = delete;
  MassAndField &operator=(const MassAndField &) = delete;
};

} // namespace

FieldProjection project_field(const mesh::DistributedMesh &mesh, double density,
                              const FlexibleReduction &reduction, const Field &u) {
  const MassAndField f(mesh, density, reduction, u);
  FieldProjection out;
  const int n = reduction.size();
  out.coordinates.setZero(n);
  // Psi_k^T (M u): collective dot products, the same on every rank.
  for (int k = 0; k < n; ++k)
    FX_PETSC(VecDot(reduction.basis[static_cast<std::size_t>(k)], f.Mx, &out.coordinates(k)));
  double uMu = 0;
  FX_PETSC(VecDot(f.x, f.Mx, &uMu));
  out.norm = std::sqrt(std::max(uMu, 0.0));
  if (uMu > 0) out.residual = std::sqrt(std::max(0.0, 1.0 - out.coordinates.squaredNorm() / uMu));
  return out;
}

void project_field_adjoint(const mesh::DistributedMesh &mesh, double density,
                           const FlexibleReduction &reduction, const Field &u,
                           const Eigen::VectorXd &zeta, const Eigen::VectorXd &zbar,
                           const std::vector<Vec> &basis_bar, std::vector<double> &w_hat) {
  const int n = reduction.size();
  if (static_cast<int>(basis_bar.size()) != n || zeta.size() != n || zbar.size() != n)
    throw Error("project_field_adjoint: the basis has " + std::to_string(n) +
                    " vectors, the cotangents do not match",
                true);
  const MassAndField f(mesh, density, reduction, u);
  // res = u - Psi zeta, a = Psi zbar, and their products with M.
  Vec res, a, Mres, Ma;
  FX_PETSC(VecDuplicate(f.x, &res));
  FX_PETSC(VecDuplicate(f.x, &a));
  FX_PETSC(VecDuplicate(f.x, &Mres));
  FX_PETSC(VecDuplicate(f.x, &Ma));
  FX_PETSC(VecCopy(f.x, res));
  FX_PETSC(VecZeroEntries(a));
  for (int k = 0; k < n; ++k) {
    const Vec psi = reduction.basis[static_cast<std::size_t>(k)];
    FX_PETSC(VecAXPY(res, -zeta(k), psi));
    FX_PETSC(VecAXPY(a, zbar(k), psi));
  }
  FX_PETSC(MatMult(f.M, res, Mres));
  FX_PETSC(MatMult(f.M, a, Ma));
  for (int k = 0; k < n; ++k) {
    FX_PETSC(VecAXPY(basis_bar[static_cast<std::size_t>(k)], zbar(k), Mres));
    FX_PETSC(VecAXPY(basis_bar[static_cast<std::size_t>(k)], -zeta(k), Ma));
  }
  {
    const fem::ElementGather g(mesh, {a, res});
    Eigen::MatrixXd ae;
    w_hat.resize(static_cast<std::size_t>(mesh.local_elements()), 0.0);
    for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
      g.element(e, ae);
      const fem::ElementMatrix Me =
          fem::element_mass(mesh.type, mesh.element_coordinates(e), density);
      w_hat[static_cast<std::size_t>(e)] += ae.col(0).dot(Me * ae.col(1));
    }
  }
  VecDestroy(&res);
  VecDestroy(&a);
  VecDestroy(&Mres);
  VecDestroy(&Ma);
}

} // namespace flexopt::reduce
