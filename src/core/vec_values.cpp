#include "flexopt/core/vec_values.hpp"

#include "flexopt/core/error.hpp"

#include <algorithm>

namespace flexopt {

std::vector<double> local_values(Vec v) {
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(v, &n));
  const PetscScalar *a;
  FX_PETSC(VecGetArrayRead(v, &a));
  std::vector<double> out(a, a + n);
  FX_PETSC(VecRestoreArrayRead(v, &a));
  return out;
}

void set_local_values(Vec v, const std::vector<double> &values) {
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(v, &n));
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  std::copy_n(values.begin(), std::min<std::size_t>(values.size(), static_cast<std::size_t>(n)), a);
  FX_PETSC(VecRestoreArray(v, &a));
}

} // namespace flexopt
