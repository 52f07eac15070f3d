#pragma once
/// \file A dynamic case turned into a Mechanism: bodies meshed; rigid bodies' mass properties
/// integrated (rank 0, broadcast), FFRF bodies reduced (in parallel); interfaces located,
/// joints and drivers expanded into constraint equations, loads and sensors bound
/// (docs/theory.md sections 6.3 and 7.4).
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/dynamics/interface_frame.hpp"
#include "flexopt/dynamics/mechanism.hpp"
#include "flexopt/dynamics/scene_description.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/field_projection.hpp"

#include <array>
#include <functional>
#include <map>
#include <memory>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::reduce {
struct FlexibleReduction;
struct ElementFactors;
} // namespace flexopt::reduce

namespace flexopt::dynamics {

/// A sensor bound to a body: `point` in body (mesh) coordinates; s + S zeta is the point
/// relative to the body's reference point (S: the basis at the point, empty for rigid bodies).
/// On an ACF body (`acf_body` >= 0: that case body), `body` is the node of its first interface
/// (-1: none), whose frame measures the elastic displacement, and `location` the point in the
/// body's mesh.
struct BoundSensor {
  std::string name;
  SensorQuantity quantity = SensorQuantity::Displacement;
  int body = 0;
  /// reaction: the joint's coincident-point rows in lambda (-1: a row dropped as redundant).
  std::array<int, 3> lambda_rows{-1, -1, -1};
  Vec3 point{0, 0, 0};
  Vec3 s{0, 0, 0};
  joints::Elastic S;
  int acf_body = -1;
  fem::PointLocation location; ///< ACF and FFRF bodies: the point in the body's mesh
};

/// What a case body became: a body of the mechanism (rigid, FFRF) or an ACF body with one
/// interface-node body per interface.
struct SceneBody {
  int mechanism = -1;          ///< body index in Scene::mechanism (-1: ACF)
  int acf = -1;                ///< index in Scene::acf (-1: not ACF)
  std::vector<int> nodes;      ///< ACF: the interface nodes' bodies, in the case's order
  std::vector<Vec3> centroids; ///< ACF: the interface centroids c_I (mesh coordinates)
  /// ACF: the frame of its elastic displacement (the body's reduction.frame, section 8.4).
  reduce::FrameCondition frame = reduce::FrameCondition::Clamped;
  Vec3 position{0, 0, 0}; ///< initial placement: mesh point X at position + R X
  bodies::Mat3 R = bodies::Mat3::Identity();
  Vec3 velocity{0, 0, 0}, omega{0, 0, 0}; ///< initial velocity of the mesh origin, spin
  /// ACF: initial elastic displacement u(X) and velocity (mesh axes), added to the placement:
  /// x = position + R (X + u), v = velocity + omega x R (X + u) + R u'. Null: zero.
  std::function<Vec3(const Vec3 &)> u0, u0_rate;
  /// The interface centroids (mesh coordinates) by name.
  std::map<std::string, Vec3> interfaces;
  /// FFRF: the reduction (interface motion in the order of the case's interfaces) and the
  /// initial elastic coordinates zeta, zeta' (empty: zero). Null and empty otherwise.
  std::shared_ptr<const reduce::FlexibleReduction> reduction;
  bodies::Vector elastic0, elastic_rate0;
};

struct Scene {
  /// The rigid, FFRF and interface-node bodies with the joints, drivers and loads: the whole
  /// mechanism without ACF bodies, its small part with them.
  Mechanism mechanism;
  /// Per case body, in the case's order (reserved once: the ACF bodies refer to them).
  std::vector<mesh::DistributedMesh> meshes;
  std::vector<SceneBody> bodies; ///< per case body
  std::vector<std::unique_ptr<bodies::AcfBody>> acf;
  std::vector<AcfInterface> acf_interfaces; ///< every ACF interface and its node
  /// Per body: the reduction basis at the owned nodes, (3 owned nodes) x n, node-major (empty
  /// for rigid bodies): the deformed mesh of the output.
  std::vector<Eigen::MatrixXd> owned_modes;
  std::vector<double> reduction_seconds; ///< per body: wall time of its reduction (0: rigid)
  Vector q0, v0; ///< placed coordinates and velocities of `mechanism` at t = 0
  std::vector<BoundSensor> sensors;
  std::vector<std::string> redundant_rows; ///< constraint rows found redundant and not enforced
  double length_scale = 1;                 ///< largest extent of the placed scene [m]
};

/// Where a joint attaches, in the initial placement: the body (-1: ground), the interface point
/// relative to the body's centre of mass in body axes (ground: world), the body's initial
/// rotation and the point's initial world position.
struct Attachment {
  int body = -1;
  Vec3 s{0, 0, 0};
  bodies::Mat3 R = bodies::Mat3::Identity();
  Vec3 world{0, 0, 0};
  /// Flexible body: the interface node's translation and small rotation per elastic
  /// coordinate (3 x n, body axes); empty for rigid bodies and the ground.
  joints::Elastic translation, rotation;
  /// A world direction in the initial placement, expressed in the body's axes.
  Vec3 local(const Vec3 &world_vector) const { return R.transpose() * world_vector; }
  /// The elastic part of a body vector u fixed to the interface: the rotation theta = Theta
  /// zeta turns u by theta x u = -[u]x Theta zeta.
  joints::Elastic vector_part(const Vec3 &u) const {
    if (rotation.cols() == 0) return {};
    return -bodies::skew(u) * rotation;
  }
};

/// The equations of a joint (docs/theory.md section 6.3): spherical 3 rows, revolute 5,
/// prismatic 5, fixed 6, with vectors fixed from the initial placement and the world `axis`
/// (revolute, prismatic). Satisfied at the initial placement when the interface points
/// coincide (prismatic: for any interface points).
std::vector<joints::Equation> joint_equations(JointType type, const Attachment &a,
                                              const Attachment &b, const Vec3 &axis,
                                              const std::string &owner);
/// The equation of a driver f(t) on a revolute joint (angle from the initial placement) or a
/// prismatic joint (displacement along the axis from the initial placement).
joints::Equation driver_equation(JointType joint_type, const Attachment &a, const Attachment &b,
                                 const Vec3 &axis, std::shared_ptr<const Expression> f,
                                 const std::string &owner);

/// A scene is built in two phases (docs/architecture.md, "Scenes"):
///
/// 1. load_bodies, once per run: every body meshed and distributed (Gmsh on rank 0, METIS),
///    its model built (rigid mass properties integrated on rank 0 and broadcast, FFRF bodies
///    reduced in parallel, ACF elements set up) and its interfaces located. This is the
///    expensive part.
/// 2. connect, after phase 1 and again whenever a body's model changes (a design evaluation
///    replacing a body's model): the initial placement q0, v0, the joints and drivers as
///    constraint equations, the loads and the sensors bound to the bodies, redundant rows
///    dropped. Cheap. `report`: print the notes on the initial placement (the first time).
///
/// Both are collective and throw collective flexopt::Errors naming the case key for
/// scene-level problems (an interface without area, a sensor on a missing body).
/// An FFRF design body's element factors at its first design: load_bodies reduces that body
/// once with them (not with the solid material first).
struct InitialDesign {
  std::vector<std::string> bodies; ///< the FFRF design bodies
  /// A design body's element factors at its first design, from its name and mesh.
  std::function<reduce::ElementFactors(const std::string &, const mesh::DistributedMesh &)> factors;
};
Scene load_bodies(MPI_Comm comm, const SceneDescription &d, const InitialDesign *design = nullptr);
void connect(MPI_Comm comm, const SceneDescription &d, Scene &scene, bool report);
/// Both phases: the scene of a dynamic case.
Scene build_scene(MPI_Comm comm, const SceneDescription &d, const InitialDesign *design = nullptr);
/// Per design: case body b (rigid or FFRF) takes the model `body` (a design's mass
/// properties, say) and the scene is connected again; no mesh is touched. Collective.
void set_body_model(MPI_Comm comm, const SceneDescription &d, Scene &scene, std::size_t b,
                    std::shared_ptr<bodies::Body> body);

/// Reduces the FFRF body b again with a design body's element factors (its stiffness and mass
/// per element, docs/theory.md section 10; the reduction keeps its adjoint data), and replaces
/// its reduction, basis values and body model, then connects the scene again (joint maps and
/// sensor bases from the new basis), the initial elastic coordinates projected with the design's
/// mass (section 10.2). Returns the new reduction. Collective; throws a collective
/// flexopt::Error if the modes count splits a repeated eigenvalue (reduce::check_modal_cut).
std::shared_ptr<const reduce::FlexibleReduction>
set_ffrf_design(MPI_Comm comm, const SceneDescription &d, Scene &scene, std::size_t b,
                const reduce::ElementFactors &factors);

/// The field `initial.elastic_displacement` (or `elastic_velocity`, if `rate`) of a body as a
/// function of the mesh coordinates; empty if the case gives none.
reduce::Field initial_elastic_field(const BodyDescription &spec, bool rate);

/// The reduction of the FFRF body `spec` meshed as `m` (its interfaces, modes, stiffening and
/// frame; with a design body's element factors, if given, and then its modal-cut check). With
/// `previous`, the body's reduction at an earlier design: its factorization's symbolic analysis
/// is reused. Collective.
std::shared_ptr<reduce::FlexibleReduction>
reduce_ffrf_body(const mesh::DistributedMesh &m, const BodyDescription &spec,
                 const fem::IsotropicMaterial &mat, const reduce::ElementFactors *design,
                 const reduce::FlexibleReduction *previous = nullptr);

/// The scene's ACF bodies, in order (DistributedAlpha's list).
std::vector<const bodies::AcfBody *> acf_body_list(const Scene &scene);
/// The consistent state at t = 0 of a scene with ACF bodies on `da` (built on the scene's ACF
/// bodies, mechanism and interfaces): every ACF body placed as its initial placement and
/// elastic fields say, the mechanism's coordinates from q0, v0, then
/// DistributedAlpha::initial_state (report and trace as there). Collective.
DistState acf_initial_state(const Scene &scene, const DistributedAlpha &da,
                            StartReport *report = nullptr, DistStartTrace *trace = nullptr);

/// What the elastic-displacement frame of an ACF body is built from at the mechanism state
/// `small`: its frame condition, its first interface node (and its second's position, chord
/// only), the interface centroids (docs/theory.md section 8.4). The body lists an interface.
FrameNodes acf_frame_nodes(const Scene &scene, const SceneBody &body, const State &small);
/// The frame itself (interface_frame of acf_frame_nodes); throws a collective flexopt::Error
/// naming the body and the time where a chord frame is undefined.
InterfaceFrame acf_frame(const Scene &scene, const SceneBody &body, const State &small);
/// The partials of w . e, e the elastic displacement of sensor `s` (an ACF body's) at world
/// position x: on the point (returned; spread over its element's nodes by the caller) and, added
/// into `small_q` (the mechanism's coordinates), on the interface nodes (section 8.4).
Vec3 add_acf_elastic_partial(const Scene &scene, const BoundSensor &s, const State &small,
                             const Vec3 &x, const Vec3 &w, Vector &small_q);

/// Value of a sensor of an ACF body at a state of `da` (the meaning of sensor_value; the elastic
/// displacement is A_F^T (x - r_0) - (X - c_0) in the body's frame, acf_frame; rotation_angle is
/// the first interface node's). Collective.
Vec3 acf_sensor_value(const Scene &scene, const DistributedAlpha &da, const BoundSensor &s,
                      const DistState &state, const State &small);

/// Value of a sensor at coordinates q (3 numbers): position (world), displacement from the
/// initial position, elastic_displacement (S zeta, in the axes of the body frame; zero for a
/// rigid body) or rotation_angle (the rotation vector of the body frame relative to its
/// initial orientation, world frame).
Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q);
/// Value of a sensor of the mechanism at a state: sensor_value of its coordinates, or for a
/// reaction sensor the force [N, world axes] its joint applies to the joint's body b at the
/// coincident point, from the state's multipliers (the constraint x_a - x_b = 0 enters
/// M a = Q - Phi_q^T lambda: on body b, +lambda).
Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const State &state);

} // namespace flexopt::dynamics
