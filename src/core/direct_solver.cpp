#include "flexopt/core/direct_solver.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/memory.hpp"

#include <cstdio>
#include <set>
#include <tuple>
#include <vector>

namespace flexopt {

namespace {

void use_mumps_factor(PC pc, Factorization factorization) {
  FX_PETSC(PCSetType(pc, factorization == Factorization::LU ? PCLU : PCCHOLESKY));
  FX_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
}

} // namespace

bool deterministic_solvers() {
  PetscBool on = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_deterministic", &on, nullptr));
  return on == PETSC_TRUE;
}

void use_mumps(KSP ksp, Factorization factorization) {
  FX_PETSC(KSPSetType(ksp, KSPPREONLY));
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  PetscMPIInt size = 1;
  FX_PETSC(MPI_Comm_size(PetscObjectComm(reinterpret_cast<PetscObject>(ksp)), &size));
  if (size == 1 || !deterministic_solvers()) {
    use_mumps_factor(pc, factorization);
    return;
  }
  // Deterministic mode (docs/solvers.md "Reproducibility"): every rank factorizes a gathered
  // copy of the whole operator with sequential MUMPS, whose result does not depend on the
  // arrival order of messages, as the parallel factorization's does.
  FX_PETSC(PCSetType(pc, PCREDUNDANT));
  KSP inner;
  FX_PETSC(PCRedundantGetKSP(pc, &inner));
  FX_PETSC(KSPSetType(inner, KSPPREONLY));
  PC inner_pc;
  FX_PETSC(KSPGetPC(inner, &inner_pc));
  use_mumps_factor(inner_pc, factorization);
}

KSPConvergedReason solve_columns(KSP ksp, Mat B, Mat X) {
  KSPConvergedReason reason = KSP_CONVERGED_ITERATING;
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  PetscBool redundant = PETSC_FALSE;
  FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), PCREDUNDANT, &redundant));
  if (!redundant) {
    FX_PETSC(KSPMatSolve(ksp, B, X));
    FX_PETSC(KSPGetConvergedReason(ksp, &reason));
    return reason;
  }
  // PCREDUNDANT solves a block one column at a time (it has no block apply); its inner solver,
  // one rank's whole copy, is given the gathered block instead, so that sequential MUMPS
  // streams its factors once for all columns, as the parallel MUMPS does in KSPMatSolve.
  FX_PETSC(KSPSetUp(ksp));
  KSP inner;
  FX_PETSC(PCRedundantGetKSP(pc, &inner));
  MPI_Comm comm = PetscObjectComm(reinterpret_cast<PetscObject>(ksp));
  PetscMPIInt size = 1, inner_size = 1;
  FX_PETSC(MPI_Comm_size(comm, &size));
  FX_PETSC(MPI_Comm_size(PetscObjectComm(reinterpret_cast<PetscObject>(inner)), &inner_size));
  if (inner_size != 1) { // a user's -redundant_number: the column-by-column solve
    FX_PETSC(KSPMatSolve(ksp, B, X));
    FX_PETSC(KSPGetConvergedReason(ksp, &reason));
    return reason;
  }
  PetscInt m = 0, N = 0, n = 0, lda = 0;
  FX_PETSC(MatGetLocalSize(B, &m, nullptr));
  FX_PETSC(MatGetSize(B, &N, &n));
  std::vector<PetscMPIInt> counts(static_cast<std::size_t>(size)), offsets(counts.size(), 0);
  const PetscMPIInt mine = static_cast<PetscMPIInt>(m);
  FX_PETSC(MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm));
  for (std::size_t r = 1; r < counts.size(); ++r) offsets[r] = offsets[r - 1] + counts[r - 1];
  Mat Bs, Xs;
  FX_PETSC(MatCreateSeqDense(PETSC_COMM_SELF, N, n, nullptr, &Bs));
  FX_PETSC(MatCreateSeqDense(PETSC_COMM_SELF, N, n, nullptr, &Xs));
  const PetscScalar *b;
  PetscScalar *bs;
  FX_PETSC(MatDenseGetLDA(B, &lda));
  FX_PETSC(MatDenseGetArrayRead(B, &b));
  FX_PETSC(MatDenseGetArrayWrite(Bs, &bs));
  for (PetscInt k = 0; k < n; ++k)
    FX_PETSC(MPI_Allgatherv(b + k * lda, mine, MPIU_SCALAR, bs + k * N, counts.data(),
                            offsets.data(), MPIU_SCALAR, comm));
  FX_PETSC(MatDenseRestoreArrayWrite(Bs, &bs));
  FX_PETSC(MatDenseRestoreArrayRead(B, &b));
  FX_PETSC(KSPMatSolve(inner, Bs, Xs));
  FX_PETSC(KSPGetConvergedReason(inner, &reason));
  const PetscScalar *xs;
  PetscScalar *x;
  PetscInt ldx = 0;
  FX_PETSC(MatDenseGetLDA(X, &ldx));
  FX_PETSC(MatDenseGetArrayRead(Xs, &xs));
  FX_PETSC(MatDenseGetArrayWrite(X, &x));
  PetscMPIInt rank = 0;
  FX_PETSC(MPI_Comm_rank(comm, &rank));
  const PetscInt lo = offsets[static_cast<std::size_t>(rank)];
  for (PetscInt k = 0; k < n; ++k)
    for (PetscInt i = 0; i < m; ++i) x[k * ldx + i] = xs[k * N + lo + i];
  FX_PETSC(MatDenseRestoreArrayWrite(X, &x));
  FX_PETSC(MatDenseRestoreArrayRead(Xs, &xs));
  FX_PETSC(MatDestroy(&Bs));
  FX_PETSC(MatDestroy(&Xs));
  return reason;
}

void check_factor_memory(Mat A, Factorization factorization, const char *prefix,
                         const std::string &what, const std::string &fix) {
  // Once per matrix pattern and process: a design run factorizes the same pattern every
  // iteration, and MUMPS's analysis is a fifth of a factorization (docs/benchmarks.md).
  static std::set<std::tuple<PetscInt, PetscLogDouble, int>> checked;
  MatInfo info;
  FX_PETSC(MatGetInfo(A, MAT_GLOBAL_SUM, &info));
  PetscInt n = 0;
  FX_PETSC(MatGetSize(A, &n, nullptr));
  if (!checked.emplace(n, info.nz_used, static_cast<int>(factorization)).second) return;
  MPI_Comm comm = PetscObjectComm(reinterpret_cast<PetscObject>(A));
  Mat F;
  FX_PETSC(MatGetFactor(A, MATSOLVERMUMPS,
                        factorization == Factorization::LU ? MAT_FACTOR_LU : MAT_FACTOR_CHOLESKY,
                        &F));
  if (prefix) FX_PETSC(MatSetOptionsPrefix(F, prefix)); // the solve's -mat_mumps_icntl_* apply
  MatFactorInfo fi;
  FX_PETSC(MatFactorInfoInitialize(&fi));
  if (factorization == Factorization::LU)
    FX_PETSC(MatLUFactorSymbolic(F, A, nullptr, nullptr, &fi));
  else
    FX_PETSC(MatCholeskyFactorSymbolic(F, A, nullptr, &fi));
  // INFO(15): this process's estimate [MB] of MUMPS's data for an in-core factorization;
  // INFOG(17): its sum over the processes.
  PetscInt mine = 0, total = 0;
  FX_PETSC(MatMumpsGetInfo(F, 15, &mine));
  FX_PETSC(MatMumpsGetInfog(F, 17, &total));
  FX_PETSC(MatDestroy(&F));
  const PetscMPIInt size = comm_size(comm);
  // The deterministic mode's redundant solve: every rank holds a whole sequential factor.
  const bool redundant = size > 1 && deterministic_solvers();
  const long long bytes = 1000000LL * (redundant ? total : mine);
  const NodeMemory need = node_memory(comm, bytes);
  char buf[600];
  std::snprintf(buf, sizeof buf,
                "memory: %s: MUMPS's analysis estimates its factorization of %lld unknowns at "
                "%.3g GB in all%s (%.3g GB on the fullest node, of %.3g GB available there)",
                what.c_str(), static_cast<long long>(n),
                static_cast<double>(redundant ? total * size : total) / 1e3,
                redundant ? ", a whole copy on every rank (-fx_deterministic)" : "",
                static_cast<double>(need.bytes) / 1e9, static_cast<double>(need.available) / 1e9);
  print0(comm, "%s\n", buf);
  if (need.fits(0.8)) return;
  throw Error(std::string(buf + 8) + ", above 80 % of it: " + fix +
                  (redundant ? " (or run without -fx_deterministic)" : ""),
              true);
}

KSP create_direct_solver(Mat A, Factorization factorization, const char *prefix) {
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(A), &comm));
  KSP ksp;
  FX_PETSC(KSPCreate(comm, &ksp));
  if (prefix) FX_PETSC(KSPSetOptionsPrefix(ksp, prefix));
  FX_PETSC(KSPSetOperators(ksp, A, A));
  use_mumps(ksp, factorization);
  FX_PETSC(KSPSetFromOptions(ksp));
  return ksp;
}

} // namespace flexopt
