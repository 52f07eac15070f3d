#include "flexopt/plan/ked.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>
#include <limits>

namespace flexopt::plan {

namespace {

/// One step of x'' + w^2 x = f (unit mass) with f = f0 + (f1 - f0) tau / h, exact:
///   x(h) = x0 c + v0 s / w + f0 (1 - c) / w^2 + (f1 - f0) (h - s / w) / (w^2 h),
///   v(h) = -x0 w s + v0 c + f0 s / w + (f1 - f0) (1 - c) / (w^2 h),
/// c = cos(w h), s = sin(w h).
struct StepCoefficients {
  double w, w2, h, c, s;
  StepCoefficients(double w2_, double h_)
      : w(std::sqrt(w2_)), w2(w2_), h(h_), c(std::cos(w * h_)), s(std::sin(w * h_)) {}
  void advance(double &x, double &v, double f0, double f1) const {
    const double df = f1 - f0;
    const double xn = x * c + v * s / w + f0 * (1 - c) / w2 + df * (h - s / w) / (w2 * h);
    const double vn = -x * w * s + v * c + f0 * s / w + df * (1 - c) / (w2 * h);
    x = xn, v = vn;
  }
};

} // namespace

Eigen::MatrixXd modal_response(const Eigen::VectorXd &w2, const Eigen::MatrixXd &F, double h,
                               Start start) {
  const Eigen::Index steps = F.rows(), n = F.cols();
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(steps, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    double x = 0, v = 0;
    if (start == Start::QuasiStatic) {
      x = F(0, k) / w2(k);
      v = steps > 1 ? (F(1, k) - F(0, k)) / (h * w2(k)) : 0.0;
      X(0, k) = x;
    }
    const StepCoefficients sc(w2(k), h);
    for (Eigen::Index i = 0; i + 1 < steps; ++i) {
      sc.advance(x, v, F(i, k), F(i + 1, k));
      X(i + 1, k) = x;
    }
  }
  return X;
}

ModalModel modal_model(const Eigen::MatrixXd &K, const Eigen::MatrixXd &M, const Eigen::MatrixXd &B,
                       int columns) {
  const Eigen::MatrixXd Bs = B.leftCols(columns);
  const Eigen::MatrixXd Ks = Bs.transpose() * K * Bs, Ms = Bs.transpose() * M * Bs;
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (Ks + Ks.transpose()),
                                                                      0.5 * (Ms + Ms.transpose()));
  if (eig.info() != Eigen::Success)
    throw Error("plan: the reduced eigenproblem of a sub-model failed (a singular mass)");
  return {Bs * eig.eigenvectors(), eig.eigenvalues()};
}

Eigen::MatrixXd ked_response(const ModalModel &model, const Eigen::MatrixXd &Q, double h) {
  // Modal forcing E^T Q(t), responses x(t) from the quasi-static start, back to the full
  // basis: zeta = E x.
  const Eigen::MatrixXd F = Q * model.E;
  return modal_response(model.w2, F, h, Start::QuasiStatic) * model.E.transpose();
}

double quasi_static_error(const ModalModel &model, const Eigen::MatrixXd &M,
                          const Eigen::MatrixXd &Z, const Eigen::MatrixXd &Q) {
  const Eigen::MatrixXd X = Z * M * model.E; // rows x(t_n)^T = zeta^T M E
  const Eigen::MatrixXd Xqs = (Q * model.E) * model.w2.cwiseInverse().asDiagonal();
  const Eigen::VectorXd w = model.w2.cwiseSqrt();
  const double top = (X * w.asDiagonal()).rowwise().norm().maxCoeff();
  return top > 0 ? ((X - Xqs) * w.asDiagonal()).rowwise().norm().maxCoeff() / top : 0.0;
}

Eigen::MatrixXd ked_response_varying(const Eigen::MatrixXd &K,
                                     const std::vector<Eigen::MatrixXd> &G,
                                     const Eigen::MatrixXd &coefficients, const Eigen::MatrixXd &Q,
                                     double h, Start start, double *lowest) {
  const Eigen::Index steps = Q.rows(), n = Q.cols();
  auto stiffness = [&](Eigen::Index i, Eigen::Index j) {
    // K + sum_r (c_r(t_i) + c_r(t_j)) / 2 G_r, symmetrized.
    Eigen::MatrixXd S = K;
    for (std::size_t r = 0; r < G.size(); ++r)
      S += 0.5 *
           (coefficients(i, static_cast<Eigen::Index>(r)) +
            coefficients(j, static_cast<Eigen::Index>(r))) *
           G[r];
    return Eigen::MatrixXd(0.5 * (S + S.transpose()));
  };
  if (lowest) *lowest = std::numeric_limits<double>::infinity();
  Eigen::MatrixXd Z = Eigen::MatrixXd::Zero(steps, n);
  if (steps == 0) return Z;
  // The quasi-static start in the stiffness of t = 0.
  const Eigen::MatrixXd S0 = stiffness(0, 0);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig0(S0);
  if (lowest) *lowest = eig0.eigenvalues()(0);
  if (!(eig0.eigenvalues()(0) > 0)) return Z;
  Eigen::VectorXd z = Eigen::VectorXd::Zero(n), zd = Eigen::VectorXd::Zero(n);
  if (start == Start::QuasiStatic) {
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(S0);
    z = ldlt.solve(Q.row(0).transpose());
    if (steps > 1) zd = ldlt.solve((Q.row(1) - Q.row(0)).transpose() / h);
  }
  Z.row(0) = z.transpose();
  for (Eigen::Index i = 0; i + 1 < steps; ++i) {
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(stiffness(i, i + 1));
    const Eigen::VectorXd &w2 = eig.eigenvalues();
    if (lowest) *lowest = std::min(*lowest, w2(0));
    if (!(w2(0) > 0)) return Z;
    const Eigen::MatrixXd &E = eig.eigenvectors();
    Eigen::VectorXd x = E.transpose() * z, v = E.transpose() * zd;
    const Eigen::VectorXd f0 = E.transpose() * Q.row(i).transpose(),
                          f1 = E.transpose() * Q.row(i + 1).transpose();
    for (Eigen::Index k = 0; k < n; ++k)
      StepCoefficients(w2(k), h).advance(x(k), v(k), f0(k), f1(k));
    z = E * x, zd = E * v;
    Z.row(i + 1) = z.transpose();
  }
  return Z;
}

} // namespace flexopt::plan
