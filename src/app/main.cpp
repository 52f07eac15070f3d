/// flexopt — MPI-parallel adjoint topology optimization of flexible mechanisms.
///
/// Sample runs:
///   mpirun -n 2 build/flexopt info cases/cantilever
///   mpirun -n 2 build/flexopt simulate cases/cantilever -ksp_monitor
///   mpirun -n 2 build/flexopt modes cases/beam_modes --count 6 --free
///   mpirun -n 2 build/flexopt plan cases/slider_crank_flexible
///   mpirun -n 2 build/flexopt optimize cases/slider_crank_topopt
#include "flexopt/app/commands.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

const char *kUsage =
    "usage: flexopt <command> CASE [options] [PETSc options]\n"
    "\n"
    "commands:\n"
    "  info      the scene as understood: bodies, elements, DOFs, partition (no solve)\n"
    "  simulate  run the case's analysis (static: K u = f) and write out/static.xdmf\n"
    "  modes     lowest natural frequencies and mode shapes (SLEPc), out/modes.xdmf\n"
    "  optimize  SIMP topology optimization with MMA, static or dynamic: out/design.xdmf,\n"
    "            history.csv (dynamic: also motion_initial.xdmf, motion_final.xdmf)\n"
    "  check-gradient  Taylor and finite-difference checks of the adjoint gradients of a\n"
    "            topology optimization case (design:, objective:, constraints:)\n"
    "  plan      the model each body needs (rigid, FFRF with its modes, ACF) for the case's\n"
    "            accuracy, with reasons and predicted cost; what `model: auto` runs\n"
    "  report    pictures of a finished run: flexopt report OUT writes OUT/report/index.html\n"
    "            (optimize and a dynamic simulate write it themselves)\n"
    "\n"
    "options:\n"
    "  --out DIR    output directory (default CASE/out)\n"
    "  --count N    modes: number of modes (default 10)\n"
    "  --free       modes: ignore the case's supports (free-free body)\n"
    "  --body NAME  modes: the Craig-Bampton reduction basis of that body\n"
    "  --restart    optimize: continue from out/restart.h5\n"
    "  --max-iterations N  optimize: override optimizer.max_iterations\n"
    "  --scenario-groups N  optimize, check-gradient: run the scenarios (load cases) on N\n"
    "               groups of ranks (default: as many as ranks and scenarios allow; 1: one\n"
    "               after another on all ranks)\n"
    "  --fd-step H  check-gradient: finite-difference step (default 1e-2)\n"
    "  --design FILE  simulate (dynamic, with design:), check-gradient: the design of a run's\n"
    "               restart.h5\n"
    "  --gradient   simulate (dynamic, with design:): also the adjoint gradients\n"
    "  --auto       plan: estimate every body as if its model were auto\n"
    "  --no-report  optimize, simulate (dynamic): no OUT/report/ (FLEXOPT_REPORT=0 too)\n"
    "  --help       this text, or a command's: flexopt <command> --help\n"
    "\n"
    "PETSc and SLEPc options (-ksp_monitor, -log_view, -eps_view, ...) pass through; the\n"
    "case's `solver:` string is applied first, so the command line overrides it.\n"
    "\n"
    "examples:\n"
    "  mpirun -n 2 flexopt optimize cases/slider_crank_topopt   # a link designed in motion\n"
    "  mpirun -n 2 flexopt plan cases/slider_crank_flexible     # which model each body needs\n"
    "  mpirun -n 2 flexopt simulate cases/slider_crank_rigid    # then open out/motion.xdmf\n"
    "  mpirun -n 2 flexopt optimize cases/cantilever_topopt     # static topology optimization\n";

/// This process's rank in the launcher's job (Open MPI, PMIx, MPICH's PMI), before MPI is
/// initialized: 0 outside a launcher. Messages printed before MPI_Init (the usage, a bad
/// argument) are printed by rank 0 only.
int launcher_rank() {
  for (const char *name : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"})
    if (const char *v = std::getenv(name)) return std::atoi(v);
  return 0;
}

const char *command_help(const std::string &cmd) {
  if (cmd == "info")
    return "usage: flexopt info CASE [--out DIR]\n"
           "Loads the case and meshes its bodies, prints bodies, element type and counts, DOFs,\n"
           "physical groups and the partition (elements and nodes per rank); writes\n"
           "out/summary.json. Nothing is solved.\n";
  if (cmd == "simulate")
    return "usage: flexopt simulate CASE [--design FILE] [--gradient] [--out DIR] [PETSc options]\n"
           "analysis: static — solves K u = f for the single body with its supports, tractions\n"
           "and gravity. Writes out/static.xdmf + .h5 (nodal displacement, element von Mises\n"
           "stress, element owner rank) and out/summary.json (compliance, max_displacement,\n"
           "sensors). Default solver: CG + GAMG with the rigid-body near-null space.\n"
           "With load_cases: every load case, out/static.NAME.xdmf and summary.json's\n"
           "load_cases.NAME. With --design FILE (the restart.h5 of an optimize run of a case\n"
           "with a design: section): the body at that design, and its responses.\n"
           "analysis: dynamic — integrates the mechanism (generalized-alpha) and writes\n"
           "out/motion.xdmf + .h5 and out/summary.json (sensors, energy, Newton statistics).\n"
           "With a design: section, the design body takes the densities of design.initial, or\n"
           "of --design FILE (the restart.h5 of a run), and summary.json reports every\n"
           "response (responses: {objective, constraint0, ...}); --gradient also computes\n"
           "their adjoint gradients (out/gradient.xdmf, forward_s, adjoint_s, checkpoints).\n";
  if (cmd == "modes")
    return "usage: flexopt modes CASE [--count N] [--free] [--body NAME] [--out DIR] [PETSc/SLEPc "
           "options]\n"
           "Lowest N (default 10) natural frequencies of the body, K phi = omega^2 M phi, by\n"
           "SLEPc shift-and-invert with a MUMPS factorization. With --free the supports are\n"
           "ignored and the six rigid-body modes come first. Writes out/modes.xdmf (one mode\n"
           "per step) and out/summary.json (frequencies_hz).\n"
           "With --body NAME (any case): the Craig-Bampton basis of that body for a flexible\n"
           "model: clamped at its first interface, 6 static modes per other interface and N\n"
           "fixed-interface modes; prints their frequencies and, to choose N, the frequencies of\n"
           "the reduced model against the full body clamped at its first interface. Writes\n"
           "out/reduction.xdmf (the basis vectors as steps) and summary.json (reduction).\n";
  if (cmd == "optimize")
    return "usage: flexopt optimize CASE [--restart] [--max-iterations N] [--out DIR] [PETSc "
           "options]\n"
           "Minimizes the case's objective subject to its constraints over the element densities\n"
           "of design.region (Helmholtz or cone filter, SIMP, adjoint gradients, MMA). Prints one "
           "line\n"
           "per iteration (objective, each constraint, max density change, seconds split into\n"
           "the problem's parts and the update); stops when\n"
           "the max change falls below optimizer.tolerance or at optimizer.max_iterations.\n"
           "Writes out/design.xdmf + .h5 (density and filtered_density every output.every\n"
           "iterations and at the end, as time steps), out/history.csv and out/summary.json.\n"
           "After every iteration out/restart.h5 is replaced atomically; --restart continues\n"
           "from it (on any number of ranks) with the same iterates as an uninterrupted run.\n"
           "A restarted run's design.xdmf holds every iteration from the first (the earlier\n"
           "frames carried over from the interrupted run's design.h5.tmp or the last design.h5).\n"
           "Dynamic cases: at the end, out/motion_initial.xdmf and out/motion_final.xdmf show the\n"
           "mechanism moving with the first and the last design (densities on the design body).\n"
           "A design region touching an interface of its flexible body is refused.\n"
           "A case with scenarios: (load_cases:) runs them concurrently on groups of ranks, as\n"
           "many groups as ranks and scenarios allow (--scenario-groups N: N groups), and writes\n"
           "motion_initial.NAME.xdmf and motion_final.NAME.xdmf per scenario.\n";
  if (cmd == "check-gradient")
    return "usage: flexopt check-gradient CASE [--design FILE] [--fd-step H] [--out DIR] [PETSc "
           "options]\n"
           "For the objective and each constraint of the case's optimization problem, at the\n"
           "initial design (or that of --design FILE, a run's restart.h5; d then points into\n"
           "[0, 1] at the bounds): a Taylor test in a random direction d (remainders\n"
           "|R(x + h d) - R(x) - h g.d| for h = 1e-1 ... 1e-5 and their observed orders, 2 when "
           "the\n"
           "gradient g is right) and fourth-order central differences (step H, default 1e-2)\n"
           "on 5 design elements (among those with at least 1% of the largest objective\n"
           "sensitivity) against the adjoint gradient. Directions and elements depend on Gmsh "
           "element tags,\n"
           "so any number of ranks checks the same thing. Writes out/summary.json (taylor, fd,\n"
           "max_rel_err).\n";
  if (cmd == "plan")
    return "usage: flexopt plan CASE [--auto] [--out DIR] [PETSc options]\n"
           "Chooses the model of every body whose model is auto (docs/theory.md section 12),\n"
           "for the case's `accuracy` (default 1e-2: the relative error of the sensors): a\n"
           "rigid pre-run of the mechanism with every body that is not rigid reduced (up to 40\n"
           "fixed-interface modes) and held rigid, the linear elastic response of each to the\n"
           "forcing of that motion (kineto-elastodynamics), and rules that pick rigid, FFRF\n"
           "(its modes, geometric stiffening) or ACF. Prints per body the choice, the reasons\n"
           "with their numbers and the predicted cost; a body whose model is given keeps it,\n"
           "with a warning where the estimates disagree. --auto estimates every body, rigid\n"
           "ones too. `simulate`, `optimize` and `check-gradient` run the same plan first when\n"
           "a body is auto. Writes out/summary.json (plan: [{body, model, modes,\n"
           "geometric_stiffening, recommended_modes, reasons, predicted_cost_s, estimates}]).\n";
  if (cmd == "report")
    return "usage: flexopt report OUT\n"
           "Pictures of a finished run in OUT/report/: history.png (optimize: objective,\n"
           "constraints and design change per iteration, the projection's beta steps marked),\n"
           "design.png (the final design thresholded at 0.5; dynamic: the initial one too),\n"
           "motion.png (a dynamic run: the mechanism at 6 instants coloured by its elastic\n"
           "displacement, and the sensors) and index.html (the pictures, the responses, the\n"
           "time split, links to the XDMF files). The 3D pictures are rendered by ParaView\n"
           "(pvbatch; under xvfb-run without a display); where that is impossible the report\n"
           "says so and still writes the plots. optimize and a dynamic simulate write it at\n"
           "their end unless --no-report (or FLEXOPT_REPORT=0).\n";
  return nullptr;
}

} // namespace

/// Runs the command inside PETSc and MPI (the PETSc arguments `petsc_argv`) and turns its errors
/// into the exit status: a collective error is printed once, by rank 0, and every rank exits 1;
/// an error of one rank aborts the job.
int run_in_context(const flexopt::app::Options &opts, std::vector<char *> petsc_argv) {
  int pargc = static_cast<int>(petsc_argv.size());
  petsc_argv.push_back(nullptr);
  char **pargv = petsc_argv.data();
  int status = 0;
  try {
    flexopt::Context ctx(&pargc, &pargv, nullptr);
    try {
      status = flexopt::app::run(ctx, opts);
    } catch (const flexopt::Error &e) {
      if (e.collective()) {
        if (ctx.rank() == 0)
          std::fprintf(stderr, "flexopt: error: %s\n", flexopt::printable(e.what()).c_str());
        status = 1;
      } else {
        std::fprintf(stderr, "flexopt: error on rank %d: %s\n", ctx.rank(),
                     flexopt::printable(e.what()).c_str());
        std::fflush(stderr);
        MPI_Abort(ctx.comm(), 1);
      }
    } catch (const std::exception &e) {
      std::fprintf(stderr, "flexopt: internal error on rank %d: %s\n", ctx.rank(), e.what());
      std::fflush(stderr);
      MPI_Abort(ctx.comm(), 1);
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "flexopt: error: %s\n", flexopt::printable(e.what()).c_str());
    return 1;
  }
  return status;
}

int main(int argc, char **argv) {
  // Our own arguments are taken out before PETSc sees the command line.
  flexopt::app::Options opts;
  std::vector<char *> petsc_argv{argv[0]};
  bool want_help = false;
  std::string arg_error;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char *name) -> std::string {
      if (i + 1 >= argc) {
        arg_error = std::string(name) + " needs a value";
        return {};
      }
      return argv[++i];
    };
    // A positive integer option value; a malformed one is reported once.
    auto positive_int = [&](const char *name, int &target) {
      std::string v = value(name);
      try {
        std::size_t pos = 0;
        target = std::stoi(v, &pos);
        if (pos != v.size() || target < 1) throw std::invalid_argument(v);
      } catch (...) {
        if (arg_error.empty())
          arg_error = std::string(name) + " needs a positive integer, got '" + v + "'";
      }
    };
    if (a == "--help" || a == "-h" || a == "help")
      want_help = true;
    else if (a == "--out")
      opts.out = value("--out");
    else if (a == "--count")
      positive_int("--count", opts.count);
    else if (a == "--free")
      opts.free = true;
    else if (a == "--body")
      opts.body = value("--body");
    else if (a == "--restart")
      opts.restart = true;
    else if (a == "--design")
      opts.design = value("--design");
    else if (a == "--gradient")
      opts.gradient = true;
    else if (a == "--auto")
      opts.all_auto = true;
    else if (a == "--no-report")
      opts.report = false;
    else if (a == "--max-iterations")
      positive_int("--max-iterations", opts.max_iterations);
    else if (a == "--scenario-groups")
      positive_int("--scenario-groups", opts.scenario_groups);
    else if (a == "--fd-step") {
      const std::string v = value("--fd-step");
      try {
        std::size_t pos = 0;
        opts.fd_step = std::stod(v, &pos);
        if (pos != v.size() || !(opts.fd_step > 0 && opts.fd_step < 0.5))
          throw std::invalid_argument(v);
      } catch (...) {
        if (arg_error.empty()) arg_error = "--fd-step needs a number in (0, 0.5), got '" + v + "'";
      }
    } else if (a.rfind("--", 0) == 0)
      arg_error = "unknown option '" + a + "'";
    else if (a[0] == '-') {
      petsc_argv.push_back(argv[i]);
      // A PETSc option's value (if any) follows it and does not start with a letter dash.
      if (i + 1 < argc &&
          (argv[i + 1][0] != '-' || (argv[i + 1][1] >= '0' && argv[i + 1][1] <= '9') ||
           argv[i + 1][1] == '.'))
        petsc_argv.push_back(argv[++i]);
    } else if (opts.command.empty())
      opts.command = a;
    else if (opts.case_dir.empty())
      opts.case_dir = a;
    else
      arg_error = "unexpected argument '" + a + "'";
  }

  const bool speaks = launcher_rank() == 0;
  if (want_help || opts.command.empty()) {
    const char *h = opts.command.empty() ? nullptr : command_help(opts.command);
    if (speaks) std::fputs(h ? h : kUsage, opts.command.empty() && !want_help ? stderr : stdout);
    return want_help ? 0 : 2;
  }
  if (!command_help(opts.command))
    arg_error = "unknown command '" + opts.command + "'";
  else if (opts.case_dir.empty())
    arg_error = opts.command == "report" ? "missing OUT directory" : "missing CASE directory";
  if (!arg_error.empty()) {
    if (speaks) std::fprintf(stderr, "flexopt: %s (see flexopt --help)\n", arg_error.c_str());
    return 2;
  }

  return run_in_context(opts, petsc_argv);
}
