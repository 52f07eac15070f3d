/// \file make_plan (docs/theory.md section 12) as an outline: the rigid pre-run (section 12.1)
/// here, the estimates (section 12.2) in plan_estimates.cpp, the rules (section 12.3) and the cost
/// (section 12.4) in plan_rules.cpp; print_plan, plan_json and apply_plan.
#include "flexopt/plan/plan.hpp"

#include "flexopt/bodies/quaternion.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/integrator.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "plan_detail.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>

namespace flexopt::plan {

namespace detail {

std::string fmt(const char *format, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  return buf;
}

} // namespace detail

namespace {

using detail::Candidate;
using detail::fmt;
using detail::PreRun;
using dynamics::BodyModel;

/// The most steps of the rigid pre-run (section 12.1).
constexpr long long kPrerunSteps = 2000;

/// The pre-run's scene (docs/theory.md section 12.1): every body that is not rigid by the user's
/// choice becomes an FFRF body with the plan's reduction and no initial elastic state; one
/// BodyPlan per body into `plan`. Returns the estimated bodies.
std::vector<std::size_t> prerun_scene(const PlanSettings &c, const PlanOptions &o,
                                      dynamics::SceneDescription &pre, Plan &plan) {
  // The pre-run's scene: every body that is not rigid by the user's choice is an FFRF body with
  // the plan's reduction and no initial elastic state.
  std::vector<std::size_t> estimated;
  for (std::size_t b = 0; b < pre.bodies.size(); ++b) {
    dynamics::BodyDescription &body = pre.bodies[b];
    BodyPlan bp;
    bp.body = body.name;
    bp.given = c.scene.bodies[b].model;
    bp.model = bp.given;
    if (body.model == BodyModel::Rigid || body.interfaces.empty()) {
      bp.recommended = BodyModel::Rigid;
      if (body.model != BodyModel::Rigid) {
        bp.model = bp.given == BodyModel::Auto ? BodyModel::Rigid : bp.given;
        bp.reasons.push_back("no interfaces: a flexible model needs one as its frame; estimated "
                             "as rigid");
      }
      body.model = BodyModel::Rigid;
      plan.bodies.push_back(bp);
      continue;
    }
    const int interfaces = static_cast<int>(body.interfaces.size());
    body.model = BodyModel::Ffrf;
    body.reduction.modes =
        std::min(o.max_modes, bodies::kMaxBodyCoordinates - 7 - 6 * (interfaces - 1));
    body.reduction.geometric_stiffening = false;
    body.initial.elastic_displacement = {};
    body.initial.elastic_velocity = {};
    body.rayleigh = {0, 0};
    bp.estimated = true;
    estimated.push_back(b);
    plan.bodies.push_back(bp);
  }
  return estimated;
}

/// The holds of section 12.1: one ElasticCoordinate row per elastic coordinate of the estimated
/// bodies, before the joints' rows; returns the candidates with their rows' entries in lambda.
std::vector<Candidate> hold_elastic_coordinates(const PlanSettings &c,
                                                const std::vector<std::size_t> &estimated,
                                                dynamics::Scene &scene) {
  // Hold every elastic coordinate of the estimated bodies at zero: rows right after the
  // Euler-parameter normalizations, so that the joint rows they make redundant are dropped.
  dynamics::Mechanism &mech = scene.mechanism;
  std::vector<Candidate> cand;
  std::vector<joints::Equation> holds;
  for (std::size_t b : estimated) {
    Candidate cd;
    cd.body = b;
    cd.mech = scene.bodies[b].mechanism;
    cd.n = mech.size(cd.mech) - 7;
    for (int k = 0; k < cd.n; ++k) {
      joints::Equation e;
      e.kind = joints::Equation::Kind::ElasticCoordinate;
      e.a = cd.mech;
      e.coordinate = k;
      e.owner = c.scene.bodies[b].name + " (held rigid)";
      e.row_in_owner = k;
      holds.push_back(e);
    }
    cand.push_back(std::move(cd));
  }
  std::size_t first_joint = 0;
  while (first_joint < mech.equations.size() &&
         mech.equations[first_joint].kind == joints::Equation::Kind::Normalize)
    ++first_joint;
  mech.equations.insert(mech.equations.begin() + static_cast<std::ptrdiff_t>(first_joint),
                        holds.begin(), holds.end());
  mech.finalize();
  mech.drop_redundant_rows(scene.q0, 0.0);
  {
    std::size_t e = first_joint;
    for (Candidate &cd : cand)
      for (int k = 0; k < cd.n; ++k, ++e) {
        const int row = mech.enforced_index(mech.first_row(static_cast<int>(e)));
        if (row < 0)
          throw Error("plan: body " + c.scene.bodies[cd.body].name +
                          ": a hold row was found redundant (an internal error)",
                      true);
        cd.lambda.push_back(row);
      }
  }
  return cand;
}

/// The rigid pre-run (section 12.1) through dynamics::Integrator: each candidate's hold
/// multipliers Q(t) and body-frame angular velocity, and the largest displacement of each
/// position or displacement sensor (its scale, section 12.2). Collective.
PreRun rigid_prerun(MPI_Comm comm, const PlanSettings &c, const PlanOptions &o,
                    dynamics::Scene &scene, std::vector<Candidate> &cand, Plan &plan) {
  const dynamics::Mechanism &mech = scene.mechanism;
  PreRun run;
  // Sensors: the scale of each position or displacement sensor is its largest displacement
  // over the pre-run.
  std::vector<dynamics::BoundSensor> track;
  std::vector<std::size_t> &track_of = run.track_of;
  for (std::size_t i = 0; i < scene.sensors.size(); ++i) {
    const dynamics::BoundSensor &s = scene.sensors[i];
    if (s.quantity == dynamics::SensorQuantity::Position ||
        s.quantity == dynamics::SensorQuantity::Displacement) {
      dynamics::BoundSensor p = s;
      p.quantity = dynamics::SensorQuantity::Position;
      track.push_back(p);
      track_of.push_back(i);
    }
  }
  std::vector<bodies::Vec3> start(track.size());
  std::vector<double> &scale = run.scale;
  scale.assign(track.size(), 0.0);

  // The pre-run's grid: the case's, or at most kPrerunSteps steps over the same time (a rigid
  // motion needs no more; the KED integration is exact for the sampled forcing, and the
  // index-3 multipliers carry less round-off at larger steps, section 6.4).
  const long long case_steps = std::max(1LL, std::llround(c.time.end / c.time.step));
  const long long steps = std::min(case_steps, kPrerunSteps);
  const double h = c.time.end / static_cast<double>(steps);
  run.case_steps = case_steps;
  run.steps = steps;
  run.h = h;
  plan.steps = steps;
  for (Candidate &cd : cand) {
    cd.Q.resize(steps + 1, cd.n);
    cd.omega.resize(steps + 1, 3);
  }
  // rho_inf at most 0.5: the multipliers' start-up oscillation of the index-3 scheme decays as
  // rho_inf^n (section 6.4), and the forcing is the multipliers; the rigid motion is second-order
  // accurate for any rho_inf.
  dynamics::IntegratorSettings settings = dynamics::IntegratorSettings::from(c.time);
  settings.alpha = dynamics::AlphaParameters::from_rho_inf(std::min(c.time.rho_inf, 0.5));
  settings.step = h;
  settings.steps = steps;
  dynamics::Integrator integrator(scene, settings);
  const double t0 = wall_time();
  integrator.start();
  const dynamics::State *state = nullptr;
  auto record = [&](long long n) {
    for (Candidate &cd : cand) {
      for (int k = 0; k < cd.n; ++k)
        cd.Q(n, k) = state->lambda(cd.lambda[static_cast<std::size_t>(k)]);
      const int rigid = mech.offset(cd.mech);
      const bodies::Vec4 p = state->q.segment<4>(rigid + 3), pd = state->v.segment<4>(rigid + 3);
      cd.omega.row(n) = (2.0 * bodies::gbar_matrix(p) * pd).transpose();
      cd.spin = std::max(cd.spin, cd.omega.row(n).norm());
    }
    for (std::size_t i = 0; i < track.size(); ++i) {
      const bodies::Vec3 x = dynamics::sensor_value(scene, track[i], state->q);
      if (n == 0) start[i] = x;
      scale[i] = std::max(scale[i], (x - start[i]).norm());
    }
  };
  try {
    integrator.run([&](const dynamics::StepView &v) {
      state = v.dense;
      record(v.step);
    });
  } catch (const Error &e) {
    throw Error(std::string("plan: the rigid pre-run: ") + e.what(), true);
  }
  plan.prerun_s = wall_time() - t0;
  if (o.report)
    print0(comm, "plan: pre-run: %lld steps of %g s in %.2f s\n", steps, h, plan.prerun_s);
  return run;
}

/// One estimated body's plan: its estimates (section 12.2), the rules and ACF's mesh (section
/// 12.3), the Tet4 check (section 12.5), the given model's warnings and its predicted cost
/// (section 12.4). Collective.
void plan_body(MPI_Comm comm, const PlanSettings &c, const dynamics::SceneDescription &pre,
               const dynamics::Scene &scene, const PreRun &run, const Candidate &cd, Plan &plan) {
  BodyPlan &bp = plan.bodies[cd.body];
  const detail::BodyKed ked = detail::estimate_body(comm, c, scene, run, cd, bp);
  detail::choose_model(c, ked, bp);
  const dynamics::BodyDescription &spec = pre.bodies[cd.body];
  const std::optional<mesh::DistributedMesh> acf_mesh =
      detail::choose_acf_mesh(comm, c, spec, ked, bp);
  detail::check_locking(comm, c, spec, ked, bp);
  detail::warn_given_model(c, ked, bp);
  detail::warn_acf_highest_frequency(c, ked, acf_mesh, bp);
  bp.predicted_cost_s = detail::predicted_cost(comm, plan, run, bp);
}

} // namespace

Plan make_plan(MPI_Comm comm, const PlanSettings &c, const PlanOptions &o) {
  const double t_plan = wall_time();
  Plan plan;
  plan.accuracy = c.accuracy;

  // The pre-run's scene (section 12.1); nothing to estimate if every body stays rigid.
  dynamics::SceneDescription pre = c.scene;
  const std::vector<std::size_t> estimated = prerun_scene(c, o, pre, plan);
  if (estimated.empty()) {
    plan.seconds = wall_time() - t_plan;
    return plan;
  }
  if (o.report)
    print0(comm,
           "plan: the rigid pre-run: every body that is not rigid reduced with up to %d "
           "fixed-interface modes and held rigid\n",
           o.max_modes);
  // The rigid pre-run (section 12.1): the elastic coordinates held at zero, their multipliers Q.
  dynamics::Scene scene = dynamics::build_scene(comm, pre);
  std::vector<Candidate> cand = hold_elastic_coordinates(c, estimated, scene);
  const PreRun run = rigid_prerun(comm, c, o, scene, cand, plan);

  // The estimates (section 12.2), the rules (section 12.3) and the cost (section 12.4) of each
  // estimated body.
  for (const Candidate &cd : cand) plan_body(comm, c, pre, scene, run, cd, plan);
  plan.seconds = wall_time() - t_plan;
  return plan;
}

void print_plan(MPI_Comm comm, const Plan &plan) {
  print0(comm, "plan: accuracy %g (relative error of the sensors)\n", plan.accuracy);
  for (const BodyPlan &bp : plan.bodies) {
    std::string what = dynamics::model_name(bp.model);
    if (bp.model == dynamics::BodyModel::Ffrf)
      what +=
          fmt(", %d modes%s", bp.modes, bp.geometric_stiffening ? ", geometric stiffening" : "");
    if (bp.model == dynamics::BodyModel::Acf && bp.mesh_size > 0)
      what += fmt(", mesh size %g m", bp.mesh_size);
    if (bp.given != dynamics::BodyModel::Auto) what += " (given)";
    print0(comm, "plan: body %s (%s): %s; predicted cost %.3g s\n", bp.body.c_str(),
           dynamics::model_name(bp.given), what.c_str(), bp.predicted_cost_s);
    if (bp.given != dynamics::BodyModel::Auto && bp.estimated && bp.recommended != bp.model)
      print0(comm, "      the estimates recommend %s\n", dynamics::model_name(bp.recommended));
    else if (bp.given == dynamics::BodyModel::Ffrf && bp.estimated &&
             bp.recommended_modes != bp.modes)
      print0(comm, "      the estimates recommend %d modes\n", bp.recommended_modes);
    for (const std::string &r : bp.reasons) print0(comm, "      %s\n", r.c_str());
    for (const std::string &w : bp.warnings) print0(comm, "      warning: %s\n", w.c_str());
  }
}

io::Json plan_json(const Plan &plan) {
  io::Json a = io::Json::array();
  for (const BodyPlan &bp : plan.bodies) {
    io::Json j = io::Json::object();
    j["body"] = bp.body;
    j["model"] = dynamics::model_name(bp.model);
    j["given"] = dynamics::model_name(bp.given);
    j["recommended"] = dynamics::model_name(bp.recommended);
    j["modes"] = bp.modes;
    j["recommended_modes"] = bp.recommended_modes;
    j["geometric_stiffening"] = bp.geometric_stiffening;
    j["recommended_geometric_stiffening"] = bp.recommended_geometric_stiffening;
    if (bp.mesh_size > 0) j["mesh_size"] = bp.mesh_size;
    io::Json r = io::Json::array();
    for (const auto &s : bp.reasons) r.push_back(s);
    j["reasons"] = r;
    io::Json w = io::Json::array();
    for (const auto &s : bp.warnings) w.push_back(s);
    j["warnings"] = w;
    j["predicted_cost_s"] = bp.predicted_cost_s;
    if (bp.estimated) {
      io::Json e = io::Json::object();
      e["dofs"] = bp.est.dofs;
      if (bp.est.acf_dofs) e["acf_dofs"] = bp.est.acf_dofs;
      e["length_m"] = bp.est.length;
      e["first_frequency_hz"] = bp.est.f1;
      e["spin_rad_s"] = bp.est.spin;
      e["excitation_hz"] = bp.est.f_excitation;
      e["deflection_m"] = bp.est.deflection;
      e["rotation_rad"] = bp.est.rotation;
      e["stress_stiffening"] = bp.est.stress_stiffening;
      e["stress_error"] =
          std::isfinite(bp.est.stress_error) ? io::Json(bp.est.stress_error) : io::Json("infinite");
      e["stress_error_at"] = bp.est.stress_error_at;
      if (bp.est.highest_frequency > 0) e["highest_frequency_hz"] = bp.est.highest_frequency;
      e["rigid_error"] = bp.est.rigid_error;
      e["rigid_error_at"] = bp.est.rigid_error_at;
      e["mode_errors"] = io::Json(bp.est.mode_errors);
      e["reduction_s"] = bp.est.reduction_s;
      e["quasi_static_error"] = bp.est.quasi_static_error;
      e["esl_suitable"] = bp.est.quasi_static_error <= kEslQuasiStatic;
      io::Json sd = io::Json::object();
      for (const auto &[name, value] : bp.est.sensor_deflection) sd[name] = value;
      e["sensor_deflection_m"] = sd;
      j["estimates"] = e;
    }
    a.push_back(j);
  }
  return a;
}

void apply_plan(dynamics::SceneDescription &scene, const Plan &plan) {
  using dynamics::BodyModel;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    dynamics::BodyDescription &body = scene.bodies[b];
    if (body.model != BodyModel::Auto) continue;
    const BodyPlan &bp = plan.bodies.at(b);
    body.model = bp.model;
    if (bp.model == BodyModel::Acf && bp.mesh_size > 0) body.mesh.size = bp.mesh_size;
    if (bp.model == BodyModel::Ffrf) {
      body.reduction.modes = bp.modes;
      body.reduction.geometric_stiffening = bp.geometric_stiffening;
      // The chord frame does not take geometric stiffening (case-format "reduction").
      if (!body.reduction.frame_given)
        body.reduction.frame = body.interfaces.size() >= 2 && !bp.geometric_stiffening
                                   ? reduce::FrameCondition::Chord
                                   : reduce::FrameCondition::Clamped;
    }
  }
}

} // namespace flexopt::plan
