#pragma once
/// \file Euler parameters p = (e0, e1, e2, e3) and the matrices of rigid-body kinematics
/// (Haug 1989, ch. 6; Nikravesh 1988, ch. 6), as used by the rigid bodies and the joints
/// (docs/theory.md section 6.1).
///
/// The rotation matrix is the quadratic form A(p) = (e0^2 - e.e) I + 2 e e^T + 2 e0 [e]x, which is
/// orthogonal when |p| = 1 (enforced as a constraint); for other p it is still the polynomial
/// that the Jacobians below differentiate exactly.
#include <Eigen/Dense>

namespace flexopt::bodies {

using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Mat3 = Eigen::Matrix3d;
using Mat34 = Eigen::Matrix<double, 3, 4>;
using Mat4 = Eigen::Matrix4d;

/// [a]x: the cross-product matrix, [a]x b = a x b.
inline Mat3 skew(const Vec3 &a) {
  Mat3 s;
  s << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return s;
}

// The kinematic matrices are inline: the joints and bodies evaluate them several times per
// Newton iteration, and small fixed-size products fold together when the compiler sees them.

/// A(p) (body to world).
inline Mat3 rotation(const Vec4 &p) {
  const double e0 = p(0);
  const Vec3 e = p.tail<3>();
  return (e0 * e0 - e.dot(e)) * Mat3::Identity() + 2 * e * e.transpose() + 2 * e0 * skew(e);
}
/// G(p) = [-e, [e]x + e0 I]: world angular velocity omega = 2 G(p) p'.
inline Mat34 g_matrix(const Vec4 &p) {
  Mat34 g;
  g.col(0) = -p.tail<3>();
  g.rightCols<3>() = skew(p.tail<3>()) + p(0) * Mat3::Identity();
  return g;
}
/// Gbar(p) = [-e, -[e]x + e0 I]: body angular velocity omega_bar = 2 Gbar(p) p'.
inline Mat34 gbar_matrix(const Vec4 &p) {
  Mat34 g;
  g.col(0) = -p.tail<3>();
  g.rightCols<3>() = -skew(p.tail<3>()) + p(0) * Mat3::Identity();
  return g;
}
/// D(p, u) = d(A(p) u)/dp for a body-fixed vector u (3 x 4, linear in p).
// A u = (e0^2 - e.e) u + 2 e (e.u) + 2 e0 (e x u):
//   d/de0 = 2 e0 u + 2 e x u,   d/de = 2 (e.u) I + 2 e u^T - 2 u e^T - 2 e0 [u]x.
inline Mat34 rotate_jacobian(const Vec4 &p, const Vec3 &u) {
  const double e0 = p(0);
  const Vec3 e = p.tail<3>();
  Mat34 d;
  d.col(0) = 2 * (e0 * u + e.cross(u));
  d.rightCols<3>() =
      2 * (e.dot(u) * Mat3::Identity() + e * u.transpose() - u * e.transpose() - e0 * skew(u));
  return d;
}
/// d(A(p)^T w)/dp (3 x 4): A(p)^T = A(p*) with p* = (e0, -e). Also D(p, u)^T w = R^T u, as
/// w . A u = (A^T w) . u.
inline Mat34 rotate_transpose_jacobian(const Vec4 &p, const Vec3 &w) {
  const Vec4 conj(p(0), -p(1), -p(2), -p(3));
  Mat34 d = rotate_jacobian(conj, w);
  d.rightCols<3>() *= -1;
  return d;
}
/// K(u, w) = d/dp (D(p, u)^T w) (4 x 4, independent of p): the second derivative of w.(A(p) u).
inline Mat4 rotate_hessian(const Vec3 &u, const Vec3 &w) {
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
/// T(w) with Gbar(p)^T w = T(w) p (4 x 4): Gbar^T is linear in p.
inline Mat4 gbar_transpose_matrix(const Vec3 &w) {
  // Gbar(p)^T w = [-e.w ; e0 w + e x w] = [[0, -w^T], [w, -[w]x]] p.
  Mat4 t = Mat4::Zero();
  t.block<1, 3>(0, 1) = -w.transpose();
  t.block<3, 1>(1, 0) = w;
  t.block<3, 3>(1, 1) = -skew(w);
  return t;
}
/// Euler parameters of the rotation by `angle` about the unit vector `axis`.
Vec4 from_axis_angle(const Vec3 &axis, double angle);
/// Euler parameters of an orthogonal matrix (Shepperd's method), e0 >= 0.
Vec4 from_matrix(const Mat3 &R);
/// The rotation vector (axis times angle in [0, pi]) of an orthogonal matrix.
Vec3 rotation_vector(const Mat3 &R);

} // namespace flexopt::bodies
