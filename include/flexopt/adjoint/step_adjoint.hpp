#pragma once
/// \file One step of the discrete adjoint of generalized-alpha (docs/theory.md section 9): the
/// transposed solve with dR/ds_{n+1} reduced to the transposed scaled Newton matrix, the
/// coupling (dR_{n+1}/ds_n)^T mu to the previous state, and the backward sweep step by step. Dense
/// backend (replicated state vectors packed as [q, v, a, acc, lambda], dynamics::State::pack). The
/// dynamics module does not include this module; it supplies the Jacobians
/// (dynamics::GeneralizedAlpha::jacobian_blocks, residual).
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <Eigen/LU>

namespace flexopt::adjoint {

using dynamics::Matrix;
using dynamics::Vector;

/// The columns mu of (dR/ds_{n+1})^T mu = F for a step of size h, from the blocks K, C, M, J of
/// dR/ds_{n+1} at the converged s_{n+1} (GeneralizedAlpha::jacobian_blocks): one LU of the
/// transposed scaled Newton matrix [M + (g'/b') C + K/b', J^T; J, 0]^T (n + m unknowns) for all
/// columns, then back-substitution (section 9). Throws flexopt::Error if that matrix is
/// singular.
Matrix step_adjoint(const Matrix &K, const Matrix &C, const Matrix &M, const Matrix &J,
                    const dynamics::AlphaParameters &par, double h, const Matrix &F);
/// The same from the full Jacobian `dR_dnext` (size 4n + m, GeneralizedAlpha::residual), for one
/// right-hand side.
Vector step_adjoint(const Matrix &dR_dnext, const dynamics::AlphaParameters &par, double h, int n,
                    int m, const Vector &f);

/// (dR_{n+1}/ds_n)^T mu, column by column: the blocks of R_q, R_v, R_a that involve the previous
/// state (section 9), without forming the Jacobian.
Matrix previous_coupling(const dynamics::AlphaParameters &par, double h, int n, int m,
                         const Matrix &mu);

/// The backward sweep of section 9 step by step, in reverse order of the forward steps, for
/// several responses at once (one column each): the multipliers carry the coupling to the
/// previous state from one call to the next.
class BackwardSweep {
public:
  BackwardSweep(const dynamics::GeneralizedAlpha &ga, int responses);
  /// mu of the step of size h that ended in `state`, with dpsi = (dPsi/ds)^T at that state
  /// (4n + m rows; an empty matrix for zero).
  Matrix step(const dynamics::State &state, double h, const Matrix &dpsi);
  /// mu_0 = -(dPsi/ds_0)^T - (dR_1/ds_0)^T mu_1 at the initial state.
  Matrix finish(const Matrix &dpsi0) const;
  long long steps() const { return steps_; }
  long long factorizations() const { return factorizations_; }

private:
  const dynamics::GeneralizedAlpha &ga_;
  int n_, m_;
  Matrix carry_; ///< (dR_(k+1)/ds_k)^T mu_(k+1)
  Matrix K_, C_, M_, J_, S_, F_, rhs_, z_;
  Eigen::PartialPivLU<Matrix> lu_;
  long long steps_ = 0, factorizations_ = 0;
};

} // namespace flexopt::adjoint
