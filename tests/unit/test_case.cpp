// Case loading: valid cases parse; each kind of bad input gives one message with
// case.yaml:LINE:COL naming the key.
#include "flexopt/core/error.hpp"
#include "flexopt/io/case.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <map>

namespace fs = std::filesystem;
using flexopt::Error;
using flexopt::io::load_case;
namespace optimize = flexopt::optimize;
namespace dynamics = flexopt::dynamics;

namespace {

class CaseFiles : public ::testing::Test {
protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("flexopt_case_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    std::ofstream(dir_ / "beam.geo") << "// geometry placeholder for parsing tests\n";
  }
  void TearDown() override { fs::remove_all(dir_); }

  void write(const std::string &yaml) { std::ofstream(dir_ / "case.yaml") << yaml; }

  /// Loads the case and returns the error message ("" if it loaded).
  std::string error() {
    try {
      load_case(dir_.string());
    } catch (const Error &e) {
      EXPECT_TRUE(e.collective());
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

const char *kValid = R"(analysis: static
materials:
  steel: {E: 2.1e11, nu: 0.3, density: 7850}
bodies:
  - name: beam
    geometry: beam.geo
    mesh: {size: 0.02, order: 2}
    material: steel
supports:
  - {body: beam, surface: clamp, fix: [x, y, z]}
tractions:
  - {body: beam, surface: tip, value: [0, -1.0e6, 0]}
loads:
  gravity: [0, -9.81, 0]
sensors:
  - {name: tip, body: beam, point: [1, 0, 0]}
solver: "-ksp_type preonly -pc_type lu"
)";

} // namespace

TEST_F(CaseFiles, ValidCaseParses) {
  write(kValid);
  auto c = load_case(dir_.string());
  EXPECT_STREQ(c.analysis_name(), "static");
  ASSERT_EQ(c.scene.bodies.size(), 1u);
  EXPECT_EQ(c.scene.bodies[0].mesh.order, 2);
  EXPECT_DOUBLE_EQ(c.scene.bodies[0].mesh.size, 0.02);
  EXPECT_DOUBLE_EQ(c.material("steel").E, 2.1e11);
  ASSERT_EQ(c.loads.supports.size(), 1u);
  EXPECT_TRUE(c.loads.supports[0].fix[0] && c.loads.supports[0].fix[1] &&
              c.loads.supports[0].fix[2]);
  EXPECT_DOUBLE_EQ(c.loads.tractions[0].value[1], -1.0e6);
  ASSERT_TRUE(c.loads.gravity.has_value());
  EXPECT_DOUBLE_EQ((*c.loads.gravity)[1], -9.81);
  EXPECT_STREQ(dynamics::quantity_name(c.scene.sensors[0].quantity), "displacement");
  EXPECT_EQ(c.solver, "-ksp_type preonly -pc_type lu");
}

TEST_F(CaseFiles, UnknownKeyNamesLineAndColumn) {
  std::string y = kValid;
  y.replace(y.find("    material: steel"), 19, "    material: steel\n    colour: red");
  write(y);
  const std::string msg = error();
  EXPECT_NE(msg.find("case.yaml:9:5:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown key 'bodies[0].colour'"), std::string::npos) << msg;
}

TEST_F(CaseFiles, IncompressibleMaterialRejected) {
  std::string y = kValid;
  y.replace(y.find("nu: 0.3"), 7, "nu: 0.5");
  write(y);
  const std::string msg = error();
  EXPECT_NE(msg.find("case.yaml:3:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("materials.steel.nu"), std::string::npos) << msg;
}

TEST_F(CaseFiles, NegativeModulusRejected) {
  std::string y = kValid;
  y.replace(y.find("E: 2.1e11"), 9, "E: -1");
  write(y);
  EXPECT_NE(error().find("Young's modulus must be positive"), std::string::npos);
}

TEST_F(CaseFiles, WrongTypeRejected) {
  std::string y = kValid;
  y.replace(y.find("size: 0.02"), 10, "size: fine");
  write(y);
  const std::string msg = error();
  EXPECT_NE(msg.find("bodies[0].mesh.size: expected a number, got 'fine'"), std::string::npos)
      << msg;
  EXPECT_NE(msg.find("case.yaml:7:"), std::string::npos) << msg;
}

TEST_F(CaseFiles, MissingGeometryFileRejected) {
  std::string y = kValid;
  y.replace(y.find("geometry: beam.geo"), 18, "geometry: nothere.geo");
  write(y);
  const std::string msg = error();
  EXPECT_NE(msg.find("nothere.geo' does not exist"), std::string::npos) << msg;
  EXPECT_NE(msg.find("case.yaml:6:15:"), std::string::npos) << msg;
}

TEST_F(CaseFiles, DanglingReferencesRejected) {
  std::string y = kValid;
  y.replace(y.find("{body: beam, surface: clamp"), 11, "{body: bean");
  write(y);
  EXPECT_NE(error().find("supports[0].body: no body named 'bean'"), std::string::npos);
  y = kValid;
  y.replace(y.find("material: steel"), 15, "material: alu");
  write(y);
  EXPECT_NE(error().find("no material named 'alu'"), std::string::npos);
}

TEST_F(CaseFiles, MissingRequiredKeyRejected) {
  std::string y = kValid;
  y.replace(y.find("analysis: static\n"), 17, "");
  write(y);
  EXPECT_NE(error().find("missing required key 'analysis'"), std::string::npos);
}

TEST_F(CaseFiles, YamlSyntaxErrorHasPosition) {
  write("analysis: static\nmaterials: {steel: [\n");
  const std::string msg = error();
  EXPECT_NE(msg.find("YAML syntax error"), std::string::npos) << msg;
  EXPECT_NE(msg.find("case.yaml:"), std::string::npos) << msg;
}

TEST_F(CaseFiles, BadFixComponentRejected) {
  std::string y = kValid;
  y.replace(y.find("fix: [x, y, z]"), 14, "fix: [x, w]");
  write(y);
  EXPECT_NE(error().find("'w' is not one of x, y, z"), std::string::npos);
}

namespace {

const char *kDesign = R"(design:
  body: beam
  region: design
  initial: 0.3
  interpolation: {penalty: 3, min_stiffness: 1.0e-9}
  filter: {radius: 0.02}
objective: {type: compliance}
constraints:
  - {type: volume_fraction, max: 0.3}
  - {type: displacement, sensor: tip, direction: [0, -2, 0], max: 0.001}
optimizer: {max_iterations: 50, move_limit: 0.2, tolerance: 0.001}
)";

} // namespace

TEST_F(CaseFiles, DesignSectionParses) {
  write(std::string(kValid) + kDesign);
  auto c = load_case(dir_.string());
  ASSERT_EQ(c.design.size(), 1u);
  EXPECT_EQ(c.design.front().region, "design");
  EXPECT_DOUBLE_EQ(c.design.front().filter_radius, 0.02);
  EXPECT_DOUBLE_EQ(c.design.front().penalty, 3.0);
  ASSERT_TRUE(c.objective.has_value());
  EXPECT_EQ(c.objective->type, optimize::ResponseType::Compliance);
  ASSERT_EQ(c.constraints.size(), 2u);
  EXPECT_DOUBLE_EQ(c.constraints[0].max, 0.3);
  EXPECT_DOUBLE_EQ(c.constraints[1].direction[1], -1.0); // normalized
  EXPECT_EQ(c.optimizer.max_iterations, 50);
}

TEST_F(CaseFiles, VolumeFractionOutsideUnitIntervalRejected) {
  std::string d = kDesign;
  d.replace(d.find("max: 0.3"), 8, "max: 1.2");
  write(std::string(kValid) + d);
  const std::string msg = error();
  EXPECT_NE(msg.find("constraints[0].max: a volume fraction bound must lie in (0, 1)"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("case.yaml:26:34:"), std::string::npos) << msg; // the value 1.2
}

TEST_F(CaseFiles, NonPositiveFilterRadiusRejected) {
  std::string d = kDesign;
  d.replace(d.find("radius: 0.02"), 12, "radius: 0");
  write(std::string(kValid) + d);
  EXPECT_NE(error().find("design.filter.radius: must be positive"), std::string::npos);
}

TEST_F(CaseFiles, DisplacementResponseNeedsAKnownSensor) {
  std::string d = kDesign;
  d.replace(d.find("sensor: tip"), 11, "sensor: toe");
  write(std::string(kValid) + d);
  EXPECT_NE(error().find("no sensor named 'toe'"), std::string::npos);
}

TEST_F(CaseFiles, ObjectiveWithoutDesignRejected) {
  write(std::string(kValid) + "objective: {type: compliance}\n");
  EXPECT_NE(error().find("need a design: section"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------
// Dynamic analysis: bodies[].initial, ground, joints, drivers, loads.forces, time.

namespace {

/// A slider-crank-like scene touching every dynamic key (line numbers matter: see the tests).
const char *kDynamic = R"yaml(analysis: dynamic
materials:
  steel: {E: 2.1e11, nu: 0.3, density: 7850}
bodies:
  - name: crank
    model: rigid
    geometry: beam.geo
    material: steel
    interfaces: [hub, pin]
  - name: rod
    geometry: beam.geo
    material: steel
    interfaces: [pin_a, pin_b]
    initial:
      position: [0.1, 0.2, 0.3]
      rotation: {axis: [0, 0, 2], angle: 0.5}
      velocity: [1, 2, 3]
      angular_velocity: [0, 0, -3]
  - name: slider
    model: auto
    geometry: beam.geo
    material: steel
    interfaces: [pin, guide]
ground: {interfaces: {origin: [0, 0, 0], rail: [0.4, 0, 0]}}
joints:
  - {name: j0, type: revolute, a: ground, a_interface: origin, b: crank, b_interface: hub, axis: [0, 0, 1]}
  - {name: j1, type: revolute, a: crank, a_interface: pin, b: rod, b_interface: pin_a, axis: [0, 0, 1]}
  - {name: j2, type: spherical, a: rod, a_interface: pin_b, b: slider, b_interface: pin}
  - {name: j3, type: prismatic, a: ground, a_interface: rail, b: slider, b_interface: guide, axis: [3, 4, 0]}
drivers:
  - {joint: j0, value: "t < 1 ? _pi*t^2 : 2*_pi*t - _pi"}
  - {joint: j3, value: 0.25}
loads:
  gravity: [0, -9.81, 0]
  forces:
    - {body: slider, interface: guide, value: [-100, "10*sin(2*_pi*t)", 1.5e-3]}
time: {end: 2.0, step: 1.0e-3, rho_inf: 0.7}
sensors:
  - {name: s, body: slider, point: [0, 0, 0], quantity: position}
  - {name: c, body: crank, point: [0.1, 0, 0], quantity: rotation_angle}
  - {name: d, body: rod, point: [0, 0, 0]}
output: {every: 10}
)yaml";

/// kDynamic with the first occurrence of `from` replaced by `to` (which must occur).
std::string dynamic_with(const std::string &from, const std::string &to) {
  std::string y = kDynamic;
  const auto at = y.find(from);
  EXPECT_NE(at, std::string::npos) << "test set-up: '" << from << "' not in kDynamic";
  if (at != std::string::npos) y.replace(at, from.size(), to);
  return y;
}

} // namespace

/// Writes `yaml`, expects load_case to fail, and checks that the message holds every part.
#define EXPECT_CASE_ERROR(yaml, ...)                                                               \
  do {                                                                                             \
    write(yaml);                                                                                   \
    const std::string msg_ = error();                                                              \
    EXPECT_FALSE(msg_.empty()) << "the case loaded";                                               \
    for (const std::string &part_ : std::initializer_list<std::string>{__VA_ARGS__})               \
      EXPECT_NE(msg_.find(part_), std::string::npos) << "'" << part_ << "' not in:\n" << msg_;     \
  } while (0)

TEST_F(CaseFiles, DynamicCaseParsesFieldByField) {
  write(kDynamic);
  const auto c = load_case(dir_.string());
  EXPECT_STREQ(c.analysis_name(), "dynamic");
  ASSERT_EQ(c.scene.bodies.size(), 3u);
  EXPECT_STREQ(dynamics::model_name(c.scene.bodies[0].model), "rigid");
  EXPECT_STREQ(dynamics::model_name(c.scene.bodies[1].model), "auto"); // default
  EXPECT_STREQ(dynamics::model_name(c.scene.bodies[2].model), "auto");
  EXPECT_EQ(c.scene.bodies[0].interfaces, (std::vector<std::string>{"hub", "pin"}));
  // crank: no initial: identity placement at rest
  const auto &i0 = c.scene.bodies[0].initial;
  EXPECT_EQ(i0.position, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(i0.axis, (std::array<double, 3>{0, 0, 1}));
  EXPECT_EQ(i0.angle, 0.0);
  EXPECT_EQ(i0.velocity, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(i0.angular_velocity, (std::array<double, 3>{0, 0, 0}));
  const auto &i1 = c.scene.bodies[1].initial;
  EXPECT_EQ(i1.position, (std::array<double, 3>{0.1, 0.2, 0.3}));
  EXPECT_EQ(i1.axis, (std::array<double, 3>{0, 0, 1})); // normalized from [0, 0, 2]
  EXPECT_DOUBLE_EQ(i1.angle, 0.5);
  EXPECT_EQ(i1.velocity, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(i1.angular_velocity, (std::array<double, 3>{0, 0, -3}));

  ASSERT_EQ(c.scene.ground.size(), 2u);
  EXPECT_EQ(c.scene.ground[0].name, "origin"); // order as written
  EXPECT_EQ(c.scene.ground[1].name, "rail");
  EXPECT_EQ(c.scene.ground[1].origin, (std::array<double, 3>{0.4, 0, 0}));
  EXPECT_EQ(c.scene.ground[1].where.line, 24);

  ASSERT_EQ(c.scene.joints.size(), 4u);
  const auto &j0 = c.scene.joints[0];
  EXPECT_EQ(j0.name, "j0");
  EXPECT_STREQ(dynamics::joint_type_name(j0.type), "revolute");
  EXPECT_EQ(j0.a, "ground");
  EXPECT_EQ(j0.a_interface, "origin");
  EXPECT_EQ(j0.b, "crank");
  EXPECT_EQ(j0.b_interface, "hub");
  EXPECT_EQ(j0.axis, (std::array<double, 3>{0, 0, 1}));
  EXPECT_EQ(j0.where.line, 26);
  EXPECT_EQ(j0.where.column, 5);
  EXPECT_EQ(c.scene.joints[1].a, "crank");
  EXPECT_EQ(c.scene.joints[1].b_interface, "pin_a");
  EXPECT_STREQ(dynamics::joint_type_name(c.scene.joints[2].type), "spherical");
  EXPECT_EQ(c.scene.joints[2].axis, (std::array<double, 3>{0, 0, 0})); // none
  EXPECT_STREQ(dynamics::joint_type_name(c.scene.joints[3].type), "prismatic");
  EXPECT_DOUBLE_EQ(c.scene.joints[3].axis[0], 0.6); // normalized from [3, 4, 0]
  EXPECT_DOUBLE_EQ(c.scene.joints[3].axis[1], 0.8);
  EXPECT_DOUBLE_EQ(c.scene.joints[3].axis[2], 0.0);

  ASSERT_EQ(c.scene.drivers.size(), 2u);
  EXPECT_EQ(c.scene.drivers[0].joint, "j0");
  EXPECT_EQ(c.scene.drivers[0].expression, "t < 1 ? _pi*t^2 : 2*_pi*t - _pi");
  EXPECT_EQ(c.scene.drivers[0].where.line, 31);
  EXPECT_EQ(c.scene.drivers[1].joint, "j3");
  EXPECT_EQ(c.scene.drivers[1].expression, "0.25");

  ASSERT_TRUE(c.scene.gravity.has_value());
  EXPECT_DOUBLE_EQ((*c.scene.gravity)[1], -9.81);
  ASSERT_EQ(c.scene.forces.size(), 1u);
  EXPECT_EQ(c.scene.forces[0].body, "slider");
  EXPECT_EQ(c.scene.forces[0].interface, "guide");
  EXPECT_EQ(c.scene.forces[0].value,
            (std::array<std::string, 3>{"-100", "10*sin(2*_pi*t)", "1.5e-3"}));
  EXPECT_EQ(c.scene.forces[0].where.line, 36);

  EXPECT_TRUE(c.time.given);
  EXPECT_DOUBLE_EQ(c.time.end, 2.0);
  EXPECT_DOUBLE_EQ(c.time.step, 1.0e-3);
  EXPECT_DOUBLE_EQ(c.time.rho_inf, 0.7);
  EXPECT_DOUBLE_EQ(c.time.newton_reuse, 0.1); // the default
  EXPECT_EQ(c.time.where.line, 37);

  ASSERT_EQ(c.scene.sensors.size(), 3u);
  EXPECT_STREQ(dynamics::quantity_name(c.scene.sensors[0].quantity), "position");
  EXPECT_STREQ(dynamics::quantity_name(c.scene.sensors[1].quantity), "rotation_angle");
  EXPECT_STREQ(dynamics::quantity_name(c.scene.sensors[2].quantity), "displacement");
  EXPECT_EQ(c.output.every, 10);
  EXPECT_EQ(c.output.interval, 0.0);
  EXPECT_TRUE(c.loads.supports.empty());
  EXPECT_TRUE(c.design.empty());
}

TEST_F(CaseFiles, OutputIntervalParsesAndOutputIsOptional) {
  write(dynamic_with("output: {every: 10}", "output: {interval: 2.5e-3}"));
  auto c = load_case(dir_.string());
  EXPECT_EQ(c.output.every, 0);
  EXPECT_DOUBLE_EQ(c.output.interval, 2.5e-3);
  EXPECT_TRUE(c.output.given());
  write(dynamic_with("output: {every: 10}\n", ""));
  c = load_case(dir_.string());
  EXPECT_FALSE(c.output.given()); // the defaults of io::FrameSchedule
}

TEST_F(CaseFiles, OutputBadValuesRejected) {
  // Line 42 of kDynamic holds output:; "output: {" is 9 characters.
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {every: 0}"),
                    "case.yaml:42:17:", "output.every: must be >= 1");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {every: 2.5}"),
                    "output.every: expected an integer");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {interval: -1}"),
                    "case.yaml:42:20:", "output.interval: must be positive");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {interval: 0}"),
                    "output.interval: must be positive");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {every: 10, interval: 0.1}"),
                    "case.yaml:42:21:", "give either every (steps) or interval (seconds)");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {frames: 10}"),
                    "unknown key 'output.frames' (allowed here: every, interval)");
  // A static case's output is per design iteration: no interval of simulated time.
  EXPECT_CASE_ERROR(std::string(kValid) + "output: {interval: 0.1}\n",
                    "output.interval: needs analysis: dynamic");
}

TEST_F(CaseFiles, TimeRhoInfDefaultsTo08) {
  write(dynamic_with("time: {end: 2.0, step: 1.0e-3, rho_inf: 0.7}", "time: {end: 1, step: 1}"));
  const auto c = load_case(dir_.string());
  EXPECT_DOUBLE_EQ(c.time.rho_inf, 0.8);
  EXPECT_DOUBLE_EQ(c.time.step, 1.0); // step == end is allowed
}

TEST_F(CaseFiles, MinimalDynamicCaseParses) {
  // One body, no joints: a free body (e.g. falling or spinning).
  write(R"(analysis: dynamic
materials: {steel: {E: 2.1e11, nu: 0.3, density: 7850}}
bodies:
  - {name: block, geometry: beam.geo, material: steel}
time: {end: 0.5, step: 0.01}
)");
  const auto c = load_case(dir_.string());
  EXPECT_TRUE(c.scene.joints.empty() && c.scene.drivers.empty() && c.scene.forces.empty() &&
              c.scene.ground.empty());
  EXPECT_TRUE(c.time.given);
  EXPECT_FALSE(c.scene.gravity.has_value());
}

// bodies[].initial, model, name

TEST_F(CaseFiles, InitialRotationAxisMustNotBeZero) {
  EXPECT_CASE_ERROR(dynamic_with("axis: [0, 0, 2]", "axis: [0, 0, 0]"),
                    "case.yaml:16:24:", "bodies[1].initial.rotation.axis: must not be zero");
}

TEST_F(CaseFiles, InitialRotationNeedsAxisAndAngle) {
  EXPECT_CASE_ERROR(dynamic_with("{axis: [0, 0, 2], angle: 0.5}", "{angle: 0.5}"),
                    "case.yaml:16:", "missing required key 'bodies[1].initial.rotation.axis'");
}

TEST_F(CaseFiles, InitialValuesMustBeFinite) {
  EXPECT_CASE_ERROR(dynamic_with("velocity: [1, 2, 3]", "velocity: [1, .nan, 3]"),
                    "case.yaml:17:", "bodies[1].initial.velocity[1]: expected a finite number");
  EXPECT_CASE_ERROR(dynamic_with("angle: 0.5", "angle: .inf"),
                    "case.yaml:16:", "bodies[1].initial.rotation.angle: expected a finite number");
  EXPECT_CASE_ERROR(dynamic_with("position: [0.1, 0.2, 0.3]", "position: [0.1, 0.2]"),
                    "case.yaml:15:", "bodies[1].initial.position: expected a list of 3 numbers");
}

TEST_F(CaseFiles, InitialUnknownKeyRejected) {
  EXPECT_CASE_ERROR(
      dynamic_with("      velocity:", "      acceleration: [0, 0, 0]\n      velocity:"),
      "case.yaml:17:7:", "unknown key 'bodies[1].initial.acceleration'");
}

TEST_F(CaseFiles, InitialNeedsDynamicAnalysis) {
  std::string y = kValid;
  y.replace(y.find("    material: steel"), 19,
            "    material: steel\n    initial: {position: [0, 0, 0]}");
  EXPECT_CASE_ERROR(y, "case.yaml:9:5:", "bodies[0].initial: needs analysis: dynamic");
}

TEST_F(CaseFiles, FfrfReductionAndDamping) {
  const std::string ffrf = "    interfaces: [pin_a, pin_b]\n    model: ffrf\n";
  write(dynamic_with("    interfaces: [pin_a, pin_b]\n",
                     ffrf + "    reduction: {modes: 8, geometric_stiffening: true}\n"
                            "    damping: {rayleigh: [0.5, 1.0e-4]}\n"));
  const flexopt::io::Case c = load_case(dir_.string());
  EXPECT_STREQ(dynamics::model_name(c.scene.bodies[1].model), "ffrf");
  EXPECT_EQ(c.scene.bodies[1].reduction.modes, 8);
  EXPECT_TRUE(c.scene.bodies[1].reduction.geometric_stiffening);
  EXPECT_DOUBLE_EQ(c.scene.bodies[1].rayleigh[0], 0.5);
  EXPECT_DOUBLE_EQ(c.scene.bodies[1].rayleigh[1], 1.0e-4);
  // Defaults: 4 fixed-interface modes, no stiffening, no damping.
  write(dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf));
  const flexopt::io::Case d = load_case(dir_.string());
  EXPECT_EQ(d.scene.bodies[1].reduction.modes, 4);
  EXPECT_FALSE(d.scene.bodies[1].reduction.geometric_stiffening);
  EXPECT_EQ(d.scene.bodies[1].rayleigh[1], 0.0);
}

TEST_F(CaseFiles, ReductionAndDampingErrors) {
  const std::string ffrf = "    interfaces: [pin_a, pin_b]\n    model: ffrf\n";
  EXPECT_CASE_ERROR(
      dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    reduction: {modes: -1}\n"),
      "case.yaml:15:", "bodies[1].reduction.modes: the number of fixed-interface");
  EXPECT_CASE_ERROR(
      dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    reduction: {nodes: 3}\n"),
      "case.yaml:15:", "unknown key 'bodies[1].reduction.nodes'");
  EXPECT_CASE_ERROR(
      dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    damping: {rayleigh: [0.1]}\n"),
      "case.yaml:15:", "bodies[1].damping.rayleigh: expected [a, b]");
  EXPECT_CASE_ERROR(dynamic_with("    interfaces: [pin_a, pin_b]\n",
                                 ffrf + "    damping: {rayleigh: [0.1, -2]}\n"),
                    "case.yaml:15:", "bodies[1].damping.rayleigh[1]: must not be negative");
  EXPECT_CASE_ERROR(
      dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    reduction: {frame: pinned}\n"),
      "case.yaml:15:", "bodies[1].reduction.frame: 'pinned' is not one of clamped | chord");
  EXPECT_CASE_ERROR(
      dynamic_with("    interfaces: [pin_a, pin_b]\n",
                   ffrf + "    reduction: {geometric_stiffening: true, frame: chord}\n"),
      "case.yaml:15:", "bodies[1].reduction.frame: chord does not combine with");
  EXPECT_CASE_ERROR(dynamic_with("    interfaces: [pin_a, pin_b]\n",
                                 "    interfaces: [pin_a]\n    model: ffrf\n"
                                 "    reduction: {frame: chord}\n"),
                    "case.yaml:15:", "bodies[1].reduction.frame: chord needs two interfaces");
}

TEST_F(CaseFiles, ReductionFrame) {
  const std::string ffrf = "    interfaces: [pin_a, pin_b]\n    model: ffrf\n";
  write(dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    reduction: {frame: chord}\n"));
  EXPECT_STREQ(dynamics::frame_name(load_case(dir_.string()).scene.bodies[1].reduction.frame),
               "chord");
  // The default: the chord for a link with two interfaces, clamped with geometric stiffening
  // (or one interface: the FFRF test scenes with one interface run in the clamped frame);
  // clamped when written.
  write(dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf));
  EXPECT_STREQ(dynamics::frame_name(load_case(dir_.string()).scene.bodies[1].reduction.frame),
               "chord");
  write(dynamic_with("    interfaces: [pin_a, pin_b]\n",
                     ffrf + "    reduction: {geometric_stiffening: true}\n"));
  EXPECT_STREQ(dynamics::frame_name(load_case(dir_.string()).scene.bodies[1].reduction.frame),
               "clamped");
  write(
      dynamic_with("    interfaces: [pin_a, pin_b]\n", ffrf + "    reduction: {frame: clamped}\n"));
  EXPECT_STREQ(dynamics::frame_name(load_case(dir_.string()).scene.bodies[1].reduction.frame),
               "clamped");
}

TEST_F(CaseFiles, FfrfInitialElasticFields) {
  const std::string ffrf = "    interfaces: [pin_a, pin_b]\n    model: ffrf\n";
  const std::string fields = "      elastic_displacement: [\"1e-3*x^2\", 0, 0]\n"
                             "      elastic_velocity: [0, \"0.4*sin(_pi*x/0.3)\", 0]\n";
  std::string y =
      dynamic_with("      velocity: [1, 2, 3]\n", "      velocity: [1, 2, 3]\n" + fields);
  y.replace(y.find("    interfaces: [pin_a, pin_b]\n"), 31, ffrf);
  write(y);
  const flexopt::io::Case c = load_case(dir_.string());
  EXPECT_EQ(c.scene.bodies[1].initial.elastic_displacement[0], "1e-3*x^2");
  EXPECT_EQ(c.scene.bodies[1].initial.elastic_velocity[1], "0.4*sin(_pi*x/0.3)");
  EXPECT_EQ(c.scene.bodies[1].initial.elastic_velocity[2], "0");
  EXPECT_TRUE(c.scene.bodies[0].initial.elastic_displacement[0].empty()); // none given: zero
}

TEST_F(CaseFiles, InitialElasticFieldErrors) {
  auto ffrf_with = [&](const std::string &to) {
    std::string y = dynamic_with("      velocity: [1, 2, 3]\n", to);
    y.replace(y.find("    interfaces: [pin_a, pin_b]\n"), 31,
              "    interfaces: [pin_a, pin_b]\n    model: ffrf\n");
    return y;
  };
  EXPECT_CASE_ERROR(ffrf_with("      velocity: [1, 2, 3]\n      elastic_velocity: [0, 1]\n"),
                    "case.yaml:19:", "bodies[1].initial.elastic_velocity: expected [fx, fy, fz]");
  EXPECT_CASE_ERROR(
      ffrf_with("      velocity: [1, 2, 3]\n      elastic_displacement: [0, \"t*x\", 0]\n"),
      "case.yaml:19:",
      "bodies[1].initial.elastic_displacement[1]: cannot parse \"t*x\": unknown name \"t\"");
}

TEST_F(CaseFiles, AcfBodiesTakeStiffnessDampingOnly) {
  EXPECT_CASE_ERROR(
      dynamic_with("model: rigid", "model: acf\n    damping: {rayleigh: [0.5, 1.0e-4]}"),
      "case.yaml:7:", "bodies[0].damping.rayleigh[0]: an acf body takes stiffness-proportional");
  write(dynamic_with("model: rigid", "model: acf\n    damping: {rayleigh: [0, 1.0e-4]}"));
  EXPECT_DOUBLE_EQ(load_case(dir_.string()).scene.bodies[0].rayleigh[1], 1.0e-4);
}

// A body carries the settings of every model; `model:` picks the ones used.

TEST(ModelSettings, WhichModelUsesWhat) {
  using flexopt::io::settings_used_by;
  using V = std::vector<std::string>;
  EXPECT_EQ(settings_used_by(dynamics::BodyModel::Rigid), V{});
  EXPECT_EQ(settings_used_by(dynamics::BodyModel::Ffrf),
            (V{"reduction.modes", "reduction.geometric_stiffening", "reduction.frame", "damping",
               "initial.elastic_displacement", "initial.elastic_velocity"}));
  // The frame of an ACF body's elastic displacement (docs/theory.md 8.4).
  EXPECT_EQ(settings_used_by(dynamics::BodyModel::Acf),
            (V{"reduction.frame", "damping", "initial.elastic_displacement",
               "initial.elastic_velocity"}));
  EXPECT_EQ(dynamics::simulated_model(dynamics::BodyModel::Auto),
            dynamics::BodyModel::Rigid); // this version
  EXPECT_EQ(settings_used_by(dynamics::BodyModel::Auto),
            settings_used_by(dynamics::BodyModel::Rigid));
}

namespace {

/// kDynamic with the rod (bodies[1], line 10) carrying the settings of every model and `model`
/// set to `model`: reduction on line 15, damping on 16, elastic_velocity on 21.
std::string rod_with_every_setting(const std::string &model, const std::string &reduction,
                                   const std::string &damping) {
  std::string y =
      dynamic_with("    interfaces: [pin_a, pin_b]\n",
                   "    interfaces: [pin_a, pin_b]\n    model: " + model +
                       "\n    reduction: " + reduction + "\n    damping: " + damping + "\n");
  y.replace(y.find("      velocity: [1, 2, 3]\n"), 26,
            "      velocity: [1, 2, 3]\n      elastic_velocity: [0, \"0.4*sin(_pi*x/0.3)\", 0]\n");
  return y;
}

} // namespace

TEST_F(CaseFiles, OneWordSwitchesTheModel) {
  using V = std::vector<std::string>;
  const std::map<std::string, V> unused = {
      {"rigid", {"reduction.modes", "reduction.frame", "damping", "initial.elastic_velocity"}},
      {"auto", {"reduction.modes", "reduction.frame", "damping", "initial.elastic_velocity"}},
      {"ffrf", {}},
      {"acf", {"reduction.modes"}}}; // an ACF body uses the frame (docs/theory.md 8.4)
  for (const auto &[model, expected] : unused) {
    SCOPED_TRACE("model: " + model);
    write(rod_with_every_setting(model, "{modes: 8, frame: chord}", "{rayleigh: [0, 2.0e-4]}"));
    const flexopt::io::Case c = load_case(dir_.string());
    const auto &rod = c.scene.bodies[1];
    EXPECT_EQ(dynamics::model_name(rod.model), model);
    // Every setting is parsed whatever the model, so that switching back uses it.
    EXPECT_EQ(rod.reduction.modes, 8);
    EXPECT_STREQ(dynamics::frame_name(rod.reduction.frame), "chord");
    EXPECT_DOUBLE_EQ(rod.rayleigh[1], 2.0e-4);
    EXPECT_EQ(rod.initial.elastic_velocity[1], "0.4*sin(_pi*x/0.3)");
    EXPECT_EQ(rod.settings,
              (V{"reduction.modes", "reduction.frame", "damping", "initial.elastic_velocity"}));
    EXPECT_EQ(flexopt::io::unused_settings(rod), expected);
    // The other bodies carry no model settings.
    EXPECT_TRUE(flexopt::io::unused_settings(c.scene.bodies[0]).empty());
    EXPECT_EQ(flexopt::io::unused_settings_note(c.scene.bodies[0]), "");
  }
  write(rod_with_every_setting("acf", "{modes: 8}", "{rayleigh: [0, 2.0e-4]}"));
  EXPECT_EQ(flexopt::io::unused_settings_note(load_case(dir_.string()).scene.bodies[1]),
            "body rod (model: acf): settings not used by this model: reduction.modes (ffrf)");
  write(rod_with_every_setting("rigid", "{modes: 8}", "{rayleigh: [0, 2.0e-4]}"));
  EXPECT_EQ(
      flexopt::io::unused_settings_note(load_case(dir_.string()).scene.bodies[1]),
      "body rod (model: rigid): settings not used by this model: reduction.modes (ffrf), damping "
      "(ffrf, acf), initial.elastic_velocity (ffrf, acf)");
  write(rod_with_every_setting("auto", "{modes: 8}", "{rayleigh: [0, 2.0e-4]}"));
  EXPECT_EQ(flexopt::io::unused_settings_note(load_case(dir_.string()).scene.bodies[1]),
            "body rod (model: auto, simulated as rigid): settings not used by this model: "
            "reduction.modes (ffrf), damping (ffrf, acf), initial.elastic_velocity (ffrf, acf)");
}

TEST_F(CaseFiles, UnusedSettingsAreStillChecked) {
  const std::string ok_damping = "{rayleigh: [0, 2.0e-4]}";
  for (const std::string model : {"rigid", "acf"}) {
    SCOPED_TRACE("model: " + model);
    // A typo in a section the model does not use is refused, the key named.
    EXPECT_CASE_ERROR(rod_with_every_setting(model, "{nodes: 8}", ok_damping),
                      "case.yaml:15:", "unknown key 'bodies[1].reduction.nodes'");
    EXPECT_CASE_ERROR(rod_with_every_setting(model, "{modes: -1}", ok_damping),
                      "case.yaml:15:", "bodies[1].reduction.modes: the number of fixed-interface");
    EXPECT_CASE_ERROR(rod_with_every_setting(model, "{frame: pinned}", ok_damping),
                      "case.yaml:15:", "bodies[1].reduction.frame: 'pinned' is not one of");
    EXPECT_CASE_ERROR(
        rod_with_every_setting(model, "{geometric_stiffening: true, frame: chord}", ok_damping),
        "case.yaml:15:", "bodies[1].reduction.frame: chord does not combine with");
    EXPECT_CASE_ERROR(rod_with_every_setting(model, "{modes: 4}", "{rayleigh: [0, -1]}"),
                      "case.yaml:16:", "bodies[1].damping.rayleigh[1]: must not be negative");
    EXPECT_CASE_ERROR(rod_with_every_setting(model, "{modes: 4}", "{raleigh: [0, 1]}"),
                      "case.yaml:16:", "unknown key 'bodies[1].damping.raleigh'");
    std::string y = rod_with_every_setting(model, "{modes: 4}", ok_damping);
    y.replace(y.find("\"0.4*sin(_pi*x/0.3)\""), 20, "\"t*x\"");
    EXPECT_CASE_ERROR(
        y, "case.yaml:21:", "bodies[1].initial.elastic_velocity[1]: cannot parse \"t*x\"");
  }
  // chord needs two interfaces whatever the model (the body has one).
  std::string y = rod_with_every_setting("acf", "{frame: chord}", ok_damping);
  y.replace(y.find("    interfaces: [pin_a, pin_b]\n"), 31, "    interfaces: [pin_a]\n");
  EXPECT_CASE_ERROR(y, "bodies[1].reduction.frame: chord needs two interfaces");
}

TEST_F(CaseFiles, MassProportionalDampingIsAnErrorOnlyWhereAcfWouldUseIt) {
  const std::string damping = "{rayleigh: [0.5, 2.0e-4]}";
  EXPECT_CASE_ERROR(rod_with_every_setting("acf", "{modes: 4}", damping), "case.yaml:16:",
                    "bodies[1].damping.rayleigh[0]: an acf body takes stiffness-proportional");
  write(rod_with_every_setting("ffrf", "{modes: 4}", damping));
  EXPECT_DOUBLE_EQ(load_case(dir_.string()).scene.bodies[1].rayleigh[0], 0.5); // used by ffrf
  write(rod_with_every_setting("rigid", "{modes: 4}", damping));
  const auto rigid = load_case(dir_.string()).scene.bodies[1];
  EXPECT_DOUBLE_EQ(rigid.rayleigh[0], 0.5); // carried, unused
  EXPECT_EQ(flexopt::io::unused_settings(rigid).at(1), "damping");
}

TEST_F(CaseFiles, StaticAnalysisIgnoresModel) {
  std::string y = kValid;
  y.replace(y.find("    geometry: beam.geo"), 22, "    model: ffrf\n    geometry: beam.geo");
  write(y);
  EXPECT_STREQ(dynamics::model_name(load_case(dir_.string()).scene.bodies[0].model), "ffrf");
}

TEST_F(CaseFiles, BodyNamedGroundRejected) {
  EXPECT_CASE_ERROR(dynamic_with("name: slider", "name: ground"),
                    "case.yaml:19:11:", "bodies[2].name: 'ground' is reserved for the fixed frame");
}

TEST_F(CaseFiles, DuplicateBodyInterfaceRejected) {
  EXPECT_CASE_ERROR(dynamic_with("[pin, guide]", "[pin, pin]"),
                    "case.yaml:23:23:", "bodies[2].interfaces: 'pin' is listed twice");
}

// ground

TEST_F(CaseFiles, GroundInterfaceNamesUnique) {
  EXPECT_CASE_ERROR(dynamic_with("rail: [0.4, 0, 0]", "origin: [0.4, 0, 0]"),
                    "case.yaml:24:", "ground.interfaces.origin: duplicate ground interface name");
}

TEST_F(CaseFiles, GroundInterfaceNeedsAPoint) {
  EXPECT_CASE_ERROR(dynamic_with("rail: [0.4, 0, 0]", "rail: [0.4, 0]"),
                    "case.yaml:24:", "ground.interfaces.rail: expected a list of 3 numbers");
  EXPECT_CASE_ERROR(dynamic_with("ground: {interfaces: {origin: [0, 0, 0], rail: [0.4, 0, 0]}}",
                                 "ground: {points: {}}"),
                    "case.yaml:24:", "unknown key 'ground.points'");
}

// joints

TEST_F(CaseFiles, JointInterfaceMustBeListedByTheBody) {
  EXPECT_CASE_ERROR(dynamic_with("b: rod, b_interface: pin_a", "b: rod, b_interface: pin_c"),
                    "case.yaml:27:",
                    "joints[1].b_interface: joint 'j1': body 'rod' has no "
                    "interface 'pin_c' (its interfaces: pin_a, pin_b)");
}

TEST_F(CaseFiles, JointInterfaceOfABodyWithoutInterfaces) {
  EXPECT_CASE_ERROR(dynamic_with("    interfaces: [hub, pin]\n", ""), "case.yaml:25:",
                    "joints[0].b_interface: joint 'j0': body 'crank' has no interface 'hub' (it "
                    "lists none; add interfaces: [hub]");
}

TEST_F(CaseFiles, JointGroundInterfaceMustExist) {
  EXPECT_CASE_ERROR(dynamic_with("a: ground, a_interface: origin", "a: ground, a_interface: orig"),
                    "case.yaml:26:",
                    "joints[0].a_interface: joint 'j0': ground has no interface "
                    "'orig' (ground interfaces: origin, rail)");
  EXPECT_CASE_ERROR(
      dynamic_with("ground: {interfaces: {origin: [0, 0, 0], rail: [0.4, 0, 0]}}\n", ""),
      "joints[0].a_interface: joint 'j0': ground has no interface 'origin' (there "
      "is no ground: section");
}

TEST_F(CaseFiles, JointBodyMustExist) {
  EXPECT_CASE_ERROR(dynamic_with("b: rod,", "b: rood,"), "case.yaml:27:",
                    "joints[1].b: joint 'j1': no body named 'rood' (bodies: crank, rod, slider; "
                    "or ground)");
}

TEST_F(CaseFiles, JointNotBetweenTheSameBodyOrGroundTwice) {
  EXPECT_CASE_ERROR(dynamic_with("b: crank, b_interface: hub", "b: ground, b_interface: rail"),
                    "case.yaml:26:", "joints[0].b: joint 'j0': a and b are both ground");
  EXPECT_CASE_ERROR(dynamic_with("b: rod, b_interface: pin_a", "b: crank, b_interface: hub"),
                    "case.yaml:27:", "joints[1].b: joint 'j1': a and b are the same body 'crank'");
}

TEST_F(CaseFiles, JointNamesUniqueAndTypesKnown) {
  EXPECT_CASE_ERROR(dynamic_with("name: j1", "name: j0"),
                    "case.yaml:27:", "joints[1].name: duplicate joint name 'j0'");
  EXPECT_CASE_ERROR(dynamic_with("type: spherical", "type: universal"), "case.yaml:28:",
                    "joints[2].type: 'universal' is not one of revolute | spherical | prismatic | "
                    "fixed");
  EXPECT_CASE_ERROR(dynamic_with("{name: j2, ", "{"),
                    "case.yaml:28:", "missing required key 'joints[2].name'");
}

TEST_F(CaseFiles, JointAxisRules) {
  EXPECT_CASE_ERROR(dynamic_with(", axis: [0, 0, 1]}", "}"), "case.yaml:26:5:",
                    "joints[0]: joint 'j0': a revolute joint needs axis: [x, y, z]");
  EXPECT_CASE_ERROR(dynamic_with("axis: [3, 4, 0]", "axis: [0, 0, 0]"),
                    "case.yaml:29:", "joints[3].axis: must not be zero");
  EXPECT_CASE_ERROR(dynamic_with("b_interface: pin}", "b_interface: pin, axis: [1, 0, 0]}"),
                    "case.yaml:28:", "joints[2].axis: a spherical joint has no axis");
  EXPECT_CASE_ERROR(dynamic_with("type: spherical, a: rod, a_interface: pin_b, b: slider, "
                                 "b_interface: pin}",
                                 "type: fixed, a: rod, a_interface: pin_b, b: slider, "
                                 "b_interface: pin, axis: [1, 0, 0]}"),
                    "case.yaml:28:", "joints[2].axis: a fixed joint has no axis");
}

// drivers

TEST_F(CaseFiles, DriverBadExpressionShowsExpressionAndPosition) {
  EXPECT_CASE_ERROR(dynamic_with("\"t < 1 ? _pi*t^2 : 2*_pi*t - _pi\"", "\"t <* 2\""),
                    "case.yaml:31:24: drivers[0].value: cannot parse \"t <* 2\": ", "at position 3",
                    "\n    t <* 2\n       ^");
}

TEST_F(CaseFiles, DriverUnknownVariableNamed) {
  EXPECT_CASE_ERROR(dynamic_with("\"t < 1 ? _pi*t^2 : 2*_pi*t - _pi\"", "\"omega*t\""),
                    "case.yaml:31:24: drivers[0].value: cannot parse \"omega*t\": unknown name "
                    "\"omega\" at position 0");
}

TEST_F(CaseFiles, DriverValueMustBeFiniteAtZeroAndAScalar) {
  EXPECT_CASE_ERROR(dynamic_with("\"t < 1 ? _pi*t^2 : 2*_pi*t - _pi\"", "\"1/t\""),
                    "case.yaml:31:24: drivers[0].value: \"1/t\" evaluates to inf at t = 0");
  EXPECT_CASE_ERROR(dynamic_with("value: 0.25", "value: [0.25]"),
                    "case.yaml:32:", "drivers[1].value: expected a number or an expression in t");
  EXPECT_CASE_ERROR(dynamic_with("value: 0.25", "value: \"\""),
                    "case.yaml:32:", "drivers[1].value: empty expression");
}

TEST_F(CaseFiles, DriverJointRules) {
  EXPECT_CASE_ERROR(dynamic_with("joint: j0", "joint: j9"), "case.yaml:31:13:",
                    "drivers[0].joint: no joint named 'j9' (joints: j0, j1, j2, j3)");
  EXPECT_CASE_ERROR(dynamic_with("joint: j3", "joint: j2"), "case.yaml:32:",
                    "drivers[1].joint: joint 'j2' is spherical; a driver prescribes the "
                    "coordinate of a revolute or prismatic joint");
  EXPECT_CASE_ERROR(dynamic_with("joint: j3", "joint: j0"), "case.yaml:32:",
                    "drivers[1].joint: joint 'j0' already has a driver (drivers[0])");
}

// loads.forces

TEST_F(CaseFiles, ForceComponentsAreNumbersOrExpressions) {
  EXPECT_CASE_ERROR(dynamic_with("\"10*sin(2*_pi*t)\"", "\"10*sin(2*pi*t)\""), "case.yaml:36:",
                    "loads.forces[0].value[1]: cannot parse \"10*sin(2*pi*t)\": unknown name "
                    "\"pi\" at position 9");
  EXPECT_CASE_ERROR(dynamic_with("value: [-100, \"10*sin(2*_pi*t)\", 1.5e-3]", "value: [-100, 0]"),
                    "case.yaml:36:", "loads.forces[0].value: expected a list of 3 components");
}

TEST_F(CaseFiles, ForceBodyAndInterfaceMustExist) {
  EXPECT_CASE_ERROR(
      dynamic_with("{body: slider, interface: guide", "{body: slider, interface: hub"),
      "case.yaml:36:",
      "loads.forces[0].interface: body 'slider' has no interface 'hub' (its "
      "interfaces: pin, guide)");
  EXPECT_CASE_ERROR(dynamic_with("{body: slider, interface", "{body: piston, interface"),
                    "case.yaml:36:", "loads.forces[0].body: no body named 'piston'");
  EXPECT_CASE_ERROR(
      dynamic_with("{body: slider, interface: guide", "{body: ground, interface: rail"),
      "case.yaml:36:", "loads.forces[0].body: the ground is fixed");
}

// time

TEST_F(CaseFiles, TimeRules) {
  EXPECT_CASE_ERROR(dynamic_with("step: 1.0e-3", "step: 0"),
                    "case.yaml:37:", "time.step: must be positive");
  EXPECT_CASE_ERROR(dynamic_with("step: 1.0e-3", "step: -1.0e-3"), "time.step: must be positive");
  EXPECT_CASE_ERROR(dynamic_with("step: 1.0e-3", "step: 3"),
                    "case.yaml:37:", "time.step: must not exceed time.end (2.0)");
  EXPECT_CASE_ERROR(dynamic_with("end: 2.0", "end: 0"),
                    "case.yaml:37:13:", "time.end: must be positive");
  EXPECT_CASE_ERROR(dynamic_with("rho_inf: 0.7", "rho_inf: 1.1"),
                    "case.yaml:37:", "time.rho_inf: must lie in [0, 1]");
  EXPECT_CASE_ERROR(dynamic_with("rho_inf: 0.7", "rho_inf: -0.1"),
                    "time.rho_inf: must lie in [0, 1]");
  EXPECT_CASE_ERROR(dynamic_with("rho_inf: 0.7", "rho_inf: 0.7, newton_reuse: 1"),
                    "case.yaml:37:", "time.newton_reuse: must lie in [0, 1)");
  EXPECT_CASE_ERROR(dynamic_with("rho_inf: 0.7", "rho_inf: 0.7, newton_reuse: -0.5"),
                    "time.newton_reuse: must lie in [0, 1)");
  EXPECT_CASE_ERROR(dynamic_with("{end: 2.0, step: 1.0e-3, rho_inf: 0.7}", "{end: 2.0}"),
                    "case.yaml:37:", "missing required key 'time.step'");
  EXPECT_CASE_ERROR(dynamic_with("rho_inf: 0.7", "rho: 0.7"),
                    "case.yaml:37:", "unknown key 'time.rho'");
}

TEST_F(CaseFiles, DynamicAnalysisNeedsTime) {
  EXPECT_CASE_ERROR(dynamic_with("time: {end: 2.0, step: 1.0e-3, rho_inf: 0.7}\n", ""),
                    "case.yaml:1:11:", "analysis: a dynamic analysis needs time:");
}

// sensors

TEST_F(CaseFiles, SensorQuantitiesPerAnalysis) {
  write(dynamic_with("quantity: rotation_angle", "quantity: elastic_displacement"));
  EXPECT_STREQ(dynamics::quantity_name(load_case(dir_.string()).scene.sensors[1].quantity),
               "elastic_displacement");
  std::string y = kValid;
  y.replace(y.find("point: [1, 0, 0]"), 16, "point: [1, 0, 0], quantity: rotation_angle");
  EXPECT_CASE_ERROR(y, "case.yaml:16:57:",
                    "sensors[0].quantity: 'rotation_angle' needs a dynamic "
                    "analysis; a static one has displacement and position");
  y = kValid;
  y.replace(y.find("point: [1, 0, 0]"), 16, "point: [1, 0, 0], quantity: position");
  write(y);
  EXPECT_STREQ(dynamics::quantity_name(load_case(dir_.string()).scene.sensors[0].quantity),
               "position");
}

// analysis cross-checks

TEST_F(CaseFiles, StaticAnalysisRejectsDynamicKeys) {
  const std::string extra[] = {"ground: {interfaces: {o: [0, 0, 0]}}\n", "joints: []\n",
                               "drivers: []\n", "time: {end: 1, step: 0.1}\n"};
  for (const auto &e : extra) {
    const std::string key = e.substr(0, e.find(':'));
    EXPECT_CASE_ERROR(std::string(kValid) + e,
                      "case.yaml:18:1: " + key + ": needs analysis: dynamic");
  }
  std::string y = kValid;
  y.replace(y.find("  gravity:"), 10, "  forces: []\n  gravity:");
  EXPECT_CASE_ERROR(y, "case.yaml:14:3: loads.forces: needs analysis: dynamic");
}

TEST_F(CaseFiles, DynamicAnalysisRejectsStaticOnlyKeys) {
  const std::string extra[] = {"supports: [{body: crank, surface: hub, fix: [x]}]\n",
                               "tractions: [{body: crank, surface: hub, value: [0, 0, 1]}]\n",
                               "line_loads: [{body: crank, curve: e, value: [0, 0, 1]}]\n"};
  for (const auto &e : extra) {
    const std::string key = e.substr(0, e.find(':'));
    EXPECT_CASE_ERROR(std::string(kDynamic) + e,
                      "case.yaml:43:1: " + key + ": not supported yet in a dynamic analysis");
  }
}

// A dynamic optimization (docs/case-format.md, "Dynamic responses and the adjoint"): every
// response type and the adjoint section parse field by field.
TEST_F(CaseFiles, DynamicResponsesAndAdjointParse) {
  write(std::string(kDynamic) + R"yaml(design: {body: rod, region: beam, filter: {radius: 0.1}}
objective: {type: tracking_error, sensor: s, target: ["cos(t)", 0, "2*t"]}
constraints:
  - {type: sensor, sensor: s, component: y, measure: ks_max, ks: 30, max: 1}
  - {type: sensor, sensor: d, component: 2, measure: final, max: -0.5}
  - {type: strain_energy_integral, body: rod, max: 3}
  - {type: mass, body: crank, max: 10}
  - {type: volume_fraction, max: 0.4}
adjoint: {checkpoints: 32, storage: disk}
)yaml");
  const auto c = load_case(dir_.string());
  ASSERT_TRUE(c.objective);
  EXPECT_EQ(c.objective->type, optimize::ResponseType::TrackingError);
  EXPECT_EQ(c.objective->target[0], "cos(t)");
  EXPECT_EQ(c.objective->target[2], "2*t");
  ASSERT_EQ(c.constraints.size(), 5u);
  EXPECT_EQ(c.constraints[0].component, 1);
  EXPECT_EQ(c.constraints[0].measure, optimize::SensorMeasure::KsMax);
  EXPECT_EQ(c.constraints[0].ks, 30);
  EXPECT_EQ(c.constraints[1].component, 2);
  EXPECT_EQ(c.constraints[1].max, -0.5);
  EXPECT_EQ(c.constraints[2].body, "rod");
  EXPECT_EQ(c.constraints[3].type, optimize::ResponseType::Mass);
  EXPECT_EQ(c.adjoint.checkpoints, 32);
  EXPECT_EQ(c.adjoint.storage, flexopt::adjoint::CheckpointStorage::Disk);
  write(std::string(kDynamic) +
        "design: {body: rod, filter: {radius: 0.1}}\nobjective: {type: volume_fraction}\n"
        "adjoint: {checkpoints: all}\n");
  EXPECT_EQ(load_case(dir_.string()).adjoint.checkpoints, 0); // all
}

TEST_F(CaseFiles, DynamicResponsesAreValidated) {
  const std::string design = "design: {body: rod, filter: {radius: 0.1}}\n";
  EXPECT_CASE_ERROR(std::string(kDynamic) + design + "objective: {type: compliance}\n",
                    "objective.type: 'compliance' is a response of a static analysis");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design +
                        "objective: {type: sensor, sensor: s, component: w, measure: final}\n",
                    "objective.component: expected 0, 1, 2 (or x, y, z), got 'w'");
  EXPECT_CASE_ERROR(
      std::string(kDynamic) + design +
          "objective: {type: sensor, sensor: s, component: 0, measure: final, ks: 5}\n",
      "objective.ks: only measure: ks_max takes it");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design +
                        "objective: {type: sensor, sensor: c, component: 0, measure: final}\n",
                    "measures rotation_angle, which a response cannot use yet");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design +
                        "objective: {type: tracking_error, sensor: s, target: [0, 0]}\n",
                    "objective.target: expected a list of 3 components");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design +
                        "objective: {type: mass, body: rod, sensor: s}\n",
                    "objective.sensor: a 'mass' response does not take it");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design + "objective: {type: volume_fraction}\n" +
                        "adjoint: {checkpoints: 0}\n",
                    "adjoint.checkpoints: must be 'all' or a number of stored states >= 1");
  EXPECT_CASE_ERROR(std::string(kDynamic) + design + "objective: {type: volume_fraction}\n" +
                        "adjoint: {storage: tape}\n",
                    "adjoint.storage");
}

// ---- scenarios (issue 45) ----

namespace {
/// kDynamic with two scenarios and an optimization over them.
std::string scenario_case(const std::string &responses) {
  std::string y = kDynamic;
  y += R"(scenarios:
  - name: slow
    drivers: [{joint: j0, value: "0.5*t"}]
    loads: {gravity: [0, 0, -1]}
    bodies: {rod: {density: 9000, initial: {angular_velocity: [0, 0, 7]}}}
    time: {end: 1.5, step: 2.0e-3}
  - {name: fast}
design: {body: rod, region: web}
)";
  return y + responses;
}
} // namespace

TEST_F(CaseFiles, ScenariosChangeTheirSceneAndTime) {
  write(scenario_case("objective: {type: strain_energy_integral, body: rod}\n"
                      "constraints:\n"
                      "  - {type: volume_fraction, max: 0.5}\n"
                      "  - {type: mass, body: rod, max: 9}\n"
                      "  - {type: sensor, sensor: s, component: x, measure: final, scenarios: "
                      "[fast], max: 1}\n"
                      "  - {type: strain_energy_integral, body: rod, combine: weighted, weights: "
                      "[1, 3], max: 1}\n"));
  const auto c = load_case(dir_.string());
  ASSERT_EQ(c.scenarios.size(), 2u);
  const auto &slow = c.scenarios[0];
  EXPECT_EQ(slow.scene.drivers[0].expression, "0.5*t");
  EXPECT_EQ(slow.scene.drivers[1].expression, c.scene.drivers[1].expression);
  EXPECT_EQ((*slow.scene.gravity)[2], -1.0);
  EXPECT_EQ(slow.scene.body("rod").material.density, 9000.0);
  EXPECT_EQ(c.scene.body("rod").material.density, 7850.0);
  EXPECT_EQ(slow.scene.body("rod").initial.angular_velocity[2], 7.0);
  EXPECT_EQ(slow.scene.body("rod").initial.velocity[0], 1.0); // kept
  EXPECT_EQ(slow.time.end, 1.5);
  EXPECT_EQ(slow.time.rho_inf, 0.7); // kept
  EXPECT_EQ(c.scenarios[1].time.end, 2.0);
  // Defaults: the objective sums every scenario, a constraint takes their maximum; the volume
  // fraction is the design's alone (first scenario); the mass of a body whose density a scenario
  // changes is per scenario.
  EXPECT_EQ(c.objective->scenarios, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(c.objective->combine, optimize::Combine::Sum);
  EXPECT_EQ(c.constraints[0].scenarios, (std::vector<std::size_t>{0}));
  EXPECT_EQ(c.constraints[1].scenarios, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(c.constraints[1].combine, optimize::Combine::Max);
  EXPECT_EQ(c.constraints[2].scenarios, (std::vector<std::size_t>{1}));
  EXPECT_EQ(c.constraints[3].weights, (std::vector<double>{1, 3}));
  // The case of scenario slow with the responses that take it.
  const auto responses = flexopt::io::condition_responses(c, 0);
  EXPECT_EQ(responses, (std::vector<std::size_t>{0, 1, 2, 4}));
  const auto one = flexopt::io::condition_case(c, 0, responses);
  EXPECT_TRUE(one.scenarios.empty());
  EXPECT_EQ(one.time.end, 1.5);
  EXPECT_EQ(one.constraints.size(), 3u);
  EXPECT_EQ(one.optimizer.bounds, (std::vector<double>{0.5, 9, 1}));
}

TEST_F(CaseFiles, ScenarioResponsesAreChecked) {
  EXPECT_CASE_ERROR(scenario_case("objective: {type: volume_fraction, scenarios: [fast]}\n"),
                    "objective.scenarios", "is the same in every condition");
  EXPECT_CASE_ERROR(
      scenario_case("objective: {type: strain_energy_integral, body: rod, combine: weighted}\n"),
      "objective.combine: weighted needs weights");
  EXPECT_CASE_ERROR(scenario_case("objective: {type: strain_energy_integral, body: rod, combine: "
                                  "weighted, weights: [1]}\n"),
                    "objective.weights: 1 weights for 2 scenarios");
  EXPECT_CASE_ERROR(scenario_case("objective: {type: strain_energy_integral, body: rod, ks: 20}\n"),
                    "objective.ks: only combine: max takes it");
  EXPECT_CASE_ERROR(scenario_case("objective: {type: strain_energy_integral, body: rod, "
                                  "scenarios: [slow]}\n"),
                    "scenario 'fast' is taken by no response");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}", "output: {every: 10}\nscenarios:\n  - "
                                                        "{name: a, time: {step: 5}}"),
                    "scenarios[0].time.step: must not exceed the scenario's end time");
  EXPECT_CASE_ERROR(dynamic_with("output: {every: 10}",
                                 "output: {every: 10}\nscenarios:\n  - {name: a, bodies: {rdo: "
                                 "{density: 1}}}"),
                    "scenarios[0].bodies.rdo: no body named 'rdo'");
  EXPECT_CASE_ERROR(std::string(kValid) + "scenarios:\n  - {name: a}\n",
                    "scenarios: needs analysis: dynamic");
  EXPECT_CASE_ERROR(std::string(kValid) + "design: {body: beam, region: web}\n"
                                          "objective: {type: compliance, scenarios: all}\n",
                    "objective.scenarios: a static case's conditions are load_cases:");
}

TEST(ScenarioCombination, KsBoundsAndDerivative) {
  // max <= KS <= max + s ln(n) / rho, and dKS/df against central differences.
  optimize::ScenarioUse use;
  use.combine = optimize::Combine::Max;
  use.ks = 20;
  const std::vector<double> f{0.8, 1.0, 0.95};
  const double s = 1.0;
  const auto c = optimize::combine_values(use, f, s);
  EXPECT_GE(c.value, 1.0);
  EXPECT_LE(c.value, 1.0 + s * std::log(3.0) / use.ks);
  double sum = 0;
  for (double d : c.df) sum += d;
  EXPECT_NEAR(sum, 1.0, 1e-15); // a convex combination
  for (std::size_t k = 0; k < f.size(); ++k) {
    const double h = 1e-6;
    auto fp = f, fm = f;
    fp[k] += h;
    fm[k] -= h;
    const double fd =
        (optimize::combine_values(use, fp, s).value - optimize::combine_values(use, fm, s).value) /
        (2 * h);
    EXPECT_NEAR(c.df[k], fd, 1e-8) << "k = " << k;
  }
  // Large values: the factored-out maximum keeps the exponentials finite.
  const auto big = optimize::combine_values(use, {1e5, 1e5 - 1}, 1.0);
  EXPECT_TRUE(std::isfinite(big.value));
  EXPECT_NEAR(big.value, 1e5 + std::log1p(std::exp(-20.0)) / 20, 1e-9);
  // Sum and weighted: exact.
  use.combine = optimize::Combine::Weighted;
  use.weights = {1, 2, 0.5};
  EXPECT_DOUBLE_EQ(optimize::combine_values(use, f, s).value, 0.8 + 2.0 + 0.475);
  EXPECT_EQ(optimize::combine_values(use, f, s).df, use.weights);
  use.combine = optimize::Combine::Sum;
  EXPECT_DOUBLE_EQ(optimize::combine_values(use, f, s).value, 2.75);
}
