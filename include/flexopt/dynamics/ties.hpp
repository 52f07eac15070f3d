#pragma once
/// \file The RBE2 ties of an ACF body's interface to its interface node (docs/theory.md section
/// 8.2): Phi_j = x_j - r - A(p) s_j = 0 for every tied surface node j, with the interface
/// node's coordinates (r, p) and the multipliers lambda_j (3 per node).
#include "flexopt/bodies/quaternion.hpp"

#include <petscmat.h>
#include <petscvec.h>
#include <vector>

namespace flexopt::dynamics {

/// The ties of one interface held by this rank, and where their unknowns live in the global
/// system: node j's position at x_dof[j] + (0, 1, 2), its rows at row0 + 3 j + (0, 1, 2), the
/// interface node's r at coord0 + (0, 1, 2) and p at coord0 + 3 + (0 .. 3).
struct TieSet {
  std::vector<PetscInt> x_dof;
  std::vector<bodies::Vec3> s; ///< s_j = X_j - c_I (mesh coordinates)
  PetscInt row0 = 0, coord0 = 0;
};

/// Adds the ties' part of the scaled Newton system of section 6.4 (ADD_VALUES, no assembly):
/// into A the rows Phi_j,q = [I (x_j), -I (r), -D(p, s_j) (p)], their transposes, and the
/// Hessian contraction of lambda_j^T Phi_j, -K(s_j, lambda_j) / beta' in the (p, p) block; into
/// rhs = -[(R_d + Phi_q^T lambda) / beta'; Phi] the parts -lambda_j / beta' (x_j rows),
/// +lambda_j / beta' (r rows), +D(p, s_j)^T lambda_j / beta' (p rows) and -Phi_j (tie rows).
/// A null: the right-hand side alone (an iteration on a kept matrix). x and lambda: 3 values
/// per tie. Returns max |Phi_j|. Not collective.
double add_ties(const TieSet &ties, const double *x, const bodies::Vec3 &r, const bodies::Vec4 &p,
                const double *lambda, double bp, Mat A, Vec rhs);

/// The velocity part of the ties' second time derivative: Phi_j'' = Phi_j,q q'' - gamma_j with
/// gamma_j = D(p', s_j) p' (D is linear in p), into gamma (3 per tie): the right-hand side of the
/// consistent initial accelerations, Phi_q q'' = gamma. Not collective.
void tie_accelerations(const TieSet &ties, const bodies::Vec4 &p_dot, double *gamma);

} // namespace flexopt::dynamics
