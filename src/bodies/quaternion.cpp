#include "flexopt/bodies/quaternion.hpp"

#include <cmath>

namespace flexopt::bodies {

Mat3 rotation(const Vec4 &p) {
  const double e0 = p(0);
  const Vec3 e = p.tail<3>();
  return (e0 * e0 - e.dot(e)) * Mat3::Identity() + 2 * e * e.transpose() + 2 * e0 * skew(e);
}

Mat34 g_matrix(const Vec4 &p) {
  Mat34 g;
  g.col(0) = -p.tail<3>();
  g.rightCols<3>() = skew(p.tail<3>()) + p(0) * Mat3::Identity();
  return g;
}

Mat34 gbar_matrix(const Vec4 &p) {
  Mat34 g;
  g.col(0) = -p.tail<3>();
  g.rightCols<3>() = -skew(p.tail<3>()) + p(0) * Mat3::Identity();
  return g;
}

// A u = (e0^2 - e.e) u + 2 e (e.u) + 2 e0 (e x u):
//   d/de0 = 2 e0 u + 2 e x u,   d/de = 2 (e.u) I + 2 e u^T - 2 u e^T - 2 e0 [u]x.
Mat34 rotate_jacobian(const Vec4 &p, const Vec3 &u) {
  const double e0 = p(0);
  const Vec3 e = p.tail<3>();
  Mat34 d;
  d.col(0) = 2 * (e0 * u + e.cross(u));
  d.rightCols<3>() =
      2 * (e.dot(u) * Mat3::Identity() + e * u.transpose() - u * e.transpose() - e0 * skew(u));
  return d;
}

Mat4 rotate_hessian(const Vec3 &u, const Vec3 &w) {
  // D(p, u)^T w = 2 [e0 (u.w) + e.(u x w) ; (e.u) w + (e.w) u - (u.w) e + e0 (u x w)], linear
  // in p, so its derivative is the constant symmetric matrix
  //   K = 2 [[u.w, (u x w)^T], [u x w, w u^T + u w^T - (u.w) I]].
  const double uw = u.dot(w);
  const Vec3 c = u.cross(w);
  Mat4 k;
  k(0, 0) = 2 * uw;
  k.block<1, 3>(0, 1) = 2 * c.transpose();
  k.block<3, 1>(1, 0) = 2 * c;
  k.block<3, 3>(1, 1) = 2 * (w * u.transpose() + u * w.transpose() - uw * Mat3::Identity());
  return k;
}

Mat4 gbar_transpose_matrix(const Vec3 &w) {
  // Gbar(p)^T w = [-e.w ; e0 w + e x w] = [[0, -w^T], [w, -[w]x]] p.
  Mat4 t = Mat4::Zero();
  t.block<1, 3>(0, 1) = -w.transpose();
  t.block<3, 1>(1, 0) = w;
  t.block<3, 3>(1, 1) = -skew(w);
  return t;
}

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
