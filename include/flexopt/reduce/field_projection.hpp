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

using Field = std::function<Eigen::Vector3d(const Eigen::Vector3d &)>;

/// Projects the field u(X) (X: mesh coordinates of the nodes, u in the mesh axes) onto the
/// basis of `reduction`, with the consistent mass matrix the reduction was made with (a design
/// reduction's M = sum_e w_e M_e, kept with its adjoint data; otherwise assembled with
/// `density`). Collective; every rank gets the same result.
FieldProjection project_field(const mesh::DistributedMesh &mesh, double density,
                              const FlexibleReduction &reduction, const Field &u);

/// The adjoint of project_field on a design body (docs/theory.md section 10.2): for the
/// cotangent zbar of the coordinates zeta it returned, differentiated in the covariant form
/// zeta = (Psi^T M Psi)^-1 Psi^T M u at Psi^T M Psi = I, adds
///   basis_bar[k] += zbar_k M (u - Psi zeta) - zeta_k M Psi zbar       (full-size vectors),
///   w_hat[e] += (Psi zbar)_e^T M0_e (u - Psi zeta)_e                  (local elements).
/// Collective.
void project_field_adjoint(const mesh::DistributedMesh &mesh, double density,
                           const FlexibleReduction &reduction, const Field &u,
                           const Eigen::VectorXd &zeta, const Eigen::VectorXd &zbar,
                           const std::vector<Vec> &basis_bar, std::vector<double> &w_hat);

} // namespace flexopt::reduce
