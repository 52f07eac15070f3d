#include "flexopt/optimize/optimizer.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/io/restart.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/grid_layout.hpp"
#include "flexopt/optimize/mma.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

namespace flexopt::optimize {

namespace {

/// Writes the densities of the current evaluation as one step of the design collection.
void write_densities(io::XdmfWriter &writer, const DesignField &p, double step) {
  writer.begin_step(step);
  const PetscScalar *a;
  FX_PETSC(VecGetArrayRead(p.density(), &a));
  writer.cell_scalar("density", a);
  FX_PETSC(VecRestoreArrayRead(p.density(), &a));
  FX_PETSC(VecGetArrayRead(p.filtered(), &a));
  writer.cell_scalar("filtered_density", a);
  FX_PETSC(VecRestoreArrayRead(p.filtered(), &a));
  FX_PETSC(VecGetArrayRead(p.physical(), &a));
  writer.cell_scalar("physical_density", a);
  FX_PETSC(VecRestoreArrayRead(p.physical(), &a));
}

/// Local values of a design-layout Vec.
std::vector<double> local_values(Vec v) {
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(v, &n));
  const PetscScalar *a;
  FX_PETSC(VecGetArrayRead(v, &a));
  std::vector<double> out(a, a + n);
  FX_PETSC(VecRestoreArrayRead(v, &a));
  return out;
}

void set_local_values(Vec v, const std::vector<double> &values) {
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  std::copy(values.begin(), values.end(), a);
  FX_PETSC(VecRestoreArray(v, &a));
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

} // namespace

OptimizationResult run_optimization(MPI_Comm comm, DesignProblem &design,
                                    const OptimizerSettings &c, const std::string &out_dir,
                                    bool restart) {
  DesignProblem *problem = &design;
  const auto &names = problem->response_names();
  const std::size_t m = c.bounds.size();
  OptimizationResult result;
  result.dofs = problem->dofs();
  result.elements = problem->mesh().global_elements;
  result.design_variables = problem->design_size();

  Vec x = problem->create_design_vector(), xold, xmin, xmax;
  problem->initial_design(x);
  FX_PETSC(VecDuplicate(x, &xold));
  FX_PETSC(VecDuplicate(x, &xmin));
  FX_PETSC(VecDuplicate(x, &xmax));
  // The move limit is applied as an outer box [max(0, x - m), min(1, x + m)] handed to MMA as
  // its bounds (Aage & Lazarov 2013), so that the initial asymptotes x -+ 0.5 (xmax - xmin) and
  // their clamps scale with the move limit rather than with [0, 1] (docs/theory-mma.md §5).
  MmaSettings settings;
  settings.move_limit = 1.0;
  auto mma = Mma::create(x, static_cast<int>(m), settings);

  // MMA works best with an objective of order 1 ... 100 and constraints of order 1 (Svanberg
  // 2007; its subproblem tolerance is absolute, docs/theory-mma.md): the objective is scaled
  // to 10 at the first iteration, and constraints are g_i = R_i / max_i - 1 (max_i > 0; else
  // (R_i - max_i) / |max_i|, or R_i for max_i = 0).
  double objective_scale = 1.0;
  std::vector<Vec> dg(m);
  for (auto &v : dg) FX_PETSC(VecDuplicate(x, &v));
  Vec df0;
  FX_PETSC(VecDuplicate(x, &df0));

  io::XdmfWriter writer(mesh::grid_layout(problem->mesh()), out_dir, "design");
  std::ostringstream history;
  history << "iteration,objective";
  for (std::size_t i = 0; i < m; ++i) history << "," << names[i + 1];
  history << ",max_change,seconds";
  // The split of an iteration's seconds: the problem's parts, then the update (the filter, the
  // pull-back, MMA and the output: the rest of the iteration).
  std::vector<std::string> split_labels;
  for (const Timing &t : problem->timings()) {
    history << ",seconds_" << t.name;
    split_labels.push_back(t.label);
    result.split_names.push_back(t.name);
  }
  split_labels.push_back("update");
  result.split_names.emplace_back("update");
  const std::size_t nsplit = split_labels.size();
  history << ",seconds_update\n";

  print0(
      comm,
      "optimize: %lld design variables, %zu constraint(s), at most %d iterations, move limit %g, "
      "%s\n",
      static_cast<long long>(problem->design_size()), m, c.max_iterations, c.move_limit,
      problem->field().filter_description().c_str());
  print0(comm, "%5s %16s", "it", "objective");
  for (std::size_t i = 0; i < m; ++i)
    print0(comm, " %16s",
           ("c" + std::to_string(i) + ":" + names[i + 1].substr(names[i + 1].find(':') + 1))
               .substr(0, 16)
               .c_str());
  print0(comm, " %10s", "change");
  for (const std::string &l : split_labels) print0(comm, " %8s", l.substr(0, 8).c_str());
  print0(comm, " %8s\n", "s");

  const std::string restart_path = (std::filesystem::path(out_dir) / "restart.h5").string();
  const std::vector<std::uint64_t> tags(problem->design_tags().begin(),
                                        problem->design_tags().end());
  int first = 1;
  // Projection continuation: stage index into design.projection.beta and its first iteration.
  const std::vector<double> &betas = problem->field().settings().beta;
  int stage = 0, stage_start = 1;
  std::vector<double> seconds_list, split_list; // per iteration; the split k x nsplit
  if (restart) {
    const io::RestartData r = io::read_restart(comm, restart_path, tags);
    const auto &meta =
        r.arrays.at("meta"); // iteration, objective scale, m, beta stage, its first iteration
    const int done = static_cast<int>(meta.at(0));
    if (static_cast<std::size_t>(meta.at(2)) != m)
      throw Error(restart_path + ": written for " + std::to_string(static_cast<int>(meta.at(2))) +
                      " constraints; the case has " + std::to_string(m),
                  true);
    objective_scale = meta.at(1);
    stage = static_cast<int>(meta.at(3));
    stage_start = static_cast<int>(meta.at(4));
    set_local_values(x, r.fields.at("x"));
    Mma::State st;
    st.iteration = done;
    Vec state_vecs[4];
    const char *names4[4] = {"xold1", "xold2", "low", "upp"};
    for (int i = 0; i < 4; ++i) {
      FX_PETSC(VecDuplicate(x, &state_vecs[i]));
      set_local_values(state_vecs[i], r.fields.at(names4[i]));
    }
    st.xold1 = state_vecs[0], st.xold2 = state_vecs[1], st.low = state_vecs[2],
    st.upp = state_vecs[3];
    mma->restore(st);
    for (Vec &v : state_vecs) FX_PETSC(VecDestroy(&v));
    const auto &obj = r.arrays.at("objective"), &chg = r.arrays.at("max_change"),
               &con = r.arrays.at("constraints"), &sec = r.arrays.at("seconds");
    // The split, k x nsplit (a restart file written without it: not a number).
    const auto split = r.arrays.find("seconds_split");
    if (split != r.arrays.end() && split->second.size() == static_cast<std::size_t>(done) * nsplit)
      split_list = split->second;
    else
      split_list.assign(static_cast<std::size_t>(done) * nsplit, std::nan(""));
    for (int k = 0; k < done; ++k) {
      result.objective.push_back(obj.at(static_cast<std::size_t>(k)));
      result.max_change.push_back(chg.at(static_cast<std::size_t>(k)));
      result.constraints.emplace_back(con.begin() + static_cast<std::ptrdiff_t>(k * m),
                                      con.begin() + static_cast<std::ptrdiff_t>((k + 1) * m));
      char buf[64];
      std::snprintf(buf, sizeof buf, "%d,%.17g", k + 1, obj[static_cast<std::size_t>(k)]);
      history << buf;
      for (std::size_t i = 0; i < m; ++i) {
        std::snprintf(buf, sizeof buf, ",%.17g", con[static_cast<std::size_t>(k) * m + i]);
        history << buf;
      }
      std::snprintf(buf, sizeof buf, ",%.17g,%.6g", chg[static_cast<std::size_t>(k)],
                    sec[static_cast<std::size_t>(k)]);
      history << buf;
      for (std::size_t p = 0; p < nsplit; ++p) {
        std::snprintf(buf, sizeof buf, ",%.6g",
                      split_list[static_cast<std::size_t>(k) * nsplit + p]);
        history << buf;
      }
      history << '\n';
    }
    seconds_list = sec;
    result.iterations = done;
    first = done + 1;
    print0(comm, "optimize: restarting from %s after iteration %d\n", restart_path.c_str(), done);
  }

  Evaluation e;
  for (int k = first; k <= c.max_iterations; ++k) {
    const double t0 = wall_time();
    if (!betas.empty()) problem->field().set_beta(betas[static_cast<std::size_t>(stage)]);
    problem->evaluate(x, true, e);
    if (!std::isfinite(e.objective))
      throw Error("optimize: iteration " + std::to_string(k) + ": the objective is not finite",
                  true);
    if (k == 1) objective_scale = std::abs(e.objective) > 0 ? 10.0 / std::abs(e.objective) : 1.0;
    const int stride = std::max(c.output_every, 1);
    const bool write = (k - 1) % stride == 0;
    if (write) write_densities(writer, problem->field(), k - 1);

    FX_PETSC(VecCopy(e.d_objective, df0));
    FX_PETSC(VecScale(df0, objective_scale));
    std::vector<double> g(m);
    for (std::size_t i = 0; i < m; ++i) {
      // R <= max as g = R / max - 1 <= 0 for a positive bound; a bound <= 0 (a sensor
      // component that must stay negative) as g = (R - max) / |max| (or R when max = 0).
      const double bound = c.bounds[i];
      const double scale = bound > 0 ? bound : bound < 0 ? -bound : 1.0;
      g[i] = bound > 0 ? e.constraints[i] / bound - 1.0 : (e.constraints[i] - bound) / scale;
      FX_PETSC(VecCopy(e.d_constraints[i], dg[i]));
      FX_PETSC(VecScale(dg[i], 1.0 / scale));
    }
    FX_PETSC(VecCopy(x, xold));
    set_move_box(x, c.move_limit, xmin, xmax);
    mma->update(x, xmin, xmax, e.objective * objective_scale, df0, g, dg);
    const double change = max_abs_change(x, xold);
    const double seconds = wall_time() - t0;
    std::vector<double> split;
    double parts = 0;
    for (const Timing &t : problem->timings()) {
      split.push_back(t.seconds);
      parts += t.seconds;
    }
    split.push_back(seconds - parts);

    result.iterations = k;
    result.objective.push_back(e.objective);
    result.constraints.push_back(e.constraints);
    result.max_change.push_back(change);
    print0(comm, "%5d %16.9e", k, e.objective);
    for (double v : e.constraints) print0(comm, " %16.9e", v);
    print0(comm, " %10.3e", change);
    for (double v : split) print0(comm, " %8.2f", v);
    print0(comm, " %8.2f\n", seconds);
    char buf[64];
    std::snprintf(buf, sizeof buf, "%d,%.17g", k, e.objective);
    history << buf;
    for (double v : e.constraints) {
      std::snprintf(buf, sizeof buf, ",%.17g", v);
      history << buf;
    }
    std::snprintf(buf, sizeof buf, ",%.17g,%.6g", change, seconds);
    history << buf;
    for (double v : split) {
      std::snprintf(buf, sizeof buf, ",%.6g", v);
      history << buf;
    }
    history << '\n';
    seconds_list.push_back(seconds);
    split_list.insert(split_list.end(), split.begin(), split.end());

    // Restart point after every iteration (atomic: a kill at any moment leaves the previous
    // complete file).
    io::RestartData rd;
    rd.tags = tags;
    rd.fields["x"] = local_values(x);
    const Mma::State st = mma->state();
    rd.fields["xold1"] = local_values(st.xold1);
    rd.fields["xold2"] = local_values(st.xold2);
    rd.fields["low"] = local_values(st.low);
    rd.fields["upp"] = local_values(st.upp);
    // Advance the projection continuation: after `every` iterations at this beta, or when
    // the design has settled at it.
    const bool last_stage = betas.empty() || stage + 1 == static_cast<int>(betas.size());
    const bool settled = change < c.tolerance;
    if (!last_stage && (settled || k - stage_start + 1 >= problem->field().settings().beta_every)) {
      ++stage;
      stage_start = k + 1;
      print0(comm, "optimize: projection beta -> %g from iteration %d\n",
             betas[static_cast<std::size_t>(stage)], k + 1);
    }
    rd.arrays["meta"] = {static_cast<double>(k), objective_scale, static_cast<double>(m),
                         static_cast<double>(stage), static_cast<double>(stage_start)};
    rd.arrays["objective"] = result.objective;
    rd.arrays["max_change"] = result.max_change;
    rd.arrays["seconds"] = seconds_list;
    rd.arrays["seconds_split"] = split_list;
    std::vector<double> flat;
    for (const auto &row : result.constraints) flat.insert(flat.end(), row.begin(), row.end());
    rd.arrays["constraints"] = flat;
    io::write_restart(comm, restart_path, rd);
    if (change < c.tolerance && last_stage) {
      result.converged = true;
      result.stop_reason = "max design change " + std::to_string(change) + " < tolerance " +
                           std::to_string(c.tolerance);
      break;
    }
  }
  if (!result.converged) result.stop_reason = "max_iterations reached";
  for (std::size_t k = 0; k * nsplit < split_list.size(); ++k)
    result.seconds_split.emplace_back(split_list.begin() + static_cast<std::ptrdiff_t>(k * nsplit),
                                      split_list.begin() +
                                          static_cast<std::ptrdiff_t>((k + 1) * nsplit));
  // Final state: the design after the last update.
  problem->evaluate(x, false, e);
  write_densities(writer, problem->field(), result.iterations);
  result.volume_fraction = problem->field().volume_fraction();
  result.output = writer.close();
  run_on_root(comm, 0, [&] {
    io::write_file_atomic((std::filesystem::path(out_dir) / "history.csv").string(), history.str());
  });
  print0(comm,
         "optimize: stopped after %d iterations: %s; final objective %.9e, volume fraction %.6f\n",
         result.iterations, result.stop_reason.c_str(), e.objective, result.volume_fraction);
  for (auto &v : dg) FX_PETSC(VecDestroy(&v));
  FX_PETSC(VecDestroy(&df0));
  FX_PETSC(VecDestroy(&x));
  FX_PETSC(VecDestroy(&xold));
  FX_PETSC(VecDestroy(&xmin));
  FX_PETSC(VecDestroy(&xmax));
  return result;
}

} // namespace flexopt::optimize
