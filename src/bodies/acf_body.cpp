#include "flexopt/bodies/acf_body.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <utility>

namespace flexopt::bodies {

AcfBody::AcfBody(std::string name, const mesh::DistributedMesh &mesh,
                 const fem::IsotropicMaterial &material, const std::vector<double> &modulus_factor)
    : name_(std::move(name)), mesh_(mesh) {
  elements_ = fem::corotated_elements(mesh, material, modulus_factor);
  M_ = fem::create_matrix(mesh);
  fem::assemble_mass(mesh, material.density, {}, M_);
  X_ = create_vector();
  PetscScalar *x;
  FX_PETSC(VecGetArray(X_, &x));
  for (PetscInt i = 0; i < 3 * mesh.owned_nodes; ++i)
    x[i] = mesh.coordinates[static_cast<std::size_t>(i)];
  FX_PETSC(VecRestoreArray(X_, &x));
  u_ = fem::create_ghosted_vector(mesh);
  // Total mass: 1_x^T M 1_x.
  Vec one = create_vector(), Mone = create_vector();
  FX_PETSC(VecSet(one, 0.0));
  PetscScalar *o;
  FX_PETSC(VecGetArray(one, &o));
  for (PetscInt i = 0; i < mesh.owned_nodes; ++i) o[3 * i] = 1.0;
  FX_PETSC(VecRestoreArray(one, &o));
  FX_PETSC(MatMult(M_, one, Mone));
  FX_PETSC(VecDot(one, Mone, &mass_));
  FX_PETSC(VecDestroy(&one));
  FX_PETSC(VecDestroy(&Mone));
}

AcfBody::~AcfBody() {
  MatDestroy(&M_);
  VecDestroy(&X_);
  VecDestroy(&u_);
}

Vec AcfBody::create_vector() const {
  Vec v;
  FX_PETSC(VecCreateMPI(mesh_.comm, 3 * mesh_.owned_nodes, 3 * mesh_.global_nodes, &v));
  FX_PETSC(VecSetBlockSize(v, 3));
  return v;
}

Mat AcfBody::create_matrix() const {
  return fem::create_matrix(mesh_);
}

void AcfBody::gravity_load(const Eigen::Vector3d &g, Vec f) const {
  Vec G = create_vector();
  PetscScalar *a;
  FX_PETSC(VecGetArray(G, &a));
  for (PetscInt i = 0; i < mesh_.owned_nodes; ++i)
    for (int k = 0; k < 3; ++k) a[3 * i + k] = g(k);
  FX_PETSC(VecRestoreArray(G, &a));
  FX_PETSC(MatMult(M_, G, f));
  FX_PETSC(VecDestroy(&G));
}

fem::CorotatedSum AcfBody::internal(Vec x, Vec F, Mat T) const {
  // u = x - X into the owned part of the ghosted vector, then its ghosts.
  FX_PETSC(VecWAXPY(u_, -1.0, X_, x));
  FX_PETSC(VecGhostUpdateBegin(u_, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(u_, INSERT_VALUES, SCATTER_FORWARD));
  return fem::assemble_corotated(mesh_, elements_, u_, F, T);
}

void AcfBody::momentum(Vec x, Vec v, Eigen::Vector3d &linear, Eigen::Vector3d &angular) const {
  Vec Mv = create_vector();
  FX_PETSC(MatMult(M_, v, Mv));
  const PetscScalar *p, *xa;
  FX_PETSC(VecGetArrayRead(Mv, &p));
  FX_PETSC(VecGetArrayRead(x, &xa));
  double s[6] = {0, 0, 0, 0, 0, 0}, g[6];
  for (PetscInt i = 0; i < mesh_.owned_nodes; ++i) {
    const Eigen::Vector3d pa(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
    const Eigen::Vector3d xi(xa[3 * i], xa[3 * i + 1], xa[3 * i + 2]);
    const Eigen::Vector3d l = xi.cross(pa);
    for (int k = 0; k < 3; ++k) s[k] += pa(k), s[3 + k] += l(k);
  }
  FX_PETSC(VecRestoreArrayRead(x, &xa));
  FX_PETSC(VecRestoreArrayRead(Mv, &p));
  FX_PETSC(VecDestroy(&Mv));
  MPI_Allreduce(s, g, 6, MPI_DOUBLE, MPI_SUM, mesh_.comm);
  linear = Eigen::Vector3d(g[0], g[1], g[2]);
  angular = Eigen::Vector3d(g[3], g[4], g[5]);
}

} // namespace flexopt::bodies
