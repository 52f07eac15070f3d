#pragma once
/// \file What a dynamic case describes (docs/case-format.md): its bodies with their models and
/// settings, the fixed frame's points, joints, drivers, interface forces, sensors, gravity and
/// the time integration. The case reader (io/case) fills it; dynamics::load_bodies and connect
/// turn it into a Scene (scene.hpp).
#include "flexopt/fem/element.hpp"
#include "flexopt/io/location.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"

#include <array>
#include <optional>
#include <string>
#include <vector>

namespace flexopt::dynamics {

/// How a body is simulated: rigid, FFRF (floating frame with a Craig-Bampton basis), ACF
/// (absolute nodal coordinates, co-rotated elements), or auto (the plan's choice,
/// docs/theory.md section 12).
enum class BodyModel { Rigid, Ffrf, Acf, Auto };
/// "rigid", "ffrf", "acf", "auto".
const char *model_name(BodyModel model);
/// The model that simulates a body of `model`: the model itself, or for `auto` rigid (the
/// commands that integrate resolve `auto` by the plan first, plan::apply_plan; only `info` sees
/// an unresolved auto).
BodyModel simulated_model(BodyModel model);

enum class JointType { Revolute, Spherical, Prismatic, Fixed };
/// "revolute", "spherical", "prismatic", "fixed".
const char *joint_type_name(JointType type);

/// What a sensor measures (section 7.4): a point's world position, its displacement from the
/// initial position, its elastic displacement in the body's frame, the body frame's rotation
/// vector, or (a joint sensor) the force its joint applies to the joint's body b.
enum class SensorQuantity { Position, Displacement, ElasticDisplacement, RotationAngle, Reaction };
/// "position", "displacement", "elastic_displacement", "rotation_angle", "reaction".
const char *quantity_name(SensorQuantity quantity);

/// Placement of a body frame at t = 0 and its velocity (`bodies[].initial`, dynamic analyses).
/// The body's mesh coordinates are body-frame coordinates; the frame is placed at `position`
/// and rotated by `angle` about `axis` (world frame).
struct InitialPlacement {
  std::array<double, 3> position{0, 0, 0};         ///< [m]
  std::array<double, 3> axis{0, 0, 1};             ///< unit vector (normalized when read)
  double angle = 0;                                ///< [rad]
  std::array<double, 3> velocity{0, 0, 0};         ///< of the body-frame origin [m/s]
  std::array<double, 3> angular_velocity{0, 0, 0}; ///< world frame [rad/s]
  /// ffrf and acf only: the elastic displacement [m] and velocity [m/s] relative to the body
  /// frame, as expressions in the mesh coordinates x, y, z (components in the mesh axes);
  /// projected onto the reduction basis of an ffrf body (docs/theory.md section 7.6), added to
  /// the placed nodes of an acf body (section 8.2). Empty: zero.
  std::array<std::string, 3> elastic_displacement, elastic_velocity;
};

/// `bodies[].reduction` of an FFRF body: the Craig-Bampton basis (docs/theory.md section 7.1).
struct ReductionSettings {
  int modes = 4; ///< fixed-interface eigenmodes (plus 6 static modes per interface after the first)
  bool geometric_stiffening = false; ///< centrifugal geometric stiffness (section 7.5)
  /// Where the floating frame sits: clamped (interface 0 clamped) or chord (origin at
  /// interface 0, axis through interface 1). Not written in case.yaml: chord for a body with two
  /// or more interfaces and no geometric stiffening (a link between joints), clamped otherwise;
  /// `frame_given` tells which.
  reduce::FrameCondition frame = reduce::FrameCondition::Clamped;
  bool frame_given = false;
};
/// "clamped", "chord".
const char *frame_name(reduce::FrameCondition frame);

/// A body of the case. It may carry the settings of every model (`reduction` for ffrf,
/// `damping` and the initial elastic fields for ffrf and acf); `model` picks the ones used, so
/// that switching a body's model is one word.
struct BodyDescription {
  std::string name;
  BodyModel model = BodyModel::Auto;
  mesh::MeshSource mesh;               ///< geometry and mesh settings
  std::string material_name;           ///< `material:`, a name of `materials:`
  fem::IsotropicMaterial material;     ///< that material
  std::vector<std::string> interfaces; ///< physical surfaces for joints and forces, unique
  InitialPlacement initial;            ///< dynamic only (identity at rest if not given)
  ReductionSettings reduction;         ///< used by ffrf
  /// Rayleigh damping C = a M + b K of the elastic coordinates (used by ffrf; by acf, which
  /// takes [0, b] only): [a, b].
  std::array<double, 2> rayleigh{0, 0};
  /// The model-dependent settings written in case.yaml (keys of io::model_settings(), in that
  /// order), whichever model they serve; the others hold their defaults.
  std::vector<std::string> settings;
  io::Location where;
};

/// A named point of the fixed frame (`ground: {interfaces: {NAME: [x, y, z]}}`); its frame is
/// the world frame.
struct GroundInterface {
  std::string name;
  std::array<double, 3> origin{0, 0, 0};
  io::Location where;
};

/// A joint between two interfaces (`joints:`). `a` or `b` may be "ground".
struct JointDescription {
  std::string name;
  JointType type = JointType::Revolute;
  std::string a, a_interface, b, b_interface;
  std::array<double, 3> axis{0, 0, 0}; ///< revolute, prismatic: unit axis, world frame at t = 0
  io::Location where;
};

/// A prescribed joint coordinate (`drivers:`): revolute angle [rad] or prismatic displacement
/// [m] from the initial configuration, as a muParser expression in t (flexopt::Expression;
/// compiled once when read, so it does not throw).
struct DriverDescription {
  std::string joint;
  std::string expression;
  io::Location where;
};

/// A force [N] at an interface (`loads.forces`), world frame; each component a number or a
/// muParser expression in t, stored as written in case.yaml (compiled once when read, so
/// `flexopt::Expression(value[k])` does not throw).
struct ForceDescription {
  std::string body;
  std::string interface;
  std::array<std::string, 3> value;
  io::Location where;
};

/// A point sensor: a quantity FE-interpolated at `point` (undeformed body coordinates); or a
/// joint sensor (`joint:` set, quantity `reaction`): the force the joint applies to its body b.
struct SensorDescription {
  std::string name;
  std::string body;
  std::string joint;
  std::array<double, 3> point{0, 0, 0};
  SensorQuantity quantity = SensorQuantity::Displacement;
  io::Location where;
};

/// Time integration (`time:`).
struct TimeSettings {
  double end = 0;       ///< [s], > 0
  double step = 0;      ///< [s], > 0, <= end
  double rho_inf = 0.8; ///< generalized-alpha spectral radius at infinity, in [0, 1]
  /// Largest contraction of Newton iterations on a kept iteration matrix before a new one is
  /// assembled (NewtonSettings::reuse_contraction), in [0, 1); 0: Newton proper.
  double newton_reuse = 0.1;
  bool given = false;
  io::Location where;
};

/// A dynamic case's scene.
struct SceneDescription {
  std::string file; ///< case.yaml (messages about the whole scene)
  std::vector<BodyDescription> bodies;
  std::vector<GroundInterface> ground;
  std::vector<JointDescription> joints;
  std::vector<DriverDescription> drivers;
  std::vector<ForceDescription> forces;
  std::vector<SensorDescription> sensors;
  std::optional<std::array<double, 3>> gravity; ///< [m/s^2]
  /// The body named `name`; throws flexopt::Error if there is none.
  const BodyDescription &body(const std::string &name) const;
};

} // namespace flexopt::dynamics
