#include "flexopt/reduce/geometric_stiffness.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/reduce/modal.hpp"

#include <memory>
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

CentrifugalLoadStates::~CentrifugalLoadStates() {
  for (Vec &v : u) VecDestroy(&v);
}

std::vector<Eigen::MatrixXd> reduced_geometric_stiffness(const mesh::DistributedMesh &mesh,
                                                         const fem::IsotropicMaterial &material,
                                                         const std::vector<Vec> &basis,
                                                         const std::vector<Vec> &u,
                                                         const std::vector<double> &modulus_factor,
                                                         const std::string &what) {
  const auto n = static_cast<Eigen::Index>(basis.size());
  std::vector<Eigen::MatrixXd> G(u.size(), Eigen::MatrixXd::Zero(n, n));
  if (u.empty()) return G;
  // Summed element by element (as fem::project_stiffness: the assembled K_sigma V would cancel
  // element forces row by row).
  {
    const fem::ElementGather vg(mesh, basis), ug(mesh, u);
    Eigen::MatrixXd Ve, Ue;
    for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
      const fem::ElementCoords X = mesh.element_coordinates(e);
      const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
      vg.element(e, Ve);
      ug.element(e, Ue);
      for (std::size_t c = 0; c < u.size(); ++c) {
        fem::ElementMatrix Ks;
        try {
          Ks = fem::element_geometric_stiffness(mesh.type, X, material,
                                                Ue.col(static_cast<Eigen::Index>(c)));
        } catch (const std::exception &err) {
          abort_local(what + ": element " +
                      std::to_string(mesh.element_tags[static_cast<std::size_t>(e)]) + ": " +
                      err.what());
        }
        G[c].noalias() += f * (Ve.transpose() * (Ks * Ve));
      }
    }
  }
  for (auto &g : G) {
    MPI_Allreduce(MPI_IN_PLACE, g.data(), static_cast<int>(g.size()), MPI_DOUBLE, MPI_SUM,
                  mesh.comm);
    g = 0.5 * (g + g.transpose()).eval();
  }
  return G;
}

std::array<Eigen::MatrixXd, 6> centrifugal_geometric_stiffness(
    const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &material, Mat K, Mat M,
    const std::string &frame_interface, const Eigen::Vector3d &origin,
    const std::vector<Vec> &basis, ClampedProblem *frame_clamped,
    const std::vector<double> &modulus_factor, CentrifugalLoadStates *keep) {
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

  // The body clamped at its frame: one factorization for the six load cases (the caller's if
  // it has one).
  std::shared_ptr<ClampedProblem> own;
  if (!frame_clamped) {
    own = std::make_shared<ClampedProblem>(K, M, frame, 0, "gs_");
    frame_clamped = own.get();
  }

  // Loads f_c = M w_c, w_c = B_c (X - origin) at the owned nodes, zero on the clamped DOFs.
  std::vector<Vec> f(6), u(6);
  auto destroy = [&] {
    for (Vec &v : f) VecDestroy(&v);
    for (Vec &v : u) VecDestroy(&v);
  };
  Vec w;
  FX_PETSC(MatCreateVecs(M, &w, nullptr));
  PetscInt lo;
  FX_PETSC(VecGetOwnershipRange(w, &lo, nullptr));
  for (int c = 0; c < 6; ++c) {
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
    const auto k = static_cast<std::size_t>(c);
    FX_PETSC(MatCreateVecs(M, &u[k], &f[k]));
    FX_PETSC(MatMult(M, w, f[k]));
    PetscScalar *fa;
    FX_PETSC(VecGetArray(f[k], &fa));
    for (PetscInt dof : frame) fa[dof - lo] = 0.0;
    FX_PETSC(VecRestoreArray(f[k], &fa));
  }
  FX_PETSC(VecDestroy(&w));
  try {
    frame_clamped->solve(f, u,
                         "centrifugal geometric stiffness: the solve of the load cases with '" +
                             frame_interface + "' clamped",
                         ". Does the frame surface hold the body against rigid motion?");
  } catch (const Error &) {
    destroy();
    throw;
  }

  // G_c = V^T K_sigma(u_c) V.
  try {
    const std::vector<Eigen::MatrixXd> Gc = reduced_geometric_stiffness(
        mesh, material, basis, u, modulus_factor, "centrifugal geometric stiffness");
    for (std::size_t c = 0; c < 6; ++c) G[c] = Gc[c];
  } catch (const Error &) {
    destroy();
    throw;
  }
  if (keep) {
    for (Vec &v : keep->u) FX_PETSC(VecDestroy(&v));
    keep->u = u;
    u.clear();
    keep->frame = own;
    keep->frame_dofs = frame;
  }
  destroy();
  return G;
}

} // namespace flexopt::reduce
