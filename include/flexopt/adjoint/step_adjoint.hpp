#pragma once
/// \file One step of the discrete adjoint of generalized-alpha (docs/theory.md section 9): the
/// transposed solve with dR/ds_{n+1} reduced to the transposed scaled Newton matrix, and the
/// coupling (dR_{n+1}/ds_n)^T mu to the previous state. Dense backend (replicated state
/// vectors packed as [q, v, a, acc, lambda], dynamics::State::pack). The dynamics module does not
/// include this module; it supplies the Jacobians (dynamics::GeneralizedAlpha::residual).
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <vector>

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

/// The backward sweep of section 9 on the dense backend: from the states s_0 ... s_N of a
/// forward run with steps of h (each converged, R(s_n, s_(n-1)) = 0) and the partials
/// dpsi[n] = (dPsi/ds_n)^T (packed like State::pack), the multipliers mu_1 ... mu_N of the step
/// residuals and mu_0 = -(dPsi/ds_0)^T - (dR_1/ds_0)^T mu_1, returned as mu[0] ... mu[N].
/// Treating s_0 as free, dPsi/ds_0 = -mu_0^T.
std::vector<Vector> backward_sweep(const dynamics::GeneralizedAlpha &ga,
                                   const std::vector<dynamics::State> &states, double h,
                                   const std::vector<Vector> &dpsi);

} // namespace flexopt::adjoint
