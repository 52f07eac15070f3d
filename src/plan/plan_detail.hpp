#pragma once
/// \file The parts of make_plan (docs/theory.md section 12), shared by plan.cpp (the pre-run,
/// section 12.1, and the outline), plan_estimates.cpp (section 12.2) and plan_rules.cpp (sections
/// 12.3-12.5). Private to src/plan/.
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/plan/ked.hpp"
#include "flexopt/plan/plan.hpp"

#include <Eigen/Dense>
#include <cstddef>
#include <mpi.h>
#include <optional>
#include <string>
#include <vector>

namespace flexopt::plan::detail {

inline constexpr double kPi = 3.14159265358979323846;

/// printf into a std::string (at most 511 characters).
std::string fmt(const char *format, ...) __attribute__((format(printf, 1, 2)));

/// A place where a body's elastic deflection is measured (section 12.2): a 3 x n map from the
/// elastic coordinates and the scale its error is relative to.
struct Measure {
  std::string name;
  Eigen::Matrix3Xd S;
  double scale = 0;
  double deflection = 0;       ///< max over time of |S zeta| (the full model's KED)
  bool elastic_sensor = false; ///< an elastic_displacement sensor: a rigid model misses all of it
};

/// One estimated body during the pre-run.
struct Candidate {
  std::size_t body = 0;    ///< case body
  int mech = -1;           ///< mechanism body
  int n = 0;               ///< elastic coordinates of the plan's reduction
  std::vector<int> lambda; ///< the hold rows' entries in lambda
  Eigen::MatrixXd Q;       ///< (steps + 1) x n: the hold rows' multipliers
  Eigen::MatrixXd omega;   ///< (steps + 1) x 3: the body-frame angular velocity
  double spin = 0;
};

/// The rigid pre-run's grid and the scales of the scene's position and displacement sensors
/// (section 12.1; the scales: section 12.2).
struct PreRun {
  long long case_steps = 0;          ///< the case's steps over the run
  long long steps = 0;               ///< the pre-run's steps (at most the case's)
  double h = 0;                      ///< the pre-run's step [s]
  std::vector<std::size_t> track_of; ///< the scene sensor of each tracked one
  std::vector<double> scale;         ///< its largest displacement over the pre-run [m]
};

/// The measures of one body and the relative error that a change of its KED response makes in
/// them (section 12.2): the largest over the measures, or the nodes at the worst instant.
struct Measures {
  std::vector<Measure> list;
  const Eigen::MatrixXd *owned_modes = nullptr; ///< the basis at the owned nodes (node-major)
  Eigen::Index worst = 0;                       ///< the sample of the largest strain energy
  double length = 0;                            ///< the body's largest extent [m]
  MPI_Comm comm = MPI_COMM_NULL;

  /// The relative error that a change D of the KED response (rows: samples) makes; `at` (if
  /// given) names the measure that sets it.
  double error(const Eigen::MatrixXd &D, std::string *at) const;
};

/// What the estimates of one body (section 12.2) leave to the rules, ACF's mesh trials and the
/// warnings (section 12.3).
struct BodyKed {
  const Candidate *cd = nullptr;
  const reduce::FlexibleReduction *red = nullptr; ///< the plan's reduction
  const mesh::DistributedMesh *mesh = nullptr;    ///< the case's mesh
  double h = 0;                                   ///< the pre-run's step [s]
  ModalModel full;                                ///< the plan's model, every coordinate
  Eigen::MatrixXd Z;                              ///< its KED response (rows: samples)
  Measures measures;
  Start start = Start::Rest;   ///< how the case starts the body (section 12.2)
  double w1 = 0;               ///< the lowest frequency of the reduction [rad/s]
  double spin_ratio = 0;       ///< spin / w1
  int s0 = 0;                  ///< static modes of the reduction
  int fixed = 0;               ///< fixed-interface modes of the reduction
  int chosen = -1;             ///< the fixed-interface modes the estimates need (rule 4)
  bool elastic_sensor = false; ///< an elastic_displacement sensor measures the body
};

/// The estimates of one candidate body from the pre-run (section 12.2) into bp.est, and rule 4's
/// geometric stiffening into bp (the stress estimate depends on it). Collective.
BodyKed estimate_body(MPI_Comm comm, const PlanSettings &c, const dynamics::Scene &scene,
                      const PreRun &run, const Candidate &cd, BodyPlan &bp);

/// The rules (section 12.3): the recommended model of an estimated body, its modes, the reasons
/// and the warning where a response keeps it from ACF.
void choose_model(const PlanSettings &c, const BodyKed &ked, BodyPlan &bp);

/// ACF's mesh (section 12.3) for a body the rules make ACF: the coarsest trial mesh whose
/// frequencies change the measures by at most eps / 4 (none: the case's mesh). Collective.
std::optional<mesh::DistributedMesh> choose_acf_mesh(MPI_Comm comm, const PlanSettings &c,
                                                     const dynamics::BodyDescription &spec,
                                                     const BodyKed &ked, BodyPlan &bp);

/// The Tet4 locking check (section 12.5): the same mesh at order 2, a warning if the first
/// frequency lies more than eps above that one. Collective.
void check_locking(MPI_Comm comm, const PlanSettings &c, const dynamics::BodyDescription &spec,
                   const BodyKed &ked, BodyPlan &bp);

/// Where a given model disagrees with the estimates (section 12.3), and what runs.
void warn_given_model(const PlanSettings &c, const BodyKed &ked, BodyPlan &bp);

/// The warning for ACF at rho_inf = 1 (docs/theory.md section 12.4): the highest frequency of
/// the run's mesh (`acf_mesh`, or the case's) neither resolved by the step nor damped. Collective.
void warn_acf_highest_frequency(const PlanSettings &c, const BodyKed &ked,
                                const std::optional<mesh::DistributedMesh> &acf_mesh, BodyPlan &bp);

/// The predicted cost of the body in the run (section 12.4) [s].
double predicted_cost(MPI_Comm comm, const Plan &plan, const PreRun &run, const BodyPlan &bp);

} // namespace flexopt::plan::detail
