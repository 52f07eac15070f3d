#pragma once
/// \file A vector field over a flexible body projected onto its reduction basis (the initial
/// elastic state of an FFRF body, docs/theory.md section 7.6).
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"

#include <Eigen/Dense>
#include <functional>

namespace flexopt::reduce {

/// The basis coordinates of the field closest to u in the mass norm, and how much of u the
/// basis leaves out.
struct FieldProjection {
  Eigen::VectorXd coordinates; ///< zeta = Psi^T M u (Psi is M-orthonormal)
  double norm = 0;             ///< ||u||_M = sqrt(u^T M u)
  /// ||u - Psi zeta||_M / ||u||_M = sqrt(1 - |zeta|^2 / u^T M u) (0 if u = 0).
  double residual = 0;
};

/// Projects the field u(X) (X: mesh coordinates of the nodes, u in the mesh axes) onto the
/// basis of `reduction`, with the consistent mass matrix of density `density`. Collective;
/// every rank gets the same result.
FieldProjection project_field(const mesh::DistributedMesh &mesh, double density,
                              const FlexibleReduction &reduction,
                              const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &u);

} // namespace flexopt::reduce
