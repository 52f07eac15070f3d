// `flexopt simulate` for `analysis: dynamic`: a mechanism of rigid, FFRF and ACF bodies
// integrated with generalized-alpha, on the dense/replicated backend (no ACF body) or the
// distributed one (docs/theory.md section 8.2); motion.xdmf (every body's mesh moving and, for
// flexible bodies, deforming), summary.json (sensors, energy, constraint violation, Newton
// statistics).
#include "app_common.hpp"
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/integrator.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/io/frame_schedule.hpp"
#include "flexopt/io/motion_writer.hpp"
#include "flexopt/io/restart.hpp"
#include "flexopt/mesh/grid_layout.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace flexopt::app {

namespace {

/// Largest residual, relative to the scene's size, that a row left out as redundant may reach
/// before the run stops (structurally redundant rows stay at round-off, ~1e-15).
constexpr double kRedundantDriftTolerance = 1e-8;

/// Size of motion.h5 above which the run warns before it starts [bytes].
constexpr double kLargeMotionBytes = 1e9;

/// True if case body b writes an elastic_displacement field with its positions: an FFRF body
/// with modes, or an ACF body with interfaces (dynamics::Integrator::positions).
bool writes_elastic(const dynamics::Scene &scene, std::size_t b) {
  const dynamics::SceneBody &sb = scene.bodies[b];
  if (sb.acf >= 0) return !sb.nodes.empty();
  return scene.mechanism.size(sb.mechanism) > 7;
}

/// "12.3 MB", "1.76 GB": decimal units, as file managers show them.
std::string human_bytes(double bytes) {
  char buf[32];
  if (bytes >= 1e9)
    std::snprintf(buf, sizeof buf, "%.2f GB", bytes / 1e9);
  else if (bytes >= 1e6)
    std::snprintf(buf, sizeof buf, "%.1f MB", bytes / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.0f kB", bytes / 1e3);
  return buf;
}

io::Json vec3_json(const bodies::Vec3 &v) {
  return io::Json(std::vector<double>{v.x(), v.y(), v.z()});
}

/// Integrates `scene` (with `design`: the scene of that problem at the design x, through its
/// forward run, and with `gradient` its adjoint gradients too), writes dir/NAME.xdmf (+ .h5)
/// and the run's figures into s. Collective.
void integrate(const Context &ctx, const io::Case &c, dynamics::Scene &scene,
               adjoint::DynamicProblem *design, Vec x, bool gradient, const std::string &dir,
               const std::string &name, io::Json &s) {
  const dynamics::Mechanism &mech = scene.mechanism;
  print0(ctx.comm(), "mechanism: %zu bodies, %d coordinates, %d constraint rows enforced of %d\n",
         mech.bodies.size(), mech.coordinates(), mech.constraints(), mech.all_rows());
  io::Json redundant = io::Json::array();
  for (const auto &r : scene.redundant_rows) {
    print0(ctx.comm(),
           "mechanism: redundant constraint %s is implied by the others and is not enforced "
           "(its residual is monitored)\n",
           r.c_str());
    redundant.push_back(r);
  }
  s["redundant_constraints"] = redundant;

  const dynamics::IntegratorSettings settings = dynamics::IntegratorSettings::from(c.time);
  const dynamics::AlphaParameters &par = settings.alpha;
  const dynamics::NewtonSettings &newton = settings.newton;
  if (!scene.acf.empty())
    print0(ctx.comm(),
           "mechanism: %zu ACF bodies on the distributed backend (one PETSc system over %d "
           "rank(s); Newton solver: options prefix mech_, MUMPS LU by default, KLU on one "
           "rank up to 2000 unknowns)\n",
           scene.acf.size(), ctx.size());
  auto run = std::make_unique<dynamics::Integrator>(scene, settings);
  dynamics::StartReport start;
  run->start(&start);
  {
    const dynamics::StartReport &st = start;
    print0(ctx.comm(),
           "initial velocities: the rigid-body velocities made consistent with the joints and "
           "drivers; kinetic energy %.9g J given -> %.9g J (%+.6g J)\n",
           st.kinetic_given, st.kinetic, st.kinetic - st.kinetic_given);
    if (st.elastic_corrected)
      print0(ctx.comm(),
             "initial velocities: warning: rigid-body velocities alone cannot satisfy the joints "
             "(residual %.3e): the elastic velocities were corrected too, with the least change "
             "of kinetic energy\n",
             st.rigid_residual);
    s["initial_kinetic_energy"]["given"] = st.kinetic_given;
    s["initial_kinetic_energy"]["start"] = st.kinetic;
    s["initial_kinetic_energy"]["elastic_corrected"] = st.elastic_corrected;
  }
  const double h = settings.step;
  const long long steps = settings.steps;
  print0(ctx.comm(),
         "integrate: generalized-alpha rho_inf = %g (alpha_m %.4f, alpha_f %.4f, gamma %.4f, beta "
         "%.4f), %lld steps of %g s to t = %g s; Newton matrix kept while the contraction is <= "
         "%g\n",
         par.rho_inf, par.alpha_m, par.alpha_f, par.gamma, par.beta, steps, h,
         static_cast<double>(steps) * h, newton.reuse_contraction);
  // rho_inf = 1 is the trapezoidal rule: it damps nothing, and on the index-3 equations of a
  // flexible mechanism the step can grow unstably (cases/slider_crank_start/README.md).
  if (par.rho_inf >= 1)
    for (const auto &b : c.scene.bodies)
      if (dynamics::simulated_model(b.model) != dynamics::BodyModel::Rigid) {
        print0(ctx.comm(),
               "time: warning: rho_inf = 1 (no numerical dissipation) with the flexible body "
               "'%s': generalized-alpha on the index-3 equations of a flexible mechanism can grow "
               "unstably at rho_inf = 1 (docs/theory.md 6.4); rho_inf <= 0.99 damps it\n",
               b.name.c_str());
        break;
      }

  std::vector<io::MotionBody> mb;
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    mb.push_back({c.scene.bodies[b].name, mesh::grid_layout(scene.meshes[b])});
  // Frames of motion.xdmf (io::FrameSchedule). Energy and sensors are small: without output:
  // they keep every step; with it they are sampled at the frames, as the key always did.
  const io::FrameSchedule schedule(c.output, steps, h);
  const bool sample_every_step = !c.output.given();
  std::vector<std::vector<std::string>> fields(c.scene.bodies.size());
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    if (writes_elastic(scene, b)) fields[b] = {"elastic_displacement"};
  const long long frames = schedule.frames();
  const double motion_bytes = io::estimate_motion_bytes(mb, fields, frames);
  if (schedule.interval_below_step())
    print0(ctx.comm(),
           "output: warning: output.interval = %g s is shorter than time.step = %g s: every step "
           "is written\n",
           c.output.interval, h);
  print0(ctx.comm(), "output: %s.xdmf: %s; about %s; energy and sensors at %s\n", name.c_str(),
         schedule.describe().c_str(), human_bytes(motion_bytes).c_str(),
         sample_every_step ? "every step" : "the frames' steps");
  if (motion_bytes > kLargeMotionBytes) {
    // The estimate is linear in the frame count: what fits in kLargeMotionBytes?
    const double fixed = io::estimate_motion_bytes(mb, fields, 0);
    const double per_frame = io::estimate_motion_bytes(mb, fields, 1) - fixed;
    const double fit = std::floor((kLargeMotionBytes - fixed) / per_frame);
    std::string hint = "write fewer frames with output: {every: N} (steps) or output: {interval: "
                       "SECONDS} in case.yaml";
    // every N writes at most steps / N + 2 frames (the first and the last state).
    if (fit >= 3 && steps > 0)
      hint += ", e.g. output: {every: " +
              std::to_string(
                  static_cast<long long>(std::ceil(static_cast<double>(steps) / (fit - 2)))) +
              "} for at most " + human_bytes(kLargeMotionBytes);
    else
      hint += " (each frame alone takes " + human_bytes(per_frame) + ")";
    print0(ctx.comm(), "output: warning: motion.h5 will take about %s (%lld frames of %s); %s\n",
           human_bytes(motion_bytes).c_str(), frames, human_bytes(per_frame).c_str(), hint.c_str());
  }
  io::MotionWriter writer(mb, dir, name);
  if (design) {
    // The design's densities on its body (the caller applied x), in every frame: threshold
    // physical_density at 0.5.
    const optimize::DesignField &f = design->field();
    for (const auto &[field, v] :
         {std::pair{"density", f.density()}, {"physical_density", f.physical()}}) {
      const PetscScalar *a;
      FX_PETSC(VecGetArrayRead(v, &a));
      writer.constant_cell_scalar(design->design_body(), field, a);
      FX_PETSC(VecRestoreArrayRead(v, &a));
    }
  }

  std::vector<double> out_t, frame_t, energy;
  std::vector<std::vector<bodies::Vec3>> sensor_values(scene.sensors.size());
  double max_violation = 0;
  dynamics::Vector all;
  // Largest residual of every row (the violation monitor) and of the rows left out as
  // redundant, with that row.
  struct Residuals {
    double unenforced = 0;
    int row = -1;
  };
  auto monitor = [&]() {
    const dynamics::State &st = run->mechanism_state();
    mech.all_constraint_values(st.q, st.t, all);
    Residuals out;
    max_violation = std::max(max_violation, run->tie_violation());
    for (int r = 0; r < all.size(); ++r) {
      const double v = std::abs(all(r));
      max_violation = std::max(max_violation, v);
      if (!mech.enforced(r) && v >= out.unenforced) out.unenforced = v, out.row = r;
    }
    return out;
  };
  auto sample = [&](double t) {
    out_t.push_back(t);
    energy.push_back(run->energy());
    for (std::size_t k = 0; k < scene.sensors.size(); ++k)
      sensor_values[k].push_back(run->sensor(scene.sensors[k]));
  };
  auto frame = [&](double t) {
    frame_t.push_back(t);
    writer.begin_step(t);
    std::vector<double> elastic;
    for (std::size_t b = 0; b < c.scene.bodies.size(); ++b) {
      const auto x = run->positions(b, elastic);
      writer.positions(b, x.data());
      if (!elastic.empty()) writer.node_vector(b, "elastic_displacement", elastic.data());
    }
  };
  long long newton_total = 0, factorizations_total = 0;
  // -fx_newton_monitor: each step's Newton iterations, factorizations and increments.
  PetscBool newton_monitor = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_newton_monitor", &newton_monitor, nullptr));
  int newton_max = 0, halvings_max = 0;
  // The time steps are their own -log_view stage (the set-up, meshing and initial state apart).
  // (registered once: optimize integrates its first and its last design)
  static PetscLogStage stage = -1;
  if (stage < 0) FX_PETSC(PetscLogStageRegister("Time steps", &stage));
  FX_PETSC(PetscLogStagePush(stage));
  const double t_start = wall_time();
  double last_print = t_start, t_end = t_start;
  double t_now = 0;
  // After main step n + 1 (the backend holds its state): the checks, the figures, the output.
  auto after_step = [&](long long n, const dynamics::StepInfo &info) {
    t_now = static_cast<double>(n + 1) * h;
    // Rows left out as redundant must stay satisfied: if one does not, it was only dependent
    // in the initial configuration (a singular position such as a dead point), not
    // structurally, and the mechanism is not what the case describes.
    const Residuals res = monitor();
    if (res.unenforced > kRedundantDriftTolerance * scene.length_scale)
      throw Error("integrate: at t = " + std::to_string(t_now) + " s (step " +
                      std::to_string(n + 1) + ") the constraint " + mech.describe_row(res.row) +
                      ", left out as redundant at t = 0, is violated by " +
                      std::to_string(res.unenforced) +
                      ": the initial placement is a singular configuration of the mechanism (a "
                      "dead point or aligned links), not a structural redundancy. Place the "
                      "bodies away from it.",
                  true);
    if (newton_monitor) {
      std::ostringstream line;
      line << "  step " << n + 1 << ": " << info.iterations << " Newton, " << info.factorizations
           << " factorizations; increments";
      for (double v : info.increment) line << ' ' << v;
      line << "; constraint residuals";
      for (double v : info.violation) line << ' ' << v;
      print0(ctx.comm(), "%s\n", line.str().c_str());
    }
    newton_total += info.iterations;
    factorizations_total += info.factorizations;
    newton_max = std::max(newton_max, info.iterations);
    halvings_max = std::max(halvings_max, info.halvings);
    // Frames and samples are full steps n h: a step that Newton halved is written once, at
    // its end.
    const bool is_frame = schedule.is_frame(n + 1);
    if (sample_every_step || is_frame) sample(t_now);
    if (is_frame) frame(t_now);
    const double now = wall_time();
    t_end = now;
    if (now - last_print > 2.0 || n + 1 == steps) {
      const double rate = static_cast<double>(n + 1) / std::max(now - t_start, 1e-9);
      print0(ctx.comm(),
             "  t = %-10.6g step %lld/%lld  Newton %.2f/step  %.0f steps/s  ETA %.1f s\n", t_now,
             n + 1, steps, static_cast<double>(newton_total) / static_cast<double>(n + 1), rate,
             static_cast<double>(steps - n - 1) / rate);
      last_print = now;
    }
  };
  if (design) {
    // The design's forward run (and, with --gradient, its backward sweep) is the integration:
    // the output follows its states, so the design is integrated once.
    design->set_observer([&](long long j, const dynamics::StepInfo &info,
                             const dynamics::State *dense, const dynamics::DistState *dist) {
      run->set_state(dense, dist, static_cast<double>(j) * h);
      if (j == 0) {
        monitor();
        sample(0.0);
        frame(0.0);
      } else {
        after_step(j - 1, info);
      }
    });
    optimize::Evaluation e;
    design->evaluate(x, gradient, e);
    design->set_observer(nullptr);
    io::Json responses = io::Json::object();
    const auto &names = design->response_names();
    for (std::size_t i = 0; i < names.size(); ++i) {
      const double v = e.value(i);
      const std::string key = i == 0 ? "objective" : "constraint" + std::to_string(i - 1);
      responses[key] = v;
      print0(ctx.comm(), "response %-12s %-28s %.10g\n", key.c_str(), names[i].c_str(), v);
    }
    s["responses"] = responses;
    io::Json rn = io::Json::array();
    for (const auto &n : names) rn.push_back(n);
    s["response_names"] = rn;
    if (gradient) {
      const std::string file = detail::write_gradients(*design, e, dir);
      io::Json a = io::Json::object();
      design->describe(a);
      s["adjoint"] = a;
      print0(ctx.comm(), "gradient: forward run %.3f s, backward sweep %.3f s; wrote %s\n",
             design->forward_seconds(), design->adjoint_seconds(), file.c_str());
    }
  } else {
    run->run([&](const dynamics::StepView &v) {
      if (v.step == 0) {
        monitor();
        sample(0.0);
        frame(0.0);
      } else {
        after_step(v.step - 1, v.info);
      }
    });
  }
  const double t_int = t_end - t_start; // the forward run (a design's backward sweep apart)
  FX_PETSC(PetscLogStagePop());
  const std::string xdmf = writer.close();
  // The files' sizes as the file system reports them (-1 if it cannot).
  std::error_code h5_error, xdmf_error;
  const auto h5_bytes =
      std::filesystem::file_size(std::filesystem::path(dir) / (name + ".h5"), h5_error);
  const auto xdmf_bytes = std::filesystem::file_size(xdmf, xdmf_error);
  const long long motion_file_bytes =
      h5_error || xdmf_error ? -1LL : static_cast<long long>(h5_bytes + xdmf_bytes);

  s["coordinates"] = mech.coordinates();
  s["constraint_rows"] = mech.constraints();
  s["steps"] = steps;
  s["time_step"] = h;
  s["t_end"] = static_cast<double>(steps) * h;
  s["rho_inf"] = par.rho_inf;
  s["output_times"] = io::Json(out_t); // the samples of energy and of the sensors
  io::Json motion = io::Json::object();
  motion["frames"] = static_cast<long long>(frame_t.size());
  motion["rule"] = c.output.every > 0 ? "every" : c.output.interval > 0 ? "interval" : "default";
  if (c.output.interval > 0) motion["interval"] = c.output.interval;
  if (schedule.stride() > 0) motion["every"] = schedule.stride();
  motion["times"] = io::Json(frame_t);
  motion["estimated_bytes"] = motion_bytes;
  motion["bytes"] = motion_file_bytes;
  s["motion"] = motion;
  s["energy"] = io::Json(energy);
  s["constraint_violation_max"] = max_violation;
  s["newton_iterations_total"] = newton_total;
  s["newton_iterations_max"] = newton_max;
  s["newton_factorizations_total"] = factorizations_total;
  s["newton_reuse"] = newton.reuse_contraction;
  s["step_halvings_max"] = halvings_max;
  s["integration_s"] = t_int;
  s["steps_per_second"] = static_cast<double>(steps) / std::max(t_int, 1e-9);
  io::Json sensors = io::Json::object();
  for (std::size_t k = 0; k < scene.sensors.size(); ++k) {
    io::Json one = io::Json::object();
    one["quantity"] = dynamics::quantity_name(scene.sensors[k].quantity);
    one["t"] = io::Json(out_t);
    io::Json vals = io::Json::array();
    for (const auto &v : sensor_values[k]) vals.push_back(vec3_json(v));
    one["value"] = vals;
    sensors[scene.sensors[k].name] = one;
  }
  s["sensors"] = sensors;
  io::Json bl = io::Json::array();
  for (std::size_t k = 0; k < c.scene.bodies.size(); ++k) {
    const dynamics::SceneBody &sb = scene.bodies[k];
    io::Json j = io::Json::object();
    j["name"] = c.scene.bodies[k].name;
    io::Json unused = io::Json::array();
    for (const std::string &key : io::unused_settings(c.scene.bodies[k])) unused.push_back(key);
    j["unused_settings"] = unused;
    if (sb.acf >= 0) {
      j["model"] = "acf";
      j["mass"] = scene.acf[static_cast<std::size_t>(sb.acf)]->total_mass();
      j["dofs"] = 3LL * scene.meshes[k].global_nodes;
      j["elements"] = static_cast<long long>(scene.meshes[k].global_elements);
      bl.push_back(j);
      continue;
    }
    const auto &b = mech.bodies[static_cast<std::size_t>(sb.mechanism)];
    j["model"] = b->model();
    j["mass"] = b->mass();
    if (const auto *rigid = dynamic_cast<const bodies::RigidBody *>(b.get())) {
      j["center"] = vec3_json(rigid->center_of_mass());
      j["inertia"] =
          io::Json(std::vector<double>(rigid->inertia().data(), rigid->inertia().data() + 9));
    } else {
      j["frame_origin"] = vec3_json(b->origin());
      j["elastic_coordinates"] = b->elastic_coordinates();
      j["dofs"] = 3LL * scene.meshes[k].global_nodes;
      j["elements"] = static_cast<long long>(scene.meshes[k].global_elements);
      j["reduction_s"] = scene.reduction_seconds[k];
    }
    bl.push_back(j);
  }
  s["bodies"] = bl;
  print0(ctx.comm(),
         "integrate: %lld steps in %.3f s (%.0f steps/s), %lld Newton iterations (max %d per "
         "step) on %lld factorized matrices, max constraint violation %.3e, energy %.9g -> "
         "%.9g\n",
         steps, t_int, static_cast<double>(steps) / std::max(t_int, 1e-9), newton_total, newton_max,
         factorizations_total, max_violation, energy.front(), energy.back());
  print0(ctx.comm(), "wrote %s (%zu frames, %s; open in ParaView and press play)\n", xdmf.c_str(),
         frame_t.size(), human_bytes(static_cast<double>(motion_file_bytes)).c_str());
}

} // namespace

int run_dynamic(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const std::string dir = detail::output_directory(ctx, o);
  io::Json s = detail::base_summary(ctx, o, c);
  s["analysis"] = "dynamic";
  print0(ctx.comm(), "case %s (%s), analysis: dynamic, %d rank(s)\n", c.name.c_str(),
         c.file.c_str(), ctx.size());
  // A body may carry the settings of every model; say which ones its model leaves unused.
  for (const dynamics::BodyDescription &b : c.scene.bodies) {
    const std::string note = io::unused_settings_note(b);
    if (!note.empty()) print0(ctx.comm(), "note: %s\n", note.c_str());
  }
  // With a design: the design body's densities (design.initial or --design FILE), every
  // response, and with --gradient their adjoint gradients (docs/theory.md section 9); the
  // motion below is that of this design.
  std::unique_ptr<adjoint::DynamicProblem> design;
  Vec x = nullptr; // the design's variables
  dynamics::Scene built;
  if (c.design) {
    design = adjoint::DynamicProblem::create(ctx.comm(), io::dynamic_settings(c), dir);
    x = design->create_design_vector();
    if (o.design.empty()) {
      design->initial_design(x);
    } else {
      detail::load_design(ctx.comm(), c, *design, o.design, x);
      print0(ctx.comm(), "design: the densities of %s\n", o.design.c_str());
    }
    design->apply_design(x); // the scene below is that of this design
  } else {
    built = dynamics::build_scene(ctx.comm(), c.scene);
  }
  integrate(ctx, c, design ? design->scene() : built, design.get(), x, o.gradient, dir, "motion",
            s);
  if (x) FX_PETSC(VecDestroy(&x));
  detail::write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s/summary.json\n", dir.c_str());
  return 0;
}

void write_design_motions(const Context &ctx, const io::Case &c, adjoint::DynamicProblem &problem,
                          const std::string &dir, io::Json &s) {
  Vec x = problem.create_design_vector();
  const double beta = problem.field().beta();
  for (const char *which : {"initial", "final"}) {
    const std::string name = std::string("motion_") + which;
    if (std::string(which) == "initial") {
      problem.initial_design(x);
      if (!c.design->beta.empty()) problem.field().set_beta(c.design->beta.front());
    } else {
      detail::load_design(ctx.comm(), c, problem,
                          (std::filesystem::path(dir) / "restart.h5").string(), x);
    }
    print0(ctx.comm(), "%s: the mechanism with the %s design moving\n", name.c_str(), which);
    io::Json one = io::Json::object();
    problem.apply_design(x);
    integrate(ctx, c, problem.scene(), &problem, x, false, dir, name, one);
    io::Json brief = io::Json::object();
    for (const char *key : {"responses", "motion", "integration_s", "constraint_violation_max"})
      brief[key] = one[key];
    s[name] = brief;
  }
  problem.field().set_beta(beta);
  FX_PETSC(VecDestroy(&x));
}

} // namespace flexopt::app
