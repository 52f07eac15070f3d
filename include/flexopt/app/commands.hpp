#pragma once
/// \file The flexopt commands (info, simulate, modes, optimize, check-gradient, plan) behind the
/// command line.
#include "flexopt/core/context.hpp"
#include "flexopt/io/json.hpp"

#include <string>

namespace flexopt::app {

struct Options {
  std::string command; ///< info | simulate | modes | optimize | check-gradient | plan | report
  std::string case_dir;
  std::string out;        ///< output directory; empty: <case>/out
  int count = 10;         ///< modes: number of modes
  bool free = false;      ///< modes: ignore supports
  std::string body;       ///< modes: Craig-Bampton basis of this body (--body NAME)
  bool restart = false;   ///< optimize: continue from out/restart.h5
  int max_iterations = 0; ///< optimize: overrides optimizer.max_iterations when > 0
  double fd_step = 0;     ///< check-gradient: finite-difference step h (0: the problem's)
  /// optimize, check-gradient: groups of ranks the scenarios (or load cases) run on (0: as many
  /// as ranks and conditions allow; 1: one after another on all ranks)
  int scenario_groups = 0;
  std::string design;    ///< simulate (dynamic): the design of this restart.h5
  bool gradient = false; ///< simulate (dynamic): also the adjoint gradients
  bool all_auto = false; ///< plan: estimate every body as if its model were auto (--auto)
  bool report = true;    ///< optimize, dynamic simulate: write OUT/report/ (--no-report: no)
  /// The plan that resolved the case's `model: auto` bodies (set by run(); null: none), for
  /// summary.json.
  io::Json plan;
};

/// Runs one command. Collective. Returns the process exit status; throws flexopt::Error.
int run(const Context &ctx, const Options &options);

} // namespace flexopt::app
