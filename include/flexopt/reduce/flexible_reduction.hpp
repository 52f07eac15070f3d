#pragma once
/// \file Everything an FFRF body takes from its FE model (docs/theory.md sections 7.1-7.5): the
/// Craig-Bampton basis turned M-orthonormal, the reduced stiffness, the inertia invariants about
/// the frame origin, the rigid motion of every interface node per basis vector, and optionally
/// the centrifugal geometric stiffness. Built once per body (per design, later), in parallel;
/// the small matrices are held on every rank, the basis vectors stay distributed for output.
#include "flexopt/fem/element.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/ffrf_invariants.hpp"

#include <Eigen/Dense>
#include <memory>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::reduce {

class ClampedProblem;

/// Where the floating frame sits on the body (docs/theory.md section 7.1). Clamped: the frame is
/// interface 0, clamped (its rigid node neither moves nor turns in the frame). Chord: the
/// frame's origin is the centroid of interface 0 and its axis through the centroid of
/// interface 1 (which moves only along it), with no twist about that axis; interface 0 turns
/// elastically. The chord frame is the classical pinned-pinned choice for a link between two
/// joints.
enum class FrameCondition { Clamped, Chord };

/// The element factors of a design body (one per local element): its stiffness is
/// sum_e stiffness_e K_e and its mass sum_e mass_e M_e (docs/theory.md section 10).
struct ElementFactors {
  std::vector<double> stiffness, mass;
};

struct ReductionAdjointData; // reduce/reduction_adjoint.hpp

struct FlexibleReduction {
  int static_modes = 0; ///< 6 per interface after the first
  int fixed_modes = 0;
  /// The basis Psi = V Y: V the Craig-Bampton vectors, Y the eigenvectors of the reduced
  /// problem K_cb y = w^2 M_cb y, so Psi^T M Psi = I and Psi^T K Psi = diag(w^2) (full size).
  std::vector<Vec> basis;
  Eigen::VectorXd eigenvalues; ///< w^2 of the reduced model (frame held), ascending
  Eigen::MatrixXd K, M;        ///< Psi^T K Psi, Psi^T M Psi (replicated)
  /// The Craig-Bampton vectors in the basis: V = Psi C, C = Y^-1 = Y^T M_cb (n x n; columns:
  /// the static modes, then the fixed-interface modes by frequency). The model with the
  /// static modes and the first j fixed-interface modes spans Psi C(:, 0 : static + j).
  Eigen::MatrixXd craig_bampton;
  FfrfInvariants invariants;                        ///< about `origin`
  Eigen::Vector3d origin = Eigen::Vector3d::Zero(); ///< frame origin: centroid of interface 0
  std::vector<Eigen::Vector3d> centroids;           ///< per interface (mesh coordinates)
  /// Per interface: the translation and (small) rotation of its rigid interface node per unit
  /// basis coordinate (3 x n each; zero for interface 0 with a clamped frame).
  std::vector<Eigen::Matrix3Xd> translation, rotation;
  /// Centrifugal geometric stiffness per unit s_c(omega) (6 matrices) or empty.
  std::vector<Eigen::MatrixXd> geometric;
  /// What the adjoint of the reduction needs (the matrices, the factorizations, the
  /// Craig-Bampton vectors): kept by a design body's reduction only, else null.
  std::shared_ptr<ReductionAdjointData> adjoint;
  int size() const { return static_cast<int>(basis.size()); }

  FlexibleReduction() = default;
  FlexibleReduction(const FlexibleReduction &) = delete;
  FlexibleReduction &operator=(const FlexibleReduction &) = delete;
  ~FlexibleReduction();
};

/// A new vector sum_k c(k) basis[k] (the layout of basis[0]; the caller destroys it): a field of
/// the reduced model's coordinates c (c.size() == basis.size()). Collective.
Vec basis_combination(const std::vector<Vec> &basis, const Eigen::VectorXd &c);

/// Reduces the body meshed as `mesh` with material `material` (interfaces: physical surfaces;
/// the frame sits on the first, `frame`; the chord frame needs two interfaces and no geometric
/// stiffening). With `design` (a design body), K and M carry its element factors, the
/// fixed-interface modes are solved to 1e-13 with the next eigenvalue (the cut of
/// check_modal_cut), and `out.adjoint` keeps what reduction_adjoint needs. Collective; throws
/// collective flexopt::Errors (missing surface, failed solve).
void reduce_flexible_body(const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &material,
                          const std::vector<std::string> &interfaces, int fixed_modes,
                          bool geometric_stiffening, FlexibleReduction &out,
                          FrameCondition frame = FrameCondition::Clamped,
                          const ElementFactors *design = nullptr,
                          std::shared_ptr<ClampedProblem> reuse = nullptr);

/// For a design body's reduction: throws a collective flexopt::Error naming `body` and both
/// frequencies if the last kept fixed-interface eigenvalue and the next are equal (relative gap
/// <= 1e-8: the reduced model is not differentiable there), prints a warning on rank 0 below
/// 1 % (docs/theory.md section 10, "The cut"). Does nothing without adjoint data or modes.
void check_modal_cut(const FlexibleReduction &r, const std::string &body, MPI_Comm comm);

/// The basis vectors' values at the owned nodes: a (3 owned_nodes) x n matrix, node-major.
Eigen::MatrixXd owned_basis_values(const FlexibleReduction &r, PetscInt owned_nodes);

/// The basis interpolated at a located point of the undeformed body (fem::locate; 3 x n, the
/// same on every rank). Collective.
Eigen::Matrix3Xd basis_at_point(const mesh::DistributedMesh &mesh, const FlexibleReduction &r,
                                const fem::PointLocation &where);

} // namespace flexopt::reduce
