#pragma once
/// \file Direct solves with MUMPS through a PETSc KSP.
#include <petscksp.h>
#include <string>

namespace flexopt {

enum class Factorization { LU, Cholesky };

/// Makes `ksp` a direct solve: preonly + MUMPS LU, or MUMPS Cholesky (LDL^T) for a symmetric
/// operator (about half the flops and memory of LU; MUMPS takes its positive definite variant
/// if the operator carries MAT_SPD). Options set afterwards (KSPSetFromOptions) still override.
/// With the option `-fx_deterministic` on more than one rank: a redundant solve instead, each
/// rank factorizing the whole operator with sequential MUMPS, so that two runs give the same
/// bits (docs/solvers.md "Reproducibility"). Not collective.
void use_mumps(KSP ksp, Factorization factorization);

/// Whether the option `-fx_deterministic` (command line or the case's `solver:`) asks for direct
/// solves whose results do not vary from run to run. Not collective.
bool deterministic_solvers();

/// X = A^{-1} B for the dense block B (columns: right-hand sides) with the direct solver `ksp`
/// (KSPMatSolve, one pass over the factors for the whole block; in the deterministic mode the
/// block is gathered and solved by each rank's whole copy). Returns the solve's converged
/// reason (negative: failed). Collective.
KSPConvergedReason solve_columns(KSP ksp, Mat B, Mat X);

/// MUMPS's estimate, from its analysis of A's pattern, of the memory its factorization will take
/// (INFO(15) per rank; with -fx_deterministic on more than one rank, the whole factor on every
/// rank): printed, and refused with `what` and `fix` in the message when a node's share exceeds
/// 80 % of the memory it reports available (core/memory.hpp). Runs once per pattern (size,
/// nonzeros, factorization) and process. Collective.
void check_factor_memory(Mat A, Factorization factorization, const char *prefix,
                         const std::string &what, const std::string &fix);

/// A new direct solver of A on A's communicator: use_mumps, then the options with `prefix`
/// (null: none). The caller destroys it. Collective.
KSP create_direct_solver(Mat A, Factorization factorization, const char *prefix);

} // namespace flexopt
