// The dynamic adjoint of rigid design bodies (docs/theory.md section 9) against two exact facts:
//  - scale invariance: with linear mass interpolation and a linear filter, multiplying every
//    density of the pendulum's link by one factor scales its mass, first moment and inertia
//    alike and changes no motion under gravity, so every kinematic response is homogeneous of
//    degree 0 in the densities and sum_e x_e dPsi/dx_e = 0 (Euler's theorem), while the mass
//    and the volume fraction are of degree 1 (sum = the value);
//  - rank independence: the gradient on all ranks equals the gradient of the same design
//    computed on one rank, element by element (keyed by Gmsh tag);
//  - separability (docs/theory.md 9.9): two pendulums that do not interact, designed together,
//    have on each body's densities the gradient of the problem that designs that body alone.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/io/case.hpp"

#include <cmath>
#include <cstdint>
#include <gtest/gtest.h>
#include <map>

using namespace flexopt;

namespace {

/// A density in [0.3, 1] from an element tag: the same design on any rank count.
double density_of(std::size_t tag) {
  unsigned long long z = tag * 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 31)) * 0xBF58476D1CE4E5B9ULL;
  return 0.3 + 0.7 * static_cast<double>(z >> 11) / 9007199254740992.0;
}

void random_design(const optimize::DesignProblem &p, Vec x) {
  PetscScalar *a;
  VecGetArray(x, &a);
  // By Gmsh tag (a key's low 48 bits): a body's design is the same whatever the other bodies.
  const auto &keys = p.design_keys();
  for (std::size_t k = 0; k < keys.size(); ++k)
    a[k] = density_of(static_cast<std::size_t>(optimize::Design::key_tag(keys[k])));
  VecRestoreArray(x, &a);
}

const io::Case &pendulum() {
  static const io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/rigid_pendulum");
  return c;
}

} // namespace

TEST(DynamicAdjoint, RigidPendulumIsScaleInvariant) {
  auto p = adjoint::DynamicProblem::create(PETSC_COMM_WORLD, io::dynamic_settings(pendulum()), ".");
  Vec x = p->create_design_vector(), xc, xg;
  random_design(*p, x);
  VecDuplicate(x, &xc);
  VecDuplicate(x, &xg);
  optimize::Evaluation e, scaled;
  p->evaluate(x, true, e);
  VecCopy(x, xc);
  VecScale(xc, 0.6);
  p->evaluate(xc, false, scaled);
  const auto &names = p->response_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    const double value = e.value(i);
    const double value_scaled = scaled.value(i);
    PetscScalar dot = 0;
    PetscReal scale = 0;
    VecDot(x, e.gradient(i), &dot);
    VecPointwiseMult(xg, x, e.gradient(i));
    VecNorm(xg, NORM_1, &scale);
    const bool degree_one =
        names[i].find("mass") != std::string::npos || names[i].find("volume") != std::string::npos;
    if (degree_one) {
      // sum_e x_e dPsi/dx_e = Psi; Psi(0.6 x) = 0.6 Psi(x).
      EXPECT_NEAR(dot, value, 1e-12 * std::abs(value)) << names[i];
      EXPECT_NEAR(value_scaled, 0.6 * value, 1e-12 * std::abs(value)) << names[i];
    } else {
      // The motion does not change: the response to the Newton tolerance (1e-12 relative), and
      // the sum vanishes to the gradient's round-off relative to its terms (measured <= 1.3e-11).
      EXPECT_NEAR(value_scaled, value, 1e-11 * std::max(std::abs(value), 1.0)) << names[i];
      EXPECT_LE(std::abs(dot), 1e-10 * scale)
          << names[i] << ": sum x_e dPsi/dx_e = " << dot << ", sum |x_e dPsi/dx_e| = " << scale;
      EXPECT_GT(scale, 0) << names[i];
    }
    int rank = 0;
    MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
    if (rank == 0)
      std::printf("%-28s sum x dPsi/dx = % .3e  (sum |x dPsi/dx| = %.3e, value %.6g)\n",
                  names[i].c_str(), dot, scale, value);
  }
  VecDestroy(&x);
  VecDestroy(&xc);
  VecDestroy(&xg);
}

// The same invariance for an ACF design body with SIMP penalty 1 and linear mass: stiffness
// (and stiffness-proportional damping) and mass scale alike, so the motion under gravity does
// not change (up to the stiffness floor E_min / E_0 = 1e-12), the kinematic responses are of
// degree 0 and the strain energy, mass and volume fraction of degree 1 in the densities.
TEST(DynamicAdjoint, AcfPendulumIsScaleInvariant) {
  io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/acf_pendulum");
  c.design.front().penalty = 1;
  c.design.front().min_stiffness = 1e-12;
  auto p = adjoint::DynamicProblem::create(PETSC_COMM_WORLD, io::dynamic_settings(c), ".");
  Vec x = p->create_design_vector(), xg;
  random_design(*p, x);
  VecDuplicate(x, &xg);
  optimize::Evaluation e;
  p->evaluate(x, true, e);
  const auto &names = p->response_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    const double value = e.value(i);
    PetscScalar dot = 0;
    PetscReal scale = 0;
    VecDot(x, e.gradient(i), &dot);
    VecPointwiseMult(xg, x, e.gradient(i));
    VecNorm(xg, NORM_1, &scale);
    const bool degree_one = names[i].find("mass") != std::string::npos ||
                            names[i].find("volume") != std::string::npos ||
                            names[i].find("strain_energy") != std::string::npos;
    int rank = 0;
    MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
    if (rank == 0)
      std::printf("ACF %-28s sum x dPsi/dx = % .6e  (value %.6e, sum |x dPsi/dx| = %.3e)\n",
                  names[i].c_str(), dot, value, scale);
    if (degree_one)
      EXPECT_NEAR(dot, value, 1e-10 * std::abs(value)) << names[i];
    else
      EXPECT_LE(std::abs(dot), 1e-10 * scale) << names[i];
  }
  VecDestroy(&x);
  VecDestroy(&xg);
}

TEST(DynamicAdjoint, GradientDoesNotDependOnTheRankCount) {
  auto world =
      adjoint::DynamicProblem::create(PETSC_COMM_WORLD, io::dynamic_settings(pendulum()), ".");
  auto one =
      adjoint::DynamicProblem::create(PETSC_COMM_SELF, io::dynamic_settings(pendulum()), ".");
  Vec xw = world->create_design_vector(), x1 = one->create_design_vector();
  random_design(*world, xw);
  random_design(*one, x1);
  optimize::Evaluation ew, e1;
  world->evaluate(xw, true, ew);
  one->evaluate(x1, true, e1);
  std::map<std::uint64_t, std::size_t> index; // tag -> local index on one rank
  for (std::size_t k = 0; k < one->design_keys().size(); ++k) index[one->design_keys()[k]] = k;
  for (std::size_t i = 0; i < world->response_names().size(); ++i) {
    const PetscScalar *gw, *g1;
    VecGetArrayRead(ew.gradient(i), &gw);
    VecGetArrayRead(e1.gradient(i), &g1);
    double gmax = 0, diff = 0;
    for (std::size_t k = 0; k < world->design_keys().size(); ++k) {
      const double b = g1[index.at(world->design_keys()[k])];
      gmax = std::max(gmax, std::abs(b));
      diff = std::max(diff, std::abs(gw[k] - b));
    }
    VecRestoreArrayRead(ew.gradient(i), &gw);
    VecRestoreArrayRead(e1.gradient(i), &g1);
    MPI_Allreduce(MPI_IN_PLACE, &gmax, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
    MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
    EXPECT_LE(diff, 1e-9 * gmax) << world->response_names()[i];
  }
  VecDestroy(&xw);
  VecDestroy(&x1);
}

// Checkpointing (docs/theory.md section 9.4): 4 and 16 stored states, in memory and on disk,
// give the gradient of all states stored to 1e-10 (recomputed steps are re-solved to the
// forward tolerance, not along the same Newton path), with the binomial schedule's count of
// recomputed steps.
void check_checkpoints(const std::string &name) {
  io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/" + name);
  const std::string scratch = ::testing::TempDir();
  auto gradient = [&](int checkpoints, const std::string &storage, long long *recomputed) {
    c.adjoint.checkpoints = checkpoints;
    c.adjoint.storage =
        storage == "disk" ? adjoint::CheckpointStorage::Disk : adjoint::CheckpointStorage::Memory;
    auto p = adjoint::DynamicProblem::create(PETSC_COMM_WORLD, io::dynamic_settings(c), scratch);
    Vec x = p->create_design_vector();
    random_design(*p, x);
    optimize::Evaluation e;
    p->evaluate(x, true, e);
    *recomputed = p->recomputed_steps();
    std::vector<std::vector<double>> g;
    for (std::size_t i = 0; i < p->response_names().size(); ++i) {
      const PetscScalar *a;
      PetscInt n = 0;
      VecGetLocalSize(e.gradient(i), &n);
      VecGetArrayRead(e.gradient(i), &a);
      g.emplace_back(a, a + n);
      VecRestoreArrayRead(e.gradient(i), &a);
    }
    VecDestroy(&x);
    return g;
  };
  long long r_all = -1, r4 = -1, r16 = -1, r16d = -1;
  const auto all = gradient(0, "memory", &r_all);
  const auto g4 = gradient(4, "memory", &r4);
  const auto g16 = gradient(16, "memory", &r16);
  const auto g16d = gradient(16, "disk", &r16d);
  const long long steps = std::llround(c.time.end / c.time.step);
  EXPECT_EQ(r_all, 0);
  EXPECT_EQ(r4, adjoint::BinomialSchedule(steps, 3).recomputed());
  EXPECT_EQ(r16, adjoint::BinomialSchedule(steps, 15).recomputed());
  EXPECT_EQ(r16d, r16);
  for (std::size_t i = 0; i < all.size(); ++i) {
    double gmax = 0, d4 = 0, d16 = 0, disk = 0;
    for (std::size_t k = 0; k < all[i].size(); ++k) {
      gmax = std::max(gmax, std::abs(all[i][k]));
      d4 = std::max(d4, std::abs(g4[i][k] - all[i][k]));
      d16 = std::max(d16, std::abs(g16[i][k] - all[i][k]));
      disk = std::max(disk, std::abs(g16d[i][k] - g16[i][k]));
    }
    for (double *v : {&gmax, &d4, &d16, &disk})
      MPI_Allreduce(MPI_IN_PLACE, v, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
    int rank = 0;
    MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
    if (rank == 0)
      std::printf("%s response %zu: |dPsi/dx| %.3e; 4, 16 checkpoints, disk: %.1e %.1e %.1e\n",
                  name.c_str(), i, gmax, d4 / gmax, d16 / gmax, disk / gmax);
    EXPECT_GT(gmax, 0) << "response " << i;
    EXPECT_LE(d4, 1e-10 * gmax) << "response " << i;
    EXPECT_LE(d16, 1e-10 * gmax) << "response " << i;
    // The same states either way: bit for bit on one rank; on several ranks the distributed
    // solver's reductions are not bitwise repeatable from one run to the next, so the kept-matrix
    // Newton paths differ within their tolerance (measured 1.4e-12 relative on 2 ranks).
    EXPECT_LE(disk, 1e-10 * gmax) << "response " << i << ": memory and disk storage";
  }
}

TEST(DynamicAdjoint, CheckpointedSweepGivesTheSameGradient) {
  check_checkpoints("rigid_slider_crank");
}

// The same on the distributed backend: an ACF design body (the records of its distributed
// states stored in memory or in each rank's HDF5 file).
TEST(DynamicAdjoint, CheckpointedDistributedSweepGivesTheSameGradient) {
  check_checkpoints("acf_pendulum");
}

namespace {
/// Response i's gradient entries of the local design variables, by key.
std::map<std::uint64_t, double> gradient_by_key(const optimize::DesignProblem &p,
                                                const optimize::Evaluation &e, std::size_t i) {
  std::map<std::uint64_t, double> g;
  const PetscScalar *a;
  VecGetArrayRead(e.gradient(i), &a);
  for (std::size_t k = 0; k < p.design_keys().size(); ++k) g[p.design_keys()[k]] = a[k];
  VecRestoreArrayRead(e.gradient(i), &a);
  return g;
}
} // namespace

// tests/gradient/two_pendulums: an FFRF bar and an ACF link on separate pivots, every response a
// sum over both. The two-body gradient restricted to one body equals the gradient of the problem
// that designs that body alone (the other solid): to round-off, 1e-10 of the largest entry (the
// distributed sweep's direct solves of the coupled, block-diagonal system). With
// -fx_deterministic (docs/solvers.md "Reproducibility"): parallel MUMPS sums contribution blocks
// in the order their messages arrive, and once in a clean run on 2 ranks the two problems'
// rounding differed by 1.8e-13 against the usual 6.5e-16 (7e-9 of the largest entry).
TEST(DynamicAdjoint, TwoPendulumsGradientIsTheOneBodyGradients) {
  PetscOptionsSetValue(nullptr, "-fx_deterministic", "1");
  struct Clear {
    ~Clear() { PetscOptionsClearValue(nullptr, "-fx_deterministic"); }
  } clear;
  const io::Case both = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/two_pendulums");
  ASSERT_EQ(both.design.size(), 2u);
  auto evaluate = [](const io::Case &c, optimize::Evaluation &e) {
    auto p = adjoint::DynamicProblem::create(PETSC_COMM_WORLD, io::dynamic_settings(c), ".");
    Vec x = p->create_design_vector();
    random_design(*p, x);
    p->evaluate(x, true, e);
    VecDestroy(&x);
    return p;
  };
  optimize::Evaluation e2;
  const auto p2 = evaluate(both, e2);
  for (std::size_t body = 0; body < 2; ++body) {
    io::Case one = both;
    one.design = {both.design[body]};
    optimize::Evaluation e1;
    const auto p1 = evaluate(one, e1);
    for (std::size_t i = 0; i < p2->response_names().size(); ++i) {
      const auto g1 = gradient_by_key(*p1, e1, i), g2 = gradient_by_key(*p2, e2, i);
      double gmax = 0, diff = 0;
      std::size_t matched = 0;
      for (const auto &[key, value] : g1) {
        const auto it = g2.find(optimize::Design::key(body, key));
        if (it == g2.end()) continue;
        ++matched;
        gmax = std::max(gmax, std::abs(value));
        diff = std::max(diff, std::abs(it->second - value));
      }
      EXPECT_EQ(matched, g1.size()) << "the same partition of body " << body;
      MPI_Allreduce(MPI_IN_PLACE, &gmax, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
      MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
      int rank = 0;
      MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
      if (rank == 0)
        std::printf("two pendulums, body %zu, %-34s max |g| %.3e, max difference %.3e\n", body,
                    p2->response_names()[i].c_str(), gmax, diff);
      EXPECT_LE(diff, 1e-10 * gmax) << p2->response_names()[i] << ", body " << body;
    }
  }
}
