#pragma once
/// \file Generalized-alpha time integration of the index-3 DAE
///   M(q) q'' + Q_v(q, q') - Q_ext(q, t) + Phi_q^T lambda = 0,   Phi(q, t) = 0
/// after Arnold & Brüls (2007), with consistent initial conditions and Newton's method on the
/// exact iteration matrix, whose factorization is kept across iterations and steps while the
/// iterations contract fast enough (simplified Newton; docs/theory.md section 6.4).
#include "flexopt/dynamics/consistent_start.hpp"
#include "flexopt/dynamics/mechanism.hpp"

#include <memory>
#include <petscmat.h>
#include <string>
#include <vector>

namespace flexopt::dynamics {

namespace detail {
struct SparseIteration; ///< the sparse iteration matrix and its index maps (generalized_alpha.cpp)
struct NewtonWork; ///< work vectors, the dense iteration matrix and its LU (generalized_alpha.cpp)
} // namespace detail

/// Chung & Hulbert (1993) parameters from the spectral radius at infinity rho_inf in [0, 1]:
/// alpha_m = (2 rho - 1)/(rho + 1), alpha_f = rho/(rho + 1), gamma = 1/2 + alpha_f - alpha_m,
/// beta = (gamma + 1/2)^2 / 4. Second order; rho_inf = 1 conserves energy for linear systems.
/// How the step's unknowns move along a Newton update dq at a fixed step start (section 6.4):
/// acc += bp dq, v += gp dq, a += ap dq with bp = beta' = (1 - alpha_m) / (beta h^2 (1 -
/// alpha_f)), gp = gamma' = gamma / (beta h), ap = (1 - alpha_f) / (1 - alpha_m) beta'.
struct NewtonScaling {
  double bp = 0, gp = 0, ap = 0;
};

struct AlphaParameters {
  double rho_inf = 0.8, alpha_m = 0, alpha_f = 0, gamma = 0.5, beta = 0.25;
  static AlphaParameters from_rho_inf(double rho_inf);
  NewtonScaling newton_scaling(double h) const;
};

/// The state of one step, s_n = (q, v, a, acc, lambda): coordinates, velocities, the
/// algorithmic acceleration a, the true acceleration acc = q'' and the multipliers.
struct State {
  double t = 0;
  Vector q, v, a, acc, lambda;
  /// [q, v, a, acc, lambda] as one vector (size 4n + m) and back.
  Vector pack() const;
  void unpack(const Vector &s, int n, int m);
};

struct NewtonSettings {
  int max_iterations = 12; ///< per attempt (and again after dropping a stale matrix)
  /// On max|dq| / (1 + max|q|) after an iteration on the matrix of its own iterate (Newton
  /// proper, which then leaves about tolerance^2): accepted when the increment, or the
  /// remaining distance predicted from the contraction theta = inc_k / inc_(k-1) < 1,
  /// theta / (1 - theta) inc_k, is at most this.
  double tolerance = 1e-12;
  /// The same test for an iteration on a kept matrix (from an earlier iterate or step), which
  /// converges only linearly: it must get this close (a few units of round-off in 1 + max|q|)
  /// to leave the solution as accurate as Newton's.
  double kept_tolerance = 1e-15;
  int max_halvings = 6; ///< step halvings before giving up
  /// Newton systems with more unknowns (n + m) than this use the sparse LU on the block
  /// pattern, smaller ones a dense LU.
  int dense_limit = 96;
  /// The factorized iteration matrix is kept across iterations and steps of the same size
  /// while the observed contraction theta stays at or below this; a larger theta assembles and
  /// factorizes it anew at the current iterate. 0: a new matrix every iteration (Newton).
  double reuse_contraction = 0.1;
  /// ACF bodies: a kept matrix is applied turned by each body's rotation since it was
  /// assembled (docs/theory.md section 8.2).
  bool corotate_kept = true;
};

/// What the consistent start did to the given velocities (docs/theory.md section 6.4): the
/// kinetic energy of the placed velocities (after the position projection) and after the
/// correction, and whether the joints needed a change of elastic velocities too.
struct StartReport {
  double kinetic_given = 0, kinetic = 0;
  /// The rigid-body velocity correction left Phi_q v + Phi_t at `rigid_residual`, above the
  /// tolerance: a mass-weighted correction of all velocities followed.
  bool elastic_corrected = false;
  double rigid_residual = 0;
  /// max |Phi_q v + Phi_t| of the given velocities (after the position projection).
  double given_violation = 0;
};

/// What the consistent start did to the velocities, for its adjoint (docs/theory.md section
/// 9.2): the rigid-body correction, and the elastic fallback's change dv of all velocities
/// (empty if the rigid-body correction sufficed).
struct StartTrace {
  VelocityCorrection rigid;
  Vector fallback;
  /// The positions: the placed coordinates, the multipliers of the smallest change
  /// (q0 - q_given + Phi_q^T mu = 0; zero if the placement satisfied the joints) and whether
  /// the closest point was reached (false: the Gauss-Newton point was kept).
  Vector given, multipliers;
  bool closest = true;
};

/// What one step did, for progress output and failure messages.
struct StepInfo {
  int iterations = 0;     ///< Newton iterations (all attempts)
  int factorizations = 0; ///< iteration matrices assembled and factorized (all attempts)
  int halvings = 0;       ///< deepest halving used
  bool converged = false;
  std::vector<double> increment, violation; ///< per iteration of the last attempt
};

/// The message of a step whose Newton iterations failed after every halving: the step, its
/// times, the last attempt's increments and constraint residuals, and what to try.
std::string newton_failure_message(long long step, double t0, double t1, const StepInfo &info,
                                   int max_halvings);

class GeneralizedAlpha {
public:
  GeneralizedAlpha(const Mechanism &mechanism, AlphaParameters parameters,
                   NewtonSettings settings = {});
  ~GeneralizedAlpha();

  const AlphaParameters &parameters() const { return par_; }

  /// The consistent state at t0 from placed coordinates q0 and velocities v0: q projected
  /// onto Phi(q, t0) = 0 (smallest change); the rigid-body velocities corrected onto
  /// Phi_q v + Phi_t = 0 with the least change of kinetic energy, the elastic ones kept
  /// (rigid_velocity_correction; should the joints need elastic velocities, a mass-weighted
  /// correction of all velocities follows); then acc and lambda from the acceleration-level
  /// equations, a = acc. What the correction did goes into `report` and `trace` (if non-null).
  /// Throws a collective flexopt::Error naming the violated rows when the projection fails or
  /// leaves a redundant row violated.
  State initial_state(const Vector &q0, const Vector &v0, double t0, StartReport *report = nullptr,
                      StartTrace *trace = nullptr) const;

  /// Advances s by h to `next`, halving the step (recursively, up to max_halvings) when Newton
  /// fails. Returns false (and fills `info`) if even the smallest substep fails. If the step
  /// was halved and `substeps` is non-null, each substep's end state and size are appended to
  /// it (the adjoint runs over them; docs/theory.md section 9.3).
  bool advance(const State &s, double h, State &next, StepInfo &info,
               std::vector<std::pair<State, double>> *substeps = nullptr) const;

  /// One step of size h without halving. Returns false if Newton did not converge.
  bool step(const State &s, double h, State &next, StepInfo &info) const;

  /// The step residual R(s_{n+1}, s_n) (size 4n + m), the single definition of the scheme:
  ///   R_q = q1 - q0 - h v0 - h^2 (1/2 - beta) a0 - h^2 beta a1
  ///   R_v = v1 - v0 - h (1 - gamma) a0 - h gamma a1
  ///   R_a = (1 - alpha_m) a1 + alpha_m a0 - (1 - alpha_f) acc1 - alpha_f acc0
  ///   R_d = M(q1) acc1 + Q_v(q1, v1) - Q_ext(q1, t1) + Phi_q(q1)^T lambda1
  ///   R_c = Phi(q1, t1)
  /// and its exact Jacobians with respect to s_{n+1} and s_n (each may be null).
  void residual(const State &next, const State &prev, double h, Vector &R, Matrix *dR_dnext,
                Matrix *dR_dprev) const;
  /// The blocks of dR/ds_{n+1} that are not multiples of the identity: dR_d/dq = K (with the
  /// constraint Hessian contracted with lambda), dR_d/dv = C, dR_d/dacc = M, and Phi_q = J (the
  /// transposed Newton matrix of the adjoint, docs/theory.md section 9).
  void jacobian_blocks(const State &next, Matrix &K, Matrix &C, Matrix &M, Matrix &J) const;
  const Mechanism &mechanism() const { return mech_; }

private:
  bool step_once(const State &s, double h, State &next, StepInfo &info) const;
  /// Assembles the scaled iteration matrix at `next` (dense up to settings.dense_limit
  /// unknowns, otherwise block by block into the sparse LU's values, whose ordering is
  /// computed once), factorizes it and fills the right-hand side rhs = -[R_d / beta'; Phi] and
  /// phi = Phi(next.q). False if the matrix is singular.
  bool factorize(const State &next, double bp, double gp) const;
  /// The right-hand side and phi alone (no derivatives), for an iteration on a kept matrix.
  void newton_rhs(const State &next, double bp) const;
  /// x = A^-1 rhs with the current factorization; false if not finite.
  bool solve() const;

  const Mechanism &mech_;
  AlphaParameters par_;
  NewtonSettings settings_;
  std::unique_ptr<detail::SparseIteration> sparse_; ///< null: dense Newton systems
  /// Work vectors and the factorized matrix, kept across iterations and steps (step() is
  /// const: the integrator's state is its argument; this is a cache of the last matrix).
  std::unique_ptr<detail::NewtonWork> work_;
};

/// The scaled Newton matrix of docs/theory.md section 6.4 of `mech` at the iterate `next`,
/// added into the PETSc matrix A (coordinate k at row and column coord0 + k, enforced constraint
/// row k at row0 + k; ADD_VALUES, no assembly), and rhs = -[(R_d + Phi_q^T lambda) / beta';
/// Phi]: the small part of the distributed backend (section 8.2). Not collective: one rank
/// adds.
void add_newton_system(const Mechanism &mech, const State &next, double bp, double gp, Mat A,
                       PetscInt coord0, PetscInt row0, Vector &rhs);
/// The matrix [M Phi_q^T; Phi_q 0] of `mech` at s (offsets and target as add_newton_system):
/// the consistent initial accelerations and the mass-weighted velocity projection of the
/// distributed backend. Not collective.
void add_mass_system(const Mechanism &mech, const State &s, Mat A, PetscInt coord0, PetscInt row0);
/// The right-hand side of add_newton_system alone (no derivatives): for iterations on a kept
/// matrix. Not collective.
void newton_system_rhs(const Mechanism &mech, const State &next, double bp, Vector &rhs);

} // namespace flexopt::dynamics
