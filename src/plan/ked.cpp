#include "flexopt/plan/ked.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>

namespace flexopt::plan {

Eigen::MatrixXd modal_response(const Eigen::VectorXd &w2, const Eigen::MatrixXd &F, double h,
                               Start start) {
  const Eigen::Index steps = F.rows(), n = F.cols();
  Eigen::MatrixXd X = Eigen::MatrixXd::Zero(steps, n);
  for (Eigen::Index k = 0; k < n; ++k) {
    // Over one step with f = f0 + (f1 - f0) tau / h (unit mass, stiffness w^2):
    //   x(tau) = x0 c + v0 s / w + f0 (1 - c) / w^2 + (f1 - f0) (tau - s / w) / (w^2 h),
    //   v(tau) = -x0 w s + v0 c + f0 s / w + (f1 - f0) (1 - c) / (w^2 h),
    // c = cos(w tau), s = sin(w tau).
    const double w = std::sqrt(w2(k)), c = std::cos(w * h), s = std::sin(w * h);
    double x = 0, v = 0;
    if (start == Start::QuasiStatic) {
      x = F(0, k) / w2(k);
      v = steps > 1 ? (F(1, k) - F(0, k)) / (h * w2(k)) : 0.0;
      X(0, k) = x;
    }
    for (Eigen::Index i = 0; i + 1 < steps; ++i) {
      const double f0 = F(i, k), df = F(i + 1, k) - f0;
      const double xn = x * c + v * s / w + f0 * (1 - c) / w2(k) + df * (h - s / w) / (w2(k) * h);
      const double vn = -x * w * s + v * c + f0 * s / w + df * (1 - c) / (w2(k) * h);
      x = xn, v = vn;
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

} // namespace flexopt::plan
