#pragma once
/// \file Natural frequencies and mode shapes: K phi = omega^2 M phi with SLEPc.
#include <Eigen/Dense>
#include <limits>
#include <petscksp.h>
#include <petscmat.h>
#include <slepceps.h>
#include <string>
#include <vector>

namespace flexopt::reduce {

struct ModalResult {
  std::vector<double> eigenvalues; ///< omega^2 [rad^2/s^2], ascending (signed: round-off
                                   ///< may make rigid-body values slightly negative)
  std::vector<Vec> modes;          ///< full-size mode shapes (zero on fixed DOFs), M-orthonormal
  int iterations = 0;              ///< Krylov-Schur restarts
  /// The eigenvalue after the last one returned, if it was asked for (else NaN).
  double next_eigenvalue = std::numeric_limits<double>::quiet_NaN();
  ~ModalResult();
  ModalResult() = default;
  ModalResult(const ModalResult &) = delete;
  ModalResult &operator=(const ModalResult &) = delete;
};

/// Lowest `count` eigenpairs of the generalized symmetric problem on the free DOFs (the
/// complement of `fixed_dofs`, owned global DOF numbers). Shift-and-invert about `shift`
/// [rad^2/s^2] with a direct factorization (MUMPS Cholesky by default; options prefix none, so
/// -eps_*, -st_* and -st_pc_* options apply). A negative shift keeps K - shift M
/// non-singular for free bodies. M's stored nonzero pattern must lie within K's (as from
/// fem::assemble_stiffness_and_mass). Collective.
void solve_modes(Mat K, Mat M, const std::vector<PetscInt> &fixed_dofs, int count, double shift,
                 ModalResult &result);

/// The fixed-interface problem of a body: its stiffness K and mass M restricted to the free DOFs
/// (the complement of `clamped`, owned global DOF numbers), K_ff symmetric positive definite.
/// ONE MUMPS Cholesky factorization of K_ff serves both the static solves (solve) and the SLEPc
/// shift-and-invert about 0 for the lowest `modes` eigenpairs (modes): the factorization is the
/// dominant cost of a Craig-Bampton reduction. The eigensolver takes the -eps_* and -st_*
/// options as solve_modes does; if they move the shift off 0 (or change the spectral
/// transformation) the static solves get their own factorization (options prefix `prefix`).
/// With `modes` = 0 it is just the factorization of K_ff for solve (no M_ff, no eigensolver).
/// K_ff must be positive definite: the clamped DOFs hold the body. Collective.
class ClampedProblem {
public:
  /// `tolerance`: SLEPc's relative tolerance (the -eps_tol option still overrides it);
  /// `next`: also converge the eigenpair after the `modes` lowest (ModalResult::next_eigenvalue).
  ClampedProblem(Mat K, Mat M, const std::vector<PetscInt> &clamped, int modes, const char *prefix,
                 double tolerance = 1e-10, bool next = false);
  ~ClampedProblem();
  ClampedProblem(const ClampedProblem &) = delete;
  ClampedProblem &operator=(const ClampedProblem &) = delete;
  /// For every full-size right-hand side b[k]: x[k] = b[k] on the clamped DOFs and
  /// K_ff x_f = b_f on the free ones, i.e. the solve with K whose clamped rows and columns are
  /// replaced by the identity. All right-hand sides in one block solve (MUMPS reads its
  /// factors once for the block). Throws a collective flexopt::Error
  /// "<what> failed (<reason>)<hint>" if the solve fails.
  void solve(const std::vector<Vec> &b, const std::vector<Vec> &x, const std::string &what,
             const std::string &hint = "");
  /// The lowest `modes` eigenpairs K phi = omega^2 M phi with phi = 0 on the clamped DOFs
  /// (full-size, M-orthonormal), ascending. Every call starts the eigensolver from the same
  /// random vector as the first (results do not depend on earlier calls).
  void lowest_modes(ModalResult &result);
  /// The same problem for new values of K and M on the same mesh (the same layout and nonzero
  /// pattern: a design's stiffness and mass), if `clamped`, `modes` and `next` are this
  /// problem's: the submatrices take the new values and the factorization is redone numerically,
  /// on the ordering and symbolic analysis made once (docs/theory.md section 10). Returns false,
  /// changing nothing, if the problem differs. K and M must outlive the use of this problem.
  /// Collective.
  bool update(Mat K, Mat M, const std::vector<PetscInt> &clamped, int modes, bool next);

private:
  IS free_ = nullptr;
  Mat K_ = nullptr, Kf_ = nullptr, Mf_ = nullptr;
  EPS eps_ = nullptr;
  KSP ksp_ = nullptr;   ///< the factorization of K_ff used by solve (the EPS's when shared)
  bool shared_ = false; ///< ksp_ is the EPS's
  int modes_ = 0;
  bool next_ = false;
  std::vector<PetscInt> clamped_; ///< sorted, without repeats
  PetscInt rows_ = 0, local_rows_ = 0;
  unsigned long seed_ = 0; ///< the eigensolver's random start (its seed when first set up)
};

/// The reduced matrix V^T A V of the full-size `vectors` V (symmetrized; every rank gets the same
/// numbers from VecMDot). Collective.
Eigen::MatrixXd project(Mat A, const std::vector<Vec> &vectors);

/// Frequency in Hz of an eigenvalue omega^2: sign(omega^2) sqrt(|omega^2|) / (2 pi).
double frequency_hz(double eigenvalue);

} // namespace flexopt::reduce
