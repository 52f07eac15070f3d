// DynamicProblem on the distributed backend (docs/theory.md sections 9.6 and 9.7), for a scene
// with ACF bodies whose design body is ACF (element partials) or rigid (mass-parameter partials
// on the small part): the forward run with the states kept or checkpointed, the responses, the
// backward sweep with the design partials, and the adjoint of the consistent start (9.2).
#include "flexopt/adjoint/dist_sweep.hpp"
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <sstream>

namespace flexopt::adjoint {

void DynamicProblem::evaluate_distributed(bool gradients, optimize::Evaluation &out) {
  const mesh::DistributedMesh &m = mesh();
  const auto ne = static_cast<std::size_t>(m.local_elements());
  const bool acf = acf_design_ >= 0; // else a rigid design body in the small part
  const auto design = static_cast<std::size_t>(acf ? acf_design_ : 0);
  bodies::AcfBody *body = acf ? scene_.acf[design].get() : nullptr;
  const std::size_t nr = specs_.size();
  Matrix G = Matrix::Zero(10, static_cast<Eigen::Index>(nr)); // rigid: dPsi/dtheta
  dynamics::Mechanism &mech = scene_.mechanism;
  const double h = settings_.time.step;

  const double t_forward = wall_time();
  const dynamics::Integrator integrator(scene_, integration_);
  const dynamics::DistributedAlpha &da = integrator.dist();
  dynamics::DistStartTrace trace; // what the start did to the velocities (section 9.2)
  DistRecord record;
  record.state = dynamics::acf_initial_state(scene_, da, nullptr, &trace);
  // Which ACF body each strain energy response measures.
  std::vector<int> strain_body(nr, -1);
  for (std::size_t i = 0; i < nr; ++i)
    if (specs_[i]->type == optimize::ResponseType::StrainEnergyIntegral)
      for (std::size_t b = 0; b < settings_.scene.bodies.size(); ++b)
        if (settings_.scene.bodies[b].name == specs_[i]->body)
          strain_body[i] = scene_.bodies[b].acf;
  // Local displacements of ACF body b at a state (mesh numbering, owned and ghosts).
  auto displacement = [&](const dynamics::DistState &s, std::size_t b) {
    std::vector<double> u;
    da.local_values(s.q, b, u);
    const mesh::DistributedMesh &mb = scene_.acf[b]->mesh();
    for (std::size_t k = 0; k < u.size(); ++k) u[k] -= mb.coordinates[k];
    return u;
  };
  samples_.assign(nr, {});
  std::vector<std::vector<double>> energy(nr); // U_n of strain responses
  std::vector<double> energy_steps;            // U_e at one step
  std::unique_ptr<BinomialSchedule> schedule;
  std::vector<char> keep;
  std::unique_ptr<DistCheckpointStore> store;
  if (gradients) {
    keep = plan_checkpoints(schedule);
    store = settings_.adjoint.storage == CheckpointStorage::Disk
                ? dist_disk_store(checkpoint_file(), da)
                : dist_memory_store();
  }
  auto sample = [&](const dynamics::DistState &s) {
    const dynamics::State small = da.small_state(s);
    for (std::size_t i = 0; i < nr; ++i) {
      if (sensor_of_[i] >= 0) {
        const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
        samples_[i].push_back(bs.acf_body >= 0
                                  ? dynamics::acf_sensor_value(scene_, da, bs, s, small)
                                  : dynamics::sensor_value(scene_, bs, small.q));
      }
      if (strain_body[i] >= 0) {
        const auto b = static_cast<std::size_t>(strain_body[i]);
        const std::vector<double> u = displacement(s, b);
        const std::vector<double> Ue = scene_.acf[b]->element_energies(u.data());
        double local = 0;
        for (double x : Ue) local += x;
        double total = 0;
        MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, m.comm);
        energy[i].push_back(total);
        if (acf && b == design) {
          // Kept per step: the direct partial sum_n w_n U_e / s_e needs the weights (N known).
          energy_steps.insert(energy_steps.end(), Ue.begin(), Ue.end());
        }
      }
    }
  };
  sample(record.state);
  const dynamics::DistState s0 = record.state;
  if (gradients) store->put(0, record);
  if (observer_) observer_(0, dynamics::StepInfo{}, nullptr, &record.state);
  dynamics::run_steps(da, steps_, h, record, &substep_sizes_,
                      [&](long long j, const dynamics::StepInfo &info) {
                        sample(record.state);
                        if (gradients && keep[static_cast<std::size_t>(j)]) store->put(j, record);
                        if (observer_) observer_(j, info, nullptr, &record.state);
                      });
  const auto N = static_cast<std::size_t>(steps_);
  sampled_.assign(nr, SampledResponse{});
  for (std::size_t i = 0; i < nr; ++i) {
    if (sensor_of_[i] >= 0) sampled_[i] = sampled_response(*specs_[i], samples_[i], h);
    if (strain_body[i] >= 0)
      for (std::size_t n = 0; n <= N; ++n)
        sampled_[i].value += trapezoid_weight(n, N) * energy[i][n];
  }
  if (!finish_forward(t_forward, gradients, out)) return;

  // Direct partials of an ACF design body: the strain energy's sum_n w_n U_e / s_e, the mass's
  // rho V_e (a rigid design body's mass: add_rigid_element_gradients).
  const std::vector<double> volume = fem::element_volumes(m);
  for (std::size_t i = 0; i < nr && acf; ++i) {
    if (strain_body[i] == acf_design_) {
      std::size_t column = 0; // energy_steps holds ne values per step for each such response
      for (std::size_t k = 0; k < i; ++k) column += strain_body[k] == acf_design_ ? 1 : 0;
      const std::size_t per_step =
          ne *
          static_cast<std::size_t>(std::count(strain_body.begin(), strain_body.end(), acf_design_));
      for (std::size_t n = 0; n <= N; ++n)
        for (std::size_t e = 0; e < ne; ++e)
          element_gradient_[i][e] += trapezoid_weight(n, N) * ds_[e] / s_[e] *
                                     energy_steps[n * per_step + column * ne + e];
    }
    if (specs_[i]->type == optimize::ResponseType::Mass && specs_[i]->body == settings_.design.body)
      for (std::size_t e = 0; e < ne; ++e)
        element_gradient_[i][e] += dw_[e] * body->material().density * volume[e];
  }

  // Backward sweep over every kept state (section 9.7), the element partials at each, for the
  // responses that depend on the state (the volume fraction and the mass do not: their
  // multipliers are zero).
  const double t_adjoint = wall_time();
  std::vector<std::size_t> active;
  for (std::size_t i = 0; i < nr; ++i)
    if (sensor_of_[i] >= 0 || strain_body[i] >= 0) active.push_back(i);
  const std::size_t na = active.size();
  auto finish_adjoint = [&](long long factorizations) {
    adjoint_s_ = wall_time() - t_adjoint;
    adjoint_factorizations_ = factorizations;
    long long bytes = store->peak_bytes();
    MPI_Allreduce(MPI_IN_PLACE, &bytes, 1, MPI_LONG_LONG, MPI_SUM, m.comm);
    checkpoint_bytes_ = bytes;
  };
  if (na == 0) { // no backward sweep: every gradient is the direct partial
    recomputed_ = 0;
    finish_adjoint(0);
    if (!acf) add_rigid_element_gradients(G);
    return;
  }
  DistBackwardSweep sweep(da, static_cast<int>(na));
  std::vector<dynamics::DistState> partials;
  for (std::size_t a = 0; a < na; ++a) partials.push_back(da.zero_state());
  // (dPsi/ds)^T at main step j, state s: the sensors' and strain energies' q blocks.
  auto state_partials_dist = [&](std::size_t j, const dynamics::DistState &s) {
    std::vector<const dynamics::DistState *> ptr(na, nullptr);
    const dynamics::State small = da.small_state(s);
    std::vector<double> force;
    for (std::size_t a = 0; a < na; ++a) {
      const std::size_t i = active[a];
      dynamics::DistState &P = partials[a];
      FX_PETSC(VecZeroEntries(P.q));
      bool any = false;
      if (sensor_of_[i] >= 0 && !sampled_[i].dy[j].isZero(0)) {
        const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
        const Vec3 &dy = sampled_[i].dy[j];
        if (bs.acf_body >= 0) {
          const auto b =
              static_cast<std::size_t>(scene_.bodies[static_cast<std::size_t>(bs.acf_body)].acf);
          da.add_point_weights(P.q, b, bs.location, dy);
        } else {
          da.add_small(P.q, sensor_jacobian(scene_, bs, small.q).transpose() * dy);
        }
        any = true;
      }
      if (strain_body[i] >= 0) {
        const auto b = static_cast<std::size_t>(strain_body[i]);
        const std::vector<double> u = displacement(s, b);
        force.assign(u.size(), 0.0);
        scene_.acf[b]->element_energies(u.data(), force.data());
        // Each element's force went to its local nodes; ghosts are added on their owners.
        for (double &f : force) f *= trapezoid_weight(j, N);
        da.add_local_values(P.q, b, force);
        any = true;
      }
      FX_PETSC(VecAssemblyBegin(P.q));
      FX_PETSC(VecAssemblyEnd(P.q));
      if (any) ptr[a] = &P;
    }
    return ptr;
  };
  std::vector<std::vector<double>> d_modulus, d_mass, mu_d(na);
  std::vector<double> u, v, acc;
  std::vector<const double *> mu_ptr(na);
  // The design partials mu . dR/dx at state s for the multipliers mu (one per active response):
  // an ACF design body's G_e += ds mu . dR/ds_e + dw mu . dR/dw_e in one element loop; a rigid
  // one's dPsi/dtheta += (dr/dtheta)^T mu_d on the small part.
  auto add_partials = [&](const dynamics::DistState &s, const std::vector<dynamics::DistState> &mu,
                          double sign) {
    if (na == 0) return;
    if (!acf) {
      const dynamics::State sm = da.small_state(s);
      Matrix W(sm.q.size(), static_cast<Eigen::Index>(na));
      for (std::size_t a = 0; a < na; ++a)
        W.col(static_cast<Eigen::Index>(a)) = da.small_values(mu[a].acc);
      const Matrix P = design_partials(sm.q, sm.v, sm.acc, true, W);
      for (std::size_t a = 0; a < na; ++a)
        G.col(static_cast<Eigen::Index>(active[a])) += sign * P.col(static_cast<Eigen::Index>(a));
      return;
    }
    u = displacement(s, design);
    da.local_values(s.v, design, v);
    da.local_values(s.acc, design, acc);
    for (std::size_t a = 0; a < na; ++a) {
      da.local_values(mu[a].acc, design, mu_d[a]);
      mu_ptr[a] = mu_d[a].data();
    }
    body->design_partials(u.data(), v.data(), acc.data(), mu_ptr, mech.gravity, d_modulus, d_mass);
    for (std::size_t a = 0; a < na; ++a)
      for (std::size_t e = 0; e < ne; ++e)
        element_gradient_[active[a]][e] +=
            sign * (ds_[e] * d_modulus[a][e] + dw_[e] * d_mass[a][e]);
  };
  auto visit = [&](long long jj, const DistRecord &r) {
    const auto j = static_cast<std::size_t>(jj);
    if (r.substeps.empty()) {
      add_partials(r.state, sweep.step(r.state, h, state_partials_dist(j, r.state)), 1.0);
      return;
    }
    // A halved step: its substeps backwards, the responses only at its end (section 9.3).
    for (std::size_t k = r.substeps.size(); k-- > 0;) {
      const bool end = k + 1 == r.substeps.size();
      const dynamics::DistState &s = end ? r.state : r.substeps[k].first;
      add_partials(s,
                   sweep.step(s, r.substeps[k].second,
                              end ? state_partials_dist(j, r.state)
                                  : std::vector<const dynamics::DistState *>(na, nullptr)),
                   1.0);
    }
  };
  recomputed_ = reverse_steps<DistRecord>(
      schedule.get(), *store, steps_,
      [&](const DistRecord &previous, long long j) { return recompute_dist(da, previous, j); },
      visit);
  std::vector<dynamics::DistState> gbar = sweep.finish(state_partials_dist(0, s0));
  // gbar = -mu_0 = dPsi/ds_0; the initial accelerations [M Phi_q^T; Phi_q 0] [acc; lambda] =
  // [Q; gamma] (section 9.2, stage 2): nu from the transposed system, then -nu_acc . dr/dtheta.
  // Stages 3 and 4 (the velocities) only if the start changed them: gv = dPsi/dv_0 through the
  // accelerations, then the elastic fallback v_0 = v_r + dv (nu_f = A^-T [gv; 0], -nu_f^T dM dv,
  // gv -= Phi_q^T nu_f,lambda) and the rigid-body correction v_r = v_given + T y (z = Pi T^T gv,
  // -(T z)^T dM (T y) on the design body's rigid velocity field).
  const bool fallback = trace.fallback != nullptr;
  const bool corrected = trace.rigid.T.size() > 0 && trace.rigid.y.size() > 0 &&
                         trace.rigid.y.cwiseAbs().maxCoeff() > 0;
  Vec cmask = da.create_vector(), lmask = da.create_vector(), rhs = da.create_vector(),
      nu = da.create_vector(), gv = da.create_vector(), w = da.create_vector();
  da.coordinate_mask(cmask);
  FX_PETSC(VecSet(lmask, 1.0));
  FX_PETSC(VecAXPY(lmask, -1.0, cmask));
  std::vector<dynamics::DistState> minus_nu;
  // Per active response: the fallback's multiplier nu_f and the rigid correction's z, at the
  // design body's local nodes (ACF) or on the small part (rigid).
  std::vector<std::vector<double>> fallback_mu(na), field_mu(na);
  Matrix fallback_small(mech.coordinates(), static_cast<Eigen::Index>(na)),
      field_small(mech.coordinates(), static_cast<Eigen::Index>(na));
  const Eigen::Index field0 =
      corrected ? trace.rigid.T.cols() - 6 * static_cast<Eigen::Index>(trace.fields.size()) : 0;
  const Vec3 centre = corrected && acf ? trace.fields[design].centre : Vec3::Zero();
  // A rigid velocity field (du, dw) at the ACF design body's local nodes.
  auto field_values = [&](const dynamics::Vector6 &p, std::vector<double> &out) {
    FX_PETSC(VecZeroEntries(w));
    da.add_rigid_field(s0, design, p, centre, w);
    da.local_values(w, design, out);
  };
  Mat A = da.acceleration_matrix(s0);
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
    da.start_velocity_transpose(s0, nu, gv);
    if (fallback) {
      da.solve_transpose(gv, nu); // gv is zero on the multiplier entries
      FX_PETSC(VecPointwiseMult(w, nu, cmask));
      if (acf)
        da.local_values(w, design, fallback_mu[a]);
      else
        fallback_small.col(col) = da.small_values(w);
      FX_PETSC(VecPointwiseMult(w, nu, lmask));
      FX_PETSC(MatMultTranspose(A, w, rhs)); // [Phi_q^T nu_lambda; 0]
      FX_PETSC(VecAXPY(gv, -1.0, rhs));
    }
    if (corrected) {
      const Vector z = trace.rigid.Pi * da.rigid_parameters_transpose(s0, trace, gv);
      if (acf)
        field_values(z.segment<6>(field0 + 6 * static_cast<Eigen::Index>(design)), field_mu[a]);
      else
        field_small.col(col) = trace.rigid.T * z;
    }
  }
  add_partials(s0, minus_nu, -1.0);
  // -mu^T (dM/dx) u at the start for multipliers mu (one per active response) and one velocity
  // change u: per element -dw_e mu_e^T M0_e u_e of an ACF design body, or -(dM/dtheta u)^T mu
  // of a rigid one.
  auto add_mass_terms = [&](const std::vector<std::vector<double>> &mus,
                            const std::vector<double> &velocity) {
    std::vector<const double *> ptr(na);
    for (std::size_t a = 0; a < na; ++a) ptr[a] = mus[a].data();
    const std::vector<double> u0 = displacement(s0, design);
    body->design_partials(u0.data(), nullptr, velocity.data(), ptr, Vec3::Zero(), d_modulus,
                          d_mass);
    for (std::size_t a = 0; a < na; ++a)
      for (std::size_t e = 0; e < ne; ++e) element_gradient_[active[a]][e] -= dw_[e] * d_mass[a][e];
  };
  auto add_small_mass_terms = [&](const Matrix &mus, const Vector &velocity) {
    const dynamics::State sm = da.small_state(s0);
    const Matrix P = design_partials(sm.q, Vector::Zero(sm.q.size()), velocity, false, mus);
    for (std::size_t a = 0; a < na; ++a)
      G.col(static_cast<Eigen::Index>(active[a])) -= P.col(static_cast<Eigen::Index>(a));
  };
  if (fallback) {
    if (acf) {
      std::vector<double> dv;
      da.local_values(trace.fallback, design, dv);
      add_mass_terms(fallback_mu, dv);
    } else {
      add_small_mass_terms(fallback_small, da.small_values(trace.fallback));
    }
  }
  if (corrected) {
    if (acf) {
      std::vector<double> uy;
      field_values(trace.rigid.field[design], uy);
      add_mass_terms(field_mu, uy);
    } else {
      add_small_mass_terms(field_small, trace.rigid.T * trace.rigid.y);
    }
  }
  for (Vec *x : {&cmask, &lmask, &rhs, &nu, &gv, &w}) VecDestroy(x);
  finish_adjoint(sweep.steps() + 1); // one factorization per backward step, one at the start
  if (!acf) add_rigid_element_gradients(G);
}

DistRecord DynamicProblem::recompute_dist(const dynamics::DistributedAlpha &da,
                                          const DistRecord &previous, long long j) const {
  return dynamics::recompute_step(da, previous, j, settings_.time.step,
                                  substep_sizes_[static_cast<std::size_t>(j)]);
}

} // namespace flexopt::adjoint
