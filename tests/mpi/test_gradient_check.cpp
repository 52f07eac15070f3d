// The gradient check as a library part (optimize::check_gradient, docs/theory.md section 5,
// "Gradient checks"), the one `flexopt check-gradient` runs:
//  - on the compact block of tests/gradient/block with the default solvers (CG + GAMG from zero to
//    1e-12, the Helmholtz filter): the Taylor orders of the compliance and the displacement are 2
//    (checked >= 1.95), the volume fraction is linear, and the central differences agree with
//    the adjoint gradient to 1e-6 (measured 3e-9 with MUMPS, docs/testing.md);
//  - on the same problem with one response's gradient made wrong by 1 % (a wrapper): the check
//    must see it — an order near 1 above the noise floor and a disagreement near 1e-2 — so
//    that a passing check means something.
#include "flexopt/io/case.hpp"
#include "flexopt/optimize/gradient_check.hpp"
#include "flexopt/optimize/topology_problem.hpp"

#include <gtest/gtest.h>

using namespace flexopt;

namespace {

std::unique_ptr<optimize::TopologyProblem> block_problem() {
  const io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/block");
  auto p = optimize::TopologyProblem::create(PETSC_COMM_WORLD, io::topology_settings(c));
  EXPECT_TRUE(p->solve_to_round_off().empty());
  return p;
}

/// A design problem whose constraint 1 (the displacement) gradient is 1.01 times the true one.
class WrongGradient : public optimize::DesignProblem {
public:
  explicit WrongGradient(optimize::DesignProblem &p) : p_(p) {}
  optimize::Design &design() override { return p_.design(); }
  const optimize::Design &design() const override { return p_.design(); }
  const std::vector<std::string> &response_names() const override { return p_.response_names(); }
  void evaluate(Vec x, bool gradients, optimize::Evaluation &out) override {
    p_.evaluate(x, gradients, out);
    if (gradients) VecScale(out.gradient(2), 1.01);
  }
  void describe(io::Json &s) const override { p_.describe(s); }
  std::vector<optimize::Timing> timings() const override { return p_.timings(); }
  long long dofs() const override { return p_.dofs(); }
  double noise_floor() const override { return p_.noise_floor(); }
  std::vector<std::string> solve_to_round_off() override { return p_.solve_to_round_off(); }
  bool set_random_start(unsigned long seed) override { return p_.set_random_start(seed); }

private:
  optimize::DesignProblem &p_;
};

} // namespace

TEST(GradientCheck, AcceptsTheAdjointGradientOfTheBlock) {
  auto problem = block_problem();
  Vec x0 = problem->create_design_vector();
  problem->initial_design(x0);
  optimize::Evaluation base;
  const auto r = optimize::check_gradient(*problem, x0, {}, base);
  // objective: compliance, constraint 0: volume fraction, constraint 1: corner displacement
  ASSERT_EQ(r.min_order.size(), 3u);
  EXPECT_GE(r.min_order[0], 1.95);
  EXPECT_TRUE(r.linear[1]);
  EXPECT_GE(r.min_order[2], 1.95);
  EXPECT_LE(r.max_rel_err, 1e-6);
  EXPECT_TRUE(r.noise_measured); // CG + GAMG: a start to perturb
  EXPECT_FALSE(r.noise_above_round_off);
  VecDestroy(&x0);
}

TEST(GradientCheck, FindsAGradientOnePercentOff) {
  auto problem = block_problem();
  WrongGradient wrong(*problem);
  Vec x0 = problem->create_design_vector();
  problem->initial_design(x0);
  optimize::Evaluation base;
  const auto r = optimize::check_gradient(wrong, x0, {}, base);
  // The remainder of a gradient off by e d falls as h (order 1) once h e |g.d| dominates.
  EXPECT_LT(r.min_order[2], 1.5);
  EXPECT_GE(r.min_order[0], 1.95); // the other responses stay right
  EXPECT_GT(r.max_rel_err, 5e-3);
  EXPECT_GT(r.max_rel_err_beyond_uncertainty, 5e-3);
  VecDestroy(&x0);
}
