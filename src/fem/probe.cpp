#include "flexopt/fem/probe.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"

#include <sstream>

namespace flexopt::fem {

PointLocation locate(const mesh::DistributedMesh &mesh, const std::array<double, 3> &point,
                     const std::string &what) {
  const Eigen::Vector3d p(point[0], point[1], point[2]);
  PointLocation loc;
  PetscInt found = -1;
  Eigen::Vector3d xi_found = Eigen::Vector3d::Zero();
  for (PetscInt e = 0; e < mesh.local_elements() && found < 0; ++e) {
    const ElementCoords X = mesh.element_coordinates(e);
    const Eigen::Vector3d lo = X.colwise().minCoeff().transpose(),
                          hi = X.colwise().maxCoeff().transpose();
    const double pad = 1e-9 * (hi - lo).norm();
    if ((p.array() < lo.array() - pad).any() || (p.array() > hi.array() + pad).any()) continue;
    Eigen::Vector3d xi;
    if (!locate_point(mesh.type, X, p, xi)) continue;
    found = e;
    xi_found = xi;
  }
  const int rank = comm_rank(mesh.comm);
  int candidate = found >= 0 ? rank : comm_size(mesh.comm);
  MPI_Allreduce(&candidate, &loc.owner, 1, MPI_INT, MPI_MIN, mesh.comm);
  if (loc.owner == comm_size(mesh.comm)) {
    std::ostringstream s;
    s << what << ": the point (" << point[0] << ", " << point[1] << ", " << point[2]
      << ") lies outside the mesh of " << mesh.source;
    throw Error(s.str(), true);
  }
  if (rank == loc.owner) {
    loc.element = found;
    double dN[3 * kMaxNodes];
    loc.shape.resize(static_cast<std::size_t>(mesh.nodes_per_element()));
    shape_functions(mesh.type, xi_found, loc.shape.data(), dN);
  }
  return loc;
}

std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const PointLocation &loc) {
  double value[3] = {0, 0, 0};
  if (loc.element >= 0) {
    Vec local;
    FX_PETSC(VecGhostGetLocalForm(field_ghosted, &local));
    const PetscScalar *u;
    FX_PETSC(VecGetArrayRead(local, &u));
    const ElementVector ue = gather_element(mesh, loc.element, u);
    for (int a = 0; a < mesh.nodes_per_element(); ++a)
      for (int k = 0; k < 3; ++k)
        value[k] += loc.shape[static_cast<std::size_t>(a)] * ue(3 * a + k);
    FX_PETSC(VecRestoreArrayRead(local, &u));
    FX_PETSC(VecGhostRestoreLocalForm(field_ghosted, &local));
  }
  MPI_Bcast(value, 3, MPI_DOUBLE, loc.owner, mesh.comm);
  return {value[0], value[1], value[2]};
}

std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const std::array<double, 3> &point, const std::string &what) {
  return probe_vector(mesh, field_ghosted, locate(mesh, point, what));
}

void add_point_functional(const mesh::DistributedMesh &mesh, const PointLocation &loc,
                          const std::array<double, 3> &direction, Vec c) {
  if (loc.element >= 0) {
    const int npe = mesh.nodes_per_element();
    std::vector<PetscInt> rows(static_cast<std::size_t>(npe));
    std::vector<PetscScalar> values(static_cast<std::size_t>(3 * npe));
    for (int a = 0; a < npe; ++a) {
      rows[static_cast<std::size_t>(a)] =
          mesh.local_to_global(mesh.connectivity[static_cast<std::size_t>(loc.element * npe + a)]);
      for (int k = 0; k < 3; ++k)
        values[static_cast<std::size_t>(3 * a + k)] =
            loc.shape[static_cast<std::size_t>(a)] * direction[static_cast<std::size_t>(k)];
    }
    FX_PETSC(VecSetValuesBlocked(c, npe, rows.data(), values.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(c));
  FX_PETSC(VecAssemblyEnd(c));
}

} // namespace flexopt::fem
