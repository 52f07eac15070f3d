#pragma once
/// \file One evaluation's runs of a dynamic design problem (private to src/adjoint;
/// docs/theory.md section 9): the forward run with its samples and checkpoints, then the
/// backward sweep with the design partials and the adjoint of the consistent start. A pass lives
/// for one evaluation; what lasts the whole run is the DynamicProblem's. The two backends differ
/// in their states and step adjoints: DensePass for scenes of rigid and FFRF bodies (the
/// replicated mechanism, sections 9.1-9.5 and 10), DistPass for scenes with ACF bodies (the
/// distributed system, sections 9.6 and 9.7).
#include "flexopt/adjoint/dist_sweep.hpp"
#include "flexopt/adjoint/dynamic_problem.hpp"

#include <algorithm>
#include <memory>
#include <type_traits>
#include <vector>

namespace flexopt::adjoint::detail {

class Pass {
public:
  virtual ~Pass() = default;
  /// The forward run (section 9.4) from the consistent start: every main step's samples of the
  /// responses into the problem's evaluation (section 9.3) and, when gradients follow, the
  /// records the backward sweep needs (all, or the binomial schedule's).
  virtual void forward() = 0;
  /// The backward sweep over the stored or recomputed states with the design partials at every
  /// step (sections 9.5, 9.7), the adjoint of the consistent start (section 9.2), and dPsi/dtheta
  /// taken to the design body's elements (sections 9.1, 9.6, 10).
  virtual void backward() = 0;
};

/// The pass of the scene of `p` on its backend. Collective.
std::unique_ptr<Pass> make_pass(DynamicProblem &p, bool gradients);

/// What the passes of both backends hold for one evaluation, on their kind of state: the
/// problem, the integrator, the consistent start and what it did (section 9.2), the running
/// record, and the checkpoints of the backward sweep; and the forward loop itself.
template <class State, class Trace> class PassRun : public Pass {
protected:
  using RecordT = Record<State>;
  using StoreT = Store<RecordT>;
  PassRun(DynamicProblem &p, bool gradients)
      : p_(p), gradients_(gradients), integrator_(p.scene_, p.integration_) {}

  /// The forward run (section 9.4) from record_, which holds the consistent start: s0_ set, the
  /// checkpoint store opened by `open_store(disk)` when gradients follow (with the records of
  /// step 0 and of the schedule's first descent), `sample(state)` at every main step and the
  /// problem's observer told. `alpha` is the backend's integrator.
  template <class Alpha, class OpenStore, class Sample>
  void run_forward(const Alpha &alpha, OpenStore &&open_store, Sample &&sample) {
    s0_ = record_.state;
    if (gradients_) {
      keep_ = p_.plan_checkpoints(schedule_);
      const bool disk = p_.settings_.adjoint.storage == CheckpointStorage::Disk;
      store_ = open_store(disk);
      store_->put(0, record_);
      if (!disk)
        p_.check_checkpoint_memory(store_->bytes(), std::count(keep_.begin(), keep_.end(), 1));
    }
    sample(record_.state);
    observe(0, dynamics::StepInfo{});
    dynamics::run_steps(alpha, p_.steps_, p_.settings_.time.step, record_, &p_.ev_.substep_sizes,
                        [&](long long j, const dynamics::StepInfo &info) {
                          sample(record_.state);
                          if (gradients_ && keep_[static_cast<std::size_t>(j)])
                            store_->put(j, record_);
                          observe(j, info);
                        });
  }

  /// The stress responses' aggregates after the forward run (docs/theory.md 8.3, 10.3); on the
  /// design body with the relaxation of its densities, whose explicit gradient is complete
  /// here (with gradients).
  void finish_stress() {
    for (std::size_t i = 0; i < p_.specs_.size(); ++i) {
      if (!p_.stress_[i]) continue;
      DesignBody *db = p_.design_of(p_.stress_case_body_[i]);
      std::vector<double> eta, deta;
      if (db) db->field->stress_factors(eta, deta);
      p_.ev_.sampled[i].value =
          p_.stress_[i]->finish(p_.settings_.time.step, eta, deta, gradients_);
      if (db && gradients_)
        for (std::size_t e = 0; e < p_.stress_[i]->explicit_gradient().size(); ++e)
          db->ev.element_gradient[i][e] += p_.stress_[i]->explicit_gradient()[e];
    }
  }

  /// A new forward run's FFRF strain energies (section 9.3): nothing summed yet.
  void start_ffrf_strain() {
    strain_value_.assign(p_.specs_.size(), 0.0);
    sampled_steps_ = 0;
  }
  /// The next main step's FFRF strain energies U_n = 1/2 zeta^T K_r zeta at the mechanism's (or
  /// small part's) coordinates q, summed over each response's bodies and with the trapezoidal
  /// weights as the steps come, and sum_n w_n 1/2 zeta_n zeta_n^T for an FFRF design body (its
  /// reduction's cotangent).
  void sample_ffrf_strain(const Vector &q) {
    const dynamics::Mechanism &mech = p_.scene_.mechanism;
    const double w = trapezoid_weight(static_cast<std::size_t>(sampled_steps_++),
                                      static_cast<std::size_t>(p_.steps_));
    for (std::size_t i = 0; i < p_.specs_.size(); ++i)
      for (const int mb : p_.strain_bodies_[i]) {
        const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(mb));
        const Vector z = q.segment(mech.offset(mb) + 7, body.coordinates() - 7);
        strain_value_[i] += w * 0.5 * z.dot(body.data().stiffness * z);
        for (DesignBody &db : p_.designs_) {
          if (!db.ffrf() || db.mechanism != mb) continue;
          Matrix &kbar = db.ev.strain_kbar[i];
          if (kbar.size() == 0) kbar.setZero(z.size(), z.size());
          kbar += w * 0.5 * z * z.transpose();
        }
      }
  }
  /// d/dzeta of response i's w_j 1/2 zeta^T K_r zeta at main step j into `dq` (the mechanism's
  /// or small part's coordinates), on its FFRF bodies' elastic rows.
  template <class Out>
  void add_ffrf_strain_partial(std::size_t i, long long j, const Vector &q, Out &&dq) const {
    const dynamics::Mechanism &mech = p_.scene_.mechanism;
    const double w =
        trapezoid_weight(static_cast<std::size_t>(j), static_cast<std::size_t>(p_.steps_));
    for (const int mb : p_.strain_bodies_[i]) {
      const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(mb));
      const int o = mech.offset(mb) + 7, ne = body.coordinates() - 7;
      dq.segment(o, ne) += w * (body.data().stiffness * q.segment(o, ne));
    }
  }

  /// The FFRF bodies' stress responses record their elastic coordinates at the mechanism's (or
  /// small part's) coordinates q (section 10.3).
  void record_ffrf_stress(const Vector &q) {
    const dynamics::Mechanism &mech = p_.scene_.mechanism;
    for (std::size_t i = 0; i < p_.specs_.size(); ++i)
      if (FfrfStress *ffrf = p_.ffrf_stress(i))
        ffrf->record(
            q.segment(mech.offset(p_.stress_body_[i]) + 7, mech.size(p_.stress_body_[i]) - 7));
  }
  /// dR/dzeta_j of response i's FFRF stress into `dq` (the mechanism's or small part's
  /// coordinates), on its body's elastic rows.
  template <class Out> void add_ffrf_stress_partial(std::size_t i, long long j, Out &&dq) const {
    const Eigen::VectorXd dz = p_.ffrf_stress(i)->dzeta(static_cast<std::size_t>(j));
    dq.segment(p_.scene_.mechanism.offset(p_.stress_body_[i]) + 7, dz.size()) += dz;
  }

  DynamicProblem &p_;
  const bool gradients_;
  std::vector<double> strain_value_; ///< per response: its FFRF strain energy integral
  long long sampled_steps_ = 0;
  const dynamics::Integrator integrator_;
  Trace trace_; ///< what the start did to the velocities (section 9.2)
  RecordT record_;
  State s0_;
  std::unique_ptr<BinomialSchedule> schedule_;
  std::vector<char> keep_;
  std::unique_ptr<StoreT> store_;

private:
  void observe(long long j, const dynamics::StepInfo &info) const {
    if (!p_.observer_) return;
    if constexpr (std::is_same_v<State, dynamics::State>)
      p_.observer_(j, info, &record_.state, nullptr);
    else
      p_.observer_(j, info, nullptr, &record_.state);
  }
};

class DensePass : public PassRun<dynamics::State, dynamics::StartTrace> {
public:
  DensePass(DynamicProblem &p, bool gradients);
  void forward() override;
  void backward() override;

private:
  /// The responses' samples at state s (sensor values, the FFRF strain energies' trapezoidal
  /// sums and, for the design body, sum_n w_n 1/2 zeta_n zeta_n^T; the sensor frames on it).
  void sample(const dynamics::State &s);
  /// (dPsi/ds)^T at main step j with state `state` (empty if zero), one column per response.
  Matrix state_partials(long long j, const dynamics::State &state) const;
  /// Main step j recomputed from the record of step j - 1 along the forward run's substeps.
  StepRecord recompute(const StepRecord &previous, long long j) const;
};

class DistPass : public PassRun<dynamics::DistState, dynamics::DistStartTrace> {
public:
  DistPass(DynamicProblem &p, bool gradients);
  ~DistPass() override;
  void forward() override;
  void backward() override;

private:
  /// Local displacements of ACF body b at a state (mesh numbering, owned and ghosts).
  std::vector<double> displacement(const dynamics::DistState &s, std::size_t b) const;
  /// The responses' samples at state s (sensor values, ACF strain energies, stresses).
  void sample(const dynamics::DistState &s);
  /// Response i's ACF strain energy at state s (summed over its ACF bodies, all ranks), and
  /// w_n U_e summed into the ACF design bodies' direct partials.
  double sample_acf_strain(std::size_t i, const dynamics::DistState &s, double w);
  /// The ACF bodies' stress responses told the run's steps and relaxation.
  void start_stress();
  /// The stress responses' samples at state s (its small part `small`).
  void sample_stress(const dynamics::DistState &s, const dynamics::State &small);
  /// Adds stress response i's partial at main step j, state s, into the coordinates q.
  void add_stress_partial(std::size_t i, std::size_t j, const dynamics::DistState &s, Vec q);
  /// The direct partials of the ACF design bodies: a strain energy's sum_n w_n U_e / s_e, a
  /// mass's rho V_e.
  void direct_partials();
  /// (dPsi/ds)^T at main step j, state s: the sensors' and strain energies' q blocks, per
  /// active response (null: zero).
  std::vector<const dynamics::DistState *> state_partials(std::size_t j,
                                                          const dynamics::DistState &s);
  /// The design partials mu . dR/dx at state s for the multipliers mu (one per active
  /// response), times `sign`: the small part's stacked ones (rigid and FFRF design bodies) and
  /// each ACF design body's element partials (docs/theory.md 9.9).
  void add_partials(const dynamics::DistState &s, const std::vector<dynamics::DistState> &mu,
                    double sign);
  /// ACF design body db's G_e += sign (ds mu . dR/ds_e + dw mu . dR/dw_e), one element loop.
  void add_acf_partials(DesignBody &db, const dynamics::DistState &s,
                        const std::vector<dynamics::DistState> &mu, double sign);
  /// The backward sweep (section 9.7); returns dPsi/ds_0 = -mu_0 per active response.
  std::vector<dynamics::DistState> sweep();
  /// The adjoint of the consistent start (section 9.2) from gbar = dPsi/ds_0.
  void start_adjoint(std::vector<dynamics::DistState> &gbar);
  /// -mu^T (dM/dx) u at the start for multipliers mu (one per active response) and one
  /// velocity change u, on ACF design body db's elements.
  void add_mass_terms(DesignBody &db, const std::vector<std::vector<double>> &mus,
                      const std::vector<double> &velocity);
  /// The same on the small part's rigid and FFRF design bodies' parameters.
  void add_small_mass_terms(const Matrix &mus, const Vector &velocity);

  const dynamics::DistributedAlpha &da_;
  std::vector<std::size_t> acf_designs_; ///< the ACF design bodies (indices in the designs)
  bool small_ = false;                   ///< some design body is rigid or FFRF (in the small part)
  std::vector<std::vector<double>> energy_; ///< per strain response: its ACF bodies' U_n
  /// Per ACF design body (as acf_designs_) and response: sum_n w_n U_e,n on its local elements
  /// (empty: the response does not take the body's strain energy).
  std::vector<std::vector<std::vector<double>>> energy_sum_;
  long long acf_samples_ = 0; ///< main steps sampled so far
  Matrix G_; ///< the rigid and FFRF design bodies: dPsi/dtheta (stacked, design_partials)
  std::vector<std::size_t> active_;           ///< the responses that depend on the state
  std::vector<dynamics::DistState> partials_; ///< work: one per active response
  std::vector<std::vector<double>> d_modulus_, d_mass_, mu_d_;
  std::vector<double> u_, v_, acc_;
};

} // namespace flexopt::adjoint::detail
