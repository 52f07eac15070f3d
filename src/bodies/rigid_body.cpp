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

RigidBody::RigidBody(std::string name, const MassProperties &props)
    : Body(std::move(name)), props_(props) {}

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
}

double RigidBody::kinetic_energy(const Vec7 &q, const Vec7 &v) const {
  const Vec3 w = 2 * gbar_matrix(q.tail<4>()) * v.tail<4>();
  return 0.5 * props_.mass * v.head<3>().squaredNorm() + 0.5 * w.dot(props_.inertia * w);
}

void RigidBody::residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                         const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                         Matrix *M) const {
  Vec7 f;
  Mat7 k, c, m;
  inertial_force(q, v, a, &f, K ? &k : nullptr, C ? &c : nullptr, M ? &m : nullptr);
  res = f;
  res.head<3>() -= props_.mass * gravity;
  if (K) *K = k;
  if (C) *C = c;
  if (M) *M = m;
}

double RigidBody::energy(const ConstVectorRef &q, const ConstVectorRef &v,
                         const Vec3 &gravity) const {
  return kinetic_energy(q, v) - props_.mass * gravity.dot(q.head<3>());
}

} // namespace flexopt::bodies
