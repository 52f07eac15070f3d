#include "flexopt/reduce/modal.hpp"

#include "flexopt/core/direct_solver.hpp"
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

namespace {

/// The owned DOFs of K's row range that are not in `fixed` (owned global numbers).
IS free_dofs(Mat K, std::vector<PetscInt> fixed) {
  std::sort(fixed.begin(), fixed.end()); // any order, repeats allowed
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(K), &comm));
  PetscInt lo, hi;
  FX_PETSC(MatGetOwnershipRange(K, &lo, &hi));
  std::vector<PetscInt> free;
  free.reserve(static_cast<std::size_t>(hi - lo));
  auto fit = fixed.begin();
  for (PetscInt i = lo; i < hi; ++i) {
    while (fit != fixed.end() && *fit < i) ++fit;
    if (fit != fixed.end() && *fit == i) continue;
    free.push_back(i);
  }
  IS is;
  FX_PETSC(ISCreateGeneral(comm, static_cast<PetscInt>(free.size()), free.data(), PETSC_COPY_VALUES,
                           &is));
  return is;
}

/// `dofs` sorted, without repeats.
std::vector<PetscInt> sorted_unique(std::vector<PetscInt> dofs) {
  std::sort(dofs.begin(), dofs.end());
  dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
  return dofs;
}

/// The random generator from which `eps` draws its start vector.
PetscRandom start_generator(EPS eps) {
  BV bv;
  PetscRandom random;
  FX_PETSC(EPSGetBV(eps, &bv));
  FX_PETSC(BVGetRandomContext(bv, &random));
  return random;
}

/// Krylov-Schur for the `count` eigenvalues of (Kf, Mf) nearest `shift`, shift-and-invert with
/// MUMPS Cholesky, then the -eps_* / -st_* options.
EPS create_eps(Mat Kf, Mat Mf, int count, double shift, double tolerance = 1e-10) {
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(Kf), &comm));
  EPS eps;
  FX_PETSC(EPSCreate(comm, &eps));
  FX_PETSC(EPSSetOperators(eps, Kf, Mf));
  FX_PETSC(EPSSetProblemType(eps, EPS_GHEP));
  FX_PETSC(EPSSetDimensions(eps, count, PETSC_DEFAULT, PETSC_DEFAULT));
  // Relative to the eigenvalue; the residuals come out far below (the Ritz values of the
  // shift-and-invert operator converge quickly at the low end of the spectrum).
  FX_PETSC(EPSSetTolerances(eps, tolerance, 1000));
  FX_PETSC(EPSSetWhichEigenpairs(eps, EPS_TARGET_REAL));
  FX_PETSC(EPSSetTarget(eps, shift));
  // Purification (one more solve per eigenvector) is for a singular B; M restricted to the free
  // DOFs is positive definite.
  FX_PETSC(EPSSetPurify(eps, PETSC_FALSE));
  ST st;
  FX_PETSC(EPSGetST(eps, &st));
  FX_PETSC(STSetType(st, STSINVERT));
  // K - shift M (shift != 0) fits K's pattern: the mass stores a subset of it
  // (fem::assemble_mass leaves out its zero off-component entries), so no new pattern is built.
  FX_PETSC(STSetMatStructure(st, SUBSET_NONZERO_PATTERN));
  KSP ksp;
  FX_PETSC(STGetKSP(st, &ksp));
  // K - shift M is symmetric: Cholesky (LDL^T), about half the work of LU.
  use_mumps(ksp, Factorization::Cholesky);
  FX_PETSC(EPSSetFromOptions(eps));
  return eps;
}

/// The `count` lowest converged eigenpairs of `eps` (ascending), mapped from the free DOFs `is`
/// into full-size vectors of K's layout (zero on the fixed DOFs).
void extract_modes(EPS eps, Mat K, Mat Kf, IS is, int count, ModalResult &result,
                   bool next = false) {
  PetscInt nconv = 0, its = 0;
  FX_PETSC(EPSGetConverged(eps, &nconv));
  FX_PETSC(EPSGetIterationNumber(eps, &its));
  result.iterations = static_cast<int>(its);
  const int needed = count + (next ? 1 : 0);
  if (nconv < needed)
    throw Error("modal analysis: SLEPc converged only " + std::to_string(nconv) + " of " +
                    std::to_string(needed) + " eigenpairs (try -eps_max_it or -eps_ncv)",
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

  if (next)
    result.next_eigenvalue =
        lambda[static_cast<std::size_t>(order[static_cast<std::size_t>(count)])];
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
}

} // namespace

void solve_modes(Mat K, Mat M, const std::vector<PetscInt> &fixed_dofs, int count, double shift,
                 ModalResult &result) {
  IS is = free_dofs(K, fixed_dofs);
  Mat Kf, Mf;
  FX_PETSC(MatCreateSubMatrix(K, is, is, MAT_INITIAL_MATRIX, &Kf));
  FX_PETSC(MatCreateSubMatrix(M, is, is, MAT_INITIAL_MATRIX, &Mf));
  EPS eps = create_eps(Kf, Mf, count, shift);
  FX_PETSC(EPSSolve(eps));
  extract_modes(eps, K, Kf, is, count, result);
  FX_PETSC(EPSDestroy(&eps));
  FX_PETSC(MatDestroy(&Kf));
  FX_PETSC(MatDestroy(&Mf));
  FX_PETSC(ISDestroy(&is));
}

ClampedProblem::ClampedProblem(Mat K, Mat M, const std::vector<PetscInt> &clamped, int modes,
                               const char *prefix, double tolerance, bool next)
    : K_(K), modes_(modes), next_(next && modes > 0), clamped_(sorted_unique(clamped)) {
  FX_PETSC(MatGetSize(K, &rows_, nullptr));
  FX_PETSC(MatGetLocalSize(K, &local_rows_, nullptr));
  free_ = free_dofs(K, clamped_);
  FX_PETSC(MatCreateSubMatrix(K, free_, free_, MAT_INITIAL_MATRIX, &Kf_));
  // The clamped surfaces hold the body: K_ff is positive definite, so MUMPS can factor without
  // pivoting (its SYM = 1 variant).
  FX_PETSC(MatSetOption(Kf_, MAT_SPD, PETSC_TRUE));
  check_factor_memory(Kf_, Factorization::Cholesky, modes_ > 0 ? "st_" : prefix,
                      "the FFRF reduction",
                      "a coarser mesh.size for the FFRF body, or ranks on more nodes");
  if (modes_ > 0) {
    FX_PETSC(MatCreateSubMatrix(M, free_, free_, MAT_INITIAL_MATRIX, &Mf_));
    // Shift 0: the shift-and-invert operator is K_ff^-1 M_ff, and SLEPc factors K_ff itself
    // (no K - sigma M is formed), which the static solves then reuse.
    eps_ = create_eps(Kf_, Mf_, modes_ + (next_ ? 1 : 0), 0.0, tolerance);
    FX_PETSC(EPSSetUp(eps_)); // the factorization
    ST st;
    FX_PETSC(EPSGetST(eps_, &st));
    KSP ksp;
    FX_PETSC(STGetKSP(st, &ksp));
    Mat op = nullptr;
    FX_PETSC(KSPGetOperators(ksp, &op, nullptr));
    // Shared only if the ST really solves with K_ff (options may move the shift or change the
    // transformation).
    if (op == Kf_) {
      FX_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(ksp)));
      ksp_ = ksp;
      shared_ = true;
    }
    FX_PETSC(PetscRandomGetSeed(start_generator(eps_), &seed_));
  }
  if (!ksp_) ksp_ = create_direct_solver(Kf_, Factorization::Cholesky, prefix);
}

bool ClampedProblem::update(Mat K, Mat M, const std::vector<PetscInt> &clamped, int modes,
                            bool next) {
  PetscInt rows, local_rows;
  FX_PETSC(MatGetSize(K, &rows, nullptr));
  FX_PETSC(MatGetLocalSize(K, &local_rows, nullptr));
  // Collective agreement: the clamped DOFs are each rank's owned ones.
  int same = sorted_unique(clamped) == clamped_ && modes == modes_ &&
             (next && modes > 0) == next_ && rows == rows_ && local_rows == local_rows_;
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(Kf_), &comm));
  MPI_Allreduce(MPI_IN_PLACE, &same, 1, MPI_INT, MPI_MIN, comm);
  if (!same) return false;
  K_ = K;
  // The same submatrices with the new values: their nonzero state is unchanged, so the
  // factorization's next set-up is numerical only (PCSetUp: SAME_NONZERO_PATTERN).
  FX_PETSC(MatCreateSubMatrix(K, free_, free_, MAT_REUSE_MATRIX, &Kf_));
  if (Mf_) FX_PETSC(MatCreateSubMatrix(M, free_, free_, MAT_REUSE_MATRIX, &Mf_));
  if (eps_) {
    FX_PETSC(EPSSetOperators(eps_, Kf_, Mf_));
    FX_PETSC(EPSSetUp(eps_)); // the numerical factorization
  }
  if (!shared_) FX_PETSC(KSPSetOperators(ksp_, Kf_, Kf_));
  return true;
}

ClampedProblem::~ClampedProblem() {
  KSPDestroy(&ksp_);
  EPSDestroy(&eps_);
  MatDestroy(&Kf_);
  MatDestroy(&Mf_);
  ISDestroy(&free_);
}

void ClampedProblem::solve(const std::vector<Vec> &b, const std::vector<Vec> &x,
                           const std::string &what, const std::string &hint) {
  const auto n = static_cast<PetscInt>(b.size());
  if (n == 0) return;
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(Kf_), &comm));
  PetscInt nf, Nf, lo;
  FX_PETSC(MatGetLocalSize(Kf_, &nf, nullptr));
  FX_PETSC(MatGetSize(Kf_, &Nf, nullptr));
  FX_PETSC(MatGetOwnershipRange(K_, &lo, nullptr));
  const PetscInt *idx;
  FX_PETSC(ISGetIndices(free_, &idx));
  // All right-hand sides as the columns of one dense matrix: MUMPS then streams its factors
  // once for the whole block instead of once per right-hand side.
  Mat B, X;
  FX_PETSC(MatCreateDense(comm, nf, PETSC_DECIDE, Nf, n, nullptr, &B));
  FX_PETSC(MatCreateDense(comm, nf, PETSC_DECIDE, Nf, n, nullptr, &X));
  {
    PetscScalar *ba;
    PetscInt lda;
    FX_PETSC(MatDenseGetLDA(B, &lda));
    FX_PETSC(MatDenseGetArrayWrite(B, &ba));
    for (PetscInt k = 0; k < n; ++k) {
      const PetscScalar *v;
      FX_PETSC(VecGetArrayRead(b[static_cast<std::size_t>(k)], &v));
      for (PetscInt i = 0; i < nf; ++i) ba[k * lda + i] = v[idx[i] - lo];
      FX_PETSC(VecRestoreArrayRead(b[static_cast<std::size_t>(k)], &v));
    }
    FX_PETSC(MatDenseRestoreArrayWrite(B, &ba));
  }
  const KSPConvergedReason reason = solve_columns(ksp_, B, X);
  if (reason < 0) {
    MatDestroy(&B);
    MatDestroy(&X);
    ISRestoreIndices(free_, &idx);
    throw Error(what + " failed (" + KSPConvergedReasons[reason] + ")" + hint, true);
  }
  {
    const PetscScalar *xa;
    PetscInt lda;
    FX_PETSC(MatDenseGetLDA(X, &lda));
    FX_PETSC(MatDenseGetArrayRead(X, &xa));
    for (PetscInt k = 0; k < n; ++k) {
      // Clamped rows carry b itself (the identity rows of the clamped operator).
      FX_PETSC(VecCopy(b[static_cast<std::size_t>(k)], x[static_cast<std::size_t>(k)]));
      PetscScalar *v;
      FX_PETSC(VecGetArray(x[static_cast<std::size_t>(k)], &v));
      for (PetscInt i = 0; i < nf; ++i) v[idx[i] - lo] = xa[k * lda + i];
      FX_PETSC(VecRestoreArray(x[static_cast<std::size_t>(k)], &v));
    }
    FX_PETSC(MatDenseRestoreArrayRead(X, &xa));
  }
  FX_PETSC(ISRestoreIndices(free_, &idx));
  FX_PETSC(MatDestroy(&B));
  FX_PETSC(MatDestroy(&X));
}

void ClampedProblem::lowest_modes(ModalResult &result) {
  if (!eps_) return;
  PetscRandom random = start_generator(eps_);
  FX_PETSC(PetscRandomSetSeed(random, seed_));
  FX_PETSC(PetscRandomSeed(random));
  FX_PETSC(EPSSolve(eps_));
  extract_modes(eps_, K_, Kf_, free_, modes_, result, next_);
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

} // namespace flexopt::reduce
