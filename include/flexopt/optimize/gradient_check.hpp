#pragma once
/// \file Checking a design problem's adjoint gradients (docs/theory.md section 5, "Gradient
/// checks"): the Taylor test in a direction and fourth-order central differences on sample
/// elements, on evaluations whose noise is measured first (from random starts of their iterative
/// solves). `flexopt check-gradient` and the tests call it.
#include "flexopt/io/json.hpp"
#include "flexopt/optimize/design_problem.hpp"

#include <petscvec.h>
#include <vector>

namespace flexopt::optimize {

struct GradientCheckOptions {
  /// > 0: central differences at the one step pair h, h/2; 0: the problem's fd_step() with its
  /// fd_levels() halvings.
  double fd_step = 0;
};

struct GradientCheckResult {
  /// Per response: value, steps, remainders, orders, noise_floor(s), round_off_floor,
  /// evaluation_noise, slope_noise, linear, min_order (null: not measured), resolved.
  io::Json taylor = io::Json::array();
  /// Per response: the smallest order above the noise floor (NaN: not measured or linear) and
  /// whether the remainders all lie within the floor (linear).
  std::vector<double> min_order;
  std::vector<bool> linear;
  /// Per sample element and response: element, response, adjoint, fd, rel_err,
  /// fd_uncertainty, rel_err_beyond_uncertainty, fd_noise, adjoint_noise, step.
  io::Json fd = io::Json::array();
  double fd_step = 0;
  double max_rel_err = 0;                    ///< the whole disagreement with the differences
  double max_rel_err_beyond_uncertainty = 0; ///< its part beyond their uncertainty
  bool noise_measured = false;               ///< the evaluations had a start to perturb
  bool noise_above_round_off = false;        ///< a nonlinear response's noise exceeds its round-off
};

/// Checks the gradients of `problem` at x0 (its solves as the caller set them, e.g.
/// solve_to_round_off()): the evaluation with gradients into `base`, the noise measurement,
/// the Taylor test and the central differences, each evaluation's progress and the tables
/// printed on rank 0. Collective.
GradientCheckResult check_gradient(DesignProblem &problem, Vec x0,
                                   const GradientCheckOptions &options, Evaluation &base);

} // namespace flexopt::optimize
