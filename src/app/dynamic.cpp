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
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/grid_layout.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <sstream>

namespace flexopt::app {

namespace {

/// Largest residual, relative to the scene's size, that a row left out as redundant may reach
/// before the run stops (structurally redundant rows stay at round-off, ~1e-15).
constexpr double kRedundantDriftTolerance = 1e-8;

/// Size of motion.h5 above which the run warns before it starts [bytes].
constexpr double kLargeMotionBytes = 1e9;
/// The linear FFRF model's range: an elastic displacement of 5 % of a body's size (a beam's
/// end rotation about 1.5 times that, 0.075 rad: its square, the order of the neglected
/// geometric terms, near the default accuracy 1e-2).
constexpr double kLinearRange = 0.05;

/// True if case body b writes an elastic_displacement field with its positions: an FFRF body
/// with modes, or an ACF body with interfaces (dynamics::Integrator::positions).
bool writes_elastic(const dynamics::Scene &scene, std::size_t b) {
  const dynamics::SceneBody &sb = scene.bodies[b];
  if (sb.acf >= 0) return !sb.nodes.empty();
  return scene.mechanism.size(sb.mechanism) > 7;
}

io::Json vec3_json(const bodies::Vec3 &v) {
  return io::Json(std::vector<double>{v.x(), v.y(), v.z()});
}

/// One integration of a scene with its output (motion file, samples, figures): the set-up
/// prints the mechanism and the start, each main step is checked and sampled, and the run's
/// figures go to the summary.
class MotionRun {
public:
  /// `max_frames` > 0: the motion file takes at most about that many frames (an
  /// optimization's motions; io::FrameSchedule).
  MotionRun(const Context &ctx, const io::Case &c, dynamics::Scene &scene, const std::string &dir,
            const std::string &name, io::Json &s, long long max_frames = 0);
  /// Integrates the scene itself (dynamics::Integrator::run).
  void run();
  /// The design's forward run (and, with `gradient`, its backward sweep) is the integration: the
  /// output follows its states, so the design is integrated once. Its responses (and gradients)
  /// go to the summary.
  void run_design(adjoint::DynamicProblem &design, Vec x, bool gradient);
  /// The run's figures, sensors and bodies into the summary; closes the motion file.
  void finish();

private:
  /// Largest residual of every row (the violation monitor) and of the rows left out as
  /// redundant, with that row.
  struct Residuals {
    double unenforced = 0;
    int row = -1;
  };
  void print_start(const dynamics::StartReport &st);
  /// Frames of motion.xdmf (io::FrameSchedule), the size estimate and its warnings.
  void plan_output();
  Residuals monitor();
  void sample(double t);
  /// Writes the frame at time t: positions, elastic displacements and, on flexible bodies,
  /// the element von Mises stress.
  void frame(double t);
  /// An FFRF or ACF body: it has stress.
  bool flexible(std::size_t b) const {
    return scene_.bodies[b].acf >= 0 || scene_.bodies[b].reduction != nullptr;
  }
  /// After main step n + 1 (the integrator holds its state): the checks, the figures, the
  /// output.
  void after_step(long long n, const dynamics::StepInfo &info);
  void observe(long long j, const dynamics::StepInfo &info);
  io::Json bodies_json() const;
  /// The FFRF bodies' largest elastic displacement over the frames against the linear model's
  /// range (kLinearRange of the body's size; docs/theory.md section 7.7): a warning in the log
  /// and in summary.json.
  void check_linear_range();

  const Context &ctx_;
  const io::Case &c_;
  dynamics::Scene &scene_;
  const dynamics::Mechanism &mech_;
  const std::string dir_, name_;
  io::Json &s_;
  const long long max_frames_;
  const dynamics::IntegratorSettings settings_;
  std::unique_ptr<dynamics::Integrator> run_;
  std::unique_ptr<io::FrameSchedule> schedule_;
  std::unique_ptr<io::MotionWriter> writer_;
  bool sample_every_step_ = true;
  double motion_bytes_ = 0;
  std::vector<double> out_t_, frame_t_, energy_;
  std::vector<std::vector<bodies::Vec3>> sensor_values_;
  std::vector<double> elastic_max_; ///< per body: the largest |elastic displacement| of a node
  /// Per body: the largest element von Mises stress over the frames (flexible bodies).
  std::vector<double> von_mises_max_;
  /// A design's body and its stress relaxation factors eta (run_design): its frames' von Mises
  /// stress is the relaxed one that its stress responses take.
  /// Per case body: the stress relaxation of its densities (a design body's), or empty.
  std::vector<std::vector<double>> relaxation_;
  std::vector<std::string> warnings_; ///< summary.json `warnings`
  double max_violation_ = 0;
  dynamics::Vector all_;
  long long newton_total_ = 0, factorizations_total_ = 0;
  int newton_max_ = 0, halvings_max_ = 0;
  bool newton_monitor_ = false;
  double t_start_ = 0, last_print_ = 0, t_end_ = 0, t_now_ = 0;
};

MotionRun::MotionRun(const Context &ctx, const io::Case &c, dynamics::Scene &scene,
                     const std::string &dir, const std::string &name, io::Json &s,
                     long long max_frames)
    : ctx_(ctx), c_(c), scene_(scene), mech_(scene.mechanism), dir_(dir), name_(name), s_(s),
      max_frames_(max_frames), settings_(dynamics::IntegratorSettings::from(c.time)),
      sensor_values_(scene.sensors.size()) {
  print0(ctx.comm(), "mechanism: %zu bodies, %d coordinates, %d constraint rows enforced of %d\n",
         mech_.bodies.size(), mech_.coordinates(), mech_.constraints(), mech_.all_rows());
  io::Json redundant = io::Json::array();
  for (const auto &r : scene.redundant_rows) {
    print0(ctx.comm(),
           "mechanism: redundant constraint %s is implied by the others and is not enforced "
           "(its residual is monitored)\n",
           r.c_str());
    redundant.push_back(r);
  }
  s["redundant_constraints"] = redundant;
  if (!scene.acf.empty())
    print0(ctx.comm(),
           "mechanism: %zu ACF bodies on the distributed backend (one PETSc system over %d "
           "rank(s); Newton solver: options prefix mech_, MUMPS LU by default, KLU on one "
           "rank up to 2000 unknowns)\n",
           scene.acf.size(), ctx.size());
  run_ = std::make_unique<dynamics::Integrator>(scene, settings_);
  dynamics::StartReport start;
  run_->start(&start);
  print_start(start);
  plan_output();
  // -fx_newton_monitor: each step's Newton iterations, factorizations and increments.
  PetscBool newton_monitor = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_newton_monitor", &newton_monitor, nullptr));
  newton_monitor_ = newton_monitor == PETSC_TRUE;
}

void MotionRun::print_start(const dynamics::StartReport &st) {
  print0(ctx_.comm(),
         "initial velocities: the rigid-body velocities made consistent with the joints and "
         "drivers; kinetic energy %.9g J given -> %.9g J (%+.6g J)\n",
         st.kinetic_given, st.kinetic, st.kinetic - st.kinetic_given);
  if (st.elastic_corrected)
    print0(ctx_.comm(),
           "initial velocities: warning: rigid-body velocities alone cannot satisfy the joints "
           "(residual %.3e): the elastic velocities were corrected too, with the least change "
           "of kinetic energy\n",
           st.rigid_residual);
  s_["initial_kinetic_energy"]["given"] = st.kinetic_given;
  s_["initial_kinetic_energy"]["start"] = st.kinetic;
  s_["initial_kinetic_energy"]["elastic_corrected"] = st.elastic_corrected;
  const dynamics::AlphaParameters &par = settings_.alpha;
  const double h = settings_.step;
  const long long steps = settings_.steps;
  print0(ctx_.comm(),
         "integrate: generalized-alpha rho_inf = %g (alpha_m %.4f, alpha_f %.4f, gamma %.4f, beta "
         "%.4f), %lld steps of %g s to t = %g s; Newton matrix kept while the contraction is <= "
         "%g\n",
         par.rho_inf, par.alpha_m, par.alpha_f, par.gamma, par.beta, steps, h,
         static_cast<double>(steps) * h, settings_.newton.reuse_contraction);
  // rho_inf = 1 is the trapezoidal rule: it damps nothing, and on the index-3 equations of a
  // flexible mechanism the step can grow unstably (cases/slider_crank_start/README.md).
  if (par.rho_inf >= 1)
    for (const auto &b : c_.scene.bodies)
      if (dynamics::simulated_model(b.model) != dynamics::BodyModel::Rigid) {
        print0(ctx_.comm(),
               "time: warning: rho_inf = 1 (no numerical dissipation) with the flexible body "
               "'%s': generalized-alpha on the index-3 equations of a flexible mechanism can grow "
               "unstably at rho_inf = 1 (docs/theory.md 6.4); rho_inf <= 0.99 damps it\n",
               b.name.c_str());
        break;
      }
}

void MotionRun::plan_output() {
  const double h = settings_.step;
  const long long steps = settings_.steps;
  std::vector<io::MotionBody> mb;
  for (std::size_t b = 0; b < c_.scene.bodies.size(); ++b)
    mb.push_back({c_.scene.bodies[b].name, mesh::grid_layout(scene_.meshes[b])});
  // Energy and sensors are small: without output: they keep every step; with it they are
  // sampled at the frames, as the key always did.
  schedule_ = std::make_unique<io::FrameSchedule>(c_.output, steps, h, max_frames_);
  sample_every_step_ = !c_.output.given();
  std::vector<std::vector<std::string>> fields(c_.scene.bodies.size());
  std::vector<std::vector<std::string>> cells(c_.scene.bodies.size());
  for (std::size_t b = 0; b < c_.scene.bodies.size(); ++b) {
    if (writes_elastic(scene_, b)) fields[b] = {"elastic_displacement"};
    if (flexible(b)) cells[b] = {"von_mises"};
  }
  const long long frames = schedule_->frames();
  motion_bytes_ = io::estimate_motion_bytes(mb, fields, frames, cells);
  if (schedule_->interval_below_step())
    print0(ctx_.comm(),
           "output: warning: output.interval = %g s is shorter than time.step = %g s: every step "
           "is written\n",
           c_.output.interval, h);
  print0(ctx_.comm(), "output: %s.xdmf: %s; about %s; energy and sensors at %s\n", name_.c_str(),
         schedule_->describe().c_str(), io::human_bytes(motion_bytes_).c_str(),
         sample_every_step_ ? "every step" : "the frames' steps");
  if (motion_bytes_ > kLargeMotionBytes) {
    // The estimate is linear in the frame count: what fits in kLargeMotionBytes?
    const double fixed = io::estimate_motion_bytes(mb, fields, 0, cells);
    const double per_frame = io::estimate_motion_bytes(mb, fields, 1, cells) - fixed;
    const double fit = std::floor((kLargeMotionBytes - fixed) / per_frame);
    std::string hint = "write fewer frames with output: {every: N} (steps) or output: {interval: "
                       "SECONDS} in case.yaml";
    // every N writes at most steps / N + 2 frames (the first and the last state).
    if (fit >= 3 && steps > 0)
      hint += ", e.g. output: {every: " +
              std::to_string(
                  static_cast<long long>(std::ceil(static_cast<double>(steps) / (fit - 2)))) +
              "} for at most " + io::human_bytes(kLargeMotionBytes);
    else
      hint += " (each frame alone takes " + io::human_bytes(per_frame) + ")";
    print0(ctx_.comm(), "output: warning: motion.h5 will take about %s (%lld frames of %s); %s\n",
           io::human_bytes(motion_bytes_).c_str(), frames, io::human_bytes(per_frame).c_str(),
           hint.c_str());
  }
  writer_ = std::make_unique<io::MotionWriter>(mb, dir_, name_);
}

MotionRun::Residuals MotionRun::monitor() {
  const dynamics::State &st = run_->mechanism_state();
  mech_.all_constraint_values(st.q, st.t, all_);
  Residuals out;
  max_violation_ = std::max(max_violation_, run_->tie_violation());
  for (int r = 0; r < all_.size(); ++r) {
    const double v = std::abs(all_(r));
    max_violation_ = std::max(max_violation_, v);
    if (!mech_.enforced(r) && v >= out.unenforced) out.unenforced = v, out.row = r;
  }
  return out;
}

void MotionRun::sample(double t) {
  out_t_.push_back(t);
  energy_.push_back(run_->energy());
  for (std::size_t k = 0; k < scene_.sensors.size(); ++k)
    sensor_values_[k].push_back(run_->sensor(scene_.sensors[k]));
}

void MotionRun::frame(double t) {
  frame_t_.push_back(t);
  writer_->begin_step(t);
  std::vector<double> elastic;
  elastic_max_.resize(c_.scene.bodies.size(), 0.0);
  von_mises_max_.resize(c_.scene.bodies.size(), 0.0);
  for (std::size_t b = 0; b < c_.scene.bodies.size(); ++b) {
    const auto x = run_->positions(b, elastic);
    writer_->positions(b, x.data());
    if (flexible(b)) {
      std::vector<double> v = run_->von_mises(b, c_.scene.bodies[b].material);
      if (b < relaxation_.size() && !relaxation_[b].empty())
        for (std::size_t e = 0; e < v.size(); ++e) v[e] *= relaxation_[b][e];
      writer_->cell_scalar(b, "von_mises", v.data());
      for (double ve : v) von_mises_max_[b] = std::max(von_mises_max_[b], ve);
    }
    if (elastic.empty()) continue;
    writer_->node_vector(b, "elastic_displacement", elastic.data());
    for (std::size_t k = 0; k + 2 < elastic.size(); k += 3)
      elastic_max_[b] =
          std::max(elastic_max_[b], std::hypot(elastic[k], elastic[k + 1], elastic[k + 2]));
  }
}

void MotionRun::check_linear_range() {
  const std::size_t nb = c_.scene.bodies.size();
  elastic_max_.resize(nb, 0.0);
  MPI_Allreduce(MPI_IN_PLACE, elastic_max_.data(), static_cast<int>(nb), MPI_DOUBLE, MPI_MAX,
                ctx_.comm());
  io::Json largest = io::Json::object();
  for (std::size_t b = 0; b < nb; ++b) {
    if (scene_.bodies[b].acf >= 0 || elastic_max_[b] == 0) continue; // ACF: nonlinear
    const double size = mesh::mesh_extent(scene_.meshes[b]);
    largest[c_.scene.bodies[b].name] = elastic_max_[b];
    if (elastic_max_[b] <= kLinearRange * size) continue;
    char buf[400];
    std::snprintf(
        buf, sizeof buf,
        "body '%s' (ffrf): elastic displacement up to %.3g m, %.0f %% of its size %.3g m, "
        "beyond the linear FFRF model's range (%.0f %%: elastic rotations near 0.1 rad); "
        "its results are not to be trusted: check the placement and the loads, or use "
        "model: acf",
        c_.scene.bodies[b].name.c_str(), elastic_max_[b], 100 * elastic_max_[b] / size, size,
        100 * kLinearRange);
    print0(ctx_.comm(), "integrate: warning: %s\n", buf);
    warnings_.emplace_back(buf);
  }
  s_["elastic_displacement_max"] = largest; // FFRF bodies, over the frames
}

void MotionRun::after_step(long long n, const dynamics::StepInfo &info) {
  const double h = settings_.step;
  const long long steps = settings_.steps;
  t_now_ = static_cast<double>(n + 1) * h;
  // Rows left out as redundant must stay satisfied: if one does not, it was only dependent
  // in the initial configuration (a singular position such as a dead point), not
  // structurally, and the mechanism is not what the case describes.
  const Residuals res = monitor();
  if (res.unenforced > kRedundantDriftTolerance * scene_.length_scale)
    throw Error("integrate: at t = " + std::to_string(t_now_) + " s (step " +
                    std::to_string(n + 1) + ") the constraint " + mech_.describe_row(res.row) +
                    ", left out as redundant at t = 0, is violated by " +
                    std::to_string(res.unenforced) +
                    ": the initial placement is a singular configuration of the mechanism (a "
                    "dead point or aligned links), not a structural redundancy. Place the "
                    "bodies away from it.",
                true);
  if (newton_monitor_) {
    std::ostringstream line;
    line << "  step " << n + 1 << ": " << info.iterations << " Newton, " << info.factorizations
         << " factorizations; increments";
    for (double v : info.increment) line << ' ' << v;
    line << "; constraint residuals";
    for (double v : info.violation) line << ' ' << v;
    print0(ctx_.comm(), "%s\n", line.str().c_str());
  }
  newton_total_ += info.iterations;
  factorizations_total_ += info.factorizations;
  newton_max_ = std::max(newton_max_, info.iterations);
  halvings_max_ = std::max(halvings_max_, info.halvings);
  // Frames and samples are full steps n h: a step that Newton halved is written once, at
  // its end.
  const bool is_frame = schedule_->is_frame(n + 1);
  if (sample_every_step_ || is_frame) sample(t_now_);
  if (is_frame) frame(t_now_);
  const double now = wall_time();
  t_end_ = now;
  if (now - last_print_ > 2.0 || n + 1 == steps) {
    const double rate = static_cast<double>(n + 1) / std::max(now - t_start_, 1e-9);
    print0(ctx_.comm(),
           "  t = %-10.6g step %lld/%lld  Newton %.2f/step  %.0f steps/s  ETA %.1f s\n", t_now_,
           n + 1, steps, static_cast<double>(newton_total_) / static_cast<double>(n + 1), rate,
           static_cast<double>(steps - n - 1) / rate);
    last_print_ = now;
  }
}

void MotionRun::observe(long long j, const dynamics::StepInfo &info) {
  if (j == 0) {
    monitor();
    sample(0.0);
    frame(0.0);
  } else {
    after_step(j - 1, info);
  }
}

/// The time steps are their own -log_view stage (the set-up, meshing and initial state apart),
/// registered once: optimize integrates its first and its last design.
PetscLogStage time_steps_stage() {
  static PetscLogStage stage = -1;
  if (stage < 0) FX_PETSC(PetscLogStageRegister("Time steps", &stage));
  return stage;
}

void MotionRun::run() {
  FX_PETSC(PetscLogStagePush(time_steps_stage()));
  t_start_ = last_print_ = t_end_ = wall_time();
  run_->run([&](const dynamics::StepView &v) { observe(v.step, v.info); });
  FX_PETSC(PetscLogStagePop());
}

void MotionRun::run_design(adjoint::DynamicProblem &design, Vec x, bool gradient) {
  // Each design body's densities (the caller applied x), in every frame; every other body is
  // solid (1), so that thresholding physical_density at 0.5 keeps the whole mechanism.
  relaxation_.assign(writer_->bodies(), {});
  std::vector<char> designed(writer_->bodies(), 0);
  for (const adjoint::DesignBody &db : design.design_bodies()) {
    const auto b = static_cast<std::size_t>(db.body);
    const optimize::DesignField &f = *db.field;
    std::vector<double> deta;
    f.stress_factors(relaxation_[b], deta);
    designed[b] = 1;
    for (const auto &[field, v] :
         {std::pair{"density", f.density()}, {"physical_density", f.physical()}}) {
      const PetscScalar *a;
      FX_PETSC(VecGetArrayRead(v, &a));
      writer_->constant_cell_scalar(b, field, a);
      FX_PETSC(VecRestoreArrayRead(v, &a));
    }
  }
  for (const char *field : {"density", "physical_density"})
    for (std::size_t b = 0; b < writer_->bodies(); ++b)
      if (!designed[b]) writer_->constant_cell_value(b, field, 1.0);
  FX_PETSC(PetscLogStagePush(time_steps_stage()));
  t_start_ = last_print_ = t_end_ = wall_time();
  const double h = settings_.step;
  design.set_observer([&](long long j, const dynamics::StepInfo &info, const dynamics::State *dense,
                          const dynamics::DistState *dist) {
    run_->set_state(dense, dist, static_cast<double>(j) * h);
    observe(j, info);
  });
  optimize::Evaluation e;
  design.evaluate(x, gradient, e);
  design.set_observer(nullptr);
  io::Json responses = io::Json::object();
  const auto &names = design.response_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    const double v = e.value(i);
    const std::string key = i == 0 ? "objective" : "constraint" + std::to_string(i - 1);
    responses[key] = v;
    print0(ctx_.comm(), "response %-12s %-28s %.10g\n", key.c_str(), names[i].c_str(), v);
  }
  s_["responses"] = responses;
  const io::Json stress = design.stress_json();
  if (!stress.is_null()) s_["stress"] = stress;
  for (const adjoint::DynamicProblem::StressSummary &st : design.stress_summaries())
    print0(ctx_.comm(),
           "response %-12s stress of body %s: peak %.6g Pa at element %lld, t = %.6g s\n",
           st.key.c_str(), st.body.c_str(), st.peak, st.element, st.time);
  io::Json rn = io::Json::array();
  for (const auto &n : names) rn.push_back(n);
  s_["response_names"] = rn;
  if (gradient) {
    for (const std::string &w : optimize::stuck_responses(design, e)) {
      print0(ctx_.comm(), "gradient: warning: %s\n", w.c_str());
      warnings_.push_back(w);
    }
    const std::string file = detail::write_gradients(design, e, dir_);
    io::Json a = io::Json::object();
    design.describe(a);
    s_["adjoint"] = a;
    print0(ctx_.comm(), "gradient: forward run %.3f s, backward sweep %.3f s; wrote %s\n",
           design.forward_seconds(), design.adjoint_seconds(), file.c_str());
  }
  FX_PETSC(PetscLogStagePop());
}

io::Json MotionRun::bodies_json() const {
  io::Json bl = io::Json::array();
  for (std::size_t k = 0; k < c_.scene.bodies.size(); ++k) {
    const dynamics::SceneBody &sb = scene_.bodies[k];
    io::Json j = io::Json::object();
    j["name"] = c_.scene.bodies[k].name;
    io::Json unused = io::Json::array();
    for (const std::string &key : io::unused_settings(c_.scene.bodies[k])) unused.push_back(key);
    j["unused_settings"] = unused;
    if (sb.acf >= 0) {
      j["model"] = "acf";
      j["mass"] = scene_.acf[static_cast<std::size_t>(sb.acf)]->total_mass();
      j["dofs"] = 3LL * scene_.meshes[k].global_nodes;
      j["elements"] = static_cast<long long>(scene_.meshes[k].global_elements);
      bl.push_back(j);
      continue;
    }
    const auto &b = mech_.bodies[static_cast<std::size_t>(sb.mechanism)];
    j["model"] = b->model();
    j["mass"] = b->mass();
    if (const auto *rigid = dynamic_cast<const bodies::RigidBody *>(b.get())) {
      j["center"] = vec3_json(rigid->center_of_mass());
      j["inertia"] =
          io::Json(std::vector<double>(rigid->inertia().data(), rigid->inertia().data() + 9));
    } else {
      j["frame_origin"] = vec3_json(b->origin());
      j["elastic_coordinates"] = b->elastic_coordinates();
      j["dofs"] = 3LL * scene_.meshes[k].global_nodes;
      j["elements"] = static_cast<long long>(scene_.meshes[k].global_elements);
      j["reduction_s"] = scene_.reduction_seconds[k];
    }
    bl.push_back(j);
  }
  return bl;
}

void MotionRun::finish() {
  const double h = settings_.step;
  const long long steps = settings_.steps;
  const double t_int = t_end_ - t_start_; // the forward run (a design's backward sweep apart)
  const std::string xdmf = writer_->close();
  // The files' sizes as the file system reports them (-1 if it cannot).
  std::error_code h5_error, xdmf_error;
  const auto h5_bytes =
      std::filesystem::file_size(std::filesystem::path(dir_) / (name_ + ".h5"), h5_error);
  const auto xdmf_bytes = std::filesystem::file_size(xdmf, xdmf_error);
  const long long motion_file_bytes =
      h5_error || xdmf_error ? -1LL : static_cast<long long>(h5_bytes + xdmf_bytes);
  s_["coordinates"] = mech_.coordinates();
  s_["constraint_rows"] = mech_.constraints();
  s_["steps"] = steps;
  s_["time_step"] = h;
  s_["t_end"] = static_cast<double>(steps) * h;
  s_["rho_inf"] = settings_.alpha.rho_inf;
  s_["output_times"] = io::Json(out_t_); // the samples of energy and of the sensors
  io::Json motion = io::Json::object();
  motion["frames"] = static_cast<long long>(frame_t_.size());
  motion["rule"] = c_.output.every > 0 ? "every" : c_.output.interval > 0 ? "interval" : "default";
  if (c_.output.interval > 0) motion["interval"] = c_.output.interval;
  if (schedule_->stride() > 0) motion["every"] = schedule_->stride();
  motion["times"] = io::Json(frame_t_);
  motion["estimated_bytes"] = motion_bytes_;
  motion["bytes"] = motion_file_bytes;
  s_["motion"] = motion;
  s_["energy"] = io::Json(energy_);
  s_["constraint_violation_max"] = max_violation_;
  s_["newton_iterations_total"] = newton_total_;
  s_["newton_iterations_max"] = newton_max_;
  s_["newton_factorizations_total"] = factorizations_total_;
  s_["newton_reuse"] = settings_.newton.reuse_contraction;
  s_["step_halvings_max"] = halvings_max_;
  s_["integration_s"] = t_int;
  s_["steps_per_second"] = static_cast<double>(steps) / std::max(t_int, 1e-9);
  io::Json sensors = io::Json::object();
  for (std::size_t k = 0; k < scene_.sensors.size(); ++k) {
    io::Json one = io::Json::object();
    one["quantity"] = dynamics::quantity_name(scene_.sensors[k].quantity);
    one["t"] = io::Json(out_t_);
    io::Json vals = io::Json::array();
    for (const auto &v : sensor_values_[k]) vals.push_back(vec3_json(v));
    one["value"] = vals;
    sensors[scene_.sensors[k].name] = one;
  }
  s_["sensors"] = sensors;
  s_["bodies"] = bodies_json();
  von_mises_max_.resize(c_.scene.bodies.size(), 0.0);
  MPI_Allreduce(MPI_IN_PLACE, von_mises_max_.data(), static_cast<int>(von_mises_max_.size()),
                MPI_DOUBLE, MPI_MAX, ctx_.comm());
  io::Json vm = io::Json::object();
  for (std::size_t b = 0; b < von_mises_max_.size(); ++b)
    if (flexible(b)) vm[c_.scene.bodies[b].name] = von_mises_max_[b];
  s_["von_mises_max"] = vm; // flexible bodies, over the frames (the design body's relaxed)
  check_linear_range();
  if (!warnings_.empty()) {
    io::Json w = io::Json::array();
    for (const std::string &line : warnings_) w.push_back(line);
    s_["warnings"] = w;
  }
  print0(ctx_.comm(),
         "integrate: %lld steps in %.3f s (%.0f steps/s), %lld Newton iterations (max %d per "
         "step) on %lld factorized matrices, max constraint violation %.3e, energy %.9g -> "
         "%.9g\n",
         steps, t_int, static_cast<double>(steps) / std::max(t_int, 1e-9), newton_total_,
         newton_max_, factorizations_total_, max_violation_, energy_.front(), energy_.back());
  print0(ctx_.comm(), "wrote %s (%zu frames, %s; open in ParaView and press play)\n", xdmf.c_str(),
         frame_t_.size(), io::human_bytes(static_cast<double>(motion_file_bytes)).c_str());
}

/// Integrates `scene` (with `design`: the scene of that problem at the design x, through its
/// forward run, and with `gradient` its adjoint gradients too), writes dir/NAME.xdmf (+ .h5)
/// and the run's figures into s. Collective.
void integrate(const Context &ctx, const io::Case &c, dynamics::Scene &scene,
               adjoint::DynamicProblem *design, Vec x, bool gradient, const std::string &dir,
               const std::string &name, io::Json &s, long long max_frames = 0) {
  MotionRun run(ctx, c, scene, dir, name, s, max_frames);
  if (design)
    run.run_design(*design, x, gradient);
  else
    run.run();
  run.finish();
}

} // namespace

namespace {

/// simulate of one scene (a case, or one scenario's case): with a design, the design's
/// responses (and with --gradient their gradients) through its forward run; dir/NAME.xdmf and
/// the run's figures into s. Collective.
void simulate_case(const Context &ctx, const Options &o, const io::Case &c, const std::string &dir,
                   const std::string &name, io::Json &s) {
  // With a design: the design body's densities (design.initial or --design FILE), every
  // response, and with --gradient their adjoint gradients (docs/theory.md section 9); the
  // motion below is that of this design.
  std::unique_ptr<adjoint::DynamicProblem> design;
  Vec x = nullptr; // the design's variables
  dynamics::Scene built;
  if (!c.design.empty()) {
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
  integrate(ctx, c, design ? design->scene() : built, design.get(), x, o.gradient, dir, name, s);
  if (x) FX_PETSC(VecDestroy(&x));
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
  if (c.scenarios.empty()) {
    simulate_case(ctx, o, c, dir, "motion", s);
  } else {
    // Every scenario, one after another on all ranks: motion.NAME.xdmf, its figures under
    // summary.json's scenarios.NAME.
    s["scenarios"] = detail::each_condition(
        ctx, c, [&](const io::Case &one, const std::string &name, io::Json &figures) {
          simulate_case(ctx, o, one, dir, "motion." + name, figures);
        });
  }
  detail::write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s/summary.json\n", dir.c_str());
  after_run(ctx, o, c, dir);
  return 0;
}

void write_scenario_motions(const Context &ctx, const io::Case &c, const std::string &dir,
                            io::Json &s) {
  s["scenario_motions"] = detail::each_condition(
      ctx, c, [&](const io::Case &one, const std::string &name, io::Json &figures) {
        auto problem = adjoint::DynamicProblem::create(ctx.comm(), io::dynamic_settings(one), dir);
        write_design_motions(ctx, one, *problem, dir, figures, "." + name);
      });
}

void write_design_motions(const Context &ctx, const io::Case &c, adjoint::DynamicProblem &problem,
                          const std::string &dir, io::Json &s, const std::string &suffix) {
  Vec x = problem.create_design_vector();
  const std::vector<double> betas = problem.design().betas();
  for (const char *which : {"initial", "final"}) {
    const std::string key = std::string("motion_") + which, name = key + suffix;
    if (std::string(which) == "initial") {
      problem.initial_design(x);
      if (problem.design().stages() > 0) problem.design().set_stage(0);
    } else {
      detail::load_design(ctx.comm(), c, problem,
                          (std::filesystem::path(dir) / "restart.h5").string(), x);
    }
    print0(ctx.comm(), "%s: the mechanism with the %s design moving\n", name.c_str(), which);
    io::Json one = io::Json::object();
    problem.apply_design(x);
    integrate(ctx, c, problem.scene(), &problem, x, false, dir, name, one,
              io::FrameSchedule::kOptimizationFrames);
    io::Json brief = io::Json::object();
    for (const char *key :
         {"responses", "motion", "integration_s", "constraint_violation_max", "sensors"})
      brief[key] = one[key];
    s[key] = brief;
  }
  problem.design().set_betas(betas);
  FX_PETSC(VecDestroy(&x));
}

} // namespace flexopt::app
