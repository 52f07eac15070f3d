#pragma once
/// \file The adjoint of the FFRF reduction (docs/theory.md section 10): from the cotangents of
/// what reduce_flexible_body hands to the mechanism (reduced matrices, inertia invariants,
/// interface maps, geometric stiffness, basis vectors) to the derivatives with respect to the
/// design body's element stiffness and mass factors. The sparse solves use the factorizations
/// of the reduction itself; their number does not depend on the number of elements.
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/ffrf_invariants.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"
#include "flexopt/reduce/modal.hpp"

#include <Eigen/Dense>
#include <memory>
#include <petscmat.h>
#include <vector>

namespace flexopt::reduce {

/// Kept by a design body's reduction (FlexibleReduction::adjoint).
struct ReductionAdjointData {
  fem::IsotropicMaterial material;
  ElementFactors factors;
  Mat K = nullptr, M = nullptr; ///< with the factors
  /// The Cholesky of K with every interface clamped (static modes, eigenmodes).
  std::shared_ptr<ClampedProblem> interior;
  std::vector<Vec> vectors; ///< the Craig-Bampton vectors V (before a chord frame's rotations)
  int static_modes = 0;
  std::vector<double> fixed_eigenvalues;
  double next_eigenvalue = 0;
  std::vector<PetscInt> interface_dofs; ///< owned DOFs of every interface surface
  Eigen::MatrixXd Y;                    ///< Psi = V' Y
  /// Interface maps in Craig-Bampton coordinates (the chord frame's rotations included): the
  /// reduction's maps are T[k] Y and R[k] Y.
  std::vector<Eigen::Matrix3Xd> T, R;
  /// The centrifugal load cases (geometric stiffening only); loads.frame is the frame-clamped
  /// factorization (interior itself for a body with one interface).
  CentrifugalLoadStates loads;
  ReductionAdjointData() = default;
  ReductionAdjointData(const ReductionAdjointData &) = delete;
  ReductionAdjointData &operator=(const ReductionAdjointData &) = delete;
  ~ReductionAdjointData();
};

/// The cotangents of one response with respect to a FlexibleReduction's outputs (same shapes;
/// an empty member stands for zero).
struct ReductionCotangent {
  Eigen::MatrixXd K, M;                                ///< of FlexibleReduction::K, M
  FfrfInvariants invariants;                           ///< D, S1, S2 empty: zero
  std::vector<Eigen::Matrix3Xd> translation, rotation; ///< per interface
  std::vector<Eigen::MatrixXd> geometric;              ///< the 6 G_c
  std::vector<Vec> basis; ///< full-size vectors, one per basis vector (not owned)
};

/// How the basis is differentiated: exactly (the default), or held fixed (`adjoint: {basis:
/// fixed}`: only K(s) and M(w) projected on the basis, docs/theory.md section 10).
enum class BasisDerivative { Exact, Fixed };

/// Collective statistics of the last reduction_adjoint call.
struct ReductionAdjointStats {
  int cg_iterations = 0; ///< of the fixed-interface modes' conjugate gradients
  double seconds = 0;
};

/// The coordinates in which the basis is differentiated (docs/theory.md section 10): the
/// M-Procrustes gauge (Psi^T M dPsi symmetric: the basis stays M-orthonormal, the interface
/// maps T Y change), or frozen Craig-Bampton coordinates (Y held: Psi = V' Y_0, the maps stay
/// constant and M_r moves). Both give the same gradient of responses that are covariant under
/// the change of coordinates (orthogonal for the first, any linear one for the second); the
/// frozen gauge needs no cotangent of the maps (they are ignored).
enum class BasisGauge { Orthonormal, FrozenCoordinates };

/// s_hat[i][e] = dPsi_i/ds_e, w_hat[i][e] = dPsi_i/dw_e for every response i (cotangent
/// bars[i]) and every local element e of the design body reduced into `r` (which must hold
/// adjoint data). Collective; throws a collective flexopt::Error if a solve fails or the
/// conjugate gradients of the fixed-interface modes do not converge.
ReductionAdjointStats
reduction_adjoint(const mesh::DistributedMesh &mesh, const FlexibleReduction &r,
                  const std::vector<ReductionCotangent> &bars, BasisDerivative mode,
                  std::vector<std::vector<double>> &s_hat, std::vector<std::vector<double>> &w_hat,
                  BasisGauge gauge = BasisGauge::Orthonormal);

} // namespace flexopt::reduce
