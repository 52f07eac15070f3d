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

} // namespace flexopt
