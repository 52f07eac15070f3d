#include "flexopt/joints/equation.hpp"

#include <cmath>

namespace flexopt::joints {

namespace {

using Mat4X =
    Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::ColMajor, 4, bodies::kMaxBodyCoordinates>;
using MatX4 =
    Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::ColMajor, bodies::kMaxBodyCoordinates, 4>;

/// One side of an equation: a body (or the ground) with its coordinate block. The rotation
/// matrix is computed once per side and evaluation (the primitives use it several times).
struct Side {
  BodyRef ref;
  int n = 0; ///< elastic coordinates
  const Vector &q;
  Vec4 p_ = Vec4::Zero();
  Mat3 A_ = Mat3::Identity();
  /// `rotations`: A(p) of every body, precomputed by the caller, or null.
  Side(const Vector &q_, int body, int offset, int elastic, const Mat3 *rotations = nullptr)
      : n(elastic), q(q_) {
    ref.index = body;
    ref.offset = offset;
    if (body >= 0) {
      p_ = q.segment<4>(offset + 3);
      A_ = rotations ? rotations[body] : bodies::rotation(p_);
    }
  }
  bool ground() const { return ref.index < 0; }
  int size() const { return 7 + n; }
  const Vec4 &p() const { return p_; }
  /// s + S zeta in body axes.
  Vec3 local(const Vec3 &s, const Elastic &S) const {
    if (n == 0) return s;
    return s + S * q.segment(ref.offset + 7, n);
  }
  /// World point r + A l and vector A l of a body-axes l = s + S zeta (local()); on the ground
  /// l itself.
  Vec3 point_at(const Vec3 &l) const {
    if (ground()) return l;
    return q.segment<3>(ref.offset) + A_ * l;
  }
  Vec3 vector_at(const Vec3 &l) const {
    if (ground()) return l;
    return A_ * l;
  }
  Vec3 point(const Vec3 &s, const Elastic &S) const { return point_at(local(s, S)); }
  Vec3 vector(const Vec3 &u, const Elastic &U) const { return vector_at(local(u, U)); }
  /// [I, D(p, l), A S] for points (translation = true), [0, D, A S] for vectors, l = local().
  Jacobian jacobian_at(const Vec3 &l, const Elastic &S, bool translation) const {
    if (ground()) return Jacobian(3, 0);
    Jacobian j(3, size());
    if (translation)
      j.leftCols<3>().setIdentity();
    else
      j.leftCols<3>().setZero();
    j.middleCols<4>(3) = bodies::rotate_jacobian(p_, l);
    if (n > 0) j.rightCols(n).noalias() = A_ * S;
    return j;
  }
  Jacobian jacobian(const Vec3 &s, const Elastic &S, bool translation) const {
    return jacobian_at(local(s, S), S, translation);
  }
  /// g += w^T d x / dq_b for x = r + A l (translation) or x = A l, l = s + S zeta:
  /// [w, w^T D(p, l), (A^T w)^T S] without forming the Jacobian.
  void add_directional(Row &g, const Vec3 &w, const Vec3 &l, const Elastic &S,
                       bool translation) const {
    if (translation) g.head<3>() += w.transpose();
    g.segment<4>(3).noalias() += w.transpose() * bodies::rotate_jacobian(p_, l);
    if (n > 0) {
      const Vec3 wb = A_.transpose() * w;
      g.tail(n).noalias() += wb.transpose() * S;
    }
  }
  Vec3 velocity_of_vector(const Vec3 &u, const Elastic &U, const Vector &v) const {
    if (ground()) return Vec3::Zero();
    return jacobian(u, U, false) * v.segment(ref.offset, size());
  }
};

/// The (p, zeta) block of d^2 (w . A(p) (s + S zeta)): columns D(p, S_l)^T w. As
/// w . A u = (A^T w) . u, D(p, S_l)^T w = R(p, w)^T S_l with R = d(A(p)^T w)/dp: one product
/// for all columns.
template <class Out>
void rotation_elastic_hessian(const Vec4 &p, const Elastic &S, const Vec3 &w, Out &pz) {
  pz.resize(4, S.cols());
  pz.noalias() = bodies::rotate_transpose_jacobian(p, w).transpose() * S;
}

/// H_bb += d^2 (w . A(p_b) (s + S zeta_b)) / dq_b^2 (points and vectors alike: r enters
/// linearly).
void add_rotation_hessian(Sink &H, const Side &b, const Vec3 &s, const Elastic &S, const Vec3 &w) {
  if (b.ground()) return;
  const Mat4 pp = bodies::rotate_hessian(b.local(s, S), w);
  H.add_block(b.ref, b.ref, 3, 3, pp);
  if (b.n == 0) return;
  Mat4X pz;
  rotation_elastic_hessian(b.p(), S, w, pz);
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

/// The driver's rotating vector at the angle f, u = sin f u1 - cos f u2, and its elastic part U
/// (left empty for a rigid body a).
void driver_vector(const Equation &e, double f, Vec3 &u, Elastic &U) {
  const double s = std::sin(f), c = std::cos(f);
  u = s * e.ua - c * e.ua2;
  if (e.na > 0) U = s * e.Ua - c * e.Ua2;
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
  driver_vector(e, f, d.u, d.U);
  const Vec3 du = c * e.ua + s * e.ua2; // d u / d f
  const Vec3 ddu = -s * e.ua + c * e.ua2;
  d.ut = fd * du;
  d.utt = fdd * du + fd * fd * ddu;
  if (e.na > 0) {
    const Elastic dU = c * e.Ua + s * e.Ua2, ddU = -s * e.Ua + c * e.Ua2;
    d.Ut = fd * dU;
    d.Utt = fdd * dU + fd * fd * ddU;
  }
  return d;
}

/// The vector on body a of a Perpendicular row (u_a) or of a RotationDriver row (u(t)) into u,
/// and its elastic part: the equation's own, or the driver's, stored in `storage`. Only f(t)
/// is evaluated (its derivatives are finite differences of several evaluations).
const Elastic &vector_a(const Equation &e, double t, Vec3 &u, Elastic &storage) {
  if (e.kind != Equation::Kind::RotationDriver) {
    u = e.ua;
    return e.Ua;
  }
  driver_vector(e, (*e.driver)(t), u, storage);
  return storage;
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
  rotation_elastic_hessian(p, S, w, pz);
}

void Equation::evaluate(const Vector &q, double t, double *out, Sink *J, int row,
                        const Mat3 *rotations) const {
  const Side A(q, a, oa, na, rotations), B(q, b, ob, nb, rotations);
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 la = A.local(sa, Sa), lb = B.local(sb, Sb);
    const Vec3 d = A.point_at(la) - B.point_at(lb);
    out[0] = d(0), out[1] = d(1), out[2] = d(2);
    if (!J) return;
    if (!A.ground()) {
      const Jacobian ja = A.jacobian_at(la, Sa, true);
      for (int k = 0; k < 3; ++k) J->add_row(row + k, A.ref, ja.row(k));
    }
    if (!B.ground()) {
      const Jacobian jb = B.jacobian_at(lb, Sb, true);
      for (int k = 0; k < 3; ++k) J->add_row(row + k, B.ref, -jb.row(k));
    }
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: { // c = 0 for drivers
    Vec3 uu;
    Elastic storage;
    const Elastic &UU = vector_a(*this, t, uu, storage);
    const Vec3 la = A.local(uu, UU), lb = B.local(vb, Vb);
    const Vec3 u = A.vector_at(la), v = B.vector_at(lb);
    out[0] = u.dot(v) - c;
    if (!J) return;
    if (!A.ground()) {
      Row g = Row::Zero(A.size());
      A.add_directional(g, v, la, UU, false);
      J->add_row(row, A.ref, g);
    }
    if (!B.ground()) {
      Row g = Row::Zero(B.size());
      B.add_directional(g, u, lb, Vb, false);
      J->add_row(row, B.ref, g);
    }
    return;
  }
  case Kind::PointOnPlane:
  case Kind::TranslationDriver: {
    const Vec3 lu = A.local(ua, Ua), lsa = A.local(sa, Sa), lsb = B.local(sb, Sb);
    const Vec3 u = A.vector_at(lu);
    const Vec3 d = B.point_at(lsb) - A.point_at(lsa);
    out[0] = u.dot(d) - c;
    if (kind == Kind::TranslationDriver) out[0] -= (*driver)(t);
    if (!J) return;
    if (!A.ground()) { // d^T d u / dq_a - u^T d x_a / dq_a
      Row g = Row::Zero(A.size());
      A.add_directional(g, d, lu, Ua, false);
      A.add_directional(g, -u, lsa, Sa, true);
      J->add_row(row, A.ref, g);
    }
    if (!B.ground()) {
      Row g = Row::Zero(B.size());
      B.add_directional(g, u, lsb, Sb, true);
      J->add_row(row, B.ref, g);
    }
    return;
  }
  case Kind::Normalize: {
    out[0] = 0.5 * (A.p().squaredNorm() - 1);
    if (!J) return;
    Row g = Row::Zero(A.size());
    g.segment<4>(3) = A.p().transpose();
    J->add_row(row, A.ref, g);
    return;
  }
  case Kind::ElasticCoordinate: {
    out[0] = q(oa + 7 + coordinate);
    if (!J) return;
    Row g = Row::Zero(A.size());
    g(7 + coordinate) = 1;
    J->add_row(row, A.ref, g);
    return;
  }
  }
}

void Equation::gradient(const Vector &q, double t, Sink &J, int row) const {
  double values[3];
  evaluate(q, t, values, &J, row);
}

void Equation::add_hessian(const Vector &q, double t, const double *lambda, Sink &H,
                           const Mat3 *rotations) const {
  const Side A(q, a, oa, na, rotations), B(q, b, ob, nb, rotations);
  switch (kind) {
  case Kind::Coincide: {
    const Vec3 l(lambda[0], lambda[1], lambda[2]);
    add_rotation_hessian(H, A, sa, Sa, l);
    add_rotation_hessian(H, B, sb, Sb, -l);
    return;
  }
  case Kind::Perpendicular:
  case Kind::RotationDriver: {
    Vec3 uu;
    Elastic storage;
    const Elastic &UU = vector_a(*this, t, uu, storage);
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
  case Kind::ElasticCoordinate: // linear in q
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
