#pragma once
/// \file Where a time step runs (docs/architecture.md, "Time integration"). A scene is integrated
/// by generalized-alpha on one of two backends: the replicated mechanism (GeneralizedAlpha, a
/// scene of rigid and FFRF bodies) or one PETSc system over all ranks (DistributedAlpha, a scene
/// with ACF bodies; docs/theory.md sections 6.4 and 8.2). Both are built here from one set of
/// settings, and every run goes through one loop, run_steps: `simulate`, the plan's pre-run, the
/// adjoint's forward runs and its recomputations from checkpoints (recompute_step).
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/dynamics/scene_description.hpp"

#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace flexopt::dynamics {

/// The time integration's settings: the generalized-alpha parameters, Newton's and the grid.
struct IntegratorSettings {
  AlphaParameters alpha;
  NewtonSettings newton;
  double step = 0;     ///< main step h [s]
  long long steps = 0; ///< main steps of the run
  /// From `time:` (rho_inf, newton_reuse, the grid round(end / step) steps of `step`) and the
  /// options: -fx_kept_turned 0 applies the ACF bodies' kept Newton matrices as assembled
  /// (docs/solvers.md). The one place where a run's integrator settings are made.
  static IntegratorSettings from(const TimeSettings &time);
};

/// One main step's end state and, if Newton halved it, its substeps (end states and sizes; the
/// last is the end state), on either backend: State (dense) or DistState (distributed, each rank
/// holding its part of the vectors).
template <class S> struct Record {
  S state;
  std::vector<std::pair<S, double>> substeps;
};

/// The one time loop: advances record.state, a state of `alpha` (GeneralizedAlpha or
/// DistributedAlpha), by `steps` main steps of h (t = j h exactly at main step j; Newton may
/// halve a step, and record.substeps then holds its substeps, substep_sizes[j] their sizes if
/// substep_sizes is non-null); on_step(j, info) runs after main step j. Collective; throws a
/// collective flexopt::Error naming the step where Newton fails.
template <class Alpha, class S, class OnStep>
void run_steps(const Alpha &alpha, long long steps, double h, Record<S> &record,
               std::vector<std::vector<double>> *substep_sizes, OnStep &&on_step) {
  if (substep_sizes) substep_sizes->assign(static_cast<std::size_t>(steps + 1), {});
  S next;
  for (long long j = 1; j <= steps; ++j) {
    StepInfo info;
    record.substeps.clear();
    const double t_next = static_cast<double>(j) * h;
    if (!alpha.advance(record.state, h, next, info, &record.substeps))
      throw Error(newton_failure_message(j, static_cast<double>(j - 1) * h, t_next, info,
                                         NewtonSettings{}.max_halvings),
                  true);
    if (substep_sizes)
      for (const auto &sub : record.substeps)
        (*substep_sizes)[static_cast<std::size_t>(j)].push_back(sub.second);
    record.state = next;
    record.state.t = t_next;
    on_step(j, info);
  }
}

/// Main step j recomputed with `alpha` from the record of step j - 1 along the forward run's
/// substeps (`sizes`; empty: one step of h), each solved to the forward tolerance
/// (docs/theory.md section 9.4). Collective; throws a collective flexopt::Error if Newton fails.
template <class Alpha, class S>
Record<S> recompute_step(const Alpha &alpha, const Record<S> &previous, long long j, double h,
                         const std::vector<double> &sizes) {
  Record<S> r;
  S from = previous.state, to = previous.state;
  const std::vector<double> whole{h};
  for (double dt : sizes.empty() ? whole : sizes) {
    StepInfo info;
    if (!alpha.step(from, dt, to, info))
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

/// What an observer of a run sees after main step j (j = 0: the consistent start, `info`
/// empty): the state on the dense backend (`dense`) or the distributed one (`dist`; the other
/// pointer is null) and the step's Newton figures.
struct StepView {
  long long step = 0;
  double t = 0;
  const StepInfo &info;
  const State *dense = nullptr;
  const DistState *dist = nullptr;
};
using StepObserver = std::function<void(const StepView &)>;

/// A scene's integrator on the backend the scene needs, built once from its settings, with the
/// state of a run and what the run's output reads of it (energy, sensors, positions).
/// Collective members are marked.
class Integrator {
public:
  /// The backend of `scene` (distributed if it has ACF bodies; gravity acts on them as on the
  /// mechanism's bodies). `scene` must outlive the integrator. Collective.
  Integrator(const Scene &scene, const IntegratorSettings &settings);
  ~Integrator();
  Integrator(const Integrator &) = delete;
  Integrator &operator=(const Integrator &) = delete;

  const IntegratorSettings &settings() const { return settings_; }
  bool distributed() const { return dist_ != nullptr; }
  /// The backends (only the scene's exists: the other throws).
  const GeneralizedAlpha &dense() const;
  const DistributedAlpha &dist() const;

  /// The consistent start from the scene's placement (section 6.4; with ACF bodies section
  /// 8.2): the run's state at t = 0. What the velocity correction did goes into `report`.
  /// Collective; throws collective flexopt::Errors (violated constraints, a singular system).
  void start(StartReport *report = nullptr);
  /// The run: settings().steps main steps of settings().step from the current state (the start),
  /// `observer` after the start (step 0) and after each main step. Collective; throws a
  /// collective flexopt::Error naming the step where Newton fails.
  void run(const StepObserver &observer);
  /// Puts a state of another run of the same scene and settings (a design's forward run) in
  /// place of the current one, at time t (the pointer of this backend is read).
  void set_state(const State *dense, const DistState *dist, double t);

  /// The mechanism's state (the small part's with ACF bodies), replicated.
  const State &mechanism_state() const { return small_; }
  /// Largest residual of the ACF ties (0 without ACF bodies). Collective.
  double tie_violation() const;
  /// Total energy of the current state. Collective.
  double energy() const;
  /// The value of sensor `s` at the current state (sensor_value / acf_sensor_value).
  /// Collective.
  Vec3 sensor(const BoundSensor &s) const;
  /// World positions of the owned nodes of case body b and, for a flexible body, its elastic
  /// displacement field into `elastic` (FFRF: Psi zeta in the frame's axes; ACF: in the frame of
  /// its interface nodes, acf_frame; empty: none). Not collective.
  std::vector<double> positions(std::size_t b, std::vector<double> &elastic) const;
  /// The von Mises stress [Pa] at the centroid of every local element of case body b at the
  /// current state, of the solid material (no design's factors): an FFRF body's linear stress of
  /// Psi zeta through its stress shapes (docs/theory.md 10.3; `material` is its material, the
  /// shapes kept until its reduction changes), an ACF body's co-rotated stress (8.3); empty for
  /// a rigid body. Collective (an FFRF body's shapes, when its reduction changed).
  std::vector<double> von_mises(std::size_t b, const fem::IsotropicMaterial &material) const;

private:
  const Scene &scene_;
  IntegratorSettings settings_;
  std::unique_ptr<GeneralizedAlpha> dense_;
  std::unique_ptr<DistributedAlpha> dist_;
  Record<State> state_;          ///< dense backend
  Record<DistState> dist_state_; ///< distributed backend
  State small_;                  ///< the mechanism's state (dense: state_.state)
  /// Per case body: the FFRF stress shapes of every local element for the reduction they were
  /// made of (von_mises).
  struct StressShapes {
    std::weak_ptr<const reduce::FlexibleReduction> reduction; ///< (a freed one never matches)
    Eigen::MatrixXd T;
  };
  mutable std::vector<StressShapes> shapes_;
};

} // namespace flexopt::dynamics
