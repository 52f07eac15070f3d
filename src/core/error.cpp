#include "flexopt/core/error.hpp"

#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace flexopt {

void throw_petsc_error(PetscErrorCode code, const char *call, const char *file, int line) {
  const char *text = nullptr;
  PetscErrorMessage(code, &text, nullptr);
  std::ostringstream msg;
  msg << "PETSc error " << static_cast<int>(code) << " (" << (text ? text : "unknown") << ") in "
      << call << " at " << file << ":" << line;
  abort_local(msg.str());
}

void abort_local(const std::string &message) {
  int rank = 0, initialized = 0;
  MPI_Initialized(&initialized);
  if (initialized) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  std::fprintf(stderr, "flexopt: error on rank %d: %s\n", rank, message.c_str());
  std::fflush(stderr);
  if (initialized) MPI_Abort(MPI_COMM_WORLD, 1);
  std::_Exit(1);
}

} // namespace flexopt
