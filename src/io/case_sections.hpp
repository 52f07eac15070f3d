#pragma once
/// \file The readers of case.yaml's sections (docs/case-format.md), shared by load_case
/// (src/io/case.cpp: the case, the loads, time and output), src/io/case_scene.cpp (materials,
/// bodies, ground, joints, drivers, forces, sensors) and src/io/case_optimization.cpp (design,
/// objective, constraints, optimizer, adjoint). Each fails with case.yaml:LINE:COL. Private to
/// src/io/.
#include "case_reader.hpp"
#include "flexopt/io/case.hpp"

#include <filesystem>
#include <string>
#include <vector>
#include <yaml-cpp/yaml.h>

namespace flexopt::io::detail {

// ---- the scene (src/io/case_scene.cpp) ----

/// `materials:` into c.materials.
void read_materials(const Reader &r, const YAML::Node &node, Case &c);
/// `bodies:` into c.scene.bodies (geometry paths relative to the case directory `dir`).
void read_bodies(const Reader &r, const YAML::Node &node, const std::filesystem::path &dir,
                 Case &c);
/// Whether the case has a body `name`.
bool has_body(const Case &c, const std::string &name);
/// `ground:` (its interfaces) into c.scene.ground.
void read_ground(const Reader &r, const YAML::Node &node, Case &c);
/// `joints:` into c.scene.joints.
void read_joints(const Reader &r, const YAML::Node &node, Case &c);
/// `drivers:` (at `key`) into c.scene.drivers.
void read_drivers(const Reader &r, const YAML::Node &node, Case &c,
                  const std::string &key = "drivers");
/// `loads.forces:` (interface forces of a dynamic analysis, at `key`) into c.scene.forces.
void read_forces(const Reader &r, const YAML::Node &node, Case &c,
                 const std::string &key = "loads.forces");
/// `time:` at `path` into t; `partial` (a scenario's time): every key optional over t's values.
void read_time(const Reader &r, const YAML::Node &v, const std::string &path,
               dynamics::TimeSettings &t, bool partial);

// ---- the operating conditions (src/io/case_scenarios.cpp) ----

/// `scenarios:` (dynamic) into c.scenarios: the case's scene and time with each scenario's
/// changes. Read after the scene, loads and time, before the responses.
void read_scenarios(const Reader &r, const YAML::Node &node, Case &c);
/// The responses' `scenarios:`, `combine:`, `weights:`, `ks` / `combine_ks` keys of response s at
/// `path` (v its node), checked against c's scenarios or load cases; `constraint`: the default
/// combination is max (sum for the objective). `ks_taken`: the response type takes `ks` itself
/// (then only combine_ks is the combination's).
void read_response_conditions(const Reader &r, const YAML::Node &v, const std::string &path,
                              const Case &c, bool constraint, bool ks_taken,
                              optimize::ResponseSettings &s);
/// `sensors:` into c.scene.sensors.
void read_sensors(const Reader &r, const YAML::Node &node, Case &c);

// ---- the optimization (src/io/case_optimization.cpp) ----

/// `design:`, `objective:`, `constraints:`, `optimizer:` and `adjoint:` of the document `root`,
/// their consistency, and the optimizer's share of other keys (the constraints' bounds,
/// design.xdmf's stride).
void read_optimization(const Reader &r, YAML::Node root, Case &c);

} // namespace flexopt::io::detail
