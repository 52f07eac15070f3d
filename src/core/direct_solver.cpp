#include "flexopt/core/direct_solver.hpp"

#include "flexopt/core/error.hpp"

namespace flexopt {

void use_mumps(KSP ksp, Factorization factorization) {
  FX_PETSC(KSPSetType(ksp, KSPPREONLY));
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  FX_PETSC(PCSetType(pc, factorization == Factorization::LU ? PCLU : PCCHOLESKY));
  FX_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
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
