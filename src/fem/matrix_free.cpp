#include "flexopt/fem/matrix_free.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"

#include <algorithm>

namespace flexopt::fem {

namespace {

PetscErrorCode shell_multiply(Mat A, Vec x, Vec y) {
  void *ctx = nullptr;
  PetscCall(MatShellGetContext(A, &ctx));
  try {
    static_cast<const MatrixFreeStiffness *>(ctx)->multiply(x, y);
  } catch (const std::exception &e) {
    SETERRQ(PetscObjectComm(reinterpret_cast<PetscObject>(A)), PETSC_ERR_LIB, "%s", e.what());
  }
  return 0;
}

} // namespace

std::unique_ptr<MatrixFreeStiffness>
MatrixFreeStiffness::create(const mesh::DistributedMesh &mesh, const IsotropicMaterial &material) {
  int fits = mesh.type == ElementType::Hex8 ? 1 : 0;
  std::unique_ptr<MatrixFreeStiffness> op(new MatrixFreeStiffness());
  if (fits) {
    UnitStiffness unit(mesh.type, material);
    op->shape_.resize(static_cast<std::size_t>(mesh.local_elements()));
    for (PetscInt e = 0; e < mesh.local_elements() && fits; ++e) {
      const int s = unit.shape(mesh.element_coordinates(e));
      if (s < 0) fits = 0;
      op->shape_[static_cast<std::size_t>(e)] = static_cast<std::uint8_t>(s);
    }
    // UnitStiffness numbers the shapes as it meets them: all below the largest are in use.
    int count = 0;
    for (std::uint8_t k : op->shape_) count = std::max(count, k + 1);
    for (int s = 0; fits && s < count; ++s) op->shapes_.push_back(unit.matrix(s));
  }
  int all = 0;
  MPI_Allreduce(&fits, &all, 1, MPI_INT, MPI_MIN, mesh.comm);
  if (!all) return nullptr;
  op->mesh_ = &mesh;
  op->factor_.assign(op->shape_.size(), 1.0);
  op->xg_ = create_ghosted_vector(mesh);
  FX_PETSC(VecDuplicate(op->xg_, &op->yg_));
  const PetscInt n = 3 * mesh.owned_nodes;
  FX_PETSC(
      MatCreateShell(mesh.comm, n, n, PETSC_DETERMINE, PETSC_DETERMINE, op.get(), &op->shell_));
  FX_PETSC(MatShellSetOperation(op->shell_, MATOP_MULT,
                                reinterpret_cast<void (*)(void)>(shell_multiply)));
  FX_PETSC(MatShellSetOperation(op->shell_, MATOP_MULT_TRANSPOSE,
                                reinterpret_cast<void (*)(void)>(shell_multiply)));
  FX_PETSC(MatSetOption(op->shell_, MAT_SYMMETRIC, PETSC_TRUE));
  FX_PETSC(MatSetOption(op->shell_, MAT_SPD, PETSC_TRUE));
  return op;
}

MatrixFreeStiffness::~MatrixFreeStiffness() {
  MatDestroy(&shell_);
  VecDestroy(&xg_);
  VecDestroy(&yg_);
}

void MatrixFreeStiffness::set(const std::vector<double> &factor, const std::vector<PetscInt> &fixed,
                              double diagonal) {
  if (factor.empty())
    factor_.assign(shape_.size(), 1.0);
  else
    factor_ = factor;
  const PetscInt first = 3 * mesh_->node_start;
  fixed_.resize(fixed.size());
  for (std::size_t k = 0; k < fixed.size(); ++k) fixed_[k] = fixed[k] - first;
  diagonal_ = diagonal;
  // A new state (MatAssemblyEnd increases it): solvers that keep data of the operator redo it.
  FX_PETSC(MatAssemblyBegin(shell_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(shell_, MAT_FINAL_ASSEMBLY));
}

void MatrixFreeStiffness::multiply(Vec x, Vec y) const {
  LogScope log("FxMatrixFreeMult");
  const PetscInt owned = 3 * mesh_->owned_nodes;
  const double *xa = nullptr;
  double *g = nullptr;
  // x with its supported entries zeroed (the zeroed columns), ghost values from their owners.
  FX_PETSC(VecGetArrayRead(x, &xa));
  FX_PETSC(VecGetArray(xg_, &g));
  std::copy(xa, xa + owned, g);
  for (PetscInt i : fixed_) g[i] = 0.0;
  FX_PETSC(VecRestoreArray(xg_, &g));
  FX_PETSC(VecGhostUpdateBegin(xg_, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(xg_, INSERT_VALUES, SCATTER_FORWARD));
  Vec xl = nullptr, yl = nullptr;
  FX_PETSC(VecGhostGetLocalForm(xg_, &xl));
  FX_PETSC(VecGhostGetLocalForm(yg_, &yl));
  FX_PETSC(VecZeroEntries(yl));
  const double *u = nullptr;
  double *v = nullptr;
  FX_PETSC(VecGetArrayRead(xl, &u));
  FX_PETSC(VecGetArray(yl, &v));
  using Vector24 = Eigen::Matrix<double, 24, 1>;
  const PetscInt *conn = mesh_->connectivity.data();
  const PetscInt ne = mesh_->local_elements();
  for (PetscInt e = 0; e < ne; ++e, conn += 8) {
    Vector24 ue;
    for (int a = 0; a < 8; ++a)
      for (int i = 0; i < 3; ++i) ue[3 * a + i] = u[3 * conn[a] + i];
    const Vector24 ye =
        factor_[static_cast<std::size_t>(e)] * (shapes_[shape_[static_cast<std::size_t>(e)]] * ue);
    for (int a = 0; a < 8; ++a)
      for (int i = 0; i < 3; ++i) v[3 * conn[a] + i] += ye[3 * a + i];
  }
  FX_PETSC(VecRestoreArray(yl, &v));
  FX_PETSC(VecRestoreArrayRead(xl, &u));
  FX_PETSC(VecGhostRestoreLocalForm(yg_, &yl));
  FX_PETSC(VecGhostRestoreLocalForm(xg_, &xl));
  // The ghost rows added to their owners; the supported rows are diagonal x.
  FX_PETSC(VecGhostUpdateBegin(yg_, ADD_VALUES, SCATTER_REVERSE));
  FX_PETSC(VecGhostUpdateEnd(yg_, ADD_VALUES, SCATTER_REVERSE));
  const double *ya = nullptr;
  double *out = nullptr;
  FX_PETSC(VecGetArrayRead(yg_, &ya));
  FX_PETSC(VecGetArray(y, &out));
  std::copy(ya, ya + owned, out);
  for (PetscInt i : fixed_) out[i] = diagonal_ * xa[i];
  FX_PETSC(VecRestoreArray(y, &out));
  FX_PETSC(VecRestoreArrayRead(yg_, &ya));
  FX_PETSC(VecRestoreArrayRead(x, &xa));
}

} // namespace flexopt::fem
