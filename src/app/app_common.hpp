#pragma once
/// \file Helpers shared by the commands (private to the app module).
#include "flexopt/app/commands.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/optimize/design_problem.hpp"

namespace flexopt::adjoint {
class DynamicProblem;
}

#include <functional>
#include <memory>
#include <string>

namespace flexopt::app {

namespace detail {
/// The command's output directory (created; a stale summary.json removed). Collective.
std::string output_directory(const Context &ctx, const Options &o);
/// The summary fields every command writes.
io::Json base_summary(const Context &ctx, const Options &o, const io::Case &c);
/// Adds wall_s and writes summary.json atomically on rank 0. Collective.
void write_summary(const Context &ctx, const std::string &dir, io::Json &s, double t0);
/// `dir`/gradient.xdmf + .h5: the gradients of `e` per element of the design body (cell arrays
/// gradient_objective, gradient_constraint0, ...; 0 outside the design region). Returns the
/// XDMF path. Collective.
std::string write_gradients(const optimize::DesignProblem &problem, const optimize::Evaluation &e,
                            const std::string &dir);
/// Reads the design variables of a run's restart.h5 into x (the field's layout) and sets the
/// projection sharpness of the run's continuation stage on `design`. Collective; throws a
/// collective flexopt::Error naming the file if it holds no design.
void load_design(MPI_Comm comm, const io::Case &c, optimize::DesignProblem &design,
                 const std::string &file, Vec x);
/// The design problem of a case: the static SIMP problem or the dynamic one (adjoint module);
/// a case with scenarios or load cases: their optimize::ScenarioProblem on `scenario_groups`
/// groups of ranks (0: as many as ranks and conditions allow). `optimizing`: a dynamic design
/// region touching an interface of its flexible body is refused. Collective.
std::unique_ptr<optimize::DesignProblem> create_design_problem(MPI_Comm comm, const io::Case &c,
                                                               bool optimizing,
                                                               const std::string &dir,
                                                               int scenario_groups = 0);
/// Every condition of c (its scenarios or load cases), one after another on all ranks: prints
/// "scenario NAME (k of n)" (or "load case ..."), runs one(the condition's case, NAME, figures)
/// with the lines it prints prefixed "[NAME] ", and returns the figures keyed by NAME.
/// Collective.
io::Json
each_condition(const Context &ctx, const io::Case &c,
               const std::function<void(const io::Case &, const std::string &, io::Json &)> &one);
} // namespace detail

/// `optimize` of a case with `optimizer: {method: esl}`: the equivalent static loads' outer
/// iteration (src/app/esl.cpp; docs/theory.md section 14). Collective.
int run_esl(const Context &ctx, const Options &o, const io::Case &c, double t0);

/// `check-gradient`: the Taylor test and central differences of a design problem's adjoint
/// gradients, on evaluations solved to round-off, with their measured noise
/// (src/app/check_gradient.cpp; docs/theory.md section 5, "Checking a gradient"). Collective.
int run_check_gradient(const Context &ctx, const Options &o, const io::Case &c, double t0);
/// The case's `solver:` string for check-gradient: without its tolerances and warm start
/// (-*ksp_rtol, -*ksp_atol, -*eps_tol, -fx_warm_start), which are named on rank 0. Collective.
std::string check_gradient_solver_options(const Context &ctx, const io::Case &c);

/// Whether a run writes its report (Options::report, and FLEXOPT_REPORT=0 in the environment
/// turns it off: the test suite's runs).
bool report_wanted(const Options &o);
/// Runs scripts/report.py on `out_dir` on rank 0 (docs/output.md "Report"); its exit status on
/// every rank (0: written; the pictures may still be missing, which the report says).
/// Collective.
int write_report(const Context &ctx, const std::string &out_dir);
/// After a dynamic simulate or optimize whose flexible bodies' models are given (none auto): the
/// plan's estimates, and a line per body where they recommend another model or warn (docs/theory.md
/// section 12); FLEXOPT_PLAN_CHECK=0 skips it (the test suite). A plan that fails is a note: the
/// run's results stand. Collective.
void check_given_models(const Context &ctx, const Options &o, const io::Case &c);
/// The end of a dynamic simulate or an optimize, after its results are written: the check of
/// the given models, then the report (a failed report is a warning). Collective.
void after_run(const Context &ctx, const Options &o, const io::Case &c, const std::string &dir);
/// `flexopt report OUT`. Collective.
int run_report(const Context &ctx, const Options &o);

/// `simulate` for `analysis: dynamic`: generalized-alpha run of the mechanism, motion.xdmf and
/// summary.json. Collective.
int run_dynamic(const Context &ctx, const Options &o, const io::Case &c, double t0);

/// After `optimize` on a dynamic case: the mechanism with the first design (design.initial) and
/// with the last one (dir/restart.h5) integrated and written to dir/motion_initial`suffix`.xdmf
/// and dir/motion_final`suffix`.xdmf; their responses and motion figures into s (motion_initial,
/// motion_final). Collective.
void write_design_motions(const Context &ctx, const io::Case &c, adjoint::DynamicProblem &problem,
                          const std::string &dir, io::Json &s, const std::string &suffix = "");
/// The same for every scenario of c, one after another on all ranks (motion_initial.NAME.xdmf,
/// ...), into s["scenario_motions"][NAME]. Collective.
void write_scenario_motions(const Context &ctx, const io::Case &c, const std::string &dir,
                            io::Json &s);

} // namespace flexopt::app
