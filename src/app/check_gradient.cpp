/// \file `flexopt check-gradient`: the case's design problem with its evaluations solved to
/// round-off where the user's options allow it (DesignProblem::solve_to_round_off), checked by
/// optimize::check_gradient (docs/theory.md section 5, "Gradient checks"), with gradient.xdmf
/// and summary.json.
#include "app_common.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/optimize/gradient_check.hpp"

#include <algorithm>
#include <filesystem>
#include <memory>

namespace fs = std::filesystem;

namespace flexopt::app {

namespace {

/// What the check says of its own accuracy before it starts.
void print_limits(const Context &ctx, const std::vector<std::string> &limits, bool dynamic) {
  if (limits.empty()) {
    print0(ctx.comm(), "check-gradient: every evaluation solved to round-off (%s)\n",
           dynamic ? "Newton's method proper at every step, time.newton_reuse = 0; direct solves"
                   : "iterative solves from zero to a relative residual of 1e-12");
    return;
  }
  print0(ctx.comm(), "check-gradient: solver-limited: ");
  for (std::size_t k = 0; k < limits.size(); ++k)
    print0(ctx.comm(), "%s%s", k ? "; " : "", limits[k].c_str());
  print0(ctx.comm(), " (options given on the command line). The check judges the gradient only "
                     "above the noise this leaves, measured below; leave them out to check to "
                     "round-off\n");
}

} // namespace

std::string check_gradient_solver_options(const Context &ctx, const io::Case &c) {
  // Tolerances and the warm start: the optimization's speed, not part of what is checked.
  const std::vector<std::string> loosening{"ksp_rtol", "ksp_atol", "eps_tol", "fx_warm_start"};
  std::string kept, left_out;
  for (const PetscOption &p : parse_petsc_options(c.solver, c.file + ": solver")) {
    const std::string text = p.name + (p.value.empty() ? "" : " " + p.value);
    const bool loose = std::any_of(loosening.begin(), loosening.end(), [&](const std::string &l) {
      return p.name.size() >= l.size() &&
             p.name.compare(p.name.size() - l.size(), l.size(), l) == 0;
    });
    (loose ? left_out : kept) += (loose ? left_out : kept).empty() ? text : " " + text;
  }
  if (!left_out.empty())
    print0(
        ctx.comm(),
        "check-gradient: the case's solver: options %s are left out, so that every evaluation is "
        "solved to round-off (optimize keeps them); give them on the command line to check "
        "the gradient at them\n",
        left_out.c_str());
  return kept;
}

int run_check_gradient(const Context &ctx, const Options &o, const io::Case &c, double t0) {
  const std::string dir = detail::output_directory(ctx, o);
  std::unique_ptr<optimize::DesignProblem> problem =
      detail::create_design_problem(ctx.comm(), c, false, dir, o.scenario_groups);
  const std::vector<std::string> limits = problem->solve_to_round_off();
  PetscBool warm = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_warm_start", &warm, nullptr));
  if (warm)
    print0(ctx.comm(), "check-gradient: -fx_warm_start does not apply: every solve starts from "
                       "zero (a warm start's error follows the previous design, the other side of "
                       "a finite difference, and biases it)\n");
  print_limits(ctx, limits, c.dynamic());
  const std::size_t nr = problem->response_names().size();
  print0(ctx.comm(), "check-gradient: %lld design variables, %zu response(s)\n",
         static_cast<long long>(problem->design_size()), nr);

  Vec x0 = problem->create_design_vector();
  if (o.design.empty()) {
    problem->initial_design(x0);
  } else {
    detail::load_design(ctx.comm(), c, *problem, o.design, x0);
    std::string betas;
    for (double b : problem->design().betas())
      betas += (betas.empty() ? "" : ", ") + std::to_string(b);
    print0(ctx.comm(), "check-gradient: at the design of %s (projection beta %s)\n",
           o.design.c_str(), betas.c_str());
  }
  optimize::Evaluation base;
  const optimize::GradientCheckResult check =
      optimize::check_gradient(*problem, x0, optimize::GradientCheckOptions{o.fd_step}, base);
  const std::string gradient_file = detail::write_gradients(*problem, base, dir);
  io::Json warnings = io::Json::array();
  bool warned = false;
  for (const std::string &w : optimize::stuck_responses(*problem, base)) {
    print0(ctx.comm(), "check-gradient: warning: %s\n", w.c_str());
    warnings.push_back(w);
    warned = true;
  }
  io::Json s = detail::base_summary(ctx, o, c);
  s["taylor"] = check.taylor;
  s["fd"] = check.fd;
  s["fd_step"] = check.fd_step;
  s["max_rel_err"] = check.max_rel_err;
  s["max_rel_err_beyond_uncertainty"] = check.max_rel_err_beyond_uncertainty;
  io::Json limit_list = io::Json::array();
  for (const std::string &l : limits) limit_list.push_back(l);
  s["solver_limits"] = limit_list;
  s["solver_limited"] = !limits.empty();
  s["noise_measured"] = check.noise_measured;
  if (warned) s["warnings"] = warnings;
  s["noise_above_round_off"] = check.noise_above_round_off;
  problem->describe(s);
  FX_PETSC(VecDestroy(&x0));
  detail::write_summary(ctx, dir, s, t0);
  if (check.noise_above_round_off)
    print0(ctx.comm(), "check-gradient: the evaluations' measured noise lies above their round-off "
                       "(the noise floors above): orders and differences are judged above it\n");
  if (!limits.empty())
    print0(ctx.comm(),
           "check-gradient: solver-limited (the command line's options): max relative error of "
           "the adjoint gradient %.2e beyond the differences' uncertainty (%.2e in all, the "
           "solves' share included)\n",
           check.max_rel_err_beyond_uncertainty, check.max_rel_err);
  else
    print0(ctx.comm(),
           "check-gradient: max relative error of the adjoint gradient %.2e (%.2e beyond the "
           "differences' uncertainty)\n",
           check.max_rel_err, check.max_rel_err_beyond_uncertainty);
  print0(ctx.comm(),
         "check-gradient: wrote %s (cell arrays gradient_objective, "
         "gradient_constraint0, ...) and %s\n",
         gradient_file.c_str(), (fs::path(dir) / "summary.json").c_str());
  return 0;
}

} // namespace flexopt::app
