// The adjoint of the consistent initial state (docs/theory.md section 9.2): stage by stage
// backwards through what the start did — the accelerations and multipliers, the elastic fallback
// of the velocity correction, the rigid-body correction, and (with `given`, item 6) the closest
// point of the joints to the placed coordinates.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/consistent_start.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <functional>

namespace flexopt::adjoint {

namespace {

/// Sum_i lambda_i H_i over the enforced rows (n x n).
Matrix constraint_hessian(const dynamics::Mechanism &mech, const Vector &q, double t,
                          const Vector &lambda) {
  const int n = mech.coordinates();
  Matrix H = Matrix::Zero(n, n);
  mech.add_constraint_hessian(q, t, lambda, H);
  return H;
}

/// Column c: grad_q (w_c . f(q)) for a vector function f that is a polynomial of degree <= 6
/// in each coordinate (the constraint rows and their time derivatives, docs/theory.md section
/// 9.2 item 6): the seven-point central difference, exact for such polynomials, with the steps
/// h_j.
Matrix polynomial_gradient(const std::function<Vector(const Vector &)> &f, const Vector &q,
                           const Vector &h, const Matrix &w) {
  static constexpr double coefficient[3] = {45.0 / 60, -9.0 / 60, 1.0 / 60};
  const auto n = q.size();
  Matrix out = Matrix::Zero(n, w.cols());
  for (Eigen::Index j = 0; j < n; ++j) {
    Vector d = Vector::Zero(w.rows());
    for (int k = 1; k <= 3; ++k) {
      Vector qp = q, qm = q;
      qp(j) += k * h(j);
      qm(j) -= k * h(j);
      d += coefficient[k - 1] * (f(qp) - f(qm));
    }
    out.row(j) = (w.transpose() * d).transpose() / h(j);
  }
  return out;
}

/// grad_q sum_c x_c^T M(q) y_c over the columns of X and Y: sum_c (K(q, 0, y_c) -
/// K(q, 0, 0))^T x_c, K = dr/dq of Mechanism::dynamics (r is linear in its acceleration
/// argument).
Vector mass_gradient(const dynamics::Mechanism &mech, const Vector &q, double t, const Matrix &X,
                     const Matrix &Y) {
  const int n = mech.coordinates();
  Vector r, out = Vector::Zero(n);
  Matrix K0, K;
  mech.dynamics(q, Vector::Zero(n), Vector::Zero(n), t, r, &K0, nullptr, nullptr);
  for (Eigen::Index c = 0; c < X.cols(); ++c) {
    mech.dynamics(q, Vector::Zero(n), Y.col(c), t, r, &K, nullptr, nullptr);
    out += (K - K0).transpose() * X.col(c);
  }
  return out;
}

/// What the stages of the start's adjoint share: the mechanism at the start, the acceleration
/// system [M J^T; J 0] (its transpose factorized), the cotangents with respect to the start's
/// velocities (gv) and, with `given`, its positions (gq, and the steps h of their exact
/// polynomial gradients).
struct StartWork {
  const dynamics::Mechanism &mech;
  const dynamics::State &s0;
  const dynamics::StartTrace &trace;
  const ResidualPartials &partials;
  bool given;
  int n, m;
  Eigen::Index r;
  double t0;
  Matrix C, M, J;
  Eigen::PartialPivLU<Matrix> lu; ///< of A^T
  Matrix nu_acc, nu_lambda;
  Matrix gv, gq;
  Vector h;
  /// Phi_t, Phi_tt or Phi_qt v (which = 0, 1, 2) at the start's time.
  Vector time_terms(const Vector &x, const Vector &v, int which) const {
    Vector phi_t, phi_tt, phi_qt_v;
    mech.constraint_time_terms(x, v, t0, phi_t, phi_tt, phi_qt_v);
    return which == 0 ? phi_t : which == 1 ? phi_tt : phi_qt_v;
  }
  /// W^T dM(x)/dx a: r(q, 0, a) less r(q, 0, 0), which holds the elastic forces of a deformed
  /// FFRF body (K_r zeta) and must not enter.
  Matrix mass_partials(const Vector &a, const Matrix &W) const {
    const Vector zero = Vector::Zero(n);
    return Matrix(partials(s0.q, zero, a, false, W) - partials(s0.q, zero, zero, false, W));
  }
};

/// Accelerations and multipliers: [M J^T; J 0] [acc; lambda] = [-r(q, v, 0); gamma(q, v)].
/// From gbar: nu = A^-T [gbar_acc + gbar_a; gbar_lambda], the design partial -nu_acc . dr/dtheta,
/// and the velocity cotangent gv through r and gamma.
void start_accelerations(StartWork &w, const Matrix &gbar, StartAdjoint &out) {
  const dynamics::Mechanism &mech = w.mech;
  const int n = w.n, m = w.m;
  const double t0 = w.t0;
  const Vector &q = w.s0.q;
  Vector res, phi;
  Matrix K;
  mech.dynamics(q, w.s0.v, Vector::Zero(n), t0, res, nullptr, &w.C, &w.M);
  mech.constraint(q, t0, phi, &w.J);
  Matrix A = Matrix::Zero(n + m, n + m);
  A.topLeftCorner(n, n) = w.M;
  A.topRightCorner(n, m) = w.J.transpose();
  A.bottomLeftCorner(m, n) = w.J;
  Matrix rhs(n + m, w.r);
  rhs.topRows(n) = gbar.middleRows(3 * n, n) + gbar.middleRows(2 * n, n); // acc and a = acc
  rhs.bottomRows(m) = gbar.middleRows(4 * n, m);
  w.lu.compute(A.transpose());
  const Matrix nu = w.lu.solve(rhs);
  if (!nu.allFinite()) throw Error("adjoint: the initial acceleration system is singular", true);
  w.nu_acc = nu.topRows(n);
  w.nu_lambda = nu.bottomRows(m);
  out.design = w.partials(q, w.s0.v, w.s0.acc, true, -w.nu_acc);
  // d gamma/dv^T nu_lambda = -2 (sum_i nu_i H_i) v - 2 Phi_qt^T nu_lambda; Phi_qt column by
  // column from the linear map v -> Phi_qt v.
  Matrix Phi_qt(m, n);
  {
    Vector phi_t, phi_tt, phi_qt_v;
    for (int j = 0; j < n; ++j) {
      mech.constraint_time_terms(q, Vector::Unit(n, j), t0, phi_t, phi_tt, phi_qt_v);
      Phi_qt.col(j) = phi_qt_v;
    }
  }
  w.gv = gbar.middleRows(n, n) - w.C.transpose() * w.nu_acc - 2 * Phi_qt.transpose() * w.nu_lambda;
  for (Eigen::Index c = 0; c < w.r; ++c)
    w.gv.col(c) -= 2 * constraint_hessian(mech, q, t0, w.nu_lambda.col(c)) * w.s0.v;
}

/// With `given` (item 6): the q-dependence of the accelerations' stage, and the steps of the
/// exact polynomial gradients of every stage.
void start_accelerations_positions(StartWork &w, const Matrix &gbar) {
  const dynamics::Mechanism &mech = w.mech;
  const int n = w.n, m = w.m;
  const double t0 = w.t0;
  const Vector &q = w.s0.q;
  double L = 1;
  for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b)
    L = std::max(L, q.segment<3>(mech.offset(b)).cwiseAbs().maxCoeff());
  w.h.resize(n);
  for (int j = 0; j < n; ++j)
    w.h(j) = 0.1 * L / std::max(m > 0 ? w.J.col(j).cwiseAbs().maxCoeff() : 0.0, 0.1);
  w.gq = gbar.topRows(n);
  Vector res;
  Matrix Kd;
  mech.dynamics(q, w.s0.v, w.s0.acc, t0, res, &Kd, nullptr, nullptr);
  w.gq -= Kd.transpose() * w.nu_acc;
  const Matrix Hl = constraint_hessian(mech, q, t0, w.s0.lambda);
  w.gq -= Hl * w.nu_acc;
  for (Eigen::Index c = 0; c < w.r; ++c)
    w.gq.col(c) -= constraint_hessian(mech, q, t0, w.nu_lambda.col(c)) * w.s0.acc;
  if (m > 0)
    w.gq -= polynomial_gradient(
        [&](const Vector &x) {
          return Vector(mech.constraint_convective(x, w.s0.v, t0) + 2 * w.time_terms(x, w.s0.v, 2) +
                        w.time_terms(x, w.s0.v, 1));
        },
        q, w.h, w.nu_lambda);
}

/// The elastic fallback of the velocity correction, v_0 = v_r + dv with [M J^T; J 0] [dv; mu] =
/// [0; -(J v_r + Phi_t)]: nu = A^-T [gv; 0], dPsi/dx += -nu_v^T dM dv, gv_r = gv - J^T
/// nu_lambda. Returns v_r (v_0 if the start needed no fallback).
Vector start_fallback(StartWork &w, StartAdjoint &out) {
  const dynamics::Mechanism &mech = w.mech;
  const int n = w.n, m = w.m;
  const double t0 = w.t0;
  const Vector &q = w.s0.q;
  const dynamics::StartTrace &trace = w.trace;
  Vector v_r = w.s0.v;
  if (trace.fallback.size() == 0) return v_r;
  v_r -= trace.fallback;
  Matrix rhs_v = Matrix::Zero(n + m, w.r);
  rhs_v.topRows(n) = w.gv;
  const Matrix nu_v = w.lu.solve(rhs_v);
  out.design += w.mass_partials(trace.fallback, -nu_v.topRows(n));
  if (w.given) {
    Vector f = Vector::Zero(n + m);
    f.tail(m) = -(w.J * v_r + w.time_terms(q, v_r, 0));
    const Vector mu = w.lu.solve(f).tail(m); // A is symmetric: lu (of A^T) solves it too
    const Matrix Hmu = constraint_hessian(mech, q, t0, mu);
    for (Eigen::Index c = 0; c < w.r; ++c) {
      const Vector nv = nu_v.col(c).head(n), nm = nu_v.col(c).tail(m);
      w.gq.col(c) -= mass_gradient(mech, q, t0, nv, trace.fallback) + Hmu * nv +
                     constraint_hessian(mech, q, t0, nm) * w.s0.v; // dv + v_r = v_0
    }
    if (m > 0)
      w.gq -= polynomial_gradient([&](const Vector &x) { return w.time_terms(x, v_r, 0); }, q, w.h,
                                  nu_v.bottomRows(m));
  }
  w.gv -= w.J.transpose() * nu_v.bottomRows(m);
  return v_r;
}

/// Item 6 of the rigid correction: the least-W-norm least-squares y = W^-1 P^T S^+ b
/// differentiated at constant rank, S^+ = B^+T B^+, S S^+ = B B^+; into gq and gvg.
void start_rigid_positions(StartWork &w, const Vector &v_r, Matrix &gvg) {
  const dynamics::Mechanism &mech = w.mech;
  const int n = w.n, m = w.m;
  const double t0 = w.t0;
  const Vector &q = w.s0.q;
  const dynamics::VelocityCorrection &vc = w.trace.rigid;
  const Matrix &gv = w.gv;
  const auto k = vc.T.cols();
  const Vector v_g = v_r - vc.T * vc.y;
  const Eigen::LLT<Matrix> W(vc.W);
  const Matrix Sp = vc.Bp.transpose() * vc.Bp;
  auto range_complement = [&](const Vector &x) { return Vector(x - vc.B * (vc.Bp * x)); };
  const Vector mu = Sp * vc.b, f = Sp * mu, e = range_complement(vc.b);
  const Matrix WiPt = W.solve(vc.P.transpose());
  for (Eigen::Index c = 0; c < w.r; ++c) {
    const Vector ybar = vc.T.transpose() * gv.col(c), yhat = W.solve(ybar);
    const Vector tt = vc.P * yhat, a = Sp * tt, g = range_complement(tt);
    const Matrix Sbar = -a * mu.transpose() + (Sp * a) * e.transpose() + g * f.transpose();
    const Matrix Pbar = mu * yhat.transpose() + (Sbar + Sbar.transpose()) * WiPt.transpose();
    Matrix Wbar = -yhat * vc.y.transpose() - WiPt * Sbar * WiPt.transpose();
    for (Eigen::Index i = 0; i < k; ++i) // W is block diagonal (6 x 6 blocks)
      for (Eigen::Index j = 0; j < k; ++j)
        if (i / 6 != j / 6) Wbar(i, j) = 0;
    const Vector &bbar = a;
    Vector g_c = Vector::Zero(n);
    for (Eigen::Index col = 0; col < k; ++col)
      g_c += constraint_hessian(mech, q, t0, Pbar.col(col)) * vc.T.col(col);
    // <Tbar, T(q)>: T's Euler-parameter blocks 1/2 G(p)^T are linear in p.
    const Matrix Tbar = gv.col(c) * vc.y.transpose() + w.J.transpose() * Pbar +
                        w.M * vc.T * (Wbar + Wbar.transpose());
    for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b) {
      const int o = mech.offset(b);
      for (Eigen::Index col = 0; col + 2 < k; col += 6) {
        if (vc.T.block(o + 3, col + 3, 4, 3).isZero(0)) continue;
        for (int j = 0; j < 4; ++j)
          g_c(o + 3 + j) += (Tbar.block(o + 3, col + 3, 4, 3).array() *
                             (0.5 * bodies::g_matrix(bodies::Vec4::Unit(j)).transpose()).array())
                                .sum();
      }
    }
    g_c += mass_gradient(mech, q, t0, vc.T * Wbar, vc.T);
    g_c -= constraint_hessian(mech, q, t0, bbar) * v_g;
    w.gq.col(c) += g_c;
    gvg.col(c) -= w.J.transpose() * bbar;
  }
  if (m > 0) {
    Matrix B_bar(m, w.r);
    for (Eigen::Index c = 0; c < w.r; ++c)
      B_bar.col(c) = Sp * (vc.P * W.solve(Vector(vc.T.transpose() * gv.col(c))));
    w.gq -= polynomial_gradient([&](const Vector &x) { return w.time_terms(x, v_g, 0); }, q, w.h,
                                B_bar);
  }
}

/// The rigid correction v_r = v_given + T y: dy = -Pi dW y, dW = T^T dM T (also for joints that
/// rigid-body velocities cannot satisfy: y is then the least-W-norm solution of the consistent
/// P y = P P^+ b, whose set of least-squares solutions does not depend on W). Returns
/// dPsi/dv_given.
Matrix start_rigid_correction(StartWork &w, const Vector &v_r, StartAdjoint &out) {
  const dynamics::VelocityCorrection &vc = w.trace.rigid;
  Matrix gvg = w.gv; // dPsi/dv_given
  if (vc.T.size() > 0) {
    const Matrix U = vc.T * (vc.Pi * (vc.T.transpose() * w.gv));
    const Vector ay = vc.T * vc.y;
    out.design += w.mass_partials(ay, -U);
    if (w.given) start_rigid_positions(w, v_r, gvg);
  }
  return gvg;
}

/// The positions: the closest point q0 of the joints' manifold to the placed coordinates,
/// F = [W (q0 - q_g) + J^T mu; Phi(q0)] = 0 with W = I: [I + H(mu), J^T; J, 0] [a; b] =
/// [gq; 0] gives dPsi/dq_g = a and the metric's cotangent -a (q0 - q_g)^T (item 6). Also when
/// the placement satisfied the joints (mu = 0): skipping the correction is the same map.
void start_positions(StartWork &w, StartAdjoint &out) {
  const dynamics::Mechanism &mech = w.mech;
  const int n = w.n, m = w.m;
  const Vector &q = w.s0.q;
  const dynamics::StartTrace &trace = w.trace;
  if (!trace.closest)
    throw Error("adjoint: the start's position correction did not converge to the closest "
                "point of the joints to the placed coordinates, whose derivative the adjoint "
                "takes (the initial placement is far from an assembled configuration)",
                true);
  out.metric.assign(static_cast<std::size_t>(w.r), Matrix::Zero(n, n));
  if (m > 0) {
    Matrix Ak = Matrix::Zero(n + m, n + m);
    Ak.topLeftCorner(n, n) = Matrix::Identity(n, n);
    const Vector mu = trace.multipliers.size() == m ? trace.multipliers : Vector::Zero(m);
    mech.add_constraint_hessian(q, w.t0, mu, Ak);
    Ak.topRightCorner(n, m) = w.J.transpose();
    Ak.bottomLeftCorner(m, n) = w.J;
    Matrix rhs_q = Matrix::Zero(n + m, w.r);
    rhs_q.topRows(n) = w.gq;
    const Matrix ab = Ak.transpose().partialPivLu().solve(rhs_q);
    w.gq = ab.topRows(n);
    const Vector dq = q - (trace.given.size() == n ? trace.given : q);
    for (Eigen::Index c = 0; c < w.r; ++c)
      out.metric[static_cast<std::size_t>(c)] = -w.gq.col(c) * dq.transpose();
  }
  out.q = w.gq;
}

} // namespace

StartAdjoint initial_state_adjoint(const dynamics::GeneralizedAlpha &ga, const dynamics::State &s0,
                                   const dynamics::StartTrace &trace, const Matrix &gbar,
                                   const ResidualPartials &partials, bool given) {
  const dynamics::Mechanism &mech = ga.mechanism();
  StartWork w{mech,
              s0,
              trace,
              partials,
              given,
              mech.coordinates(),
              mech.constraints(),
              gbar.cols(),
              s0.t,
              {},
              {},
              {},
              {},
              {},
              {},
              {},
              {},
              {}};
  StartAdjoint out;
  start_accelerations(w, gbar, out);
  if (given) start_accelerations_positions(w, gbar);
  // The velocity correction, as the forward start made it (trace): first the rigid-body
  // velocities, v_r = v_given + T y; then, if they could not satisfy the joints, the elastic
  // fallback (section 9.2).
  const Vector v_r = start_fallback(w, out);
  const Matrix gvg = start_rigid_correction(w, v_r, out);
  if (!given) return out;
  start_positions(w, out);
  out.v = gvg;
  return out;
}

} // namespace flexopt::adjoint
