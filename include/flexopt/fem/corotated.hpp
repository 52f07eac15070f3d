#pragma once
/// \file The co-rotated linear-elastic element of ACF bodies (docs/theory.md section 8.1): the
/// linear elastic energy E = 1/2 u~^T K u~ of the displacement u~ measured in the frame of the
/// rotation R of the polar decomposition of the deformation gradient at the element centroid,
/// its exact gradient (the internal force, including the variation of R) and its exact Hessian
/// (the tangent). E is invariant under rigid motions, so the force carries no net force or
/// moment and vanishes for a rigidly moved element.
///
/// Pure functions of element data, like element.hpp: no PETSc, no MPI, no heap allocation in
/// corotated_state. Positions are node-major rows (Gmsh ordering), forces and tangents node-major
/// [fx, fy, fz] per node.
#include "flexopt/fem/element.hpp"

namespace flexopt::fem {

/// What an element keeps between evaluations: its reference geometry, its linear stiffness and
/// the shape data at the reference centroid.
struct CorotatedElement {
  ElementType type = ElementType::Tet4;
  ElementCoords X; ///< reference node positions [m]
  ElementMatrix K; ///< linear stiffness [N/m] (modulus factor included)
  ElementCoords h; ///< reference gradients grad_X N_a at the centroid [1/m], one row per node
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxNodes, 1> Nc; ///< N_a at the centroid
  int nodes() const { return static_cast<int>(X.rows()); }
};

/// Sets up the element from its reference node positions: the linear stiffness of
/// element_stiffness (same material, modulus factor and degenerate-element check) and the
/// centroid shape data. Throws flexopt::Error like element_stiffness.
CorotatedElement corotated_element(ElementType type, const ElementCoords &X,
                                   const IsotropicMaterial &mat, double modulus_factor = 1.0);

/// At the current node positions x (one row per node): returns the elastic energy E [J] and,
/// for non-null pointers, the internal force f = dE/dx [N] (3n) and the tangent T = d^2E/dx^2
/// [N/m] (3n x 3n, symmetric). Throws flexopt::Error("... inverted ...") if det F <= 0 at the
/// centroid.
double corotated_state(const CorotatedElement &e, const ElementCoords &x, ElementVector *f,
                       ElementMatrix *T);

/// Stiffness-proportional (Rayleigh) damping on the co-rotated velocities (docs/theory.md
/// section 8.1): with u~' = d u~/dt = B(x) v at positions x and velocities v (one row / 3 per
/// node), returns the dissipated power P = beta u~'^T K u~' [W] (twice the dissipation function
/// D = 1/2 beta u~'^T K u~') and, for non-null pointers, the damping force f = dD/dv [N] (3n),
/// Cv = df/dv [N s/m] (symmetric) and Cx = df/dx [N/m] (not symmetric). f vanishes for every
/// rigid velocity field and carries no net force or moment. beta [s]: the damping ratio of an
/// elastic mode of angular frequency w is beta w / 2. Throws like corotated_state.
double corotated_damping(const CorotatedElement &e, const ElementCoords &x, const ElementVector &v,
                         double beta, ElementVector *f, ElementMatrix *Cv, ElementMatrix *Cx);

/// The von Mises stress [Pa] of the co-rotated stress sigma = S u~ (docs/theory.md section
/// 8.3), S the element's stress matrix at the reference centroid (element_stress_matrix at
/// reference_centroid, of the solid material: no modulus factor), and, if `grad` is non-null,
/// its exact gradient dv/dx [Pa/m] (3n, including the variation of R; zero where v = 0).
/// v is invariant under rigid motions of the element. Throws like corotated_state.
double corotated_von_mises(const CorotatedElement &e, const StressMatrix &S, const ElementCoords &x,
                           ElementVector *grad);

/// The rotation of the polar decomposition F = R U (U symmetric positive definite) of a matrix
/// with det F > 0, by Higham's iteration R <- (R + R^-T) / 2 from R = F, to round-off.
Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d &F);

} // namespace flexopt::fem
