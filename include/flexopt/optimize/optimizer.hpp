#pragma once
/// \file The optimization loop: MMA on the topology problem, with history and density output.
#include "flexopt/io/location.hpp"
#include "flexopt/optimize/design_problem.hpp"

#include <mpi.h>
#include <string>
#include <utility>
#include <vector>

namespace flexopt::optimize {

/// The MMA loop's settings (`optimizer:`, the constraints' bounds, `output.every`).
struct OptimizerSettings {
  int max_iterations = 100;
  double move_limit = 0.2;
  double tolerance = 1e-3; ///< stop when the max design change is below
  /// design.xdmf: the densities every this many iterations (and at the last); 0: the default,
  /// about kDesignFrames frames over max_iterations (design_output_stride)
  int output_every = 0;
  std::vector<double> bounds; ///< each constraint's upper bound, in the problem's order
  /// The first design: this rank's design variables in the problem's order (empty: the design
  /// field's `initial`), and the projection stage it starts at (equivalent static loads: each
  /// static design continues from the last one's design and stage).
  std::vector<double> start;
  int first_stage = 0;
};

/// `optimizer: {method: esl, ...}`: the equivalent static loads' outer iteration (docs/theory.md
/// section 14). The MMA settings of each static design are the case's `optimizer:` ones, with
/// inner_iterations as its iteration count.
struct EslSettings {
  int instants = 12;        ///< N: load cases per outer iteration
  int outer_iterations = 5; ///< K: at most this many simulate-and-design rounds
  int inner_iterations = 0; ///< MMA iterations per static design (0: optimizer.max_iterations)
  io::Location where;       ///< of `method: esl`
};

/// design.xdmf without output.every: about this many frames over optimizer.max_iterations.
constexpr int kDesignFrames = 100;
/// A design.xdmf estimated above this size draws a warning before the run [bytes].
constexpr double kLargeDesignBytes = 1e9;

/// design.xdmf's stride: output.every when given, else ceil(max_iterations / kDesignFrames).
int design_output_stride(const OptimizerSettings &settings);
/// design.xdmf's frames over a run of max_iterations: iterations 1, 1 + stride, ... (the design
/// that each evaluated) and the final design.
long long design_output_frames(const OptimizerSettings &settings);

struct OptimizationResult {
  int iterations = 0;
  std::vector<double> objective;                ///< per iteration (unscaled)
  std::vector<std::vector<double>> constraints; ///< per iteration, response values
  std::vector<double> max_change;               ///< per iteration
  /// The parts of an iteration's seconds (DesignProblem::timings, then "update") and their
  /// values per iteration (not a number for iterations of a restart file that lacks them).
  std::vector<std::string> split_names;
  std::vector<std::vector<double>> seconds_split;
  double volume_fraction = 0; ///< final, of the design region (of every design body's together)
  std::vector<double> body_volume_fractions; ///< final, per design body (several only)
  bool converged = false;                    ///< stopped on optimizer.tolerance
  /// The projection's continuation: (first iteration, beta) of every stage run, the first one
  /// included (none without projection); beta per design body (0: that body is not projected)
  std::vector<std::pair<int, std::vector<double>>> beta_stages;
  std::vector<std::string> design_bodies; ///< the design bodies, in the order of `design:`
  std::string stop_reason;
  /// What the first evaluation found of the responses (stuck_responses), also printed.
  std::vector<std::string> warnings;
  long long dofs = 0, elements = 0, design_variables = 0;
  std::string output;                ///< design.xdmf path
  int output_stride = 1;             ///< design.xdmf's frames: every this many iterations
  long long output_frames = 0;       ///< planned over max_iterations
  double output_estimated_bytes = 0; ///< design.h5 + design.xdmf, estimated before the run
  std::vector<double> design;        ///< the final design: this rank's design variables
  int stage = 0;                     ///< the projection stage at the end
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
