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
  // A stress peak outside the design region: the design changes it only through the loads (a
  // support, a joint's rigid interface or a concentrated load makes it a singularity of the
  // model). Collective.
  const auto stress = p.design_stress();
  if (stress.empty()) return out;
  for (const DesignProblem::DesignStress &st : stress) {
    const std::size_t i = st.response;
    const StressAggregate *a = st.aggregate;
    const DesignField &f = p.design().field(st.field);
    const mesh::DistributedMesh &m = f.mesh();
    int inside = 0;
    for (PetscInt e : f.design_elements())
      if (static_cast<long long>(m.element_tags[static_cast<std::size_t>(e)]) == a->peak_tag())
        inside = 1;
    MPI_Allreduce(MPI_IN_PLACE, &inside, 1, MPI_INT, MPI_LOR, m.comm);
    if (inside) continue;
    char buf[600];
    std::snprintf(buf, sizeof buf,
                  "response %s: its true peak (%.4g Pa at element %lld) lies outside the design "
                  "region '%s', where the design changes the stress only through the loads; a "
                  "stress at a support, at a joint's rigid interface or under a concentrated load "
                  "is a singularity of the model, which a limit cannot bound: give the response "
                  "region: %s to take the stress where the design acts",
                  names[i].c_str(), a->peak(), a->peak_tag(), f.settings().region.c_str(),
                  f.settings().region.c_str());
    out.emplace_back(buf);
  }
  return out;
}

} // namespace flexopt::optimize
