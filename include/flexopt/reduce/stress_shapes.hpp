#pragma once
/// \file Stress shapes of an FFRF body (docs/theory.md section 10.3): the centroid stress of each
/// element per unit elastic coordinate, T_e = S_e Psi_e (6 x m), so that an element's stress at
/// elastic coordinates zeta is T_e zeta; and the adjoint, a cotangent of the T_e carried back to
/// the basis vectors.
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <Eigen/Dense>
#include <petscvec.h>
#include <vector>

namespace flexopt::reduce {

/// T_e of the local elements `elements` of `mesh` for the basis vectors `basis` (full size, the
/// mesh's layout), stacked: rows 6 i ... 6 i + 5 hold elements[i]'s block. Unit modulus factor
/// (the solid stress, section 5.1). Collective.
Eigen::MatrixXd stress_shapes(const mesh::DistributedMesh &mesh,
                              const fem::IsotropicMaterial &material, const std::vector<Vec> &basis,
                              const std::vector<PetscInt> &elements);

/// The adjoint of stress_shapes: out[k] += sum_i A_i^T S_i^T Tbar(6 i : 6 i + 5, k) for every
/// basis vector k, A_i the gather of elements[i] (out[k]: full-size vectors of the mesh's layout,
/// summed over the ranks that share a node). Collective.
void add_stress_shape_cotangent(const mesh::DistributedMesh &mesh,
                                const fem::IsotropicMaterial &material,
                                const std::vector<PetscInt> &elements, const Eigen::MatrixXd &Tbar,
                                const std::vector<Vec> &out);

} // namespace flexopt::reduce
