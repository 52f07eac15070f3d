#pragma once
/// \file Choosing each body's model (`model: auto`, `flexopt plan`; docs/theory.md section 12):
/// a rigid pre-run of the scene with every flexible candidate reduced and held rigid, the
/// kineto-elastodynamic (KED) response of each candidate to the forcing of that motion, and the
/// rules that turn the estimates into rigid, FFRF (modes, geometric stiffening) or ACF.
#include "flexopt/dynamics/scene_description.hpp"
#include "flexopt/io/json.hpp"

#include <mpi.h>
#include <string>
#include <utility>
#include <vector>

namespace flexopt::plan {

/// The estimates behind one body's choice (docs/theory.md section 12.2).
struct Estimates {
  int dofs = 0;            ///< FE DOFs of the body's mesh
  int acf_dofs = 0;        ///< acf: FE DOFs of the mesh the plan chose (0: the case's)
  double length = 0;       ///< largest extent of the body [m]
  double f1 = 0;           ///< lowest frequency of the reduction (body on its frame) [Hz]
  double spin = 0;         ///< max |omega| of the pre-run [rad/s]
  double f_excitation = 0; ///< frequency below which 1 - eps^2 of the forcing's energy lies [Hz]
  double deflection = 0;   ///< max elastic displacement over time and nodes (KED) [m]
  double rotation = 0;     ///< max elastic rotation over time and elements (KED) [rad]
  /// max over time of |relative stiffness change| from the stress of the loads' quasi-static
  /// deformation that FFRF leaves out (section 12.2): P / P_buckling for an axially loaded link
  double stress_stiffening = 0;
  /// what that stiffness change does to the measures (KED with and without it), relative to
  /// their scales; infinite where the body buckles under the loads
  double stress_error = 0;
  std::string stress_error_at;     ///< the measure that sets it
  double highest_frequency = 0;    ///< acf: bound of the mesh's highest frequency [Hz] (else 0)
  double rigid_error = 0;          ///< relative sensor error of the rigid model (section 12.2)
  std::string rigid_error_at;      ///< the sensor, interface or "nodes" that sets it
  std::vector<double> mode_errors; ///< relative sensor error of FFRF with j fixed-interface modes
  double reduction_s = 0;          ///< the plan's reduction of the body [s]
  /// e_qs of section 14.5: the KED response's distance from its quasi-static part, max over
  /// time in the modal energy norm, relative to its largest; <= kEslQuasiStatic: equivalent
  /// static loads would design the body
  double quasi_static_error = 0;
  /// The KED estimate of each of the body's sensors: max over time of |elastic displacement| [m].
  std::vector<std::pair<std::string, double>> sensor_deflection;
};

/// ESL's criterion (docs/theory.md 14.5): e_qs at most this.
constexpr double kEslQuasiStatic = 0.05;

struct BodyPlan {
  std::string body;
  dynamics::BodyModel given = dynamics::BodyModel::Auto;        ///< the case's model
  dynamics::BodyModel recommended = dynamics::BodyModel::Rigid; ///< what the estimates choose
  /// ffrf: the fixed-interface modes and geometric stiffening of what runs (the case's for a
  /// given ffrf body, the recommendation's for auto)
  int modes = 0;
  bool geometric_stiffening = false;
  /// ffrf: what the estimates recommend (the fewest modes within accuracy / 2; stiffening where
  /// (spin / w1)^2 > accuracy), whatever the case gives
  int recommended_modes = 0;
  bool recommended_geometric_stiffening = false;
  double mesh_size = 0; ///< acf: the element size the plan chose [m] (0: the case's mesh)
  /// what runs: the given model, or the recommendation for auto
  dynamics::BodyModel model = dynamics::BodyModel::Rigid;
  std::vector<std::string> reasons;  ///< why (with numbers)
  std::vector<std::string> warnings; ///< where a given model disagrees with the estimates
  double predicted_cost_s = 0;       ///< predicted wall time of the body in the run
  bool estimated = false;            ///< false: rigid as given, no estimates made
  Estimates est;
};

struct Plan {
  double accuracy = 1e-2;
  std::vector<BodyPlan> bodies; ///< per case body, in the case's order
  double prerun_s = 0;          ///< the rigid pre-run's integration [s]
  long long steps = 0;
  double seconds = 0; ///< the whole plan [s]
};

/// What the plan of a dynamic case reads: its scene and time grid, the accuracy the user
/// accepts, and what its optimization needs of the models.
struct PlanSettings {
  dynamics::SceneDescription scene;
  dynamics::TimeSettings time;
  double accuracy = 1e-2; ///< `accuracy`: the relative error of the sensors the user accepts
  std::vector<std::string> design_bodies; ///< the design bodies; a flexible one stays flexible
};

struct PlanOptions {
  int max_modes =
      40; ///< fixed-interface modes of the plan's reduction (fewer if the body has fewer)
  bool report = true; ///< progress and the scene's notes on rank 0
};

/// The plan of a dynamic case: every body that is not `model: rigid` is estimated. Collective;
/// throws collective flexopt::Errors (a failed pre-run names the step).
Plan make_plan(MPI_Comm comm, const PlanSettings &settings, const PlanOptions &options = {});

/// Prints one block per body (choice, reasons, numbers, warnings) on rank 0.
void print_plan(MPI_Comm comm, const Plan &plan);

/// summary.json's `plan`: [{body, model, given, recommended, modes, geometric_stiffening,
/// reasons, warnings, predicted_cost_s, estimates}].
io::Json plan_json(const Plan &plan);

/// Sets every `model: auto` body of `scene` to its plan (model, reduction modes, geometric
/// stiffening, ACF's mesh size).
void apply_plan(dynamics::SceneDescription &scene, const Plan &plan);

} // namespace flexopt::plan
