#pragma once
/// \file The Newton iteration of one generalized-alpha step with a kept iteration matrix
/// (docs/theory.md section 6.4), shared by the dense/replicated integrator (GeneralizedAlpha) and
/// the distributed one (DistributedAlpha). What differs between them is behind `Backend`:
///
///   void predict();                         // next state := the predictor from the step's start
///   bool has_matrix(const NewtonScaling &) const; // a factorization for this step size is kept
///   bool factorize(const NewtonScaling &);  // assemble + factorize at `next`, rhs too; false if
///                                           // singular
///   bool rhs(const NewtonScaling &);        // the right-hand side alone at `next`; false if
///                                           // it cannot be evaluated (an inverted element)
///   bool solve_update(const NewtonScaling &, double &increment, double &violation);
///       // max|Phi| before the update into violation; solve with the current factorization,
///       // update `next` and report max|dq| / (1 + max|q|); false if the solve failed
///   void drop_matrix();                     // forget the factorization
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>
#include <vector>

namespace flexopt::dynamics::detail {

template <class Backend>
bool newton_loop(Backend &b, const NewtonSettings &settings, const NewtonScaling &k,
                 StepInfo &info) {
  b.predict();
  info.increment.clear();
  info.violation.clear();
  // The factorized matrix is kept across iterations and steps: on a kept matrix (assembled at
  // an earlier iterate) the iterations contract linearly, by theta = inc_k / inc_(k-1), instead
  // of quadratically. It is replaced at the current iterate when theta exceeds
  // reuse_contraction; one from an earlier step (`stale`) that does not contract at all is
  // dropped and the step starts over from the predictor.
  const double reuse = settings.reuse_contraction;
  bool refresh = !(reuse > 0 && b.has_matrix(k));
  bool stale = !refresh; // the factorization predates this attempt
  double inc_prev = 0;   // the last increment (0: none since the predictor)
  for (int it = 0; it < settings.max_iterations; ++it) {
    const bool kept = !refresh; // a matrix from an earlier iterate
    bool evaluated = true;
    if (refresh) {
      ++info.factorizations;
      if (!b.factorize(k)) return false;
      refresh = stale = false;
    } else {
      evaluated = b.rhs(k);
    }
    double inc = 0, violation = 0;
    if (!evaluated || !b.solve_update(k, inc, violation))
      inc = std::numeric_limits<double>::infinity();
    ++info.iterations;
    info.increment.push_back(inc);
    info.violation.push_back(violation);
    const double theta = inc_prev > 0 ? inc / inc_prev : 0.0;
    if (stale && !(theta < 1 && std::isfinite(inc))) {
      b.predict();
      refresh = true;
      inc_prev = 0;
      it = -1; // a full budget of iterations (and a new history) for the new matrix
      info.increment.clear();
      info.violation.clear();
      continue;
    }
    if (!std::isfinite(inc)) {
      b.drop_matrix();
      return false;
    }
    // Stopping rule: the remaining distance to the solution, predicted from the contraction
    // (Hairer & Wanner's theta / (1 - theta) inc_k), or the increment itself. After an
    // iteration on the matrix of its own iterate (Newton proper) what remains is about inc^2,
    // so `tolerance` suffices; on a kept matrix the iteration converges only linearly and must
    // get down to `kept_tolerance` to leave the solution as accurate as Newton's.
    // On a kept matrix the contraction of two increments can understate that of the error:
    // the error may lie mostly in components that contract fast, the slower ones hidden
    // below them. The matrix is kept only while it contracts by at most `reuse`, so that (up to
    // 1/2) bounds the slower components' rate.
    const double theta_est = kept ? std::max(theta, std::min(reuse, 0.5)) : theta;
    const double rest = inc_prev > 0 && theta_est < 1 ? theta_est / (1 - theta_est) * inc
                                                      : std::numeric_limits<double>::infinity();
    const double tol = kept ? settings.kept_tolerance : settings.tolerance;
    if (inc <= tol || rest <= tol) return true;
    if (reuse <= 0 || (kept && theta > reuse)) refresh = true;
    // A kept matrix that contracts, but too slowly to reach the tolerance within the
    // iterations left (about log(tol / rest) / log(theta_est) more), is replaced too.
    if (kept && !refresh && inc_prev > 0 && rest > tol && theta_est > 0) {
      const double needed = std::log(tol / rest) / std::log(theta_est);
      if (it + 1 + needed >= settings.max_iterations) refresh = true;
    }
    inc_prev = inc;
  }
  b.drop_matrix();
  return false;
}

/// One step of h from s to `next` by step_once(from, dt, to, info); if it fails, two half
/// steps, each of which may halve again, down to h / 2^max_halvings. Returns (and records in
/// info.converged) whether the step was made. If the step was halved and `path` is non-null,
/// every substep's end state and size are appended to it in order (the last is `next`); a step
/// made whole appends nothing.
template <class State, class StepOnce>
bool advance_with_halving(const State &s, double h, State &next, StepInfo &info, int max_halvings,
                          StepOnce &&step_once,
                          std::vector<std::pair<State, double>> *path = nullptr) {
  info.converged = step_once(s, h, next, info);
  if (info.converged) return true;
  auto made = [&](const State &from, double dt, State &to) {
    if (!step_once(from, dt, to, info)) return false;
    if (path) path->emplace_back(to, dt);
    return true;
  };
  std::function<bool(const State &, double, State &, int)> split =
      [&](const State &from, double dt, State &to, int depth) -> bool {
    if (depth > max_halvings) return false;
    info.halvings = std::max(info.halvings, depth);
    State mid;
    if (!made(from, dt, mid) && !split(from, 0.5 * dt, mid, depth + 1)) return false;
    if (!made(mid, dt, to) && !split(mid, 0.5 * dt, to, depth + 1)) return false;
    return true;
  };
  info.converged = split(s, 0.5 * h, next, 1);
  return info.converged;
}

} // namespace flexopt::dynamics::detail
