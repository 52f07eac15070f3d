// The loads a body carries at one state of its mechanism (docs/theory.md section 14.2).
#include "flexopt/dynamics/body_loads.hpp"

#include "flexopt/bodies/quaternion.hpp"
#include "flexopt/core/error.hpp"

#include <functional>
#include <map>
#include <utility>

namespace flexopt::dynamics {

BodyLoads::BodyLoads(BodyLoads &&other) noexcept {
  *this = std::move(other);
}

BodyLoads &BodyLoads::operator=(BodyLoads &&other) noexcept {
  if (this == &other) return *this;
  if (nodal) VecDestroy(&nodal);
  if (body_force) VecDestroy(&body_force);
  points = std::move(other.points);
  nodal = std::exchange(other.nodal, nullptr);
  body_force = std::exchange(other.body_force, nullptr);
  inertia_force = other.inertia_force, inertia_moment = other.inertia_moment;
  force_residual = other.force_residual, moment_residual = other.moment_residual;
  force_scale = other.force_scale, moment_scale = other.moment_scale;
  return *this;
}

BodyLoads::~BodyLoads() {
  if (nodal) VecDestroy(&nodal);
  if (body_force) VecDestroy(&body_force);
}

namespace {

/// The motion of one body at a state, in its own axes (docs/theory.md section 14.2).
struct BodyMotion {
  bodies::Mat3 A;                      ///< frame rotation
  Vec3 acc{0, 0, 0};                   ///< A^T r'' (the origin's acceleration)
  Vec3 omega{0, 0, 0}, alpha{0, 0, 0}; ///< body angular velocity and acceleration
  Vec3 gravity{0, 0, 0};               ///< A^T g
  Vector zeta, zeta_rate, zeta_acc;    ///< elastic coordinates (empty: rigid)
  bodies::Vec4 p;
};

BodyMotion body_motion(const Mechanism &mech, int mb, const State &s) {
  const int o = mech.offset(mb), n = mech.size(mb) - 7;
  BodyMotion m;
  m.p = s.q.segment<4>(o + 3);
  const bodies::Vec4 pd = s.v.segment<4>(o + 3), pdd = s.acc.segment<4>(o + 3);
  m.A = bodies::rotation(m.p);
  const bodies::Mat34 gbar = bodies::gbar_matrix(m.p);
  // omega_bar = 2 Gbar(p) p'; its rate 2 Gbar(p) p'' + 2 Gbar(p') p' = 2 Gbar(p) p''.
  m.omega = 2 * gbar * pd;
  m.alpha = 2 * gbar * pdd;
  // A rigid body's Euler-parameter equations (Lagrange's, docs/theory.md section 6.2) are
  // Euler's only for p' orthogonal to p; the index-3 run keeps |p| = 1 but not p.p' = 0, and
  // their moment is J alpha + omega x J omega + 2 (p.p') J omega. The loads follow the
  // equations as integrated (section 14.2).
  if (n == 0) m.alpha += 2 * m.p.dot(pd) * m.omega;
  m.acc = m.A.transpose() * s.acc.segment<3>(o);
  m.gravity = m.A.transpose() * mech.gravity;
  m.zeta = s.q.segment(o + 7, n);
  m.zeta_rate = s.v.segment(o + 7, n);
  m.zeta_acc = s.acc.segment(o + 7, n);
  return m;
}

/// Receives one body's columns of constraint gradient rows.
class BodyRows : public joints::Sink {
public:
  BodyRows(int body, int rows, int size) : body_(body), rows_(Matrix::Zero(rows, size)) {}
  void add_row(int row, const joints::BodyRef &b, const joints::Row &g) override {
    if (b.index == body_) rows_.block(row, 0, 1, g.size()) += g;
  }
  void add_block(const joints::BodyRef &, const joints::BodyRef &, int, int,
                 const Eigen::Ref<const Matrix> &) override {}
  void add_product(const joints::BodyRef &, const joints::BodyRef &, double,
                   const joints::Jacobian &, const joints::Jacobian &) override {}
  const Matrix &rows() const { return rows_; }

private:
  int body_;
  Matrix rows_;
};

/// The name of the body's interface whose centroid is at a body point (relative to the origin,
/// undeformed), or empty.
using InterfaceAt = std::function<std::string(const Vec3 &)>;

/// "joint NAME (type)" and "driver of joint NAME" -> NAME; anything else: empty.
std::string joint_name(const std::string &owner) {
  const std::string driver = "driver of joint ", joint = "joint ";
  if (owner.rfind(driver, 0) == 0) return owner.substr(driver.size());
  if (owner.rfind(joint, 0) != 0) return {};
  const auto end = owner.find(" (");
  return owner.substr(joint.size(),
                      end == std::string::npos ? std::string::npos : end - joint.size());
}

/// A body point s + S zeta (S empty or zero-width for a rigid body).
Vec3 body_point(const Vec3 &s, const joints::Elastic &S, const Vector &zeta) {
  return S.cols() == 0 || zeta.size() == 0 ? s : Vec3(s + S * zeta);
}

/// The joints' forces and moments on body mb (docs/theory.md section 14.2): per joint, the
/// generalized force -Phi_qb^T lambda of its rows, as a force (body axes) and a moment about
/// the origin, turned into a moment about the joint's point on the body.
std::vector<PointLoad> joint_loads(const Mechanism &mech, int mb, const State &s,
                                   const BodyMotion &m, const InterfaceAt &interface_at) {
  struct Sum {
    Vec3 force{0, 0, 0}, moment{0, 0, 0}, point{0, 0, 0}, rest{0, 0, 0};
  };
  std::map<std::string, Sum> joints;
  std::vector<std::string> order;
  const bodies::Mat34 gbar = bodies::gbar_matrix(m.p);
  for (std::size_t ei = 0; ei < mech.equations.size(); ++ei) {
    const joints::Equation &e = mech.equations[ei];
    if ((e.a != mb && e.b != mb) || e.kind == joints::Equation::Kind::Normalize) continue;
    const std::string name = joint_name(e.owner);
    if (name.empty())
      throw Error("body_loads: constraint rows of '" + e.owner + "' act on the body");
    BodyRows rows(mb, e.rows(), mech.size(mb));
    e.gradient(s.q, s.t, rows, 0);
    Vector g = Vector::Zero(mech.size(mb));
    for (int k = 0; k < e.rows(); ++k) {
      const int idx = mech.enforced_index(mech.first_row(static_cast<int>(ei)) + k);
      if (idx >= 0) g -= rows.rows().row(k).transpose() * s.lambda(idx);
    }
    if (!joints.count(name)) order.push_back(name);
    Sum &j = joints[name];
    j.force += m.A.transpose() * g.head<3>();
    j.moment += 0.5 * gbar * g.segment<4>(3); // f_p = 2 Gbar^T n  =>  n = Gbar f_p / 2
    if (e.kind == joints::Equation::Kind::Coincide ||
        e.kind == joints::Equation::Kind::PointOnPlane) {
      j.point = e.a == mb ? body_point(e.sa, e.Sa, m.zeta) : body_point(e.sb, e.Sb, m.zeta);
      j.rest = e.a == mb ? e.sa : e.sb;
    }
  }
  std::vector<PointLoad> out;
  for (const std::string &name : order) {
    const Sum &j = joints[name];
    out.push_back({"joint " + name, interface_at(j.rest), j.point, j.force,
                   j.moment - j.point.cross(j.force)});
  }
  return out;
}

/// The case's interface forces on body mb (world values at t, applied at s + S zeta).
void add_point_forces(const Mechanism &mech, int mb, const State &s, const BodyMotion &m,
                      const InterfaceAt &interface_at, std::vector<PointLoad> &out) {
  for (std::size_t k = 0; k < mech.forces.size(); ++k) {
    const PointForce &f = mech.forces[k];
    if (f.body != mb) continue;
    const Vec3 world(f.value[0](s.t), f.value[1](s.t), f.value[2](s.t));
    out.push_back({"force " + std::to_string(k), interface_at(f.s), body_point(f.s, f.S, m.zeta),
                   m.A.transpose() * world, Vec3::Zero()});
  }
}

/// f = M (A^T g - a) at the owned nodes, and its resultant force and moment about the origin.
void inertia_loads(const Scene &scene, std::size_t b, const Vec3 &origin, const BodyMotion &m,
                   Mat mass, BodyLoads &out) {
  const mesh::DistributedMesh &mesh = scene.meshes[b];
  const Eigen::MatrixXd &modes = scene.owned_modes[b];
  const auto owned = static_cast<Eigen::Index>(mesh.owned_nodes);
  const bool elastic = m.zeta.size() > 0;
  FX_PETSC(MatCreateVecs(mass, &out.body_force, &out.nodal));
  Vec field = out.body_force;
  PetscInt local = 0;
  FX_PETSC(VecGetLocalSize(field, &local));
  std::vector<Vec3> xbar(static_cast<std::size_t>(owned));
  {
    PetscScalar *a = nullptr;
    FX_PETSC(VecGetArray(field, &a));
    for (Eigen::Index i = 0; i < owned && local == 3 * owned; ++i) {
      Vec3 x = Eigen::Map<const Vec3>(&mesh.coordinates[static_cast<std::size_t>(3 * i)]) - origin;
      Vec3 extra = Vec3::Zero();
      if (elastic) {
        const auto Vi = modes.middleRows(3 * i, 3);
        x += Vi * m.zeta;
        extra = 2 * m.omega.cross(Vec3(Vi * m.zeta_rate)) + Vi * m.zeta_acc;
      }
      xbar[static_cast<std::size_t>(i)] = x;
      const Vec3 acc = m.acc + m.alpha.cross(x) + m.omega.cross(m.omega.cross(x)) + extra;
      Eigen::Map<Vec3>(a + 3 * i) = m.gravity - acc;
    }
    FX_PETSC(VecRestoreArray(field, &a));
  }
  const MPI_Comm comm = PetscObjectComm(reinterpret_cast<PetscObject>(mass));
  int bad = local == 3 * owned ? 0 : 1;
  MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm);
  if (bad) {
    throw Error("body_loads: the mass matrix does not have the mesh's layout", true);
  }
  FX_PETSC(MatMult(mass, field, out.nodal));
  std::array<double, 6> sum{};
  const PetscScalar *f = nullptr;
  FX_PETSC(VecGetArrayRead(out.nodal, &f));
  for (Eigen::Index i = 0; i < owned; ++i) {
    const Vec3 fi = Eigen::Map<const Vec3>(f + 3 * i);
    const Vec3 mi = xbar[static_cast<std::size_t>(i)].cross(fi);
    for (int c = 0; c < 3; ++c) sum[static_cast<std::size_t>(c)] += fi(c), sum[3 + c] += mi(c);
  }
  FX_PETSC(VecRestoreArrayRead(out.nodal, &f));
  MPI_Allreduce(MPI_IN_PLACE, sum.data(), 6, MPI_DOUBLE, MPI_SUM, comm);
  out.inertia_force = Vec3(sum[0], sum[1], sum[2]);
  out.inertia_moment = Vec3(sum[3], sum[4], sum[5]);
}

} // namespace

BodyLoads body_loads(const Scene &scene, std::size_t b, const State &s, Mat mass) {
  const int mb = scene.bodies.at(b).mechanism;
  if (mb < 0) throw Error("body_loads: an ACF body's loads are not defined", true);
  const Mechanism &mech = scene.mechanism;
  const BodyMotion m = body_motion(mech, mb, s);
  const Vec3 origin = mech.bodies[static_cast<std::size_t>(mb)]->origin();
  // Interface centroids and attachment points are the same numbers up to the placement's
  // rounding; joints whose points miss by less than 1e-4 of the scene are placed at body a's.
  const InterfaceAt interface_at = [&](const Vec3 &point) {
    for (const auto &[name, centroid] : scene.bodies[b].interfaces)
      if ((centroid - origin - point).norm() <= 1e-4 * scene.length_scale) return name;
    return std::string();
  };
  BodyLoads out;
  out.points = joint_loads(mech, mb, s, m, interface_at);
  add_point_forces(mech, mb, s, m, interface_at, out.points);
  inertia_loads(scene, b, origin, m, mass, out);

  out.force_residual = out.inertia_force;
  out.moment_residual = out.inertia_moment;
  out.force_scale = out.inertia_force.norm();
  out.moment_scale = out.inertia_moment.norm();
  for (const PointLoad &p : out.points) {
    const Vec3 about_origin = p.moment + p.point.cross(p.force);
    out.force_residual += p.force;
    out.moment_residual += about_origin;
    out.force_scale = std::max(out.force_scale, p.force.norm());
    out.moment_scale = std::max(out.moment_scale, about_origin.norm());
  }
  return out;
}

} // namespace flexopt::dynamics
