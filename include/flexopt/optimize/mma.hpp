#pragma once
/// \file The Method of Moving Asymptotes (Svanberg 1987, 2002; "MMA and GCMMA", 2007 notes) for a
/// design vector distributed as a PETSc Vec.
///
/// Problem solved (Svanberg's standard form of the 2007 notes):
///
///   minimize    f0(x) + a0 z + sum_i (c_i y_i + 1/2 d_i y_i^2)
///   subject to  f_i(x) - a_i z - y_i <= 0   (i = 1..m)
///               xmin_j <= x_j <= xmax_j,  y_i >= 0,  z >= 0.
///
/// With the defaults a0 = 1, a_i = 0, c_i = 1000, d_i = 1 the artificial variables y, z vanish
/// at the solution of a feasible problem whose Lagrange multipliers are below c_i, and the
/// method solves "minimize f0 subject to f_i <= 0 and the bounds".
///
/// Every x-dependent operation is local to the rank that owns the component; the ranks combine
/// their parts through MPI_Allreduce of O(m^2) numbers and solve the same small dense
/// (m+1)-systems redundantly (docs/theory-mma.md describes the algorithm as implemented).
#include <memory>
#include <petscvec.h>
#include <vector>

namespace flexopt::optimize {

/// Parameters of the method. The same values must be given on every rank.
struct MmaSettings {
  /// Largest change of x_j in one iteration, as a fraction of (xmax_j - xmin_j); in (0, 1].
  double move_limit = 0.2;
  /// Initial distance of the asymptotes from x, as a fraction of (xmax_j - xmin_j); in (0, 1].
  double asymptote_init = 0.5;
  /// Factor widening (>= 1) / narrowing (in (0, 1]) the asymptote interval when the last two
  /// steps of x_j had the same / the opposite sign.
  double asymptote_increase = 1.2;
  double asymptote_decrease = 0.7;
  /// Smallest barrier parameter of the subproblem's interior-point method (in (0, 1]); the
  /// levels are 1, 0.1, ..., down to the last power of 10 >= subproblem_epsilon (Svanberg:
  /// 1e-7). The KKT conditions of the subproblem are met to about this *absolute* accuracy, so
  /// x_j is accurate to ~ subproblem_epsilon / (curvature of the approximation in x_j): scale
  /// f0 and f_i so that their gradient components are not much below 1, or lower this.
  double subproblem_epsilon = 1e-7;
  /// Weight of z in the objective (> 0).
  double a0 = 1.0;
  /// Per constraint: a_i >= 0, c_i >= 0, d_i >= 0 (d_i + c_i > 0). Empty: a_i = 0, c_i = 1000,
  /// d_i = 1. Otherwise each must have m entries.
  std::vector<double> a, c, d;
};

/// Diagnostics of the last subproblem solve (identical on every rank).
struct MmaSubproblemInfo {
  int newton_iterations = 0;  ///< Newton steps summed over the barrier levels (1 ... 1e-7)
  int line_search_trials = 0; ///< residual evaluations in the line searches, summed
  /// Max-norm of the relaxed KKT residual at the last level (epsilon = subproblem_epsilon),
  /// absolute.
  double kkt_residual_max = 0;
  /// Svanberg's criterion, kkt_residual_max <= 0.9 epsilon at the last level, was met. When false
  /// (Newton-step limit of a level reached) the point is still interior and feasible for the
  /// subproblem and is used as the new iterate, as in Svanberg's reference code.
  bool converged = false;
};

namespace detail {
class MmaSubsolver; // the subproblem and its work arrays (src/optimize/mma.cpp)
}

/// One MMA optimizer: holds the history (x_{k-1}, x_{k-2}, asymptotes) of one design vector.
class Mma {
public:
  /// x_template: layout of the design vector (any distribution; only its layout is used);
  /// m >= 0: number of constraints. Throws a collective flexopt::Error on invalid settings.
  /// Collective on the communicator of x_template.
  static std::unique_ptr<Mma> create(Vec x_template, int m, const MmaSettings &settings);
  ~Mma();
  Mma(const Mma &) = delete;
  Mma &operator=(const Mma &) = delete;

  /// One MMA iteration. x: current design, replaced by the next iterate (which lies in
  /// [xmin, xmax] and within the move limit); xmin, xmax: bounds (xmin_j < xmax_j strictly, x
  /// inside them); f0, df0: objective and its gradient; f[i], df[i]: constraint values (<= 0
  /// when satisfied) and gradients. All Vecs have the layout of x_template; f0 and f must be
  /// the same on every rank (f0 itself is only checked for finiteness: MMA uses its gradient).
  /// Throws a collective flexopt::Error on invalid input (wrong sizes or layouts, bounds,
  /// non-finite values) or if the subproblem solver breaks down (non-finite values); x and the
  /// state are then unchanged. Collective.
  void update(Vec x, Vec xmin, Vec xmax, double f0, Vec df0, const std::vector<double> &f,
              const std::vector<Vec> &df);

  /// Number of completed update() calls (the k of x_k). Not collective.
  int iteration() const { return iteration_; }
  /// Number of constraints m. Not collective.
  int constraints() const { return m_; }
  /// The settings with a, c, d expanded to m entries. Not collective.
  const MmaSettings &settings() const { return settings_; }

  /// The state needed to continue a run: iteration count k, x_{k-1}, x_{k-2} and the asymptotes
  /// L, U of the last iteration (meaningful once k >= 1; the asymptotes are re-initialised in
  /// iterations 1 and 2). Restoring it into a fresh Mma with the same settings and continuing
  /// gives bit-identical iterates.
  struct State {
    int iteration = 0;
    Vec xold1 = nullptr, xold2 = nullptr, low = nullptr, upp = nullptr;
  };
  /// The internal state. The Vecs are owned by this object: read them (VecCopy, VecView), do
  /// not modify or destroy them; they change with the next update(). Not collective.
  State state() const { return State{iteration_, xold1_, xold2_, low_, upp_}; }
  /// Copies a state (from state() of an Mma with the same layout, m and settings, possibly
  /// written to and read back from a file) into this object. With iteration == 0 the Vecs are
  /// not read and may be null. Throws a collective flexopt::Error on a layout mismatch.
  /// Collective.
  void restore(const State &state);

  /// Subproblem solution of the last update(): multipliers lambda_i of the approximated
  /// constraints (they converge to the KKT multipliers of the problem), the artificial
  /// variables y_i and z. Identical on every rank. Not collective.
  const std::vector<double> &multipliers() const { return lam_; }
  const std::vector<double> &y() const { return y_; }
  double z() const { return z_; }
  const MmaSubproblemInfo &last_subproblem() const { return info_; }

private:
  Mma() = default;
  MPI_Comm comm_ = MPI_COMM_NULL;
  int m_ = 0;
  PetscInt n_local_ = 0, n_global_ = 0;
  MmaSettings settings_;
  int iteration_ = 0;
  Vec xold1_ = nullptr, xold2_ = nullptr, low_ = nullptr, upp_ = nullptr;
  std::unique_ptr<detail::MmaSubsolver> sub_; // allocated once: (19 + 3m) doubles per local x_j
  std::vector<double> lam_, y_;
  double z_ = 0;
  MmaSubproblemInfo info_;
};

/// max_j |a_j - b_j| over all ranks (+infinity if any difference is NaN); a and b have the same
/// layout. Collective.
double max_abs_change(Vec a, Vec b);

} // namespace flexopt::optimize
