#pragma once
/// \file The shared frame of the benchmark drivers: PETSc and MPI up for the run, and every
/// error reported once (by rank 0 when the communicator is up) with a non-zero exit.
#include "flexopt/core/context.hpp"

#include <cstdio>
#include <exception>
#include <petscsys.h>

namespace flexopt::bench {

/// Runs `body` inside a Context built from (argc, argv); returns the process's exit status.
template <class Body> int run_bench(int &argc, char **&argv, const char *name, Body &&body) {
  int status = 0;
  try {
    Context ctx(&argc, &argv, nullptr);
    try {
      body();
    } catch (const std::exception &e) {
      if (comm_rank(PETSC_COMM_WORLD) == 0) std::fprintf(stderr, "%s: %s\n", name, e.what());
      status = 1;
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "%s: %s\n", name, e.what());
    status = 1;
  }
  return status;
}

} // namespace flexopt::bench
