#include "flexopt/core/krylov.hpp"

#include "flexopt/core/error.hpp"

#include <cstdio>

namespace flexopt {

bool is_direct(KSP ksp) {
  PetscBool preonly = PETSC_FALSE;
  FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(ksp), KSPPREONLY, &preonly));
  return preonly == PETSC_TRUE;
}

std::string tighten_krylov(KSP ksp, double rtol, PetscInt max_it, const std::string &what) {
  if (is_direct(ksp)) return "";
  const char *prefix = nullptr;
  FX_PETSC(KSPGetOptionsPrefix(ksp, &prefix));
  const std::string p = prefix ? prefix : "";
  PetscReal given_rtol = 0, abstol = 0, dtol = 0;
  PetscInt its = 0;
  PetscBool rtol_given = PETSC_FALSE, atol_given = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetReal(nullptr, prefix, "-ksp_rtol", &given_rtol, &rtol_given));
  FX_PETSC(PetscOptionsHasName(nullptr, prefix, "-ksp_atol", &atol_given));
  FX_PETSC(KSPGetTolerances(ksp, nullptr, &abstol, &dtol, &its));
  std::string limit;
  char buf[160];
  if (rtol_given && given_rtol > rtol) {
    std::snprintf(buf, sizeof buf, "%s stop at -%sksp_rtol %g", what.c_str(), p.c_str(),
                  static_cast<double>(given_rtol));
    limit = buf;
  } else if (!rtol_given) {
    FX_PETSC(KSPSetTolerances(ksp, rtol, abstol, dtol, its > max_it ? its : max_it));
  }
  if (atol_given) {
    std::snprintf(buf, sizeof buf, "%s%s stop at -%sksp_atol %g", limit.empty() ? "" : "; ",
                  limit.empty() ? what.c_str() : "and", p.c_str(), static_cast<double>(abstol));
    limit += buf;
  }
  return limit;
}

void fill_random(Vec x, unsigned long seed, double scale) {
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(x), &comm));
  PetscRandom r;
  FX_PETSC(PetscRandomCreate(comm, &r));
  FX_PETSC(PetscRandomSetInterval(r, -scale, scale));
  FX_PETSC(PetscRandomSetSeed(r, seed));
  FX_PETSC(PetscRandomSeed(r));
  FX_PETSC(VecSetRandom(x, r));
  FX_PETSC(PetscRandomDestroy(&r));
}

} // namespace flexopt
