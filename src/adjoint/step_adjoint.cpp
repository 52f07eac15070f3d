#include "flexopt/adjoint/step_adjoint.hpp"

#include "flexopt/core/error.hpp"

#include <Eigen/LU>
#include <cmath>
#include <limits>

namespace flexopt::adjoint {

namespace {

/// The reduced system of section 9: S = [A^T, J^T; J, 0] with A = M + (g'/b') C + K/b' (the lambda
/// row of dR/ds_{n+1} is dR_d/dlambda = J^T, whose transpose J closes the system), into S.
void reduced_matrix(const Matrix &K, const Matrix &C, const Matrix &M, const Matrix &J,
                    const dynamics::NewtonScaling &k, Matrix &S) {
  const auto n = K.rows(), m = J.rows();
  S.resize(n + m, n + m);
  S.topLeftCorner(n, n).noalias() = M.transpose();
  S.topLeftCorner(n, n).noalias() += (k.gp / k.bp) * C.transpose();
  S.topLeftCorner(n, n).noalias() += (1 / k.bp) * K.transpose();
  S.topRightCorner(n, m) = J.transpose();
  S.bottomLeftCorner(m, n) = J;
  S.bottomRightCorner(m, m).setZero();
}

/// Its right-hand side [fd + c fa + fq / b' + (g'/b') fv; fc].
void reduced_rhs(const Matrix &F, Eigen::Index n, Eigen::Index m,
                 const dynamics::AlphaParameters &par, const dynamics::NewtonScaling &k,
                 Matrix &rhs) {
  const double c = (1 - par.alpha_f) / (1 - par.alpha_m);
  rhs.resize(n + m, F.cols());
  rhs.topRows(n) = F.middleRows(3 * n, n) + c * F.middleRows(2 * n, n) +
                   (1 / k.bp) * F.middleRows(0, n) + (k.gp / k.bp) * F.middleRows(n, n);
  rhs.bottomRows(m) = F.middleRows(4 * n, m);
}

/// mu from the solution z = [mu_d; mu_c / b'] of the reduced system.
Matrix back_substitute(const Matrix &K, const Matrix &C, const Matrix &J, const Matrix &z,
                       const Matrix &F, const dynamics::AlphaParameters &par, double h,
                       const dynamics::NewtonScaling &k) {
  const auto n = K.rows(), m = J.rows();
  const double am = par.alpha_m, b = par.beta, g = par.gamma;
  Matrix mu(4 * n + m, F.cols());
  mu.middleRows(3 * n, n) = z.topRows(n);
  mu.middleRows(4 * n, m) = k.bp * z.bottomRows(m);
  mu.middleRows(0, n) = F.middleRows(0, n);
  mu.middleRows(0, n).noalias() -= K.transpose() * mu.middleRows(3 * n, n);
  mu.middleRows(0, n).noalias() -= J.transpose() * mu.middleRows(4 * n, m);
  mu.middleRows(n, n) = F.middleRows(n, n);
  mu.middleRows(n, n).noalias() -= C.transpose() * mu.middleRows(3 * n, n);
  mu.middleRows(2 * n, n) =
      (F.middleRows(2 * n, n) + h * h * b * mu.middleRows(0, n) + h * g * mu.middleRows(n, n)) /
      (1 - am);
  return mu;
}

/// Whether an LU has a zero or non-finite pivot (relative to the largest): a singular matrix.
bool singular(const Eigen::PartialPivLU<Matrix> &lu) {
  const auto d = lu.matrixLU().diagonal().cwiseAbs();
  return !d.allFinite() || !(d.minCoeff() > 1e-300) ||
         !(d.minCoeff() > std::numeric_limits<double>::epsilon() * d.maxCoeff() * 1e-3);
}

[[noreturn]] void singular_error() {
  throw Error("adjoint: the transposed Newton matrix of a step is singular (a body without "
              "mass or redundant constraints)");
}

} // namespace

Matrix step_adjoint(const Matrix &K, const Matrix &C, const Matrix &M, const Matrix &J,
                    const dynamics::AlphaParameters &par, double h, const Matrix &F) {
  const auto n = K.rows(), m = J.rows();
  if (F.rows() != 4 * n + m) throw Error("step_adjoint: right-hand sides of size 4n + m needed");
  const dynamics::NewtonScaling k = par.newton_scaling(h);
  Matrix S, rhs;
  reduced_matrix(K, C, M, J, k, S);
  reduced_rhs(F, n, m, par, k, rhs);
  const Eigen::PartialPivLU<Matrix> lu(S);
  if (singular(lu)) singular_error();
  const Matrix z = lu.solve(rhs);
  if (!z.allFinite()) singular_error();
  return back_substitute(K, C, J, z, F, par, h, k);
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
  const dynamics::NewtonScaling k = ga_.parameters().newton_scaling(h);
  F_ = dpsi.size() == 0 ? Matrix(-carry_) : Matrix(-dpsi - carry_);
  reduced_matrix(K_, C_, M_, J_, k, S_);
  reduced_rhs(F_, n_, m_, ga_.parameters(), k, rhs_);
  ++steps_;
  // A new factorization every step: at the sizes of the dense backend (tens of unknowns) an LU
  // costs about three refinement sweeps with a kept one (measured: 2,000 slider-crank steps,
  // 131 factorizations and 10,686 refinements took 1.5 times as long as 2,000 factorizations).
  lu_.compute(S_);
  ++factorizations_;
  if (singular(lu_)) singular_error();
  z_ = lu_.solve(rhs_);
  if (!z_.allFinite()) singular_error();
  Matrix mu = back_substitute(K_, C_, J_, z_, F_, ga_.parameters(), h, k);
  carry_ = previous_coupling(ga_.parameters(), h, n_, m_, mu);
  return mu;
}

Matrix BackwardSweep::finish(const Matrix &dpsi0) const {
  return dpsi0.size() == 0 ? Matrix(-carry_) : Matrix(-dpsi0 - carry_);
}

} // namespace flexopt::adjoint
