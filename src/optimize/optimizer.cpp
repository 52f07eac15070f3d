#include "flexopt/optimize/optimizer.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/vec_values.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/io/restart.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/grid_layout.hpp"
#include "flexopt/optimize/design_file.hpp"
#include "flexopt/optimize/mma.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

namespace flexopt::optimize {

namespace {

/// An interrupted run's design.h5.tmp, set aside by `optimize --restart` while its frames are
/// carried over into the new design.h5.
constexpr const char *kInterruptedDesign = "design.interrupted.h5";

/// Writes the densities of the current evaluation, and the problem's other cell fields (a stress
/// response's von Mises stress), as one step of the design collection.
void write_densities(io::XdmfWriter &writer, const DesignProblem &problem, double step) {
  const Design &d = problem.design();
  writer.begin_step(step);
  writer.cell_scalar("density", d.cells(&DesignField::density).data());
  writer.cell_scalar("filtered_density", d.cells(&DesignField::filtered).data());
  writer.cell_scalar("physical_density", d.cells(&DesignField::physical).data());
  for (const auto &[name, values] : problem.cell_fields()) writer.cell_scalar(name, values.data());
}

/// The outer move-limit box: xmin_j = max(0, x_j - move), xmax_j = min(1, x_j + move).
void set_move_box(Vec x, double move, Vec xmin, Vec xmax) {
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(x, &n));
  const PetscScalar *xa;
  PetscScalar *lo, *hi;
  FX_PETSC(VecGetArrayRead(x, &xa));
  FX_PETSC(VecGetArray(xmin, &lo));
  FX_PETSC(VecGetArray(xmax, &hi));
  for (PetscInt j = 0; j < n; ++j) {
    lo[j] = std::max(0.0, xa[j] - move);
    hi[j] = std::min(1.0, xa[j] + move);
  }
  FX_PETSC(VecRestoreArray(xmax, &hi));
  FX_PETSC(VecRestoreArray(xmin, &lo));
  FX_PETSC(VecRestoreArrayRead(x, &xa));
}

/// Appends one line of history.csv: iteration, objective, constraints, max change, seconds and
/// the split of the seconds (docs/theory.md section 11: the columns of the iteration line).
void append_history_row(std::ostringstream &history, int k, double objective,
                        const double *constraints, std::size_t m, double change, double seconds,
                        const double *split, std::size_t nsplit,
                        const std::vector<double> &volume_fractions) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%d,%.17g", k, objective);
  history << buf;
  for (std::size_t i = 0; i < m; ++i) {
    std::snprintf(buf, sizeof buf, ",%.17g", constraints[i]);
    history << buf;
  }
  std::snprintf(buf, sizeof buf, ",%.17g,%.6g", change, seconds);
  history << buf;
  for (std::size_t p = 0; p < nsplit; ++p) {
    std::snprintf(buf, sizeof buf, ",%.6g", split[p]);
    history << buf;
  }
  for (double v : volume_fractions) {
    std::snprintf(buf, sizeof buf, ",%.17g", v);
    history << buf;
  }
  history << '\n';
}

/// One run of the optimization loop of docs/theory.md section 11: the design vectors, MMA with
/// its move-limit box (docs/theory-mma.md §5), the scaling, the projection continuation, the
/// history and the restart file.
class OptimizationRun {
public:
  /// With `restart`, the interrupted run's design.h5.tmp is set aside before design.h5.tmp is
  /// created anew, for read_restart to carry its frames over.
  OptimizationRun(MPI_Comm comm, DesignProblem &design, const OptimizerSettings &c,
                  const std::string &out_dir, bool restart);
  OptimizationRun(const OptimizationRun &) = delete;
  OptimizationRun &operator=(const OptimizationRun &) = delete;

  /// Continues after the iterations stored in restart.h5 (docs/theory-mma.md §7).
  void read_restart();
  /// x = settings.start, or the design field's initial design.
  void first_design(Vec x) const;
  void check_restart_contents(const io::RestartData &r) const;
  /// Runs the iterations up to the limit or the stop rule.
  void iterate();
  /// The final evaluation, design.xdmf's last step and history.csv; the result. Destroys the
  /// design vectors (an exception before leaves them to the end of the run).
  OptimizationResult finish();

private:
  void plan_design_output(const io::GridLayout &layout);
  void write_history_header();
  void print_header() const;
  void restore_history(const io::RestartData &r, int done);
  void carry_design_frames(int done);
  bool iteration(int k, Evaluation &e);
  std::vector<double> scaled_constraints(const Evaluation &e);
  /// Reports (log and summary.json warnings) every constraint that the final design `e`
  /// exceeds by more than kInfeasible.
  void report_infeasible(const Evaluation &e);
  std::vector<double> iteration_split(double seconds) const;
  void record(int k, const Evaluation &e, double change, double seconds,
              const std::vector<double> &split);
  bool advance_continuation(int k, double change);
  void write_restart_point(int k, double change, bool &last_stage);

  MPI_Comm comm_;
  DesignProblem *problem_;
  const OptimizerSettings &c_;
  const std::string out_dir_;
  const std::size_t m_;
  OptimizationResult result_;
  Vec x_ = nullptr, xold_ = nullptr, xmin_ = nullptr, xmax_ = nullptr, df0_ = nullptr;
  std::vector<Vec> dg_;
  std::unique_ptr<Mma> mma_;
  double objective_scale_ = 1.0;
  std::optional<io::XdmfWriter> writer_; ///< design.xdmf, opened after the vectors
  std::ostringstream history_;
  std::vector<std::string> split_labels_;
  std::size_t nsplit_ = 0;
  std::string restart_path_;
  std::map<std::string, std::string> fingerprint_; ///< of the design, in every restart point
  std::vector<std::uint64_t> tags_;
  std::vector<std::uint64_t> state_keys_; ///< of the solvers' state, once it is first written
  int first_ = 1;
  // Projection continuation (Design::stages): the stage and its first iteration.
  const int stages_;
  int stage_ = 0, stage_start_ = 1;
  /// With several design bodies: each body's volume fraction per iteration (k x bodies).
  std::size_t bodies_ = 0;
  std::vector<double> body_fractions_;
  std::vector<double> body_fractions() const;
  std::vector<double> seconds_list_, split_list_; // per iteration; the split k x nsplit
  Evaluation e_;
  double t_start_ = wall_time(); ///< the run's start, for the elapsed time
  /// The seconds the iterations after k will take at the pace of the last few (at most: the
  /// stop rule may end the run earlier).
  double eta(int k, double seconds) const {
    double sum = seconds;
    int n = 1;
    for (auto it = seconds_list_.rbegin(); it != seconds_list_.rend() && n < 5; ++it, ++n)
      sum += *it;
    return static_cast<double>(std::max(c_.max_iterations - k, 0)) * sum / n;
  }
};

/// "42.1s", "3:05", "1:02:03": a duration for the iteration lines.
std::string clock_text(double s) {
  char buf[32];
  const auto t = static_cast<long long>(std::llround(s));
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%.1fs", s);
  else if (t < 3600)
    std::snprintf(buf, sizeof buf, "%lld:%02lld", t / 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", t / 3600, t / 60 % 60, t % 60);
  return buf;
}

OptimizationRun::OptimizationRun(MPI_Comm comm, DesignProblem &design, const OptimizerSettings &c,
                                 const std::string &out_dir, bool restart)
    : comm_(comm), problem_(&design), c_(c), out_dir_(out_dir), m_(c.bounds.size()),
      stages_(design.design().stages()) {
  DesignProblem *problem = problem_;
  result_.dofs = problem->dofs();
  result_.elements = problem->design().global_elements();
  bodies_ = problem->design().size() > 1 ? problem->design().size() : 0;
  for (std::size_t b = 0; b < problem->design().size(); ++b)
    result_.design_bodies.push_back(problem->design().field(b).settings().body);
  result_.design_variables = problem->design_size();

  x_ = problem->create_design_vector();
  first_design(x_);
  stage_ = std::min(std::max(c.first_stage, 0), std::max(stages_ - 1, 0));
  FX_PETSC(VecDuplicate(x_, &xold_));
  FX_PETSC(VecDuplicate(x_, &xmin_));
  FX_PETSC(VecDuplicate(x_, &xmax_));
  // The move limit is applied as an outer box [max(0, x - m), min(1, x + m)] handed to MMA as
  // its bounds (Aage & Lazarov 2013), so that the initial asymptotes x -+ 0.5 (xmax - xmin) and
  // their clamps scale with the move limit rather than with [0, 1] (docs/theory-mma.md §5).
  MmaSettings settings;
  settings.move_limit = 1.0;
  mma_ = Mma::create(x_, static_cast<int>(m_), settings);

  // MMA works best with an objective of order 1 ... 100 and constraints of order 1 (Svanberg
  // 2007; its subproblem tolerance is absolute, docs/theory-mma.md): the objective is scaled
  // to 10 at the first iteration, and constraints are g_i = R_i / max_i - 1 (max_i > 0; else
  // (R_i - max_i) / |max_i|, or R_i for max_i = 0).
  dg_.resize(m_);
  for (auto &v : dg_) FX_PETSC(VecDuplicate(x_, &v));
  FX_PETSC(VecDuplicate(x_, &df0_));

  const io::GridLayout layout = problem->design_layout();
  plan_design_output(layout);
  if (restart)
    run_on_root(comm_, 0, [&] {
      std::error_code ec;
      const std::filesystem::path dir(out_dir);
      if (std::filesystem::is_regular_file(dir / "design.h5.tmp", ec))
        std::filesystem::rename(dir / "design.h5.tmp", dir / kInterruptedDesign, ec);
    });
  writer_.emplace(layout, out_dir, "design");
  // A run that stops on an error (a full disk, a diverging solve) leaves design.h5.tmp with its
  // flushed frames for `--restart` to carry over; the next run without --restart removes it.
  writer_->keep_unfinished_file();
  // design.h5 carries the design's fingerprint, as restart.h5 does: --restart carries frames
  // over only from a file of this design.
  fingerprint_ = design_fingerprint(problem->design());
  for (const auto &[name, value] : fingerprint_) writer_->label(name, value);
  write_history_header();
  print_header();
  restart_path_ = (std::filesystem::path(out_dir) / "restart.h5").string();
  tags_ = problem->design_keys();
}

void OptimizationRun::first_design(Vec x) const {
  if (c_.start.empty()) return problem_->initial_design(x);
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(x, &n));
  int bad = static_cast<std::size_t>(n) != c_.start.size();
  MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, comm_);
  if (bad) throw Error("optimize: the starting design has another layout than the problem's", true);
  set_local_values(x, c_.start);
}

/// design.xdmf's frames and estimated size, printed before the run; a warning above
/// kLargeDesignBytes with the output.every that keeps it below.
void OptimizationRun::plan_design_output(const io::GridLayout &layout) {
  const std::vector<std::string> fields{"density", "filtered_density", "physical_density"};
  result_.output_stride = design_output_stride(c_);
  result_.output_frames = design_output_frames(c_);
  result_.output_estimated_bytes =
      io::estimate_xdmf_bytes(layout, "design", fields, result_.output_frames);
  print0(comm_, "output: design.xdmf: %lld frames (every %d iteration%s%s); about %s\n",
         result_.output_frames, result_.output_stride, result_.output_stride == 1 ? "" : "s",
         c_.output_every > 0 ? ", output.every" : ", the default: about 100 per run",
         io::human_bytes(result_.output_estimated_bytes).c_str());
  if (result_.output_estimated_bytes <= kLargeDesignBytes) return;
  const double fixed = io::estimate_xdmf_bytes(layout, "design", fields, 0);
  const double per_frame = io::estimate_xdmf_bytes(layout, "design", fields, 1) - fixed;
  const double fit = std::floor((kLargeDesignBytes - fixed) / per_frame);
  std::string hint = "write fewer frames with output: {every: N} (iterations) in case.yaml";
  if (fit >= 3)
    hint += ", e.g. output: {every: " +
            std::to_string(static_cast<long long>(
                std::ceil(static_cast<double>(c_.max_iterations) / (fit - 2)))) +
            "} for at most " + io::human_bytes(kLargeDesignBytes);
  print0(comm_, "output: warning: design.h5 will take about %s (%lld frames of %s); %s\n",
         io::human_bytes(result_.output_estimated_bytes).c_str(), result_.output_frames,
         io::human_bytes(per_frame).c_str(), hint.c_str());
}

/// history.csv's header and the labels of the seconds' split (docs/theory.md section 11).
void OptimizationRun::write_history_header() {
  const auto &names = problem_->response_names();
  history_ << "iteration,objective";
  for (std::size_t i = 0; i < m_; ++i) history_ << "," << names[i + 1];
  history_ << ",max_change,seconds";
  // The split of an iteration's seconds: the problem's parts, then the update (the filter, the
  // pull-back, MMA and the output: the rest of the iteration).
  for (const Timing &t : problem_->timings()) {
    history_ << ",seconds_" << t.name;
    split_labels_.push_back(t.label);
    result_.split_names.push_back(t.name);
  }
  split_labels_.push_back("update");
  result_.split_names.emplace_back("update");
  nsplit_ = split_labels_.size();
  history_ << ",seconds_update";
  for (std::size_t b = 0; b < bodies_; ++b)
    history_ << ",volume_fraction_" << problem_->design().field(b).settings().body;
  history_ << "\n";
}

/// The run's first line and the header of the iteration lines.
void OptimizationRun::print_header() const {
  const auto &names = problem_->response_names();
  print0(
      comm_,
      "optimize: %lld design variables, %zu constraint(s), at most %d iterations, move limit %g, "
      "%s\n",
      static_cast<long long>(problem_->design_size()), m_, c_.max_iterations, c_.move_limit,
      problem_->design().filter_description().c_str());
  print0(comm_, "%5s %16s", "it", "objective");
  for (std::size_t i = 0; i < m_; ++i)
    print0(comm_, " %16s",
           ("c" + std::to_string(i) + ":" + names[i + 1].substr(names[i + 1].find(':') + 1))
               .substr(0, 16)
               .c_str());
  print0(comm_, " %10s", "change");
  for (const std::string &l : split_labels_) print0(comm_, " %8s", l.substr(0, 8).c_str());
  print0(comm_, " %8s %9s %9s", "s", "elapsed", "ETA");
  for (std::size_t b = 0; b < bodies_; ++b)
    print0(comm_, " %9s",
           ("vf:" + problem_->design().field(b).settings().body).substr(0, 9).c_str());
  print0(comm_, "\n");
}

/// Every field and array a restart needs, with its size (the same on every rank: rank 0 read
/// the file): a damaged file is refused here, not by an exception deep in the restore.
void OptimizationRun::check_restart_contents(const io::RestartData &r) const {
  const auto damaged = [&](const std::string &what) {
    throw Error(restart_path_ + ": damaged restart file: " + what, true);
  };
  for (const char *name : {"x", "xold1", "xold2", "low", "upp"})
    if (r.fields.count(name) == 0) damaged(std::string("no field ") + name);
  const auto meta = r.arrays.find("meta");
  if (meta == r.arrays.end() || meta->second.size() < 5) damaged("no meta array of 5 values");
  const double done = meta->second[0];
  if (!(done >= 1 && done < 1e9 && done == std::floor(done))) damaged("its iteration count");
  if (!(meta->second[1] > 0 && std::isfinite(meta->second[1]))) damaged("its objective scale");
  const auto n = static_cast<std::size_t>(done);
  for (const char *name : {"objective", "max_change", "seconds"}) {
    const auto it = r.arrays.find(name);
    if (it == r.arrays.end() || it->second.size() < n) damaged(std::string("array ") + name);
  }
  const auto con = r.arrays.find("constraints");
  if (con == r.arrays.end() || con->second.size() < n * m_) damaged("array constraints");
  const double stage = meta->second[3], start = meta->second[4];
  if (!(stage >= 0 && stage < 1e6 && start >= 0 && start <= done))
    damaged("its continuation stage");
}

void OptimizationRun::read_restart() {
  check_design_file(problem_->design(), restart_path_);
  const std::vector<std::uint64_t> state_keys = problem_->solver_state_keys();
  const io::RestartData r = io::read_restart(comm_, restart_path_, tags_, state_keys);
  check_restart_contents(r);
  for (const char *name : {"x", "xold1", "xold2"}) // MMA's asymptotes low, upp leave [0, 1]
    check_design_values(problem_->design(), r.fields.at(name), restart_path_, name);
  const auto &meta =
      r.arrays.at("meta"); // iteration, objective scale, m, beta stage, its first iteration
  const int done = static_cast<int>(meta.at(0));
  if (static_cast<std::size_t>(meta.at(2)) != m_)
    throw Error(restart_path_ + ": written for " + std::to_string(static_cast<int>(meta.at(2))) +
                    " constraints; the case has " + std::to_string(m_),
                true);
  objective_scale_ = meta.at(1);
  stage_ = static_cast<int>(meta.at(3));
  stage_start_ = static_cast<int>(meta.at(4));
  set_local_values(x_, r.fields.at("x"));
  Mma::State st;
  st.iteration = done;
  Vec state_vecs[4];
  const char *names4[4] = {"xold1", "xold2", "low", "upp"};
  for (int i = 0; i < 4; ++i) {
    FX_PETSC(VecDuplicate(x_, &state_vecs[i]));
    set_local_values(state_vecs[i], r.fields.at(names4[i]));
  }
  st.xold1 = state_vecs[0], st.xold2 = state_vecs[1], st.low = state_vecs[2],
  st.upp = state_vecs[3];
  mma_->restore(st);
  for (Vec &v : state_vecs) FX_PETSC(VecDestroy(&v));
  restore_history(r, done);
  if (const auto sc = r.arrays.find("response_scales"); sc != r.arrays.end())
    problem_->restore_response_scales(sc->second);
  // Solvers that keep what they built for the run's first design (GAMG's interpolation) build
  // it again from that design, at the first stage's projection, as the uninterrupted run did.
  {
    if (stages_ > 0)
      problem_->design().set_stage(std::min(std::max(c_.first_stage, 0), stages_ - 1));
    Vec x0 = problem_->create_design_vector();
    first_design(x0);
    problem_->prepare_resume(x0);
    FX_PETSC(VecDestroy(&x0));
  }
  if (!r.dof_fields.empty())
    problem_->restore_solver_state(r.dof_fields);
  else if (!state_keys.empty())
    print0(comm_,
           "optimize: %s holds no solver state for this mesh: the first solves start from "
           "zero (the run then agrees with an uninterrupted one to the solver's "
           "tolerance, not bit for bit)\n",
           restart_path_.c_str());
  result_.iterations = done;
  first_ = done + 1;
  print0(comm_, "optimize: restarting from %s after iteration %d\n", restart_path_.c_str(), done);
  carry_design_frames(done);
}

/// design.xdmf's frames of the iterations before `done` (docs/output.md "Restarts"), from the
/// killed run's design.h5.tmp (set aside by the constructor), else from the design.h5 of the
/// last run that ended. Each frame was flushed before the restart point of its iteration was
/// written, so a kill at any moment leaves them.
void OptimizationRun::carry_design_frames(int done) {
  namespace fs = std::filesystem;
  const fs::path dir(out_dir_), interrupted = dir / kInterruptedDesign;
  int from_interrupted = 0;
  run_on_root(comm_, 0, [&] { from_interrupted = fs::is_regular_file(interrupted) ? 1 : 0; });
  MPI_Bcast(&from_interrupted, 1, MPI_INT, 0, comm_);
  const fs::path source = from_interrupted ? interrupted : dir / "design.h5";
  std::vector<std::string> names{"density", "filtered_density", "physical_density"};
  for (const std::string &n : problem_->cell_field_names()) names.push_back(n);
  const io::XdmfWriter::Copied got =
      writer_->copy_steps(source.string(), done, names, fingerprint_);
  // The last frame due before `done` at this run's stride.
  const int stride = result_.output_stride, due = done > 0 ? (done - 1) / stride * stride : -1;
  if (got.steps > 0)
    print0(comm_, "optimize: design.xdmf: iterations 0 to %g (%d frames) carried over from %s\n",
           got.last_time, got.steps, source.filename().c_str());
  if (got.last_time < due) {
    const std::string w = "design.xdmf lacks the frames of iterations " +
                          std::to_string(static_cast<int>(got.last_time) + 1) + " to " +
                          std::to_string(due) + ": " + source.string() + ": " +
                          (got.problem.empty() ? "holds no more" : got.problem);
    print0(comm_, "optimize: warning: %s\n", w.c_str());
    result_.warnings.push_back(w);
  }
  run_on_root(comm_, 0, [&] {
    std::error_code ec;
    fs::remove(interrupted, ec);
  });
}

/// The result's and history.csv's rows of the `done` iterations stored in a restart file.
void OptimizationRun::restore_history(const io::RestartData &r, int done) {
  const std::size_t m = m_, nsplit = nsplit_;
  const auto &obj = r.arrays.at("objective"), &chg = r.arrays.at("max_change"),
             &con = r.arrays.at("constraints"), &sec = r.arrays.at("seconds");
  // The split, k x nsplit (a restart file written without it: not a number).
  const auto split = r.arrays.find("seconds_split");
  if (split != r.arrays.end() && split->second.size() == static_cast<std::size_t>(done) * nsplit)
    split_list_ = split->second;
  else
    split_list_.assign(static_cast<std::size_t>(done) * nsplit, std::nan(""));
  const auto fr = r.arrays.find("body_volume_fractions");
  if (fr != r.arrays.end() && fr->second.size() == static_cast<std::size_t>(done) * bodies_)
    body_fractions_ = fr->second;
  else
    body_fractions_.assign(static_cast<std::size_t>(done) * bodies_, std::nan(""));
  for (int k = 0; k < done; ++k) {
    const auto kk = static_cast<std::size_t>(k);
    result_.objective.push_back(obj.at(kk));
    result_.max_change.push_back(chg.at(kk));
    result_.constraints.emplace_back(con.begin() + static_cast<std::ptrdiff_t>(k * m),
                                     con.begin() + static_cast<std::ptrdiff_t>((k + 1) * m));
    append_history_row(
        history_, k + 1, obj[kk], con.data() + kk * m, m, chg[kk], sec[kk],
        split_list_.data() + kk * nsplit, nsplit,
        std::vector<double>(body_fractions_.begin() + static_cast<std::ptrdiff_t>(kk * bodies_),
                            body_fractions_.begin() +
                                static_cast<std::ptrdiff_t>((kk + 1) * bodies_)));
  }
  seconds_list_ = sec;
}

void OptimizationRun::iterate() {
  for (int k = first_; k <= c_.max_iterations; ++k)
    if (iteration(k, e_)) break;
}

namespace {
/// The scale of a constraint's bound: the bound, its magnitude when negative, 1 when zero.
double bound_scale(double bound) {
  return bound > 0 ? bound : bound < 0 ? -bound : 1.0;
}
/// R <= max as g = R / max - 1 <= 0 for a positive bound; a bound <= 0 (a sensor component that
/// must stay negative) as g = (R - max) / |max| (or R when max = 0).
double scaled_constraint(double value, double bound) {
  return bound > 0 ? value / bound - 1.0 : (value - bound) / bound_scale(bound);
}
/// A final design whose constraint is over its bound by more than this (of the bound's scale)
/// is reported as infeasible.
constexpr double kInfeasible = 1e-2;
} // namespace

/// The constraints g_i for MMA and their scaled gradients dg_i (docs/theory-mma.md §6).
std::vector<double> OptimizationRun::scaled_constraints(const Evaluation &e) {
  std::vector<double> g(m_);
  for (std::size_t i = 0; i < m_; ++i) {
    g[i] = scaled_constraint(e.constraints[i], c_.bounds[i]);
    FX_PETSC(VecCopy(e.d_constraints[i], dg_[i]));
    FX_PETSC(VecScale(dg_[i], 1.0 / bound_scale(c_.bounds[i])));
  }
  return g;
}

void OptimizationRun::report_infeasible(const Evaluation &e) {
  const std::vector<std::string> &names = problem_->response_names();
  for (std::size_t i = 0; i < m_; ++i) {
    const double g = scaled_constraint(e.constraints[i], c_.bounds[i]);
    if (!(g > kInfeasible)) continue;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "the final design violates %s: %.6g against the bound %.6g, "
                  "over by %.1f %% of it; more iterations (optimizer.max_iterations) or, if it "
                  "oscillates about its bound in history.csv, a smaller optimizer.move_limit (now "
                  "%g) may reach a feasible design",
                  names[i + 1].c_str(), e.constraints[i], c_.bounds[i], 100 * g, c_.move_limit);
    print0(comm_, "optimize: warning: %s\n", buf);
    result_.warnings.emplace_back(buf);
  }
}

/// The split of an iteration's seconds: the problem's parts, then the update (the rest).
std::vector<double> OptimizationRun::iteration_split(double seconds) const {
  std::vector<double> split;
  double parts = 0;
  for (const Timing &t : problem_->timings()) {
    split.push_back(t.seconds);
    parts += t.seconds;
  }
  split.push_back(seconds - parts);
  return split;
}

/// Iteration k of docs/theory.md section 11: evaluate, scale, the MMA update in the move-limit
/// box, record, restart point, continuation. Returns true if the stop rule holds.
bool OptimizationRun::iteration(int k, Evaluation &e) {
  DesignProblem *problem = problem_;
  const double t0 = wall_time();
  if (stages_ > 0) {
    problem->design().set_stage(stage_);
    if (result_.beta_stages.empty() || result_.beta_stages.back().first < stage_start_)
      result_.beta_stages.emplace_back(k, problem->design().betas());
  }
  problem->evaluate(x_, true, e);
  if (!std::isfinite(e.objective))
    throw Error("optimize: iteration " + std::to_string(k) + ": the objective is not finite", true);
  if (k == 1) {
    objective_scale_ = std::abs(e.objective) > 0 ? 10.0 / std::abs(e.objective) : 1.0;
    for (const std::string &w : stuck_responses(*problem, e)) {
      print0(comm_, "optimize: warning: %s\n", w.c_str());
      result_.warnings.push_back(w);
    }
  }
  const bool write = (k - 1) % result_.output_stride == 0;
  if (write) {
    write_densities(*writer_, *problem, k - 1);
    writer_->flush(); // before restart point k: a kill leaves this frame for --restart
  }

  FX_PETSC(VecCopy(e.d_objective, df0_));
  FX_PETSC(VecScale(df0_, objective_scale_));
  const std::vector<double> g = scaled_constraints(e);
  FX_PETSC(VecCopy(x_, xold_));
  set_move_box(x_, c_.move_limit, xmin_, xmax_);
  mma_->update(x_, xmin_, xmax_, e.objective * objective_scale_, df0_, g, dg_);
  const double change = max_abs_change(x_, xold_);
  const double seconds = wall_time() - t0;
  record(k, e, change, seconds, iteration_split(seconds));
  problem->end_iteration(); // the adaptive scales for iteration k + 1, kept in its restart point

  bool last_stage = false;
  write_restart_point(k, change, last_stage);
  if (change < c_.tolerance && last_stage) {
    result_.converged = true;
    result_.stop_reason = "max design change " + std::to_string(change) + " < tolerance " +
                          std::to_string(c_.tolerance);
    return true;
  }
  return false;
}

/// Iteration k's entries of the result, its line on the terminal and in history.csv.
void OptimizationRun::record(int k, const Evaluation &e, double change, double seconds,
                             const std::vector<double> &split) {
  result_.iterations = k;
  result_.objective.push_back(e.objective);
  result_.constraints.push_back(e.constraints);
  result_.max_change.push_back(change);
  print0(comm_, "%5d %16.9e", k, e.objective);
  for (double v : e.constraints) print0(comm_, " %16.9e", v);
  print0(comm_, " %10.3e", change);
  for (double v : split) print0(comm_, " %8.2f", v);
  print0(comm_, " %8.2f %9s %9s", seconds, clock_text(wall_time() - t_start_).c_str(),
         clock_text(eta(k, seconds)).c_str());
  const std::vector<double> fractions = body_fractions();
  for (double v : fractions) print0(comm_, " %9.6f", v);
  print0(comm_, "\n");
  body_fractions_.insert(body_fractions_.end(), fractions.begin(), fractions.end());
  append_history_row(history_, k, e.objective, e.constraints.data(), e.constraints.size(), change,
                     seconds, split.data(), split.size(), fractions);
  seconds_list_.push_back(seconds);
  split_list_.insert(split_list_.end(), split.begin(), split.end());
}

/// Advances the projection continuation after iteration k: after `every` iterations at this
/// beta, or when the design has settled at it. Returns whether the stage (before advancing) is
/// the last.
bool OptimizationRun::advance_continuation(int k, double change) {
  const bool last_stage = stages_ == 0 || stage_ + 1 == stages_;
  const bool settled = change < c_.tolerance;
  if (!last_stage && (settled || k - stage_start_ + 1 >= problem_->design().stage_length())) {
    ++stage_;
    stage_start_ = k + 1;
    print0(comm_, "optimize: projection beta -> %s from iteration %d\n",
           problem_->design().stage_text(stage_).c_str(), k + 1);
  }
  return last_stage;
}

/// restart.h5 after iteration k (docs/theory-mma.md §7: x and MMA's state; the scale, the
/// continuation stage and the history), with the continuation advanced in between.
void OptimizationRun::write_restart_point(int k, double change, bool &last_stage) {
  // Restart point after every iteration (atomic: a kill at any moment leaves the previous
  // complete file).
  io::RestartData rd;
  rd.tags = tags_;
  rd.labels = fingerprint_;
  rd.fields["x"] = local_values(x_);
  const Mma::State st = mma_->state();
  rd.fields["xold1"] = local_values(st.xold1);
  rd.fields["xold2"] = local_values(st.xold2);
  rd.fields["low"] = local_values(st.low);
  rd.fields["upp"] = local_values(st.upp);
  // Advance the projection continuation: after `every` iterations at this beta, or when
  // the design has settled at it.
  last_stage = advance_continuation(k, change);
  rd.arrays["meta"] = {static_cast<double>(k), objective_scale_, static_cast<double>(m_),
                       static_cast<double>(stage_), static_cast<double>(stage_start_)};
  rd.arrays["objective"] = result_.objective;
  rd.arrays["max_change"] = result_.max_change;
  rd.arrays["seconds"] = seconds_list_;
  rd.arrays["seconds_split"] = split_list_;
  if (bodies_ > 0) rd.arrays["body_volume_fractions"] = body_fractions_;
  std::vector<double> flat;
  for (const auto &row : result_.constraints) flat.insert(flat.end(), row.begin(), row.end());
  rd.arrays["constraints"] = flat;
  const std::vector<double> scales = problem_->response_scales();
  if (!scales.empty()) rd.arrays["response_scales"] = scales;
  // The solvers' warm-start state (DesignProblem::solver_state), keyed by position.
  rd.dof_fields = problem_->solver_state();
  if (!rd.dof_fields.empty()) {
    if (state_keys_.empty()) state_keys_ = problem_->solver_state_keys();
    rd.dof_keys = state_keys_;
  }
  io::write_restart(comm_, restart_path_, rd);
}

/// Each design body's volume fraction at the last evaluation (none with one body).
std::vector<double> OptimizationRun::body_fractions() const {
  std::vector<double> v;
  for (std::size_t b = 0; b < bodies_; ++b) v.push_back(problem_->design().volume_fraction(b));
  return v;
}

OptimizationResult OptimizationRun::finish() {
  DesignProblem *problem = problem_;
  OptimizationResult &result = result_;
  Evaluation &e = e_;
  if (!result.converged) result.stop_reason = "max_iterations reached";
  for (std::size_t k = 0; k * nsplit_ < split_list_.size(); ++k)
    result.seconds_split.emplace_back(
        split_list_.begin() + static_cast<std::ptrdiff_t>(k * nsplit_),
        split_list_.begin() + static_cast<std::ptrdiff_t>((k + 1) * nsplit_));
  // Final state: the design after the last update.
  problem->evaluate(x_, false, e);
  report_infeasible(e);
  write_densities(*writer_, *problem, result.iterations);
  result.volume_fraction = problem->design().volume_fraction();
  result.stage = stage_;
  result.design = local_values(x_);
  if (bodies_ > 0) result.body_volume_fractions = body_fractions();
  result.output = writer_->close();
  run_on_root(comm_, 0, [&] {
    io::write_file_atomic((std::filesystem::path(out_dir_) / "history.csv").string(),
                          history_.str());
  });
  print0(comm_,
         "optimize: stopped after %d iterations: %s; final objective %.9e, volume fraction %.6f\n",
         result.iterations, result.stop_reason.c_str(), e.objective, result.volume_fraction);
  for (auto &v : dg_) FX_PETSC(VecDestroy(&v));
  FX_PETSC(VecDestroy(&df0_));
  FX_PETSC(VecDestroy(&x_));
  FX_PETSC(VecDestroy(&xold_));
  FX_PETSC(VecDestroy(&xmin_));
  FX_PETSC(VecDestroy(&xmax_));
  return result;
}

} // namespace

int design_output_stride(const OptimizerSettings &settings) {
  if (settings.output_every > 0) return settings.output_every;
  return std::max(1, (settings.max_iterations + kDesignFrames - 1) / kDesignFrames);
}

long long design_output_frames(const OptimizerSettings &settings) {
  const int stride = design_output_stride(settings);
  return (std::max(settings.max_iterations, 1) - 1) / stride + 2;
}

OptimizationResult run_optimization(MPI_Comm comm, DesignProblem &design,
                                    const OptimizerSettings &c, const std::string &out_dir,
                                    bool restart) {
  OptimizationRun run(comm, design, c, out_dir, restart);
  if (restart) run.read_restart();
  run.iterate();
  return run.finish();
}

} // namespace flexopt::optimize
