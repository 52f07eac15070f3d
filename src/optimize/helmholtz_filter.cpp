#include "flexopt/optimize/helmholtz_filter.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/krylov.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/static_problem.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <sstream>

namespace flexopt::optimize {

namespace {

/// The linear element on an element's corner nodes: the filter field's element.
fem::ElementType corner_element(fem::ElementType t) {
  return t == fem::ElementType::Hex8 ? fem::ElementType::Hex8 : fem::ElementType::Tet4;
}

using CornerMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor, 8, 8>;

/// Scalar diffusion K = int grad N grad N^T, mass M = int N N^T and weights w = int N on the
/// linear corner element with coordinates X (first nc rows of the element's coordinates).
void corner_kernels(fem::ElementType type, const fem::ElementCoords &X, int nc, CornerMatrix &K,
                    CornerMatrix &M, Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 8, 1> &w) {
  // Degree 2 is exact for N N^T on affine tets; hexes take 3 x 3 x 3 points (degree 5 per
  // direction), exact for the mass of any trilinear hex.
  static const fem::QuadratureRule kTet = fem::volume_quadrature(fem::ElementType::Tet4, 2);
  static const fem::QuadratureRule kHex = fem::volume_quadrature(fem::ElementType::Hex8, 5);
  const fem::QuadratureRule &q = type == fem::ElementType::Hex8 ? kHex : kTet;
  K.setZero(nc, nc);
  M.setZero(nc, nc);
  w.setZero(nc);
  double N[8], dN[24];
  for (std::size_t p = 0; p < q.points.size(); ++p) {
    fem::shape_functions(type, q.points[p], N, dN);
    Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
    for (int a = 0; a < nc; ++a)
      for (int i = 0; i < 3; ++i)
        for (int k = 0; k < 3; ++k) J(i, k) += (X(a, i) - X(0, i)) * dN[a * 3 + k];
    const double det = J.determinant();
    if (!(det > 0)) throw Error("Helmholtz filter: degenerate or inverted element (det J <= 0)");
    const Eigen::Matrix3d Jinv = J.inverse();
    Eigen::Matrix<double, 8, 3> G;
    for (int a = 0; a < nc; ++a)
      for (int k = 0; k < 3; ++k)
        G(a, k) =
            dN[a * 3 + 0] * Jinv(0, k) + dN[a * 3 + 1] * Jinv(1, k) + dN[a * 3 + 2] * Jinv(2, k);
    const double dv = q.weights[p] * det;
    for (int a = 0; a < nc; ++a) {
      w(a) += N[a] * dv;
      for (int b = 0; b < nc; ++b) {
        K(a, b) += G.row(a).dot(G.row(b)) * dv;
        M(a, b) += N[a] * N[b] * dv;
      }
    }
  }
}

} // namespace

std::unique_ptr<HelmholtzFilter> HelmholtzFilter::create(const mesh::DistributedMesh &mesh,
                                                         double radius) {
  if (!(radius > 0)) throw Error("Helmholtz filter: the radius must be positive", true);
  LogScope log("FxFilterSetUp");
  std::unique_ptr<HelmholtzFilter> f(new HelmholtzFilter());
  f->mesh_ = &mesh;
  f->radius_ = radius;
  const fem::ElementType ctype = corner_element(mesh.type);
  const int nc = fem::corner_nodes(mesh.type), npe = mesh.nodes_per_element();
  f->corners_ = nc;
  const PetscInt ne = mesh.local_elements();
  f->weights_.resize(static_cast<std::size_t>(ne * nc));
  f->volume_.resize(static_cast<std::size_t>(ne));

  f->A_ = fem::create_matrix(mesh, 1);
  FX_PETSC(MatZeroEntries(f->A_));
  CornerMatrix K, M, A;
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 8, 1> w;
  std::vector<char> is_corner(static_cast<std::size_t>(mesh.local_nodes()), 0);
  for (PetscInt e = 0; e < ne; ++e) {
    const fem::ElementCoords X = mesh.element_coordinates(e);
    corner_kernels(ctype, X, nc, K, M, w);
    A = radius * radius * K + M;
    const PetscInt *idx = &mesh.connectivity[static_cast<std::size_t>(e * npe)];
    FX_PETSC(MatSetValuesLocal(f->A_, nc, idx, nc, idx, A.data(), ADD_VALUES));
    for (int a = 0; a < nc; ++a) {
      f->weights_[static_cast<std::size_t>(e * nc + a)] = w(a);
      is_corner[static_cast<std::size_t>(idx[a])] = 1;
    }
    f->volume_[static_cast<std::size_t>(e)] = w.sum();
  }
  // Nodes that are no element's corner (Tet10 mid-edge nodes) are not part of the filter
  // field: identity rows keep the system non-singular (their phi is 0 and never read).
  // Every owned node is touched by a local element, so the owner knows its role.
  for (PetscInt i = 0; i < mesh.owned_nodes; ++i)
    if (!is_corner[static_cast<std::size_t>(i)])
      FX_PETSC(MatSetValueLocal(f->A_, i, i, 1.0, ADD_VALUES));
  FX_PETSC(MatAssemblyBegin(f->A_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(f->A_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatSetOption(f->A_, MAT_SPD, PETSC_TRUE));

  FX_PETSC(VecCreateGhost(mesh.comm, mesh.owned_nodes, PETSC_DETERMINE,
                          static_cast<PetscInt>(mesh.ghosts.size()), mesh.ghosts.data(), &f->rhs_));
  FX_PETSC(VecDuplicate(f->rhs_, &f->phi_));
  f->scaled_ = f->create_element_vector();

  FX_PETSC(KSPCreate(mesh.comm, &f->ksp_));
  FX_PETSC(KSPSetOptionsPrefix(f->ksp_, "filter_"));
  FX_PETSC(KSPSetOperators(f->ksp_, f->A_, f->A_));
  FX_PETSC(KSPSetType(f->ksp_, KSPCG));
  PC pc;
  FX_PETSC(KSPGetPC(f->ksp_, &pc));
  FX_PETSC(PCSetType(pc, PCGAMG));
  FX_PETSC(KSPSetTolerances(f->ksp_, 1e-12, 1e-300, PETSC_DEFAULT, 1000));
  FX_PETSC(KSPSetFromOptions(f->ksp_));
  FX_PETSC(KSPSetUp(f->ksp_));
  return f;
}

HelmholtzFilter::~HelmholtzFilter() {
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
  VecDestroy(&rhs_);
  VecDestroy(&phi_);
  VecDestroy(&scaled_);
}

Vec HelmholtzFilter::create_element_vector() const {
  Vec v;
  FX_PETSC(VecCreateMPI(mesh_->comm, mesh_->local_elements(), PETSC_DETERMINE, &v));
  return v;
}

void HelmholtzFilter::element_to_nodes(Vec x, Vec b) const {
  const int npe = mesh_->nodes_per_element();
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(b, &local));
  FX_PETSC(VecZeroEntries(local));
  PetscScalar *bl;
  const PetscScalar *xe;
  FX_PETSC(VecGetArray(local, &bl));
  FX_PETSC(VecGetArrayRead(x, &xe));
  for (PetscInt e = 0; e < mesh_->local_elements(); ++e)
    for (int a = 0; a < corners_; ++a)
      bl[mesh_->connectivity[static_cast<std::size_t>(e * npe + a)]] +=
          weights_[static_cast<std::size_t>(e * corners_ + a)] * xe[e];
  FX_PETSC(VecRestoreArrayRead(x, &xe));
  FX_PETSC(VecRestoreArray(local, &bl));
  FX_PETSC(VecGhostRestoreLocalForm(b, &local));
  FX_PETSC(VecGhostUpdateBegin(b, ADD_VALUES, SCATTER_REVERSE));
  FX_PETSC(VecGhostUpdateEnd(b, ADD_VALUES, SCATTER_REVERSE));
}

void HelmholtzFilter::nodes_to_element(Vec phi, Vec y) const {
  const int npe = mesh_->nodes_per_element();
  FX_PETSC(VecGhostUpdateBegin(phi, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(phi, INSERT_VALUES, SCATTER_FORWARD));
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(phi, &local));
  const PetscScalar *pl;
  PetscScalar *ye;
  FX_PETSC(VecGetArrayRead(local, &pl));
  FX_PETSC(VecGetArray(y, &ye));
  for (PetscInt e = 0; e < mesh_->local_elements(); ++e) {
    double s = 0;
    for (int a = 0; a < corners_; ++a)
      s += weights_[static_cast<std::size_t>(e * corners_ + a)] *
           pl[mesh_->connectivity[static_cast<std::size_t>(e * npe + a)]];
    ye[e] = s;
  }
  FX_PETSC(VecRestoreArray(y, &ye));
  FX_PETSC(VecRestoreArrayRead(local, &pl));
  FX_PETSC(VecGhostRestoreLocalForm(phi, &local));
}

std::string HelmholtzFilter::solve_to_round_off() {
  return tighten_krylov(ksp_, 1e-12, 10000, "the filter's solves");
}

bool HelmholtzFilter::set_random_start(unsigned long seed) {
  random_start_ = seed;
  random_draws_ = 0;
  return !is_direct(ksp_);
}

void HelmholtzFilter::solve(Vec b, Vec phi) const {
  LogScope log("FxFilterSolve");
  const bool random = random_start_ != 0 && !is_direct(ksp_);
  // Filtered densities lie in [0, 1]: a random start of that size.
  if (random) fill_random(phi, random_start_ * 1000003UL + random_draws_++, 1.0);
  FX_PETSC(KSPSetInitialGuessNonzero(ksp_, random ? PETSC_TRUE : PETSC_FALSE));
  FX_PETSC(KSPSolve(ksp_, b, phi));
  fem::check_converged(ksp_, "Helmholtz filter");
  PetscInt its = 0;
  FX_PETSC(KSPGetIterationNumber(ksp_, &its));
  iterations_ = static_cast<int>(its);
}

void HelmholtzFilter::apply(Vec rho, Vec rho_filtered) const {
  element_to_nodes(rho, rhs_);
  solve(rhs_, phi_);
  nodes_to_element(phi_, rho_filtered);
  PetscScalar *y;
  FX_PETSC(VecGetArray(rho_filtered, &y));
  for (PetscInt e = 0; e < mesh_->local_elements(); ++e)
    y[e] /= volume_[static_cast<std::size_t>(e)];
  FX_PETSC(VecRestoreArray(rho_filtered, &y));
}

void HelmholtzFilter::apply_transpose(Vec g_filtered, Vec g) const {
  FX_PETSC(VecCopy(g_filtered, scaled_));
  PetscScalar *s;
  FX_PETSC(VecGetArray(scaled_, &s));
  for (PetscInt e = 0; e < mesh_->local_elements(); ++e)
    s[e] /= volume_[static_cast<std::size_t>(e)];
  FX_PETSC(VecRestoreArray(scaled_, &s));
  element_to_nodes(scaled_, rhs_);
  solve(rhs_, phi_);
  nodes_to_element(phi_, g);
}

std::string HelmholtzFilter::describe() const {
  std::ostringstream s;
  s << "Helmholtz filter r = " << radius_;
  return s.str();
}

} // namespace flexopt::optimize
