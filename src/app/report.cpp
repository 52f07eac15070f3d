/// `flexopt report OUT` and the report written at the end of `optimize` and of a dynamic
/// `simulate` (docs/output.md "Report"): rank 0 runs scripts/report.py on the output directory.
#include "app_common.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/plan/plan.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <spawn.h>
#include <string>
#include <sys/wait.h>
#include <vector>

extern char **environ;

namespace flexopt::app {

namespace {

/// The directory of report.py: $FLEXOPT_SCRIPTS_DIR, else the source tree's scripts/.
std::string scripts_dir() {
  if (const char *d = std::getenv("FLEXOPT_SCRIPTS_DIR"); d && *d) return d;
  return FLEXOPT_SCRIPTS_DIR;
}

/// Debian's Python (where python3-matplotlib is), else the first python3 on PATH.
std::string python() {
  return std::filesystem::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
}

/// Runs `argv` and waits; its exit status, or -1 if it could not be started.
int spawn_and_wait(const std::vector<std::string> &args) {
  std::vector<char *> argv;
  for (const std::string &a : args) argv.push_back(const_cast<char *>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

} // namespace

bool report_wanted(const Options &o) {
  const char *env = std::getenv("FLEXOPT_REPORT");
  return o.report && !(env && std::string(env) == "0");
}

int write_report(const Context &ctx, const std::string &out_dir) {
  int status = 0;
  if (ctx.rank() == 0) {
    std::fflush(stdout);
    const std::string script = scripts_dir() + "/report.py";
    status = std::filesystem::exists(script) ? spawn_and_wait({python(), script, out_dir}) : -2;
    if (status == -2)
      std::fprintf(stderr, "flexopt: report: %s not found (set FLEXOPT_SCRIPTS_DIR)\n",
                   script.c_str());
    else if (status == -1)
      std::fprintf(stderr, "flexopt: report: could not run %s\n", python().c_str());
    std::fflush(stderr);
  }
  MPI_Bcast(&status, 1, MPI_INT, 0, ctx.comm());
  return status;
}

void check_given_models(const Context &ctx, const Options &o, const io::Case &c) {
  const char *env = std::getenv("FLEXOPT_PLAN_CHECK");
  if (!c.dynamic() || !o.plan.is_null() || (env && std::string(env) == "0")) return;
  const bool flexible =
      std::any_of(c.scene.bodies.begin(), c.scene.bodies.end(), [](const auto &b) {
        return b.model == dynamics::BodyModel::Ffrf || b.model == dynamics::BodyModel::Acf;
      });
  if (!flexible) return;
  plan::PlanOptions po;
  po.report = false;
  plan::Plan p;
  try {
    p = plan::make_plan(ctx.comm(), io::plan_settings(c), po);
  } catch (const Error &e) {
    if (!e.collective()) throw;
    print0(ctx.comm(), "plan: note: the estimates of the given models could not be made: %s\n",
           e.what());
    return;
  }
  for (const plan::BodyPlan &bp : p.bodies) {
    if (bp.given == dynamics::BodyModel::Auto || !bp.estimated) continue;
    if (bp.recommended != bp.model)
      print0(ctx.comm(), "plan: body %s is given model %s; the estimates recommend %s\n",
             bp.body.c_str(), dynamics::model_name(bp.model), dynamics::model_name(bp.recommended));
    for (const std::string &w : bp.warnings)
      print0(ctx.comm(), "plan: body %s: warning: %s\n", bp.body.c_str(), w.c_str());
  }
  print0(ctx.comm(), "plan: (flexopt plan %s gives the reasons and numbers; %.1f s)\n",
         o.case_dir.c_str(), p.seconds);
}

void after_run(const Context &ctx, const Options &o, const io::Case &c, const std::string &dir) {
  check_given_models(ctx, o, c);
  if (report_wanted(o) && write_report(ctx, dir) != 0)
    print0(ctx.comm(),
           "%s: warning: the report failed (the run's results are complete; flexopt report %s "
           "tries again)\n",
           o.command.c_str(), dir.c_str());
}

int run_report(const Context &ctx, const Options &o) {
  if (!std::filesystem::exists(std::filesystem::path(o.case_dir) / "summary.json"))
    throw Error(o.case_dir + ": no summary.json: `flexopt report OUT` takes the output directory "
                             "of a finished run (CASE/out by default)",
                true);
  return write_report(ctx, o.case_dir) == 0 ? 0 : 1;
}

} // namespace flexopt::app
