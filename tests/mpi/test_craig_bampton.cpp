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
#include "flexopt/reduce/ffrf_invariants.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "test_meshes.hpp"

#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>

using namespace flexopt;

TEST(CraigBampton, StaticModesCondenseTheBeamOntoItsTip) {
  const double E = 2.1e11, nu = 0.3, rho = 7850, L = 1.0, h = 0.05, b = 0.1;
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
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

// One Cholesky factorization of K_ii serves the static modes and the shift-and-invert about 0
// of the fixed-interface modes (reduce::ClampedProblem). An -eps_target option moves the shift
// off 0; the static solves then get their own factorization (prefix cb_). Both paths must give
// the same basis: the same reduced matrices to round-off of the direct solves (1e-9 of their
// scale) and the same eigenvalues to the eigensolver tolerance (1e-10 relative, 1e-8 here).
TEST(CraigBampton, SharedAndSeparateFactorizationsAgree) {
  const double E = 2.1e11, nu = 0.3, rho = 7850;
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  Mat K = fem::create_matrix(m), M = fem::create_matrix(m);
  fem::assemble_stiffness(m, fem::IsotropicMaterial{E, nu, rho}, {}, K);
  fem::assemble_mass(m, rho, {}, M);
  reduce::CraigBamptonBasis shared, separate;
  reduce::craig_bampton(m, K, M, {"clamp", "tip"}, 4, shared);
  PetscOptionsSetValue(nullptr, "-eps_target", "1e4"); // below the lowest omega^2 (~1e6)
  reduce::craig_bampton(m, K, M, {"clamp", "tip"}, 4, separate);
  PetscOptionsClearValue(nullptr, "-eps_target");
  ASSERT_EQ(shared.K.rows(), 10);
  ASSERT_EQ(separate.K.rows(), 10);
  const double kscale = shared.K.cwiseAbs().maxCoeff(), mscale = shared.M.cwiseAbs().maxCoeff();
  // Mode signs are arbitrary: compare |entries| of the coupling blocks, the rest directly.
  EXPECT_LT((shared.K.topLeftCorner(6, 6) - separate.K.topLeftCorner(6, 6)).cwiseAbs().maxCoeff(),
            1e-9 * kscale);
  EXPECT_LT((shared.M.topLeftCorner(6, 6) - separate.M.topLeftCorner(6, 6)).cwiseAbs().maxCoeff(),
            1e-9 * mscale);
  EXPECT_LT((shared.M.topRightCorner(6, 4).cwiseAbs() - separate.M.topRightCorner(6, 4).cwiseAbs())
                .cwiseAbs()
                .maxCoeff(),
            1e-7 * mscale);
  for (std::size_t i = 0; i < 4; ++i)
    EXPECT_NEAR(shared.fixed_eigenvalues[i], separate.fixed_eigenvalues[i],
                1e-8 * shared.fixed_eigenvalues[i]);
  MatDestroy(&K);
  MatDestroy(&M);
}

// The frame conditions of the FFRF reduction (docs/theory.md section 7.1) on the steel beam
// with interfaces "clamp" and "tip": with the frame clamped at "clamp" the reduced model's
// lowest frequency is the cantilever's, 1.8751^2 sqrt(EI/rho A) / L^2; with the chord frame the
// beam is held at "clamp"'s centroid and "tip"'s centroid moves only along the axis, both ends
// free to turn: the simply supported beam's pi^2 sqrt(EI/rho A) / L^2, here about the weak
// axis (h along y). Timoshenko's shear and rotary-inertia corrections are -0.1 % (cantilever)
// and -0.4 % (pinned, (pi^2 / 2)(r / L)^2 (1 + E / (kappa G))); the Tet10 mesh (2 elements
// through h) is a little stiff and the rigid end faces restrain their warping: 1 % (measured
// +0.35 % and +0.05 %).
// In the chord frame "tip" moves only along the axis, and "clamp" turns (its rotation is
// elastic, zero in the clamped frame).
TEST(FlexibleReduction, ClampedAndChordFramesGiveCantileverAndPinnedFrequencies) {
  const double E = 2.1e11, nu = 0.3, rho = 7850, L = 1.0, h = 0.05, b = 0.1;
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const fem::IsotropicMaterial steel{E, nu, rho};
  const double c = std::sqrt(E * b * h * h * h / 12 / (rho * b * h)) / (L * L);
  const double kappa = 10 * (1 + nu) / (12 + 11 * nu), r2 = h * h / 12;
  const double w_cantilever = 1.8751 * 1.8751 * c;
  const double w_pinned =
      M_PI * M_PI * c * (1 - 0.5 * M_PI * M_PI * r2 / (L * L) * (1 + E / (kappa * E / 2.6)));
  reduce::FlexibleReduction clamped, chord;
  reduce::reduce_flexible_body(m, steel, {"clamp", "tip"}, 4, false, clamped);
  reduce::reduce_flexible_body(m, steel, {"clamp", "tip"}, 4, false, chord,
                               reduce::FrameCondition::Chord);
  const double w1 = std::sqrt(clamped.eigenvalues(0)), w2 = std::sqrt(chord.eigenvalues(0));
  if (comm_rank(m.comm) == 0)
    std::printf("lowest frequency: clamped frame %.2f rad/s (cantilever %.2f), chord frame %.2f "
                "rad/s (simply supported %.2f)\n",
                w1, w_cantilever, w2, w_pinned);
  EXPECT_NEAR(w1, w_cantilever, 0.01 * w_cantilever);
  EXPECT_NEAR(w2, w_pinned, 0.01 * w_pinned);
  // Interface motion per basis coordinate: in the chord frame "tip" moves along x only and no
  // end twists about the axis.
  const double scale = chord.translation[1].cwiseAbs().maxCoeff();
  EXPECT_LT(chord.translation[1].bottomRows(2).cwiseAbs().maxCoeff(), 1e-12 * scale);
  EXPECT_LT(chord.translation[0].cwiseAbs().maxCoeff(), 1e-12 * scale);
  EXPECT_GT(chord.rotation[0].cwiseAbs().maxCoeff(), 0.1 * chord.rotation[1].cwiseAbs().maxCoeff());
  EXPECT_LT(chord.rotation[0].row(0).cwiseAbs().maxCoeff(),
            1e-12 * chord.rotation[0].cwiseAbs().maxCoeff());
  EXPECT_EQ(clamped.rotation[0].cwiseAbs().maxCoeff(), 0.0);
  // Both bases stay M-orthonormal with the same reduced stiffness spectrum structure.
  EXPECT_LT((chord.M - Eigen::MatrixXd::Identity(10, 10)).cwiseAbs().maxCoeff(), 1e-10);
}

// FFRF inertia invariants (docs/theory.md section 7.2) of the same beam with its Craig-Bampton
// basis: in the undeformed state they are the box's exact mass, first moment and inertia about
// the frame origin (the clamp centroid); for a random deformation zeta the expansions
// d(zeta) = d0 + D zeta and S(zeta) = S0 + ... equal the moments of the deformed node positions
// X + Psi zeta computed directly with the mass matrix (to round-off).
TEST(FfrfInvariants, RigidMomentsAndDeformedExpansion) {
  const double rho = 7850, L = 1.0, h = 0.05, b = 0.1;
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  Mat K = fem::create_matrix(m), M = fem::create_matrix(m);
  fem::assemble_stiffness(m, fem::IsotropicMaterial{2.1e11, 0.3, rho}, {}, K);
  fem::assemble_mass(m, rho, {}, M);
  reduce::CraigBamptonBasis cb;
  reduce::craig_bampton(m, K, M, {"clamp", "tip"}, 3, cb);
  const Eigen::Vector3d origin = cb.centroids[0];
  const auto inv = reduce::ffrf_invariants(m, M, cb.vectors, origin);
  const int n = inv.modes();
  ASSERT_EQ(n, 9);
  const double mass = rho * L * h * b;
  EXPECT_NEAR(inv.mass, mass, 1e-12 * mass);
  EXPECT_LT((inv.d0 - mass * Eigen::Vector3d(L / 2, 0, 0)).norm(), 1e-12 * mass * L);
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  J(0, 0) = mass * (h * h + b * b) / 12;
  J(1, 1) = mass * (L * L / 3 + b * b / 12);
  J(2, 2) = mass * (L * L / 3 + h * h / 12);
  EXPECT_LT((inv.inertia(Eigen::VectorXd::Zero(n)) - J).cwiseAbs().maxCoeff(), 1e-12 * J.norm());

  // Deformed: x = X + sum_k zeta_k Psi_k, moments straight from M.
  Eigen::VectorXd zeta(n);
  for (int k = 0; k < n; ++k) zeta(k) = 1e-3 * std::cos(1.0 + 2.3 * k);
  Vec x, Mx;
  MatCreateVecs(M, &x, &Mx);
  {
    PetscScalar *a;
    VecGetArray(x, &a);
    for (PetscInt i = 0; i < m.owned_nodes; ++i)
      for (int c = 0; c < 3; ++c)
        a[3 * i + c] =
            m.coordinates[3 * static_cast<std::size_t>(i) + static_cast<std::size_t>(c)] -
            origin(c);
    VecRestoreArray(x, &a);
  }
  for (int k = 0; k < n; ++k) VecAXPY(x, zeta(k), cb.vectors[static_cast<std::size_t>(k)]);
  MatMult(M, x, Mx);
  double local[12] = {0};
  const PetscScalar *xa, *ma;
  VecGetArrayRead(x, &xa);
  VecGetArrayRead(Mx, &ma);
  for (PetscInt i = 0; i < m.owned_nodes; ++i)
    for (int r = 0; r < 3; ++r) {
      local[9 + r] += ma[3 * i + r];
      for (int c = 0; c < 3; ++c) local[3 * r + c] += xa[3 * i + r] * ma[3 * i + c];
    }
  VecRestoreArrayRead(x, &xa);
  VecRestoreArrayRead(Mx, &ma);
  double global[12];
  MPI_Allreduce(local, global, 12, MPI_DOUBLE, MPI_SUM, m.comm);
  const Eigen::Matrix3d S = Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(global);
  const Eigen::Vector3d d(global[9], global[10], global[11]);
  EXPECT_LT((inv.second_moment(zeta) - S).cwiseAbs().maxCoeff(), 1e-12 * S.norm());
  EXPECT_LT((inv.first_moment(zeta) - d).norm(), 1e-12 * d.norm());
  // The deformation is not negligible in the check: the moments did change.
  EXPECT_GT((inv.second_moment(zeta) - inv.S0).cwiseAbs().maxCoeff(), 1e-9 * S.norm());
  VecDestroy(&x);
  VecDestroy(&Mx);
  MatDestroy(&K);
  MatDestroy(&M);
}
