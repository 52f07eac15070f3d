#include "distributed_alpha_detail.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"

#include <cmath>
#include <cstdio>

/// \file DistributedAlpha's consistent start (docs/theory.md section 6.4) and the pieces its
/// adjoint uses (section 9.2).

namespace flexopt::dynamics {

using detail::copy_of;
using detail::factorized;
using detail::max_abs;
using detail::range;

Mat DistributedAlpha::acceleration_matrix(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  // The matrix [M Phi_q^T; Phi_q 0] (ties with zero multipliers: no Hessian).
  factored_ = false;
  FX_PETSC(MatZeroEntries(A_));
  FX_PETSC(MatAXPY(A_, 1.0, M_, SAME_NONZERO_PATTERN));
  const State sm = small_state(s);
  if (small_) add_all_ties(s, sm, false, 1.0, A_, w_); // w_: the ties' right-hand side, unused
  if (comm_rank(comm_) == 0 && small_)
    add_mass_system(*small_, sm, A_, L.small_coord0, L.small_row0);
  FX_PETSC(VecAssemblyBegin(w_));
  FX_PETSC(VecAssemblyEnd(w_));
  FX_PETSC(MatAssemblyBegin(A_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(A_, MAT_FINAL_ASSEMBLY));
  return A_;
}

DistState DistributedAlpha::initial_state(Vec q0, Vec v0, double t0, StartReport *report,
                                          DistStartTrace *trace) const {
  const detail::AcfLayout &L = *layout_;
  const bool root = comm_rank(comm_) == 0;
  DistState s;
  s.t = t0;
  s.q = copy_of(q0);
  s.v = copy_of(v0);
  FX_PETSC(VecPointwiseMult(s.q, s.q, cmask_)); // no values on the multiplier entries
  FX_PETSC(VecPointwiseMult(s.v, s.v, cmask_));
  s.acc = create_vector();
  s.a = create_vector();
  s.lambda = create_vector();
  const fem::CorotatedSum sum = internal(s.q, nullptr);
  if (!sum.ok) throw Error("initial state: " + sum.failure, true);
  // Positions: every constraint must hold (the ties do by construction of the placement).
  const double scale = 1 + max_abs(s.q);
  State sm = small_state(s);
  {
    const double ties = tie_violation(s);
    std::string bad;
    int nbad = 0;
    auto sci = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.3e", v);
      return std::string(buf);
    };
    if (ties > 1e-9 * scale)
      bad += "\n  the ties of the ACF interfaces: residual " + sci(ties), ++nbad;
    if (small_) {
      Vector all;
      small_->all_constraint_values(sm.q, t0, all);
      for (int r = 0; r < all.size(); ++r)
        if (!(std::abs(all(r)) <= 1e-9 * scale) && nbad++ < 6)
          bad += "\n  " + small_->describe_row(r) + ": residual " + sci(all(r));
    }
    if (nbad > 0)
      throw Error("initial conditions: a scene with ACF bodies must be placed assembled (its "
                  "joints closed to 1e-9 of the scene's size; positions are not projected); "
                  "these constraints are violated:" +
                      bad +
                      "\n(an interface's point is the centroid of its meshed surface placed with "
                      "the body; gaps below 1e-4 of the scene's size count as meeting, larger ones "
                      "are not closed in a scene with ACF bodies: place the bodies assembled, or "
                      "give the body with an initial elastic field the field that closes them; "
                      "docs/case-format.md \"joints\")",
                  true);
  }
  acceleration_matrix(s);
  if (!factorized(ksp_))
    throw Error("initial conditions: the acceleration system [M Phi_q^T; Phi_q 0] is singular "
                "(a body without mass, an interface node held by nothing, or joints that "
                "leave no consistent acceleration)",
                true);
  auto solve = [&](const char *what) {
    FX_PETSC(KSPSolve(ksp_, r_, dz_));
    KSPConvergedReason reason;
    FX_PETSC(KSPGetConvergedReason(ksp_, &reason));
    if (reason < 0 || !std::isfinite(max_abs(dz_)))
      throw Error(std::string("initial conditions: the solve for the ") + what + " failed (" +
                      KSPConvergedReasons[reason] + ")",
                  true);
  };
  // Velocities: the rigid-body velocities corrected onto Phi_q v + Phi_t = 0 with the least
  // change of kinetic energy, the elastic ones kept (section 6.4).
  StartReport rep;
  rep.kinetic_given = kinetic_energy(s);
  const double given = velocity_violation(s, sm);
  rep.given_violation = given;
  if (small_) {
    const std::vector<RigidField> fields = rigid_fields(s);
    const VelocityCorrection c = rigid_velocity_correction(*small_, sm.q, sm.v, t0, fields);
    if (trace) {
      trace->rigid = c;
      trace->fields = fields;
    }
    if (root) {
      PetscScalar *v;
      FX_PETSC(VecGetArray(s.v, &v));
      for (int k = 0; k < L.small_n; ++k) v[L.small_coord0 - L.start + k] += c.dv(k);
      FX_PETSC(VecRestoreArray(s.v, &v));
    }
    for (std::size_t b = 0; b < bodies_.size(); ++b)
      add_rigid_field(s, b, c.field[b], fields[b].centre, s.v);
    sm = small_state(s);
  }
  rep.rigid_residual = velocity_violation(s, sm);
  if (rep.rigid_residual > kVelocityTolerance * (1 + given)) {
    // The joints (or ties holding a surface that the given elastic velocities deform) need
    // elastic velocities: the smallest change in kinetic energy of all velocities,
    // S [dv; mu] = [0; -(Phi_q v + Phi_t)] (massless interface nodes change freely).
    solve("velocity projection");
    FX_PETSC(VecPointwiseMult(w_, dz_, cmask_));
    FX_PETSC(VecAXPY(s.v, 1.0, w_));
    sm = small_state(s);
    rep.elastic_corrected = true;
    if (trace) {
      FX_PETSC(VecDestroy(&trace->fallback));
      trace->fallback = copy_of(w_);
    }
  }
  rep.kinetic = kinetic_energy(s);
  if (report) *report = rep;
  // Accelerations and multipliers: [M Phi_q^T; Phi_q 0] [acc; lambda] = [Q; gamma].
  start_rhs(s, r_);
  solve("initial accelerations");
  FX_PETSC(VecPointwiseMult(s.acc, dz_, cmask_));
  FX_PETSC(VecPointwiseMult(s.lambda, dz_, lmask_));
  FX_PETSC(VecCopy(s.acc, s.a));
  return s;
}

void DistributedAlpha::add_rigid_field(const DistState &s, std::size_t b, const Vector6 &p,
                                       const Vec3 &centre, Vec v) const {
  const detail::AcfLayout &L = *layout_;
  const Vec3 du = p.head<3>(), dw = p.tail<3>();
  const PetscInt base = L.offset[b] - L.start;
  PetscScalar *va;
  const PetscScalar *x;
  FX_PETSC(VecGetArray(v, &va));
  FX_PETSC(VecGetArrayRead(s.q, &x));
  for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
    const Vec3 d =
        du + dw.cross(Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - centre);
    for (int k = 0; k < 3; ++k) va[base + 3 * i + k] += d(k);
  }
  FX_PETSC(VecRestoreArrayRead(s.q, &x));
  FX_PETSC(VecRestoreArray(v, &va));
}

Vector DistributedAlpha::small_values(Vec v) const {
  const detail::AcfLayout &L = *layout_;
  const int n = small_ ? small_->coordinates() : 0;
  Vector out(n);
  if (comm_rank(comm_) == 0 && n > 0) {
    const PetscScalar *a;
    FX_PETSC(VecGetArrayRead(v, &a));
    for (int i = 0; i < n; ++i) out(i) = a[L.small_coord0 - L.start + i];
    FX_PETSC(VecRestoreArrayRead(v, &a));
  }
  MPI_Bcast(out.data(), n, MPI_DOUBLE, 0, comm_);
  return out;
}

void DistributedAlpha::start_rhs(const DistState &s, Vec r) const {
  const detail::AcfLayout &L = *layout_;
  const bool root = comm_rank(comm_) == 0;
  const State sm = small_state(s);
  const double t0 = s.t;
  Vector phi_t, phi_tt, phi_qt_v;
  internal(s.q, nullptr, s.v);          // the damping force at the velocities of s
  FX_PETSC(VecWAXPY(r, -1.0, F_, fg_)); // f_g - f(x) - f_d(x, v) on the ACF rows, 0 elsewhere
  {
    PetscScalar *ra;
    FX_PETSC(VecGetArray(r, &ra));
    std::vector<double> gamma;
    for (std::size_t i = 0; i < L.ties.size(); ++i) {
      const TieSet &t = L.ties[i];
      gamma.resize(3 * t.s.size());
      const int o = small_ ? small_->offset(interfaces_[i].node_body) : 0;
      if (!t.s.empty()) tie_accelerations(t, sm.v.segment<4>(o + 3), gamma.data());
      for (std::size_t k = 0; k < gamma.size(); ++k)
        ra[t.row0 - L.start + static_cast<PetscInt>(k)] = gamma[k];
    }
    if (root && small_) {
      const int n = L.small_n, m = L.small_m;
      Vector r0;
      small_->dynamics(sm.q, sm.v, Vector::Zero(n), t0, r0, nullptr, nullptr, nullptr);
      small_->constraint_time_terms(sm.q, sm.v, t0, phi_t, phi_tt, phi_qt_v);
      const Vector gamma_s = -small_->constraint_convective(sm.q, sm.v, t0) - 2 * phi_qt_v - phi_tt;
      for (int k = 0; k < n; ++k) ra[L.small_coord0 + k] = -r0(k);
      for (int k = 0; k < m; ++k) ra[L.small_row0 + k] = gamma_s(k);
    }
    FX_PETSC(VecRestoreArray(r, &ra));
  }
}

void DistributedAlpha::start_velocity_transpose(const DistState &s0, Vec nu, Vec gv) const {
  const detail::AcfLayout &L = *layout_;
  // Q = f_g - f - f_d(x, v) on the ACF rows and -r(q, v, 0) on the small part's: -C^T nu.
  FX_PETSC(VecPointwiseMult(w_, nu, cmask_));
  velocity_transpose_multiply(s0, w_, dz_);
  FX_PETSC(VecAXPY(gv, -1.0, dz_));
  if (!small_) return;
  const State sm = small_state(s0);
  const int n = small_->coordinates(), m = small_->constraints(); // on every rank
  // The ties: gamma_j = D(p', s_j) p' (3 rows per tied node), d gamma_j / dp' = 2 D(p', s_j);
  // each rank sums over its tied nodes, rank 0 adds the total to the interface nodes' rates.
  Vector local = Vector::Zero(n), total(n);
  {
    const PetscScalar *l;
    FX_PETSC(VecGetArrayRead(nu, &l));
    for (std::size_t i = 0; i < L.ties.size(); ++i) {
      const TieSet &t = L.ties[i];
      const int o = small_->offset(interfaces_[i].node_body);
      const bodies::Vec4 pd = sm.v.segment<4>(o + 3);
      for (std::size_t j = 0; j < t.s.size(); ++j) {
        const PetscInt row = t.row0 - L.start + 3 * static_cast<PetscInt>(j);
        const Vec3 w(l[row], l[row + 1], l[row + 2]);
        local.segment<4>(o + 3) += 2 * bodies::rotate_jacobian(pd, t.s[j]).transpose() * w;
      }
    }
    FX_PETSC(VecRestoreArrayRead(nu, &l));
  }
  MPI_Allreduce(local.data(), total.data(), n, MPI_DOUBLE, MPI_SUM, comm_);
  if (comm_rank(comm_) == 0 && m > 0) {
    // The small part's gamma = -(Phi_q v)_q v - 2 Phi_qt v - Phi_tt: gamma_v^T nu_c =
    // -2 (sum_i nu_c,i H_i) v - 2 Phi_qt^T nu_c, Phi_qt column by column from v -> Phi_qt v.
    Vector nc(m);
    const PetscScalar *l;
    FX_PETSC(VecGetArrayRead(nu, &l));
    for (int k = 0; k < m; ++k) nc(k) = l[L.small_row0 - L.start + k];
    FX_PETSC(VecRestoreArrayRead(nu, &l));
    Matrix H = Matrix::Zero(n, n);
    small_->add_constraint_hessian(sm.q, s0.t, nc, H);
    total -= 2 * H * sm.v;
    Vector phi_t, phi_tt, phi_qt_v;
    for (int j = 0; j < n; ++j) {
      small_->constraint_time_terms(sm.q, Vector::Unit(n, j), s0.t, phi_t, phi_tt, phi_qt_v);
      total(j) -= 2 * phi_qt_v.dot(nc);
    }
  }
  // gv += gamma_v^T nu (the constraint rows' right-hand side is +gamma).
  if (comm_rank(comm_) == 0) {
    PetscScalar *g;
    FX_PETSC(VecGetArray(gv, &g));
    for (int k = 0; k < n; ++k) g[L.small_coord0 - L.start + k] += total(k);
    FX_PETSC(VecRestoreArray(gv, &g));
  }
}

Vector DistributedAlpha::rigid_parameters_transpose(const DistState &s0,
                                                    const DistStartTrace &trace, Vec g) const {
  const detail::AcfLayout &L = *layout_;
  const auto k = trace.rigid.T.cols();
  const Eigen::Index field0 = k - 6 * static_cast<Eigen::Index>(trace.fields.size());
  Vector local = Vector::Zero(k), out(k);
  const PetscScalar *ga, *x;
  FX_PETSC(VecGetArrayRead(g, &ga));
  FX_PETSC(VecGetArrayRead(s0.q, &x));
  if (comm_rank(comm_) == 0 && small_)
    for (int i = 0; i < L.small_n; ++i)
      local += ga[L.small_coord0 - L.start + i] * trace.rigid.T.row(i).transpose();
  for (std::size_t b = 0; b < trace.fields.size(); ++b) {
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
      const Vec3 gi(ga[base + 3 * i], ga[base + 3 * i + 1], ga[base + 3 * i + 2]);
      const Vec3 arm =
          Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - trace.fields[b].centre;
      local.segment<3>(field0 + 6 * static_cast<Eigen::Index>(b)) += gi;
      local.segment<3>(field0 + 6 * static_cast<Eigen::Index>(b) + 3) += arm.cross(gi);
    }
  }
  FX_PETSC(VecRestoreArrayRead(s0.q, &x));
  FX_PETSC(VecRestoreArrayRead(g, &ga));
  MPI_Allreduce(local.data(), out.data(), static_cast<int>(k), MPI_DOUBLE, MPI_SUM, comm_);
  return out;
}

double DistributedAlpha::velocity_violation(const DistState &s, const State &small) const {
  const detail::AcfLayout &L = *layout_;
  FX_PETSC(MatMult(A_, s.v, w_)); // multiplier rows: Phi_q v
  FX_PETSC(VecPointwiseMult(r_, w_, lmask_));
  FX_PETSC(VecScale(r_, -1.0));
  if (comm_rank(comm_) == 0 && small_) {
    Vector phi_t, phi_tt, phi_qt_v;
    small_->constraint_time_terms(small.q, small.v, small.t, phi_t, phi_tt, phi_qt_v);
    const Vector m_phi_t = -phi_t;
    const auto ir = range(L.small_row0, L.small_m);
    FX_PETSC(VecSetValues(r_, L.small_m, ir.data(), m_phi_t.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(r_));
  FX_PETSC(VecAssemblyEnd(r_));
  return max_abs(r_);
}

std::vector<RigidField> DistributedAlpha::rigid_fields(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  std::vector<RigidField> fields(bodies_.size());
  const PetscScalar *x;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    RigidField &f = fields[b];
    for (const AcfInterface &i : interfaces_)
      if (i.body == b) f.nodes.push_back(i.node_body);
    const PetscInt base = L.offset[b] - L.start, nodes = bodies_[b]->mesh().owned_nodes;
    double sum[4] = {0, 0, 0, static_cast<double>(nodes)}, all[4];
    FX_PETSC(VecGetArrayRead(s.q, &x));
    for (PetscInt i = 0; i < nodes; ++i)
      for (int k = 0; k < 3; ++k) sum[k] += x[base + 3 * i + k];
    FX_PETSC(VecRestoreArrayRead(s.q, &x));
    MPI_Allreduce(sum, all, 4, MPI_DOUBLE, MPI_SUM, comm_);
    f.centre = Vec3(all[0], all[1], all[2]) / all[3];
    // V: unit translations and unit spins about the centre on body b's nodes; metric V^T M V.
    std::array<Vec, 6> V{}, MV{};
    FX_PETSC(VecGetArrayRead(s.q, &x));
    std::vector<Vec3> arm(static_cast<std::size_t>(nodes));
    for (PetscInt i = 0; i < nodes; ++i)
      arm[static_cast<std::size_t>(i)] =
          Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - f.centre;
    FX_PETSC(VecRestoreArrayRead(s.q, &x));
    for (int c = 0; c < 6; ++c) {
      V[static_cast<std::size_t>(c)] = create_vector();
      MV[static_cast<std::size_t>(c)] = create_vector();
      PetscScalar *a;
      FX_PETSC(VecGetArray(V[static_cast<std::size_t>(c)], &a));
      for (PetscInt i = 0; i < nodes; ++i) {
        const Vec3 d = c < 3 ? Vec3(Vec3::Unit(c))
                             : Vec3(Vec3::Unit(c - 3).cross(arm[static_cast<std::size_t>(i)]));
        for (int k = 0; k < 3; ++k) a[base + 3 * i + k] = d(k);
      }
      FX_PETSC(VecRestoreArray(V[static_cast<std::size_t>(c)], &a));
      FX_PETSC(MatMult(M_, V[static_cast<std::size_t>(c)], MV[static_cast<std::size_t>(c)]));
    }
    for (int c = 0; c < 6; ++c) {
      PetscScalar dots[6];
      FX_PETSC(VecMDot(V[static_cast<std::size_t>(c)], 6, MV.data(), dots));
      for (int d = 0; d < 6; ++d) f.metric(c, d) = dots[d];
    }
    f.metric = 0.5 * (f.metric + f.metric.transpose()).eval();
    for (int c = 0; c < 6; ++c) {
      FX_PETSC(VecDestroy(&V[static_cast<std::size_t>(c)]));
      FX_PETSC(VecDestroy(&MV[static_cast<std::size_t>(c)]));
    }
  }
  return fields;
}

} // namespace flexopt::dynamics
