#pragma once
/// \file Centrifugal stress stiffening of a floating-frame (FFRF) flexible body: reduced geometric
/// stiffness matrices of the stress that unit centrifugal loads produce in the body clamped at its
/// frame (docs/theory.md section 7.5).
///
/// A body turning with the body-frame angular velocity omega [rad/s] carries the centrifugal body
/// force density rho (|omega|^2 I - omega omega^T)(x - o) = sum_c s_c(omega) rho B_c (x - o)
/// [N/m^3] (o: frame origin), with the six load cases c = xx, yy, zz, yz, xz, xy:
///   s = (wx^2, wy^2, wz^2, wy wz, wx wz, wx wy),
///   B_aa = I - e_a e_a^T,  B_ab = -(e_a e_b^T + e_b e_a^T) (a < b).
/// The stress of that load stiffens the body (Southwell); linear FFRF misses it. With the reduced
/// matrices G_c of this file, the elastic force on the modal coordinates zeta becomes
///   (K_r + sum_c s_c(omega) G_c) zeta.
/// The stress is the quasi-static response to the steady centrifugal load only: the loads of the
/// frame's angular and linear acceleration and of the elastic motion itself are left out (the
/// usual first-order stiffening model).
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/modal.hpp"

#include <Eigen/Dense>
#include <array>
#include <memory>
#include <petscmat.h>
#include <string>
#include <vector>

namespace flexopt::reduce {

/// Names of the six load cases, in the order of the arrays below: "xx", "yy", "zz", "yz", "xz",
/// "xy".
extern const std::array<const char *, 6> kCentrifugalCases;

/// Coefficients s(omega) = (wx^2, wy^2, wz^2, wy wz, wx wz, wx wy) [rad^2/s^2] of the six load
/// cases for the body-frame angular velocity omega [rad/s] and, if `derivative` is given, ds/domega
/// (6 x 3). Not collective.
Eigen::Matrix<double, 6, 1>
centrifugal_coefficients(const Eigen::Vector3d &omega,
                         Eigen::Matrix<double, 6, 3> *derivative = nullptr);

/// The 3x3 matrix B_c of load case c (0..5) above, so that
/// sum_c s_c(omega) B_c = |omega|^2 I - omega omega^T. Throws flexopt::Error for c outside 0..5.
Eigen::Matrix3d centrifugal_load_matrix(int c);

/// G_k = V^T K_sigma(u_k) V for each full-size displacement u_k (ghosts need not be up to date)
/// and the basis V (full-size vectors in the layout of K), summed element by element, replicated
/// on every rank and symmetrized; K_sigma from element_geometric_stiffness with `material`, each
/// element's stress scaled by modulus_factor[e] (empty: 1). Collective; an element whose
/// geometric stiffness fails aborts with `what` and its Gmsh tag.
std::vector<Eigen::MatrixXd> reduced_geometric_stiffness(const mesh::DistributedMesh &mesh,
                                                         const fem::IsotropicMaterial &material,
                                                         const std::vector<Vec> &basis,
                                                         const std::vector<Vec> &u,
                                                         const std::vector<double> &modulus_factor,
                                                         const std::string &what);

/// The 6 reduced geometric stiffness matrices G_c = V^T K_sigma(u_c) V [N/m per rad^2/s^2]
/// (replicated on every rank, symmetrized), c = xx, yy, zz, yz, xz, xy, for the basis V =
/// `basis` (full-size vectors in the layout of K, e.g. CraigBamptonBasis::vectors).
///
/// u_c solves K u_c = M w_c with every DOF of the surface `frame_interface` clamped, where w_c is
/// the nodal vector B_c (X_j - origin): since M (the consistent mass, density included) is exact
/// for the linear field B_c (x - origin), M w_c is exactly the consistent load of the body force
/// rho B_c (x - origin). One MUMPS Cholesky factorization of the clamped K (options prefix
/// `gs_`) serves all six solves, done as one block solve; `frame_clamped`, if given, must be K
/// with exactly the frame's DOFs clamped (e.g. the Craig-Bampton factorization of a body whose
/// only interface is its frame, CraigBamptonBasis::interior) and is used instead of a new
/// factorization. K_sigma(u_c) is assembled from element_geometric_stiffness with `material`
/// (its density is not used: the mass comes from M). `origin` is the frame origin in mesh
/// coordinates [m]. An empty basis gives six 0 x 0 matrices (and no solve).
///
/// Collective. Throws a collective flexopt::Error for a missing frame surface, an invalid
/// material or a failed solve (e.g. a frame surface that does not hold the body).
///
/// `modulus_factor` (one per local element, empty: 1) scales the elements' stress as it scales
/// their stiffness in K (a design body). If `keep` is given it receives what the adjoint of G_c
/// needs (docs/theory.md section 10, step 1): the six displacements u_c and, unless
/// `frame_clamped` was given, the factorization of the frame-clamped K.
struct CentrifugalLoadStates {
  std::vector<Vec> u;                    ///< u_c, c = xx ... xy (full size, zero on the frame)
  std::shared_ptr<ClampedProblem> frame; ///< null if the caller's factorization was used
  std::vector<PetscInt> frame_dofs;      ///< the frame surface's owned DOFs
  CentrifugalLoadStates() = default;
  CentrifugalLoadStates(const CentrifugalLoadStates &) = delete;
  CentrifugalLoadStates &operator=(const CentrifugalLoadStates &) = delete;
  ~CentrifugalLoadStates();
};
std::array<Eigen::MatrixXd, 6> centrifugal_geometric_stiffness(
    const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &material, Mat K, Mat M,
    const std::string &frame_interface, const Eigen::Vector3d &origin,
    const std::vector<Vec> &basis, ClampedProblem *frame_clamped = nullptr,
    const std::vector<double> &modulus_factor = {}, CentrifugalLoadStates *keep = nullptr);

/// sum_c s_c(omega) G_c: the stiffening of the reduced stiffness at the body-frame angular
/// velocity omega [rad/s]. Not collective.
Eigen::MatrixXd centrifugal_stiffening(const std::array<Eigen::MatrixXd, 6> &G,
                                       const Eigen::Vector3d &omega);

} // namespace flexopt::reduce
