#include "flexopt/joints/equation.hpp"

#include <cmath>

namespace flexopt::joints {

namespace {

using Mat37 = Eigen::Matrix<double, 3, 7>;

Vec4 euler(const Vector &q, int b) {
  return q.segment<4>(7 * b + 3);
}

/// 3 x 7 Jacobian of a body point (zero for the ground).
Mat37 point_jacobian(const Vector &q, int b, const Vec3 &s) {
  Mat37 j = Mat37::Zero();
  if (b < 0) return j;
  j.leftCols<3>().setIdentity();
  j.rightCols<4>() = bodies::rotate_jacobian(euler(q, b), s);
  return j;
}

/// 3 x 7 Jacobian of a body vector.
Mat37 vector_jacobian(const Vector &q, int b, const Vec3 &u) {
  Mat37 j = Mat37::Zero();
  if (b < 0) return j;
  j.rightCols<4>() = bodies::rotate_jacobian(euler(q, b), u);
  return j;
}

/// H_bb += d^2 (w . A(p_b) u) / dp_b^2 (points and vectors alike: r enters linearly).
void add_rotation_hessian(Sink &H, int b, const Vec3 &u, const Vec3 &w) {
  if (b < 0) return;
  Block7 B = Block7::Zero();
  B.bottomRightCorner<4, 4>() = bodies::rotate_hessian(u, w);
  H.add_block(b, b, B);
}

/// H_ab += B, H_ba += B^T for a 7 x 7 cross block (both bodies moving).
void add_cross(Sink &H, int a, int b, const Block7 &B) {
  if (a < 0 || b < 0) return;
  H.add_block(a, b, B);
  H.add_block(b, a, B.transpose());
}

void add_row(Sink &J, int row, int b, const Row7 &g) {
  if (b < 0) return;
  J.add_row(row, b, g);
}

/// The driver's rotating vector u(t) = sin f u1 - cos f u2 and its first two time derivatives.
void driver_vectors(const Equation &e, double t, Vec3 &u, Vec3 &ut, Vec3 &utt) {
  const double f = (*e.driver)(t), fd = e.driver->derivative(t),
               fdd = e.driver->second_derivative(t);
  const double s = std::sin(f), c = std::cos(f);
  u = s * e.ua - c * e.ua2;
  const Vec3 du = c * e.ua + s * e.ua2; // d u / d f
  const Vec3 ddu = -s * e.ua + c * e.ua2;
  ut = fd * du;
  utt = fdd * du + fd * fd * ddu;
}

} // namespace

Vec3 point_position(const Vector &q, int b, const Vec3 &s) {
  if (b < 0) return s;
  return q.segment<3>(7 * b) + bodies::rotation(euler(q, b)) * s;
}

Vec3 vector_direction(const Vector &q, int b, const Vec3 &u) {
  if (b < 0) return u;
  return bodies::rotation(euler(q, b)) * u;
}

void Equation::value(const Vector &q, double t, double *out) const {
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 d = point_position(q, a, sa) - point_position(q, b, sb);
    out[0] = d(0), out[1] = d(1), out[2] = d(2);
    return;
  }
  case Kind::Perpendicular:
    out[0] = vector_direction(q, a, ua).dot(vector_direction(q, b, vb)) - c;
    return;
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const Vec3 d = point_position(q, b, sb) - point_position(q, a, sa);
    out[0] = vector_direction(q, a, ua).dot(d) - c;
    if (kind == Kind::TranslationDriver) out[0] -= (*driver)(t);
    return;
  }
  case Kind::Normalize:
    out[0] = 0.5 * (euler(q, a).squaredNorm() - 1);
    return;
  case Kind::RotationDriver: {
    Vec3 u, ut, utt;
    driver_vectors(*this, t, u, ut, utt);
    out[0] = vector_direction(q, a, u).dot(vector_direction(q, b, vb));
    return;
  }
  }
}

void Equation::gradient(const Vector &q, double t, Sink &J, int row) const {
  switch (kind) {
  case Kind::Coincide: {
    const Mat37 ja = point_jacobian(q, a, sa), jb = point_jacobian(q, b, sb);
    for (int k = 0; k < 3; ++k) {
      add_row(J, row + k, a, ja.row(k));
      add_row(J, row + k, b, -jb.row(k));
    }
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: {
    Vec3 uu = ua, ut, utt;
    if (kind == Kind::RotationDriver) driver_vectors(*this, t, uu, ut, utt);
    const Vec3 u = vector_direction(q, a, uu), v = vector_direction(q, b, vb);
    add_row(J, row, a, v.transpose() * vector_jacobian(q, a, uu));
    add_row(J, row, b, u.transpose() * vector_jacobian(q, b, vb));
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const Vec3 u = vector_direction(q, a, ua);
    const Vec3 d = point_position(q, b, sb) - point_position(q, a, sa);
    add_row(J, row, a,
            d.transpose() * vector_jacobian(q, a, ua) - u.transpose() * point_jacobian(q, a, sa));
    add_row(J, row, b, u.transpose() * point_jacobian(q, b, sb));
    return;
  }
  case Kind::Normalize:
    Row7 g = Row7::Zero();
    g.tail<4>() = euler(q, a).transpose();
    J.add_row(row, a, g);
    return;
  }
}

void Equation::add_hessian(const Vector &q, double t, const double *lambda, Sink &H) const {
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 l(lambda[0], lambda[1], lambda[2]);
    add_rotation_hessian(H, a, sa, l);
    add_rotation_hessian(H, b, sb, -l);
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: {
    Vec3 uu = ua, ut, utt;
    if (kind == Kind::RotationDriver) driver_vectors(*this, t, uu, ut, utt);
    const double l = lambda[0];
    const Vec3 u = vector_direction(q, a, uu), v = vector_direction(q, b, vb);
    add_rotation_hessian(H, a, uu, l * v);
    add_rotation_hessian(H, b, vb, l * u);
    add_cross(H, a, b, l * vector_jacobian(q, a, uu).transpose() * vector_jacobian(q, b, vb));
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const double l = lambda[0];
    const Vec3 u = vector_direction(q, a, ua);
    const Vec3 d = point_position(q, b, sb) - point_position(q, a, sa);
    const Mat37 Ju = vector_jacobian(q, a, ua), Jxa = point_jacobian(q, a, sa),
                Jxb = point_jacobian(q, b, sb);
    add_rotation_hessian(H, a, ua, l * d);
    add_rotation_hessian(H, a, sa, -l * u);
    if (a >= 0) H.add_block(a, a, -l * (Ju.transpose() * Jxa + Jxa.transpose() * Ju));
    add_rotation_hessian(H, b, sb, l * u);
    add_cross(H, a, b, l * Ju.transpose() * Jxb);
    return;
  }
  case Kind::Normalize:
    Block7 B = Block7::Zero();
    B.bottomRightCorner<4, 4>() = lambda[0] * Mat4::Identity();
    H.add_block(a, a, B);
    return;
  }
}

void Equation::time_derivatives(const Vector &q, const Vector &v, double t, double *phi_t,
                                double *phi_tt, double *phi_qt_v) const {
  const int n = rows();
  for (int i = 0; i < n; ++i) phi_t[i] = phi_tt[i] = phi_qt_v[i] = 0;
  if (kind == Kind::TranslationDriver) {
    phi_t[0] = -driver->derivative(t);
    phi_tt[0] = -driver->second_derivative(t);
  } else if (kind == Kind::RotationDriver) {
    Vec3 u, ut, utt;
    driver_vectors(*this, t, u, ut, utt);
    const Vec3 w = vector_direction(q, b, vb);
    phi_t[0] = vector_direction(q, a, ut).dot(w);
    phi_tt[0] = vector_direction(q, a, utt).dot(w);
    // d/dt of the gradient rows [w^T D(p_a, u), (A_a u)^T D(p_b, v)], applied to v.
    double s = 0;
    if (a >= 0) s += w.dot(vector_jacobian(q, a, ut) * v.segment<7>(7 * a));
    if (b >= 0)
      s += vector_direction(q, a, ut).dot(vector_jacobian(q, b, vb) * v.segment<7>(7 * b));
    phi_qt_v[0] = s;
  }
}

} // namespace flexopt::joints
