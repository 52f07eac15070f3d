// What an evaluation says of its responses before they guide a design (issue 42).
#include "flexopt/optimize/design_problem.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>
#include <cstdio>

namespace flexopt::optimize {

std::vector<std::string> stuck_responses(const DesignProblem &p, const Evaluation &e) {
  std::vector<std::string> out;
  const auto &names = p.response_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    PetscReal largest = 0;
    FX_PETSC(VecNorm(e.gradient(i), NORM_INFINITY, &largest));
    const double value = e.value(i), level = p.round_off_level(i);
    char buf[400];
    if (largest <= 1e-12 * std::abs(value)) {
      // Even all densities changed by 1 would change it by a relative n 1e-12: round-off.
      std::snprintf(buf, sizeof buf,
                    "response %s (%.3g) does not depend on the design: its gradient is at most "
                    "%.3g on every design element (1e-12 of its value, or zero): a kinematic "
                    "response of a mechanism whose motion the drivers fix, or a body the design "
                    "does not reach",
                    names[i].c_str(), value, static_cast<double>(largest));
      out.emplace_back(buf);
    } else if (std::abs(value) < level) {
      std::snprintf(buf, sizeof buf,
                    "response %s is %.3g, below its round-off level %.3g: it is zero "
                    "by construction and cannot guide the design (e.g. an elastic_displacement "
                    "sensor on an interface that defines its body's frame: move the sensor, or "
                    "set reduction.frame so that another interface defines it)",
                    names[i].c_str(), value, level);
      out.emplace_back(buf);
    }
  }
  return out;
}

} // namespace flexopt::optimize
