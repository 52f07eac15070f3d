#pragma once
/// \file The case directory: case.yaml parsed and validated into plain specs.
///
/// Every rank parses case.yaml itself (it is small), so that a malformed case raises the same
/// collective flexopt::Error on every rank: `case.yaml:LINE:COL: message`. See
/// docs/case-format.md for every key.
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/io/location.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/optimize/design_field.hpp"
#include "flexopt/optimize/optimizer.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace flexopt::io {

struct MaterialSpec {
  std::string name;
  double E = 0;       ///< Young's modulus [Pa]
  double nu = 0;      ///< Poisson's ratio
  double density = 0; ///< [kg/m^3]
};

/// Placement of a body frame at t = 0 and its velocity (`bodies[].initial`, dynamic analyses).
/// The body's mesh coordinates are body-frame coordinates; the frame is placed at `position`
/// and rotated by `angle` about `axis` (world frame).
struct InitialSpec {
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
struct ReductionSpec {
  int modes = 4; ///< fixed-interface eigenmodes (plus 6 static modes per interface after the first)
  bool geometric_stiffening = false; ///< centrifugal geometric stiffness (section 7.5)
  /// Where the floating frame sits: "clamped" (interface 0 clamped) or "chord" (origin at
  /// interface 0, axis through interface 1; reduce::FrameCondition). Not written in case.yaml:
  /// chord for a body with two or more interfaces and no geometric stiffening (a link between
  /// joints), clamped otherwise; `frame_given` tells which.
  std::string frame = "clamped";
  bool frame_given = false;
};

/// A body in case.yaml. It may carry the settings of every model (`reduction` for ffrf,
/// `damping` and the initial elastic fields for ffrf and acf); `model` picks the ones used
/// (model_settings(), unused_settings()), so that switching a body's model is one word.
struct BodySpec {
  std::string name;
  std::string model = "auto";          ///< rigid | ffrf | acf | auto (dynamic: the plan's choice)
  mesh::MeshSource mesh;               ///< geometry and mesh settings
  std::string material_name;           ///< `material:`, a name of `materials:`
  fem::IsotropicMaterial material;     ///< that material
  std::vector<std::string> interfaces; ///< physical surfaces for joints and forces, unique
  InitialSpec initial;                 ///< dynamic only (identity at rest if not given)
  ReductionSpec reduction;             ///< used by ffrf
  /// Rayleigh damping C = a M + b K of the elastic coordinates (used by ffrf; by acf, which
  /// takes [0, b] only): [a, b].
  std::array<double, 2> rayleigh{0, 0};
  /// The model-dependent settings written in case.yaml (keys of model_settings(), in that
  /// order), whichever model they serve; the others hold their defaults.
  std::vector<std::string> settings;
  Location where;
};

/// A body setting that only some models use.
struct ModelSetting {
  std::string key;                 ///< below the body: "reduction", "initial.elastic_velocity"
  std::vector<std::string> models; ///< the models (rigid, ffrf, acf) that use it
};

/// Every model-dependent body setting, in the order of docs/case-format.md: `reduction` (ffrf),
/// `damping` (ffrf, acf), `initial.elastic_displacement` and `initial.elastic_velocity` (ffrf,
/// acf). Every other body key is used by every model.
const std::vector<ModelSetting> &model_settings();

/// The formulation that simulates a body of `model` in a dynamic analysis: the model itself,
/// or for `auto` rigid — the commands that integrate resolve `auto` by the plan first
/// (plan::apply_plan, docs/theory.md section 12); only `info` sees an unresolved auto.
std::string simulated_model(const std::string &model);

/// The keys of model_settings() that a body of `model` uses (`auto`: those of
/// simulated_model(model)).
std::vector<std::string> settings_used_by(const std::string &model);

/// The settings `body` carries that its model does not use, in the order of model_settings().
std::vector<std::string> unused_settings(const BodySpec &body);

/// One line reporting unused_settings(body), e.g. "body rod (model: acf): settings not used by
/// this model: reduction (ffrf)"; empty if every setting the body carries is used.
std::string unused_settings_note(const BodySpec &body);

/// A named point of the fixed frame (`ground: {interfaces: {NAME: [x, y, z]}}`); its frame is
/// the world frame.
struct GroundInterfaceSpec {
  std::string name;
  std::array<double, 3> origin{0, 0, 0};
  Location where;
};

/// A joint between two interfaces (`joints:`). `a` or `b` may be "ground".
struct JointSpec {
  std::string name;
  std::string type; ///< revolute | spherical | prismatic | fixed
  std::string a, a_interface, b, b_interface;
  std::array<double, 3> axis{0, 0, 0}; ///< revolute, prismatic: unit axis, world frame at t = 0
  Location where;
};

/// A prescribed joint coordinate (`drivers:`): revolute angle [rad] or prismatic displacement
/// [m] from the initial configuration, as a muParser expression in t (flexopt::Expression;
/// compiled once when read, so it does not throw).
struct DriverSpec {
  std::string joint;
  std::string expression;
  Location where;
};

/// A force [N] at an interface (`loads.forces`), world frame; each component a number or a
/// muParser expression in t, stored as written in case.yaml (compiled once when read, so
/// `flexopt::Expression(value[k])` does not throw).
struct ForceSpec {
  std::string body;
  std::string interface;
  std::array<std::string, 3> value;
  Location where;
};

/// Time integration (`time:`).
struct TimeSpec {
  double end = 0;       ///< [s], > 0
  double step = 0;      ///< [s], > 0, <= end
  double rho_inf = 0.8; ///< generalized-alpha spectral radius at infinity, in [0, 1]
  /// Largest contraction of Newton iterations on a kept iteration matrix before a new one is
  /// assembled (dynamics::NewtonSettings::reuse_contraction), in [0, 1); 0: Newton proper.
  double newton_reuse = 0.1;
  bool given = false;
  Location where;
};

/// `output:`: which time steps of a dynamic run are written to motion.xdmf (and, when given, at
/// which steps energy and sensors are sampled), or which design iterations of `optimize` are
/// written to design.xdmf. At most one of `every` and `interval`; neither: the defaults of
/// io::FrameSchedule (dynamic) and every iteration (optimize).
struct OutputSpec {
  int every = 0;       ///< output.every, >= 1; 0: not given
  double interval = 0; ///< output.interval [s] of simulated time, > 0 (dynamic only); 0: not given
  bool given() const { return every > 0 || interval > 0; }
};

/// A point sensor: a quantity FE-interpolated at `point` (undeformed body coordinates); or a
/// joint sensor (`joint:` set, quantity `reaction`): the force the joint applies to its body b.
struct SensorSpec {
  std::string name;
  std::string body;
  std::string joint;
  std::array<double, 3> point{0, 0, 0};
  std::string quantity = "displacement";
  Location where;
};

/// `adjoint:` of a dynamic optimization (docs/theory.md section 9.4).
struct AdjointSpec {
  int checkpoints = 0;            ///< stored states; 0: all (`checkpoints: all`)
  std::string storage = "memory"; ///< memory | disk (an HDF5 file in the output directory)
  std::string basis = "exact";    ///< FFRF design bodies: exact | fixed
  Location where;
};

struct Case {
  std::string directory; ///< the case directory as given
  std::string file;      ///< path of case.yaml
  std::string name;      ///< last component of the directory
  std::string analysis;  ///< static | dynamic
  std::vector<MaterialSpec> materials;
  std::vector<BodySpec> bodies;
  std::optional<std::array<double, 3>> gravity; ///< [m/s^2] (dynamic; static: in `loads`)
  fem::StaticLoads loads; ///< static: supports, tractions, line loads, gravity, loads.inertia
  std::vector<SensorSpec> sensors;
  std::vector<GroundInterfaceSpec> ground; ///< dynamic: named points of the fixed frame
  std::vector<JointSpec> joints;           ///< dynamic
  std::vector<DriverSpec> drivers;         ///< dynamic
  std::vector<ForceSpec> forces;           ///< dynamic: loads.forces
  TimeSpec time;                           ///< dynamic
  std::string solver;                      ///< PETSc options applied before the command line's
  OutputSpec output;                       ///< `output:` (docs/case-format.md)
  std::optional<optimize::DesignSettings> design;      ///< topology optimization: the design field
  std::optional<optimize::ResponseSettings> objective; ///< topology optimization: minimized
  std::vector<optimize::ResponseSettings> constraints; ///< topology optimization: each <= max
  optimize::OptimizerSettings optimizer;
  AdjointSpec adjoint; ///< dynamic optimization: checkpointing of the backward sweep
  /// `accuracy`: the relative error of the sensors the user accepts; `model: auto` and
  /// `flexopt plan` choose each body's model for it (docs/theory.md section 12).
  double accuracy = 1e-2;

  const MaterialSpec &material(const std::string &name) const;
  const BodySpec &body(const std::string &name) const;
};

/// The static problem of a static case: its one body's mesh and material, and the loads.
fem::StaticSettings static_settings(const Case &c);
/// The topology optimization of a static case. Throws a collective flexopt::Error naming the
/// case file if it has no design: or objective:.
optimize::TopologySettings topology_settings(const Case &c);

/// Reads and validates `<directory>/case.yaml`. Throws flexopt::Error (collective: call on
/// every rank) with `case.yaml:LINE:COL: message` for unknown keys, wrong types, missing
/// required keys, impossible values and dangling references (a body naming a missing
/// material, a support naming a missing body, a missing geometry file, ...).
Case load_case(const std::string &directory);

} // namespace flexopt::io
