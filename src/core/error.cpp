#include "flexopt/core/error.hpp"

#include <sstream>

namespace flexopt {

void throw_petsc_error(PetscErrorCode code, const char *call, const char *file, int line) {
  const char *text = nullptr;
  PetscErrorMessage(code, &text, nullptr);
  std::ostringstream msg;
  msg << "PETSc error " << static_cast<int>(code) << " (" << (text ? text : "unknown") << ") in "
      << call << " at " << file << ":" << line;
  throw Error(msg.str());
}

} // namespace flexopt
