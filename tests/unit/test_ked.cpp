// The KED modal integrator and sub-models (docs/theory.md section 12.1): exact for forcing
// linear between samples (constant and ramp loads against the closed forms to round-off),
// second order in h for smooth forcing (a sine against its closed form); the sub-model of a
// 2-DOF system against the Rayleigh quotient and the full model's response to a ramp; the
// quasi-static start follows constant and ramp loads without ringing.
#include "flexopt/plan/ked.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <vector>

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

TEST(Ked, VaryingStiffnessHeldConstantIsTheModalResponse) {
  // K + c G with c constant: the same system as the modal model of K + c G, to round-off.
  Eigen::MatrixXd K(2, 2), G(2, 2);
  K << 9, 0, 0, 40;
  G << 1.5, -0.7, -0.7, 2.0;
  const double c = -1.3, h = 0.011;
  const int steps = 500;
  Eigen::MatrixXd Q(steps + 1, 2), coef = Eigen::MatrixXd::Constant(steps + 1, 1, c);
  for (int i = 0; i <= steps; ++i) Q(i, 0) = std::sin(3.0 * i * h), Q(i, 1) = 0.4 + 0.2 * i * h;
  double lowest = 0;
  const Eigen::MatrixXd Z = ked_response_varying(K, {G}, coef, Q, h, Start::QuasiStatic, &lowest);
  // From rest: the modal response of K + c G from rest.
  const Eigen::MatrixXd Zr = ked_response_varying(K, {G}, coef, Q, h, Start::Rest);
  const Eigen::MatrixXd Kc = K + c * G;
  const Eigen::MatrixXd R = ked_response(
      modal_model(Kc, Eigen::MatrixXd::Identity(2, 2), Eigen::MatrixXd::Identity(2, 2), 2), Q, h);
  EXPECT_LT((Z - R).cwiseAbs().maxCoeff(), 1e-12 * R.cwiseAbs().maxCoeff());
  const ModalModel m =
      modal_model(Kc, Eigen::MatrixXd::Identity(2, 2), Eigen::MatrixXd::Identity(2, 2), 2);
  const Eigen::MatrixXd Rr = modal_response(m.w2, Q * m.E, h, Start::Rest) * m.E.transpose();
  EXPECT_LT((Zr - Rr).cwiseAbs().maxCoeff(), 1e-12 * Rr.cwiseAbs().maxCoeff());
  EXPECT_NEAR(lowest, Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Kc).eigenvalues()(0), 1e-12);
}

TEST(Ked, VaryingStiffnessIsSecondOrder) {
  // x'' + (w0^2 + a t) x = f, x from the quasi-static start: the frozen-midpoint steps converge
  // at order 2 against a fine classical Runge-Kutta solution (h / 64, its error ~1e-12 here).
  const double w0 = 6.0, a = 20.0, f = 1.0, T = 2.0;
  auto reference = [&](int steps) {
    const double h = T / steps;
    std::vector<double> x(static_cast<std::size_t>(steps) + 1);
    // The integrator's start: K(0) x(0) = f, K(0) x'(0) = (Q(h) - Q(0)) / h = 0.
    double y = f / (w0 * w0), v = 0;
    x[0] = y;
    auto acc = [&](double t, double xx) { return f - (w0 * w0 + a * t) * xx; };
    for (int i = 0; i < steps; ++i) {
      const double t = i * h;
      const double k1x = v, k1v = acc(t, y);
      const double k2x = v + 0.5 * h * k1v, k2v = acc(t + 0.5 * h, y + 0.5 * h * k1x);
      const double k3x = v + 0.5 * h * k2v, k3v = acc(t + 0.5 * h, y + 0.5 * h * k2x);
      const double k4x = v + h * k3v, k4v = acc(t + h, y + h * k3x);
      y += h / 6 * (k1x + 2 * k2x + 2 * k3x + k4x);
      v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
      x[static_cast<std::size_t>(i) + 1] = y;
    }
    return x;
  };
  const int base = 100, fine = 64;
  const std::vector<double> ref = reference(base * 4 * fine);
  double errors[2];
  for (int k = 0; k < 2; ++k) {
    const int steps = base << k;
    const double h = T / steps;
    Eigen::MatrixXd K(1, 1), G(1, 1), Q = Eigen::MatrixXd::Constant(steps + 1, 1, f),
                                      coef(steps + 1, 1);
    K << w0 * w0;
    G << a;
    for (int i = 0; i <= steps; ++i) coef(i, 0) = i * h;
    const Eigen::MatrixXd Z = ked_response_varying(K, {G}, coef, Q, h);
    double e = 0;
    for (int i = 0; i <= steps; ++i)
      e = std::max(e, std::abs(Z(i, 0) - ref[static_cast<std::size_t>(i * (4 * fine >> k))]));
    errors[k] = e;
  }
  EXPECT_NEAR(std::log2(errors[0] / errors[1]), 2.0, 0.1) << errors[0] << " " << errors[1];
}

TEST(Ked, QuasiStaticErrorOfAHarmonicLoad) {
  // ESL's criterion e_qs (docs/theory.md 14.5) on two uncoupled modes w_k under sin(p t) b_k
  // from the quasi-static start (x(0) = 0, x'(0) = (f(h) - f(0)) / (h w^2)): the closed form
  // x_k = b_k (A_k sin(p t) + B_k sin(w_k t)), A_k = 1 / (w_k^2 - p^2), B_k from x'(0), against
  // x_qs,k = b_k sin(p t) / w_k^2, in the energy norm sum_k w_k^2 x_k^2, max over the samples.
  // The integrator is second order for a sine (its forcing is linear between samples): the
  // difference from the closed form falls 4 times when h halves.
  const double p = 2.0, T = 12.0;
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(2, 2), M = Eigen::MatrixXd::Identity(2, 2);
  K(0, 0) = 7.0 * 7.0, K(1, 1) = 19.0 * 19.0;
  const ModalModel model = modal_model(K, M, Eigen::MatrixXd::Identity(2, 2), 2);
  const double b[2] = {1.0, 0.5};
  auto measure = [&](int steps) {
    const double h = T / steps;
    Eigen::MatrixXd Q(steps + 1, 2);
    for (int i = 0; i <= steps; ++i)
      for (int k = 0; k < 2; ++k) Q(i, k) = b[k] * std::sin(p * i * h);
    double top = 0, distance = 0;
    for (int i = 0; i <= steps; ++i) {
      double e2 = 0, d2 = 0;
      for (int k = 0; k < 2; ++k) {
        const double w2 = K(k, k), w = std::sqrt(w2), A = 1 / (w2 - p * p);
        const double v0 = std::sin(p * h) / (h * w2), B = (v0 - A * p) / w;
        const double t = i * h, x = b[k] * (A * std::sin(p * t) + B * std::sin(w * t));
        const double dx = x - b[k] * std::sin(p * t) / w2;
        e2 += w2 * x * x, d2 += w2 * dx * dx;
      }
      top = std::max(top, std::sqrt(e2)), distance = std::max(distance, std::sqrt(d2));
    }
    const double e = quasi_static_error(model, M, ked_response(model, Q, h), Q);
    return std::pair{e, distance / top};
  };
  const auto [e1, exact1] = measure(5000);
  const auto [e2, exact2] = measure(10000);
  const double d1 = std::abs(e1 - exact1), d2 = std::abs(e2 - exact2);
  EXPECT_LT(d2, 1e-5 * exact2) << e2 << " against " << exact2;
  EXPECT_NEAR(d1 / d2, 4.0, 0.5) << d1 << ", " << d2;
  // The single-mode estimate of section 14.5: about (p / w_1)^2 = 0.082.
  EXPECT_GT(e2, 0.5 * std::pow(p / 7.0, 2));
  EXPECT_LT(e2, 2.0 * std::pow(p / 7.0, 2));
}
