// Assembly of the co-rotated elastic energy, force and tangent of a whole body
// (fem::assemble_corotated, docs/theory.md section 8.1) on the steel beam (meshes/beam.geo,
// Tet10, 1 m x 50 x 100 mm), on 1 and 2 ranks:
//  - a uniform stretch e along x has the energy (lambda + 2 mu) e^2 V / 2 exactly, before and
//    after a large rigid rotation (which a linear model would see as a huge strain), and a
//    rigid motion has no force;
//  - the force carries no net force and no net moment about the origin;
//  - the force is the derivative of the energy and the tangent that of the force (central
//    differences along a smooth field), and the tangent at u = 0 is the linear stiffness.
#include "flexopt/core/context.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "test_meshes.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <gtest/gtest.h>

using namespace flexopt;

namespace {

const fem::IsotropicMaterial kSteel{2.1e11, 0.3, 7850};

/// Sets the ghosted vector u to field(X) at every local node (owned and ghosts).
void set_field(const mesh::DistributedMesh &m, Vec u,
               const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &field) {
  Vec local;
  VecGhostGetLocalForm(u, &local);
  PetscScalar *a;
  VecGetArray(local, &a);
  for (PetscInt i = 0; i < m.local_nodes(); ++i) {
    const Eigen::Vector3d X(&m.coordinates[3 * static_cast<std::size_t>(i)]);
    const Eigen::Vector3d v = field(X);
    for (int k = 0; k < 3; ++k) a[3 * i + k] = v(k);
  }
  VecRestoreArray(local, &a);
  VecGhostRestoreLocalForm(u, &local);
}

/// Sum over the owned nodes of f_a (net force) and of x_a x f_a (moment about the origin),
/// x = X + u, reduced over the ranks.
std::pair<Eigen::Vector3d, Eigen::Vector3d>
net_force_and_moment(const mesh::DistributedMesh &m, Vec F,
                     const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &field) {
  const PetscScalar *f;
  VecGetArrayRead(F, &f);
  double s[6] = {0, 0, 0, 0, 0, 0}, g[6];
  for (PetscInt i = 0; i < m.owned_nodes; ++i) {
    const Eigen::Vector3d X(&m.coordinates[3 * static_cast<std::size_t>(i)]);
    const Eigen::Vector3d fa(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
    const Eigen::Vector3d mo = (X + field(X)).cross(fa);
    for (int k = 0; k < 3; ++k) s[k] += fa(k), s[3 + k] += mo(k);
  }
  VecRestoreArrayRead(F, &f);
  MPI_Allreduce(s, g, 6, MPI_DOUBLE, MPI_SUM, m.comm);
  return {Eigen::Vector3d(g[0], g[1], g[2]), Eigen::Vector3d(g[3], g[4], g[5])};
}

double norm_inf(Vec v) {
  PetscReal n;
  VecNorm(v, NORM_INFINITY, &n);
  return n;
}

double norm_2(Vec v) {
  PetscReal n;
  VecNorm(v, NORM_2, &n);
  return n;
}

} // namespace

TEST(AcfAssembly, UniformStretchRotatedAndRigidMotion) {
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const auto elements = fem::corotated_elements(m, kSteel, {});
  Vec u = fem::create_ghosted_vector(m), F;
  VecDuplicate(u, &F);
  Mat T = fem::create_matrix(m);
  const double e = 1e-3, V = 1.0 * 0.05 * 0.1;
  const double exact = 0.5 * (kSteel.lambda() + 2 * kSteel.mu()) * e * e * V;
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.4, -1.0, 2.0);
  auto stretch = [&](const Eigen::Vector3d &X) { return Eigen::Vector3d(e * X.x(), 0, 0); };
  auto rotated = [&](const Eigen::Vector3d &X) {
    return Eigen::Vector3d(Q * (X + stretch(X)) + t - X);
  };
  auto rigid = [&](const Eigen::Vector3d &X) { return Eigen::Vector3d(Q * X + t - X); };
  set_field(m, u, stretch);
  const fem::CorotatedSum s1 = fem::assemble_corotated(m, elements, u, F, T);
  const double f1 = norm_2(F);
  set_field(m, u, rotated);
  const fem::CorotatedSum s2 = fem::assemble_corotated(m, elements, u, F, nullptr);
  const double f2 = norm_2(F);
  set_field(m, u, rigid);
  const fem::CorotatedSum s3 = fem::assemble_corotated(m, elements, u, F, nullptr);
  if (comm_rank(m.comm) == 0)
    std::printf("uniform stretch: energy %.12e (exact %.12e), rotated %.12e; rigid %.3e\n",
                s1.energy, exact, s2.energy, s3.energy);
  ASSERT_TRUE(s1.ok && s2.ok && s3.ok);
  // Tet10 integrates the constant strain exactly: round-off of summing ~10^4 elements.
  EXPECT_NEAR(s1.energy, exact, 1e-11 * exact);
  EXPECT_NEAR(s2.energy, exact, 1e-9 * exact); // the rotation costs digits of R
  EXPECT_NEAR(f2, f1, 1e-8 * f1);              // the same forces, rotated (2-norm)
  EXPECT_LT(std::abs(s3.energy), 1e-18 * exact);
  EXPECT_LT(norm_2(F), 1e-9 * f1);
  MatDestroy(&T);
  VecDestroy(&F);
  VecDestroy(&u);
}

TEST(AcfAssembly, MomentumDerivativesAndLinearLimit) {
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const auto elements = fem::corotated_elements(m, kSteel, {});
  Vec u = fem::create_ghosted_vector(m), F, Fp, Fm, d, Td;
  VecDuplicate(u, &F);
  VecDuplicate(u, &Fp);
  VecDuplicate(u, &Fm);
  VecDuplicate(u, &d);
  VecDuplicate(u, &Td);
  Mat T = fem::create_matrix(m);
  // A bent, twisted and rotated beam: strains ~1e-3, rotations ~0.5 rad.
  const Eigen::Matrix3d Q =
      Eigen::AngleAxisd(0.5, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  auto bent = [&](const Eigen::Vector3d &X) {
    const double s = X.x();
    const Eigen::Vector3d local(1e-3 * s, 2e-2 * s * s - 1e-3 * X.z() * s, 3e-3 * s * s * s);
    return Eigen::Vector3d(Q * (X + local) - X);
  };
  auto dir = [](const Eigen::Vector3d &X) {
    return Eigen::Vector3d(std::sin(3 * X.x()), X.x() * X.y(), std::cos(2 * X.x()) * X.z());
  };
  set_field(m, u, bent);
  const fem::CorotatedSum s = fem::assemble_corotated(m, elements, u, F, T);
  ASSERT_TRUE(s.ok);
  const double fs = norm_inf(F);
  const auto [net, moment] = net_force_and_moment(m, F, bent);
  EXPECT_LT(net.cwiseAbs().maxCoeff(), 1e-10 * fs);
  EXPECT_LT(moment.cwiseAbs().maxCoeff(), 1e-10 * fs); // lever arms ~1 m

  // Central differences along d (max |d| = 1) with a step of 1e-7 m.
  const double h = 1e-7;
  set_field(m, d, dir);
  auto shifted = [&](double sign) {
    return [&, sign](const Eigen::Vector3d &X) {
      return Eigen::Vector3d(bent(X) + sign * h * dir(X));
    };
  };
  set_field(m, u, shifted(1));
  const double Ep = fem::assemble_corotated(m, elements, u, Fp, nullptr).energy;
  set_field(m, u, shifted(-1));
  const double Em = fem::assemble_corotated(m, elements, u, Fm, nullptr).energy;
  PetscScalar fd;
  VecDot(F, d, &fd);
  EXPECT_NEAR((Ep - Em) / (2 * h), fd, 1e-6 * std::abs(fd));
  MatMult(T, d, Td);
  VecAXPY(Fp, -1.0, Fm);
  VecScale(Fp, 1 / (2 * h));
  VecAXPY(Fp, -1.0, Td);
  EXPECT_LT(norm_inf(Fp), 1e-6 * norm_inf(Td));

  // At u = 0 the tangent is the linear stiffness.
  set_field(m, u, [](const Eigen::Vector3d &) { return Eigen::Vector3d::Zero(); });
  fem::assemble_corotated(m, elements, u, F, T);
  Mat K = fem::create_matrix(m);
  fem::assemble_stiffness(m, kSteel, {}, K);
  PetscReal kn, dn;
  MatNorm(K, NORM_INFINITY, &kn);
  MatAXPY(T, -1.0, K, SAME_NONZERO_PATTERN);
  MatNorm(T, NORM_INFINITY, &dn);
  EXPECT_LT(dn, 1e-12 * kn);
  // R is the identity to round-off: forces of K times 1e-16 m.
  EXPECT_LT(norm_inf(F), 1e-15 * kn);
  MatDestroy(&K);
  MatDestroy(&T);
  for (Vec *v : {&u, &F, &Fp, &Fm, &d, &Td}) VecDestroy(v);
}

TEST(AcfAssembly, InvertedElementIsReportedOnEveryRank) {
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const auto elements = fem::corotated_elements(m, kSteel, {});
  Vec u = fem::create_ghosted_vector(m), F;
  VecDuplicate(u, &F);
  // Fold the beam's far half back through itself: x -> 2 * 0.9 - x beyond x = 0.9.
  set_field(m, u, [](const Eigen::Vector3d &X) {
    return Eigen::Vector3d(X.x() > 0.9 ? 2 * (0.9 - X.x()) : 0.0, 0, 0);
  });
  const fem::CorotatedSum s = fem::assemble_corotated(m, elements, u, F, nullptr);
  EXPECT_FALSE(s.ok);
  EXPECT_NE(s.failure.find("inverted"), std::string::npos) << s.failure;
  EXPECT_NE(s.failure.find("element"), std::string::npos) << s.failure;
  VecDestroy(&F);
  VecDestroy(&u);
}
