#include "flexopt/dynamics/distributed_alpha.hpp"

#include "flexopt/core/direct_solver.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/newton_loop.hpp"

#include <limits>

namespace flexopt::dynamics {

namespace {

Vec copy_of(Vec v) {
  if (!v) return nullptr;
  Vec c;
  FX_PETSC(VecDuplicate(v, &c));
  FX_PETSC(VecCopy(v, c));
  return c;
}

/// Copies the values of `from` into `to`, creating `to` if it does not exist yet.
void assign(Vec &to, Vec from) {
  if (!from) {
    VecDestroy(&to);
    return;
  }
  if (!to) FX_PETSC(VecDuplicate(from, &to));
  FX_PETSC(VecCopy(from, to));
}

double max_abs(Vec v) {
  PetscReal n;
  FX_PETSC(VecNorm(v, NORM_INFINITY, &n));
  return n;
}

} // namespace

DistState::DistState(const DistState &o)
    : t(o.t), q(copy_of(o.q)), v(copy_of(o.v)), a(copy_of(o.a)), acc(copy_of(o.acc)) {}

DistState &DistState::operator=(const DistState &o) {
  if (this == &o) return *this;
  t = o.t;
  assign(q, o.q);
  assign(v, o.v);
  assign(a, o.a);
  assign(acc, o.acc);
  return *this;
}

DistState::~DistState() {
  VecDestroy(&q);
  VecDestroy(&v);
  VecDestroy(&a);
  VecDestroy(&acc);
}

DistributedAlpha::DistributedAlpha(const bodies::AcfBody &body, const Eigen::Vector3d &gravity,
                                   AlphaParameters parameters, NewtonSettings settings)
    : body_(body), par_(parameters), settings_(settings) {
  fg_ = body_.create_vector();
  body_.gravity_load(gravity, fg_);
  F_ = body_.create_vector();
  r_ = body_.create_vector();
  dq_ = body_.create_vector();
  A_ = body_.create_matrix();
  FX_PETSC(KSPCreate(body_.mesh().comm, &ksp_));
  FX_PETSC(KSPSetOptionsPrefix(ksp_, "mech_"));
  use_mumps(ksp_, Factorization::LU);
  FX_PETSC(KSPSetFromOptions(ksp_));
}

DistributedAlpha::~DistributedAlpha() {
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
  VecDestroy(&fg_);
  VecDestroy(&F_);
  VecDestroy(&r_);
  VecDestroy(&dq_);
}

DistState DistributedAlpha::initial_state(Vec x0, Vec v0, double t0) const {
  DistState s;
  s.t = t0;
  s.q = copy_of(x0);
  s.v = copy_of(v0);
  s.acc = body_.create_vector();
  const fem::CorotatedSum sum = body_.internal(s.q, F_, nullptr);
  if (!sum.ok) throw Error("initial state: " + sum.failure, true);
  // M acc = f_g - f(x0), with a direct solve of the constant mass.
  FX_PETSC(VecWAXPY(r_, -1.0, F_, fg_));
  KSP k;
  FX_PETSC(KSPCreate(body_.mesh().comm, &k));
  FX_PETSC(KSPSetOperators(k, body_.mass_matrix(), body_.mass_matrix()));
  use_mumps(k, Factorization::Cholesky);
  FX_PETSC(KSPSolve(k, r_, s.acc));
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(k, &reason));
  FX_PETSC(KSPDestroy(&k));
  if (reason < 0)
    throw Error(std::string("initial state: the mass-matrix solve failed (") +
                    KSPConvergedReasons[reason] + ")",
                true);
  s.a = copy_of(s.acc);
  return s;
}

void DistributedAlpha::energies(const DistState &s, double &kinetic, double &elastic,
                                double &potential) const {
  FX_PETSC(MatMult(body_.mass_matrix(), s.v, r_));
  FX_PETSC(VecDot(s.v, r_, &kinetic));
  kinetic *= 0.5;
  elastic = body_.internal(s.q, F_, nullptr).energy;
  FX_PETSC(VecDot(fg_, s.q, &potential));
  potential = -potential;
}

bool DistributedAlpha::step_once(const DistState &s, double h, DistState &next,
                                 StepInfo &info) const {
  const double am = par_.alpha_m, af = par_.alpha_f, g = par_.gamma, b = par_.beta;
  const double bp = (1 - am) / (b * h * h * (1 - af)), gp = g / (b * h);
  if (!next.q) next = s; // vectors of the right layout
  struct Backend {
    const DistributedAlpha &da;
    const DistState &s;
    DistState &next;
    double h, am, af, g, b;
    void predict() { // acc1 = acc0
      next.t = s.t + h;
      FX_PETSC(VecCopy(s.acc, next.acc));
      // a1 = (af acc0 - am a0 + (1 - af) acc1) / (1 - am) = (acc0 - am a0) / (1 - am)
      FX_PETSC(VecAXPBYPCZ(next.a, 1 / (1 - am), -am / (1 - am), 0.0, s.acc, s.a));
      // v1 = v0 + h (1 - g) a0 + h g a1
      FX_PETSC(VecCopy(s.v, next.v));
      FX_PETSC(VecAXPBYPCZ(next.v, h * (1 - g), h * g, 1.0, s.a, next.a));
      // q1 = q0 + h v0 + h^2 (1/2 - b) a0 + h^2 b a1
      FX_PETSC(VecCopy(s.q, next.q));
      const PetscScalar coef[3] = {h, h * h * (0.5 - b), h * h * b};
      Vec vecs[3] = {s.v, s.a, next.a};
      FX_PETSC(VecMAXPY(next.q, 3, coef, vecs));
    }
    bool has_matrix(double bp_, double gp_) const {
      return da.factored_ && da.bp_ == bp_ && da.gp_ == gp_;
    }
    /// r = -(M acc + f(q) - f_g) / beta' (F_ holds f(q)).
    void residual(double bp_) {
      FX_PETSC(MatMult(da.body_.mass_matrix(), next.acc, da.r_));
      FX_PETSC(VecAXPY(da.r_, 1.0, da.F_));
      FX_PETSC(VecAXPY(da.r_, -1.0, da.fg_));
      FX_PETSC(VecScale(da.r_, -1.0 / bp_));
    }
    bool factorize(double bp_, double gp_) {
      da.factored_ = false;
      const fem::CorotatedSum sum = da.body_.internal(next.q, da.F_, da.A_);
      da.bad_ = !sum.ok;
      if (!sum.ok) return false;
      // A = M + T / beta' (no damping yet: C = 0).
      FX_PETSC(MatScale(da.A_, 1.0 / bp_));
      FX_PETSC(MatAXPY(da.A_, 1.0, da.body_.mass_matrix(), SUBSET_NONZERO_PATTERN));
      FX_PETSC(KSPSetOperators(da.ksp_, da.A_, da.A_));
      FX_PETSC(KSPSetUp(da.ksp_));
      PC pc;
      FX_PETSC(KSPGetPC(da.ksp_, &pc));
      PCFailedReason failed;
      FX_PETSC(PCGetFailedReason(pc, &failed));
      if (failed != PC_NOERROR) return false;
      residual(bp_);
      da.factored_ = true;
      da.bp_ = bp_;
      da.gp_ = gp_;
      return true;
    }
    void rhs(double bp_) {
      const fem::CorotatedSum sum = da.body_.internal(next.q, da.F_, nullptr);
      da.bad_ = !sum.ok;
      if (sum.ok) residual(bp_);
    }
    bool solve_update(double bp_, double gp_, double &increment, double &violation) {
      violation = 0; // no constraints
      if (da.bad_) return false;
      FX_PETSC(KSPSolve(da.ksp_, da.r_, da.dq_));
      KSPConvergedReason reason;
      FX_PETSC(KSPGetConvergedReason(da.ksp_, &reason));
      if (reason < 0) return false;
      FX_PETSC(VecAXPY(next.q, 1.0, da.dq_));
      FX_PETSC(VecAXPY(next.v, gp_, da.dq_));
      FX_PETSC(VecAXPY(next.acc, bp_, da.dq_));
      FX_PETSC(VecAXPY(next.a, (1 - af) / (1 - am) * bp_, da.dq_));
      const double d = max_abs(da.dq_);
      if (!std::isfinite(d)) return false;
      increment = d / (1 + max_abs(next.q));
      return true;
    }
    void drop_matrix() { da.factored_ = false; }
  } backend{*this, s, next, h, am, af, g, b};
  return detail::newton_loop(backend, settings_, bp, gp, info);
}

bool DistributedAlpha::advance(const DistState &s, double h, DistState &next,
                               StepInfo &info) const {
  return detail::advance_with_halving(s, h, next, info, settings_.max_halvings,
                                      [this](const DistState &from, double dt, DistState &to,
                                             StepInfo &i) { return step_once(from, dt, to, i); });
}

} // namespace flexopt::dynamics
