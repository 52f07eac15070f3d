#include "flexopt/joints/equation.hpp"

#include <cmath>

namespace flexopt::joints {

namespace {

using Mat4X =
    Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::ColMajor, 4, bodies::kMaxBodyCoordinates>;
using MatX4 =
    Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::ColMajor, bodies::kMaxBodyCoordinates, 4>;

/// One side of an equation: a body (or the ground) with its coordinate block.
struct Side {
  BodyRef ref;
  int n = 0; ///< elastic coordinates
  const Vector &q;
  Side(const Vector &q_, int body, int offset, int elastic) : n(elastic), q(q_) {
    ref.index = body;
    ref.offset = offset;
  }
  bool ground() const { return ref.index < 0; }
  int size() const { return 7 + n; }
  Vec4 p() const { return q.segment<4>(ref.offset + 3); }
  /// s + S zeta in body axes.
  Vec3 local(const Vec3 &s, const Elastic &S) const {
    if (n == 0) return s;
    return s + S * q.segment(ref.offset + 7, n);
  }
  Vec3 point(const Vec3 &s, const Elastic &S) const {
    if (ground()) return s;
    return q.segment<3>(ref.offset) + bodies::rotation(p()) * local(s, S);
  }
  Vec3 vector(const Vec3 &u, const Elastic &U) const {
    if (ground()) return u;
    return bodies::rotation(p()) * local(u, U);
  }
  /// [I, D(p, s + S zeta), A S] for points (translation = true), [0, D, A U] for vectors.
  Jacobian jacobian(const Vec3 &s, const Elastic &S, bool translation) const {
    if (ground()) return Jacobian(3, 0);
    Jacobian j = Jacobian::Zero(3, size());
    if (translation) j.leftCols<3>().setIdentity();
    const Vec4 pp = p();
    j.middleCols<4>(3) = bodies::rotate_jacobian(pp, local(s, S));
    if (n > 0) j.rightCols(n) = bodies::rotation(pp) * S;
    return j;
  }
  Vec3 velocity_of_vector(const Vec3 &u, const Elastic &U, const Vector &v) const {
    if (ground()) return Vec3::Zero();
    return jacobian(u, U, false) * v.segment(ref.offset, size());
  }
};

/// H_bb += d^2 (w . A(p_b) (s + S zeta_b)) / dq_b^2 (points and vectors alike: r enters
/// linearly).
void add_rotation_hessian(Sink &H, const Side &b, const Vec3 &s, const Elastic &S, const Vec3 &w) {
  if (b.ground()) return;
  const Mat4 pp = bodies::rotate_hessian(b.local(s, S), w);
  H.add_block(b.ref, b.ref, 3, 3, pp);
  if (b.n == 0) return;
  const Vec4 p = b.p();
  Mat4X pz(4, b.n);
  for (int l = 0; l < b.n; ++l) pz.col(l) = bodies::rotate_jacobian(p, S.col(l)).transpose() * w;
  const MatX4 zp = pz.transpose();
  H.add_block(b.ref, b.ref, 3, 7, pz);
  H.add_block(b.ref, b.ref, 7, 3, zp);
}

/// H_ab += s X^T Y, H_ba += s Y^T X for a cross term (both bodies moving).
void add_cross(Sink &H, const Side &a, const Side &b, double scale, const Jacobian &X,
               const Jacobian &Y) {
  if (a.ground() || b.ground()) return;
  H.add_product(a.ref, b.ref, scale, X, Y);
  H.add_product(b.ref, a.ref, scale, Y, X);
}

void add_row(Sink &J, int row, const Side &b, const Row &g) {
  if (b.ground()) return;
  J.add_row(row, b.ref, g);
}

/// The driver's rotating vector u(t) = sin f u1 - cos f u2 (and its elastic part) and its
/// first two time derivatives.
struct DriverVectors {
  Vec3 u, ut, utt;
  Elastic U, Ut, Utt;
};
DriverVectors driver_vectors(const Equation &e, double t) {
  const double f = (*e.driver)(t), fd = e.driver->derivative(t),
               fdd = e.driver->second_derivative(t);
  const double s = std::sin(f), c = std::cos(f);
  DriverVectors d;
  d.u = s * e.ua - c * e.ua2;
  const Vec3 du = c * e.ua + s * e.ua2; // d u / d f
  const Vec3 ddu = -s * e.ua + c * e.ua2;
  d.ut = fd * du;
  d.utt = fdd * du + fd * fd * ddu;
  if (e.na > 0) {
    d.U = s * e.Ua - c * e.Ua2;
    const Elastic dU = c * e.Ua + s * e.Ua2, ddU = -s * e.Ua + c * e.Ua2;
    d.Ut = fd * dU;
    d.Utt = fdd * dU + fd * fd * ddU;
  }
  return d;
}

/// The vector on body a of a Perpendicular row (u_a) or of a RotationDriver row (u(t)), with its
/// elastic part.
std::pair<Vec3, Elastic> vector_a(const Equation &e, double t) {
  if (e.kind != Equation::Kind::RotationDriver) return {e.ua, e.Ua};
  DriverVectors dv = driver_vectors(e, t);
  return {dv.u, std::move(dv.U)};
}

int elastic(const Elastic &M) {
  return static_cast<int>(M.cols());
}

} // namespace

Vec3 anchor_position(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S) {
  const Vec3 local = S.cols() > 0 ? Vec3(s + S * q_b.tail(S.cols())) : s;
  return q_b.head<3>() + bodies::rotation(q_b.segment<4>(3)) * local;
}

Jacobian anchor_jacobian(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S) {
  const Vector q = q_b;
  return Side(q, 0, 0, elastic(S)).jacobian(s, S, true);
}

void anchor_hessian(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S,
                    const Vec3 &w, Mat4 &pp, Eigen::Matrix<double, 4, Eigen::Dynamic> &pz) {
  const int n = elastic(S);
  const Vec4 p = q_b.segment<4>(3);
  const Vec3 local = n > 0 ? Vec3(s + S * q_b.tail(n)) : s;
  pp = bodies::rotate_hessian(local, w);
  pz.resize(4, n);
  for (int l = 0; l < n; ++l) pz.col(l) = bodies::rotate_jacobian(p, S.col(l)).transpose() * w;
}

void Equation::value(const Vector &q, double t, double *out) const {
  const Side A(q, a, oa, na), B(q, b, ob, nb);
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 d = A.point(sa, Sa) - B.point(sb, Sb);
    out[0] = d(0), out[1] = d(1), out[2] = d(2);
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: { // c = 0 for drivers
    const auto [u, U] = vector_a(*this, t);
    out[0] = A.vector(u, U).dot(B.vector(vb, Vb)) - c;
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const Vec3 d = B.point(sb, Sb) - A.point(sa, Sa);
    out[0] = A.vector(ua, Ua).dot(d) - c;
    if (kind == Kind::TranslationDriver) out[0] -= (*driver)(t);
    return;
  }
  case Kind::Normalize:
    out[0] = 0.5 * (A.p().squaredNorm() - 1);
    return;
  }
}

void Equation::gradient(const Vector &q, double t, Sink &J, int row) const {
  const Side A(q, a, oa, na), B(q, b, ob, nb);
  switch (kind) {
  case Kind::Coincide: {
    const Jacobian ja = A.jacobian(sa, Sa, true), jb = B.jacobian(sb, Sb, true);
    for (int k = 0; k < 3; ++k) {
      if (!A.ground()) add_row(J, row + k, A, ja.row(k));
      if (!B.ground()) add_row(J, row + k, B, -jb.row(k));
    }
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: {
    const auto [uu, UU] = vector_a(*this, t);
    const Vec3 u = A.vector(uu, UU), v = B.vector(vb, Vb);
    if (!A.ground()) add_row(J, row, A, v.transpose() * A.jacobian(uu, UU, false));
    if (!B.ground()) add_row(J, row, B, u.transpose() * B.jacobian(vb, Vb, false));
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const Vec3 u = A.vector(ua, Ua);
    const Vec3 d = B.point(sb, Sb) - A.point(sa, Sa);
    if (!A.ground())
      add_row(J, row, A,
              d.transpose() * A.jacobian(ua, Ua, false) - u.transpose() * A.jacobian(sa, Sa, true));
    if (!B.ground()) add_row(J, row, B, u.transpose() * B.jacobian(sb, Sb, true));
    return;
  }
  case Kind::Normalize:
    Row g = Row::Zero(A.size());
    g.segment<4>(3) = A.p().transpose();
    J.add_row(row, A.ref, g);
    return;
  }
}

void Equation::add_hessian(const Vector &q, double t, const double *lambda, Sink &H) const {
  const Side A(q, a, oa, na), B(q, b, ob, nb);
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 l(lambda[0], lambda[1], lambda[2]);
    add_rotation_hessian(H, A, sa, Sa, l);
    add_rotation_hessian(H, B, sb, Sb, -l);
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: {
    const auto [uu, UU] = vector_a(*this, t);
    const double l = lambda[0];
    const Vec3 u = A.vector(uu, UU), v = B.vector(vb, Vb);
    add_rotation_hessian(H, A, uu, UU, l * v);
    add_rotation_hessian(H, B, vb, Vb, l * u);
    if (!A.ground() && !B.ground())
      add_cross(H, A, B, l, A.jacobian(uu, UU, false), B.jacobian(vb, Vb, false));
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const double l = lambda[0];
    const Vec3 u = A.vector(ua, Ua);
    const Vec3 d = B.point(sb, Sb) - A.point(sa, Sa);
    add_rotation_hessian(H, A, ua, Ua, l * d);
    add_rotation_hessian(H, A, sa, Sa, -l * u);
    add_rotation_hessian(H, B, sb, Sb, l * u);
    if (!A.ground()) {
      const Jacobian Ju = A.jacobian(ua, Ua, false), Jxa = A.jacobian(sa, Sa, true);
      H.add_product(A.ref, A.ref, -l, Ju, Jxa);
      H.add_product(A.ref, A.ref, -l, Jxa, Ju);
      if (!B.ground()) add_cross(H, A, B, l, Ju, B.jacobian(sb, Sb, true));
    }
    return;
  }
  case Kind::Normalize:
    H.add_block(A.ref, A.ref, 3, 3, lambda[0] * Mat4::Identity());
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
    const Side A(q, a, oa, na), B(q, b, ob, nb);
    const DriverVectors dv = driver_vectors(*this, t);
    const Vec3 w = B.vector(vb, Vb);
    phi_t[0] = A.vector(dv.ut, dv.Ut).dot(w);
    phi_tt[0] = A.vector(dv.utt, dv.Utt).dot(w);
    // d/dt of the gradient rows [w^T J_a(u_t), (A_a u_t)^T J_b(v)], applied to v.
    phi_qt_v[0] = w.dot(A.velocity_of_vector(dv.ut, dv.Ut, v)) +
                  A.vector(dv.ut, dv.Ut).dot(B.velocity_of_vector(vb, Vb, v));
  }
}

} // namespace flexopt::joints
