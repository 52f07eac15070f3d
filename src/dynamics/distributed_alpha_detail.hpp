#pragma once
/// \file The internals shared by the files of dynamics::DistributedAlpha
/// (distributed_alpha.cpp: layout, vectors and diagnostics; distributed_alpha_start.cpp: the
/// consistent start; distributed_alpha_step.cpp: the Newton step and its transposes): the layout
/// of the unknowns, the kept matrix's frame and small PETSc helpers.
#include "flexopt/dynamics/distributed_alpha.hpp"

#include <algorithm>
#include <petscksp.h>
#include <vector>

namespace flexopt::dynamics {

namespace detail {

/// The layout of the unknowns (see the header). Rank r's local block: [ACF coordinates
/// (acf_local) | small coordinates (rank 0: small_n) | tie multipliers | small multipliers (rank
/// 0: small_m)]; the coordinates are the first `coords_local` entries. Body b's owned node i has
/// the DOFs offset[b] + 3 i + (0, 1, 2); node_dof[b][l] is that first DOF for every local node l
/// (owned, then ghosts: from the owner's offset), and `gather[b]` scatters the positions of all
/// local nodes into `local_x[b]` (3 per local node). ties[i]: interface i's ties of the owned
/// nodes of its surface.
struct AcfLayout {
  PetscInt local = 0, start = 0, global = 0;
  PetscInt acf_local = 0, coords_local = 0;
  int small_n = 0, small_m = 0;              ///< the small part's coordinates and enforced rows
  PetscInt small_coord0 = 0, small_row0 = 0; ///< their first global numbers (every rank)
  std::vector<PetscInt> offset;
  std::vector<std::vector<PetscInt>> node_dof;
  std::vector<Vec> local_x, local_v; ///< positions, velocities of the local nodes
  std::vector<VecScatter> gather;
  std::vector<TieSet> ties;
  ~AcfLayout() {
    for (Vec &v : local_x) VecDestroy(&v);
    for (Vec &v : local_v) VecDestroy(&v);
    for (VecScatter &g : gather) VecScatterDestroy(&g);
  }
};

/// A copy of v (null for null); the caller destroys it.
Vec copy_of(Vec v);
/// max_i |v_i|. Collective.
double max_abs(Vec v);

/// Factorizes the KSP's operator (if it changed); false if the factorization failed (a zero
/// pivot, MUMPS out of workspace, a singular matrix for KLU). PCSetUp is called here, not left to
/// the next KSPSolve (KSPSetUp does not set the PC up again for a refilled operator), so that a
/// failure is seen here and -log_view shows the factorizations apart from the solves. KLU (one
/// rank only) reports a singular matrix as a PETSc error: on one rank that is returned as a
/// failure, not thrown; on more ranks an error still throws (and aborts every rank) rather than
/// leave the others waiting in a collective.
bool factorized(KSP ksp);
/// The PETSc indices first .. first + n - 1.
std::vector<PetscInt> range(PetscInt first, int n);

} // namespace detail

struct DistributedAlpha::KeptFrame {
  Vec q = nullptr;                    ///< the positions at which the kept matrix was assembled
  bool rotated = false;               ///< rotation[b] is not the identity
  std::vector<bodies::Mat3> rotation; ///< of each ACF body since then (docs/theory.md 8.2)
  /// The same rotation acting on Euler parameters, p -> q p: L(q) = [q0, -qv^T; qv, q0 I + [qv]x]
  std::vector<Eigen::Matrix4d> quaternion;
  KeptFrame(Vec like, std::size_t bodies)
      : rotation(bodies, bodies::Mat3::Identity()),
        quaternion(bodies, Eigen::Matrix4d::Identity()) {
    FX_PETSC(VecDuplicate(like, &q));
    FX_PETSC(VecCopy(like, q));
  }
  KeptFrame(const KeptFrame &) = delete;
  KeptFrame &operator=(const KeptFrame &) = delete;
  ~KeptFrame() { VecDestroy(&q); }
  void reset(Vec at) {
    FX_PETSC(VecCopy(at, q));
    std::fill(rotation.begin(), rotation.end(), bodies::Mat3::Identity());
    std::fill(quaternion.begin(), quaternion.end(), Eigen::Matrix4d::Identity());
    rotated = false;
  }
};

} // namespace flexopt::dynamics
