#pragma once
/// \file A PETSc vector's local values as a std::vector, and back.
#include <petscvec.h>
#include <vector>

namespace flexopt {

/// The values this rank holds of `v` (a ghosted vector: its owned part). Not collective.
std::vector<double> local_values(Vec v);

/// Sets this rank's values of `v` from `values` (at most its local size). Not collective.
void set_local_values(Vec v, const std::vector<double> &values);

} // namespace flexopt
