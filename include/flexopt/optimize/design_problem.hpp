#pragma once
/// \file What the optimizer and `check-gradient` see of a design problem, static or dynamic:
/// design vectors, response values and their gradients with respect to the design variables
/// (docs/theory.md sections 5 and 9).
#include "flexopt/io/json.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/design.hpp"
#include "flexopt/optimize/stress_aggregate.hpp"

#include <array>
#include <cstdint>
#include <map>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// Values of the objective and constraints at one design, and optionally their gradients
/// with respect to the design variables (Vecs in the design layout, owned by the caller
/// through `DesignProblem::evaluate`).
struct Evaluation {
  double objective = 0;
  std::vector<double> constraints; ///< response values (the bound is in the spec)
  Vec d_objective = nullptr;
  std::vector<Vec> d_constraints;
  /// Response i: 0 the objective, i >= 1 constraint i - 1 (the order of response_names).
  double &value(std::size_t i) { return i == 0 ? objective : constraints[i - 1]; }
  double value(std::size_t i) const { return i == 0 ? objective : constraints[i - 1]; }
  Vec &gradient(std::size_t i) { return i == 0 ? d_objective : d_constraints[i - 1]; }
  Vec gradient(std::size_t i) const { return i == 0 ? d_objective : d_constraints[i - 1]; }
  Evaluation() = default;
  Evaluation(const Evaluation &) = delete;
  Evaluation &operator=(const Evaluation &) = delete;
  ~Evaluation();
};

/// One part of an evaluation's wall time.
struct Timing {
  std::string name;  ///< history.csv column seconds_<name>
  std::string label; ///< the iteration line's column head (at most 8 characters)
  double seconds = 0;
};

class DesignProblem {
public:
  virtual ~DesignProblem() = default;
  /// The design variables of every design body, their filters and projections. Mutable: the
  /// optimizer's continuation sets the projection sharpness.
  virtual Design &design() = 0;
  virtual const Design &design() const = 0;
  MPI_Comm comm() const { return design().comm(); }
  /// The grid of design.xdmf and gradient.xdmf: the design bodies' meshes (Design::grid_layout);
  /// a dynamic problem places each body as the scene does at the start.
  virtual io::GridLayout design_layout() const { return design().grid_layout(); }
  /// Where each design body sits in its scene at the start, when design_layout() places them
  /// (several dynamic design bodies): per field the position p and the rotation R (row-major),
  /// x = p + R X. Empty: each body in its own frame.
  virtual std::vector<std::array<double, 12>> design_placements() const { return {}; }
  /// "objective:TYPE", "constraint0:TYPE", ...
  virtual const std::vector<std::string> &response_names() const = 0;
  /// Evaluates the objective and every constraint at x; with `gradients`, also their
  /// derivatives by the adjoint method. Collective.
  virtual void evaluate(Vec x, bool gradients, Evaluation &out) = 0;
  /// Facts of the problem and of the evaluations so far for summary.json (sizes, solves,
  /// timings). Collective.
  virtual void describe(io::Json &summary) const = 0;
  /// The parts of the last evaluate's wall time, the same names in the same order at every
  /// evaluation of a problem (static: solve, adjoint; dynamic: forward, adjoint, and with an FFRF
  /// design body reduction and reduction_adjoint). The filter and the pull-back are the rest.
  virtual std::vector<Timing> timings() const = 0;
  /// Unknowns of one state solve (static: displacement DOFs; dynamic: the mechanism's
  /// coordinates).
  virtual long long dofs() const = 0;
  /// Relative round-off of a response evaluation, |R| times this, below which a Taylor
  /// remainder is noise (check-gradient).
  virtual double noise_floor() const = 0;
  /// The same for response i (0 the objective, i >= 1 constraint i - 1): by default the
  /// problem's; responses computed from the densities alone (the volume fraction, a mass) may
  /// carry less round-off than the state's.
  virtual double noise_floor(std::size_t i) const {
    (void)i;
    return noise_floor();
  }
  /// check-gradient's finite-difference step on a design variable when --fd-step is not given:
  /// large enough that noise_floor() |R| / (h |dR/dx_e|) stays below the checked tolerance,
  /// small enough that the fourth-order truncation does too.
  virtual double fd_step() const { return 1e-2; }
  /// check-gradient: every later evaluation solved as exactly as the problem can (its
  /// iterative solves from zero to a relative residual of 1e-12, Newton's method proper), where
  /// the user's options (the case's `solver:`, the command line) do not set otherwise. Returns
  /// what still limits the evaluations' accuracy, one phrase per limit naming its option
  /// (empty: round-off alone). Collective.
  virtual std::vector<std::string> solve_to_round_off() = 0;
  /// check-gradient's measurement of the evaluation noise: seed != 0 makes the later
  /// evaluations start their iterative solves from random vectors drawn with `seed` (as far from
  /// the solution as a start from zero), seed 0 from where they normally start. Returns whether
  /// any solve's start was perturbed (false: the evaluations are the same whatever the start,
  /// and their noise is their round-off, noise_floor()). Collective.
  virtual bool set_random_start(unsigned long seed) {
    bool any = false;
    for (std::size_t k = 0; k < design().size(); ++k)
      any = design().field(k).filter().set_random_start(seed) || any;
    return any;
  }
  /// How many halvings of fd_step() check-gradient tries (1: the steps h and h/2, one
  /// Richardson extrapolation; L > 1: L + 1 steps, and per response the extrapolation that
  /// agrees best with the next, where truncation and noise balance).
  virtual int fd_levels() const { return 1; }
  /// The size below which response i's value is round-off, a response that cannot move
  /// (stuck_responses): for a sensor response 1e-12 L (L the scene's length scale), squared
  /// for a mean square and a tracking error. 0: none known.
  virtual double round_off_level(std::size_t i) const {
    (void)i;
    return 0;
  }

  /// The solvers' state that the next evaluation starts from (a warm start: the last
  /// solutions of iterative solves), kept in restart.h5 so that a resumed run goes on with the
  /// same bits (docs/output.md "Restart file"): values per owned degree of freedom, keyed by
  /// solver_state_keys(). Empty: none (every evaluation starts afresh).
  virtual std::map<std::string, std::vector<double>> solver_state() const { return {}; }
  /// The keys of solver_state()'s values (optimize::dof_keys). Collective.
  virtual std::vector<std::uint64_t> solver_state_keys() const { return {}; }
  /// Before a resumed run's first evaluation: sets up, at the run's first design x0, the
  /// solvers that keep what they build for their first operator (GAMG's interpolation, reused
  /// for later designs), so that they hold what the uninterrupted run's did. Collective.
  virtual void prepare_resume(Vec x0) { (void)x0; }
  /// Takes up a state that solver_state() returned (read back from a restart file).
  virtual void restore_solver_state(const std::map<std::string, std::vector<double>> &state) {
    (void)state;
  }

  /// After each iteration's evaluation (optimize only, never check-gradient): responses whose
  /// scale follows the design (a stress aggregate's adaptive normalization, docs/theory.md 5.1)
  /// take it from this evaluation for the next.
  virtual void end_iteration() {}
  /// Those scales, one per response that has one (restart.h5 keeps them), and their restore.
  virtual std::vector<double> response_scales() const { return {}; }
  virtual void restore_response_scales(const std::vector<double> &scales) { (void)scales; }
  /// Cell fields (one value per local element) that design.xdmf carries at each written
  /// iteration besides the densities, from the last evaluation: name and values.
  virtual std::vector<std::pair<std::string, std::vector<double>>> cell_fields() const {
    return {};
  }
  /// The names of cell_fields(), known before any evaluation (a restart carries them over).
  virtual std::vector<std::string> cell_field_names() const { return {}; }
  /// A stress response on a design body: its response index (0 the objective), the body's
  /// field in design(), and the aggregate of the last evaluation (stuck_responses checks where
  /// its peak lies).
  struct DesignStress {
    std::size_t response = 0, field = 0;
    const StressAggregate *aggregate = nullptr;
  };
  virtual std::vector<DesignStress> design_stress() const { return {}; }

  Vec create_design_vector() const { return design().create_design_vector(); }
  void initial_design(Vec x) const { design().initial_design(x); }
  PetscInt design_size() const { return design().design_size(); }
  const std::vector<std::uint64_t> &design_keys() const { return design().design_keys(); }
};

/// The responses of evaluation e (with gradients) that cannot guide a design, one sentence each
/// naming the response and why: a gradient at most 1e-12 of the value everywhere (or zero),
/// or a value below the
/// problem's round_off_level (an elastic_displacement sensor on an interface that defines its
/// body's frame is zero by construction). Collective.
std::vector<std::string> stuck_responses(const DesignProblem &p, const Evaluation &e);

} // namespace flexopt::optimize
