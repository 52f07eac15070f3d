// One evaluation on the dense backend (docs/theory.md sections 9.1-9.5 and 10): a rigid or FFRF
// design body in a scene of rigid and FFRF bodies, integrated on the replicated mechanism.
#include "flexopt/core/context.hpp"
#include "passes.hpp"

namespace flexopt::adjoint::detail {

DensePass::DensePass(DynamicProblem &p, bool gradients) : PassRun(p, gradients) {}

void DensePass::sample(const dynamics::State &s) {
  const std::size_t nr = p_.specs_.size();
  sample_ffrf_strain(s.q);
  record_ffrf_stress(s.q);
  for (std::size_t i = 0; i < nr; ++i) {
    if (p_.sensor_of_[i] < 0) continue;
    const dynamics::BoundSensor &bs = p_.scene_.sensors[static_cast<std::size_t>(p_.sensor_of_[i])];
    p_.ev_.samples[i].push_back(dynamics::sensor_value(p_.scene_, bs, s.q));
    p_.record_design_frame(i, s.q);
  }
}

void DensePass::forward() {
  // Every main step's samples; the records the backward sweep needs go to the store, all of
  // them or those of the binomial schedule's first descent.
  const dynamics::GeneralizedAlpha &ga = integrator_.dense();
  record_ = StepRecord{ga.initial_state(p_.scene_.q0, p_.scene_.v0, 0.0, nullptr, &trace_), {}};
  const std::size_t nr = p_.specs_.size();
  p_.ev_.samples.assign(nr, {});
  p_.ev_.sensor_frames.assign(nr, {});
  start_ffrf_strain();
  for (const auto &st : p_.stress_)
    if (st) st->clear();
  run_forward(
      ga, [&](bool disk) { return disk ? disk_store(p_.checkpoint_file()) : memory_store(); },
      [&](const dynamics::State &s) { sample(s); });
  const double h = p_.settings_.time.step;
  // The responses on the time grid.
  p_.ev_.sampled.assign(nr, SampledResponse{});
  for (std::size_t i = 0; i < nr; ++i) {
    if (p_.sensor_of_[i] >= 0)
      p_.ev_.sampled[i] = sampled_response(*p_.specs_[i], p_.ev_.samples[i], h);
    if (!p_.strain_bodies_[i].empty()) p_.ev_.sampled[i].value = strain_value_[i];
  }
  finish_stress();
}

void DensePass::backward() {
  // All responses at once (one column each), main step by main step.
  const double t_adjoint = wall_time();
  const dynamics::GeneralizedAlpha &ga = integrator_.dense();
  const int n = p_.scene_.mechanism.coordinates();
  const int cols = static_cast<int>(p_.specs_.size());
  const double h = p_.settings_.time.step;
  BackwardSweep sweep(ga, cols);
  Matrix G = Matrix::Zero(p_.design_parameters(), cols); // dPsi/dtheta
  auto backward = [&](const dynamics::State &s, double dt, const Matrix &dpsi) {
    const Matrix mu = sweep.step(s, dt, dpsi);
    G += p_.design_partials(s.q, s.v, s.acc, true, mu.middleRows(3 * n, n));
  };
  auto visit = [&](long long j, const StepRecord &r) {
    if (r.substeps.empty()) {
      backward(r.state, h, state_partials(j, r.state));
      return;
    }
    // A halved step: its substeps backwards, the responses only at its end (section 9.3).
    for (std::size_t k = r.substeps.size(); k-- > 0;)
      backward(k + 1 == r.substeps.size() ? r.state : r.substeps[k].first, r.substeps[k].second,
               k + 1 == r.substeps.size() ? state_partials(j, r.state) : Matrix());
  };
  p_.recomputed_ = reverse_steps<StepRecord>(
      schedule_.get(), *store_, p_.steps_,
      [&](const StepRecord &previous, long long j) { return recompute(previous, j); }, visit);
  p_.checkpoint_bytes_ = store_->peak_bytes();
  p_.adjoint_factorizations_ = sweep.factorizations();
  const Matrix mu0 = sweep.finish(state_partials(0, s0_));
  // The placed state depends on the design when an FFRF design body has initial elastic fields
  // (section 10.2): then the start returns its sensitivities to it too.
  bool given = false;
  for (const DesignBody &db : p_.designs_) given = given || p_.given_fields(db);
  const StartAdjoint start = initial_state_adjoint(
      ga, s0_, trace_, -mu0,
      [&](const Vector &q, const Vector &v, const Vector &a, bool gravity, const Matrix &W) {
        return p_.design_partials(q, v, a, gravity, W);
      },
      given);
  G += start.design;
  p_.adjoint_s_ = wall_time() - t_adjoint;
  p_.add_element_gradients(G, start);
}

Matrix DensePass::state_partials(long long j, const dynamics::State &state) const {
  const dynamics::Scene &scene = p_.scene_;
  const int n = scene.mechanism.coordinates(), m = scene.mechanism.constraints();
  Matrix P;
  for (std::size_t i = 0; i < p_.specs_.size(); ++i) {
    if (p_.stress_[i]) { // dR/dzeta_j of the stress aggregate (section 10.3)
      if (P.size() == 0) P.setZero(4 * n + m, static_cast<Eigen::Index>(p_.specs_.size()));
      add_ffrf_stress_partial(i, j, P.col(static_cast<Eigen::Index>(i)).head(n));
      continue;
    }
    if (!p_.strain_bodies_[i].empty()) {
      if (P.size() == 0) P.setZero(4 * n + m, static_cast<Eigen::Index>(p_.specs_.size()));
      add_ffrf_strain_partial(i, j, state.q, P.col(static_cast<Eigen::Index>(i)).head(n));
      continue;
    }
    if (p_.ev_.sampled[i].dy.empty()) continue;
    const Vec3 &dy = p_.ev_.sampled[i].dy[static_cast<std::size_t>(j)];
    if (dy.isZero(0)) continue;
    if (P.size() == 0) P.setZero(4 * n + m, static_cast<Eigen::Index>(p_.specs_.size()));
    const dynamics::BoundSensor &s = scene.sensors[static_cast<std::size_t>(p_.sensor_of_[i])];
    P.col(static_cast<Eigen::Index>(i)).head(n) =
        sensor_jacobian(scene, s, state.q).transpose() * dy;
  }
  return P;
}

StepRecord DensePass::recompute(const StepRecord &previous, long long j) const {
  return dynamics::recompute_step(integrator_.dense(), previous, j, p_.settings_.time.step,
                                  p_.ev_.substep_sizes[static_cast<std::size_t>(j)]);
}

} // namespace flexopt::adjoint::detail
