#pragma once
/// \file Generalized-alpha time integration on the distributed backend (docs/theory.md sections
/// 6.4 and 8.2): a mechanism of ACF bodies, whose node positions are distributed over the
/// ranks, and a small part (rigid, FFRF and interface-node bodies with their joints, drivers and
/// loads: a dynamics::Mechanism evaluated on rank 0) whose coordinates and multipliers rank 0
/// owns. The interfaces of the ACF bodies are tied to interface-node bodies of the small part
/// (RBE2 ties, dynamics/ties.hpp). One PETSc vector layout holds every unknown; the Newton
/// matrix is one PETSc Mat over all ranks, solved by a KSP (a direct MUMPS LU by default,
/// options prefix `mech_`); the Newton iteration, its kept matrix and the step halving are those
/// of GeneralizedAlpha (detail::newton_loop).
///
/// Layout on rank r: the coordinates of its owned nodes of ACF body 0, body 1, ..., then (rank 0)
/// the small part's coordinates; then the multipliers of the ties of its owned tied nodes, then
/// (rank 0) the small part's enforced constraint rows. All state vectors have this layout: q, v,
/// a, acc are zero on the multiplier entries, lambda on the coordinate entries.
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/dynamics/consistent_start.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/ties.hpp"
#include "flexopt/fem/probe.hpp"

#include <functional>
#include <memory>
#include <petscksp.h>
#include <string>
#include <vector>

namespace flexopt::dynamics {

/// The state of a step: t and the PETSc vectors q, v, a, acc and lambda (the integrator's
/// layout). Copies are deep (new vectors with the same values).
struct DistState {
  double t = 0;
  Vec q = nullptr, v = nullptr, a = nullptr, acc = nullptr, lambda = nullptr;
  DistState() = default;
  DistState(const DistState &o);
  DistState &operator=(const DistState &o);
  ~DistState();
};

/// An interface of an ACF body: the owned nodes of its surface are tied rigidly to the
/// interface-node body `node_body` of the small mechanism (whose reference point is c_I).
struct AcfInterface {
  std::size_t body = 0;   ///< the ACF body
  std::string surface;    ///< its physical surface
  int node_body = 0;      ///< the interface node: a body of the small mechanism (7 coordinates)
  Vec3 centroid{0, 0, 0}; ///< c_I (mesh coordinates)
  std::string where = ""; ///< for messages (the case key)
};

namespace detail {
struct AcfLayout; ///< the DOF numbers of every body's local nodes, the ties, the scatters
}

/// What the consistent start of DistributedAlpha did to the velocities, for its adjoint
/// (docs/theory.md section 9.2): the rigid-body correction over the small part's frames and the
/// ACF bodies' rigid velocity fields, and the elastic fallback's change dv of all velocities
/// (null if the rigid-body correction sufficed). Owns dv.
struct DistStartTrace {
  VelocityCorrection rigid;
  std::vector<RigidField> fields; ///< per ACF body
  Vec fallback = nullptr;
  DistStartTrace() = default;
  DistStartTrace(const DistStartTrace &) = delete;
  DistStartTrace &operator=(const DistStartTrace &) = delete;
  ~DistStartTrace() { VecDestroy(&fallback); }
};

class DistributedAlpha {
public:
  /// ACF bodies (sharing one communicator), the small mechanism (finalized, identical on every
  /// rank; null or without bodies for free ACF bodies) and the interfaces tying them; gravity
  /// acts on the ACF bodies (the small mechanism has its own). All must outlive the integrator.
  /// Collective; throws a collective flexopt::Error for a missing surface or two interfaces of a
  /// body sharing a node.
  DistributedAlpha(std::vector<const bodies::AcfBody *> bodies, const Mechanism *small,
                   std::vector<AcfInterface> interfaces, const Eigen::Vector3d &gravity,
                   AlphaParameters parameters, NewtonSettings settings = {});
  /// Free ACF bodies under gravity (no small part).
  DistributedAlpha(std::vector<const bodies::AcfBody *> bodies, const Eigen::Vector3d &gravity,
                   AlphaParameters parameters, NewtonSettings settings = {});
  ~DistributedAlpha();
  DistributedAlpha(const DistributedAlpha &) = delete;
  DistributedAlpha &operator=(const DistributedAlpha &) = delete;

  const AlphaParameters &parameters() const { return par_; }
  /// A zero vector of the integrator's layout; the caller destroys it. Collective.
  Vec create_vector() const;
  /// A state of zero vectors of this layout (t = 0). Collective.
  DistState zero_state() const;
  /// Sets field(X) at the owned nodes of ACF body b (X: reference position) in v. Not
  /// collective.
  void set_nodal(Vec v, std::size_t body,
                 const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &field) const;
  /// Sets the small part's coordinate entries of v (rank 0 writes; the values must be the same
  /// on every rank). Not collective.
  void set_small(Vec v, const Vector &values) const;
  /// The small part's state (q, v, a, acc, lambda), replicated on every rank. Collective.
  State small_state(const DistState &s) const;
  /// World positions of the owned nodes of ACF body b (3 per node, node-major). Not collective.
  std::vector<double> owned_positions(const DistState &s, std::size_t body) const;
  /// The entries of a vector of this layout at the owned nodes of ACF body b (3 per node,
  /// node-major). Not collective.
  std::vector<double> owned_values(Vec v, std::size_t body) const;
  /// The position at a located point of ACF body b (FE interpolation), on every rank.
  /// Collective.
  Vec3 point_position(const DistState &s, std::size_t body, const fem::PointLocation &p) const;

  /// The consistent state at t0 from placed positions q0 and velocities v0 (this layout,
  /// multiplier entries ignored): the positions must satisfy every enforced constraint (ties
  /// and the small part's rows, to 1e-9 of the scene's size); the velocities are corrected onto
  /// Phi_q v + Phi_t = 0 by the rigid-body velocities of every body (the frames of rigid and
  /// FFRF bodies, the six rigid velocity fields of each ACF body) with the least change of
  /// kinetic energy, the elastic velocities kept (rigid_velocity_correction); should the joints
  /// need elastic velocities, the mass-weighted projection of all velocities follows. acc and
  /// lambda solve the acceleration-level equations [M Phi_q^T; Phi_q 0] [acc; lambda] =
  /// [Q; gamma]; a = acc. What the correction did goes into `report` (if non-null).
  /// Collective; throws a collective flexopt::Error naming the violated constraints, an
  /// inverted element or a singular system.
  DistState initial_state(Vec q0, Vec v0, double t0, StartReport *report = nullptr,
                          DistStartTrace *trace = nullptr) const;
  /// r = [Q; gamma] at s (its positions and velocities): the right-hand side of the start's
  /// acceleration system [M Phi_q^T; Phi_q 0] [acc; lambda] = [Q; gamma], with Q = f_g - f(x) -
  /// f_d(x, v) on the ACF rows and -r(q, v, 0) (Mechanism::dynamics) on the small part's, gamma
  /// the ties' D(p', s_j) p' and the small part's -(Phi_q v)_q v - 2 Phi_qt v - Phi_tt.
  /// Collective.
  void start_rhs(const DistState &s, Vec r) const;
  /// gv += (d[Q; gamma]/dv)^T nu at the consistent start s0, on the coordinate entries
  /// (docs/theory.md section 9.2, stage 2): the ACF bodies' damping and the small part's
  /// velocity Jacobian (velocity_transpose_multiply), the small part's convective terms
  /// gamma_v^T nu = -2 (sum_i nu_i H_i) v - 2 Phi_qt^T nu, and the ties'
  /// gamma_j = D(p', s_j) p', whose derivative 2 D(p', s_j) acts on the interface nodes'
  /// Euler-parameter rates. nu: a vector of this layout (multipliers on the constraint
  /// entries). Collective.
  void start_velocity_transpose(const DistState &s0, Vec nu, Vec gv) const;
  /// v += du + dw x (x_i - c) at the owned nodes x_i (positions of s) of ACF body b: the rigid
  /// velocity field p = (du, dw) about c. Not collective.
  void add_rigid_field(const DistState &s, std::size_t b, const Vector6 &p, const Vec3 &centre,
                       Vec v) const;
  /// The small part's coordinate entries of v, on every rank. Collective.
  Vector small_values(Vec v) const;
  /// T^T g for the rigid-body correction of the start (section 9.2, stage 3): the gradient with
  /// respect to its parameters (the columns of trace.rigid.T for the small part's frames, then
  /// per ACF body sum_i [g_i; (x_i - c) x g_i] over its nodes) of a gradient g on the
  /// coordinates. Replicated on every rank. Collective.
  Vector rigid_parameters_transpose(const DistState &s0, const DistStartTrace &trace, Vec g) const;
  /// Advances s by h to `next`, halving the step (recursively, up to max_halvings) when Newton
  /// fails. Returns false (and fills `info`) if even the smallest substep fails. Collective.
  bool advance(const DistState &s, double h, DistState &next, StepInfo &info,
               std::vector<std::pair<DistState, double>> *substeps = nullptr) const;
  /// One step of size h without halving (the adjoint's recomputation). Collective.
  bool step(const DistState &s, double h, DistState &next, StepInfo &info) const;
  /// The matrix [M Phi_q^T; Phi_q 0] of the consistent start at s (the ties without their
  /// multipliers' Hessian), as the operator of solve_transpose. Collective.
  Mat acceleration_matrix(const DistState &s) const;
  /// The entries of v at ACF body b's local nodes (owned and ghosts, the mesh's local
  /// numbering, 3 per node). Collective.
  void local_values(Vec v, std::size_t body, std::vector<double> &out) const;
  /// v += local (3 per local node of ACF body b, owned and ghosts); the caller assembles v. Not
  /// collective.
  void add_local_values(Vec v, std::size_t body, const std::vector<double> &local) const;
  /// v += N_a w at the nodes of the element holding the located point p of ACF body b (the
  /// owner rank adds); the caller assembles v. Not collective.
  void add_point_weights(Vec v, std::size_t body, const fem::PointLocation &p, const Vec3 &w) const;
  /// v += values on the small part's coordinate entries (rank 0 adds); the caller assembles v.
  /// Not collective.
  void add_small(Vec v, const Vector &values) const;

  /// The equations at a state, R = [R_d; Phi] in this layout: on the coordinates the
  /// equations of motion M acc + f(x) - f_g + Phi_q^T lambda (ACF bodies) and those of the small
  /// part (Mechanism::dynamics plus Phi_q^T lambda), on the multipliers the constraints. The
  /// rest of the step residual (R_q, R_v, R_a of GeneralizedAlpha::residual) is linear. Collective.
  void equations(const DistState &s, Vec R) const;
  /// The scaled Newton matrix of section 6.4 at s for the step size h: its product with
  /// [dq; dlambda_hat] is the derivative of [R_d / beta'; Phi] along q += dq, v += gamma' dq,
  /// a += alpha' dq, acc += beta' dq, lambda += beta' dlambda_hat. Owned by the integrator (valid
  /// until its next step). Collective.
  Mat newton_matrix(const DistState &s, double h) const;

  /// z with A^T z = rhs for the matrix A last returned by newton_matrix
  /// (factorized here by the integrator's solver; a later step assembles and factorizes anew).
  /// Collective; throws a collective flexopt::Error if A is singular or the solve fails.
  void solve_transpose(Vec rhs, Vec z) const;
  /// y = M x on the coordinate entries (the ACF bodies' mass, with their mass factors, and the
  /// small part's mass matrix at s), 0 on the multipliers. Collective.
  void mass_multiply(const DistState &s, Vec x, Vec y) const;
  /// y = C^T x with C = dR_d/dv at s: the ACF bodies' damping (d f_d/dv of the co-rotated
  /// elements, symmetric) and the small part's velocity Jacobian; 0 on the multipliers.
  /// Collective.
  void velocity_transpose_multiply(const DistState &s, Vec x, Vec y) const;

  /// Kinetic energy 1/2 v^T M v, elastic energy and the potential of gravity -f_g . x of the
  /// ACF bodies. Collective.
  void energies(const DistState &s, double &kinetic, double &elastic, double &potential) const;
  /// Kinetic energy of the ACF bodies and of the small part, 1/2 v^T M v. Collective.
  double kinetic_energy(const DistState &s) const;
  /// The whole mechanism's energy: the ACF bodies' plus the small part's (Mechanism::energy).
  /// Collective.
  double energy(const DistState &s) const;
  /// The work [J] done against the damping forces of the ACF bodies from state a to state b,
  /// (q_b - q_a) . (f_d(a) + f_d(b)) / 2: with rho_inf = 1 (the trapezoidal rule) the energy
  /// lost over a step, up to the scheme's drift. Collective.
  double damping_work(const DistState &a, const DistState &b) const;
  /// Largest |Phi| of the ties. Collective.
  double tie_violation(const DistState &s) const;
  /// Linear momentum M v summed over all nodes and angular momentum sum_a x_a x (M v)_a about
  /// the world origin, of the ACF bodies. Collective.
  void momentum(const DistState &s, Eigen::Vector3d &linear, Eigen::Vector3d &angular) const;
  /// 1_k^T M x / m: the centre of mass of the ACF bodies. Collective.
  Eigen::Vector3d centre_of_mass(Vec x) const;

  /// out := 1 on the coordinate entries of the layout, 0 on the multipliers. Not collective.
  void coordinate_mask(Vec out) const;
  /// Unknowns over all ranks: coordinates and multipliers.
  PetscInt global_size() const;

private:
  /// The six rigid velocity fields of every ACF body at the positions of s (for the consistent
  /// start): metric V^T M V about the mean node position, and its interface nodes. Collective.
  std::vector<RigidField> rigid_fields(const DistState &s) const;
  /// r_ := -(Phi_q v + Phi_t) on the multiplier entries (ties and the small part's rows), 0
  /// elsewhere, with the matrix [M Phi_q^T; Phi_q 0] in A_; returns max |r_|. Collective.
  double velocity_violation(const DistState &s, const State &small) const;
  bool step_once(const DistState &s, double h, DistState &next, StepInfo &info) const;
  /// Energy and force (and tangent) of all ACF bodies at positions x into F_ (and T); with
  /// velocities v, the damping force of the damped bodies is added (and their Jacobians,
  /// df_d/dx + gp df_d/dv). Collective.
  fem::CorotatedSum internal(Vec x, Mat T, Vec v = nullptr, double gp = 0) const;
  /// Adds the ties and the small part to the right-hand side r_ (and the matrix A_) at `next`
  /// with the scaling bp, gp; returns max |Phi| over all ranks. Collective (assembles r_, A_).
  double add_constraints(const DistState &next, double bp, double gp, bool matrix) const;
  /// Fills r_ = -[R_d / beta'; Phi] at `next` and, if `matrix`, A_ with the scaled Newton matrix;
  /// max |Phi| into violation. False if an element is inverted. Collective.
  bool assemble(const DistState &next, const NewtonScaling &k, bool matrix,
                double &violation) const;
  /// Adds every tie at s (the interface nodes from `small`; the multipliers if `multipliers`,
  /// else zero) with the scaling bp into A (null: none) and rhs; returns this rank's max |Phi|.
  /// Not collective (no assembly).
  double add_all_ties(const DistState &s, const State &small, bool multipliers, double bp, Mat A,
                      Vec rhs) const;
  /// Values of x at ACF body b's local nodes (owned and ghosts) into `local` (null:
  /// layout_->local_x[b]).
  void gather(Vec x, std::size_t body, Vec local = nullptr) const;

  std::vector<const bodies::AcfBody *> bodies_;
  const Mechanism *small_ = nullptr;
  std::vector<AcfInterface> interfaces_;
  MPI_Comm comm_;
  std::unique_ptr<detail::AcfLayout> layout_;
  AlphaParameters par_;
  NewtonSettings settings_;
  double mass_ = 0;
  Mat M_ = nullptr;                       ///< the ACF bodies' consistent mass (the pattern of A_)
  Vec fg_ = nullptr;                      ///< gravity load on the ACF bodies
  Vec cmask_ = nullptr, lmask_ = nullptr; ///< 1 on the coordinate (multiplier) entries, else 0
  mutable Vec F_ = nullptr, r_ = nullptr, dz_ = nullptr, w_ = nullptr; ///< work vectors
  mutable Mat A_ = nullptr;                                            ///< the iteration matrix
  mutable KSP ksp_ = nullptr;
  mutable bool factored_ = false;
  struct KeptFrame; ///< where the kept matrix was assembled, the bodies' rotations since
  std::unique_ptr<KeptFrame> kept_;
  /// Each ACF body's rotation from the positions of the kept matrix to q (collective).
  void kept_rotations(Vec q) const;
  /// v := T v (or T^T v): the ACF nodes' and ties' blocks turned by their body's rotation, the
  /// interface nodes' coordinates with them (not collective).
  void rotate_kept(Vec v, bool transpose) const;
  mutable double bp_ = 0, gp_ = 0;
};

} // namespace flexopt::dynamics
