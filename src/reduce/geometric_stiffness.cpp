#include "flexopt/reduce/geometric_stiffness.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/reduce/modal.hpp"

#include <petscksp.h>
#include <string>

namespace flexopt::reduce {

const std::array<const char *, 6> kCentrifugalCases = {"xx", "yy", "zz", "yz", "xz", "xy"};

Eigen::Matrix<double, 6, 1> centrifugal_coefficients(const Eigen::Vector3d &omega,
                                                     Eigen::Matrix<double, 6, 3> *derivative) {
  const double x = omega.x(), y = omega.y(), z = omega.z();
  Eigen::Matrix<double, 6, 1> s;
  s << x * x, y * y, z * z, y * z, x * z, x * y;
  if (derivative) *derivative << 2 * x, 0, 0, 0, 2 * y, 0, 0, 0, 2 * z, 0, z, y, z, 0, x, y, x, 0;
  return s;
}

Eigen::Matrix3d centrifugal_load_matrix(int c) {
  // Axis pairs (a, b) of the off-diagonal cases yz, xz, xy.
  static constexpr int kPairs[3][2] = {{1, 2}, {0, 2}, {0, 1}};
  if (c < 0 || c > 5)
    throw Error("centrifugal_load_matrix: load case " + std::to_string(c) + " is not in 0..5");
  Eigen::Matrix3d B = Eigen::Matrix3d::Zero();
  if (c < 3) {
    B = Eigen::Matrix3d::Identity();
    B(c, c) = 0.0;
  } else {
    const int a = kPairs[c - 3][0], b = kPairs[c - 3][1];
    B(a, b) = B(b, a) = -1.0;
  }
  return B;
}

Eigen::MatrixXd centrifugal_stiffening(const std::array<Eigen::MatrixXd, 6> &G,
                                       const Eigen::Vector3d &omega) {
  const Eigen::Matrix<double, 6, 1> s = centrifugal_coefficients(omega);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(G[0].rows(), G[0].cols());
  for (int c = 0; c < 6; ++c) sum += s(c) * G[static_cast<std::size_t>(c)];
  return sum;
}

std::array<Eigen::MatrixXd, 6>
centrifugal_geometric_stiffness(const mesh::DistributedMesh &mesh,
                                const fem::IsotropicMaterial &material, Mat K, Mat M,
                                const std::string &frame_interface, const Eigen::Vector3d &origin,
                                const std::vector<Vec> &basis) {
  LogScope log("FxGeomStiffness");
  const int n = static_cast<int>(basis.size());
  std::array<Eigen::MatrixXd, 6> G;
  for (auto &g : G) g.setZero(n, n);
  // Every rank holds the same material: its error is collective.
  try {
    material.validate();
  } catch (const Error &err) {
    throw Error(std::string("centrifugal geometric stiffness: ") + err.what(), true);
  }
  const std::vector<PetscInt> frame = fem::surface_dofs(mesh, frame_interface, {true, true, true},
                                                        "centrifugal geometric stiffness frame");
  if (n == 0) return G;

  // The body clamped at its frame: one factorization for the six load cases.
  const ClampedSolver clamped(mesh.comm, K, frame, "gs_");

  Vec w, f;
  FX_PETSC(MatCreateVecs(M, &w, &f));
  Vec u = fem::create_ghosted_vector(mesh);
  Mat Ks = fem::create_matrix(mesh);
  PetscInt lo;
  FX_PETSC(VecGetOwnershipRange(f, &lo, nullptr));
  auto destroy = [&] {
    MatDestroy(&Ks);
    VecDestroy(&u);
    VecDestroy(&f);
    VecDestroy(&w);
  };
  for (int c = 0; c < 6; ++c) {
    // Load: f_c = M w_c, w_c = B_c (X - origin) at the owned nodes, zero on the clamped DOFs.
    const Eigen::Matrix3d B = centrifugal_load_matrix(c);
    {
      PetscScalar *wa;
      FX_PETSC(VecGetArray(w, &wa));
      for (PetscInt i = 0; i < mesh.owned_nodes; ++i) {
        const Eigen::Vector3d x =
            Eigen::Map<const Eigen::Vector3d>(&mesh.coordinates[3 * static_cast<std::size_t>(i)]) -
            origin;
        Eigen::Map<Eigen::Vector3d> wi(&wa[3 * i]);
        wi = B * x;
      }
      FX_PETSC(VecRestoreArray(w, &wa));
    }
    FX_PETSC(MatMult(M, w, f));
    {
      PetscScalar *fa;
      FX_PETSC(VecGetArray(f, &fa));
      for (PetscInt dof : frame) fa[dof - lo] = 0.0;
      FX_PETSC(VecRestoreArray(f, &fa));
    }
    try {
      clamped.solve(f, u,
                    std::string("centrifugal geometric stiffness: the solve of load case ") +
                        kCentrifugalCases[static_cast<std::size_t>(c)] + " with '" +
                        frame_interface + "' clamped",
                    ". Does the frame surface hold the body against rigid motion?");
    } catch (const Error &) {
      destroy();
      throw;
    }
    FX_PETSC(VecGhostUpdateBegin(u, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecGhostUpdateEnd(u, INSERT_VALUES, SCATTER_FORWARD));

    // G_c = V^T K_sigma(u_c) V.
    fem::assemble_geometric_stiffness(mesh, material, u, Ks);
    G[static_cast<std::size_t>(c)] = project(Ks, basis);
  }
  destroy();
  return G;
}

} // namespace flexopt::reduce
