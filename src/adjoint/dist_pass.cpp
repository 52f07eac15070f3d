// One evaluation on the distributed backend (docs/theory.md sections 9.6-9.9), for a scene
// with ACF bodies whose design bodies are ACF (element partials), rigid (mass-parameter partials
// on the small part) or FFRF (its model's partials on the small part, through the reduction's
// adjoint), in any mix: the forward run with the states kept or checkpointed, the responses, the
// backward sweep with the design partials, and the adjoint of the consistent start (9.2).
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "passes.hpp"

#include <algorithm>

namespace flexopt::adjoint::detail {

std::unique_ptr<Pass> make_pass(DynamicProblem &p, bool gradients) {
  if (p.scene().acf.empty()) return std::make_unique<DensePass>(p, gradients);
  return std::make_unique<DistPass>(p, gradients);
}

DistPass::DistPass(DynamicProblem &p, bool gradients)
    : PassRun(p, gradients), da_(integrator_.dist()) {
  for (const DesignBody &db : p_.designs_) {
    if (db.acf_model())
      acf_designs_.push_back(db.index);
    else
      small_ = true;
  }
  G_ = Matrix::Zero(p_.design_parameters(), static_cast<Eigen::Index>(p_.specs_.size()));
}

DistPass::~DistPass() = default;

std::vector<double> DistPass::displacement(const dynamics::DistState &s, std::size_t b) const {
  std::vector<double> u;
  da_.local_values(s.q, b, u);
  const mesh::DistributedMesh &mb = p_.scene_.acf[b]->mesh();
  for (std::size_t k = 0; k < u.size(); ++k) u[k] -= mb.coordinates[k];
  return u;
}

void DistPass::sample(const dynamics::DistState &s) {
  const dynamics::State small = da_.small_state(s);
  sample_stress(s, small);
  sample_ffrf_strain(small.q);
  for (std::size_t i = 0; i < p_.specs_.size(); ++i) {
    if (p_.sensor_of_[i] >= 0) {
      const dynamics::BoundSensor &bs =
          p_.scene_.sensors[static_cast<std::size_t>(p_.sensor_of_[i])];
      p_.ev_.samples[i].push_back(bs.acf_body >= 0
                                      ? dynamics::acf_sensor_value(p_.scene_, da_, bs, s, small)
                                      : dynamics::sensor_value(p_.scene_, bs, small.q));
      p_.record_design_frame(i, small.q);
    }
    if (!p_.acf_strain_bodies_[i].empty())
      energy_[i].push_back(
          sample_acf_strain(i, s,
                            trapezoid_weight(static_cast<std::size_t>(acf_samples_),
                                             static_cast<std::size_t>(p_.steps_))));
  }
  ++acf_samples_;
}

double DistPass::sample_acf_strain(std::size_t i, const dynamics::DistState &s, double w) {
  double local = 0;
  for (const int acf : p_.acf_strain_bodies_[i]) {
    const auto b = static_cast<std::size_t>(acf);
    const std::vector<double> u = displacement(s, b);
    const std::vector<double> Ue = p_.scene_.acf[b]->element_energies(u.data());
    for (double x : Ue) local += x;
    // The direct partial sum_n w_n U_e / s_e of an ACF design body (its weights w_n known).
    for (std::size_t k = 0; k < acf_designs_.size(); ++k)
      if (p_.designs_[acf_designs_[k]].acf == acf && !energy_sum_[k][i].empty())
        for (std::size_t e = 0; e < Ue.size(); ++e) energy_sum_[k][i][e] += w * Ue[e];
  }
  double total = 0;
  MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, p_.comm());
  return total;
}

void DistPass::sample_stress(const dynamics::DistState &s, const dynamics::State &small) {
  // ACF bodies' co-rotated stress from their displacements (section 8.3); FFRF bodies' elastic
  // coordinates from the small part (section 10.3).
  for (std::size_t i = 0; i < p_.specs_.size(); ++i)
    if (AcfStress *acf = p_.acf_stress(i))
      acf->record(displacement(s, static_cast<std::size_t>(p_.stress_body_[i])).data());
  record_ffrf_stress(small.q);
}

void DistPass::start_stress() {
  // The ACF bodies' stress aggregates as the steps come (section 8.3), on the design body with
  // the relaxation of its densities.
  for (std::size_t i = 0; i < p_.specs_.size(); ++i) {
    AcfStress *acf = p_.acf_stress(i);
    if (!acf) continue;
    std::vector<double> eta, deta;
    if (const DesignBody *db = p_.design_of(p_.stress_case_body_[i]))
      db->field->stress_factors(eta, deta);
    acf->start(static_cast<std::size_t>(p_.steps_), p_.settings_.time.step, eta, deta);
  }
}

void DistPass::forward() {
  const std::size_t nr = p_.specs_.size();
  const double h = p_.settings_.time.step;
  record_.state = dynamics::acf_initial_state(p_.scene_, da_, nullptr, &trace_);
  p_.ev_.samples.assign(nr, {});
  p_.ev_.sensor_frames.assign(nr, {});
  start_ffrf_strain();
  energy_.assign(nr, {});
  acf_samples_ = 0;
  // The ACF design bodies' sums sum_n w_n U_e for the strain energies that take them.
  energy_sum_.assign(acf_designs_.size(), std::vector<std::vector<double>>(nr));
  for (std::size_t k = 0; k < acf_designs_.size() && gradients_; ++k) {
    const DesignBody &db = p_.designs_[acf_designs_[k]];
    for (std::size_t i = 0; i < nr; ++i) {
      const auto &list = p_.acf_strain_bodies_[i];
      if (std::find(list.begin(), list.end(), db.acf) != list.end())
        energy_sum_[k][i].assign(static_cast<std::size_t>(db.field->mesh().local_elements()), 0.0);
    }
  }
  for (const auto &st : p_.stress_)
    if (st) st->clear();
  start_stress();
  run_forward(
      da_,
      [&](bool disk) {
        return disk ? dist_disk_store(p_.checkpoint_file(), da_) : dist_memory_store();
      },
      [&](const dynamics::DistState &s) { sample(s); });
  const auto N = static_cast<std::size_t>(p_.steps_);
  p_.ev_.sampled.assign(nr, SampledResponse{});
  for (std::size_t i = 0; i < nr; ++i) {
    if (p_.sensor_of_[i] >= 0)
      p_.ev_.sampled[i] = sampled_response(*p_.specs_[i], p_.ev_.samples[i], h);
    if (!p_.acf_strain_bodies_[i].empty())
      for (std::size_t n = 0; n <= N; ++n)
        p_.ev_.sampled[i].value += trapezoid_weight(n, N) * energy_[i][n];
    if (!p_.strain_bodies_[i].empty()) p_.ev_.sampled[i].value += strain_value_[i]; // FFRF
  }
  finish_stress();
}

void DistPass::direct_partials() {
  // Direct partials of the ACF design bodies: a strain energy's sum_n w_n U_e / s_e, a mass's
  // rho V_e (a rigid design body's mass: add_rigid_element_gradients).
  for (std::size_t k = 0; k < acf_designs_.size(); ++k) {
    DesignBody &db = p_.designs_[acf_designs_[k]];
    const mesh::DistributedMesh &m = db.field->mesh();
    const auto ne = static_cast<std::size_t>(m.local_elements());
    const std::vector<double> volume = fem::element_volumes(m);
    const double density = p_.scene_.acf[static_cast<std::size_t>(db.acf)]->material().density;
    for (std::size_t i = 0; i < p_.specs_.size(); ++i) {
      std::vector<double> &g = db.ev.element_gradient[i];
      const std::vector<double> &sum = energy_sum_[k][i];
      for (std::size_t e = 0; e < sum.size(); ++e) g[e] += db.ev.ds[e] / db.ev.s[e] * sum[e];
      if (p_.counts_mass(i, db))
        for (std::size_t e = 0; e < ne; ++e) g[e] += db.ev.dw[e] * density * volume[e];
    }
  }
}

std::vector<const dynamics::DistState *> DistPass::state_partials(std::size_t j,
                                                                  const dynamics::DistState &s) {
  const std::size_t na = active_.size();
  const auto N = static_cast<std::size_t>(p_.steps_);
  std::vector<const dynamics::DistState *> ptr(na, nullptr);
  const dynamics::State small = da_.small_state(s);
  std::vector<double> force;
  for (std::size_t a = 0; a < na; ++a) {
    const std::size_t i = active_[a];
    dynamics::DistState &P = partials_[a];
    FX_PETSC(VecZeroEntries(P.q));
    bool any = false;
    if (p_.sensor_of_[i] >= 0 && !p_.ev_.sampled[i].dy[j].isZero(0)) {
      const dynamics::BoundSensor &bs =
          p_.scene_.sensors[static_cast<std::size_t>(p_.sensor_of_[i])];
      const Vec3 &dy = p_.ev_.sampled[i].dy[j];
      if (bs.acf_body >= 0) {
        const auto b =
            static_cast<std::size_t>(p_.scene_.bodies[static_cast<std::size_t>(bs.acf_body)].acf);
        Vec3 w = dy;
        // The elastic displacement through its frame's interface nodes (docs/theory.md 8.4).
        if (bs.quantity == dynamics::SensorQuantity::ElasticDisplacement) {
          Vector d = Vector::Zero(small.q.size());
          w = dynamics::add_acf_elastic_partial(p_.scene_, bs, small,
                                                da_.point_position(s, b, bs.location), dy, d);
          da_.add_small(P.q, d);
        }
        da_.add_point_weights(P.q, b, bs.location, w);
      } else {
        da_.add_small(P.q, sensor_jacobian(p_.scene_, bs, small.q).transpose() * dy);
      }
      any = true;
    }
    if (p_.stress_[i]) {
      add_stress_partial(i, j, s, P.q);
      any = true;
    }
    if (!p_.strain_bodies_[i].empty()) { // FFRF bodies', on the small part
      Vector d = Vector::Zero(small.q.size());
      add_ffrf_strain_partial(i, static_cast<long long>(j), small.q, d);
      da_.add_small(P.q, d);
      any = true;
    }
    for (const int acf : p_.acf_strain_bodies_[i]) {
      const auto b = static_cast<std::size_t>(acf);
      const std::vector<double> u = displacement(s, b);
      force.assign(u.size(), 0.0);
      p_.scene_.acf[b]->element_energies(u.data(), force.data());
      // Each element's force went to its local nodes; ghosts are added on their owners.
      for (double &f : force) f *= trapezoid_weight(j, N);
      da_.add_local_values(P.q, b, force);
      any = true;
    }
    FX_PETSC(VecAssemblyBegin(P.q));
    FX_PETSC(VecAssemblyEnd(P.q));
    if (any) ptr[a] = &P;
  }
  return ptr;
}

void DistPass::add_stress_partial(std::size_t i, std::size_t j, const dynamics::DistState &s,
                                  Vec q) {
  const auto b = static_cast<std::size_t>(p_.stress_body_[i]);
  if (p_.ffrf_stress(i)) { // dR/dzeta_j on the small part (10.3)
    Vector d = Vector::Zero(p_.scene_.mechanism.coordinates());
    add_ffrf_stress_partial(i, static_cast<long long>(j), d);
    da_.add_small(q, d);
    return;
  }
  // dR/dx_j of an ACF body's co-rotated stress (8.3), element by element; ghosts' shares are
  // added on their owners.
  const std::vector<double> u = displacement(s, b);
  std::vector<double> force(u.size(), 0.0);
  DesignBody *db = p_.design_of(p_.stress_case_body_[i]);
  p_.acf_stress(i)->add_state_partial(j, u.data(), force.data(),
                                      db ? db->ev.element_gradient[i].data() : nullptr);
  da_.add_local_values(q, b, force);
}

void DistPass::add_partials(const dynamics::DistState &s,
                            const std::vector<dynamics::DistState> &mu, double sign) {
  // The rigid and FFRF design bodies' dPsi/dtheta += (dr/dtheta)^T mu_d on the small part (one
  // stacked call); each ACF design body's element partials.
  const std::size_t na = active_.size();
  if (na == 0) return;
  if (small_) {
    const dynamics::State sm = da_.small_state(s);
    Matrix W(sm.q.size(), static_cast<Eigen::Index>(na));
    for (std::size_t a = 0; a < na; ++a)
      W.col(static_cast<Eigen::Index>(a)) = da_.small_values(mu[a].acc);
    const Matrix P = p_.design_partials(sm.q, sm.v, sm.acc, true, W);
    for (std::size_t a = 0; a < na; ++a)
      G_.col(static_cast<Eigen::Index>(active_[a])) += sign * P.col(static_cast<Eigen::Index>(a));
  }
  for (const std::size_t k : acf_designs_) add_acf_partials(p_.designs_[k], s, mu, sign);
}

void DistPass::add_acf_partials(DesignBody &db, const dynamics::DistState &s,
                                const std::vector<dynamics::DistState> &mu, double sign) {
  const std::size_t na = active_.size();
  const auto b = static_cast<std::size_t>(db.acf);
  const auto ne = static_cast<std::size_t>(db.field->mesh().local_elements());
  std::vector<const double *> mu_ptr(na);
  u_ = displacement(s, b);
  da_.local_values(s.v, b, v_);
  da_.local_values(s.acc, b, acc_);
  for (std::size_t a = 0; a < na; ++a) {
    da_.local_values(mu[a].acc, b, mu_d_[a]);
    mu_ptr[a] = mu_d_[a].data();
  }
  p_.scene_.acf[b]->design_partials(u_.data(), v_.data(), acc_.data(), mu_ptr,
                                    p_.scene_.mechanism.gravity, d_modulus_, d_mass_);
  for (std::size_t a = 0; a < na; ++a)
    for (std::size_t e = 0; e < ne; ++e)
      db.ev.element_gradient[active_[a]][e] +=
          sign * (db.ev.ds[e] * d_modulus_[a][e] + db.ev.dw[e] * d_mass_[a][e]);
}

std::vector<dynamics::DistState> DistPass::sweep() {
  const std::size_t na = active_.size();
  const double h = p_.settings_.time.step;
  DistBackwardSweep sweep(da_, static_cast<int>(na));
  partials_.clear();
  for (std::size_t a = 0; a < na; ++a) partials_.push_back(da_.zero_state());
  mu_d_.assign(na, {});
  auto visit = [&](long long jj, const DistRecord &r) {
    const auto j = static_cast<std::size_t>(jj);
    if (r.substeps.empty()) {
      add_partials(r.state, sweep.step(r.state, h, state_partials(j, r.state)), 1.0);
      return;
    }
    // A halved step: its substeps backwards, the responses only at its end (section 9.3).
    for (std::size_t k = r.substeps.size(); k-- > 0;) {
      const bool end = k + 1 == r.substeps.size();
      const dynamics::DistState &s = end ? r.state : r.substeps[k].first;
      add_partials(s,
                   sweep.step(s, r.substeps[k].second,
                              end ? state_partials(j, r.state)
                                  : std::vector<const dynamics::DistState *>(na, nullptr)),
                   1.0);
    }
  };
  p_.recomputed_ = reverse_steps<DistRecord>(
      schedule_.get(), *store_, p_.steps_,
      [&](const DistRecord &previous, long long j) {
        return dynamics::recompute_step(da_, previous, j, h,
                                        p_.ev_.substep_sizes[static_cast<std::size_t>(j)]);
      },
      visit);
  p_.adjoint_factorizations_ = sweep.steps() + 1; // one per backward step, one at the start
  return sweep.finish(state_partials(0, s0_));
}

void DistPass::add_mass_terms(DesignBody &db, const std::vector<std::vector<double>> &mus,
                              const std::vector<double> &velocity) {
  // Per element -dw_e mu_e^T M0_e u_e of an ACF design body.
  const std::size_t na = active_.size();
  const auto b = static_cast<std::size_t>(db.acf);
  const auto ne = static_cast<std::size_t>(db.field->mesh().local_elements());
  std::vector<const double *> ptr(na);
  for (std::size_t a = 0; a < na; ++a) ptr[a] = mus[a].data();
  const std::vector<double> u0 = displacement(s0_, b);
  p_.scene_.acf[b]->design_partials(u0.data(), nullptr, velocity.data(), ptr, Vec3::Zero(),
                                    d_modulus_, d_mass_);
  for (std::size_t a = 0; a < na; ++a)
    for (std::size_t e = 0; e < ne; ++e)
      db.ev.element_gradient[active_[a]][e] -= db.ev.dw[e] * d_mass_[a][e];
}

void DistPass::add_small_mass_terms(const Matrix &mus, const Vector &velocity) {
  // -(dM/dtheta u)^T mu of a rigid or FFRF design body in the small part: the mass part of r
  // only, r(q, 0, u) - r(q, 0, 0) (an FFRF body's r also holds K_r zeta; section 9.8).
  const dynamics::State sm = da_.small_state(s0_);
  const Vector zero = Vector::Zero(sm.q.size());
  const Matrix P = p_.design_partials(sm.q, zero, velocity, false, mus) -
                   p_.design_partials(sm.q, zero, zero, false, mus);
  for (std::size_t a = 0; a < active_.size(); ++a)
    G_.col(static_cast<Eigen::Index>(active_[a])) -= P.col(static_cast<Eigen::Index>(a));
}

void DistPass::start_adjoint(std::vector<dynamics::DistState> &gbar) {
  // gbar = -mu_0 = dPsi/ds_0; the initial accelerations [M Phi_q^T; Phi_q 0] [acc; lambda] =
  // [Q; gamma] (section 9.2, stage 2): nu from the transposed system, then -nu_acc . dr/dtheta.
  // Stages 3 and 4 (the velocities) only if the start changed them: gv = dPsi/dv_0 through the
  // accelerations, then the elastic fallback v_0 = v_r + dv (nu_f = A^-T [gv; 0], -nu_f^T dM dv,
  // gv -= Phi_q^T nu_f,lambda) and the rigid-body correction v_r = v_given + T y (z = Pi T^T gv,
  // -(T z)^T dM (T y) on each design body's rigid velocity field): on the ACF design bodies'
  // local nodes and on the small part's rigid and FFRF design bodies (docs/theory.md 9.9).
  const dynamics::DistributedAlpha &da = da_;
  const dynamics::DistStartTrace &trace = trace_;
  const std::size_t na = active_.size(), nacf = acf_designs_.size();
  const int coordinates = p_.scene_.mechanism.coordinates();
  const bool fallback = trace.fallback != nullptr;
  const bool corrected = trace.rigid.T.size() > 0 && trace.rigid.y.size() > 0 &&
                         trace.rigid.y.cwiseAbs().maxCoeff() > 0;
  Vec cmask = da.create_vector(), lmask = da.create_vector(), rhs = da.create_vector(),
      nu = da.create_vector(), gv = da.create_vector(), w = da.create_vector();
  da.coordinate_mask(cmask);
  FX_PETSC(VecSet(lmask, 1.0));
  FX_PETSC(VecAXPY(lmask, -1.0, cmask));
  std::vector<dynamics::DistState> minus_nu;
  // Per ACF design body and active response: the fallback's multiplier nu_f and the rigid
  // correction's z at its local nodes; per active response the same on the small part.
  std::vector<std::vector<std::vector<double>>> fallback_mu(nacf,
                                                            std::vector<std::vector<double>>(na)),
      field_mu(nacf, std::vector<std::vector<double>>(na));
  Matrix fallback_small(coordinates, static_cast<Eigen::Index>(na)),
      field_small(coordinates, static_cast<Eigen::Index>(na));
  const Eigen::Index field0 =
      corrected ? trace.rigid.T.cols() - 6 * static_cast<Eigen::Index>(trace.fields.size()) : 0;
  // A rigid velocity field (du, dw) at ACF body b's local nodes, about its centre.
  auto field_values = [&](std::size_t b, const dynamics::Vector6 &p, std::vector<double> &out) {
    FX_PETSC(VecZeroEntries(w));
    da.add_rigid_field(s0_, b, p, trace.fields[b].centre, w);
    da.local_values(w, b, out);
  };
  Mat A = da.acceleration_matrix(s0_);
  for (std::size_t a = 0; a < na; ++a) {
    const auto col = static_cast<Eigen::Index>(a);
    dynamics::DistState &g = gbar[a];
    for (Vec x : {g.q, g.v, g.a, g.acc, g.lambda}) FX_PETSC(VecScale(x, -1.0));
    FX_PETSC(VecWAXPY(rhs, 1.0, g.acc, g.a));
    FX_PETSC(VecAXPY(rhs, 1.0, g.lambda));
    da.solve_transpose(rhs, nu);
    dynamics::DistState mu0 = da.zero_state();
    FX_PETSC(VecPointwiseMult(mu0.acc, nu, cmask));
    minus_nu.push_back(mu0);
    if (!fallback && !corrected) continue;
    FX_PETSC(VecPointwiseMult(gv, g.v, cmask));
    da.start_velocity_transpose(s0_, nu, gv);
    if (fallback) {
      da.solve_transpose(gv, nu); // gv is zero on the multiplier entries
      FX_PETSC(VecPointwiseMult(w, nu, cmask));
      for (std::size_t k = 0; k < nacf; ++k)
        da.local_values(w, static_cast<std::size_t>(p_.designs_[acf_designs_[k]].acf),
                        fallback_mu[k][a]);
      if (small_) fallback_small.col(col) = da.small_values(w);
      FX_PETSC(VecPointwiseMult(w, nu, lmask));
      FX_PETSC(MatMultTranspose(A, w, rhs)); // [Phi_q^T nu_lambda; 0]
      FX_PETSC(VecAXPY(gv, -1.0, rhs));
    }
    if (corrected) {
      const Vector z = trace.rigid.Pi * da.rigid_parameters_transpose(s0_, trace, gv);
      for (std::size_t k = 0; k < nacf; ++k) {
        const auto b = static_cast<std::size_t>(p_.designs_[acf_designs_[k]].acf);
        field_values(b, z.segment<6>(field0 + 6 * static_cast<Eigen::Index>(b)), field_mu[k][a]);
      }
      if (small_) field_small.col(col) = trace.rigid.T * z;
    }
  }
  add_partials(s0_, minus_nu, -1.0);
  for (std::size_t k = 0; k < nacf; ++k) {
    DesignBody &db = p_.designs_[acf_designs_[k]];
    const auto b = static_cast<std::size_t>(db.acf);
    std::vector<double> u;
    if (fallback) {
      da.local_values(trace.fallback, b, u);
      add_mass_terms(db, fallback_mu[k], u);
    }
    if (corrected) {
      field_values(b, trace.rigid.field[b], u);
      add_mass_terms(db, field_mu[k], u);
    }
  }
  if (small_ && fallback) add_small_mass_terms(fallback_small, da.small_values(trace.fallback));
  if (small_ && corrected) add_small_mass_terms(field_small, trace.rigid.T * trace.rigid.y);
  for (Vec *x : {&cmask, &lmask, &rhs, &nu, &gv, &w}) VecDestroy(x);
}

void DistPass::backward() {
  direct_partials();
  const double t_adjoint = wall_time();
  // The backward sweep over every kept state (section 9.7), the element partials at each, for
  // the responses that depend on the state (the volume fraction and the mass do not: their
  // multipliers are zero).
  for (std::size_t i = 0; i < p_.specs_.size(); ++i)
    if (p_.sensor_of_[i] >= 0 || !p_.acf_strain_bodies_[i].empty() ||
        !p_.strain_bodies_[i].empty() || p_.stress_[i])
      active_.push_back(i);
  if (active_.empty()) { // no backward sweep: every gradient is the direct partial
    p_.recomputed_ = 0;
    p_.adjoint_factorizations_ = 0;
  } else {
    std::vector<dynamics::DistState> gbar = sweep();
    start_adjoint(gbar);
  }
  p_.adjoint_s_ = wall_time() - t_adjoint;
  long long bytes = store_->peak_bytes();
  MPI_Allreduce(MPI_IN_PLACE, &bytes, 1, MPI_LONG_LONG, MPI_SUM, p_.comm());
  p_.checkpoint_bytes_ = bytes;
  // The small part's design bodies: rigid ones through their mass parameters, FFRF ones through
  // the reduction's adjoint (sections 9.8, 10).
  if (small_) p_.add_element_gradients(G_, StartAdjoint{});
}

} // namespace flexopt::adjoint::detail
