#include "flexopt/reduce/modal.hpp"

#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <slepceps.h>

namespace flexopt::reduce {

ModalResult::~ModalResult() {
  for (Vec &v : modes) VecDestroy(&v);
}

double frequency_hz(double eigenvalue) {
  return std::copysign(std::sqrt(std::abs(eigenvalue)), eigenvalue) / (2.0 * M_PI);
}

void use_mumps_lu(KSP ksp) {
  FX_PETSC(KSPSetType(ksp, KSPPREONLY));
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  FX_PETSC(PCSetType(pc, PCLU));
  FX_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
}

void solve_modes(Mat K, Mat M, const std::vector<PetscInt> &fixed_dofs, int count, double shift,
                 ModalResult &result) {
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(K), &comm));
  PetscInt lo, hi;
  FX_PETSC(MatGetOwnershipRange(K, &lo, &hi));
  std::vector<PetscInt> free;
  free.reserve(static_cast<std::size_t>(hi - lo));
  auto fit = fixed_dofs.begin();
  for (PetscInt i = lo; i < hi; ++i) {
    while (fit != fixed_dofs.end() && *fit < i) ++fit;
    if (fit != fixed_dofs.end() && *fit == i) continue;
    free.push_back(i);
  }
  IS is;
  FX_PETSC(ISCreateGeneral(comm, static_cast<PetscInt>(free.size()), free.data(), PETSC_COPY_VALUES,
                           &is));
  Mat Kf, Mf;
  FX_PETSC(MatCreateSubMatrix(K, is, is, MAT_INITIAL_MATRIX, &Kf));
  FX_PETSC(MatCreateSubMatrix(M, is, is, MAT_INITIAL_MATRIX, &Mf));

  EPS eps;
  FX_PETSC(EPSCreate(comm, &eps));
  FX_PETSC(EPSSetOperators(eps, Kf, Mf));
  FX_PETSC(EPSSetProblemType(eps, EPS_GHEP));
  FX_PETSC(EPSSetDimensions(eps, count, PETSC_DEFAULT, PETSC_DEFAULT));
  FX_PETSC(EPSSetTolerances(eps, 1e-10, 1000));
  FX_PETSC(EPSSetWhichEigenpairs(eps, EPS_TARGET_REAL));
  FX_PETSC(EPSSetTarget(eps, shift));
  ST st;
  FX_PETSC(EPSGetST(eps, &st));
  FX_PETSC(STSetType(st, STSINVERT));
  KSP ksp;
  FX_PETSC(STGetKSP(st, &ksp));
  use_mumps_lu(ksp);
  FX_PETSC(EPSSetFromOptions(eps));
  FX_PETSC(EPSSolve(eps));

  PetscInt nconv = 0, its = 0;
  FX_PETSC(EPSGetConverged(eps, &nconv));
  FX_PETSC(EPSGetIterationNumber(eps, &its));
  result.iterations = static_cast<int>(its);
  if (nconv < count)
    throw Error("modal analysis: SLEPc converged only " + std::to_string(nconv) + " of " +
                    std::to_string(count) + " eigenpairs (try -eps_max_it or -eps_ncv)",
                true);

  std::vector<double> lambda(static_cast<std::size_t>(nconv));
  for (PetscInt i = 0; i < nconv; ++i) {
    PetscScalar kr, ki;
    FX_PETSC(EPSGetEigenvalue(eps, i, &kr, &ki));
    lambda[static_cast<std::size_t>(i)] = PetscRealPart(kr);
  }
  std::vector<PetscInt> order(static_cast<std::size_t>(nconv));
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](PetscInt a, PetscInt b) {
    return lambda[static_cast<std::size_t>(a)] < lambda[static_cast<std::size_t>(b)];
  });

  Vec xf;
  FX_PETSC(MatCreateVecs(Kf, &xf, nullptr));
  for (int k = 0; k < count; ++k) {
    const PetscInt i = order[static_cast<std::size_t>(k)];
    result.eigenvalues.push_back(lambda[static_cast<std::size_t>(i)]);
    FX_PETSC(EPSGetEigenvector(eps, i, xf, nullptr));
    Vec full;
    FX_PETSC(MatCreateVecs(K, &full, nullptr));
    FX_PETSC(VecZeroEntries(full));
    FX_PETSC(VecISCopy(full, is, SCATTER_FORWARD, xf));
    result.modes.push_back(full);
  }
  FX_PETSC(VecDestroy(&xf));
  FX_PETSC(EPSDestroy(&eps));
  FX_PETSC(MatDestroy(&Kf));
  FX_PETSC(MatDestroy(&Mf));
  FX_PETSC(ISDestroy(&is));
}

Eigen::MatrixXd project(Mat A, const std::vector<Vec> &vectors) {
  const int n = static_cast<int>(vectors.size());
  Eigen::MatrixXd out(n, n);
  if (n == 0) return out;
  Vec w;
  FX_PETSC(VecDuplicate(vectors.front(), &w));
  std::vector<PetscScalar> dots(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) {
    FX_PETSC(MatMult(A, vectors[static_cast<std::size_t>(j)], w));
    FX_PETSC(VecMDot(w, n, vectors.data(), dots.data()));
    for (int i = 0; i < n; ++i) out(i, j) = dots[static_cast<std::size_t>(i)];
  }
  FX_PETSC(VecDestroy(&w));
  return 0.5 * (out + out.transpose());
}

ClampedSolver::ClampedSolver(MPI_Comm comm, Mat K, const std::vector<PetscInt> &clamped,
                             const char *prefix) {
  FX_PETSC(MatDuplicate(K, MAT_COPY_VALUES, &Kc_));
  FX_PETSC(MatZeroRowsColumns(Kc_, static_cast<PetscInt>(clamped.size()), clamped.data(), 1.0,
                              nullptr, nullptr));
  FX_PETSC(KSPCreate(comm, &ksp_));
  FX_PETSC(KSPSetOptionsPrefix(ksp_, prefix));
  FX_PETSC(KSPSetOperators(ksp_, Kc_, Kc_));
  use_mumps_lu(ksp_);
  FX_PETSC(KSPSetFromOptions(ksp_));
}

ClampedSolver::~ClampedSolver() {
  KSPDestroy(&ksp_);
  MatDestroy(&Kc_);
}

void ClampedSolver::solve(Vec b, Vec x, const std::string &what, const std::string &hint) const {
  FX_PETSC(KSPSolve(ksp_, b, x));
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(ksp_, &reason));
  if (reason < 0) throw Error(what + " failed (" + KSPConvergedReasons[reason] + ")" + hint, true);
}

} // namespace flexopt::reduce
