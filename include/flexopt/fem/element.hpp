#pragma once
/// \file Element kernels for 3D isotropic linear elasticity (Tet4, Tet10, Hex8 volumes; Tri3, Tri6,
/// Quad4 faces).
///
/// Every function here is a pure function of element data: no PETSc, no MPI, no global state other
/// than immutable, thread-safe function-local caches of quadrature rules and shape-function values.
/// The kernels do not allocate on the heap (fixed-maximum-size Eigen types); the functions
/// returning a `QuadratureRule` do, and are meant for set-up code and tests.
///
/// Units: the kernels are unit-agnostic but consistent; the documentation uses SI (coordinates [m],
/// displacements [m], moduli and stresses [Pa], density [kg/m^3], forces [N]).
/// Conventions: DOF order is node-major, [ux, uy, uz] per node. Voigt order is xx, yy, zz, yz, xz,
/// xy; stresses use tensor components, strains use engineering shear (gamma_ij = 2 eps_ij).
/// Node orderings are Gmsh's. The equations are written out in docs/theory.md (section 3; geometric
/// stiffness: section 7.5). Errors (bad input sizes, invalid material, degenerate or inverted
/// elements) throw flexopt::Error.
#include "flexopt/core/error.hpp"
#include "flexopt/mesh/element_type.hpp"

#include <Eigen/Dense>
#include <vector>

namespace flexopt::fem {

/// The mesh's element and face types (mesh/element_type.hpp), which the kernels are written for.
using mesh::ElementType;
using mesh::FaceType;
using mesh::kMaxFaceNodes;
using mesh::kMaxNodes;
/// Maximum number of DOFs of a volume element: three displacement components per node.
constexpr int kMaxDofs = 3 * kMaxNodes;
using mesh::corner_nodes;
using mesh::element_name;
using mesh::ElementCoords;
using mesh::face_name;
using mesh::FaceCoords;
using mesh::nodes_per_element;
using mesh::nodes_per_face;
/// Element matrix (3n x 3n), node-major DOF order.
using ElementMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor, kMaxDofs, kMaxDofs>;
/// Element vector (3n), node-major DOF order.
using ElementVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxDofs, 1>;
/// Symmetric tensor in Voigt notation, order xx, yy, zz, yz, xz, xy. Stresses [Pa] hold tensor
/// components; strains hold engineering shear (gamma = 2 eps) so that sigma = D * eps.
using Voigt = Eigen::Matrix<double, 6, 1>;

/// Isotropic linear-elastic material.
struct IsotropicMaterial {
  double E;       ///< Young's modulus [Pa], > 0
  double nu;      ///< Poisson's ratio [-], -1 < nu < 0.5
  double density; ///< mass density [kg/m^3]
  /// First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) [Pa].
  double lambda() const;
  /// Shear modulus mu = E / (2 (1 + nu)) [Pa].
  double mu() const;
  /// 6x6 elasticity matrix D [Pa] such that sigma = D * eps (Voigt order above, engineering shear
  /// strains): D = lambda m m^T + mu diag(2, 2, 2, 1, 1, 1), m = (1, 1, 1, 0, 0, 0).
  Eigen::Matrix<double, 6, 6> elasticity() const;
  /// Throws flexopt::Error unless E > 0, -1 < nu < 0.5 and density >= 0 (all finite).
  void validate() const;
};

/// Quadrature rule on a reference element: sum_q weights[q] f(points[q]) approximates the integral
/// of f over the reference element. All weights are positive.
struct QuadratureRule {
  std::vector<Eigen::Vector3d> points; ///< reference coordinates (third coordinate 0 on faces)
  std::vector<double> weights;         ///< weights; they sum to the reference measure
};

/// Quadrature on the reference element: exact for polynomials of total degree <= `degree` (for
/// Hex8: of degree <= `degree` in each coordinate direction). Tets: reference tet (0,0,0), (1,0,0),
/// (0,1,0), (0,0,1), volume 1/6; degree <= 1 gives the 1-point centroid rule, degree 2 the
/// symmetric 4-point rule, degree >= 3 a collapsed (Duffy) tensor Gauss-Legendre rule. Hex8:
/// reference cube
/// [-1,1]^3, tensor Gauss-Legendre with ceil((degree+1)/2) points per direction. Gauss-Legendre
/// points are computed by Newton iteration on the Legendre polynomials. 0 <= degree <= 40.
QuadratureRule volume_quadrature(ElementType type, int degree);
/// Quadrature on the reference face: triangles (0,0), (1,0), (0,1) (area 1/2; centroid rule for
/// degree <= 1, 3-point rule for degree 2, collapsed Gauss-Legendre above), quad [-1,1]^2 (tensor
/// Gauss-Legendre, degree per direction). Points are 2D (third coordinate 0). 0 <= degree <= 40.
QuadratureRule face_quadrature(FaceType type, int degree);

/// Shape functions and their reference derivatives at reference point xi (any point; no range
/// check). N has n entries, dN is n x 3 row-major: dN[i*3+k] = dN_i/dxi_k. Node ordering is Gmsh's
/// (Tet10: nodes 4..9 on edges (0,1), (1,2), (2,0), (3,0), (3,2), (3,1); Hex8: Gmsh = VTK ordering,
/// bottom face z=-1 counter-clockwise from (-1,-1,-1), then the top face). Either pointer may be
/// null to skip that output.
void shape_functions(ElementType type, const Eigen::Vector3d &xi, double *N, double *dN);
/// Face shape functions at reference point xi: N has n entries, dN is n x 2 row-major. Gmsh node
/// ordering (Tri6: nodes 3, 4, 5 on edges (0,1), (1,2), (2,0); Quad4 counter-clockwise from
/// (-1,-1)). Either pointer may be null.
void face_shape_functions(FaceType type, const Eigen::Vector2d &xi, double *N, double *dN);
/// Reference coordinates of the element centroid: (1/4, 1/4, 1/4) for tets, (0, 0, 0) for Hex8.
Eigen::Vector3d reference_centroid(ElementType type);

/// Element stiffness K_e = modulus_factor * int_e B^T D B dV [N/m] (DOF order node-major),
/// symmetric positive semi-definite with exactly the 6 rigid-body modes in its kernel.
/// modulus_factor scales E (e.g. the SIMP interpolation factor). Quadrature: Tet4 1 point, Tet10 4
/// points (18 if its mid-edge nodes are displaced from the edge midpoints, so that the patch test
/// still holds), Hex8 2x2x2. X has nodes_per_element(type) rows. Throws flexopt::Error("...
/// degenerate or inverted element ...") if det J <= 1e-12 h^3 at a quadrature point (h:
/// bounding-box diagonal).
ElementMatrix element_stiffness(ElementType type, const ElementCoords &X,
                                const IsotropicMaterial &mat, double modulus_factor = 1.0);
/// Consistent mass M_e = density * int_e N^T N dV [kg] (3x3 identity blocks per node pair), exact
/// for every element geometry of the type (affine or curved Tet10, any trilinear Hex8). Throws
/// like element_stiffness for degenerate or inverted elements.
ElementMatrix element_mass(ElementType type, const ElementCoords &X, double density);
/// Element volume int_e dV = int det J dxi [m^3], computed exactly for every geometry of the type.
/// Does not throw for inverted elements: the result is the signed integral of det J (negative for
/// a fully inverted element), so that callers can use it as an orientation check.
double element_volume(ElementType type, const ElementCoords &X);
/// Consistent nodal load of a constant body force b [N/m^3]: f_(i,k) = b_k int_e N_i dV [N], exact
/// for every geometry of the type. Throws like element_stiffness for degenerate or inverted
/// elements.
ElementVector element_body_force(ElementType type, const ElementCoords &X,
                                 const Eigen::Vector3d &b);
/// Displacement gradient H(i, j) = du_i/dx_j at reference point xi for the element displacement
/// vector u_e (node-major, 3n entries). Throws flexopt::Error naming `who` if det J <= 0 at xi
/// or u_e has the wrong size.
Eigen::Matrix3d displacement_gradient(ElementType type, const ElementCoords &X,
                                      const ElementVector &u_e, const Eigen::Vector3d &xi,
                                      const char *who = "displacement_gradient");
/// Stress (Voigt) [Pa] at reference point xi for the element displacement vector u_e [m]
/// (node-major, 3n entries): sigma = modulus_factor * D * B(xi) u_e. Throws if det J <= 0 at xi.
Voigt element_stress(ElementType type, const ElementCoords &X, const IsotropicMaterial &mat,
                     double modulus_factor, const ElementVector &u_e, const Eigen::Vector3d &xi);
/// Geometric (initial-stress) stiffness [N/m] of the stress that the element displacement u_e
/// [m] (node-major, 3n entries) produces: K_sigma = int_e G^T S G dV, i.e.
///   (K_sigma)_(i,k),(j,l) = delta_kl int_e dN_i/dx_a sigma_ab(u_e) dN_j/dx_b dV,
/// with the stress tensor sigma(u_e) = D B u_e (tensor components, modulus factor 1) evaluated at
/// every quadrature point of element_stiffness's rule for this element (same points, same
/// degenerate-element check and error). w^T K_sigma w = int_e sigma : (grad w^T grad w) dV is the
/// second-order work of the prestress on a displacement w; adding K_sigma to K is the standard
/// stress-stiffening correction of a prestressed body. Exactly symmetric and linear in u_e;
/// zero on rigid translations. Exact for Tet4; for a uniform stress (u_e of a linear field) exact
/// on affine Tet10 and parallelepiped Hex8, and w^T K_sigma w of a linear w is exact on every
/// geometry of the type (the rule integrates det J exactly). Otherwise (varying stress on Tet10,
/// distorted Hex8) it carries the quadrature error of the stiffness rule. Throws flexopt::Error
/// for a wrong u_e size, an invalid material, or a degenerate or inverted element.
ElementMatrix element_geometric_stiffness(ElementType type, const ElementCoords &X,
                                          const IsotropicMaterial &mat, const ElementVector &u_e);
/// The derivative with respect to u_e of sum_kl Gbar_kl psi_k^T K_sigma(u_e) psi_l, for the n
/// element vectors psi_k (the columns of `psi`, 3 nodes_per_element rows, node-major) and a
/// symmetric n x n `Gbar`: the "pseudo-load" of the adjoint of a reduced geometric stiffness
/// (docs/theory.md section 10, step 1). Since K_sigma is linear in u_e, this is the internal force
/// int_e B^T (D : T) dV of the stress-like tensor T = sum_kl Gbar_kl sym(H_k^T H_l), H_k = grad
/// psi_k, on element_geometric_stiffness's rule (modulus factor 1). Throws as
/// element_geometric_stiffness.
ElementVector element_geometric_stiffness_load(ElementType type, const ElementCoords &X,
                                               const IsotropicMaterial &mat,
                                               const Eigen::Ref<const Eigen::MatrixXd> &psi,
                                               const Eigen::Ref<const Eigen::MatrixXd> &Gbar);
/// Stress matrix S = D B(xi) [Pa/m], 6 x 3n (node-major columns), of unit modulus factor: the
/// Voigt stress of an element displacement u_e at reference point xi is S u_e (= element_stress
/// with modulus_factor 1), and S^T g is the nodal load whose work on u_e is g . sigma (the
/// adjoint of a stress functional; docs/theory.md section 5.1). Throws if det J <= 0 at xi.
using StressMatrix = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxDofs>;
StressMatrix element_stress_matrix(ElementType type, const ElementCoords &X,
                                   const IsotropicMaterial &mat, const Eigen::Vector3d &xi);
/// von Mises equivalent stress [Pa] of a Voigt stress:
/// sqrt(((sxx-syy)^2 + (syy-szz)^2 + (szz-sxx)^2) / 2 + 3 (syz^2 + sxz^2 + sxy^2)).
double von_mises(const Voigt &sigma);
/// d(von_mises)/d(sigma) [-] of a Voigt stress: V sigma / von_mises(sigma), i.e.
/// (2sxx-syy-szz, 2syy-szz-sxx, 2szz-sxx-syy, 6syz, 6sxz, 6sxy) / (2 von_mises); zero where
/// the von Mises stress is zero (the cone point of the norm; docs/theory.md section 5.1).
Voigt von_mises_gradient(const Voigt &sigma);
/// Consistent nodal load [N] of a constant traction t [N/m^2] on a (possibly curved, quadratic)
/// face in 3D: f_(i,k) = t_k int N_i dA, dA = |dx/dxi x dx/deta| dxi deta. Xf: one row per face
/// node (Gmsh ordering). Exact for flat straight-sided Tri3/Tri6 and planar Quad4; curved Tri6 and
/// warped Quad4 faces use a high-order rule (Tri6: degree 10, Quad4: 4x4 points).
ElementVector face_traction_load(FaceType type, const FaceCoords &Xf, const Eigen::Vector3d &t);
/// Consistent nodal load [N] of the linear traction t(x) = t0 + T (x - c) on a face:
/// f_(a,k) = int N_a t_k dA (the face's rule, at least degree 2: exact on flat straight-sided
/// faces). A force F and moment M about c carried by a surface: t0 = F / area, T = [J^-1 M]x with
/// J the surface's face_second_moment about its centroid c (docs/theory.md section 14.3).
ElementVector face_linear_traction_load(FaceType type, const FaceCoords &Xf,
                                        const Eigen::Vector3d &t0, const Eigen::Matrix3d &T,
                                        const Eigen::Vector3d &c);
/// int (|x - c|^2 I - (x - c)(x - c)^T) dA over a face [m^4] (the rule of
/// face_linear_traction_load).
Eigen::Matrix3d face_second_moment(FaceType type, const FaceCoords &Xf, const Eigen::Vector3d &c);
/// Face area int dA [m^2], with the same quadrature as face_traction_load (so that the nodal loads
/// of a constant traction sum to t * face_area).
double face_area(FaceType type, const FaceCoords &Xf);
/// Inverse isoparametric map: finds xi with x(xi) = p by Newton's method from the reference
/// centroid. Returns true (and xi) if Newton converged and p lies inside the element up to `tol`
/// in reference coordinates (tets: xi_k >= -tol and xi_1 + xi_2 + xi_3 <= 1 + tol; Hex8:
/// |xi_k| <= 1 + tol); false if p is outside or Newton does not converge (xi then holds the last
/// iterate and must not be used).
bool locate_point(ElementType type, const ElementCoords &X, const Eigen::Vector3d &p,
                  Eigen::Vector3d &xi, double tol = 1e-8);

} // namespace flexopt::fem
