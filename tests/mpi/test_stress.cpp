// Stress responses of static designs against analytic stresses (docs/theory.md 5.1): a bar in
// tension (every element at F / A) with the aggregates' exact values for equal samples, and a
// cantilever's peak bending stress against beam theory. Solid designs (initial 1: eta = 1, SIMP
// factor 1), so the relaxed stress is the element's own.
#include "flexopt/io/case.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <cmath>
#include <gtest/gtest.h>

namespace {

using flexopt::optimize::Evaluation;
using flexopt::optimize::TopologyProblem;

std::unique_ptr<TopologyProblem> solid_design(const std::string &dir, Evaluation &e) {
  const flexopt::io::Case c =
      flexopt::io::load_case(std::string(FLEXOPT_SOURCE_DIR) + "/tests/static/" + dir);
  auto p = TopologyProblem::create(PETSC_COMM_WORLD, flexopt::io::topology_settings(c));
  Vec x = p->create_design_vector();
  p->initial_design(x);
  p->evaluate(x, false, e);
  VecDestroy(&x);
  return p;
}

TEST(StressResponse, BarInTensionAndTheAggregatesOfEqualSamples) {
  // The solve to round-off (the case's `solver:` is the app's to apply, not the problem's).
  PetscOptionsSetValue(nullptr, "-ksp_rtol", "1e-14");
  Evaluation e;
  auto p = solid_design("stress_bar", e);
  PetscOptionsClearValue(nullptr, "-ksp_rtol");
  const double sigma = 100.0 / 4e-4; // F / A
  const auto *pnorm = p->stress_response(0);
  const auto *ks = p->stress_response(1);
  ASSERT_TRUE(pnorm && ks);
  const double n = static_cast<double>(pnorm->global_elements());
  // Every element reproduces the linear field: the peak is F / A to round-off (1e-9: the
  // strain of a displacement solved to 1e-14, differenced over an element 50 times smaller than
  // the bar).
  EXPECT_NEAR(pnorm->aggregate().peak(), sigma, 1e-9 * sigma);
  // N equal samples: (N s^8)^(1/8) = N^(1/8) s; KS = s + s_ref ln(N) / k (s_ref = max = 1e6).
  EXPECT_NEAR(e.objective, std::pow(n, 1.0 / 8) * sigma, 1e-9 * sigma);
  EXPECT_NEAR(e.constraints[0], sigma + 1e6 * std::log(n) / 20, 1e-9 * sigma);
  // Adaptive normalization (Le et al. 2010): c = 1 at the first evaluation, then
  // c <- (M / R + c) / 2 each iteration, which for equal samples tends to N^(-1/4).
  auto *adaptive = p->stress_response(2);
  EXPECT_NEAR(e.constraints[1], std::pow(n, 0.25) * sigma, 1e-9 * sigma);
  double c = 1;
  for (int k = 0; k < 3; ++k) {
    p->end_iteration();
    c = 0.5 * std::pow(n, -0.25) + 0.5 * c;
    EXPECT_NEAR(adaptive->scale(), c, 1e-9);
  }
}

TEST(StressResponse, CantileverPeakAgainstBeamTheory) {
  Evaluation e;
  auto p = solid_design("stress_cantilever", e);
  const auto *s = p->stress_response(0);
  ASSERT_TRUE(s);
  // The peak element's centroid (x, z), from the rank that holds it.
  const auto &m = p->mesh();
  double xz[2] = {0, 0};
  for (PetscInt el = 0; el < m.local_elements(); ++el)
    if (static_cast<long long>(m.element_tags[static_cast<std::size_t>(el)]) ==
        s->aggregate().peak_tag()) {
      const auto X = m.element_coordinates(el);
      xz[0] = X.col(0).mean();
      xz[1] = X.col(2).mean();
    }
  MPI_Allreduce(MPI_IN_PLACE, xz, 2, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
  const double F = 10, L = 1, b = 0.02, I = b * b * b * b / 12;
  const double sxx = F * (L - xz[0]) * xz[1] / I;
  const double txz = F * (b * b / 4 - xz[1] * xz[1]) / (2 * I);
  const double beam = std::sqrt(sxx * sxx + 3 * txz * txz);
  // At the root: a 3D clamp against plane sections, Tet10 at h = 4 mm. The shear that the clamp
  // stops from warping the root face is tau / sigma ~ b / L = 2 % of the bending stress, and
  // acts on part of it only; the element stress at the centroid carries the discretization
  // error of the gradient, O(h^2). Measured 0.26 % (1 and 2 ranks); 1 % holds both causes.
  EXPECT_LT(xz[0], 0.01); // the peak is at the root
  EXPECT_GT(std::abs(xz[1]), 0.25 * b);
  EXPECT_NEAR(s->aggregate().peak(), beam, 0.01 * beam);
}

} // namespace
