#include "flexopt/bodies/body.hpp"

namespace flexopt::bodies {

Vector Body::placement(const Vec3 &origin_world, const Mat3 &R) const {
  Vector q = Vector::Zero(coordinates());
  q.head<3>() = origin_world + R * origin();
  q.segment<4>(3) = from_matrix(R);
  return q;
}

Vector Body::placement_velocity(const Vector &q, const Vec3 &velocity, const Vec3 &omega) const {
  const Vec4 p = q.segment<4>(3);
  const Mat3 R = rotation(p);
  Vector v = Vector::Zero(coordinates());
  v.head<3>() = velocity + omega.cross(R * origin());
  v.segment<4>(3) = 0.5 * g_matrix(p).transpose() * omega; // omega = 2 G p', p' _|_ p
  return v;
}

} // namespace flexopt::bodies
