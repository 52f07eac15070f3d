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
#include "flexopt/reduce/reduction_adjoint.hpp"

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

std::vector<joints::Equation> joint_equations(JointType type, const Attachment &A,
                                              const Attachment &B, const Vec3 &axis,
                                              const std::string &owner) {
  std::vector<Equation> out;
  int row = 0;
  auto add = [&](Equation e) {
    e.a = A.body, e.b = B.body, e.owner = owner, e.row_in_owner = row;
    row += e.rows();
    out.push_back(e);
  };
  const Vec3 w = type == JointType::Revolute || type == JointType::Prismatic ? axis.normalized()
                                                                             : Vec3::UnitZ();
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
  if (type == JointType::Spherical) {
    coincide();
  } else if (type == JointType::Revolute) {
    coincide();
    perpendicular(u1, w);
    perpendicular(u2, w);
  } else if (type == JointType::Fixed) {
    coincide();
    lock_orientation();
  } else {
    lock_orientation();
    for (const Vec3 &u : {u1, u2}) {
      Equation e;
      e.kind = K::PointOnPlane;
      e.ua = A.local(u), e.sa = A.s, e.sb = B.s;
      e.Ua = A.vector_part(e.ua), e.Sa = A.translation, e.Sb = B.translation;
      e.c = u.dot(B.world - A.world); // the interfaces need not lie on one axis line
      add(e);
    }
  }
  return out;
}

joints::Equation driver_equation(JointType joint_type, const Attachment &A, const Attachment &B,
                                 const Vec3 &axis, std::shared_ptr<const Expression> f,
                                 const std::string &owner) {
  const Vec3 w = axis.normalized();
  Vec3 u1, u2;
  complete_triad(w, u1, u2);
  Equation e;
  e.a = A.body, e.b = B.body;
  e.owner = owner;
  e.driver = std::move(f);
  if (joint_type == JointType::Revolute) {
    // angle = atan2(u2_a . u1_b, u1_a . u1_b) = f(t):  (sin f u1_a - cos f u2_a) . u1_b = 0
    e.kind = K::RotationDriver;
    e.ua = A.local(u1), e.ua2 = A.local(u2), e.vb = B.local(u1);
    e.Ua = A.vector_part(e.ua), e.Ua2 = A.vector_part(e.ua2), e.Vb = B.vector_part(e.vb);
  } else if (joint_type == JointType::Prismatic) {
    // displacement along the axis from the initial configuration = f(t)
    e.kind = K::TranslationDriver;
    e.ua = A.local(w), e.sa = A.s, e.sb = B.s;
    e.Ua = A.vector_part(e.ua), e.Sa = A.translation, e.Sb = B.translation;
    e.c = w.dot(B.world - A.world);
  } else {
    throw Error(std::string("a driver needs a revolute or prismatic joint, not '") +
                    joint_type_name(joint_type) + "'",
                true);
  }
  return e;
}

reduce::Field initial_elastic_field(const BodyDescription &spec, bool rate) {
  const auto &text = rate ? spec.initial.elastic_velocity : spec.initial.elastic_displacement;
  if (text[0].empty()) return {};
  const auto f = std::make_shared<std::array<PointExpression, 3>>(std::array<PointExpression, 3>{
      PointExpression(text[0]), PointExpression(text[1]), PointExpression(text[2])});
  return [f](const Vec3 &x) {
    return Vec3((*f)[0](x.x(), x.y(), x.z()), (*f)[1](x.x(), x.y(), x.z()),
                (*f)[2](x.x(), x.y(), x.z()));
  };
}

namespace {

/// The Rayleigh damping a M + b K of a reduced body.
Matrix rayleigh(const reduce::FlexibleReduction &r, const std::array<double, 2> &ab) {
  return ab[0] * r.M + ab[1] * r.K;
}

/// The initial elastic displacement (or velocity, if `rate`) of an FFRF body: its
/// `initial.elastic_displacement` (`elastic_velocity`) field projected onto the basis with the
/// reduction's mass (a design body's sum_e w_e M_e; docs/theory.md sections 7.6 and 10.2); empty if
/// the case gives none. If `report`, logs how much of the field the basis represents.
bodies::Vector initial_elastic(MPI_Comm comm, const BodyDescription &spec,
                               const mesh::DistributedMesh &mesh, double density,
                               const reduce::FlexibleReduction &red, bool rate,
                               bool report = true) {
  const reduce::Field u = initial_elastic_field(spec, rate);
  if (!u) return {};
  const reduce::FieldProjection p = reduce::project_field(mesh, density, red, u);
  if (!report) return p.coordinates;
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

namespace {

/// An ACF body: its mesh, its co-rotated elements, one interface node per interface.
void add_acf_body(MPI_Comm comm, const BodyDescription &spec, const fem::IsotropicMaterial &mat,
                  Scene &scene, SceneBody &sb) {
  Mechanism &mech = scene.mechanism;
  scene.meshes.push_back(mesh::load_body_mesh(comm, spec.mesh));
  const mesh::DistributedMesh &m = scene.meshes.back();
  sb.mechanism = -1;
  sb.acf = static_cast<int>(scene.acf.size());
  sb.frame = spec.reduction.frame; // section 8.4: the frame FFRF's basis would hold
  scene.acf.push_back(std::make_unique<bodies::AcfBody>(
      spec.name, m, fem::IsotropicMaterial{mat.E, mat.nu, mat.density}, std::vector<double>{},
      spec.rayleigh[1]));
  std::string names;
  for (const std::string &iface : spec.interfaces) {
    const Vec3 cI =
        fem::surface_centroid(m, iface, spec.where.str() + ": body '" + spec.name + "' interface");
    sb.interfaces[iface] = cI;
    sb.nodes.push_back(static_cast<int>(mech.bodies.size()));
    sb.centroids.push_back(cI);
    scene.acf_interfaces.push_back({static_cast<std::size_t>(sb.acf), iface, sb.nodes.back(), cI,
                                    spec.where.str() + ": body '" + spec.name + "'"});
    mech.bodies.push_back(std::make_shared<bodies::InterfaceNode>(spec.name + ":" + iface, cI));
    names += (names.empty() ? "" : ", ") + iface;
  }
  // Initial elastic fields, added to the rigid placement of the nodes.
  for (const bool rate : {false, true}) {
    const auto &text = rate ? spec.initial.elastic_velocity : spec.initial.elastic_displacement;
    if (text[0].empty()) continue;
    const auto f = std::make_shared<std::array<PointExpression, 3>>(std::array<PointExpression, 3>{
        PointExpression(text[0]), PointExpression(text[1]), PointExpression(text[2])});
    (rate ? sb.u0_rate : sb.u0) = [f](const Vec3 &X) {
      return Vec3((*f)[0](X.x(), X.y(), X.z()), (*f)[1](X.x(), X.y(), X.z()),
                  (*f)[2](X.x(), X.y(), X.z()));
    };
  }
  scene.owned_modes.emplace_back();
  scene.reduction_seconds.push_back(0.0);
  print0(comm,
         "body %s: acf (absolute nodal coordinates, co-rotated elements), mass %.6g kg, %lld "
         "nodes (%lld DOFs), %lld elements, interface nodes: %s\n",
         spec.name.c_str(), scene.acf.back()->total_mass(), static_cast<long long>(m.global_nodes),
         3LL * m.global_nodes, static_cast<long long>(m.global_elements),
         names.empty() ? "none" : names.c_str());
}

/// What the FFRF body takes from its reduction.
bodies::FfrfModel ffrf_model(const reduce::FlexibleReduction &red, const BodyDescription &spec) {
  bodies::FfrfModel model;
  model.invariants = red.invariants;
  model.stiffness = red.K;
  model.damping = rayleigh(red, spec.rayleigh);
  model.geometric = red.geometric;
  model.origin = red.origin;
  return model;
}

/// An FFRF body: its mesh reduced (in parallel) to the floating frame and the Craig-Bampton
/// basis, its initial elastic coordinates projected onto the basis.
void add_ffrf_body(MPI_Comm comm, const BodyDescription &spec, const fem::IsotropicMaterial &mat,
                   Scene &scene, SceneBody &sb, const InitialDesign *design) {
  if (spec.interfaces.empty())
    throw Error(spec.where.str() + ": body '" + spec.name +
                    "' (model: ffrf) lists no interfaces; its floating frame is clamped at "
                    "the first one",
                true);
  scene.meshes.push_back(mesh::load_body_mesh(comm, spec.mesh));
  const mesh::DistributedMesh &m = scene.meshes.back();
  // A design body is reduced with its first design's element factors (once, not with the
  // solid material and again for the design).
  reduce::ElementFactors factors;
  const bool designed = design && std::find(design->bodies.begin(), design->bodies.end(),
                                            spec.name) != design->bodies.end();
  if (designed) factors = design->factors(spec.name, m);
  const double t0 = wall_time();
  const auto red = reduce_ffrf_body(m, spec, mat, designed ? &factors : nullptr);
  auto body = std::make_shared<bodies::FfrfBody>(spec.name, ffrf_model(*red, spec));
  for (std::size_t i = 0; i < spec.interfaces.size(); ++i)
    sb.interfaces[spec.interfaces[i]] = red->centroids[i];
  scene.owned_modes.push_back(reduce::owned_basis_values(*red, m.owned_nodes));
  print0(comm,
         "body %s: ffrf, mass %.6g kg, frame %s at interface '%s' (%.6g, %.6g, %.6g), %d "
         "elastic coordinates (%d static + %d fixed-interface modes)%s, reduced in %.2f s\n",
         spec.name.c_str(), body->mass(),
         spec.reduction.frame == reduce::FrameCondition::Chord
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
           frame_name(spec.reduction.frame), freq.c_str(), red->size() > 8 ? ", ..." : "");
  }
  sb.reduction = red;
  scene.reduction_seconds.push_back(wall_time() - t0);
  sb.elastic0 = initial_elastic(comm, spec, m, mat.density, *red, false);
  sb.elastic_rate0 = initial_elastic(comm, spec, m, mat.density, *red, true);
  scene.mechanism.bodies.push_back(body);
}

/// A rigid body: mass properties and interface centroids from the whole mesh on rank 0,
/// broadcast as one buffer, so that every rank, whatever the rank count, holds the same numbers
/// to the last bit.
void add_rigid_body(MPI_Comm comm, const BodyDescription &spec, const fem::IsotropicMaterial &mat,
                    Scene &scene, SceneBody &sb) {
  std::vector<double> buf(13 + 3 * spec.interfaces.size(), 0.0);
  scene.meshes.push_back(mesh::load_body_mesh(comm, spec.mesh, [&](const mesh::MeshData &data) {
    const bodies::MassProperties p = bodies::mass_properties(data, mat.density);
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
    sb.interfaces[spec.interfaces[i]] = Vec3(buf[13 + 3 * i], buf[14 + 3 * i], buf[15 + 3 * i]);
  scene.mechanism.bodies.push_back(std::make_shared<bodies::RigidBody>(spec.name, p));
  scene.owned_modes.emplace_back();
  scene.reduction_seconds.push_back(0.0);
  const Eigen::SelfAdjointEigenSolver<Mat3> principal(p.inertia);
  print0(comm,
         "body %s: rigid, mass %.6g kg, centre of mass (%.6g, %.6g, %.6g), principal inertia "
         "(%.6g, %.6g, %.6g) kg m^2\n",
         spec.name.c_str(), p.mass, p.center.x(), p.center.y(), p.center.z(),
         principal.eigenvalues()(0), principal.eigenvalues()(1), principal.eigenvalues()(2));
}

/// The placed coordinates q0 and velocities v0 of the mechanism at t = 0.
void place(MPI_Comm comm, const SceneDescription &c, Scene &scene) {
  const Mechanism &mech = scene.mechanism;
  int total = 0;
  for (const auto &b : mech.bodies) total += b->coordinates();
  scene.q0.setZero(total);
  scene.v0.setZero(total);
  for (std::size_t b = 0, o = 0; b < scene.bodies.size(); ++b) {
    const SceneBody &sb = scene.bodies[b];
    std::vector<int> list = sb.nodes; // an ACF body's interface nodes move with it
    if (sb.mechanism >= 0) list.push_back(sb.mechanism);
    for (std::size_t i = 0; i < list.size(); ++i) {
      const int mb = list[i];
      const bodies::Body &body = *mech.bodies[static_cast<std::size_t>(mb)];
      const auto n = static_cast<Eigen::Index>(body.coordinates());
      bodies::Vector q = body.placement(sb.position, sb.R);
      bodies::Vector v = body.placement_velocity(q, sb.velocity, sb.omega);
      if (sb.acf >= 0 && (sb.u0 || sb.u0_rate)) {
        // An interface node moves with the mean initial elastic field of its surface's nodes
        // (exact when the field moves the surface rigidly by a translation; otherwise the ties
        // are violated and the initial state says so).
        const mesh::DistributedMesh &m = scene.meshes[b];
        const auto it = m.surface_nodes.find(c.bodies[b].interfaces[i]);
        double sum[7] = {0, 0, 0, 0, 0, 0, 0}, all[7];
        if (it != m.surface_nodes.end())
          for (PetscInt g : it->second) {
            const Vec3 X(&m.coordinates[3 * static_cast<std::size_t>(g - m.node_start)]);
            const Vec3 u = sb.u0 ? sb.u0(X) : Vec3::Zero(),
                       w = sb.u0_rate ? sb.u0_rate(X) : Vec3::Zero();
            for (int k = 0; k < 3; ++k) sum[k] += u(k), sum[3 + k] += w(k);
            sum[6] += 1;
          }
        MPI_Allreduce(sum, all, 7, MPI_DOUBLE, MPI_SUM, comm);
        const Vec3 u = Vec3(all[0], all[1], all[2]) / all[6],
                   w = Vec3(all[3], all[4], all[5]) / all[6];
        q.head<3>() += sb.R * u;
        v.head<3>() += sb.omega.cross(sb.R * u) + sb.R * w;
      }
      scene.q0.segment(static_cast<Eigen::Index>(o), n) = q;
      scene.v0.segment(static_cast<Eigen::Index>(o), n) = v;
      // FFRF: the elastic coordinates follow the 7 frame coordinates.
      if (sb.elastic0.size() > 0)
        scene.q0.segment(static_cast<Eigen::Index>(o) + 7, n - 7) = sb.elastic0;
      if (sb.elastic_rate0.size() > 0)
        scene.v0.segment(static_cast<Eigen::Index>(o) + 7, n - 7) = sb.elastic_rate0;
      o += static_cast<std::size_t>(n);
    }
  }
}

} // namespace

std::shared_ptr<reduce::FlexibleReduction>
reduce_ffrf_body(const mesh::DistributedMesh &m, const BodyDescription &spec,
                 const fem::IsotropicMaterial &mat, const reduce::ElementFactors *design,
                 const reduce::FlexibleReduction *previous) {
  auto red = std::make_shared<reduce::FlexibleReduction>();
  std::shared_ptr<reduce::ClampedProblem> reuse;
  if (previous && previous->adjoint) reuse = previous->adjoint->interior;
  reduce::reduce_flexible_body(
      m, fem::IsotropicMaterial{mat.E, mat.nu, mat.density}, spec.interfaces, spec.reduction.modes,
      spec.reduction.geometric_stiffening, *red, spec.reduction.frame, design, std::move(reuse));
  if (design) reduce::check_modal_cut(*red, spec.name, m.comm);
  return red;
}

Scene load_bodies(MPI_Comm comm, const SceneDescription &c, const InitialDesign *design) {
  Scene scene;
  const std::size_t nbodies = c.bodies.size();
  scene.meshes.reserve(nbodies); // the ACF bodies refer to their meshes
  scene.bodies.resize(nbodies);
  for (std::size_t b = 0; b < nbodies; ++b) {
    const BodyDescription &spec = c.bodies[b];
    const fem::IsotropicMaterial &mat = spec.material;
    SceneBody &sb = scene.bodies[b];
    sb.mechanism = static_cast<int>(scene.mechanism.bodies.size());
    const BodyModel model = simulated_model(spec.model);
    if (model == BodyModel::Acf)
      add_acf_body(comm, spec, mat, scene, sb);
    else if (model == BodyModel::Ffrf)
      add_ffrf_body(comm, spec, mat, scene, sb, design);
    else
      add_rigid_body(comm, spec, mat, scene, sb);
    sb.position = v3(spec.initial.position);
    sb.R = Eigen::AngleAxisd(spec.initial.angle, v3(spec.initial.axis)).toRotationMatrix();
    sb.velocity = v3(spec.initial.velocity);
    sb.omega = v3(spec.initial.angular_velocity);
  }
  return scene;
}

namespace {

/// Binds a scene description's joints, drivers, forces and sensors to the placed bodies of a
/// Scene (connect): names resolved to bodies and interfaces, attachments in the mechanism's
/// bodies.
class Connector {
public:
  Connector(const SceneDescription &c, Scene &scene)
      : c_(c), scene_(scene), mech_(scene.mechanism) {
    for (std::size_t b = 0; b < c.bodies.size(); ++b) body_index_[c.bodies[b].name] = b;
    for (const auto &g : c.ground) ground_[g.name] = v3(g.origin);
    for (const JointDescription &j : c.joints) joints_by_name_[j.name] = &j;
    for (const SceneBody &sb : scene.bodies)
      snap_scale_ = std::max(snap_scale_, sb.position.norm());
  }

  /// Euler-parameter normalization, one row per body, first.
  void add_normalizations() {
    for (std::size_t b = 0; b < mech_.bodies.size(); ++b) {
      Equation e;
      e.kind = K::Normalize;
      e.a = static_cast<int>(b);
      e.owner = std::string(mech_.bodies[b]->model() == std::string("interface") ? "interface node "
                                                                                 : "body ") +
                mech_.bodies[b]->name() + " (|p| = 1)";
      mech_.equations.push_back(e);
    }
  }

  /// Drivers come before the joints: when rows are found redundant, joint rows are left out
  /// rather than a prescribed motion.
  void add_drivers() {
    for (const DriverDescription &d : c_.drivers) {
      const JointDescription &j = *joints_by_name_.at(d.joint);
      const auto [A, B] = joint_attachments(j);
      mech_.equations.push_back(driver_equation(j.type, A, B, v3(j.axis),
                                                std::make_shared<const Expression>(d.expression),
                                                "driver of joint " + j.name));
    }
  }

  void add_joints() {
    for (const JointDescription &j : c_.joints) {
      const auto [A, B] = joint_attachments(j);
      joint_equation_[j.name] = static_cast<int>(mech_.equations.size());
      const double gap = (A.world - B.world).norm();
      if (j.type != JointType::Prismatic) gaps_.emplace_back(&j, gap);
      if (gap > max_gap_ && (j.type != JointType::Prismatic)) max_gap_ = gap, gap_joint_ = j.name;
      for (Equation &e : joint_equations(j.type, A, B, v3(j.axis),
                                         "joint " + j.name + " (" + joint_type_name(j.type) + ")"))
        mech_.equations.push_back(std::move(e));
    }
  }

  /// Refuses a joint whose interfaces the initial placement puts apart by more than a tenth of
  /// the larger body it joins (an angle given in degrees, a position off by a body's length):
  /// the consistent start would close such a gap by moving bodies far from where the case put
  /// them, or, for an FFRF body, by a huge "elastic" displacement. Collective.
  void check_gaps() const {
    std::vector<double> sizes;
    for (const mesh::DistributedMesh &m : scene_.meshes) sizes.push_back(mesh::mesh_extent(m));
    const auto size = [&](const std::string &body) {
      const auto it = body_index_.find(body);
      return it == body_index_.end() ? 0.0 : sizes[it->second]; // the ground: 0
    };
    for (const auto &[j, gap] : gaps_) {
      const double sa = size(j->a), sb = size(j->b), s = std::max(sa, sb);
      if (gap <= 0.1 * s) continue;
      char buf[400];
      std::snprintf(buf, sizeof buf,
                    ": joint '%s': its interfaces are %.3g m apart in the initial placement, more "
                    "than a tenth of the larger body it joins ('%s' %.3g m, '%s' %.3g m across): "
                    "place the bodies where the joint holds them (bodies[].initial position and "
                    "angle; angles are in radians)",
                    j->name.c_str(), gap, j->a.c_str(), sa, j->b.c_str(), sb);
      throw Error(j->where.str() + buf, true);
    }
  }

  /// The joints' gaps in the initial placement: the largest one snapped, the largest one left.
  void report_gaps(MPI_Comm comm) const {
    if (max_snap_ > 0)
      print0(comm,
             "scene: the interfaces of joint %s are %.3g m apart in the initial placement (a "
             "meshed surface's centroid); joints with gaps below %g m are placed at their body "
             "a's interface point\n",
             snap_joint_.c_str(), max_snap_, kMeshGap * snap_scale_);
    // (A scene with ACF bodies is not projected: its initial state checks the joints instead.)
    if (max_gap_ > 1e-9 && scene_.acf.empty())
      print0(comm,
             "scene: the interfaces of joint %s are %.3g m apart in the initial placement; the "
             "initial conditions move the bodies to close the joints\n",
             gap_joint_.c_str(), max_gap_);
  }

  void add_forces() {
    for (const ForceDescription &f : c_.forces) {
      PointForce pf;
      const Attachment a = attach(f.body, f.interface);
      const std::size_t ub = body_index_.at(f.body);
      pf.body = a.body;
      pf.s = a.s;
      if (const auto &red = scene_.bodies[ub].reduction)
        pf.S = red->translation[interface_index(ub, f.interface)];
      for (int k = 0; k < 3; ++k)
        pf.value[static_cast<std::size_t>(k)] = Expression(f.value[static_cast<std::size_t>(k)]);
      mech_.forces.push_back(pf);
    }
  }

  /// The sensors in scene.sensors; returns (sensor, joint equation) of the reaction sensors.
  std::vector<std::pair<std::size_t, int>> bind_sensors() {
    std::vector<std::pair<std::size_t, int>> reactions;
    for (const SensorDescription &s : c_.sensors) {
      if (!s.joint.empty()) {
        BoundSensor bs;
        bs.name = s.name;
        bs.quantity = s.quantity;
        bs.body = -1;
        reactions.emplace_back(scene_.sensors.size(), joint_equation_.at(s.joint));
        scene_.sensors.push_back(bs);
      } else {
        scene_.sensors.push_back(body_sensor(s));
      }
    }
    return reactions;
  }

private:
  /// Interface points closer than kMeshGap of the scene's size are taken to meet
  /// (joint_attachments).
  static constexpr double kMeshGap = 1e-4;

  /// Position of a (validated) interface in the body's list: the index of its reduction data.
  std::size_t interface_index(std::size_t b, const std::string &iface) const {
    const auto &list = c_.bodies[b].interfaces;
    return static_cast<std::size_t>(std::find(list.begin(), list.end(), iface) - list.begin());
  }

  Attachment attach(const std::string &body, const std::string &iface) const {
    Attachment a;
    if (body == "ground") {
      a.s = ground_.at(iface);
      a.world = a.s;
      return a;
    }
    const std::size_t ub = body_index_.at(body);
    const SceneBody &sb = scene_.bodies[ub];
    // An ACF body's interface: its interface node (reference point at the centroid).
    a.body = sb.mechanism >= 0 ? sb.mechanism : sb.nodes[interface_index(ub, iface)];
    const Vec3 X = sb.interfaces.at(iface);
    a.s = X - mech_.bodies[static_cast<std::size_t>(a.body)]->origin();
    a.R = sb.R;
    a.world = sb.position + a.R * X;
    if (sb.reduction) {
      const std::size_t i = interface_index(ub, iface);
      a.translation = sb.reduction->translation[i];
      a.rotation = sb.reduction->rotation[i];
    }
    return a;
  }

  /// A body given an initial elastic field meets its joints through that field.
  bool elastic_start(const std::string &body) const {
    if (body == "ground") return false;
    const SceneBody &sb = scene_.bodies[body_index_.at(body)];
    return static_cast<bool>(sb.u0) || sb.elastic0.size() > 0;
  }

  /// A joint's two attachments. Interface points closer than kMeshGap of the scene's size are
  /// taken to meet: a meshed curved surface's centroid (a pin hole's) misses the geometric
  /// centre by such an amount, and an over-constrained (planar) mechanism's projection would
  /// leave that misfit in its redundant rows, while ACF scenes are not projected at all. Body
  /// b's attachment is moved onto body a's point (by the gap, in b's axes), so the placement
  /// is assembled exactly. Larger gaps are left to the initial conditions (rigid and FFRF
  /// bodies: projected; ACF: refused); so are bodies with an initial elastic field. Prismatic
  /// joints hold for any points (their offsets are taken from the placement).
  /// docs/case-format.md "joints".
  std::pair<Attachment, Attachment> joint_attachments(const JointDescription &j) {
    const Attachment A = attach(j.a, j.a_interface);
    Attachment B = attach(j.b, j.b_interface);
    const Vec3 d = A.world - B.world;
    const double gap = d.norm();
    if (j.type != JointType::Prismatic && gap > 0 && gap <= kMeshGap * snap_scale_ &&
        !elastic_start(j.a) && !elastic_start(j.b)) {
      B.s += B.body < 0 ? d : Vec3(B.R.transpose() * d);
      B.world = A.world;
      if (gap > max_snap_) max_snap_ = gap, snap_joint_ = j.name;
    }
    return std::make_pair(A, B);
  }

  /// A sensor at a point of a body: in the ACF body's mesh (measured in the frame of its first
  /// interface node), or in a rigid or FFRF body's frame (with the modes at the point).
  BoundSensor body_sensor(const SensorDescription &s) const {
    BoundSensor bs;
    bs.name = s.name;
    bs.quantity = s.quantity;
    const std::size_t ub = body_index_.at(s.body);
    bs.point = v3(s.point);
    const SceneBody &sb = scene_.bodies[ub];
    const std::string where = s.where.str() + ": sensor '" + s.name + "' point";
    if (sb.acf >= 0) {
      bs.acf_body = static_cast<int>(ub);
      bs.body = sb.nodes.empty() ? -1 : sb.nodes.front();
      if (bs.body < 0 && (s.quantity == SensorQuantity::ElasticDisplacement ||
                          s.quantity == SensorQuantity::RotationAngle))
        throw Error(s.where.str() + ": sensor '" + s.name + "': " + quantity_name(s.quantity) +
                        " of an ACF body is measured in the frame of its interfaces, and "
                        "body '" +
                        s.body + "' lists no interfaces",
                    true);
      bs.location =
          fem::locate(scene_.meshes[ub], {bs.point.x(), bs.point.y(), bs.point.z()}, where);
      return bs;
    }
    bs.body = sb.mechanism;
    bs.s = bs.point - mech_.bodies[static_cast<std::size_t>(bs.body)]->origin();
    if (sb.reduction) {
      bs.location =
          fem::locate(scene_.meshes[ub], {bs.point.x(), bs.point.y(), bs.point.z()}, where);
      bs.S = reduce::basis_at_point(scene_.meshes[ub], *sb.reduction, bs.location);
    }
    return bs;
  }

  const SceneDescription &c_;
  Scene &scene_;
  Mechanism &mech_;
  std::map<std::string, std::size_t> body_index_;
  std::map<std::string, Vec3> ground_;
  std::map<std::string, const JointDescription *> joints_by_name_;
  std::map<std::string, int> joint_equation_; ///< a joint's first equation (the coincidence)
  double snap_scale_ = 1, max_snap_ = 0, max_gap_ = 0;
  std::string snap_joint_, gap_joint_;
  std::vector<std::pair<const JointDescription *, double>> gaps_; ///< not prismatic
};

/// Finalizes the scene's mechanism: the rigid sensors' empty mode matrices sized, the
/// redundant rows dropped at q0, the reaction sensors' multiplier rows and the length scale.
void finish_mechanism(Scene &scene, const std::vector<std::pair<std::size_t, int>> &reactions) {
  Mechanism &mech = scene.mechanism;
  mech.finalize();
  for (BoundSensor &bs : scene.sensors)
    if (bs.acf_body < 0 && bs.body >= 0 && bs.S.cols() == 0)
      bs.S.setZero(3, mech.size(bs.body) - 7);
  scene.redundant_rows = mech.drop_redundant_rows(scene.q0, 0.0);
  for (const auto &[k, e] : reactions) {
    // A planar mechanism built of 3D joints has redundant out-of-plane rows; a dropped row's
    // force component is carried by the rows kept (statically indeterminate): reported 0.
    BoundSensor &bs = scene.sensors[k];
    const int r0 = mech.first_row(e);
    for (int i = 0; i < 3; ++i)
      bs.lambda_rows[static_cast<std::size_t>(i)] = mech.enforced_index(r0 + i);
  }
  for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b)
    scene.length_scale =
        std::max(scene.length_scale, scene.q0.segment<3>(mech.offset(b)).cwiseAbs().maxCoeff());
}

} // namespace

void connect(MPI_Comm comm, const SceneDescription &c, Scene &scene, bool report) {
  Mechanism &mech = scene.mechanism;
  mech.equations.clear();
  mech.forces.clear();
  scene.sensors.clear();
  place(comm, c, scene);
  Connector k(c, scene);
  k.add_normalizations();
  k.add_drivers();
  k.add_joints();
  if (report) {
    k.check_gaps();
    k.report_gaps(comm);
  }
  if (c.gravity) mech.gravity = v3(*c.gravity);
  k.add_forces();
  finish_mechanism(scene, k.bind_sensors());
}

Scene build_scene(MPI_Comm comm, const SceneDescription &c, const InitialDesign *design) {
  Scene scene = load_bodies(comm, c, design);
  connect(comm, c, scene, true);
  return scene;
}

void set_body_model(MPI_Comm comm, const SceneDescription &c, Scene &scene, std::size_t b,
                    std::shared_ptr<bodies::Body> body) {
  const int mb = scene.bodies.at(b).mechanism;
  if (mb < 0) throw Error("set_body_model: body '" + c.bodies[b].name + "' is an ACF body", true);
  scene.mechanism.bodies[static_cast<std::size_t>(mb)] = std::move(body);
  connect(comm, c, scene, false);
}

std::shared_ptr<const reduce::FlexibleReduction>
set_ffrf_design(MPI_Comm comm, const SceneDescription &c, Scene &scene, std::size_t b,
                const reduce::ElementFactors &factors) {
  const BodyDescription &spec = c.bodies.at(b);
  SceneBody &sb = scene.bodies.at(b);
  if (!sb.reduction)
    throw Error("set_ffrf_design: body '" + spec.name + "' is not an FFRF body", true);
  const mesh::DistributedMesh &m = scene.meshes[b];
  const double t0 = wall_time();
  const auto red = reduce_ffrf_body(m, spec, spec.material, &factors, sb.reduction.get());
  sb.reduction = red;
  scene.owned_modes[b] = reduce::owned_basis_values(*red, m.owned_nodes);
  scene.reduction_seconds[b] = wall_time() - t0;
  const double density = spec.material.density;
  sb.elastic0 = initial_elastic(comm, spec, m, density, *red, false, false);
  sb.elastic_rate0 = initial_elastic(comm, spec, m, density, *red, true, false);
  set_body_model(comm, c, scene, b,
                 std::make_shared<bodies::FfrfBody>(spec.name, ffrf_model(*red, spec)));
  return red;
}

std::vector<const bodies::AcfBody *> acf_body_list(const Scene &scene) {
  std::vector<const bodies::AcfBody *> list;
  for (const auto &a : scene.acf) list.push_back(a.get());
  return list;
}

DistState acf_initial_state(const Scene &scene, const DistributedAlpha &da, StartReport *report,
                            DistStartTrace *trace) {
  Vec x0 = da.create_vector(), v0 = da.create_vector();
  struct Destroy {
    Vec &x, &v;
    ~Destroy() {
      VecDestroy(&x);
      VecDestroy(&v);
    }
  } destroy{x0, v0}; // also when the initial state throws
  for (const SceneBody &sb : scene.bodies) {
    if (sb.acf < 0) continue;
    const auto k = static_cast<std::size_t>(sb.acf);
    auto placed = [&](const Vec3 &X) { return Vec3(X + (sb.u0 ? sb.u0(X) : Vec3::Zero())); };
    da.set_nodal(x0, k, [&](const Vec3 &X) { return Vec3(sb.position + sb.R * placed(X)); });
    da.set_nodal(v0, k, [&](const Vec3 &X) {
      return Vec3(sb.velocity + sb.omega.cross(sb.R * placed(X)) +
                  (sb.u0_rate ? Vec3(sb.R * sb.u0_rate(X)) : Vec3::Zero()));
    });
  }
  da.set_small(x0, scene.q0);
  da.set_small(v0, scene.v0);
  return da.initial_state(x0, v0, 0.0, report, trace);
}

FrameNodes acf_frame_nodes(const Scene &scene, const SceneBody &body, const State &small) {
  const Mechanism &mech = scene.mechanism;
  FrameNodes n;
  n.condition = body.frame;
  const int o = mech.offset(body.nodes.front());
  n.r0 = small.q.segment<3>(o);
  n.p0 = small.q.segment<4>(o + 3);
  n.c0 = body.centroids.front();
  if (n.condition == reduce::FrameCondition::Chord) {
    n.r1 = small.q.segment<3>(mech.offset(body.nodes[1]));
    n.c1 = body.centroids[1];
  }
  return n;
}

InterfaceFrame acf_frame(const Scene &scene, const SceneBody &body, const State &small) {
  return interface_frame(acf_frame_nodes(scene, body, small),
                         scene.acf[static_cast<std::size_t>(body.acf)]->name(), small.t);
}

Vec3 add_acf_elastic_partial(const Scene &scene, const BoundSensor &s, const State &small,
                             const Vec3 &x, const Vec3 &w, Vector &small_q) {
  const SceneBody &sb = scene.bodies[static_cast<std::size_t>(s.acf_body)];
  const FrameCotangent ct =
      elastic_cotangent(acf_frame_nodes(scene, sb, small), x, w,
                        scene.acf[static_cast<std::size_t>(sb.acf)]->name(), small.t);
  const Mechanism &mech = scene.mechanism;
  const int o = mech.offset(sb.nodes.front());
  small_q.segment<3>(o) += ct.r0;
  small_q.segment<4>(o + 3) += ct.p0;
  if (sb.frame == reduce::FrameCondition::Chord)
    small_q.segment<3>(mech.offset(sb.nodes[1])) += ct.r1;
  return ct.x;
}

Vec3 acf_sensor_value(const Scene &scene, const DistributedAlpha &da, const BoundSensor &s,
                      const DistState &state, const State &small) {
  // The first interface node's rotation, as for the body of any other sensor.
  if (s.quantity == SensorQuantity::RotationAngle) return sensor_value(scene, s, small.q);
  const SceneBody &sb = scene.bodies[static_cast<std::size_t>(s.acf_body)];
  const Vec3 x = da.point_position(state, static_cast<std::size_t>(sb.acf), s.location);
  if (s.quantity == SensorQuantity::Position) return x;
  if (s.quantity == SensorQuantity::Displacement) return x - (sb.position + sb.R * s.point);
  return acf_frame(scene, sb, small).elastic(x, s.point);
}

Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const State &state) {
  if (s.quantity != SensorQuantity::Reaction) return sensor_value(scene, s, state.q);
  Vec3 f = Vec3::Zero();
  for (int i = 0; i < 3; ++i) {
    const int r = s.lambda_rows[static_cast<std::size_t>(i)];
    if (r >= 0 && r < state.lambda.size()) f(i) = state.lambda(r);
  }
  return f;
}

Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q) {
  const Mechanism &mech = scene.mechanism;
  const int o = mech.offset(s.body), n = mech.size(s.body);
  if (s.quantity == SensorQuantity::RotationAngle) {
    const Mat3 A = bodies::rotation(q.segment<4>(o + 3).normalized());
    const Mat3 A0 = bodies::rotation(scene.q0.segment<4>(o + 3).normalized());
    return bodies::rotation_vector(A * A0.transpose());
  }
  if (s.quantity == SensorQuantity::ElasticDisplacement) return s.S * q.segment(o + 7, n - 7);
  const Vec3 x = joints::anchor_position(q.segment(o, n), s.s, s.S);
  if (s.quantity == SensorQuantity::Displacement)
    return x - joints::anchor_position(scene.q0.segment(o, n), s.s, s.S);
  return x;
}

} // namespace flexopt::dynamics
