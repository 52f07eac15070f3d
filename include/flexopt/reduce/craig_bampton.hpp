#pragma once
/// \file Craig–Bampton reduction of a body's FE model with rigid interface surfaces
/// (docs/theory.md section 7.1). The first step of the FFRF body: the body is clamped at its
/// first interface (the reference frame); every other interface surface is made rigid (RBE2)
/// and carries 6 static constraint modes (unit translation or rotation of the surface about
/// its centroid, the others clamped); the lowest fixed-interface eigenmodes (all interface
/// surfaces clamped) complete the basis.
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/modal.hpp"

#include <Eigen/Dense>
#include <limits>
#include <memory>
#include <petscmat.h>
#include <string>
#include <vector>

namespace flexopt::reduce {

struct CraigBamptonBasis {
  int static_modes = 0; ///< 6 per interface after the first
  int fixed_modes = 0;
  /// Full-size basis vectors: the static modes first (interface k = 1.., components tx, ty,
  /// tz, rx, ry, rz), then the fixed-interface modes (M-orthonormal among themselves).
  std::vector<Vec> vectors;
  std::vector<double> fixed_eigenvalues; ///< omega^2 of the fixed-interface modes [rad^2/s^2]
  /// omega^2 of the first fixed-interface mode left out (CraigBamptonOptions::next_eigenvalue),
  /// else NaN.
  double next_eigenvalue = std::numeric_limits<double>::quiet_NaN();
  /// The owned DOFs of every interface surface (repeats possible): the clamped set.
  std::vector<PetscInt> interface_dofs;
  Eigen::MatrixXd K, M; ///< reduced stiffness and mass V^T K V, V^T M V (replicated)
  std::vector<Eigen::Vector3d> centroids; ///< area-weighted centroid of each interface surface
  /// The factorization of K with every interface clamped that built the basis, kept for further
  /// solves of that problem (e.g. the geometric stiffness of a body whose only interface is its
  /// frame); release it to free its memory. Null if the basis is empty.
  std::shared_ptr<ClampedProblem> interior;
  CraigBamptonBasis() = default;
  CraigBamptonBasis(const CraigBamptonBasis &) = delete;
  CraigBamptonBasis &operator=(const CraigBamptonBasis &) = delete;
  ~CraigBamptonBasis();
};

/// Builds the basis for the mesh's interfaces `interfaces` (physical surfaces; the first is the
/// clamped reference frame) with `fixed_modes` fixed-interface modes, from the assembled full
/// stiffness K and mass M (block size 3). One MUMPS Cholesky factorization of the interior
/// stiffness K_ii (all interface DOFs constrained) serves both the static modes (one block solve
/// with all their right-hand sides) and the SLEPc shift-and-invert about 0 of the
/// fixed-interface modes (reduce::ClampedProblem; -eps_* / -st_* options; the static solves fall
/// back to their own factorization, options prefix `cb_`, if options move the shift off 0).
/// Collective; throws a collective flexopt::Error for a missing surface or a failed solve.
/// `tolerance` is SLEPc's relative tolerance of the fixed-interface modes; `next_eigenvalue`
/// also converges the first mode left out (for the gap at the cut, docs/theory.md section 10).
struct CraigBamptonOptions {
  double tolerance = 1e-10;
  bool next_eigenvalue = false;
  /// A previous design's interior problem of the same body: updated with this K and M
  /// (ClampedProblem::update: the symbolic factorization made once) instead of a new one.
  std::shared_ptr<ClampedProblem> reuse;
};
void craig_bampton(const mesh::DistributedMesh &mesh, Mat K, Mat M,
                   const std::vector<std::string> &interfaces, int fixed_modes,
                   CraigBamptonBasis &out, const CraigBamptonOptions &options = {});

} // namespace flexopt::reduce
