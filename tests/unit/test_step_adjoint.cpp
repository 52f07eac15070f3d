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
