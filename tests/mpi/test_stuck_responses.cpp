// optimize::stuck_responses (docs/theory.md section 5, "Responses that cannot move"): the
// sentences optimize and check-gradient print before a response misleads a design. On a stand-in
// problem with four responses and their gradients over 3 design variables per rank:
//  - a value of 1 with gradient 1e-3: nothing to say;
//  - a value of 0.5 with a zero gradient: "does not depend on the design";
//  - a value of 1e-30 below the response's round-off level 1e-24, with gradient 1e-3: "below its
//    round-off level";
//  - a value of 1e-20 above that level, with gradient 1e-3: nothing to say.
#include "flexopt/core/error.hpp"
#include "flexopt/optimize/design_problem.hpp"

#include <gtest/gtest.h>
#include <stdexcept>

using namespace flexopt;

namespace {

class StandIn : public optimize::DesignProblem {
public:
  optimize::Design &design() override { throw std::logic_error("no design"); }
  const optimize::Design &design() const override { throw std::logic_error("no design"); }
  const std::vector<std::string> &response_names() const override { return names_; }
  void evaluate(Vec, bool, optimize::Evaluation &) override {}
  void describe(io::Json &) const override {}
  std::vector<optimize::Timing> timings() const override { return {}; }
  long long dofs() const override { return 0; }
  double noise_floor() const override { return 1e-14; }
  std::vector<std::string> solve_to_round_off() override { return {}; }
  double round_off_level(std::size_t i) const override { return i >= 2 ? 1e-24 : 0; }

private:
  std::vector<std::string> names_{"objective:a", "constraint0:b", "constraint1:c", "constraint2:d"};
};

Vec filled(double value) {
  Vec v;
  FX_PETSC(VecCreateMPI(PETSC_COMM_WORLD, 3, PETSC_DECIDE, &v));
  FX_PETSC(VecSet(v, value));
  return v;
}

} // namespace

TEST(StuckResponses, NamesTheResponsesThatCannotMove) {
  StandIn p;
  optimize::Evaluation e;
  e.objective = 1.0;
  e.d_objective = filled(1e-3);
  e.constraints = {0.5, 1e-30, 1e-20};
  e.d_constraints = {filled(0.0), filled(1e-3), filled(1e-3)};
  const std::vector<std::string> w = optimize::stuck_responses(p, e);
  ASSERT_EQ(w.size(), 2u);
  EXPECT_NE(w[0].find("constraint0:b"), std::string::npos);
  EXPECT_NE(w[0].find("does not depend on the design"), std::string::npos);
  EXPECT_NE(w[1].find("constraint1:c"), std::string::npos);
  EXPECT_NE(w[1].find("below its round-off level"), std::string::npos);
}
