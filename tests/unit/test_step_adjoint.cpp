// One step of the discrete adjoint (docs/theory.md section 9, adjoint/step_adjoint.hpp): the
// reduced transposed solve equals the full solve (dR/ds_{n+1})^T mu = f, and the coupling to the
// previous state equals (dR/ds_n)^T mu, with the Jacobians of GeneralizedAlpha::residual, on a
// swinging chain of rigid links (converged steps of the forward run) for several rho_inf.
//
// Tolerance: both sides are direct solves of the same linear system (the reduced one is the
// Schur form of the full one), each backward stable (|D^T mu - f| <= 1e-13 |D| |mu|), so they
// differ by round-off amplified by the condition number of D: at most 100 cond(D) eps relative.
#include "dynamics_checks.hpp"
#include "flexopt/adjoint/step_adjoint.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <cstdio>
#include <gtest/gtest.h>

using namespace flexopt;
using dynamics::Matrix;
using dynamics::Vector;

TEST(StepAdjoint, ReducedTransposedSolveEqualsTheFullOne) {
  Vector q0;
  const dynamics::Mechanism m = test_support::chain(3, q0);
  const int n = m.coordinates(), c = m.constraints();
  const double h = 1e-3;
  for (double rho : {0.0, 0.5, 0.8, 1.0}) {
    const dynamics::AlphaParameters par = dynamics::AlphaParameters::from_rho_inf(rho);
    const dynamics::GeneralizedAlpha ga(m, par);
    dynamics::State s = ga.initial_state(q0, Vector::Zero(n), 0.0), next;
    for (int step = 0; step < 20; ++step) { // swinging: a state with motion and multipliers
      dynamics::StepInfo info;
      ASSERT_TRUE(ga.advance(s, h, next, info));
      if (step < 19) s = next;
    }
    Vector R;
    Matrix D1, D0;
    ga.residual(next, s, h, R, &D1, &D0);
    const Vector f = Vector::Random(4 * n + c);
    const Vector mu = adjoint::step_adjoint(D1, par, h, n, c, f);
    const Vector full = Eigen::FullPivLU<Matrix>(D1.transpose()).solve(f);
    // Two backward-stable solves differ by at most ~ cond(D) eps in the forward error.
    const Eigen::JacobiSVD<Matrix> svd(D1);
    const double cond = svd.singularValues()(0) / svd.singularValues().tail(1)(0);
    EXPECT_LT((mu - full).norm(), 100 * cond * 2.2e-16 * full.norm()) << "rho_inf " << rho;
    // Backward error of the reduced solve, as small as the full LU's.
    const double scale = D1.norm() * mu.norm();
    EXPECT_LT((D1.transpose() * mu - f).norm(), 1e-13 * scale) << "rho_inf " << rho;
    std::printf("rho_inf %.1f: cond(D) %.1e, |mu - full| / |full| %.1e, backward errors %.1e "
                "(reduced) %.1e (full)\n",
                rho, cond, (mu - full).norm() / full.norm(),
                (D1.transpose() * mu - f).norm() / scale,
                (D1.transpose() * full - f).norm() / (D1.norm() * full.norm()));
    const Vector coupling = adjoint::previous_coupling(par, h, n, c, mu);
    EXPECT_LT((coupling - D0.transpose() * mu).norm(), 1e-12 * (D0.transpose() * mu).norm())
        << "rho_inf " << rho;
  }
}

// The backward sweep (section 9) gives the derivative of a response of the whole discrete
// trajectory with respect to the initial state: Psi = sum_n w_n c.q_n (a trapezoidal time
// average of a coordinate combination) + d.v_N over 40 steps of a swinging 2-link chain, whose
// derivative with respect to the initial velocities is -mu_0 (v block); compared with central
// differences of whole forward runs (Newton's method every iteration, so that nearby runs differ
// smoothly; step 1e-4 m/s: truncation ~1e-8 relative, the Newton tolerance 1e-12 / 1e-4 ~ 1e-8):
// 1e-7 relative.
TEST(StepAdjoint, BackwardSweepGivesTheDerivativeOfATrajectoryResponse) {
  Vector q0;
  const dynamics::Mechanism m = test_support::chain(2, q0);
  const int n = m.coordinates(), c = m.constraints();
  const double h = 2e-3;
  const int N = 40;
  dynamics::NewtonSettings newton;
  newton.reuse_contraction = 0;
  const dynamics::AlphaParameters par = dynamics::AlphaParameters::from_rho_inf(0.8);
  const dynamics::GeneralizedAlpha ga(m, par, newton);
  const dynamics::State s0 = ga.initial_state(q0, Vector::Zero(n), 0.0);
  const Vector cq = Vector::LinSpaced(n, 0.5, 1.5), dv = Vector::LinSpaced(n, -1.0, 1.0);
  auto weight = [&](int k) { return (k == 0 || k == N ? 0.5 : 1.0) / N; };
  auto run = [&](const dynamics::State &start, std::vector<dynamics::State> *states) {
    dynamics::State s = start, next;
    double psi = weight(0) * cq.dot(s.q);
    if (states) states->push_back(s);
    for (int k = 1; k <= N; ++k) {
      dynamics::StepInfo info;
      if (!ga.step(s, h, next, info)) throw std::runtime_error("step failed");
      s = next;
      psi += weight(k) * cq.dot(s.q);
      if (states) states->push_back(s);
    }
    return psi + dv.dot(s.v);
  };
  std::vector<dynamics::State> states;
  run(s0, &states);
  std::vector<Vector> dpsi(N + 1, Vector::Zero(4 * n + c));
  for (int k = 0; k <= N; ++k) dpsi[k].head(n) = weight(k) * cq;
  dpsi[N].segment(n, n) += dv;
  adjoint::BackwardSweep sweep(ga, 1);
  for (int k = N; k >= 1; --k) sweep.step(states[static_cast<std::size_t>(k)], h, dpsi[k]);
  const Vector grad = -sweep.finish(dpsi[0]).col(0).segment(n, n); // dPsi / dv_0
  const double eps = 1e-4;
  double worst = 0;
  for (int i = 0; i < n; ++i) {
    dynamics::State a = s0, b = s0;
    a.v(i) += eps;
    b.v(i) -= eps;
    const double fd = (run(a, nullptr) - run(b, nullptr)) / (2 * eps);
    worst = std::max(worst, std::abs(fd - grad(i)));
  }
  std::printf("backward sweep, %d steps: max |dPsi/dv0 - central differences| %.2e (|grad| "
              "%.2e)\n",
              N, worst, grad.norm());
  EXPECT_LT(worst, 1e-7 * grad.norm()); // measured 1.6e-9
}
