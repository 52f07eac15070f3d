#pragma once
/// \file Helpers shared by the commands (private to the app module).
#include "flexopt/app/commands.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/optimize/design_problem.hpp"

namespace flexopt::adjoint {
class DynamicProblem;
}

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
} // namespace detail

/// `simulate` for `analysis: dynamic`: generalized-alpha run of the mechanism, motion.xdmf and
/// summary.json. Collective.
int run_dynamic(const Context &ctx, const Options &o, const io::Case &c, double t0);

/// After `optimize` on a dynamic case: the mechanism with the first design (design.initial) and
/// with the last one (dir/restart.h5) integrated and written to dir/motion_initial.xdmf and
/// dir/motion_final.xdmf; their responses and motion figures into s. Collective.
void write_design_motions(const Context &ctx, const io::Case &c, adjoint::DynamicProblem &problem,
                          const std::string &dir, io::Json &s);

} // namespace flexopt::app
