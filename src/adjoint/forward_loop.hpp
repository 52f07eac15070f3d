#pragma once
/// \file The forward time loop of the dynamic problem, the same on both backends (private to
/// src/adjoint): main steps n h, each halved step's substeps kept with their sizes (docs/theory.md
/// section 9.3), a clear error naming the step where Newton fails.
#include "flexopt/core/error.hpp"

#include <sstream>
#include <string>
#include <vector>

namespace flexopt::adjoint::detail {

/// Advances record.state (a state of `integrator`) by `steps` main steps of h: record.substeps
/// holds the substeps of the last step (empty if it was whole), substep_sizes[j] their sizes;
/// on_step(j, info) runs after main step j (info: its Newton iterations, factorizations,
/// halvings). Collective; throws a collective flexopt::Error if Newton
/// fails.
template <class Integrator, class Record, class OnStep>
void forward_loop(const Integrator &integrator, long long steps, double h, Record &record,
                  std::vector<std::vector<double>> &substep_sizes, OnStep &&on_step) {
  substep_sizes.assign(static_cast<std::size_t>(steps + 1), {});
  decltype(record.state) next;
  for (long long j = 1; j <= steps; ++j) {
    dynamics::StepInfo info;
    record.substeps.clear();
    const double t_next = static_cast<double>(j) * h;
    if (!integrator.advance(record.state, h, next, info, &record.substeps)) {
      throw Error(dynamics::newton_failure_message(j, static_cast<double>(j - 1) * h, t_next, info,
                                                   dynamics::NewtonSettings{}.max_halvings),
                  true);
    }
    for (const auto &sub : record.substeps)
      substep_sizes[static_cast<std::size_t>(j)].push_back(sub.second);
    record.state = next;
    record.state.t = t_next;
    on_step(j, info);
  }
}

/// Main step j recomputed with `integrator` from the record of step j - 1 along the forward
/// run's substeps (`sizes`; empty: one step of h), each solved to the forward tolerance
/// (docs/theory.md section 9.4). Collective; throws a collective flexopt::Error if Newton fails.
template <class Integrator, class Record>
Record recompute_step(const Integrator &integrator, const Record &previous, long long j, double h,
                      const std::vector<double> &sizes) {
  Record r;
  auto from = previous.state, to = previous.state;
  const std::vector<double> whole{h};
  for (double dt : sizes.empty() ? whole : sizes) {
    dynamics::StepInfo info;
    if (!integrator.step(from, dt, to, info))
      throw Error("adjoint: recomputing step " + std::to_string(j) +
                      " from a checkpoint, Newton did not converge where the forward run did",
                  true);
    if (!sizes.empty()) r.substeps.emplace_back(to, dt);
    from = to;
  }
  r.state = to;
  r.state.t = static_cast<double>(j) * h;
  return r;
}

} // namespace flexopt::adjoint::detail
