// Craig-Bampton reduction (docs/theory.md section 7.1) of the steel beam (meshes/beam.geo,
// Tet10), clamped at "clamp", with the rigid "tip" surface as second interface, on 1 and 2
// ranks:
//  - the static modes condense the beam onto its tip: the reduced 6 x 6 stiffness inverted is
//    the tip compliance, which beam theory gives in closed form (Timoshenko bending with
//    Cowper's shear factor, bar extension L/EA);
//  - static and fixed-interface modes are K-orthogonal (the static modes are K-harmonic in the
//    interior, the fixed modes vanish on the interfaces), and the fixed modes are M-orthonormal
//    with V^T K V = diag(omega^2).
#include "flexopt/core/context.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/craig_bampton.hpp"

#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>

using namespace flexopt;

namespace {

mesh::DistributedMesh load(const char *geometry, double size, int order) {
  mesh::MeshData data;
  const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/" + geometry;
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    data = mesh::read_gmsh(geo, mesh::MeshOptions{size, order});
  });
  return mesh::distribute_mesh(PETSC_COMM_WORLD,
                               comm_rank(PETSC_COMM_WORLD) == 0 ? &data : nullptr);
}

} // namespace

TEST(CraigBampton, StaticModesCondenseTheBeamOntoItsTip) {
  const double E = 2.1e11, nu = 0.3, rho = 7850, L = 1.0, h = 0.05, b = 0.1;
  auto m = load("beam.geo", 0.025, 2);
  Mat K = fem::create_matrix(m), M = fem::create_matrix(m);
  fem::assemble_stiffness(m, fem::IsotropicMaterial{E, nu, rho}, {}, K);
  fem::assemble_mass(m, rho, {}, M);
  reduce::CraigBamptonBasis cb;
  reduce::craig_bampton(m, K, M, {"clamp", "tip"}, 4, cb);
  ASSERT_EQ(cb.static_modes, 6);
  ASSERT_EQ(cb.fixed_modes, 4);
  EXPECT_NEAR(cb.centroids[1].x(), L, 1e-12);
  EXPECT_NEAR(cb.centroids[1].y(), h / 2, 1e-12);
  EXPECT_NEAR(cb.centroids[1].z(), b / 2, 1e-12);

  // Tip compliance from the static block.
  const Eigen::MatrixXd C = cb.K.topLeftCorner(6, 6).inverse();
  const double G = E / (2 * (1 + nu)), A = h * b, kappa = 10 * (1 + nu) / (12 + 11 * nu);
  const double Iz = b * h * h * h / 12, Iy = h * b * b * b / 12;
  const double cy = L * L * L / (3 * E * Iz) + L / (kappa * G * A); // force along y
  const double cz = L * L * L / (3 * E * Iy) + L / (kappa * G * A); // force along z
  const double cx = L / (E * A);
  if (comm_rank(m.comm) == 0)
    std::printf("tip compliance x %.6e (bar %.6e), y %.6e (Timoshenko %.6e), z %.6e (%.6e)\n",
                C(0, 0), cx, C(1, 1), cy, C(2, 2), cz);
  // Beam theory leaves out the end effects of the clamp and of the rigid tip surface
  // (restrained warping and Poisson contraction) and the Tet10 mesh is a little stiff: 2 %.
  EXPECT_NEAR(C(1, 1), cy, 0.02 * cy);
  EXPECT_NEAR(C(2, 2), cz, 0.02 * cz);
  EXPECT_NEAR(C(0, 0), cx, 0.02 * cx);

  // K-orthogonality of static and fixed modes; fixed modes M-orthonormal, K-diagonal.
  const double kscale = cb.K.topLeftCorner(6, 6).cwiseAbs().maxCoeff();
  EXPECT_LT(cb.K.topRightCorner(6, 4).cwiseAbs().maxCoeff(), 1e-9 * kscale);
  EXPECT_LT((cb.M.bottomRightCorner(4, 4) - Eigen::MatrixXd::Identity(4, 4)).cwiseAbs().maxCoeff(),
            1e-9);
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(cb.K(6 + i, 6 + i), cb.fixed_eigenvalues[static_cast<std::size_t>(i)],
                1e-8 * cb.fixed_eigenvalues[static_cast<std::size_t>(i)]);
    EXPECT_GT(cb.fixed_eigenvalues[static_cast<std::size_t>(i)], 0);
  }
  MatDestroy(&K);
  MatDestroy(&M);
}
