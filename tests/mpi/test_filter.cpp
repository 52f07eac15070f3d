// Helmholtz filter: constants are preserved exactly, the transpose is exact (dot-product
// test), and a cosine density along the beam is damped by the PDE's factor 1 / (1 + r^2 k^2).
#include "flexopt/core/context.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/helmholtz_filter.hpp"

#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>
#include <random>

using namespace flexopt;

namespace {

mesh::DistributedMesh load_beam(const char *geometry, double size, int order) {
  mesh::MeshData data;
  const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/" + geometry;
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    data = mesh::read_gmsh(geo, mesh::MeshOptions{size, order});
  });
  return mesh::distribute_mesh(PETSC_COMM_WORLD,
                               comm_rank(PETSC_COMM_WORLD) == 0 ? &data : nullptr);
}

/// Tight solver tolerance: the filter is exact up to the linear solve; rtol 1e-13 with a
/// condition number of A = r^2 K + M below 1e3 bounds the error by about 1e-10.
void tight_filter_solver() {
  PetscOptionsSetValue(nullptr, "-filter_ksp_rtol", "1e-13");
}

struct FilterCase {
  const char *geometry;
  double size;
  int order;
  const char *name;
};

class Filter : public ::testing::TestWithParam<FilterCase> {};

/// Fills an element vector with values of f(element centroid).
template <class F> void fill(const mesh::DistributedMesh &m, Vec v, F f) {
  PetscScalar *a;
  VecGetArray(v, &a);
  const int nc = fem::corner_nodes(m.type);
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const fem::ElementCoords X = m.element_coordinates(e);
    Eigen::Vector3d c = X.topRows(nc).colwise().mean().transpose();
    a[e] = f(c);
  }
  VecRestoreArray(v, &a);
}

} // namespace

TEST_P(Filter, PreservesConstants) {
  tight_filter_solver();
  auto m = load_beam(GetParam().geometry, GetParam().size, GetParam().order);
  auto filter = optimize::HelmholtzFilter::create(m, 0.03);
  Vec rho = filter->create_element_vector(), out;
  VecDuplicate(rho, &out);
  VecSet(rho, 0.37);
  filter->apply(rho, out);
  VecShift(out, -0.37);
  PetscReal err;
  VecNorm(out, NORM_INFINITY, &err);
  EXPECT_LT(err, 1e-10 * 0.37);
  VecDestroy(&rho);
  VecDestroy(&out);
}

TEST_P(Filter, TransposeIsExact) {
  tight_filter_solver();
  auto m = load_beam(GetParam().geometry, GetParam().size, GetParam().order);
  auto filter = optimize::HelmholtzFilter::create(m, 0.03);
  Vec x = filter->create_element_vector(), y, Fx, FTy;
  VecDuplicate(x, &y);
  VecDuplicate(x, &Fx);
  VecDuplicate(x, &FTy);
  std::mt19937 gen(1234 + comm_rank(m.comm));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  fill(m, x, [&](const Eigen::Vector3d &) { return u(gen); });
  fill(m, y, [&](const Eigen::Vector3d &) { return u(gen) - 0.5; });
  filter->apply(x, Fx);
  filter->apply_transpose(y, FTy);
  PetscScalar a, b;
  VecDot(Fx, y, &a);
  VecDot(x, FTy, &b);
  EXPECT_NEAR(a, b, 1e-10 * std::abs(a)) << "<F x, y> = " << a << ", <x, F^T y> = " << b;
  VecDestroy(&x);
  VecDestroy(&y);
  VecDestroy(&Fx);
  VecDestroy(&FTy);
}

INSTANTIATE_TEST_SUITE_P(Meshes, Filter,
                         ::testing::Values(FilterCase{"beam.geo", 0.02, 1, "Tet4"},
                                           FilterCase{"beam.geo", 0.03, 2, "Tet10"},
                                           FilterCase{"beam_hex.geo", 0.0, 1, "Hex8"}),
                         [](const auto &info) { return std::string(info.param.name); });

// rho = cos(k x) along the beam (k = 4 pi / L, zero normal derivative at both ends) solves
// the filter PDE with phi = cos(k x) / (1 + r^2 k^2). On a mesh with h = 0.01 (k h = 0.13)
// the P1 discretization and the piecewise-constant input differ from the continuous
// amplitude by O((k h)^2 / 12) ~ 0.1 % (measured: 0.716175 against 0.716957, 0.11 %); the test
// allows 1 %. Without the damping the amplitude would be off by 40 %.
TEST(FilterPhysics, DampsACosineByTheHelmholtzFactor) {
  tight_filter_solver();
  auto m = load_beam("beam.geo", 0.01, 1);
  const double r = 0.05, k = 4 * M_PI;
  auto filter = optimize::HelmholtzFilter::create(m, r);
  Vec rho = filter->create_element_vector(), out;
  VecDuplicate(rho, &out);
  fill(m, rho, [&](const Eigen::Vector3d &c) { return std::cos(k * c[0]); });
  filter->apply(rho, out);
  // Least-squares amplitude of out against cos(k x_e).
  Vec basis;
  VecDuplicate(rho, &basis);
  VecCopy(rho, basis);
  PetscScalar num, den;
  VecDot(out, basis, &num);
  VecDot(basis, basis, &den);
  const double amplitude = num / den, expected = 1.0 / (1.0 + r * r * k * k);
  EXPECT_NEAR(amplitude, expected, 0.01 * expected)
      << "amplitude " << amplitude << " expected " << expected;
  if (comm_rank(m.comm) == 0)
    std::printf("filtered cosine amplitude %.6f, continuous %.6f\n", amplitude, expected);
  VecDestroy(&rho);
  VecDestroy(&out);
  VecDestroy(&basis);
}
