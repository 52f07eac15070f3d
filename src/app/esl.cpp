/// \file `optimize` with `optimizer: {method: esl}`: design by equivalent static loads
/// (docs/theory.md section 14). Each outer iteration simulates the mechanism with the current
/// design (adjoint::DynamicProblem, no gradients), takes the design body's loads at N instants
/// (dynamics::body_loads), and designs the body statically for those N load cases
/// (optimize::ScenarioProblem over N optimize::TopologyProblem, the MMA loop of
/// optimize::run_optimization), starting from the current design.
#include "app_common.hpp"
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/core/vec_values.hpp"
#include "flexopt/dynamics/body_loads.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/io/restart.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/grid_layout.hpp"
#include "flexopt/optimize/design_file.hpp"
#include "flexopt/optimize/optimizer.hpp"
#include "flexopt/optimize/scenario_problem.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace flexopt::app {

namespace {

namespace fs = std::filesystem;
using dynamics::Vec3;

/// The design body's loads at one instant, in its mesh axes (docs/theory.md 14.2 and 14.3).
struct Instant {
  long long step = 0;
  double time = 0;
  std::vector<fem::SurfaceLoad> tractions; ///< force and moment per loaded interface (not I0)
  std::vector<double> body_force;          ///< A^T g - a at the mesh's local nodes [m/s^2]
  double imbalance = 0; ///< the larger relative force and moment imbalance (section 14.2)
};

/// What an equivalent-static-loads run reads from the case.
struct EslInputs {
  adjoint::DynamicSettings dynamic;
  optimize::EslSettings esl;
  optimize::OptimizerSettings optimizer; ///< each static design's MMA settings
  dynamics::BodyDescription body;        ///< the design body
  std::size_t body_index = 0;            ///< in the scene
  std::string case_file;
};

/// Steps n_k = round(k n / N), k = 1 ... N (section 14.1).
std::vector<long long> instant_steps(long long steps, int n) {
  std::vector<long long> out;
  for (int k = 1; k <= n; ++k)
    out.push_back(std::llround(static_cast<double>(k) * static_cast<double>(steps) / n));
  return out;
}

/// Per loaded interface, the force and the moment about its centroid (section 14.2); I0, the
/// clamped frame interface, is left to the support. A load at no interface is refused.
std::vector<fem::SurfaceLoad> interface_tractions(const dynamics::BodyLoads &l,
                                                  const dynamics::BodyDescription &body,
                                                  const io::Location &where) {
  std::map<std::string, std::pair<Vec3, Vec3>> sum; // interface -> force, moment about point
  std::map<std::string, Vec3> at;
  for (const dynamics::PointLoad &p : l.points) {
    if (p.interface.empty())
      throw Error(where.str() + ": optimizer.method: esl: the " + p.owner + " acts on body '" +
                      body.name +
                      "' away from its interfaces; a static load case applies loads "
                      "at interfaces only",
                  true);
    const auto it = at.emplace(p.interface, p.point).first;
    auto &[force, moment] =
        sum.try_emplace(p.interface, Vec3::Zero(), Vec3::Zero()).first->second; // Eigen: no zero
    force += p.force;
    moment += p.moment + (p.point - it->second).cross(p.force);
  }
  std::vector<fem::SurfaceLoad> out;
  for (const auto &[name, fm] : sum) {
    if (name == body.interfaces.front()) continue;
    fem::SurfaceLoad s;
    s.surface = name;
    s.total = true;
    for (int c = 0; c < 3; ++c)
      s.value[static_cast<std::size_t>(c)] = fm.first(c),
      s.moment[static_cast<std::size_t>(c)] = fm.second(c);
    s.where = where;
    out.push_back(s);
  }
  return out;
}

/// The owned nodes' values of `owned` (block size 3) at every local node (owned, then ghosts).
std::vector<double> at_local_nodes(const mesh::DistributedMesh &m, Vec owned) {
  Vec g = fem::create_ghosted_vector(m), local = nullptr;
  FX_PETSC(VecCopy(owned, g));
  FX_PETSC(VecGhostUpdateBegin(g, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(g, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostGetLocalForm(g, &local));
  const PetscScalar *v = nullptr;
  FX_PETSC(VecGetArrayRead(local, &v));
  std::vector<double> out(v, v + 3 * m.local_nodes());
  FX_PETSC(VecRestoreArrayRead(local, &v));
  FX_PETSC(VecGhostRestoreLocalForm(g, &local));
  FX_PETSC(VecDestroy(&g));
  return out;
}

/// The static load cases share one operator (fem::StaticProblem::create_sharing): a direct
/// solver factorizes it once per design for all N of them, against N preconditioned Krylov
/// solves at SIMP's contrast (docs/benchmarks.md "Equivalent static loads": 10 times faster on
/// the slow crank). The default up to kEslDirectDofs unknowns, unless the case's `solver:` or
/// the command line chose a solver. Collective.
constexpr long long kEslDirectDofs = 200000;
void default_direct_solver(MPI_Comm comm, long long dofs) {
  PetscBool ksp = PETSC_FALSE, pc = PETSC_FALSE;
  FX_PETSC(PetscOptionsHasName(nullptr, nullptr, "-ksp_type", &ksp));
  FX_PETSC(PetscOptionsHasName(nullptr, nullptr, "-pc_type", &pc));
  if (ksp || pc || dofs > kEslDirectDofs) return;
  insert_default_petsc_options("-ksp_type preonly -pc_type cholesky "
                               "-pc_factor_mat_solver_type mumps",
                               "esl: the static load cases' direct solver");
  print0(comm,
         "esl: the static load cases share one Cholesky factorization (MUMPS) per design (%lld "
         "unknowns; solver: in the case chooses another)\n",
         dofs);
}

/// One row of the outer history.
struct OuterRow {
  double dynamic_objective = 0;
  std::vector<double> dynamic_constraints;
  double static_objective = 0, max_change = 0, simulate_s = 0, design_s = 0, imbalance = 0;
  int inner_iterations = 0;
  std::vector<double> flat() const {
    std::vector<double> v{dynamic_objective,
                          static_objective,
                          max_change,
                          simulate_s,
                          design_s,
                          imbalance,
                          static_cast<double>(inner_iterations)};
    v.insert(v.end(), dynamic_constraints.begin(), dynamic_constraints.end());
    return v;
  }
  static OuterRow from(const double *v, std::size_t constraints) {
    OuterRow r{v[0], {}, v[1], v[2], v[3], v[4], v[5], static_cast<int>(v[6])};
    r.dynamic_constraints.assign(v + 7, v + 7 + constraints);
    return r;
  }
  static constexpr std::size_t kFixed = 7;
};

class EslRun {
public:
  EslRun(const Context &ctx, const EslInputs &in, const std::string &dir)
      : ctx_(ctx), in_(in), dir_(dir), esl_dir_((fs::path(dir) / "esl").string()) {}
  /// Outer iterations until the design settles or K ran; returns the final design's row.
  void run(bool restart);
  const std::vector<OuterRow> &rows() const { return rows_; }
  const OuterRow &final_row() const { return final_; }
  bool converged() const { return converged_; }
  adjoint::DynamicProblem &dynamic() { return *dyn_; }

private:
  /// Simulates design x (outer iteration j's), its loads at the instants into `instants`.
  OuterRow simulate(Vec x, std::vector<Instant> *instants);
  /// The static design of the instants' load cases from x at `stage`, in esl/outer_JJ.
  optimize::OptimizationResult design_statically(int j, const std::vector<Instant> &instants,
                                                 const std::vector<double> &x, int stage,
                                                 bool restart);
  void write_loads(int j, const std::vector<Instant> &instants) const;
  void write_state(int done, const std::vector<double> &x, int stage) const;
  /// Reads esl/restart.h5: the outer iterations done (0: none), x and the stage.
  int read_state(std::vector<double> &x, int &stage);
  void write_history() const;
  std::string outer_dir(int j) const;

  const Context &ctx_;
  const EslInputs &in_;
  std::string dir_, esl_dir_;
  std::unique_ptr<adjoint::DynamicProblem> dyn_;
  std::shared_ptr<const std::vector<double>> coordinates_; ///< of the body's local nodes
  std::vector<OuterRow> rows_;
  OuterRow final_;
  bool converged_ = false;
};

std::string EslRun::outer_dir(int j) const {
  char name[32];
  std::snprintf(name, sizeof name, "outer_%02d", j);
  return (fs::path(esl_dir_) / name).string();
}

OuterRow EslRun::simulate(Vec x, std::vector<Instant> *instants) {
  const dynamics::Scene &scene = dyn_->scene();
  const std::size_t b = in_.body_index;
  const mesh::DistributedMesh &m = scene.meshes[b];
  const std::vector<long long> steps =
      instant_steps(std::llround(in_.dynamic.time.end / in_.dynamic.time.step), in_.esl.instants);
  Mat mass = nullptr;
  std::size_t next = 0;
  dyn_->set_observer([&](long long j, const dynamics::StepInfo &, const dynamics::State *dense,
                         const dynamics::DistState *) {
    if (!instants) return;
    if (!dense)
      throw Error(in_.esl.where.str() + ": optimizer.method: esl takes a scene of rigid and FFRF "
                                        "bodies (an ACF body runs on the distributed backend)",
                  true);
    if (j == 0) { // the design's mass matrix, with the factors of this evaluation's design
      mass = fem::create_matrix(m);
      fem::assemble_mass(m, in_.body.material.density, dyn_->design_bodies().front().ev.w, mass);
    }
    if (next >= steps.size() || j != steps[next]) return;
    ++next;
    const dynamics::BodyLoads l = dynamics::body_loads(scene, b, *dense, mass);
    Instant in;
    in.step = j;
    in.time = dense->t;
    in.tractions = interface_tractions(l, in_.body, in_.esl.where);
    in.body_force = at_local_nodes(m, l.body_force);
    in.imbalance = std::max(l.force_residual.norm() / std::max(l.force_scale, 1e-300),
                            l.moment_residual.norm() / std::max(l.moment_scale, 1e-300));
    instants->push_back(std::move(in));
  });
  if (instants) instants->clear();
  optimize::Evaluation ev;
  const double t = wall_time();
  dyn_->evaluate(x, false, ev);
  dyn_->set_observer({});
  if (mass) MatDestroy(&mass);
  OuterRow row;
  row.simulate_s = wall_time() - t;
  row.dynamic_objective = ev.objective;
  row.dynamic_constraints = ev.constraints;
  if (instants)
    for (const Instant &i : *instants) row.imbalance = std::max(row.imbalance, i.imbalance);
  return row;
}

/// The static problem's responses (section 14.4): the objective sum_k w_k 1/2 C_k, the volume
/// and mass constraints on one load case, the stress constraints' KS maximum over all.
std::vector<optimize::ResponseSettings> static_responses(const EslInputs &in,
                                                         optimize::ScenarioSettings &s) {
  const std::size_t n = s.names.size();
  std::vector<std::size_t> all(n);
  for (std::size_t k = 0; k < n; ++k) all[k] = k;
  std::vector<optimize::ResponseSettings> out;
  optimize::ResponseSettings objective;
  objective.type = optimize::ResponseType::Compliance;
  objective.where = in.dynamic.objective.where;
  out.push_back(objective);
  s.response_names.push_back("objective:compliance");
  s.responses.push_back(
      {all, optimize::Combine::Weighted, std::vector<double>(n, 0.5 / static_cast<double>(n)), 50});
  for (std::size_t i = 0; i < in.dynamic.constraints.size(); ++i) {
    const optimize::ResponseSettings &r = in.dynamic.constraints[i];
    out.push_back(r);
    s.response_names.push_back("constraint" + std::to_string(i) + ":" +
                               optimize::response_type_name(r.type));
    if (r.type == optimize::ResponseType::Stress)
      s.responses.push_back({all, optimize::Combine::Max, {}, r.combine_ks});
    else
      s.responses.push_back({{0}, optimize::Combine::Sum, {}, 50});
  }
  return out;
}

optimize::OptimizationResult EslRun::design_statically(int j, const std::vector<Instant> &instants,
                                                       const std::vector<double> &x, int stage,
                                                       bool restart) {
  optimize::ScenarioSettings s;
  for (std::size_t k = 0; k < instants.size(); ++k) {
    char name[48];
    std::snprintf(name, sizeof name, "instant_%02zu", k + 1);
    s.names.push_back(name);
  }
  s.noun = "instant";
  s.groups = 1; // one distribution: the load cases' nodal fields are the dynamic mesh's
  const std::vector<optimize::ResponseSettings> responses = static_responses(in_, s);
  fem::Support clamp;
  clamp.surface = in_.body.interfaces.front();
  clamp.fix = {true, true, true};
  clamp.where = in_.esl.where;
  const optimize::TopologyProblem *first = nullptr; // the load cases share its K and solver
  auto problem = optimize::ScenarioProblem::create(
      ctx_.comm(), s,
      [&](MPI_Comm comm, std::size_t k, const std::vector<std::size_t> &taken) {
        optimize::TopologySettings t;
        t.share_operator = first;
        t.problem.mesh = in_.body.mesh;
        t.problem.material = in_.body.material;
        t.problem.case_file = in_.case_file;
        t.problem.loads.supports = {clamp};
        t.problem.loads.tractions = instants[k].tractions;
        t.problem.loads.body_force = fem::NodalBodyForce{instants[k].body_force, coordinates_};
        t.design = in_.dynamic.design.front();
        t.objective = responses[taken.front()];
        for (std::size_t i = 1; i < taken.size(); ++i) t.constraints.push_back(responses[taken[i]]);
        auto p = optimize::TopologyProblem::create(comm, t);
        if (!first) first = p.get();
        return std::unique_ptr<optimize::DesignProblem>(std::move(p));
      },
      [](MPI_Comm) -> std::shared_ptr<optimize::Design> { return nullptr; });
  int other = problem->design_keys() != dyn_->design_keys();
  MPI_Allreduce(MPI_IN_PLACE, &other, 1, MPI_INT, MPI_MAX, ctx_.comm());
  if (other)
    throw Error(in_.case_file + ": optimizer.method: esl: the static design's elements differ "
                                "from the dynamic one's (the body's mesh was not reproduced)",
                true);
  optimize::OptimizerSettings settings = in_.optimizer;
  settings.max_iterations =
      in_.esl.inner_iterations > 0 ? in_.esl.inner_iterations : in_.optimizer.max_iterations;
  settings.start = x;
  settings.first_stage = stage;
  settings.bounds.clear();
  for (const optimize::ResponseSettings &r : in_.dynamic.constraints)
    settings.bounds.push_back(r.max);
  const std::string out = outer_dir(j);
  run_on_root(ctx_.comm(), 0, [&] { fs::create_directories(out); });
  MPI_Barrier(ctx_.comm());
  const PrintPrefix prefix("  ");
  return optimize::run_optimization(ctx_.comm(), *problem, settings, out, restart);
}

void EslRun::write_loads(int j, const std::vector<Instant> &instants) const {
  const mesh::DistributedMesh &m = dyn_->scene().meshes[in_.body_index];
  char base[32];
  std::snprintf(base, sizeof base, "loads_%02d", j);
  io::XdmfWriter writer(mesh::grid_layout(m), esl_dir_, base);
  for (const Instant &i : instants) {
    writer.begin_step(i.time);
    writer.node_vector("body_force", i.body_force.data()); // the owned nodes come first
  }
  writer.close();
  run_on_root(ctx_.comm(), 0, [&] {
    std::ostringstream csv;
    csv << "instant,step,time,interface,fx,fy,fz,mx,my,mz\n";
    csv.precision(12);
    for (std::size_t k = 0; k < instants.size(); ++k)
      for (const fem::SurfaceLoad &s : instants[k].tractions) {
        csv << k + 1 << ',' << instants[k].step << ',' << instants[k].time << ',' << s.surface;
        for (double v : s.value) csv << ',' << v;
        for (double v : s.moment) csv << ',' << v;
        csv << '\n';
      }
    io::write_file_atomic((fs::path(esl_dir_) / (std::string(base) + ".csv")).string(), csv.str());
  });
}

void EslRun::write_state(int done, const std::vector<double> &x, int stage) const {
  io::RestartData r;
  const std::vector<std::uint64_t> &keys = dyn_->design_keys();
  r.tags.assign(keys.begin(), keys.end());
  r.fields["x"] = x;
  r.arrays["meta"] = {static_cast<double>(done), static_cast<double>(stage),
                      static_cast<double>(in_.dynamic.constraints.size())};
  std::vector<double> flat;
  for (const OuterRow &row : rows_) {
    const std::vector<double> v = row.flat();
    flat.insert(flat.end(), v.begin(), v.end());
  }
  r.arrays["rows"] = flat;
  r.labels = optimize::design_fingerprint(dyn_->design());
  io::write_restart(ctx_.comm(), (fs::path(esl_dir_) / "restart.h5").string(), r);
}

int EslRun::read_state(std::vector<double> &x, int &stage) {
  const std::string path = (fs::path(esl_dir_) / "restart.h5").string();
  int exists = 0;
  run_on_root(ctx_.comm(), 0, [&] { exists = fs::is_regular_file(path) ? 1 : 0; });
  MPI_Bcast(&exists, 1, MPI_INT, 0, ctx_.comm());
  if (!exists) {
    // Killed in the first outer iteration: its static design's restart.h5 is all there is.
    int inner = 0;
    run_on_root(ctx_.comm(), 0,
                [&] { inner = fs::is_regular_file(fs::path(outer_dir(0)) / "restart.h5"); });
    MPI_Bcast(&inner, 1, MPI_INT, 0, ctx_.comm());
    if (!inner)
      throw Error(path + ": restart file not found (nor " + outer_dir(0) +
                      "/restart.h5): run optimize without --restart first",
                  true);
    return 0;
  }
  optimize::check_design_file(dyn_->design(), path);
  const io::RestartData r = io::read_restart(ctx_.comm(), path, dyn_->design_keys());
  const std::vector<double> &meta = r.arrays.at("meta");
  const auto m = static_cast<std::size_t>(meta.at(2));
  if (m != in_.dynamic.constraints.size())
    throw Error(path + ": written for " + std::to_string(m) + " constraints, the case has " +
                    std::to_string(in_.dynamic.constraints.size()),
                true);
  x = r.fields.at("x");
  stage = static_cast<int>(meta.at(1));
  const std::vector<double> &flat = r.arrays.at("rows");
  const std::size_t width = OuterRow::kFixed + m;
  for (std::size_t k = 0; k + width <= flat.size(); k += width)
    rows_.push_back(OuterRow::from(flat.data() + k, m));
  return static_cast<int>(meta.at(0));
}

void EslRun::write_history() const {
  run_on_root(ctx_.comm(), 0, [&] {
    std::ostringstream h;
    h.precision(12);
    h << "outer,dynamic_objective";
    for (std::size_t i = 0; i < in_.dynamic.constraints.size(); ++i)
      h << ",dynamic_constraint" << i;
    h << ",static_objective,inner_iterations,max_change,imbalance,seconds_simulate,"
         "seconds_design\n";
    auto line = [&](const std::string &outer, const OuterRow &r) {
      h << outer << ',' << r.dynamic_objective;
      for (double v : r.dynamic_constraints) h << ',' << v;
      h << ',' << r.static_objective << ',' << r.inner_iterations << ',' << r.max_change << ','
        << r.imbalance << ',' << r.simulate_s << ',' << r.design_s << '\n';
    };
    for (std::size_t j = 0; j < rows_.size(); ++j) line(std::to_string(j), rows_[j]);
    line("final", final_);
    io::write_file_atomic((fs::path(dir_) / "history.csv").string(), h.str());
  });
}

void EslRun::run(bool restart) {
  dyn_ = adjoint::DynamicProblem::create(ctx_.comm(), in_.dynamic, dir_, true);
  const adjoint::DesignBody &db = dyn_->design_bodies().front();
  if (!db.rigid() && !db.ffrf())
    throw Error(in_.esl.where.str() + ": optimizer.method: esl: design body '" + in_.body.name +
                    "' runs as ACF, whose loads are not built; use model: ffrf or rigid",
                true);
  const mesh::DistributedMesh &m = dyn_->scene().meshes[in_.body_index];
  coordinates_ = std::make_shared<const std::vector<double>>(m.coordinates);
  default_direct_solver(ctx_.comm(), 3LL * m.global_nodes);
  Vec x = dyn_->create_design_vector();
  dyn_->initial_design(x);
  std::vector<double> xv = local_values(x);
  int stage = 0, first = 0;
  if (restart) first = read_state(xv, stage);
  if (!rows_.empty()) converged_ = rows_.back().max_change < in_.optimizer.tolerance;
  if (!restart) run_on_root(ctx_.comm(), 0, [&] { fs::remove_all(esl_dir_); });
  run_on_root(ctx_.comm(), 0, [&] { fs::create_directories(esl_dir_); });
  MPI_Barrier(ctx_.comm());
  if (first > 0)
    print0(ctx_.comm(), "esl: restarting after outer iteration %d (%s)\n", first - 1,
           (fs::path(esl_dir_) / "restart.h5").c_str());
  const int outer = in_.esl.outer_iterations;
  for (int j = first; j < outer && !converged_; ++j) {
    print0(ctx_.comm(), "esl: outer iteration %d of at most %d: simulating the design\n", j, outer);
    set_local_values(x, xv);
    // The design as the static designs see it: at their projection stage.
    if (dyn_->design().stages() > 0) dyn_->design().set_stage(stage);
    std::vector<Instant> instants;
    OuterRow row = simulate(x, &instants);
    print0(ctx_.comm(),
           "esl: dynamic objective %.9e (%.1f s); loads at %zu instants (largest imbalance "
           "%.1e)\n",
           row.dynamic_objective, row.simulate_s, instants.size(), row.imbalance);
    write_loads(j, instants);
    const double t = wall_time();
    const bool inner_restart =
        restart && j == first && fs::is_regular_file(fs::path(outer_dir(j)) / "restart.h5");
    const optimize::OptimizationResult r = design_statically(j, instants, xv, stage, inner_restart);
    row.design_s = wall_time() - t;
    row.inner_iterations = r.iterations;
    row.static_objective = r.objective.empty() ? 0 : r.objective.back();
    double change = 0;
    for (std::size_t e = 0; e < xv.size(); ++e)
      change = std::max(change, std::abs(r.design[e] - xv[e]));
    MPI_Allreduce(MPI_IN_PLACE, &change, 1, MPI_DOUBLE, MPI_MAX, ctx_.comm());
    row.max_change = change;
    xv = r.design;
    stage = r.stage;
    rows_.push_back(row);
    converged_ = change < in_.optimizer.tolerance;
    write_state(j + 1, xv, stage);
    print0(ctx_.comm(),
           "esl: outer iteration %d: %d static iterations (%.1f s), design change %.3e\n", j,
           r.iterations, row.design_s, change);
  }
  if (!rows_.empty()) converged_ = rows_.back().max_change < in_.optimizer.tolerance;
  set_local_values(x, xv);
  if (dyn_->design().stages() > 0) dyn_->design().set_stage(stage);
  final_ = simulate(x, nullptr);
  FX_PETSC(VecDestroy(&x));
  write_history();
  print0(ctx_.comm(), "esl: final design's dynamic objective %.9e\n", final_.dynamic_objective);
}

/// The inputs of an ESL run from the case (after the plan chose the auto models).
EslInputs esl_inputs(const io::Case &c, const Options &o) {
  EslInputs in{io::dynamic_settings(c), *c.esl, c.optimizer, {}, 0, c.file};
  if (o.max_iterations > 0) in.esl.inner_iterations = o.max_iterations;
  const std::string &name = c.design.front().body;
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    if (c.scene.bodies[b].name == name) in.body = c.scene.bodies[b], in.body_index = b;
  if (in.body.interfaces.empty())
    throw Error(in.esl.where.str() + ": optimizer.method: esl: design body '" + name +
                    "' has no interfaces (its first one is clamped in the static load cases)",
                true);
  return in;
}

/// The last static design's design.xdmf/.h5 and restart.h5 copied to the output directory:
/// the run's design, for ParaView and `simulate --design OUT/restart.h5`.
void copy_final_design(const Context &ctx, const std::string &from, const std::string &dir) {
  run_on_root(ctx.comm(), 0, [&] {
    for (const char *f : {"design.h5", "design.xdmf", "restart.h5"})
      fs::copy_file(fs::path(from) / f, fs::path(dir) / f, fs::copy_options::overwrite_existing);
  });
  MPI_Barrier(ctx.comm());
}

} // namespace

int run_esl(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const std::string dir = detail::output_directory(ctx, o);
  const EslInputs in = esl_inputs(c, o);
  print0(ctx.comm(),
         "esl: equivalent static loads on body '%s': %d instants, at most %d outer iterations of "
         "%d static iterations\n",
         in.body.name.c_str(), in.esl.instants, in.esl.outer_iterations,
         in.esl.inner_iterations > 0 ? in.esl.inner_iterations : in.optimizer.max_iterations);
  EslRun run(ctx, in, dir);
  run.run(o.restart);
  const int last = static_cast<int>(run.rows().size()) - 1;
  char name[32];
  std::snprintf(name, sizeof name, "outer_%02d", last);
  copy_final_design(ctx, (fs::path(dir) / "esl" / name).string(), dir);
  io::Json s = detail::base_summary(ctx, o, c);
  s["method"] = "esl";
  s["instants"] = in.esl.instants;
  s["outer_iterations"] = static_cast<int>(run.rows().size());
  std::vector<double> dyn, stat, change, inner;
  for (const OuterRow &r : run.rows()) {
    dyn.push_back(r.dynamic_objective), stat.push_back(r.static_objective);
    change.push_back(r.max_change), inner.push_back(r.inner_iterations);
  }
  s["dynamic_objective"] = dyn; // of the design each outer iteration started from
  s["static_objective"] = stat;
  s["max_change"] = change;
  s["inner_iterations"] = inner;
  s["final_dynamic_objective"] = run.final_row().dynamic_objective;
  s["final_dynamic_constraints"] = run.final_row().dynamic_constraints;
  s["constraint_bounds"] = in.optimizer.bounds;
  s["converged"] = run.converged();
  s["restarted"] = o.restart;
  s["volume_fraction"] = run.dynamic().design().volume_fraction();
  s["history"] = (fs::path(dir) / "history.csv").string();
  s["output"] = (fs::path(dir) / "design.xdmf").string();
  detail::write_summary(ctx, dir, s, t0);
  print0(ctx.comm(), "wrote %s/design.xdmf (the last static design), %s/history.csv, %s/esl/\n",
         dir.c_str(), dir.c_str(), dir.c_str());
  return 0;
}

} // namespace flexopt::app
