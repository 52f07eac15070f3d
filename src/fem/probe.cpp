#include "flexopt/fem/probe.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"

#include <sstream>

namespace flexopt::fem {

std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const std::array<double, 3> &point, const std::string &what) {
  const Eigen::Vector3d p(point[0], point[1], point[2]);
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(field_ghosted, &local));
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(local, &u));
  const int npe = mesh.nodes_per_element();
  double value[3] = {0, 0, 0};
  int found = 0;
  for (PetscInt e = 0; e < mesh.local_elements() && !found; ++e) {
    const ElementCoords X = mesh.element_coordinates(e);
    const Eigen::Vector3d lo = X.colwise().minCoeff().transpose(),
                          hi = X.colwise().maxCoeff().transpose();
    const double pad = 1e-9 * (hi - lo).norm();
    if ((p.array() < lo.array() - pad).any() || (p.array() > hi.array() + pad).any()) continue;
    Eigen::Vector3d xi;
    if (!locate_point(mesh.type, X, p, xi)) continue;
    double N[kMaxNodes], dN[3 * kMaxNodes];
    shape_functions(mesh.type, xi, N, dN);
    const ElementVector ue = gather_element(mesh, e, u);
    for (int a = 0; a < npe; ++a)
      for (int k = 0; k < 3; ++k) value[k] += N[a] * ue(3 * a + k);
    found = 1;
  }
  FX_PETSC(VecRestoreArrayRead(local, &u));
  FX_PETSC(VecGhostRestoreLocalForm(field_ghosted, &local));

  const int rank = comm_rank(mesh.comm);
  int candidate = found ? rank : comm_size(mesh.comm), owner = 0;
  MPI_Allreduce(&candidate, &owner, 1, MPI_INT, MPI_MIN, mesh.comm);
  if (owner == comm_size(mesh.comm)) {
    std::ostringstream s;
    s << what << ": the point (" << point[0] << ", " << point[1] << ", " << point[2]
      << ") lies outside the mesh of " << mesh.source;
    throw Error(s.str(), true);
  }
  MPI_Bcast(value, 3, MPI_DOUBLE, owner, mesh.comm);
  return {value[0], value[1], value[2]};
}

} // namespace flexopt::fem
