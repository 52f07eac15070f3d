#include "flexopt/adjoint/step_adjoint.hpp"

#include "flexopt/core/error.hpp"

#include <Eigen/LU>

namespace flexopt::adjoint {

Vector step_adjoint(const Matrix &D, const dynamics::AlphaParameters &par, double h, int n, int m,
                    const Vector &f) {
  if (D.rows() != 4 * n + m || D.cols() != 4 * n + m || f.size() != 4 * n + m)
    throw Error("step_adjoint: sizes do not match 4n + m");
  const dynamics::NewtonScaling k = par.newton_scaling(h);
  const double am = par.alpha_m, af = par.alpha_f, b = par.beta, g = par.gamma;
  const double c = (1 - af) / (1 - am);
  // Blocks of dR/ds_{n+1} (rows R_q, R_v, R_a, R_d, R_c; columns q, v, a, acc, lambda).
  const auto K = D.block(3 * n, 0, n, n), C = D.block(3 * n, n, n, n),
             M = D.block(3 * n, 3 * n, n, n), Jt = D.block(3 * n, 4 * n, n, m),
             J = D.block(4 * n, 0, m, n);
  const auto fq = f.segment(0, n), fv = f.segment(n, n), fa = f.segment(2 * n, n),
             fd = f.segment(3 * n, n), fc = f.segment(4 * n, m);
  // [A^T, J^T; J, 0] [mu_d; mu_c / b'] = [fd + c fa + fq / b' + (g'/b') fv; fc],
  // A = M + (g'/b') C + K / b'.
  Matrix S = Matrix::Zero(n + m, n + m);
  S.topLeftCorner(n, n) = (M + (k.gp / k.bp) * C + K / k.bp).transpose();
  S.topRightCorner(n, m) = J.transpose();    // (dR_c/dq)^T, from the q row
  S.bottomLeftCorner(m, n) = Jt.transpose(); // (dR_d/dlambda)^T, the lambda row
  Vector rhs(n + m);
  rhs << fd + c * fa + fq / k.bp + (k.gp / k.bp) * fv, fc;
  const Eigen::FullPivLU<Matrix> lu(S);
  if (lu.rank() < n + m) throw Error("step_adjoint: the transposed Newton matrix is singular");
  const Vector z = lu.solve(rhs);
  Vector mu(4 * n + m);
  const Vector mu_d = z.head(n), mu_c = k.bp * z.tail(m);
  const Vector mu_q = fq - K.transpose() * mu_d - J.transpose() * mu_c;
  const Vector mu_v = fv - C.transpose() * mu_d;
  const Vector mu_a = (fa + h * h * b * mu_q + h * g * mu_v) / (1 - am);
  mu << mu_q, mu_v, mu_a, mu_d, mu_c;
  return mu;
}

Vector previous_coupling(const dynamics::AlphaParameters &par, double h, int n, int m,
                         const Vector &mu) {
  const double am = par.alpha_m, af = par.alpha_f, b = par.beta, g = par.gamma;
  const auto mq = mu.segment(0, n), mv = mu.segment(n, n), ma = mu.segment(2 * n, n);
  Vector out(4 * n + m);
  out << -mq, -mv - h * mq, -h * h * (0.5 - b) * mq - h * (1 - g) * mv + am * ma, -af * ma,
      Vector::Zero(m);
  return out;
}

std::vector<Vector> backward_sweep(const dynamics::GeneralizedAlpha &ga,
                                   const std::vector<dynamics::State> &states, double h,
                                   const std::vector<Vector> &dpsi) {
  const std::size_t N = states.size() - 1;
  if (states.empty() || dpsi.size() != states.size())
    throw Error("backward_sweep: one partial per state is needed");
  const int n = static_cast<int>(states.front().q.size());
  const int m = static_cast<int>(states.front().lambda.size());
  const dynamics::AlphaParameters &par = ga.parameters();
  std::vector<Vector> mu(N + 1);
  Vector carry = Vector::Zero(4 * n + m); // (dR_(k+1)/ds_k)^T mu_(k+1)
  for (std::size_t k = N; k >= 1; --k) {
    Vector R;
    Matrix D;
    ga.residual(states[k], states[k - 1], h, R, &D, nullptr);
    mu[k] = step_adjoint(D, par, h, n, m, -dpsi[k] - carry);
    carry = previous_coupling(par, h, n, m, mu[k]);
  }
  mu[0] = -dpsi[0] - carry;
  return mu;
}

} // namespace flexopt::adjoint
