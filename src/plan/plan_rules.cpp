/// \file The rules of make_plan (docs/theory.md section 12.3: rigid, FFRF or ACF, ACF's mesh, the
/// given model's warnings), the Tet4 locking check (section 12.5) and the predicted cost (section
/// 12.4).
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "plan_detail.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

namespace flexopt::plan::detail {

namespace {

using dynamics::BodyModel;

/// ACF cost model (docs/theory.md section 12.4): rank-seconds per DOF and Newton iteration, and
/// Newton iterations per step: the median of the quiet ACF runs at rho_inf < 1 of the
/// speed-accuracy map (docs/benchmarks.md "Speed against accuracy": 1.5-2.7 us, median 2.2, on
/// 837-13,257 DOFs with no visible trend; 3.7-4.5 iterations per step).
constexpr double kAcfSecondsPerDofIteration = 2.2e-6;
constexpr double kAcfIterationsPerStep = 4.2;
/// The largest Tet4 mesh (nodes) that the plan meshes again at order 2 to check for locking
/// (section 12.5): about 8 times the nodes at order 2.
constexpr PetscInt kLockingCheckNodes = 5000;

/// An upper bound of the mesh's highest angular frequency [rad/s]: the largest over the
/// elements of the largest eigenvalue of K_e x = w^2 M_e x (the assembled spectrum lies below
/// the elements' largest, Irons & Treharne 1971). Collective.
double highest_frequency(const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &mat) {
  const fem::IsotropicMaterial material{mat.E, mat.nu, mat.density};
  double w2 = 0;
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const fem::ElementCoords X = mesh.element_coordinates(e);
    try {
      const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(
          fem::element_stiffness(mesh.type, X, material),
          fem::element_mass(mesh.type, X, mat.density), Eigen::EigenvaluesOnly);
      w2 = std::max(w2, eig.eigenvalues().maxCoeff());
    } catch (const std::exception &err) {
      abort_local(std::string("plan: highest frequency: element ") +
                  std::to_string(mesh.element_tags[static_cast<std::size_t>(e)]) + ": " +
                  err.what());
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, &w2, 1, MPI_DOUBLE, MPI_MAX, mesh.comm);
  return std::sqrt(w2);
}

/// Whether the body is the optimization's design body (a flexible one stays flexible, section
/// 12.3).
bool is_design_body(const PlanSettings &c, const BodyPlan &bp) {
  return std::find(c.design_bodies.begin(), c.design_bodies.end(), bp.body) !=
         c.design_bodies.end();
}

/// Why ACF (section 12.3, rules 2 and 3): the first reason that holds.
std::string acf_reason(const Estimates &est, const BodyPlan &bp, double eps) {
  if (est.rotation * est.rotation > eps)
    return fmt("acf: the elastic rotation reaches %.3g rad; FFRF's linear strain in a "
               "floating frame leaves out terms of order rotation^2 = %.2g > %g",
               est.rotation, est.rotation * est.rotation, eps);
  if (!std::isfinite(est.stress_error))
    return std::string("acf: the loads' stress takes the body's stiffness to zero (it "
                       "buckles under the rigid motion's loads), which FFRF's linear "
                       "elasticity leaves out");
  return fmt("acf: the loads' stress (inertia, gravity, joints%s) changes the body's "
             "stiffness by up to %.2g and %s by %.2g of its scale (> %g / 2), which FFRF's "
             "linear elasticity leaves out",
             bp.geometric_stiffening ? "; less the centrifugal part stiffened FFRF takes in" : "",
             est.stress_stiffening, est.stress_error_at.c_str(), est.stress_error, eps);
}

/// The reasons of an FFRF body (section 12.3, rule 4): why flexible, why not ACF, the modes and
/// the geometric stiffening.
void ffrf_reasons(const BodyKed &ked, bool flexible_design, bool stressed, double eps,
                  BodyPlan &bp) {
  const Estimates &est = bp.est;
  const int chosen = ked.chosen, fixed = ked.fixed;
  const double spin_ratio = ked.spin_ratio, w1 = ked.w1;
  if (ked.elastic_sensor)
    bp.reasons.push_back("flexible: a sensor measures this body's elastic displacement");
  else if (flexible_design)
    bp.reasons.push_back("flexible: the design body of the optimization");
  else
    bp.reasons.push_back(fmt("flexible: a rigid model misses %.2g of %s's scale (> %g)",
                             est.rigid_error, est.rigid_error_at.c_str(), eps));
  bp.reasons.push_back(fmt("ffrf: elastic rotation %.3g rad (rotation^2 = %.2g %s %g), the "
                           "loads' stress stiffening %.2g, %.2g of the measures (%s %g / 2)",
                           est.rotation, est.rotation * est.rotation,
                           est.rotation * est.rotation > eps ? ">" : "<=", eps,
                           est.stress_stiffening, est.stress_error, stressed ? ">" : "<=", eps));
  std::string errs;
  for (std::size_t j = 0; j < est.mode_errors.size() && j <= static_cast<std::size_t>(chosen) + 2;
       ++j)
    errs += fmt("%s%zu: %.2g", errs.empty() ? "" : ", ", j, est.mode_errors[j]);
  bp.reasons.push_back(fmt("modes: %d (relative error against %d modes, KED: %s; <= %g)", chosen,
                           fixed, errs.c_str(), 0.5 * eps));
  if (bp.geometric_stiffening)
    bp.reasons.push_back(fmt("geometric stiffening: spin %.3g rad/s is %.3g times the first "
                             "frequency %.4g rad/s; (spin/w1)^2 = %.2g > %g",
                             est.spin, spin_ratio, w1, spin_ratio * spin_ratio, eps));
  else
    bp.reasons.push_back(
        fmt("no geometric stiffening: (spin/w1)^2 = %.2g <= %g", spin_ratio * spin_ratio, eps));
}

} // namespace

void choose_model(const PlanSettings &c, const BodyKed &ked, BodyPlan &bp) {
  const double eps = c.accuracy;
  const Estimates &est = bp.est;
  // The rules (section 12.3).
  const bool flexible_design = is_design_body(c, bp);
  // Why ACF (the first reason that holds). The loads' stress, which FFRF leaves out, changes
  // what the measures see by e_sigma; half the budget (the other half: the modes' truncation).
  const bool stressed = est.stress_error > 0.5 * eps;
  bp.modes = ked.chosen;
  if (!ked.elastic_sensor && !flexible_design && est.rigid_error <= eps) {
    bp.recommended = BodyModel::Rigid;
    bp.reasons.push_back(fmt("rigid: the elastic deflection changes %s by %.2g of its scale, "
                             "within the accuracy %g",
                             est.rigid_error_at.c_str(), est.rigid_error, eps));
  } else if (est.rotation * est.rotation > eps || stressed) {
    bp.recommended = BodyModel::Acf;
    bp.reasons.push_back(acf_reason(est, bp, eps));
  } else {
    bp.recommended = BodyModel::Ffrf;
    ffrf_reasons(ked, flexible_design, stressed, eps, bp);
  }
  bp.reasons.push_back(fmt("estimates: first frequency %.4g Hz, excitation below %.3g Hz, spin "
                           "%.3g rad/s, KED deflection %.3g m, rotation %.3g rad, the loads' "
                           "stress stiffening %.3g (%.2g of the measures)",
                           est.f1, est.f_excitation, est.spin, est.deflection, est.rotation,
                           est.stress_stiffening, est.stress_error));
  // Equivalent static loads (section 14.5): where the elastic response follows the loads.
  const bool quasi = est.quasi_static_error <= kEslQuasiStatic;
  bp.reasons.push_back(fmt(
      "quasi-static: e_qs %.2g (the elastic response's distance from its quasi-static part; "
      "docs/theory.md section 14.5): %s",
      est.quasi_static_error,
      !quasi ? "above 0.05, its elastic dynamics matter: equivalent static loads would miss them"
      : is_design_body(c, bp)
          ? "at most 0.05: equivalent static loads (optimizer: {method: esl}) would design it "
            "at a fraction of the dynamic design's cost"
          : "at most 0.05: equivalent static loads would serve to design it"));
}

std::optional<mesh::DistributedMesh> choose_acf_mesh(MPI_Comm comm, const PlanSettings &c,
                                                     const dynamics::BodyDescription &spec,
                                                     const BodyKed &ked, BodyPlan &bp) {
  const double eps = c.accuracy, h = ked.h;
  const Candidate &cd = *ked.cd;
  const reduce::FlexibleReduction &red = *ked.red;
  const ModalModel &full = ked.full;
  Estimates &est = bp.est;
  // ACF's mesh (section 12.3): for an auto body that the rules make ACF, meshed from a .geo at a
  // given size and not a design body, the coarsest of 4, 3, 2 and 1.5 times the case's size
  // whose frequencies, put into the KED response in place of the case mesh's, change the
  // measures by at most eps / 4.
  std::optional<mesh::DistributedMesh> acf_mesh;
  if (bp.recommended == BodyModel::Acf && bp.given == BodyModel::Auto && !is_design_body(c, bp) &&
      spec.mesh.size > 0 && mesh::meshed_from_geo(spec.mesh)) {
    const fem::IsotropicMaterial &mat = spec.material;
    const Eigen::MatrixXd F = cd.Q * full.E;
    const Eigen::MatrixXd Zf = modal_response(full.w2, F, h, ked.start) * full.E.transpose();
    std::string trials;
    for (double factor : {4.0, 3.0, 2.0, 1.5}) {
      dynamics::BodyDescription trial = spec;
      trial.mesh.size = factor * spec.mesh.size;
      std::optional<mesh::DistributedMesh> tm;
      std::shared_ptr<reduce::FlexibleReduction> tr;
      try {
        tm.emplace(mesh::load_body_mesh(comm, trial.mesh));
        tr = dynamics::reduce_ffrf_body(*tm, trial, mat, nullptr);
      } catch (const Error &err) { // collective: every rank skips the size
        trials +=
            fmt("%s%g m: failed (%s)", trials.empty() ? "" : ", ", trial.mesh.size, err.what());
        continue;
      }
      // The case mesh's modes with the trial mesh's frequencies, mode by mode.
      Eigen::VectorXd w2 = full.w2;
      const Eigen::Index m = std::min(w2.size(), tr->eigenvalues.size());
      for (Eigen::Index k = 0; k < m; ++k) w2(k) *= tr->eigenvalues(k) / red.eigenvalues(k);
      const double e = ked.measures.error(
          modal_response(w2, F, h, ked.start) * full.E.transpose() - Zf, nullptr);
      trials += fmt("%s%g m: %.2g (%lld DOFs)", trials.empty() ? "" : ", ", trial.mesh.size, e,
                    3LL * static_cast<long long>(tm->global_nodes));
      if (e <= 0.25 * eps) {
        bp.mesh_size = trial.mesh.size;
        est.acf_dofs = static_cast<int>(3 * tm->global_nodes);
        acf_mesh.emplace(std::move(*tm));
        break;
      }
    }
    if (bp.mesh_size > 0)
      bp.reasons.push_back(fmt("acf mesh: size %g m (the case's %g m): its frequencies change "
                               "the measures by at most %g / 4 (%s)",
                               bp.mesh_size, spec.mesh.size, eps, trials.c_str()));
    else
      bp.reasons.push_back(fmt("acf mesh: the case's (%g m): a coarser one changes the measures "
                               "by more than %g / 4 (%s)",
                               spec.mesh.size, eps, trials.c_str()));
  }
  return acf_mesh;
}

void check_locking(MPI_Comm comm, const PlanSettings &c, const dynamics::BodyDescription &spec,
                   const BodyKed &ked, BodyPlan &bp) {
  const double eps = c.accuracy;
  const mesh::DistributedMesh &mesh = *ked.mesh;
  const reduce::FlexibleReduction &red = *ked.red;
  const Estimates &est = bp.est;
  // Linear tetrahedra lock in bending (section 12.5): a flexible body meshed from a .geo with
  // Tet4 (up to kLockingCheckNodes nodes) is reduced again on the same mesh at order 2, and a
  // first frequency more than eps above that one is reported.
  if (bp.recommended != BodyModel::Rigid && mesh.type == fem::ElementType::Tet4 &&
      mesh::meshed_from_geo(spec.mesh) && mesh.global_nodes <= kLockingCheckNodes) {
    dynamics::BodyDescription quadratic = spec;
    quadratic.mesh.order = 2;
    try {
      const mesh::DistributedMesh qm = mesh::load_body_mesh(comm, quadratic.mesh);
      const auto qr = dynamics::reduce_ffrf_body(qm, quadratic, spec.material, nullptr);
      const double stiff = std::sqrt(red.eigenvalues(0) / qr->eigenvalues(0)) - 1;
      if (stiff > eps)
        bp.warnings.push_back(
            fmt("the mesh is too stiff: linear tetrahedra (Tet4) lock in bending; its first "
                "frequency, %.4g Hz, is %.1f %% above the same mesh at order 2 (%.4g Hz), and the "
                "estimates take the mesh as exact: give mesh: {order: 2} (or a finer size)",
                est.f1, 100 * stiff, std::sqrt(qr->eigenvalues(0)) / (2 * kPi)));
    } catch (const Error &err) { // collective
      bp.warnings.push_back(std::string("the order-2 check of the Tet4 mesh failed: ") +
                            err.what());
    }
  }
}

void warn_given_model(const PlanSettings &c, const BodyKed &ked, BodyPlan &bp) {
  const double eps = c.accuracy, spin_ratio = ked.spin_ratio, w1 = ked.w1;
  const int chosen = ked.chosen, fixed = ked.fixed;
  const Estimates &est = bp.est;
  // What runs, and where a given model disagrees.
  if (bp.given == BodyModel::Auto) {
    bp.model = bp.recommended;
    bp.recommended_modes = bp.modes;
    bp.recommended_geometric_stiffening = bp.geometric_stiffening;
    return;
  }
  bp.model = bp.given;
  const dynamics::ReductionSettings &r = c.scene.bodies[ked.cd->body].reduction;
  // What runs is what the case gives: its modes and stiffening (the recommendation's are kept in
  // recommended_modes and recommended_geometric_stiffening).
  bp.recommended_modes = bp.modes;
  bp.recommended_geometric_stiffening = bp.geometric_stiffening;
  if (bp.given == BodyModel::Ffrf) {
    bp.modes = r.modes;
    bp.geometric_stiffening = r.geometric_stiffening;
  }
  if (bp.given == BodyModel::Ffrf && !r.geometric_stiffening && spin_ratio >= 1)
    bp.warnings.push_back(fmt("linear FFRF will diverge at this spin rate: %.3g rad/s is "
                              "%.3g times the first frequency %.4g rad/s (give reduction: "
                              "{geometric_stiffening: true})",
                              est.spin, spin_ratio, w1));
  else if (bp.given == BodyModel::Ffrf && !r.geometric_stiffening &&
           bp.recommended_geometric_stiffening)
    bp.warnings.push_back(fmt("the spin changes the first frequency by about (spin/w1)^2 = "
                              "%.2g > %g; reduction: {geometric_stiffening: true} takes it in",
                              spin_ratio * spin_ratio, eps));
  if (bp.given == BodyModel::Ffrf && bp.recommended == BodyModel::Acf)
    bp.warnings.push_back(
        est.rotation * est.rotation > eps
            ? fmt("FFRF's small-deformation assumption: the elastic rotation reaches %.3g "
                  "rad (rotation^2 = %.2g > %g); model: acf",
                  est.rotation, est.rotation * est.rotation, eps)
            : fmt("FFRF's linear elasticity: the loads' stress changes the stiffness by "
                  "%.2g and the measures by %.2g (> %g / 2); model: acf",
                  est.stress_stiffening, est.stress_error, eps));
  if (bp.given == BodyModel::Ffrf && bp.recommended == BodyModel::Ffrf && r.modes < chosen)
    bp.warnings.push_back(fmt(
        "%d modes leave %.2g of the sensors' scale (the estimates "
        "need %d for %g)",
        r.modes, est.mode_errors[static_cast<std::size_t>(std::min(r.modes, fixed))], chosen, eps));
  if (bp.given == BodyModel::Rigid && bp.recommended != BodyModel::Rigid)
    bp.warnings.push_back(fmt("a rigid model misses %.2g of %s's scale (> %g)", est.rigid_error,
                              est.rigid_error_at.c_str(), eps));
  if (bp.given == BodyModel::Acf && bp.recommended != BodyModel::Acf)
    bp.warnings.push_back(std::string("the estimates find ") +
                          dynamics::model_name(bp.recommended) +
                          " enough for the accuracy, at a fraction of ACF's cost");
}

void warn_acf_highest_frequency(const PlanSettings &c, const BodyKed &ked,
                                const std::optional<mesh::DistributedMesh> &acf_mesh,
                                BodyPlan &bp) {
  Estimates &est = bp.est;
  // ACF at rho_inf = 1: nothing damps the mesh's highest frequencies, which the step does
  // not resolve (h w_max >> 1); on the co-rotated elements they can stall Newton
  // (docs/benchmarks.md "Where each method fails").
  if (bp.model == BodyModel::Acf) {
    const double w_max =
        highest_frequency(acf_mesh ? *acf_mesh : *ked.mesh, c.scene.bodies[ked.cd->body].material);
    est.highest_frequency = w_max / (2 * kPi);
    if (c.time.rho_inf > 0.99 && c.time.step * w_max > 2)
      bp.warnings.push_back(
          fmt("ACF at rho_inf = %g: the mesh's highest frequency, %.3g Hz, is not resolved by the "
              "step (h w_max = %.3g > 2) and not damped; Newton may stall on it: rho_inf <= 0.9 "
              "damps it",
              c.time.rho_inf, est.highest_frequency, c.time.step * w_max));
  }
}

double predicted_cost(MPI_Comm comm, const Plan &plan, const PreRun &run, const BodyPlan &bp) {
  const Estimates &est = bp.est;
  int size = 1;
  MPI_Comm_size(comm, &size);
  // Predicted cost of the body in the run.
  if (bp.model == BodyModel::Ffrf)
    return est.reduction_s +
           plan.prerun_s * static_cast<double>(run.case_steps) / static_cast<double>(run.steps);
  if (bp.model == BodyModel::Acf)
    return static_cast<double>(run.case_steps) * kAcfIterationsPerStep *
           (est.acf_dofs ? est.acf_dofs : est.dofs) * kAcfSecondsPerDofIteration / size;
  return 0;
}

} // namespace flexopt::plan::detail
