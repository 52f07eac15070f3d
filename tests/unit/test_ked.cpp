// The KED modal integrator and sub-models (docs/theory.md section 12.1): exact for forcing
// linear between samples (constant and ramp loads against the closed forms to round-off),
// second order in h for smooth forcing (a sine against its closed form); the sub-model of a
// 2-DOF system against the Rayleigh quotient and the full model's response to a ramp; the
// quasi-static start follows constant and ramp loads without ringing.
#include "flexopt/plan/ked.hpp"

#include <cmath>
#include <gtest/gtest.h>

using namespace flexopt::plan;

TEST(Ked, ConstantAndRampLoadsAreExact) {
  const double w = 7.3, h = 0.013;
  const int steps = 400;
  Eigen::VectorXd w2(2);
  w2 << w * w, 4 * w * w;
  Eigen::MatrixXd F(steps + 1, 2);
  for (int i = 0; i <= steps; ++i) F(i, 0) = 2.5, F(i, 1) = 3.0 * i * h;
  const Eigen::MatrixXd X = modal_response(w2, F, h);
  double err = 0;
  for (int i = 0; i <= steps; ++i) {
    const double t = i * h, w1 = 2 * w;
    err = std::max(err, std::abs(X(i, 0) - 2.5 / w2(0) * (1 - std::cos(w * t))));
    err = std::max(err, std::abs(X(i, 1) - 3.0 / w2(1) * (t - std::sin(w1 * t) / w1)));
  }
  EXPECT_LT(err, 1e-13);
}

TEST(Ked, QuasiStaticStartFollowsTheLoad) {
  // From the quasi-static state, a constant load stays in equilibrium (no ringing), and a ramp
  // f = a t is followed exactly: x = a t / w^2 solves x'' + w^2 x = a t with x(0) = 0,
  // x'(0) = a / w^2.
  const double w = 4.1, h = 0.02;
  const int steps = 300;
  Eigen::VectorXd w2(2);
  w2 << w * w, 9 * w * w;
  Eigen::MatrixXd F(steps + 1, 2);
  for (int i = 0; i <= steps; ++i) F(i, 0) = -1.7, F(i, 1) = 0.6 * i * h;
  const Eigen::MatrixXd X = modal_response(w2, F, h, Start::QuasiStatic);
  double err = 0;
  for (int i = 0; i <= steps; ++i) {
    err = std::max(err, std::abs(X(i, 0) + 1.7 / w2(0)));
    err = std::max(err, std::abs(X(i, 1) - 0.6 * i * h / w2(1)));
  }
  EXPECT_LT(err, 1e-14);
}

TEST(Ked, SecondOrderForASine) {
  // x'' + w^2 x = sin(p t), x(0) = x'(0) = 0: x = (sin(p t) - (p / w) sin(w t)) / (w^2 - p^2).
  const double w = 5.0, p = 2.0, T = 3.0;
  double errors[2];
  for (int k = 0; k < 2; ++k) {
    const int steps = 100 << k;
    const double h = T / steps;
    Eigen::VectorXd w2(1);
    w2 << w * w;
    Eigen::MatrixXd F(steps + 1, 1);
    for (int i = 0; i <= steps; ++i) F(i, 0) = std::sin(p * i * h);
    const Eigen::MatrixXd X = modal_response(w2, F, h);
    double e = 0;
    for (int i = 0; i <= steps; ++i) {
      const double t = i * h;
      e = std::max(
          e, std::abs(X(i, 0) - (std::sin(p * t) - p / w * std::sin(w * t)) / (w * w - p * p)));
    }
    errors[k] = e;
  }
  const double order = std::log2(errors[0] / errors[1]);
  EXPECT_NEAR(order, 2.0, 0.05) << errors[0] << " " << errors[1];
}

TEST(Ked, SubModelIsTheRayleighQuotientAndFullModelTheEigenpairs) {
  Eigen::MatrixXd K(2, 2), M(2, 2);
  K << 4, -1, -1, 3;
  M << 2, 0.5, 0.5, 1;
  const ModalModel full = modal_model(K, M, Eigen::MatrixXd::Identity(2, 2), 2);
  EXPECT_LT((full.E.transpose() * M * full.E - Eigen::MatrixXd::Identity(2, 2)).norm(), 1e-14);
  EXPECT_LT((full.E.transpose() * K * full.E - Eigen::MatrixXd(full.w2.asDiagonal())).norm(),
            1e-13);
  Eigen::MatrixXd B(2, 2);
  B << 1, 0, 1, 1;
  const ModalModel one = modal_model(K, M, B, 1);
  const Eigen::Vector2d r(1, 1);
  EXPECT_NEAR(one.w2(0), r.dot(K * r) / r.dot(M * r), 1e-14);

  // A ramp Q = a t + b in the full basis, started quasi-statically: zeta(t) = K^-1 (a t + b)
  // exactly (each mode follows its load, as above).
  const int steps = 300;
  const double h = 0.01;
  const Eigen::Vector2d a(0.7, -1.1), b(0.3, 0.2);
  Eigen::MatrixXd Q(steps + 1, 2);
  for (int i = 0; i <= steps; ++i) Q.row(i) = (a * (i * h) + b).transpose();
  const Eigen::MatrixXd Z = ked_response(full, Q, h);
  double err = 0;
  for (int i = 0; i <= steps; ++i)
    err = std::max(err, (Z.row(i).transpose() - K.ldlt().solve(a * (i * h) + b)).norm());
  EXPECT_LT(err, 1e-13);
}
