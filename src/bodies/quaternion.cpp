#include "flexopt/bodies/quaternion.hpp"

#include <cmath>

namespace flexopt::bodies {

Vec4 from_axis_angle(const Vec3 &axis, double angle) {
  Vec4 p;
  p(0) = std::cos(0.5 * angle);
  p.tail<3>() = std::sin(0.5 * angle) * axis.normalized();
  return p;
}

Vec4 from_matrix(const Mat3 &R) {
  const double tr = R.trace();
  Vec4 p;
  if (tr >= R(0, 0) && tr >= R(1, 1) && tr >= R(2, 2)) {
    p(0) = 0.5 * std::sqrt(1 + tr);
    const double s = 0.25 / p(0);
    p(1) = (R(2, 1) - R(1, 2)) * s;
    p(2) = (R(0, 2) - R(2, 0)) * s;
    p(3) = (R(1, 0) - R(0, 1)) * s;
  } else {
    int i = 0;
    if (R(1, 1) > R(i, i)) i = 1;
    if (R(2, 2) > R(i, i)) i = 2;
    const int j = (i + 1) % 3, k = (i + 2) % 3;
    const double ei = 0.5 * std::sqrt(1 + 2 * R(i, i) - tr);
    const double s = 0.25 / ei;
    p(0) = (R(k, j) - R(j, k)) * s;
    p(1 + i) = ei;
    p(1 + j) = (R(j, i) + R(i, j)) * s;
    p(1 + k) = (R(k, i) + R(i, k)) * s;
  }
  if (p(0) < 0) p = -p;
  return p;
}

Vec3 rotation_vector(const Mat3 &R) {
  const Vec4 p = from_matrix(R); // e0 = cos(angle / 2) >= 0, so angle in [0, pi]
  const double s = p.tail<3>().norm();
  if (s < 1e-300) return Vec3::Zero();
  const double angle = 2 * std::atan2(s, p(0));
  return (angle / s) * p.tail<3>();
}

} // namespace flexopt::bodies
