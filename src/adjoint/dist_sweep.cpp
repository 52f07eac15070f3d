#include "flexopt/adjoint/dist_sweep.hpp"

#include "flexopt/core/error.hpp"

namespace flexopt::adjoint {

DistBackwardSweep::DistBackwardSweep(const dynamics::DistributedAlpha &da, int responses)
    : da_(da) {
  for (int r = 0; r < responses; ++r) {
    carry_.push_back(da.zero_state());
    mu_.push_back(da.zero_state());
    z_.push_back(da.create_vector());
  }
  f_ = da.zero_state();
  cmask_ = da.create_vector();
  da.coordinate_mask(cmask_);
  lmask_ = da.create_vector();
  FX_PETSC(VecSet(lmask_, 1.0));
  FX_PETSC(VecAXPY(lmask_, -1.0, cmask_));
  rhs_ = da.create_vector();
  w1_ = da.create_vector();
  w2_ = da.create_vector();
  w3_ = da.create_vector();
}

DistBackwardSweep::~DistBackwardSweep() {
  for (Vec *v : {&cmask_, &lmask_, &rhs_, &w1_, &w2_, &w3_}) VecDestroy(v);
  for (Vec &v : z_) VecDestroy(&v);
}

void DistBackwardSweep::right_hand_side(std::size_t r, const dynamics::DistState *dpsi,
                                        dynamics::DistState &f) const {
  const dynamics::DistState &c = carry_[r];
  const bool has = dpsi && dpsi->q;
  FX_PETSC(VecAXPBY(f.q, -1.0, 0.0, c.q));
  FX_PETSC(VecAXPBY(f.v, -1.0, 0.0, c.v));
  FX_PETSC(VecAXPBY(f.a, -1.0, 0.0, c.a));
  FX_PETSC(VecAXPBY(f.acc, -1.0, 0.0, c.acc));
  FX_PETSC(VecZeroEntries(f.lambda)); // the coupling has no lambda block
  if (has) {
    FX_PETSC(VecAXPY(f.q, -1.0, dpsi->q));
    FX_PETSC(VecAXPY(f.v, -1.0, dpsi->v));
    FX_PETSC(VecAXPY(f.a, -1.0, dpsi->a));
    FX_PETSC(VecAXPY(f.acc, -1.0, dpsi->acc));
    FX_PETSC(VecAXPY(f.lambda, -1.0, dpsi->lambda));
  }
}

const std::vector<dynamics::DistState> &
DistBackwardSweep::step(const dynamics::DistState &state, double h,
                        const std::vector<const dynamics::DistState *> &dpsi) {
  const dynamics::AlphaParameters &par = da_.parameters();
  const dynamics::NewtonScaling k = par.newton_scaling(h);
  const double am = par.alpha_m, af = par.alpha_f, b = par.beta, g = par.gamma;
  const double c = (1 - af) / (1 - am);
  const std::size_t nr = mu_.size();
  ++steps_;
  // S1 = M + (g'/b') C + K/b' (with Phi_q, Phi_q^T): S1^T z = [fd + c fa + fq/b' + (g'/b') fv; fc]
  // (the coordinate blocks are zero on the multipliers, lambda on the coordinates).
  Mat S = da_.newton_matrix(state, h);
  for (std::size_t r = 0; r < nr; ++r) {
    right_hand_side(r, r < dpsi.size() ? dpsi[r] : nullptr, f_);
    FX_PETSC(VecCopy(f_.acc, rhs_));
    FX_PETSC(VecAXPY(rhs_, c, f_.a));
    FX_PETSC(VecAXPY(rhs_, 1 / k.bp, f_.q));
    FX_PETSC(VecAXPY(rhs_, k.gp / k.bp, f_.v));
    FX_PETSC(VecAXPY(rhs_, 1.0, f_.lambda));
    da_.solve_transpose(rhs_, z_[r]);
    // mu_d = z on the coordinates, mu_c = b' z on the multipliers.
    dynamics::DistState &mu = mu_[r];
    FX_PETSC(VecPointwiseMult(mu.acc, z_[r], cmask_));
    FX_PETSC(VecPointwiseMult(mu.lambda, z_[r], lmask_));
    FX_PETSC(VecScale(mu.lambda, k.bp));
    // C^T mu_d from the element loop and the small part (docs/theory.md section 9.7), then
    // K^T mu_d + Phi_q^T mu_c = b' ((S^T z)_coord - M mu_d - (g'/b') C^T mu_d).
    FX_PETSC(VecCopy(f_.q, mu.q));
    FX_PETSC(VecCopy(f_.v, mu.v));
    FX_PETSC(VecCopy(f_.a, mu.a));
    da_.velocity_transpose_multiply(state, mu.acc, w1_);
    FX_PETSC(VecAXPY(mu.v, -1.0, w1_)); // mu_v = f_v - C^T mu_d
    FX_PETSC(MatMultTranspose(S, z_[r], w2_));
    FX_PETSC(VecPointwiseMult(w2_, w2_, cmask_));
    da_.mass_multiply(state, mu.acc, w3_);
    FX_PETSC(VecAXPY(w2_, -1.0, w3_));
    FX_PETSC(VecAXPY(w2_, -k.gp / k.bp, w1_));
    FX_PETSC(VecAXPY(mu.q, -k.bp, w2_)); // mu_q = f_q - K^T mu_d - Phi_q^T mu_c
    // mu_a = (f_a + h^2 b mu_q + h g mu_v) / (1 - a_m).
    FX_PETSC(VecAXPBYPCZ(mu.a, h * h * b, h * g, 1.0, mu.q, mu.v));
    FX_PETSC(VecScale(mu.a, 1 / (1 - am)));
    // The coupling to the previous state: q: -mu_q, v: -mu_v - h mu_q,
    // a: -h^2 (1/2 - b) mu_q - h (1 - g) mu_v + a_m mu_a, acc: -a_f mu_a.
    dynamics::DistState &cr = carry_[r];
    FX_PETSC(VecAXPBY(cr.q, -1.0, 0.0, mu.q));
    FX_PETSC(VecAXPBYPCZ(cr.v, -1.0, -h, 0.0, mu.v, mu.q));
    FX_PETSC(VecAXPBYPCZ(cr.a, -h * h * (0.5 - b), -h * (1 - g), 0.0, mu.q, mu.v));
    FX_PETSC(VecAXPY(cr.a, am, mu.a));
    FX_PETSC(VecAXPBY(cr.acc, -af, 0.0, mu.a));
  }
  return mu_;
}

std::vector<dynamics::DistState>
DistBackwardSweep::finish(const std::vector<const dynamics::DistState *> &dpsi0) const {
  std::vector<dynamics::DistState> out;
  for (std::size_t r = 0; r < mu_.size(); ++r) {
    dynamics::DistState f = da_.zero_state();
    right_hand_side(r, r < dpsi0.size() ? dpsi0[r] : nullptr, f);
    out.push_back(f);
  }
  return out;
}

} // namespace flexopt::adjoint
