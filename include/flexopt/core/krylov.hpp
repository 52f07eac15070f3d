#pragma once
/// \file What `check-gradient` needs of an iterative (Krylov) solver: solves to round-off and
/// starts that can be perturbed, so that an evaluation's noise can be measured
/// (docs/theory.md section 5, "Checking a gradient"; docs/solvers.md, "Warm start").
#include <petscksp.h>
#include <string>

namespace flexopt {

/// Whether `ksp` solves directly (KSPPREONLY: a factorization and its triangular solves).
bool is_direct(KSP ksp);

/// Sets the relative tolerance of the iterative solver `ksp` to `rtol` (and its iteration limit
/// to at least `max_it`), unless the options database sets -<prefix>ksp_rtol for it (the case's
/// `solver:` string or the command line): the user's own tolerance is kept. Returns what then
/// still limits the solves' accuracy, in words naming `what` and the option ("" when nothing
/// does: a direct solver, or the tolerance tightened). Collective.
std::string tighten_krylov(KSP ksp, double rtol, PetscInt max_it, const std::string &what);

/// x := uniform random values in [-scale, scale] drawn with `seed` (the same seed gives the same
/// vector on the same layout). Collective.
void fill_random(Vec x, unsigned long seed, double scale);

} // namespace flexopt
