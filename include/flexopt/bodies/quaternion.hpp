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

/// A(p) (body to world).
Mat3 rotation(const Vec4 &p);
/// G(p) = [-e, [e]x + e0 I]: world angular velocity omega = 2 G(p) p'.
Mat34 g_matrix(const Vec4 &p);
/// Gbar(p) = [-e, -[e]x + e0 I]: body angular velocity omega_bar = 2 Gbar(p) p'.
Mat34 gbar_matrix(const Vec4 &p);
/// D(p, u) = d(A(p) u)/dp for a body-fixed vector u (3 x 4, linear in p).
Mat34 rotate_jacobian(const Vec4 &p, const Vec3 &u);
/// K(u, w) = d/dp (D(p, u)^T w) (4 x 4, independent of p): the second derivative of w.(A(p) u).
Mat4 rotate_hessian(const Vec3 &u, const Vec3 &w);
/// T(w) with Gbar(p)^T w = T(w) p (4 x 4): Gbar^T is linear in p.
Mat4 gbar_transpose_matrix(const Vec3 &w);
/// Euler parameters of the rotation by `angle` about the unit vector `axis`.
Vec4 from_axis_angle(const Vec3 &axis, double angle);
/// Euler parameters of an orthogonal matrix (Shepperd's method), e0 >= 0.
Vec4 from_matrix(const Mat3 &R);
/// The rotation vector (axis times angle in [0, pi]) of an orthogonal matrix.
Vec3 rotation_vector(const Mat3 &R);

} // namespace flexopt::bodies
