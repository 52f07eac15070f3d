#include "flexopt/fem/assembly.hpp"

#include "flexopt/core/error.hpp"

#include <sstream>

namespace flexopt::fem {

namespace {

void set_local_to_global(const mesh::DistributedMesh &mesh, Mat A) {
  std::vector<PetscInt> l2g(static_cast<std::size_t>(mesh.local_nodes()));
  for (PetscInt i = 0; i < mesh.local_nodes(); ++i) l2g[static_cast<std::size_t>(i)] = mesh.local_to_global(i);
  ISLocalToGlobalMapping map;
  FX_PETSC(ISLocalToGlobalMappingCreate(mesh.comm, 3, mesh.local_nodes(), l2g.data(), PETSC_COPY_VALUES, &map));
  FX_PETSC(MatSetLocalToGlobalMapping(A, map, map));
  FX_PETSC(ISLocalToGlobalMappingDestroy(&map));
}

std::string element_context(const mesh::DistributedMesh &mesh, PetscInt e, const std::exception &err) {
  std::ostringstream s;
  s << mesh.source << ": element " << mesh.element_tags[static_cast<std::size_t>(e)] << " (" << element_name(mesh.type)
    << "): " << err.what();
  return s.str();
}

} // namespace

Mat create_matrix(const mesh::DistributedMesh &mesh) {
  const PetscInt n = 3 * mesh.owned_nodes;
  const int npe = mesh.nodes_per_element();
  Mat pre;
  FX_PETSC(MatCreate(mesh.comm, &pre));
  FX_PETSC(MatSetType(pre, MATPREALLOCATOR));
  FX_PETSC(MatSetSizes(pre, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  FX_PETSC(MatSetBlockSize(pre, 3));
  FX_PETSC(MatSetUp(pre));
  set_local_to_global(mesh, pre);
  std::vector<PetscScalar> zeros(static_cast<std::size_t>(9 * npe * npe), 0.0);
  for (PetscInt e = 0; e < mesh.local_elements(); ++e)
    FX_PETSC(MatSetValuesBlockedLocal(pre, npe, &mesh.connectivity[static_cast<std::size_t>(e * npe)], npe,
                                      &mesh.connectivity[static_cast<std::size_t>(e * npe)], zeros.data(), INSERT_VALUES));
  FX_PETSC(MatAssemblyBegin(pre, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(pre, MAT_FINAL_ASSEMBLY));

  Mat A;
  FX_PETSC(MatCreate(mesh.comm, &A));
  FX_PETSC(MatSetSizes(A, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  FX_PETSC(MatSetBlockSize(A, 3));
  FX_PETSC(MatSetType(A, MATAIJ));
  FX_PETSC(MatPreallocatorPreallocate(pre, PETSC_TRUE, A));
  FX_PETSC(MatDestroy(&pre));
  set_local_to_global(mesh, A);
  FX_PETSC(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  return A;
}

Vec create_ghosted_vector(const mesh::DistributedMesh &mesh) {
  Vec v;
  FX_PETSC(VecCreateGhostBlock(mesh.comm, 3, 3 * mesh.owned_nodes, PETSC_DETERMINE,
                               static_cast<PetscInt>(mesh.ghosts.size()), mesh.ghosts.data(), &v));
  return v;
}

namespace {

template <class Kernel>
void assemble_matrix(const mesh::DistributedMesh &mesh, Mat A, Kernel &&kernel) {
  const int npe = mesh.nodes_per_element();
  FX_PETSC(MatZeroEntries(A));
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    ElementMatrix Ke;
    try {
      Ke = kernel(e, mesh.element_coordinates(e));
    } catch (const std::exception &err) {
      throw Error(element_context(mesh, e, err));
    }
    const PetscInt *idx = &mesh.connectivity[static_cast<std::size_t>(e * npe)];
    FX_PETSC(MatSetValuesBlockedLocal(A, npe, idx, npe, idx, Ke.data(), ADD_VALUES));
  }
  FX_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
}

} // namespace

void assemble_stiffness(const mesh::DistributedMesh &mesh, const IsotropicMaterial &material,
                        const std::vector<double> &modulus_factor, Mat A) {
  assemble_matrix(mesh, A, [&](PetscInt e, const ElementCoords &X) {
    const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
    return element_stiffness(mesh.type, X, material, f);
  });
}

void assemble_mass(const mesh::DistributedMesh &mesh, double density,
                   const std::vector<double> &density_factor, Mat A) {
  assemble_matrix(mesh, A, [&](PetscInt e, const ElementCoords &X) {
    const double f = density_factor.empty() ? 1.0 : density_factor[static_cast<std::size_t>(e)];
    return element_mass(mesh.type, X, density * f);
  });
}

void add_body_force(const mesh::DistributedMesh &mesh, const Eigen::Vector3d &b, Vec f) {
  const int npe = mesh.nodes_per_element();
  std::vector<PetscInt> rows(static_cast<std::size_t>(npe));
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    ElementVector fe = element_body_force(mesh.type, mesh.element_coordinates(e), b);
    for (int a = 0; a < npe; ++a) rows[static_cast<std::size_t>(a)] = mesh.local_to_global(mesh.connectivity[static_cast<std::size_t>(e * npe + a)]);
    FX_PETSC(VecSetValuesBlocked(f, npe, rows.data(), fe.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(f));
  FX_PETSC(VecAssemblyEnd(f));
}

void add_surface_traction(const mesh::DistributedMesh &mesh, const std::string &surface,
                          const Eigen::Vector3d &t, const std::string &where, Vec f) {
  const mesh::LocalSurface &s = mesh.surface(surface, where);
  const int npf = nodes_per_face(s.type);
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor, 9, 3> Xf(npf, 3);
  for (std::size_t k = 0; k < s.size(); ++k) {
    for (int a = 0; a < npf; ++a)
      for (int c = 0; c < 3; ++c) Xf(a, c) = s.coordinates[3 * (k * static_cast<std::size_t>(npf) + static_cast<std::size_t>(a)) + static_cast<std::size_t>(c)];
    ElementVector fe = face_traction_load(s.type, Xf, t);
    FX_PETSC(VecSetValuesBlocked(f, npf, &s.global_nodes[k * static_cast<std::size_t>(npf)], fe.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(f));
  FX_PETSC(VecAssemblyEnd(f));
}

std::vector<PetscInt> surface_dofs(const mesh::DistributedMesh &mesh, const std::string &surface,
                                   const std::array<bool, 3> &components, const std::string &where) {
  mesh.surface(surface, where); // existence check with a clear message
  std::vector<PetscInt> dofs;
  for (PetscInt g : mesh.surface_nodes.at(surface))
    for (int k = 0; k < 3; ++k)
      if (components[static_cast<std::size_t>(k)]) dofs.push_back(3 * g + k);
  return dofs;
}

Vec create_coordinate_vector(const mesh::DistributedMesh &mesh) {
  Vec x;
  FX_PETSC(VecCreateMPI(mesh.comm, 3 * mesh.owned_nodes, PETSC_DETERMINE, &x));
  FX_PETSC(VecSetBlockSize(x, 3));
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  for (PetscInt i = 0; i < 3 * mesh.owned_nodes; ++i) a[i] = mesh.coordinates[static_cast<std::size_t>(i)];
  FX_PETSC(VecRestoreArray(x, &a));
  return x;
}

std::vector<double> element_volumes(const mesh::DistributedMesh &mesh) {
  std::vector<double> v(static_cast<std::size_t>(mesh.local_elements()));
  for (PetscInt e = 0; e < mesh.local_elements(); ++e)
    v[static_cast<std::size_t>(e)] = element_volume(mesh.type, mesh.element_coordinates(e));
  return v;
}

ElementVector gather_element(const mesh::DistributedMesh &mesh, PetscInt e, const PetscScalar *u_local) {
  const int npe = mesh.nodes_per_element();
  ElementVector ue(3 * npe);
  for (int a = 0; a < npe; ++a) {
    const PetscInt n = mesh.connectivity[static_cast<std::size_t>(e * npe + a)];
    for (int k = 0; k < 3; ++k) ue(3 * a + k) = u_local[3 * n + k];
  }
  return ue;
}

std::vector<double> element_von_mises(const mesh::DistributedMesh &mesh,
                                      const IsotropicMaterial &material,
                                      const std::vector<double> &modulus_factor, Vec u_ghosted) {
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(u_ghosted, &local));
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(local, &u));
  std::vector<double> vm(static_cast<std::size_t>(mesh.local_elements()));
  const Eigen::Vector3d xi = reference_centroid(mesh.type);
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
    vm[static_cast<std::size_t>(e)] =
        von_mises(element_stress(mesh.type, mesh.element_coordinates(e), material, f, gather_element(mesh, e, u), xi));
  }
  FX_PETSC(VecRestoreArrayRead(local, &u));
  FX_PETSC(VecGhostRestoreLocalForm(u_ghosted, &local));
  return vm;
}

} // namespace flexopt::fem
