#pragma once
/// \file The case directory: case.yaml parsed and validated into the settings of the modules
/// that use them (docs/architecture.md, "Settings").
///
/// Every rank parses case.yaml itself (it is small), so that a malformed case raises the same
/// collective flexopt::Error on every rank: `case.yaml:LINE:COL: message`. See
/// docs/case-format.md for every key. Only `app` includes this header: each module receives its
/// own settings (mesh::MeshSource, fem::StaticSettings, dynamics::SceneDescription, ...), never
/// the Case.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/dynamics/scene_description.hpp"
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/io/frame_schedule.hpp"
#include "flexopt/io/location.hpp"
#include "flexopt/optimize/design_field.hpp"
#include "flexopt/optimize/optimizer.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/scenario_problem.hpp"
#include "flexopt/optimize/topology_problem.hpp"
#include "flexopt/plan/plan.hpp"

#include <array>
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

/// A body setting that only some models use.
struct ModelSetting {
  std::string key; ///< below the body: "reduction", "initial.elastic_velocity"
  std::vector<dynamics::BodyModel> models; ///< the models (rigid, ffrf, acf) that use it
};

/// Every model-dependent body setting, in the order of docs/case-format.md: `reduction` (ffrf),
/// `damping` (ffrf, acf), `initial.elastic_displacement` and `initial.elastic_velocity` (ffrf,
/// acf). Every other body key is used by every model.
const std::vector<ModelSetting> &model_settings();

/// The keys of model_settings() that a body of `model` uses (`auto`: those of
/// dynamics::simulated_model(model)).
std::vector<std::string> settings_used_by(dynamics::BodyModel model);

/// The settings `body` carries that its model does not use, in the order of model_settings().
std::vector<std::string> unused_settings(const dynamics::BodyDescription &body);

/// One line reporting unused_settings(body), e.g. "body rod (model: acf): settings not used by
/// this model: reduction (ffrf)"; empty if every setting the body carries is used.
std::string unused_settings_note(const dynamics::BodyDescription &body);

enum class Analysis { Static, Dynamic };

/// One operating condition of a dynamic case (`scenarios:`, docs/case-format.md "Scenarios"):
/// the case's scene and time grid with the scenario's changes (drivers, loads, gravity, initial
/// speeds, densities, time settings) applied.
struct Scenario {
  std::string name;
  dynamics::SceneDescription scene;
  dynamics::TimeSettings time;
  io::Location where;
};

/// One load case of a static case (`load_cases:`): its supports and loads.
struct LoadCase {
  std::string name;
  fem::StaticLoads loads;
  io::Location where;
};

struct Case {
  std::string directory; ///< the case directory as given
  std::string file;      ///< path of case.yaml
  std::string name;      ///< last component of the directory
  Analysis analysis = Analysis::Static;
  std::vector<MaterialSpec> materials;
  /// The bodies (every analysis; static: one) and sensors (every analysis), and for a dynamic
  /// analysis the ground, joints, drivers, interface forces and gravity.
  dynamics::SceneDescription scene;
  fem::StaticLoads loads;      ///< static: supports, tractions, line loads, gravity, inertia
  dynamics::TimeSettings time; ///< dynamic
  std::string solver;          ///< PETSc options applied before the command line's
  OutputSettings output;       ///< `output:` (docs/case-format.md)
  /// topology optimization: the design field of each design body (`design:`, one map or a
  /// list; empty: no optimization)
  std::vector<optimize::DesignSettings> design;
  std::optional<optimize::ResponseSettings> objective; ///< topology optimization: minimized
  std::vector<optimize::ResponseSettings> constraints; ///< topology optimization: each <= max
  optimize::OptimizerSettings optimizer;
  /// `optimizer: {method: esl}`: design by equivalent static loads (a dynamic case).
  std::optional<optimize::EslSettings> esl;
  adjoint::CheckpointSettings
      adjoint; ///< dynamic optimization: checkpointing of the backward sweep
  /// `scenarios:` (dynamic) or `load_cases:` (static); empty: the case is its one condition.
  std::vector<Scenario> scenarios;
  std::vector<LoadCase> load_cases;
  /// `accuracy`: the relative error of the sensors the user accepts; `model: auto` and
  /// `flexopt plan` choose each body's model for it (docs/theory.md section 12).
  double accuracy = 1e-2;

  bool dynamic() const { return analysis == Analysis::Dynamic; }
  /// "static", "dynamic".
  const char *analysis_name() const { return dynamic() ? "dynamic" : "static"; }
  const MaterialSpec &material(const std::string &name) const;
};

/// The static problem of a static case: its one body's mesh and material, and the loads.
fem::StaticSettings static_settings(const Case &c);

/// What a condition of the case is called: "scenario" (dynamic) or "load case" (static).
const char *condition_noun(const Case &c);
/// The names of the case's scenarios or load cases (empty: none).
std::vector<std::string> condition_names(const Case &c);
/// The case as its condition k (a scenario's scene and time, or a load case's loads) whose
/// objective and constraints are the responses `responses` of the case (indices: 0 the objective,
/// i >= 1 constraint i - 1; the first becomes the objective). Without conditions, k = 0 is the
/// case.
Case condition_case(const Case &c, std::size_t k, const std::vector<std::size_t> &responses);
/// The responses (0 the objective, i >= 1 constraint i - 1) that take condition k (empty: the
/// case has no objective).
std::vector<std::size_t> condition_responses(const Case &c, std::size_t k);
/// The scenario combination of a case's responses (optimize::ScenarioProblem).
optimize::ScenarioSettings scenario_settings(const Case &c);
/// The topology optimization of a static case. Throws a collective flexopt::Error naming the
/// case file if it has no design: or objective:.
optimize::TopologySettings topology_settings(const Case &c);

/// The design problem of a dynamic case (adjoint::DynamicProblem). Throws a collective
/// flexopt::Error naming the case file if it has no design: or objective:.
adjoint::DynamicSettings dynamic_settings(const Case &c);
/// What the plan of a dynamic case reads (plan::make_plan).
plan::PlanSettings plan_settings(const Case &c);

/// Reads and validates `<directory>/case.yaml`. Throws flexopt::Error (collective: call on
/// every rank) with `case.yaml:LINE:COL: message` for unknown keys, wrong types, missing
/// required keys, impossible values and dangling references (a body naming a missing
/// material, a support naming a missing body, a missing geometry file, ...).
Case load_case(const std::string &directory);

} // namespace flexopt::io
