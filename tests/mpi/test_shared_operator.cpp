// fem::StaticProblem::create_sharing: the load cases of equivalent static loads (docs/theory.md
// 14.7) on one stiffness matrix and solver. On the block of tests/gradient/block, a second load
// case (another traction, a body force) sharing the first's operator gives the displacement and
// compliance of the same load case with an operator of its own, to the solves' round-off:
//  - at a design where the owner assembled K and the sharer found it assembled (no second
//    assembly);
//  - after a design change on rank 0's elements only: every rank re-assembles (the decision is
//    collective; a rank that skipped alone would hang the assembly), and the two still agree;
// and a load case with other supports gets an operator of its own.
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/io/case.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <mpi.h>

using namespace flexopt;

namespace {

double relative_difference(Vec a, Vec b) {
  Vec d;
  VecDuplicate(a, &d);
  VecWAXPY(d, -1.0, b, a);
  PetscReal nd = 0, na = 0;
  VecNorm(d, NORM_2, &nd);
  VecNorm(a, NORM_2, &na);
  VecDestroy(&d);
  return nd / na;
}

} // namespace

TEST(SharedOperator, EveryLoadCaseAsWithItsOwnOperator) {
  const io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/block");
  const fem::StaticSettings first = io::topology_settings(c).problem;
  fem::StaticSettings second = first;
  second.loads.tractions.front().value = {0.004, 0.007, 0.002};
  second.loads.gravity = std::array<double, 3>{0.0, -0.002, 0.001};
  auto owner = fem::StaticProblem::create(PETSC_COMM_WORLD, first);
  auto sharer = fem::StaticProblem::create_sharing(*owner, second);
  auto own = fem::StaticProblem::create(PETSC_COMM_WORLD, second);
  EXPECT_EQ(sharer->stiffness(), owner->stiffness());
  EXPECT_NE(own->stiffness(), owner->stiffness());
  for (auto *p : {owner.get(), sharer.get(), own.get()}) EXPECT_EQ(p->solve_to_round_off(), "");

  const PetscInt n = owner->mesh().local_elements();
  std::vector<double> factor(static_cast<std::size_t>(n));
  for (PetscInt e = 0; e < n; ++e)
    factor[static_cast<std::size_t>(e)] = 0.2 + 0.8 * std::abs(std::sin(1.3 * e + 0.4));
  int rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  for (int round = 0; round < 2; ++round) {
    if (round == 1 && rank == 0) factor[0] *= 0.5; // a change on rank 0's elements only
    for (auto *p : {owner.get(), sharer.get(), own.get()}) {
      p->assemble_operator(factor);
      p->set_body_load_factors(factor);
      p->solve();
    }
    const double du = relative_difference(sharer->displacement(), own->displacement());
    const double dc = std::abs(sharer->compliance() - own->compliance()) / own->compliance();
    EXPECT_LT(du, 1e-9) << "round " << round;
    EXPECT_LT(dc, 1e-10) << "round " << round;
    // The two load cases differ: the shared operator did not hand the owner's load over.
    EXPECT_GT(relative_difference(sharer->displacement(), owner->displacement()), 0.1);
  }

  fem::StaticSettings other = second;
  other.loads.supports.front().fix = {true, true, false};
  auto separate = fem::StaticProblem::create_sharing(*owner, other);
  EXPECT_NE(separate->stiffness(), owner->stiffness());
}
