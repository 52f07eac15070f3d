// Case loading: valid cases parse; each kind of bad input gives one message with
// case.yaml:LINE:COL naming the key.
#include "flexopt/core/error.hpp"
#include "flexopt/io/case.hpp"

#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>

namespace fs = std::filesystem;
using flexopt::Error;
using flexopt::io::load_case;

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
  EXPECT_EQ(c.analysis, "static");
  ASSERT_EQ(c.bodies.size(), 1u);
  EXPECT_EQ(c.bodies[0].mesh.order, 2);
  EXPECT_DOUBLE_EQ(c.bodies[0].mesh.size, 0.02);
  EXPECT_DOUBLE_EQ(c.material("steel").E, 2.1e11);
  ASSERT_EQ(c.supports.size(), 1u);
  EXPECT_TRUE(c.supports[0].fix[0] && c.supports[0].fix[1] && c.supports[0].fix[2]);
  EXPECT_DOUBLE_EQ(c.tractions[0].value[1], -1.0e6);
  ASSERT_TRUE(c.gravity.has_value());
  EXPECT_DOUBLE_EQ((*c.gravity)[1], -9.81);
  EXPECT_EQ(c.sensors[0].quantity, "displacement");
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
  ASSERT_TRUE(c.design.has_value());
  EXPECT_EQ(c.design->region, "design");
  EXPECT_DOUBLE_EQ(c.design->filter_radius, 0.02);
  EXPECT_DOUBLE_EQ(c.design->penalty, 3.0);
  ASSERT_TRUE(c.objective.has_value());
  EXPECT_EQ(c.objective->type, "compliance");
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
