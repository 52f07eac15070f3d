#pragma once
/// \file Direct solves with MUMPS through a PETSc KSP.
#include <petscksp.h>

namespace flexopt {

enum class Factorization { LU, Cholesky };

/// Makes `ksp` a direct solve: preonly + MUMPS LU, or MUMPS Cholesky (LDL^T) for a symmetric
/// operator (about half the flops and memory of LU; MUMPS takes its positive definite variant
/// if the operator carries MAT_SPD). Options set afterwards (KSPSetFromOptions) still override.
/// Not collective.
void use_mumps(KSP ksp, Factorization factorization);

/// A new direct solver of A on A's communicator: use_mumps, then the options with `prefix`
/// (null: none). The caller destroys it. Collective.
KSP create_direct_solver(Mat A, Factorization factorization, const char *prefix);

} // namespace flexopt
