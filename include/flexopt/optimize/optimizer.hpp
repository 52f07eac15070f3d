#pragma once
/// \file The optimization loop: MMA on the topology problem, with history and density output.
#include "flexopt/io/case.hpp"
#include "flexopt/optimize/design_problem.hpp"

#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

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

/// Runs the case's optimization problem (design:, objective:, constraints:, optimizer:) on
/// `problem` (static or dynamic: the same loop for both),
/// writing `out_dir`/history.csv and `out_dir`/design.xdmf (+ .h5: design and filtered
/// densities every output.every iterations and at the last). Prints one line per
/// iteration. Collective.
/// With `restart`, continues from `out_dir`/restart.h5 (written atomically after every
/// iteration: design, MMA state, objective scale and history, keyed by element tag so that
/// any number of ranks can resume); the iterates are those of an uninterrupted run.
OptimizationResult run_optimization(MPI_Comm comm, DesignProblem &problem, const io::Case &c,
                                    const std::string &out_dir, bool restart = false);

} // namespace flexopt::optimize
