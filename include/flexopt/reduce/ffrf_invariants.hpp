#pragma once
/// \file Inertia invariants of a reduced flexible body in its floating frame (docs/theory.md
/// section 7.2): the sums over the consistent mass matrix that the FFRF equations of motion
/// need, computed once per reduction basis in parallel and held on every rank.
#include "flexopt/mesh/distributed_mesh.hpp"

#include <Eigen/Dense>
#include <petscmat.h>
#include <vector>

namespace flexopt::reduce {

/// With the scalar consistent mass m_ij (M = m_ij (x) I3), node positions X_i in the frame
/// (mesh coordinates minus the frame origin) and mode shapes Psi_ik (3-vectors, mode k at
/// node i):
///   mass = sum_ij m_ij,  d0 = sum_ij m_ij X_j,  D(:, k) = sum_ij m_ij Psi_jk,
///   S0 = sum_ij m_ij X_i X_j^T,  S1[k] = sum_ij m_ij X_i Psi_jk^T,  S2[k][l] = sum_ij m_ij Psi_ik
///   Psi_jl^T,
/// so that the first moment and the second-moment tensor of the deformed body are
///   d(zeta) = d0 + D zeta,  S(zeta) = S0 + sum_k zeta_k (S1[k] + S1[k]^T) + sum_kl zeta_k zeta_l
///   S2[k][l].
struct FfrfInvariants {
  double mass = 0;
  Eigen::Vector3d d0 = Eigen::Vector3d::Zero();
  Eigen::Matrix3Xd D;
  Eigen::Matrix3d S0 = Eigen::Matrix3d::Zero();
  std::vector<Eigen::Matrix3d> S1;
  std::vector<std::vector<Eigen::Matrix3d>> S2;

  int modes() const { return static_cast<int>(S1.size()); }
  Eigen::Vector3d first_moment(const Eigen::Ref<const Eigen::VectorXd> &zeta) const;
  Eigen::Matrix3d second_moment(const Eigen::VectorXd &zeta) const;
  /// Inertia tensor about the frame origin: tr(S) I - S.
  Eigen::Matrix3d inertia(const Eigen::VectorXd &zeta) const;
};

/// Invariants for the mode shapes `modes` (full-size vectors, block size 3, the layout of M)
/// with the frame origin `origin` (mesh coordinates). Collective; every rank receives the same
/// numbers (one MPI_Allreduce of all the sums).
FfrfInvariants ffrf_invariants(const mesh::DistributedMesh &mesh, Mat M,
                               const std::vector<Vec> &modes, const Eigen::Vector3d &origin);

} // namespace flexopt::reduce
