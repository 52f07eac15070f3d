#include "distributed_alpha_detail.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/dynamics/newton_loop.hpp"

#include <cmath>

/// \file DistributedAlpha's Newton step (docs/theory.md sections 6 and 8.2): the kept matrix's
/// rotations, the internal forces, the ties and constraints, the assembly, the step and the
/// transposed products of its adjoint.

namespace flexopt::dynamics {

using detail::copy_of;
using detail::factorized;
using detail::max_abs;
using detail::range;

void DistributedAlpha::kept_rotations(Vec q) const {
  const detail::AcfLayout &L = *layout_;
  KeptFrame &a = *kept_;
  const PetscScalar *x, *x0;
  FX_PETSC(VecGetArrayRead(q, &x));
  FX_PETSC(VecGetArrayRead(a.q, &x0));
  // Per body the centroids and the 3x3 sum of (x - c)(x0 - c0)^T = sum x x0^T - n c c0^T, from
  // sums of x, x0 and x x0^T over the owned nodes.
  const std::size_t nb = bodies_.size();
  std::vector<double> sums(nb * 16, 0.0), all(nb * 16);
  for (std::size_t b = 0; b < nb; ++b) {
    double *m = &sums[16 * b];
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
      const PetscScalar *xi = x + base + 3 * i, *yi = x0 + base + 3 * i;
      for (int r = 0; r < 3; ++r) {
        m[9 + r] += xi[r];
        m[12 + r] += yi[r];
        for (int c = 0; c < 3; ++c) m[3 * r + c] += xi[r] * yi[c];
      }
      m[15] += 1;
    }
  }
  FX_PETSC(VecRestoreArrayRead(q, &x));
  FX_PETSC(VecRestoreArrayRead(a.q, &x0));
  MPI_Allreduce(sums.data(), all.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM, comm_);
  a.rotated = false;
  for (std::size_t b = 0; b < nb; ++b) {
    const double *m = &all[16 * b];
    const Vec3 c(m[9], m[10], m[11]), c0(m[12], m[13], m[14]);
    bodies::Mat3 H;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) H(r, k) = m[3 * r + k];
    H -= c * c0.transpose() / m[15];
    // The rotation nearest to H (Kabsch): U V^T with the sign of det fixed.
    const Eigen::JacobiSVD<bodies::Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    bodies::Mat3 D = bodies::Mat3::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    a.rotation[b] = svd.matrixU() * D * svd.matrixV().transpose();
    const Eigen::Quaterniond qr(a.rotation[b]);
    const Vec3 qv(qr.x(), qr.y(), qr.z());
    Eigen::Matrix4d &Lq = a.quaternion[b];
    Lq(0, 0) = qr.w();
    Lq.block<1, 3>(0, 1) = -qv.transpose();
    Lq.block<3, 1>(1, 0) = qv;
    Lq.block<3, 3>(1, 1) = qr.w() * bodies::Mat3::Identity() + bodies::skew(qv);
    if (!a.rotation[b].isIdentity(0)) a.rotated = true;
  }
}

void DistributedAlpha::rotate_kept(Vec v, bool transpose) const {
  const detail::AcfLayout &L = *layout_;
  const KeptFrame &a = *kept_;
  PetscScalar *x;
  FX_PETSC(VecGetArray(v, &x));
  auto turn = [&](PetscScalar *y, const bodies::Mat3 &R) {
    const Vec3 w =
        transpose ? Vec3(R.transpose() * Vec3(y[0], y[1], y[2])) : Vec3(R * Vec3(y[0], y[1], y[2]));
    y[0] = w(0), y[1] = w(1), y[2] = w(2);
  };
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i)
      turn(x + base + 3 * i, a.rotation[b]);
  }
  for (std::size_t i = 0; i < L.ties.size(); ++i) {
    const TieSet &t = L.ties[i];
    const bodies::Mat3 &R = a.rotation[interfaces_[i].body];
    for (std::size_t j = 0; j < t.s.size(); ++j)
      turn(x + t.row0 - L.start + static_cast<PetscInt>(3 * j), R);
    // The interface node: r turns with R, the Euler parameters by the quaternion product
    // p -> q p (R(q p) = R(q) R(p)).
    const PetscInt o = L.small_coord0 + small_->offset(interfaces_[i].node_body);
    if (o >= L.start && o + 7 <= L.start + L.local) {
      turn(x + o - L.start, R);
      const Eigen::Matrix4d &Lq = a.quaternion[interfaces_[i].body];
      PetscScalar *y = x + o - L.start + 3;
      const Eigen::Vector4d w =
          transpose ? Eigen::Vector4d(Lq.transpose() * Eigen::Vector4d(y[0], y[1], y[2], y[3]))
                    : Eigen::Vector4d(Lq * Eigen::Vector4d(y[0], y[1], y[2], y[3]));
      for (int k = 0; k < 4; ++k) y[k] = w(k);
    }
  }
  FX_PETSC(VecRestoreArray(v, &x));
}

fem::CorotatedSum DistributedAlpha::internal(Vec x, Mat T, Vec v, double gp) const {
  detail::AcfLayout &L = *layout_;
  FX_PETSC(VecZeroEntries(F_));
  if (T) FX_PETSC(MatZeroEntries(T));
  double energy = 0;
  std::string failure;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
    gather(x, b);
    PetscScalar *u;
    FX_PETSC(VecGetArray(L.local_x[b], &u));
    for (PetscInt l = 0; l < 3 * m.local_nodes(); ++l)
      u[l] -= m.coordinates[static_cast<std::size_t>(l)];
    fem::CorotatedDamping damping;
    const bool damped = v && bodies_[b]->damping() > 0;
    if (damped) {
      gather(v, b, L.local_v[b]);
      FX_PETSC(VecGetArrayRead(L.local_v[b], &damping.v));
      damping.beta = bodies_[b]->damping();
      damping.gp = gp;
    }
    energy += fem::add_corotated(m, bodies_[b]->elements(), u, L.node_dof[b], F_, T, failure,
                                 damped ? &damping : nullptr);
    if (damped) FX_PETSC(VecRestoreArrayRead(L.local_v[b], &damping.v));
    FX_PETSC(VecRestoreArray(L.local_x[b], &u));
  }
  FX_PETSC(VecAssemblyBegin(F_));
  FX_PETSC(VecAssemblyEnd(F_));
  if (T) {
    FX_PETSC(MatAssemblyBegin(T, MAT_FINAL_ASSEMBLY));
    FX_PETSC(MatAssemblyEnd(T, MAT_FINAL_ASSEMBLY));
  }
  return fem::reduce_corotated(comm_, energy, failure);
}

double DistributedAlpha::add_all_ties(const DistState &s, const State &small, bool multipliers,
                                      double bp, Mat A, Vec rhs) const {
  const detail::AcfLayout &L = *layout_;
  const PetscScalar *q, *l = nullptr;
  FX_PETSC(VecGetArrayRead(s.q, &q));
  if (multipliers) FX_PETSC(VecGetArrayRead(s.lambda, &l));
  double violation = 0;
  std::vector<double> x, lambda;
  for (std::size_t i = 0; i < L.ties.size(); ++i) {
    const TieSet &t = L.ties[i];
    if (t.s.empty()) continue;
    // The tied nodes and their rows are owned: their values are in the local arrays.
    x.resize(3 * t.s.size());
    lambda.assign(3 * t.s.size(), 0.0);
    for (std::size_t j = 0; j < t.s.size(); ++j)
      for (std::size_t k = 0; k < 3; ++k) {
        x[3 * j + k] = q[t.x_dof[j] - L.start + static_cast<PetscInt>(k)];
        if (l) lambda[3 * j + k] = l[t.row0 - L.start + static_cast<PetscInt>(3 * j + k)];
      }
    const int o = small_->offset(interfaces_[i].node_body);
    violation = std::max(violation, add_ties(t, x.data(), small.q.segment<3>(o),
                                             small.q.segment<4>(o + 3), lambda.data(), bp, A, rhs));
  }
  FX_PETSC(VecRestoreArrayRead(s.q, &q));
  if (l) FX_PETSC(VecRestoreArrayRead(s.lambda, &l));
  return violation;
}

double DistributedAlpha::add_constraints(const DistState &next, double bp, double gp,
                                         bool matrix) const {
  const detail::AcfLayout &L = *layout_;
  double violation = 0;
  if (small_) {
    const State sm = small_state(next);
    violation = add_all_ties(next, sm, true, bp, matrix ? A_ : nullptr, r_);
    if (comm_rank(comm_) == 0) {
      Vector rhs;
      if (matrix)
        add_newton_system(*small_, sm, bp, gp, A_, L.small_coord0, L.small_row0, rhs);
      else
        newton_system_rhs(*small_, sm, bp, rhs);
      const int n = L.small_n, m = L.small_m;
      const auto ic = range(L.small_coord0, n), ir = range(L.small_row0, m);
      FX_PETSC(VecSetValues(r_, n, ic.data(), rhs.data(), ADD_VALUES));
      FX_PETSC(VecSetValues(r_, m, ir.data(), rhs.data() + n, ADD_VALUES));
      if (m > 0) violation = std::max(violation, rhs.tail(m).cwiseAbs().maxCoeff());
    }
  }
  FX_PETSC(VecAssemblyBegin(r_));
  FX_PETSC(VecAssemblyEnd(r_));
  if (matrix) {
    FX_PETSC(MatAssemblyBegin(A_, MAT_FINAL_ASSEMBLY));
    FX_PETSC(MatAssemblyEnd(A_, MAT_FINAL_ASSEMBLY));
  }
  double global;
  MPI_Allreduce(&violation, &global, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return global;
}

bool DistributedAlpha::assemble(const DistState &next, const NewtonScaling &k, bool matrix,
                                double &violation) const {
  LogScope log(matrix ? "FxNewtonMatrix" : "FxNewtonRhs"); // the element loops included
  // An inverted element fails the evaluation.
  if (!internal(next.q, matrix ? A_ : nullptr, next.v, k.gp).ok) return false;
  if (matrix) {
    // A = M + (T + df_d/dx + gamma' df_d/dv) / beta' on the ACF bodies; M_ has A_'s stored
    // pattern.
    FX_PETSC(MatScale(A_, 1.0 / k.bp));
    FX_PETSC(MatAXPY(A_, 1.0, M_, SAME_NONZERO_PATTERN));
  }
  // r = -(M acc + f(q) + f_d(q, v) - f_g) / beta' on the ACF rows (0 elsewhere), then the
  // constraints.
  FX_PETSC(MatMult(M_, next.acc, r_));
  FX_PETSC(VecAXPY(r_, 1.0, F_));
  FX_PETSC(VecAXPY(r_, -1.0, fg_));
  FX_PETSC(VecScale(r_, -1.0 / k.bp));
  violation = add_constraints(next, k.bp, k.gp, matrix);
  return true;
}

void DistributedAlpha::equations(const DistState &s, Vec R) const {
  double violation;
  NewtonScaling unit;
  unit.bp = 1;
  if (!assemble(s, unit, false, violation))
    throw Error("DistributedAlpha::equations: an inverted element", true);
  FX_PETSC(VecAXPBY(R, -1.0, 0.0, r_));
}

Mat DistributedAlpha::newton_matrix(const DistState &s, double h) const {
  double violation;
  factored_ = false;
  if (!assemble(s, par_.newton_scaling(h), true, violation))
    throw Error("DistributedAlpha::newton_matrix: an inverted element", true);
  return A_;
}

void DistributedAlpha::solve_transpose(Vec rhs, Vec z) const {
  factored_ = false; // the factorization below is not a kept Newton matrix of the forward run
  if (!factorized(ksp_))
    throw Error("adjoint: the transposed Newton matrix of a step is singular", true);
  FX_PETSC(KSPSolveTranspose(ksp_, rhs, z));
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(ksp_, &reason));
  if (reason < 0 || !std::isfinite(max_abs(z)))
    throw Error("adjoint: the transposed solve of a step failed (" +
                    std::string(KSPConvergedReasons[reason]) + ")",
                true);
}

void DistributedAlpha::velocity_transpose_multiply(const DistState &s, Vec x, Vec y) const {
  detail::AcfLayout &L = *layout_;
  FX_PETSC(VecZeroEntries(y));
  std::vector<double> xl, vl, pos;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const double beta = bodies_[b]->damping();
    if (!(beta > 0)) continue;
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
    local_values(x, b, xl);
    local_values(s.v, b, vl);
    local_values(s.q, b, pos);
    fem::ElementMatrix Cv;
    std::vector<double> out(xl.size(), 0.0);
    const int npe = m.nodes_per_element();
    for (PetscInt e = 0; e < m.local_elements(); ++e) {
      const fem::CorotatedElement &ce = bodies_[b]->elements()[static_cast<std::size_t>(e)];
      fem::ElementCoords xe(npe, 3);
      for (int a = 0; a < npe; ++a) {
        const PetscInt l = m.connectivity[static_cast<std::size_t>(e * npe + a)];
        for (int k = 0; k < 3; ++k) xe(a, k) = pos[static_cast<std::size_t>(3 * l + k)];
      }
      fem::corotated_damping(ce, xe, fem::gather_element(m, e, vl.data()), beta, nullptr, &Cv,
                             nullptr);
      const fem::ElementVector ye = Cv.transpose() * fem::gather_element(m, e, xl.data());
      for (int a = 0; a < npe; ++a) {
        const PetscInt l = m.connectivity[static_cast<std::size_t>(e * npe + a)];
        for (int k = 0; k < 3; ++k) out[static_cast<std::size_t>(3 * l + k)] += ye(3 * a + k);
      }
    }
    add_local_values(y, b, out);
  }
  if (small_) {
    const State sm = small_state(s);
    if (comm_rank(comm_) == 0) {
      const int n = L.small_n;
      Vector r, xs(n);
      Matrix C;
      small_->dynamics(sm.q, sm.v, sm.acc, sm.t, r, nullptr, &C, nullptr);
      const PetscScalar *xa;
      FX_PETSC(VecGetArrayRead(x, &xa));
      for (int i = 0; i < n; ++i) xs(i) = xa[L.small_coord0 + i];
      FX_PETSC(VecRestoreArrayRead(x, &xa));
      add_small(y, C.transpose() * xs);
    }
  }
  FX_PETSC(VecAssemblyBegin(y));
  FX_PETSC(VecAssemblyEnd(y));
}

void DistributedAlpha::mass_multiply(const DistState &s, Vec x, Vec y) const {
  const detail::AcfLayout &L = *layout_;
  FX_PETSC(MatMult(M_, x, y)); // the ACF rows (M_ is zero elsewhere)
  if (!small_) return;
  const State sm = small_state(s);
  if (comm_rank(comm_) == 0) {
    const int n = L.small_n;
    Vector r, xs(n);
    Matrix Ms;
    small_->dynamics(sm.q, sm.v, Vector::Zero(n), sm.t, r, nullptr, nullptr, &Ms);
    const PetscScalar *xa;
    FX_PETSC(VecGetArrayRead(x, &xa));
    for (int i = 0; i < n; ++i) xs(i) = xa[L.small_coord0 + i];
    FX_PETSC(VecRestoreArrayRead(x, &xa));
    const Vector ys = Ms * xs;
    const auto ic = range(L.small_coord0, n);
    FX_PETSC(VecSetValues(y, n, ic.data(), ys.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(y));
  FX_PETSC(VecAssemblyEnd(y));
}

bool DistributedAlpha::step_once(const DistState &s, double h, DistState &next,
                                 StepInfo &info) const {
  if (!next.q) next = s; // vectors of the right layout
  struct Backend {
    const DistributedAlpha &da;
    const DistState &s;
    DistState &next;
    double h;
    double violation = 0; ///< max |Phi| at the last right-hand side
    void predict() {      // acc1 = acc0, lambda1 = lambda0
      predict_state();
      // A kept matrix is applied in the bodies' present orientation (co-rotated kept matrix).
      if (da.factored_ && da.settings_.corotate_kept) da.kept_rotations(next.q);
    }
    void predict_state() {
      const double am = da.par_.alpha_m, g = da.par_.gamma, b = da.par_.beta;
      next.t = s.t + h;
      FX_PETSC(VecCopy(s.acc, next.acc));
      FX_PETSC(VecCopy(s.lambda, next.lambda));
      // a1 = (af acc0 - am a0 + (1 - af) acc1) / (1 - am) = (acc0 - am a0) / (1 - am)
      FX_PETSC(VecAXPBYPCZ(next.a, 1 / (1 - am), -am / (1 - am), 0.0, s.acc, s.a));
      // v1 = v0 + h (1 - g) a0 + h g a1
      FX_PETSC(VecCopy(s.v, next.v));
      FX_PETSC(VecAXPBYPCZ(next.v, h * (1 - g), h * g, 1.0, s.a, next.a));
      // q1 = q0 + h v0 + h^2 (1/2 - b) a0 + h^2 b a1
      FX_PETSC(VecCopy(s.q, next.q));
      const PetscScalar coef[3] = {h, h * h * (0.5 - b), h * h * b};
      Vec vecs[3] = {s.v, s.a, next.a};
      FX_PETSC(VecMAXPY(next.q, 3, coef, vecs));
    }
    bool has_matrix(const NewtonScaling &k) const {
      return da.factored_ && da.bp_ == k.bp && da.gp_ == k.gp;
    }
    bool factorize(const NewtonScaling &k) {
      da.kept_->reset(next.q);
      da.factored_ = false;
      if (!da.assemble(next, k, true, violation) || !factorized(da.ksp_)) return false;
      da.factored_ = true;
      da.bp_ = k.bp;
      da.gp_ = k.gp;
      return true;
    }
    bool rhs(const NewtonScaling &k) { return da.assemble(next, k, false, violation); }
    bool solve_update(const NewtonScaling &k, double &increment, double &phi) {
      phi = violation;
      const bool turn = da.kept_->rotated;
      if (turn) da.rotate_kept(da.r_, true); // into the frame of the kept matrix
      FX_PETSC(KSPSolve(da.ksp_, da.r_, da.dz_));
      if (turn) da.rotate_kept(da.dz_, false);
      KSPConvergedReason reason;
      FX_PETSC(KSPGetConvergedReason(da.ksp_, &reason));
      if (reason < 0) return false;
      FX_PETSC(VecPointwiseMult(da.w_, da.dz_, da.cmask_)); // dq
      const double d = max_abs(da.w_);
      if (!std::isfinite(d)) return false;
      FX_PETSC(VecAXPY(next.q, 1.0, da.w_));
      FX_PETSC(VecAXPY(next.v, k.gp, da.w_));
      FX_PETSC(VecAXPY(next.acc, k.bp, da.w_));
      FX_PETSC(VecAXPY(next.a, k.ap, da.w_));
      FX_PETSC(VecPointwiseMult(da.w_, da.dz_, da.lmask_)); // the scaled multipliers' update
      FX_PETSC(VecAXPY(next.lambda, k.bp, da.w_));
      increment = d / (1 + max_abs(next.q));
      return true;
    }
    void drop_matrix() { da.factored_ = false; }
  } backend{*this, s, next, h};
  return detail::newton_loop(backend, settings_, par_.newton_scaling(h), info);
}

bool DistributedAlpha::advance(const DistState &s, double h, DistState &next, StepInfo &info,
                               std::vector<std::pair<DistState, double>> *substeps) const {
  return detail::advance_with_halving(
      s, h, next, info, settings_.max_halvings,
      [this](const DistState &from, double dt, DistState &to, StepInfo &i) {
        return step_once(from, dt, to, i);
      },
      substeps);
}

bool DistributedAlpha::step(const DistState &s, double h, DistState &next, StepInfo &info) const {
  return step_once(s, h, next, info);
}

} // namespace flexopt::dynamics
