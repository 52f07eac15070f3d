// The responses of a dynamic analysis on the time grid (docs/theory.md section 9.3): the
// trapezoidal weights, each response's value and dPsi/dy_n from its sensor samples, and a
// sensor's dy/dq.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/expression.hpp"

#include <array>
#include <cmath>
#include <limits>
#include <sstream>

namespace flexopt::adjoint {

double trapezoid_weight(std::size_t n, std::size_t N) {
  if (N == 0) return 1.0;
  return (n == 0 || n == N ? 0.5 : 1.0) / static_cast<double>(N);
}

SampledResponse sampled_response(const optimize::ResponseSettings &r, const std::vector<Vec3> &y,
                                 double h) {
  SampledResponse out;
  const std::size_t N = y.size() - 1;
  out.dy.assign(y.size(), Vec3::Zero());
  auto weight = [&](std::size_t n) { return trapezoid_weight(n, N); };
  const int K = r.component;
  if (r.type == optimize::ResponseType::TrackingError) {
    std::array<Expression, 3> target;
    for (int k = 0; k < 3; ++k)
      target[static_cast<std::size_t>(k)] = Expression(r.target[static_cast<std::size_t>(k)]);
    for (std::size_t n = 0; n <= N; ++n) {
      const double t = static_cast<double>(n) * h;
      Vec3 e;
      for (int k = 0; k < 3; ++k) {
        const double yt = target[static_cast<std::size_t>(k)](t);
        if (!std::isfinite(yt)) {
          std::ostringstream msg;
          msg << r.where.str() << ": tracking_error: target[" << k << "] = '"
              << r.target[static_cast<std::size_t>(k)] << "' is not finite at t = " << t << " s";
          throw Error(msg.str(), true);
        }
        e(k) = y[n](k) - yt;
      }
      out.value += weight(n) * e.squaredNorm();
      out.dy[n] = 2 * weight(n) * e;
    }
    return out;
  }
  // type sensor
  if (r.measure == optimize::SensorMeasure::Final) {
    out.value = y[N](K);
    out.dy[N](K) = 1;
  } else if (r.measure == optimize::SensorMeasure::MeanSquare) {
    for (std::size_t n = 0; n <= N; ++n) {
      out.value += weight(n) * y[n](K) * y[n](K);
      out.dy[n](K) = 2 * weight(n) * y[n](K);
    }
  } else { // ks_max
    double Y = -std::numeric_limits<double>::infinity();
    for (const Vec3 &v : y) Y = std::max(Y, v(K));
    double sum = 0;
    std::vector<double> e(N + 1);
    for (std::size_t n = 0; n <= N; ++n) {
      e[n] = weight(n) * std::exp(r.ks * (y[n](K) - Y));
      sum += e[n];
    }
    out.value = Y + std::log(sum) / r.ks;
    for (std::size_t n = 0; n <= N; ++n) out.dy[n](K) = e[n] / sum;
  }
  return out;
}

/// dy/dq of a sensor of a rigid or FFRF body at q (3 x n, the body's columns only).
Matrix sensor_jacobian(const dynamics::Scene &scene, const dynamics::BoundSensor &s,
                       const Vector &q) {
  const dynamics::Mechanism &mech = scene.mechanism;
  const int o = mech.offset(s.body), nb = mech.size(s.body);
  Matrix D = Matrix::Zero(3, mech.coordinates());
  if (s.quantity == dynamics::SensorQuantity::ElasticDisplacement) {
    if (nb > 7) D.block(0, o + 7, 3, nb - 7) = s.S;
    return D;
  }
  D.block(0, o, 3, nb) = joints::anchor_jacobian(q.segment(o, nb), s.s, s.S);
  return D;
}

} // namespace flexopt::adjoint
