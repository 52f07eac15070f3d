#include "flexopt/adjoint/step_adjoint.hpp"

#include "flexopt/core/error.hpp"

#include <Eigen/LU>
#include <limits>

namespace flexopt::adjoint {

Matrix step_adjoint(const Matrix &K, const Matrix &C, const Matrix &M, const Matrix &J,
                    const dynamics::AlphaParameters &par, double h, const Matrix &F) {
  const auto n = K.rows(), m = J.rows();
  if (F.rows() != 4 * n + m) throw Error("step_adjoint: right-hand sides of size 4n + m needed");
  const dynamics::NewtonScaling k = par.newton_scaling(h);
  const double am = par.alpha_m, af = par.alpha_f, b = par.beta, g = par.gamma;
  const double c = (1 - af) / (1 - am);
  const auto fq = F.middleRows(0, n), fv = F.middleRows(n, n), fa = F.middleRows(2 * n, n),
             fd = F.middleRows(3 * n, n), fc = F.middleRows(4 * n, m);
  // [A^T, J^T; J, 0] [mu_d; mu_c / b'] = [fd + c fa + fq / b' + (g'/b') fv; fc],
  // A = M + (g'/b') C + K / b'. The lambda row of dR/ds_{n+1} is dR_d/dlambda = J^T, whose
  // transpose J closes the system.
  Matrix S = Matrix::Zero(n + m, n + m);
  S.topLeftCorner(n, n) = (M + (k.gp / k.bp) * C + K / k.bp).transpose();
  S.topRightCorner(n, m) = J.transpose();
  S.bottomLeftCorner(m, n) = J;
  Matrix rhs(n + m, F.cols());
  rhs.topRows(n) = fd + c * fa + fq / k.bp + (k.gp / k.bp) * fv;
  rhs.bottomRows(m) = fc;
  const Eigen::PartialPivLU<Matrix> lu(S);
  const Matrix z = lu.solve(rhs);
  if (!z.allFinite() || !(lu.rcond() > std::numeric_limits<double>::epsilon()))
    throw Error("adjoint: the transposed Newton matrix of a step is singular (a body without "
                "mass or redundant constraints)");
  const Matrix mu_d = z.topRows(n), mu_c = k.bp * z.bottomRows(m);
  Matrix mu(4 * n + m, F.cols());
  mu.middleRows(0, n) = fq - K.transpose() * mu_d - J.transpose() * mu_c;
  mu.middleRows(n, n) = fv - C.transpose() * mu_d;
  mu.middleRows(2 * n, n) =
      (fa + h * h * b * mu.middleRows(0, n) + h * g * mu.middleRows(n, n)) / (1 - am);
  mu.middleRows(3 * n, n) = mu_d;
  mu.middleRows(4 * n, m) = mu_c;
  return mu;
}

Vector step_adjoint(const Matrix &D, const dynamics::AlphaParameters &par, double h, int n, int m,
                    const Vector &f) {
  if (D.rows() != 4 * n + m || D.cols() != 4 * n + m || f.size() != 4 * n + m)
    throw Error("step_adjoint: sizes do not match 4n + m");
  // Blocks of dR/ds_{n+1} (rows R_q, R_v, R_a, R_d, R_c; columns q, v, a, acc, lambda).
  return step_adjoint(D.block(3 * n, 0, n, n), D.block(3 * n, n, n, n), D.block(3 * n, 3 * n, n, n),
                      D.block(4 * n, 0, m, n), par, h, f);
}

Matrix previous_coupling(const dynamics::AlphaParameters &par, double h, int n, int m,
                         const Matrix &mu) {
  const double am = par.alpha_m, af = par.alpha_f, b = par.beta, g = par.gamma;
  const auto mq = mu.middleRows(0, n), mv = mu.middleRows(n, n), ma = mu.middleRows(2 * n, n);
  Matrix out(4 * n + m, mu.cols());
  out.middleRows(0, n) = -mq;
  out.middleRows(n, n) = -mv - h * mq;
  out.middleRows(2 * n, n) = -h * h * (0.5 - b) * mq - h * (1 - g) * mv + am * ma;
  out.middleRows(3 * n, n) = -af * ma;
  out.middleRows(4 * n, m).setZero();
  return out;
}

BackwardSweep::BackwardSweep(const dynamics::GeneralizedAlpha &ga, int responses)
    : ga_(ga), n_(ga.mechanism().coordinates()), m_(ga.mechanism().constraints()),
      carry_(Matrix::Zero(4 * n_ + m_, responses)) {}

Matrix BackwardSweep::step(const dynamics::State &state, double h, const Matrix &dpsi) {
  ga_.jacobian_blocks(state, K_, C_, M_, J_);
  const Matrix mu = step_adjoint(K_, C_, M_, J_, ga_.parameters(), h,
                                 dpsi.size() == 0 ? Matrix(-carry_) : Matrix(-dpsi - carry_));
  carry_ = previous_coupling(ga_.parameters(), h, n_, m_, mu);
  ++steps_;
  return mu;
}

Matrix BackwardSweep::finish(const Matrix &dpsi0) const {
  return dpsi0.size() == 0 ? Matrix(-carry_) : Matrix(-dpsi0 - carry_);
}

Matrix backward_sweep(const dynamics::GeneralizedAlpha &ga, const Trajectory &tr, int responses,
                      const std::function<Matrix(std::size_t)> &dpsi,
                      const std::function<void(std::size_t, const Matrix &)> &on_step) {
  if (tr.states.empty() || tr.h.size() != tr.states.size())
    throw Error("backward_sweep: one step size per state is needed");
  BackwardSweep sweep(ga, responses);
  for (std::size_t k = tr.steps(); k >= 1; --k) {
    const Matrix mu = sweep.step(tr.states[k], tr.h[k], dpsi(k));
    if (on_step) on_step(k, mu);
  }
  return sweep.finish(dpsi(0));
}

std::vector<Vector> backward_sweep(const dynamics::GeneralizedAlpha &ga,
                                   const std::vector<dynamics::State> &states, double h,
                                   const std::vector<Vector> &dpsi) {
  if (states.empty() || dpsi.size() != states.size())
    throw Error("backward_sweep: one partial per state is needed");
  Trajectory tr{states, std::vector<double>(states.size(), h)};
  std::vector<Vector> mu(states.size());
  mu[0] = backward_sweep(
      ga, tr, 1, [&](std::size_t k) { return Matrix(dpsi[k]); },
      [&](std::size_t k, const Matrix &m) { mu[k] = m.col(0); });
  return mu;
}

} // namespace flexopt::adjoint
