#include "flexopt/reduce/stress_shapes.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"

namespace flexopt::reduce {

namespace {
/// The element's stress matrix S = D B at its centroid (unit modulus).
fem::StressMatrix centroid_stress_matrix(const mesh::DistributedMesh &mesh,
                                         const fem::IsotropicMaterial &material, PetscInt e) {
  return fem::element_stress_matrix(mesh.type, mesh.element_coordinates(e), material,
                                    fem::reference_centroid(mesh.type));
}
} // namespace

Eigen::MatrixXd stress_shapes(const mesh::DistributedMesh &mesh,
                              const fem::IsotropicMaterial &material, const std::vector<Vec> &basis,
                              const std::vector<PetscInt> &elements) {
  const auto m = static_cast<Eigen::Index>(basis.size());
  const auto ne = static_cast<Eigen::Index>(elements.size());
  const int nd = 3 * mesh.nodes_per_element();
  // The basis at every element's nodes (ghosts included): Psi_e, nd x m per element.
  Eigen::MatrixXd psi(nd * ne, m);
  Vec g = fem::create_ghosted_vector(mesh);
  for (Eigen::Index k = 0; k < m; ++k) {
    FX_PETSC(VecCopy(basis[static_cast<std::size_t>(k)], g));
    FX_PETSC(VecGhostUpdateBegin(g, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecGhostUpdateEnd(g, INSERT_VALUES, SCATTER_FORWARD));
    Vec gl;
    const PetscScalar *a;
    FX_PETSC(VecGhostGetLocalForm(g, &gl));
    FX_PETSC(VecGetArrayRead(gl, &a));
    for (Eigen::Index i = 0; i < ne; ++i)
      psi.block(nd * i, k, nd, 1) =
          fem::gather_element(mesh, elements[static_cast<std::size_t>(i)], a);
    FX_PETSC(VecRestoreArrayRead(gl, &a));
    FX_PETSC(VecGhostRestoreLocalForm(g, &gl));
  }
  FX_PETSC(VecDestroy(&g));
  Eigen::MatrixXd T(6 * ne, m);
  for (Eigen::Index i = 0; i < ne; ++i)
    T.middleRows(6 * i, 6) =
        centroid_stress_matrix(mesh, material, elements[static_cast<std::size_t>(i)]) *
        psi.middleRows(nd * i, nd);
  return T;
}

void add_stress_shape_cotangent(const mesh::DistributedMesh &mesh,
                                const fem::IsotropicMaterial &material,
                                const std::vector<PetscInt> &elements, const Eigen::MatrixXd &Tbar,
                                const std::vector<Vec> &out) {
  const auto ne = static_cast<Eigen::Index>(elements.size());
  const int nd = 3 * mesh.nodes_per_element();
  // S_e^T Tbar_e for every element and basis vector, then scattered into each out[k].
  Eigen::MatrixXd f(nd * ne, Tbar.cols());
  for (Eigen::Index i = 0; i < ne; ++i)
    f.middleRows(nd * i, nd) =
        centroid_stress_matrix(mesh, material, elements[static_cast<std::size_t>(i)]).transpose() *
        Tbar.middleRows(6 * i, 6);
  Vec g = fem::create_ghosted_vector(mesh);
  for (std::size_t k = 0; k < out.size(); ++k) {
    const Eigen::VectorXd column = f.col(static_cast<Eigen::Index>(k));
    fem::assemble_ghosted(g, [&](PetscScalar *a) {
      for (Eigen::Index i = 0; i < ne; ++i)
        fem::add_element(mesh, elements[static_cast<std::size_t>(i)], column.data() + nd * i, a);
    });
    FX_PETSC(VecAXPY(out[k], 1.0, g));
  }
  FX_PETSC(VecDestroy(&g));
}

} // namespace flexopt::reduce
