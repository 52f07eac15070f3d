// Centrifugal geometric stiffness of a floating-frame body (reduce/geometric_stiffness.hpp,
// docs/theory.md section 7.5) on the slender square cantilever of meshes/slender_beam.geo (Tet10,
// L / b = 25), clamped at its root, on 1 and 2 ranks:
//  - the six load cases add up to the centrifugal tensor |w|^2 I - w w^T;
//  - Southwell: spinning about z (s = Omega^2 (0, 0, 1, 0, 0, 0), G = Omega^2 G_zz), the two
//    lowest bending eigenvalues of (K_r + Omega^2 G_zz, M_r) are omega0^2 + K1 Omega^2, with the
//    Southwell coefficient K1 = 1.1933 computed here from the Euler-Bernoulli cantilever mode;
//  - with a basis of polynomial fields (independent of the partition), G_c of the distributed
//    mesh equals G_c of the whole mesh on one rank to 1e-9, and the entries of the bar in
//    centrifugal tension match 1D bar theory.
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/craig_bampton.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"
#include "test_meshes.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>
#include <random>
#include <string>
#include <vector>

using namespace flexopt;

namespace {

const double kE = 2.1e11, kNu = 0.3, kRho = 7850, kLength = 1.0, kWidth = 0.04;
const fem::IsotropicMaterial kSteel{kE, kNu, kRho};
/// Tet10 with two elements across the 0.04 m section: the lowest bending frequency is within
/// 0.5 % of Euler-Bernoulli (see the Southwell test).
const double kMeshSize = 0.02;

/// First root of cosh(beta) cos(beta) = -1 (clamped-free beam), by Newton from 1.875.
double cantilever_beta() {
  double beta = 1.875;
  for (int it = 0; it < 50; ++it) {
    const double f = std::cosh(beta) * std::cos(beta) + 1.0;
    const double df = std::sinh(beta) * std::cos(beta) - std::cosh(beta) * std::sin(beta);
    const double step = f / df;
    beta -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return beta;
}

/// Southwell coefficient of a uniform Euler-Bernoulli cantilever with zero hub radius, spinning
/// about an axis through its root perpendicular to it. The centrifugal axial force is
/// N(x) = rho A Omega^2 (L^2 - x^2) / 2 and adds (1/2) int N w'^2 dx to the strain energy; the
/// Rayleigh quotient with the first non-rotating mode phi gives omega^2 = omega0^2 + K1 Omega^2,
///   K1 = int_0^1 (1 - s^2) / 2 phi'(s)^2 ds / int_0^1 phi(s)^2 ds   (s = x / L; rho A cancels),
/// phi = cosh(beta s) - cos(beta s) - k (sinh(beta s) - sin(beta s)),
/// k = (cosh beta + cos beta) / (sinh beta + sin beta). Composite Simpson rule with 2000 panels:
/// the integrands are entire functions of s, so the error (~h^4 |f''''| / 180) is below 1e-13.
/// (Wright et al. 1982 tabulate 1.1933.)
double southwell_coefficient() {
  const double beta = cantilever_beta();
  const double k = (std::cosh(beta) + std::cos(beta)) / (std::sinh(beta) + std::sin(beta));
  constexpr int kPanels = 2000;
  double num = 0.0, den = 0.0;
  for (int i = 0; i <= kPanels; ++i) {
    const double s = static_cast<double>(i) / kPanels, bs = beta * s;
    const double weight = (i == 0 || i == kPanels) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    const double phi = std::cosh(bs) - std::cos(bs) - k * (std::sinh(bs) - std::sin(bs));
    const double dphi = beta * (std::sinh(bs) + std::sin(bs) - k * (std::cosh(bs) - std::cos(bs)));
    num += weight * 0.5 * (1.0 - s * s) * dphi * dphi;
    den += weight * phi * phi;
  }
  return num / den;
}

/// K and M of the steel beam on `m`.
void assemble(const mesh::DistributedMesh &m, Mat &K, Mat &M) {
  K = fem::create_matrix(m);
  M = fem::create_matrix(m);
  fem::assemble_stiffness(m, kSteel, {}, K);
  fem::assemble_mass(m, kRho, {}, M);
}

/// A basis that does not depend on the partition: polynomial fields vanishing on the root x = 0
/// (s = x / L): s^2 e_y, s^2 e_z, s^3 e_y, s e_x, s (-z e_y + y e_z) / b (twist), s^2 e_x.
std::vector<Vec> polynomial_basis(const mesh::DistributedMesh &m, Mat K) {
  constexpr int kFields = 6;
  std::vector<Vec> basis(kFields);
  for (Vec &v : basis) MatCreateVecs(K, &v, nullptr);
  for (int f = 0; f < kFields; ++f) {
    PetscScalar *a;
    VecGetArray(basis[static_cast<std::size_t>(f)], &a);
    for (PetscInt i = 0; i < m.owned_nodes; ++i) {
      const double *x = &m.coordinates[3 * static_cast<std::size_t>(i)];
      const double s = x[0] / kLength;
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      switch (f) {
      case 0:
        v.y() = s * s;
        break;
      case 1:
        v.z() = s * s;
        break;
      case 2:
        v.y() = s * s * s;
        break;
      case 3:
        v.x() = s;
        break;
      case 4:
        v = s * Eigen::Vector3d(0.0, -x[2], x[1]) / kWidth;
        break;
      default:
        v.x() = s * s;
        break;
      }
      for (int k = 0; k < 3; ++k) a[3 * i + k] = v(k);
    }
    VecRestoreArray(basis[static_cast<std::size_t>(f)], &a);
  }
  return basis;
}

} // namespace

TEST(CentrifugalLoad, CasesSumToTheCentrifugalTensor) {
  // sum_c s_c(w) B_c = |w|^2 I - w w^T for any w (the definition of the six load cases), and the
  // stiffening combination is the same linear map applied to the matrices.
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 10; ++trial) {
    const Eigen::Vector3d w(u(rng), u(rng), u(rng));
    const Eigen::Matrix<double, 6, 1> s = reduce::centrifugal_coefficients(w);
    Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
    std::array<Eigen::MatrixXd, 6> B;
    for (int c = 0; c < 6; ++c) {
      sum += s(c) * reduce::centrifugal_load_matrix(c);
      B[static_cast<std::size_t>(c)] = reduce::centrifugal_load_matrix(c);
    }
    const Eigen::Matrix3d exact = w.squaredNorm() * Eigen::Matrix3d::Identity() - w * w.transpose();
    EXPECT_LT((sum - exact).cwiseAbs().maxCoeff(), 1e-14 * w.squaredNorm());
    EXPECT_LT((reduce::centrifugal_stiffening(B, w) - exact).cwiseAbs().maxCoeff(),
              1e-14 * w.squaredNorm());
  }
  EXPECT_THROW(reduce::centrifugal_load_matrix(6), Error);
}

TEST(GeometricStiffness, SouthwellStiffeningOfARotatingCantilever) {
  const double t0 = wall_time();
  auto m = test_support::load_test_mesh("slender_beam.geo", kMeshSize, 2);
  Mat K, M;
  assemble(m, K, M);
  reduce::CraigBamptonBasis cb;
  reduce::craig_bampton(m, K, M, {"root"}, 6, cb);
  ASSERT_EQ(cb.static_modes, 0);
  ASSERT_EQ(cb.fixed_modes, 6);
  const auto G =
      reduce::centrifugal_geometric_stiffness(m, kSteel, K, M, "root", cb.centroids[0], cb.vectors);
  for (const auto &g : G) {
    ASSERT_EQ(g.rows(), 6);
    EXPECT_EQ((g - g.transpose()).cwiseAbs().maxCoeff(), 0.0);
  }

  // Non-rotating: the fixed modes are M-orthonormal, so the reduced eigenvalues are theirs. The
  // square section gives a pair of equal bending frequencies (y and z), within 0.5 % of
  // Euler-Bernoulli (shear and rotary inertia ~ (b/L)^2, Tet10 discretization).
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> still(cb.K, cb.M);
  const Eigen::VectorXd lambda0 = still.eigenvalues();
  const double A = kWidth * kWidth, I = kWidth * kWidth * kWidth * kWidth / 12;
  const double beta = cantilever_beta();
  const double omega_eb =
      beta * beta * std::sqrt(kE * I / (kRho * A * kLength * kLength * kLength * kLength));
  for (int k = 0; k < 2; ++k) EXPECT_NEAR(std::sqrt(lambda0(k)), omega_eb, 5e-3 * omega_eb);

  // Spin about z at Omega = 0.1 omega0: both bending eigenvalues rise by K1 Omega^2. A
  // Rayleigh-Ritz solution of the Euler-Bernoulli rotating cantilever with 6 modes gives a ratio
  // (omega^2 - omega0^2) / Omega^2 of 1.19319 at Omega / omega0 = 0.1 against K1 = 1.19334 at
  // Omega -> 0 (the Omega^4 term: -1e-4 relative), so the test measures K1 itself. The 3D solid
  // differs from the beam model by its mode shapes (shear, Poisson contraction held at the root:
  // ~(b/L)^2 = 0.2 %) and by the stress beyond sigma_xx (the lateral part of the load): 1 %.
  const double K1 = southwell_coefficient();
  const double Omega = 0.1 * std::sqrt(lambda0(0));
  auto spin_ratios = [&](const Eigen::Vector3d &axis) {
    const Eigen::MatrixXd Ks = cb.K + reduce::centrifugal_stiffening(G, Omega * axis);
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> spin(Ks, cb.M);
    return Eigen::Vector2d((spin.eigenvalues()(0) - lambda0(0)) / (Omega * Omega),
                           (spin.eigenvalues()(1) - lambda0(1)) / (Omega * Omega));
  };
  const Eigen::Vector2d about_z = spin_ratios(Eigen::Vector3d::UnitZ());
  const Eigen::Vector2d about_y = spin_ratios(Eigen::Vector3d::UnitY());
  const Eigen::Vector2d about_x = spin_ratios(Eigen::Vector3d::UnitX());
  // At Omega = omega0 for information (beam model, Rayleigh-Ritz: 1.1802).
  const Eigen::MatrixXd Kfast =
      cb.K + reduce::centrifugal_stiffening(G, 10 * Omega * Eigen::Vector3d::UnitZ());
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> fast(Kfast, cb.M);
  const double fast_ratio = (fast.eigenvalues()(0) - lambda0(0)) / (100 * Omega * Omega);
  if (comm_rank(m.comm) == 0)
    std::printf("Southwell: omega0 = %.4f, %.4f rad/s (Euler-Bernoulli %.4f); K1 expected %.6f, "
                "measured about z %.6f %.6f, about y %.6f %.6f, about x %.2e %.2e; at "
                "Omega = omega0 %.4f (%.1f s)\n",
                std::sqrt(lambda0(0)), std::sqrt(lambda0(1)), omega_eb, K1, about_z(0), about_z(1),
                about_y(0), about_y(1), about_x(0), about_x(1), fast_ratio, wall_time() - t0);
  EXPECT_NEAR(K1, 1.1933, 5e-5); // the tabulated value, to its 4 decimals
  for (int k = 0; k < 2; ++k) {
    EXPECT_NEAR(about_z(k), K1, 0.01 * K1);
    EXPECT_NEAR(about_y(k), K1, 0.01 * K1);
    // Spin about the beam's own axis only loads the section in its plane: ~(b/L)^2.
    EXPECT_LT(std::abs(about_x(k)), 0.01);
  }
  MatDestroy(&K);
  MatDestroy(&M);
}

TEST(GeometricStiffness, SameOnEveryPartitionAndMatchesBarTheory) {
  const double t0 = wall_time();
  mesh::MeshData whole;
  auto m = test_support::load_test_mesh("slender_beam.geo", kMeshSize, 2, &whole);
  Mat K, M;
  assemble(m, K, M);
  std::vector<Vec> basis = polynomial_basis(m, K);
  const Eigen::Vector3d origin = Eigen::Vector3d::Zero(); // root centroid
  const auto G = reduce::centrifugal_geometric_stiffness(m, kSteel, K, M, "root", origin, basis);
  for (Vec &v : basis) VecDestroy(&v);
  MatDestroy(&K);
  MatDestroy(&M);
  const int n = static_cast<int>(G[0].rows());
  ASSERT_EQ(n, 6);

  // Reference: the whole mesh on rank 0 alone (PETSC_COMM_SELF), broadcast to every rank.
  std::vector<double> reference(static_cast<std::size_t>(6 * n * n));
  if (comm_rank(m.comm) == 0) {
    auto serial = mesh::distribute_mesh(PETSC_COMM_SELF, &whole);
    Mat Ks, Ms;
    assemble(serial, Ks, Ms);
    std::vector<Vec> serial_basis = polynomial_basis(serial, Ks);
    const auto Gs = reduce::centrifugal_geometric_stiffness(serial, kSteel, Ks, Ms, "root", origin,
                                                            serial_basis);
    for (int c = 0; c < 6; ++c)
      Eigen::Map<Eigen::MatrixXd>(&reference[static_cast<std::size_t>(c * n * n)], n, n) =
          Gs[static_cast<std::size_t>(c)];
    for (Vec &v : serial_basis) VecDestroy(&v);
    MatDestroy(&Ks);
    MatDestroy(&Ms);
  }
  MPI_Bcast(reference.data(), static_cast<int>(reference.size()), MPI_DOUBLE, 0, m.comm);
  // Relative to the largest entry of the six matrices (the scale of the stiffening per unit
  // |omega|^2): in this basis G_yz vanishes by the symmetry of the section (its entries, ~1e-8
  // of the scale, are round-off of the in-plane solve), so a per-case scale would compare noise.
  // Measured: 2e-10 on 2 ranks (MUMPS with another ordering), 0 on 1 rank.
  double scale = 0.0;
  for (double r : reference) scale = std::max(scale, std::abs(r));
  ASSERT_GT(scale, 0.0);
  double worst = 0.0;
  for (int c = 0; c < 6; ++c) {
    const Eigen::Map<const Eigen::MatrixXd> ref(&reference[static_cast<std::size_t>(c * n * n)], n,
                                                n);
    const double diff = (G[static_cast<std::size_t>(c)] - ref).cwiseAbs().maxCoeff() / scale;
    worst = std::max(worst, diff);
    EXPECT_LT(diff, 1e-9) << reduce::kCentrifugalCases[static_cast<std::size_t>(c)];
  }

  // Bar theory for spin about z: sigma_xx = rho Omega^2 (L^2 - x^2) / 2, G = Omega^2 G_zz, and
  // v^T G_zz v = int sigma_xx |dv/dx|^2 dV / Omega^2 for the fields that vary along x only.
  //  - s e_x: rho A L / 3. The Tet10 solution satisfies this exactly (x e_x is a test function,
  //    the load is consistent and the stiffness rule integrates the linear stress exactly), so
  //    only the solve's round-off remains: 1e-10.
  //  - s^2 e_y, s^2 e_z: 4 rho A L / 15 = int N(x) (2 x / L^2)^2 dx. The section resultant
  //    N(x) = int sigma_xx dA is statically determinate, so the 3D solid has the bar's value;
  //    the FE error of this functional is a(u - u_h, v - v_h) with v = x^3 / (3 L^2) e_x, of
  //    order h^4, plus the 4-point rule's error on the cubic integrand (measured 3e-9 in all):
  //    1e-6.
  //  - twist s (-z e_y + y e_z) / b: sigma_xx gives rho b^2 L / 18 (polar moment b^4 / 6), and
  //    the in-plane part rho Omega^2 y e_y of the load is carried by sigma_yy = rho Omega^2
  //    (b^2 / 4 - y^2) / 2 (free faces y = +-b/2), which meets (dv_z/dy)^2 = s^2 / b^2: another
  //    rho b^2 L / 36; rho b^2 L / 12 in all. That sigma_yy is the strength-of-materials one
  //    (it ignores the self-equilibrated Poisson stresses ~nu rho Omega^2 b^2): 0.5 % (measured
  //    0.03 %).
  const Eigen::MatrixXd &Gzz = G[2];
  const double A = kWidth * kWidth;
  const double axial = kRho * A * kLength / 3, bending = 4 * kRho * A * kLength / 15,
               twist = kRho * kWidth * kWidth * kLength / 12;
  if (comm_rank(m.comm) == 0)
    std::printf("G_zz: axial %.10f (bar %.10f), bending y %.8f z %.8f (bar %.8f), twist %.6f "
                "(bar %.6f); partitions differ by %.2e relative (%.1f s)\n",
                Gzz(3, 3), axial, Gzz(0, 0), Gzz(1, 1), bending, Gzz(4, 4), twist, worst,
                wall_time() - t0);
  EXPECT_NEAR(Gzz(3, 3), axial, 1e-10 * axial);
  EXPECT_NEAR(Gzz(0, 0), bending, 1e-6 * bending);
  EXPECT_NEAR(Gzz(1, 1), bending, 1e-6 * bending);
  EXPECT_NEAR(Gzz(4, 4), twist, 5e-3 * twist);
}

TEST(GeometricStiffness, MissingFrameSurfaceIsACollectiveError) {
  auto m = test_support::load_test_mesh("slender_beam.geo", 0.04, 1);
  Mat K, M;
  assemble(m, K, M);
  try {
    reduce::centrifugal_geometric_stiffness(m, kSteel, K, M, "hub", Eigen::Vector3d::Zero(), {});
    ADD_FAILURE() << "no exception";
  } catch (const Error &e) {
    EXPECT_TRUE(e.collective());
    EXPECT_NE(std::string(e.what()).find("hub"), std::string::npos) << e.what();
  }
  MatDestroy(&K);
  MatDestroy(&M);
}
