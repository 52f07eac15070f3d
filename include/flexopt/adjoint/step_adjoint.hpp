#pragma once
/// \file One step of the discrete adjoint of generalized-alpha (docs/theory.md section 9): the
/// transposed solve with dR/ds_{n+1} reduced to the transposed scaled Newton matrix, and the
/// coupling (dR_{n+1}/ds_n)^T mu to the previous state. Dense backend (replicated state
/// vectors packed as [q, v, a, acc, lambda], dynamics::State::pack). The dynamics module does not
/// include this module; it supplies the Jacobians (dynamics::GeneralizedAlpha::residual).
#include "flexopt/dynamics/generalized_alpha.hpp"

namespace flexopt::adjoint {

using dynamics::Matrix;
using dynamics::Vector;

/// mu with (dR/ds_{n+1})^T mu = f, from the Jacobian `dR_dnext` (size 4n + m, as
/// GeneralizedAlpha::residual returns it at the converged s_{n+1}) of a step of size h: one LU
/// of the transposed scaled Newton matrix [M + (g'/b') C + K/b', Phi_q^T; Phi_q, 0]^T (n + m
/// unknowns) and back-substitution (section 9). Throws flexopt::Error if that matrix is
/// singular.
Vector step_adjoint(const Matrix &dR_dnext, const dynamics::AlphaParameters &par, double h, int n,
                    int m, const Vector &f);

/// (dR_{n+1}/ds_n)^T mu: the blocks of R_q, R_v, R_a that involve the previous state (section
/// 9), without forming the Jacobian.
Vector previous_coupling(const dynamics::AlphaParameters &par, double h, int n, int m,
                         const Vector &mu);

} // namespace flexopt::adjoint
