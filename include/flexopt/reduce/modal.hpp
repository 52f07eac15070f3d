#pragma once
/// \file Natural frequencies and mode shapes: K phi = omega^2 M phi with SLEPc.
#include <Eigen/Dense>
#include <petscksp.h>
#include <petscmat.h>
#include <string>
#include <vector>

namespace flexopt::reduce {

struct ModalResult {
  std::vector<double> eigenvalues; ///< omega^2 [rad^2/s^2], ascending (signed: round-off
                                   ///< may make rigid-body values slightly negative)
  std::vector<Vec> modes;          ///< full-size mode shapes (zero on fixed DOFs), M-orthonormal
  int iterations = 0;              ///< Krylov-Schur restarts
  ~ModalResult();
  ModalResult() = default;
  ModalResult(const ModalResult &) = delete;
  ModalResult &operator=(const ModalResult &) = delete;
};

/// Lowest `count` eigenpairs of the generalized symmetric problem on the free DOFs (the
/// complement of `fixed_dofs`, owned global DOF numbers). Shift-and-invert about `shift`
/// [rad^2/s^2] with a direct factorization (MUMPS by default; options prefix none, so
/// -eps_*, -st_* and -st_pc_* options apply). A negative shift keeps K - shift M
/// non-singular for free bodies. Collective.
void solve_modes(Mat K, Mat M, const std::vector<PetscInt> &fixed_dofs, int count, double shift,
                 ModalResult &result);

/// Makes `ksp` a direct solve: preonly + LU with MUMPS (options still override). Not collective.
void use_mumps_lu(KSP ksp);

/// A direct solver of K with the DOFs `clamped` (owned global numbers) held fixed: K_c is K with
/// those rows and columns replaced by the identity, factored once by MUMPS LU (options prefix
/// `prefix`). Used for the static modes of the Craig-Bampton basis and the centrifugal load
/// cases of the geometric stiffness. Collective.
class ClampedSolver {
public:
  ClampedSolver(MPI_Comm comm, Mat K, const std::vector<PetscInt> &clamped, const char *prefix);
  ~ClampedSolver();
  ClampedSolver(const ClampedSolver &) = delete;
  ClampedSolver &operator=(const ClampedSolver &) = delete;
  /// Solves K_c x = b; throws a collective flexopt::Error "<what> failed (<reason>)<hint>" if
  /// the solve does not converge.
  void solve(Vec b, Vec x, const std::string &what, const std::string &hint = "") const;

private:
  Mat Kc_ = nullptr;
  KSP ksp_ = nullptr;
};

/// The reduced matrix V^T A V of the full-size `vectors` V (symmetrized; every rank gets the same
/// numbers from VecMDot). Collective.
Eigen::MatrixXd project(Mat A, const std::vector<Vec> &vectors);

/// Frequency in Hz of an eigenvalue omega^2: sign(omega^2) sqrt(|omega^2|) / (2 pi).
double frequency_hz(double eigenvalue);

} // namespace flexopt::reduce
