#include "flexopt/bodies/rigid_body.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/element.hpp"

#include <utility>

namespace flexopt::bodies {

MassProperties mass_properties(const mesh::MeshData &mesh, double density) {
  const int npe = fem::nodes_per_element(mesh.type);
  double m = 0;
  Vec3 first = Vec3::Zero();
  Mat3 second = Mat3::Zero();
  fem::ElementCoords X(npe, 3);
  for (std::int64_t e = 0; e < mesh.element_count(); ++e) {
    for (int a = 0; a < npe; ++a) {
      const auto node = mesh.connectivity[static_cast<std::size_t>(e * npe + a)];
      for (int k = 0; k < 3; ++k)
        X(a, k) = mesh.coordinates[static_cast<std::size_t>(3 * node + k)];
    }
    const fem::ElementMatrix Me = fem::element_mass(mesh.type, X, density);
    for (int a = 0; a < npe; ++a)
      for (int b = 0; b < npe; ++b) {
        const double mab = Me(3 * a, 3 * b); // the scalar mass of the node pair
        m += mab;
        first += mab * X.row(b).transpose();
        second += mab * X.row(a).transpose() * X.row(b);
      }
  }
  if (!(m > 0)) throw Error(mesh.source + ": the body has no mass (density or volume is zero)");
  MassProperties p;
  p.mass = m;
  p.center = first / m;
  const Mat3 S = 0.5 * (second + second.transpose());
  const Mat3 Jo = S.trace() * Mat3::Identity() - S;
  const Vec3 &c = p.center;
  p.inertia = Jo - m * (c.dot(c) * Mat3::Identity() - c * c.transpose());
  p.inertia = 0.5 * (p.inertia + p.inertia.transpose()).eval();
  return p;
}

SurfaceCentroid surface_centroid(const mesh::MeshData &mesh, const std::string &surface) {
  const auto it = mesh.surface_groups.find(surface);
  if (it == mesh.surface_groups.end())
    throw Error(mesh.source + ": no physical surface named '" + surface + "'");
  const mesh::SurfaceGroup &g = it->second;
  const int nf = fem::nodes_per_face(g.type);
  SurfaceCentroid out;
  Vec3 moment = Vec3::Zero();
  fem::FaceCoords Xf(nf, 3);
  for (std::size_t f = 0; f < g.size(); ++f) {
    for (int a = 0; a < nf; ++a) {
      const auto node =
          g.connectivity[f * static_cast<std::size_t>(nf) + static_cast<std::size_t>(a)];
      for (int k = 0; k < 3; ++k)
        Xf(a, k) = mesh.coordinates[static_cast<std::size_t>(3 * node + k)];
    }
    // int N_a dA from the consistent load of a unit traction (1, 0, 0).
    const fem::ElementVector w = fem::face_traction_load(g.type, Xf, Vec3(1, 0, 0));
    for (int a = 0; a < nf; ++a) {
      out.area += w(3 * a);
      moment += w(3 * a) * Xf.row(a).transpose();
    }
  }
  if (!(out.area > 0))
    throw Error(mesh.source + ": physical surface '" + surface + "' has no area");
  out.centroid = moment / out.area;
  return out;
}

MassParameters to_parameters(const MassProperties &p) {
  MassParameters t;
  const Mat3 &J = p.inertia;
  t << p.mass, p.first, J(0, 0), J(1, 1), J(2, 2), J(0, 1), J(1, 2), J(0, 2);
  return t;
}

MassProperties from_parameters(const MassParameters &t, const Vec3 &reference) {
  MassProperties p;
  p.mass = t(0);
  p.first = t.segment<3>(1);
  p.center = reference;
  p.inertia << t(4), t(7), t(9), t(7), t(5), t(8), t(9), t(8), t(6);
  return p;
}

MassParameters element_mass_parameters(fem::ElementType type, const fem::ElementCoords &X,
                                       double density, const Vec3 &reference) {
  const int npe = fem::nodes_per_element(type);
  const fem::ElementMatrix Me = fem::element_mass(type, X, density);
  double m = 0;
  Vec3 first = Vec3::Zero();
  Mat3 second = Mat3::Zero();
  for (int a = 0; a < npe; ++a) {
    const Vec3 Xa = X.row(a).transpose() - reference;
    for (int b = 0; b < npe; ++b) {
      const double mab = Me(3 * a, 3 * b);
      const Vec3 Xb = X.row(b).transpose() - reference;
      m += mab;
      first += mab * Xb;
      second += mab * Xa * Xb.transpose();
    }
  }
  MassProperties p;
  p.mass = m;
  p.first = first;
  const Mat3 S = 0.5 * (second + second.transpose());
  p.inertia = S.trace() * Mat3::Identity() - S;
  return to_parameters(p);
}

RigidBody::RigidBody(std::string name, const MassProperties &props)
    : Body(std::move(name)), props_(props), offset_(props.first != Vec3::Zero()) {}

Vec3 RigidBody::center_of_mass() const {
  return props_.mass > 0 ? Vec3(props_.center + props_.first / props_.mass) : props_.center;
}

void RigidBody::inertial_force(const Vec7 &q, const Vec7 &v, const Vec7 &a, Vec7 *f, Mat7 *df_dq,
                               Mat7 *df_dv, Mat7 *mass_matrix) const {
  const Vec4 p = q.tail<4>(), vp = v.tail<4>(), ap = a.tail<4>();
  const Mat3 &J = props_.inertia;
  const Mat34 G = gbar_matrix(p), Gv = gbar_matrix(vp);
  const Mat4 Mp = 4 * G.transpose() * J * G;
  const Vec3 w1 = J * (G * ap), w2 = J * (G * vp);
  if (f) {
    f->head<3>() = props_.mass * a.head<3>();
    f->tail<4>() = Mp * ap + 8 * Gv.transpose() * w2;
  }
  if (df_dq) {
    df_dq->setZero();
    // d/dp [4 Gbar(p)^T w1(p)] = 4 T(w1) - 4 Gbar^T J Gbar(a_p)  (Gbar(p) a_p = -Gbar(a_p) p)
    // d/dp [8 Gbar(v)^T J Gbar(p) v] = -8 Gbar(v)^T J Gbar(v)
    df_dq->bottomRightCorner<4, 4>() = 4 * gbar_transpose_matrix(w1) -
                                       4 * G.transpose() * J * gbar_matrix(ap) -
                                       8 * Gv.transpose() * J * Gv;
  }
  if (df_dv) {
    df_dv->setZero();
    df_dv->bottomRightCorner<4, 4>() = 8 * gbar_transpose_matrix(w2) + 8 * Gv.transpose() * J * G;
  }
  if (mass_matrix) {
    mass_matrix->setZero();
    mass_matrix->topLeftCorner<3, 3>() = props_.mass * Mat3::Identity();
    mass_matrix->bottomRightCorner<4, 4>() = Mp;
  }
  if (!offset_) return;
  // The first moment S about the reference point (docs/theory.md section 9.1):
  //   f_r += A u, u = alpha x S + omega x (omega x S);  f_p += 2 Gbar^T (S x A^T a_r).
  const Vec3 &S = props_.first;
  const Mat3 A = rotation(p), Sx = skew(S);
  const Vec3 omega = 2 * G * vp, alpha = 2 * G * ap;
  const Vec3 u = alpha.cross(S) + omega.cross(omega.cross(S));
  const Vec3 ar = a.head<3>();
  const Vec3 w = S.cross(A.transpose() * ar);
  // H = d(omega x (omega x S))/d omega.
  const Mat3 H =
      omega.dot(S) * Mat3::Identity() + omega * S.transpose() - 2 * S * omega.transpose();
  if (f) {
    f->head<3>() += A * u;
    f->tail<4>() += 2 * G.transpose() * w;
  }
  if (df_dq) {
    df_dq->block<3, 4>(0, 3) += rotate_jacobian(p, u) + A * (2 * Sx * gbar_matrix(ap) - 2 * H * Gv);
    df_dq->bottomRightCorner<4, 4>() +=
        2 * gbar_transpose_matrix(w) + 2 * G.transpose() * Sx * rotate_transpose_jacobian(p, ar);
  }
  if (df_dv) df_dv->block<3, 4>(0, 3) += 2 * A * H * G;
  if (mass_matrix) {
    const Eigen::Matrix<double, 3, 4> Mrp = -2 * A * Sx * G;
    mass_matrix->block<3, 4>(0, 3) += Mrp;
    mass_matrix->block<4, 3>(3, 0) += Mrp.transpose();
  }
}

double RigidBody::kinetic_energy(const Vec7 &q, const Vec7 &v) const {
  const Vec3 w = 2 * gbar_matrix(q.tail<4>()) * v.tail<4>();
  double T = 0.5 * props_.mass * v.head<3>().squaredNorm() + 0.5 * w.dot(props_.inertia * w);
  if (offset_) // r' . (A S)' (section 9.1)
    T += v.head<3>().dot(rotate_jacobian(q.tail<4>(), props_.first) * v.tail<4>());
  return T;
}

void RigidBody::residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                         const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                         Matrix *M) const {
  Vec7 f;
  Mat7 k, c, m;
  inertial_force(q, v, a, &f, K ? &k : nullptr, C ? &c : nullptr, M ? &m : nullptr);
  res = f;
  res.head<3>() -= props_.mass * gravity;
  if (offset_) {
    // The potential -g . (A S) on the rotation: -2 Gbar^T (S x A^T g) (section 9.1).
    const Vec4 p = q.tail<4>();
    const Mat34 G = gbar_matrix(p);
    const Vec3 w = props_.first.cross(rotation(p).transpose() * gravity);
    res.tail<4>() -= 2 * G.transpose() * w;
    if (K)
      k.bottomRightCorner<4, 4>() -=
          2 * gbar_transpose_matrix(w) +
          2 * G.transpose() * skew(props_.first) * rotate_transpose_jacobian(p, gravity);
  }
  if (K) *K = k;
  if (C) *C = c;
  if (M) *M = m;
}

double RigidBody::energy(const ConstVectorRef &q, const ConstVectorRef &v,
                         const Vec3 &gravity) const {
  double V = -props_.mass * gravity.dot(q.head<3>());
  if (offset_) V -= gravity.dot(rotation(q.tail<4>()) * props_.first);
  return kinetic_energy(q, v) + V;
}

Eigen::Matrix<double, 7, 10> RigidBody::parameter_jacobian(const Vec7 &q, const Vec7 &v,
                                                           const Vec7 &a,
                                                           const Vec3 &gravity) const {
  Eigen::Matrix<double, 7, 10> d;
  for (int k = 0; k < 10; ++k) {
    MassParameters e = MassParameters::Zero();
    e(k) = 1;
    MassProperties unit = from_parameters(e, props_.center);
    const RigidBody b(name(), unit);
    Vec7 r;
    b.residual(q, v, a, gravity, r, nullptr, nullptr, nullptr);
    d.col(k) = r;
  }
  return d;
}

} // namespace flexopt::bodies
