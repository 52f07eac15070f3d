#include "flexopt/dynamics/scene.hpp"

#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/expression.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/reduce/field_projection.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/modal.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
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
    e.Sa = A.translation, e.Sb = B.translation;
    add(e);
  };
  auto perpendicular = [&](const Vec3 &ua_world, const Vec3 &vb_world) {
    Equation e;
    e.kind = K::Perpendicular;
    e.ua = A.local(ua_world), e.vb = B.local(vb_world);
    e.Ua = A.vector_part(e.ua), e.Vb = B.vector_part(e.vb);
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
      e.Ua = A.vector_part(e.ua), e.Sa = A.translation, e.Sb = B.translation;
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
    e.Ua = A.vector_part(e.ua), e.Ua2 = A.vector_part(e.ua2), e.Vb = B.vector_part(e.vb);
  } else if (joint_type == "prismatic") {
    // displacement along the axis from the initial configuration = f(t)
    e.kind = K::TranslationDriver;
    e.ua = A.local(w), e.sa = A.s, e.sb = B.s;
    e.Ua = A.vector_part(e.ua), e.Sa = A.translation, e.Sb = B.translation;
    e.c = w.dot(B.world - A.world);
  } else {
    throw Error("a driver needs a revolute or prismatic joint, not '" + joint_type + "'", true);
  }
  return e;
}

namespace {

/// The Rayleigh damping a M + b K of a reduced body.
Matrix rayleigh(const reduce::FlexibleReduction &r, const std::array<double, 2> &ab) {
  return ab[0] * r.M + ab[1] * r.K;
}

/// The initial elastic displacement (or velocity, if `rate`) of an FFRF body: its
/// `initial.elastic_displacement` (`elastic_velocity`) field projected onto the basis
/// (docs/theory.md section 7.6); empty if the case gives none. Logs how much of the field the
/// basis represents.
bodies::Vector initial_elastic(MPI_Comm comm, const io::BodySpec &spec,
                               const mesh::DistributedMesh &mesh, double density,
                               const reduce::FlexibleReduction &red, bool rate) {
  const auto &text = rate ? spec.initial.elastic_velocity : spec.initial.elastic_displacement;
  if (text[0].empty()) return {};
  const std::array<PointExpression, 3> f{PointExpression(text[0]), PointExpression(text[1]),
                                         PointExpression(text[2])};
  const reduce::FieldProjection p = reduce::project_field(mesh, density, red, [&](const Vec3 &x) {
    return Vec3(f[0](x.x(), x.y(), x.z()), f[1](x.x(), x.y(), x.z()), f[2](x.x(), x.y(), x.z()));
  });
  const char *what = rate ? "elastic_velocity" : "elastic_displacement";
  print0(comm,
         "body %s: initial.%s projected onto the basis: ||u||_M = %.6g, %.3g %% of it outside "
         "the basis\n",
         spec.name.c_str(), what, p.norm, 100 * p.residual);
  if (p.residual > 0.1)
    print0(comm,
           "body %s: warning: the basis represents initial.%s poorly (%.3g %% left out); the "
           "field should vanish on interface '%s', where the frame is (with its rotation if the "
           "frame is clamped)\n",
           spec.name.c_str(), what, 100 * p.residual, spec.interfaces.front().c_str());
  return p.coordinates;
}

} // namespace

Scene build_scene(MPI_Comm comm, const io::Case &c) {
  Scene scene;
  Mechanism &mech = scene.mechanism;
  std::map<std::string, int> body_index;
  // Per body: interface centroids (mesh coordinates) by name, the reduction of flexible
  // bodies (interface motion in the order of spec.interfaces); initial rotation and origin.
  const std::size_t nbodies = c.bodies.size();
  std::vector<std::map<std::string, Vec3>> interfaces(nbodies);
  std::vector<std::shared_ptr<reduce::FlexibleReduction>> reductions(nbodies);
  std::vector<Mat3> R0(nbodies);
  std::vector<Vec3> origin(nbodies);
  std::vector<bodies::Vector> elastic0(nbodies), elastic_rate0(nbodies); // zeta, zeta' at t = 0
  for (std::size_t b = 0; b < nbodies; ++b) {
    const io::BodySpec &spec = c.bodies[b];
    const auto &mat = c.material(spec.material);
    if (spec.model == "ffrf") {
      if (spec.interfaces.empty())
        throw Error(spec.where.str() + ": body '" + spec.name +
                        "' (model: ffrf) lists no interfaces; its floating frame is clamped at "
                        "the first one",
                    true);
      scene.meshes.push_back(mesh::load_body_mesh(comm, spec));
      const mesh::DistributedMesh &m = scene.meshes.back();
      auto red = std::make_shared<reduce::FlexibleReduction>();
      const double t0 = wall_time();
      reduce::reduce_flexible_body(
          m, fem::IsotropicMaterial{mat.E, mat.nu, mat.density}, spec.interfaces,
          spec.reduction.modes, spec.reduction.geometric_stiffening, *red,
          spec.reduction.frame == "chord" ? reduce::FrameCondition::Chord
                                          : reduce::FrameCondition::Clamped);
      bodies::FfrfModel model;
      model.invariants = red->invariants;
      model.stiffness = red->K;
      model.damping = rayleigh(*red, spec.rayleigh);
      model.geometric = red->geometric;
      model.origin = red->origin;
      auto body = std::make_shared<bodies::FfrfBody>(spec.name, std::move(model));
      for (std::size_t i = 0; i < spec.interfaces.size(); ++i) {
        interfaces[b][spec.interfaces[i]] = red->centroids[i];
      }
      scene.owned_modes.push_back(reduce::owned_basis_values(*red, m.owned_nodes));
      print0(comm,
             "body %s: ffrf, mass %.6g kg, frame %s at interface '%s' (%.6g, %.6g, %.6g), %d "
             "elastic coordinates (%d static + %d fixed-interface modes)%s, reduced in %.2f s\n",
             spec.name.c_str(), body->mass(),
             spec.reduction.frame == "chord"
                 ? ("chord (axis to '" + spec.interfaces[1] + "')").c_str()
                 : "clamped",
             spec.interfaces.front().c_str(), red->origin.x(), red->origin.y(), red->origin.z(),
             red->size(), red->static_modes, red->fixed_modes,
             spec.reduction.geometric_stiffening ? ", centrifugal geometric stiffening" : "",
             wall_time() - t0);
      if (red->size() > 0) {
        std::string freq;
        for (int k = 0; k < std::min(red->size(), 8); ++k) {
          char buf[32];
          std::snprintf(buf, sizeof buf, "%s%.6g", k ? ", " : "",
                        reduce::frequency_hz(red->eigenvalues(k)));
          freq += buf;
        }
        print0(comm, "body %s: reduced frequencies (frame %s) [Hz]: %s%s\n", spec.name.c_str(),
               spec.reduction.frame.c_str(), freq.c_str(), red->size() > 8 ? ", ..." : "");
      }
      reductions[b] = red;
      scene.reduction_seconds.push_back(wall_time() - t0);
      elastic0[b] = initial_elastic(comm, spec, m, mat.density, *red, false);
      elastic_rate0[b] = initial_elastic(comm, spec, m, mat.density, *red, true);
      mech.bodies.push_back(body);
    } else {
      // Mass properties and interface centroids from the whole mesh on rank 0, broadcast as
      // one buffer: every rank, whatever the rank count, holds the same numbers to the last
      // bit.
      std::vector<double> buf(13 + 3 * spec.interfaces.size(), 0.0);
      scene.meshes.push_back(mesh::load_body_mesh(comm, spec, [&](const mesh::MeshData &data) {
        const bodies::MassProperties p = bodies::mass_properties(data, mat.density);
        buf[0] = p.mass;
        for (int k = 0; k < 3; ++k) buf[static_cast<std::size_t>(1 + k)] = p.center(k);
        for (int k = 0; k < 9; ++k) buf[static_cast<std::size_t>(4 + k)] = p.inertia(k / 3, k % 3);
        for (std::size_t i = 0; i < spec.interfaces.size(); ++i) {
          const bodies::SurfaceCentroid sc = bodies::surface_centroid(data, spec.interfaces[i]);
          for (int k = 0; k < 3; ++k)
            buf[13 + 3 * i + static_cast<std::size_t>(k)] = sc.centroid(k);
        }
      }));
      MPI_Bcast(buf.data(), static_cast<int>(buf.size()), MPI_DOUBLE, 0, comm);
      bodies::MassProperties p;
      p.mass = buf[0];
      p.center = Vec3(buf[1], buf[2], buf[3]);
      for (int k = 0; k < 9; ++k) p.inertia(k / 3, k % 3) = buf[static_cast<std::size_t>(4 + k)];
      for (std::size_t i = 0; i < spec.interfaces.size(); ++i)
        interfaces[b][spec.interfaces[i]] = Vec3(buf[13 + 3 * i], buf[14 + 3 * i], buf[15 + 3 * i]);
      mech.bodies.push_back(std::make_shared<bodies::RigidBody>(spec.name, p));
      scene.owned_modes.emplace_back();
      scene.reduction_seconds.push_back(0.0);
      const Eigen::SelfAdjointEigenSolver<Mat3> principal(p.inertia);
      print0(comm,
             "body %s: rigid, mass %.6g kg, centre of mass (%.6g, %.6g, %.6g), principal inertia "
             "(%.6g, %.6g, %.6g) kg m^2\n",
             spec.name.c_str(), p.mass, p.center.x(), p.center.y(), p.center.z(),
             principal.eigenvalues()(0), principal.eigenvalues()(1), principal.eigenvalues()(2));
    }
    body_index[spec.name] = static_cast<int>(b);
    R0[b] = Eigen::AngleAxisd(spec.initial.angle, v3(spec.initial.axis)).toRotationMatrix();
    origin[b] = v3(spec.initial.position);
  }
  int total = 0;
  for (const auto &b : mech.bodies) total += b->coordinates();
  scene.q0.setZero(total);
  scene.v0.setZero(total);
  for (std::size_t b = 0, o = 0; b < nbodies; ++b) {
    const bodies::Body &body = *mech.bodies[b];
    const auto n = static_cast<Eigen::Index>(body.coordinates());
    const bodies::Vector q = body.placement(origin[b], R0[b]);
    scene.q0.segment(static_cast<Eigen::Index>(o), n) = q;
    scene.v0.segment(static_cast<Eigen::Index>(o), n) = body.placement_velocity(
        q, v3(c.bodies[b].initial.velocity), v3(c.bodies[b].initial.angular_velocity));
    // FFRF: the elastic coordinates follow the 7 frame coordinates.
    if (elastic0[b].size() > 0)
      scene.q0.segment(static_cast<Eigen::Index>(o) + 7, n - 7) = elastic0[b];
    if (elastic_rate0[b].size() > 0)
      scene.v0.segment(static_cast<Eigen::Index>(o) + 7, n - 7) = elastic_rate0[b];
    o += static_cast<std::size_t>(n);
  }

  std::map<std::string, Vec3> ground;
  for (const auto &g : c.ground) ground[g.name] = v3(g.origin);

  // Position of a (validated) interface in the body's list: the index of its reduction data.
  auto interface_index = [&](std::size_t b, const std::string &iface) {
    const auto &list = c.bodies[b].interfaces;
    return static_cast<std::size_t>(std::find(list.begin(), list.end(), iface) - list.begin());
  };
  auto attach = [&](const std::string &body, const std::string &iface) {
    Attachment a;
    if (body == "ground") {
      a.s = ground.at(iface);
      a.world = a.s;
      return a;
    }
    const int b = body_index.at(body);
    const auto ub = static_cast<std::size_t>(b);
    a.body = b;
    const Vec3 X = interfaces[ub].at(iface);
    a.s = X - mech.bodies[ub]->origin();
    a.R = R0[ub];
    a.world = origin[ub] + a.R * X;
    if (reductions[ub]) {
      const std::size_t i = interface_index(ub, iface);
      a.translation = reductions[ub]->translation[i];
      a.rotation = reductions[ub]->rotation[i];
    }
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
    const auto ub = static_cast<std::size_t>(pf.body);
    pf.s = interfaces[ub].at(f.interface) - mech.bodies[ub]->origin();
    if (reductions[ub]) pf.S = reductions[ub]->translation[interface_index(ub, f.interface)];
    for (int k = 0; k < 3; ++k)
      pf.value[static_cast<std::size_t>(k)] = Expression(f.value[static_cast<std::size_t>(k)]);
    mech.forces.push_back(pf);
  }
  for (const io::SensorSpec &s : c.sensors) {
    BoundSensor bs;
    bs.name = s.name;
    bs.quantity = s.quantity;
    bs.body = body_index.at(s.body);
    const auto ub = static_cast<std::size_t>(bs.body);
    bs.point = v3(s.point);
    bs.s = bs.point - mech.bodies[ub]->origin();
    if (reductions[ub])
      bs.S = reduce::basis_at_point(scene.meshes[ub], *reductions[ub], bs.point,
                                    s.where.str() + ": sensor '" + s.name + "' point");
    scene.sensors.push_back(bs);
  }
  mech.finalize();
  for (BoundSensor &bs : scene.sensors)
    if (bs.S.cols() == 0) bs.S.setZero(3, mech.size(bs.body) - 7);
  scene.redundant_rows = mech.drop_redundant_rows(scene.q0, 0.0);
  for (int b = 0; b < static_cast<int>(nbodies); ++b)
    scene.length_scale =
        std::max(scene.length_scale, scene.q0.segment<3>(mech.offset(b)).cwiseAbs().maxCoeff());
  return scene;
}

Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q) {
  const Mechanism &mech = scene.mechanism;
  const int o = mech.offset(s.body), n = mech.size(s.body);
  if (s.quantity == "rotation_angle") {
    const Mat3 A = bodies::rotation(q.segment<4>(o + 3).normalized());
    const Mat3 A0 = bodies::rotation(scene.q0.segment<4>(o + 3).normalized());
    return bodies::rotation_vector(A * A0.transpose());
  }
  if (s.quantity == "elastic_displacement") return s.S * q.segment(o + 7, n - 7);
  const Vec3 x = joints::anchor_position(q.segment(o, n), s.s, s.S);
  if (s.quantity == "displacement")
    return x - joints::anchor_position(scene.q0.segment(o, n), s.s, s.S);
  return x;
}

} // namespace flexopt::dynamics
