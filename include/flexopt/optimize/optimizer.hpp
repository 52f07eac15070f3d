#pragma once
/// \file The optimization loop: MMA on the topology problem, with history and density output.
#include "flexopt/optimize/design_problem.hpp"

#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// The MMA loop's settings (`optimizer:`, the constraints' bounds, `output.every`).
struct OptimizerSettings {
  int max_iterations = 100;
  double move_limit = 0.2;
  double tolerance = 1e-3; ///< stop when the max design change is below
  /// design.xdmf: the densities every this many iterations (and at the last)
  int output_every = 1;
  std::vector<double> bounds; ///< each constraint's upper bound, in the problem's order
};

struct OptimizationResult {
  int iterations = 0;
  std::vector<double> objective;                ///< per iteration (unscaled)
  std::vector<std::vector<double>> constraints; ///< per iteration, response values
  std::vector<double> max_change;               ///< per iteration
  /// The parts of an iteration's seconds (DesignProblem::timings, then "update") and their
  /// values per iteration (not a number for iterations of a restart file that lacks them).
  std::vector<std::string> split_names;
  std::vector<std::vector<double>> seconds_split;
  double volume_fraction = 0; ///< final, of the design region
  bool converged = false;     ///< stopped on optimizer.tolerance
  std::string stop_reason;
  long long dofs = 0, elements = 0, design_variables = 0;
  std::string output; ///< design.xdmf path
};

/// Runs MMA on `problem` (static or dynamic: the same loop for both), with the projection
/// continuation of its design field (DesignSettings::beta, beta_every), writing
/// `out_dir`/history.csv and `out_dir`/design.xdmf (+ .h5: design and filtered densities every
/// settings.output_every iterations and at the last). Prints one line per iteration.
/// Collective.
/// With `restart`, continues from `out_dir`/restart.h5 (written atomically after every
/// iteration: design, MMA state, objective scale and history, keyed by element tag so that
/// any number of ranks can resume); the iterates are those of an uninterrupted run.
OptimizationResult run_optimization(MPI_Comm comm, DesignProblem &problem,
                                    const OptimizerSettings &settings, const std::string &out_dir,
                                    bool restart = false);

} // namespace flexopt::optimize
