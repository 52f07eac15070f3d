#pragma once
// Shared by the MPI tests: a mesh from meshes/ read on rank 0 and distributed over
// PETSC_COMM_WORLD.
#include "flexopt/core/context.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <Eigen/Dense>
#include <petscvec.h>
#include <string>

namespace flexopt::test_support {

/// meshes/<geometry> meshed with `size` and `order` (0, 1: the .geo's own sizes, linear) on
/// rank 0, a copy of the whole mesh into *root_copy if given (significant on rank 0), then
/// distributed. Collective.
inline mesh::DistributedMesh load_test_mesh(const std::string &geometry, double size = 0,
                                            int order = 1, mesh::MeshData *root_copy = nullptr) {
  mesh::MeshData data;
  const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/" + geometry;
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    data = mesh::read_gmsh(geo, mesh::MeshOptions{size, order});
  });
  if (root_copy) *root_copy = data;
  return mesh::distribute_mesh(PETSC_COMM_WORLD,
                               comm_rank(PETSC_COMM_WORLD) == 0 ? &data : nullptr);
}

/// All entries of a distributed vector, on every rank. Collective.
inline Eigen::VectorXd gather_all(Vec v) {
  Vec all;
  VecScatter sc;
  VecScatterCreateToAll(v, &sc, &all);
  VecScatterBegin(sc, v, all, INSERT_VALUES, SCATTER_FORWARD);
  VecScatterEnd(sc, v, all, INSERT_VALUES, SCATTER_FORWARD);
  PetscInt size;
  VecGetSize(all, &size);
  const PetscScalar *a;
  VecGetArrayRead(all, &a);
  Eigen::VectorXd out = Eigen::Map<const Eigen::VectorXd>(a, size);
  VecRestoreArrayRead(all, &a);
  VecScatterDestroy(&sc);
  VecDestroy(&all);
  return out;
}

} // namespace flexopt::test_support
