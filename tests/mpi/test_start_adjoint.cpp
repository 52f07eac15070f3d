// The adjoint of the consistent start with respect to the placed state (docs/theory.md section
// 9.2 item 6) against central differences of the whole start: the flexible slider-crank whose
// stretched rod violates the wrist pin, so that every stage acts (the closest-point position
// correction, the rigid-body velocity correction with joints it cannot satisfy, the elastic
// fallback, the accelerations with the crank's rotation driver). The pairing <gbar, s0(q_g +
// e dq, v_g + e dv)> is differenced (fourth order, at two steps that must agree to 1e-5)
// against qbar . dq + vbar . dv for a random gbar and directions on the rod's elastic
// coordinates (the design's) and on all coordinates.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/io/case.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <random>

using namespace flexopt;
using adjoint::Matrix;
using adjoint::Vector;

namespace {

struct StartCheck {
  double adjoint = 0, fd = 0, fd_coarse = 0;
};

StartCheck check_start(bool elastic_only, bool velocities) {
  const io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/ffrf_slider_crank_initial");
  const dynamics::Scene scene = dynamics::build_scene(PETSC_COMM_WORLD, c.scene);
  const dynamics::Mechanism &mech = scene.mechanism;
  const dynamics::GeneralizedAlpha ga(mech, dynamics::AlphaParameters::from_rho_inf(0.8));
  const int n = mech.coordinates(), m = mech.constraints();
  dynamics::StartTrace trace;
  const dynamics::State s0 = ga.initial_state(scene.q0, scene.v0, 0.0, nullptr, &trace);
  EXPECT_GT(trace.multipliers.cwiseAbs().maxCoeff(), 0); // every stage acts
  EXPECT_TRUE(trace.closest);
  EXPECT_GT(trace.fallback.size(), 0);
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  // A cotangent of every part of the state, scaled to its size.
  const Vector s = s0.pack();
  Vector gbar(4 * n + m);
  for (Eigen::Index i = 0; i < gbar.size(); ++i) gbar(i) = normal(rng) / (1e-3 + std::abs(s(i)));

  // The direction: the rod's elastic coordinates (body 1), or every coordinate.
  const int rod = 1, o = mech.offset(rod), nb = mech.size(rod);
  Vector dq = Vector::Zero(n), dv = Vector::Zero(n);
  Vector &d = velocities ? dv : dq;
  const Vector &base = velocities ? scene.v0 : scene.q0;
  for (int i = 0; i < n; ++i) {
    if (elastic_only && (i < o + 7 || i >= o + nb)) continue;
    d(i) = normal(rng) * 1e-2 * (1e-4 + std::abs(base(i)));
  }
  const adjoint::StartAdjoint sa = adjoint::initial_state_adjoint(
      ga, s0, trace, gbar,
      [](const Vector &, const Vector &, const Vector &, bool, const Matrix &W) {
        return Matrix::Zero(1, W.cols());
      },
      true);
  StartCheck out;
  out.adjoint = sa.q.col(0).dot(dq) + sa.v.col(0).dot(dv);
  auto pairing = [&](double e) {
    return gbar.dot(ga.initial_state(scene.q0 + e * dq, scene.v0 + e * dv, 0.0).pack());
  };
  auto fd4 = [&](double e) {
    return (8 * (pairing(e) - pairing(-e)) - (pairing(2 * e) - pairing(-2 * e))) / (12 * e);
  };
  // The largest steps whose fourth-order quotients are converged: the pairing sums terms of
  // very different size, and its round-off divided by the step is what limits the check.
  const double e0 = velocities ? 1e-1 : 1e-2;
  out.fd_coarse = fd4(2 * e0);
  out.fd = fd4(e0);
  return out;
}

void expect_agree(const StartCheck &r, const char *what) {
  const double err = std::abs(r.fd - r.adjoint) / std::abs(r.fd);
  const double trunc = std::abs(r.fd - r.fd_coarse) / std::abs(r.fd);
  std::printf("%s: adjoint %.12e fd %.12e (coarse %.12e) rel err %.2e\n", what, r.adjoint, r.fd,
              r.fd_coarse, err);
  EXPECT_LT(trunc, 1e-5) << what << ": the difference quotients are not converged";
  EXPECT_LT(err, 2e-8) << what; // the quotients agree with each other to 1e-8
}

} // namespace

TEST(InitialState, AdjointOfTheGivenElasticCoordinates) {
  expect_agree(check_start(true, false), "elastic coordinates");
}
TEST(InitialState, AdjointOfTheGivenElasticRates) {
  expect_agree(check_start(true, true), "elastic rates");
}
TEST(InitialState, AdjointOfTheGivenCoordinates) {
  expect_agree(check_start(false, false), "all coordinates");
}
TEST(InitialState, AdjointOfTheGivenVelocities) {
  expect_agree(check_start(false, true), "all velocities");
}
