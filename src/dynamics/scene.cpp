#include "flexopt/dynamics/scene.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/mesh/load.hpp"

#include <cmath>
#include <map>
#include <memory>

namespace flexopt::dynamics {

namespace {

using bodies::Mat3;
using bodies::Vec4;
using joints::Equation;
using K = Equation::Kind;

Vec3 v3(const std::array<double, 3> &a) {
  return Vec3(a[0], a[1], a[2]);
}

/// Two unit vectors completing the unit axis w to a right-handed triad (u1, u2, w).
void complete_triad(const Vec3 &w, Vec3 &u1, Vec3 &u2) {
  Vec3 e = Vec3::UnitX();
  if (std::abs(w.x()) > std::abs(w.y()) || std::abs(w.x()) > std::abs(w.z()))
    e = std::abs(w.y()) < std::abs(w.z()) ? Vec3::UnitY() : Vec3::UnitZ();
  u1 = (e - e.dot(w) * w).normalized();
  u2 = w.cross(u1);
}

} // namespace

std::vector<joints::Equation> joint_equations(const std::string &type, const Attachment &A,
                                              const Attachment &B, const Vec3 &axis,
                                              const std::string &owner) {
  std::vector<Equation> out;
  int row = 0;
  auto add = [&](Equation e) {
    e.a = A.body, e.b = B.body, e.owner = owner, e.row_in_owner = row;
    row += e.rows();
    out.push_back(e);
  };
  const Vec3 w = type == "revolute" || type == "prismatic" ? axis.normalized() : Vec3::UnitZ();
  Vec3 u1, u2;
  complete_triad(w, u1, u2);
  auto coincide = [&] {
    Equation e;
    e.kind = K::Coincide;
    e.sa = A.s, e.sb = B.s;
    add(e);
  };
  auto perpendicular = [&](const Vec3 &ua_world, const Vec3 &vb_world) {
    Equation e;
    e.kind = K::Perpendicular;
    e.ua = A.local(ua_world), e.vb = B.local(vb_world);
    add(e);
  };
  auto lock_orientation = [&] {
    perpendicular(u1, u2);
    perpendicular(u1, w);
    perpendicular(u2, w);
  };
  if (type == "spherical") {
    coincide();
  } else if (type == "revolute") {
    coincide();
    perpendicular(u1, w);
    perpendicular(u2, w);
  } else if (type == "fixed") {
    coincide();
    lock_orientation();
  } else if (type == "prismatic") {
    lock_orientation();
    for (const Vec3 &u : {u1, u2}) {
      Equation e;
      e.kind = K::PointOnPlane;
      e.ua = A.local(u), e.sa = A.s, e.sb = B.s;
      e.c = u.dot(B.world - A.world); // the interfaces need not lie on one axis line
      add(e);
    }
  } else {
    throw Error("joint type '" + type + "' is not one of revolute, spherical, prismatic, fixed",
                true);
  }
  return out;
}

joints::Equation driver_equation(const std::string &joint_type, const Attachment &A,
                                 const Attachment &B, const Vec3 &axis,
                                 std::shared_ptr<const Expression> f, const std::string &owner) {
  const Vec3 w = axis.normalized();
  Vec3 u1, u2;
  complete_triad(w, u1, u2);
  Equation e;
  e.a = A.body, e.b = B.body;
  e.owner = owner;
  e.driver = std::move(f);
  if (joint_type == "revolute") {
    // angle = atan2(u2_a . u1_b, u1_a . u1_b) = f(t):  (sin f u1_a - cos f u2_a) . u1_b = 0
    e.kind = K::RotationDriver;
    e.ua = A.local(u1), e.ua2 = A.local(u2), e.vb = B.local(u1);
  } else if (joint_type == "prismatic") {
    // displacement along the axis from the initial configuration = f(t)
    e.kind = K::TranslationDriver;
    e.ua = A.local(w), e.sa = A.s, e.sb = B.s;
    e.c = w.dot(B.world - A.world);
  } else {
    throw Error("a driver needs a revolute or prismatic joint, not '" + joint_type + "'", true);
  }
  return e;
}

Scene build_scene(MPI_Comm comm, const io::Case &c) {
  Scene scene;
  Mechanism &mech = scene.mechanism;
  std::map<std::string, int> body_index;
  // Per body: interface centroids (body frame) by name; initial rotation and origin.
  std::vector<std::map<std::string, Vec3>> interfaces(c.bodies.size());
  std::vector<Mat3> R0(c.bodies.size());
  std::vector<Vec3> origin(c.bodies.size());
  scene.q0.resize(7 * static_cast<int>(c.bodies.size()));
  scene.v0.resize(scene.q0.size());
  for (std::size_t b = 0; b < c.bodies.size(); ++b) {
    const io::BodySpec &spec = c.bodies[b];
    const double density = c.material(spec.material).density;
    // Mass properties and interface centroids from the whole mesh on rank 0, broadcast as one
    // buffer: every rank, whatever the rank count, holds the same numbers to the last bit.
    std::vector<double> buf(13 + 3 * spec.interfaces.size(), 0.0);
    scene.meshes.push_back(mesh::load_body_mesh(comm, spec, [&](const mesh::MeshData &data) {
      const bodies::MassProperties p = bodies::mass_properties(data, density);
      buf[0] = p.mass;
      for (int k = 0; k < 3; ++k) buf[static_cast<std::size_t>(1 + k)] = p.center(k);
      for (int k = 0; k < 9; ++k) buf[static_cast<std::size_t>(4 + k)] = p.inertia(k / 3, k % 3);
      for (std::size_t i = 0; i < spec.interfaces.size(); ++i) {
        const bodies::SurfaceCentroid sc = bodies::surface_centroid(data, spec.interfaces[i]);
        for (int k = 0; k < 3; ++k) buf[13 + 3 * i + static_cast<std::size_t>(k)] = sc.centroid(k);
      }
    }));
    MPI_Bcast(buf.data(), static_cast<int>(buf.size()), MPI_DOUBLE, 0, comm);
    bodies::MassProperties p;
    p.mass = buf[0];
    p.center = Vec3(buf[1], buf[2], buf[3]);
    for (int k = 0; k < 9; ++k) p.inertia(k / 3, k % 3) = buf[static_cast<std::size_t>(4 + k)];
    for (std::size_t i = 0; i < spec.interfaces.size(); ++i)
      interfaces[b][spec.interfaces[i]] = Vec3(buf[13 + 3 * i], buf[14 + 3 * i], buf[15 + 3 * i]);
    mech.bodies.emplace_back(spec.name, p);
    body_index[spec.name] = static_cast<int>(b);
    R0[b] = Eigen::AngleAxisd(spec.initial.angle, v3(spec.initial.axis)).toRotationMatrix();
    origin[b] = v3(spec.initial.position);
    const auto q = mech.bodies.back().placement(origin[b], R0[b]);
    scene.q0.segment<7>(7 * static_cast<int>(b)) = q;
    scene.v0.segment<7>(7 * static_cast<int>(b)) = mech.bodies.back().placement_velocity(
        q, v3(spec.initial.velocity), v3(spec.initial.angular_velocity));
    print0(comm,
           "body %s: rigid, mass %.6g kg, centre of mass (%.6g, %.6g, %.6g), principal inertia "
           "(%.6g, %.6g, %.6g) kg m^2\n",
           spec.name.c_str(), p.mass, p.center.x(), p.center.y(), p.center.z(),
           Eigen::SelfAdjointEigenSolver<Mat3>(p.inertia).eigenvalues()(0),
           Eigen::SelfAdjointEigenSolver<Mat3>(p.inertia).eigenvalues()(1),
           Eigen::SelfAdjointEigenSolver<Mat3>(p.inertia).eigenvalues()(2));
  }
  std::map<std::string, Vec3> ground;
  for (const auto &g : c.ground) ground[g.name] = v3(g.origin);

  auto attach = [&](const std::string &body, const std::string &iface) {
    Attachment a;
    if (body == "ground") {
      a.s = ground.at(iface);
      a.world = a.s;
      return a;
    }
    const int b = body_index.at(body);
    a.body = b;
    const Vec3 X = interfaces[static_cast<std::size_t>(b)].at(iface);
    a.s = X - mech.bodies[static_cast<std::size_t>(b)].center();
    a.R = R0[static_cast<std::size_t>(b)];
    a.world = origin[static_cast<std::size_t>(b)] + a.R * X;
    return a;
  };

  // Euler-parameter normalization, one row per body, first.
  for (std::size_t b = 0; b < c.bodies.size(); ++b) {
    Equation e;
    e.kind = K::Normalize;
    e.a = static_cast<int>(b);
    e.owner = "body " + c.bodies[b].name + " (|p| = 1)";
    mech.equations.push_back(e);
  }
  std::map<std::string, const io::JointSpec *> joints_by_name;
  for (const io::JointSpec &j : c.joints) joints_by_name[j.name] = &j;
  // Drivers come before the joints: when rows are found redundant, joint rows are left out
  // rather than a prescribed motion.
  for (const io::DriverSpec &d : c.drivers) {
    const io::JointSpec &j = *joints_by_name.at(d.joint);
    const Attachment A = attach(j.a, j.a_interface), B = attach(j.b, j.b_interface);
    mech.equations.push_back(driver_equation(j.type, A, B, v3(j.axis),
                                             std::make_shared<const Expression>(d.expression),
                                             "driver of joint " + j.name));
  }
  double max_gap = 0;
  std::string gap_joint;
  for (const io::JointSpec &j : c.joints) {
    const Attachment A = attach(j.a, j.a_interface), B = attach(j.b, j.b_interface);
    const double gap = (A.world - B.world).norm();
    if (gap > max_gap && (j.type != "prismatic")) max_gap = gap, gap_joint = j.name;
    for (Equation &e :
         joint_equations(j.type, A, B, v3(j.axis), "joint " + j.name + " (" + j.type + ")"))
      mech.equations.push_back(std::move(e));
  }
  if (max_gap > 1e-9)
    print0(comm,
           "scene: the interfaces of joint %s are %.3g m apart in the initial placement; the "
           "initial conditions move the bodies to close the joints\n",
           gap_joint.c_str(), max_gap);
  if (c.gravity) mech.gravity = v3(*c.gravity);
  for (const io::ForceSpec &f : c.forces) {
    PointForce pf;
    pf.body = body_index.at(f.body);
    pf.s = interfaces[static_cast<std::size_t>(pf.body)].at(f.interface) -
           mech.bodies[static_cast<std::size_t>(pf.body)].center();
    for (int k = 0; k < 3; ++k)
      pf.value[static_cast<std::size_t>(k)] = Expression(f.value[static_cast<std::size_t>(k)]);
    mech.forces.push_back(pf);
  }
  for (const io::SensorSpec &s : c.sensors) {
    BoundSensor bs;
    bs.name = s.name;
    bs.quantity = s.quantity;
    bs.body = body_index.at(s.body);
    bs.point = v3(s.point);
    scene.sensors.push_back(bs);
  }
  mech.finalize();
  scene.redundant_rows = mech.drop_redundant_rows(scene.q0, 0.0);
  for (std::size_t b = 0; b < c.bodies.size(); ++b)
    scene.length_scale = std::max(
        scene.length_scale, scene.q0.segment<3>(7 * static_cast<int>(b)).cwiseAbs().maxCoeff());
  return scene;
}

Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q) {
  const auto &body = scene.mechanism.bodies[static_cast<std::size_t>(s.body)];
  const int o = 7 * s.body;
  if (s.quantity == "rotation_angle") {
    const Mat3 A = bodies::rotation(q.segment<4>(o + 3).normalized());
    const Mat3 A0 = bodies::rotation(scene.q0.segment<4>(o + 3).normalized());
    return bodies::rotation_vector(A * A0.transpose());
  }
  const Vec3 x = body.point(q.segment<7>(o), s.point);
  if (s.quantity == "displacement") return x - body.point(scene.q0.segment<7>(o), s.point);
  return x;
}

} // namespace flexopt::dynamics
