#pragma once
/// \file Errors: one exception type carrying a user-facing message.
///
/// flexopt code throws `flexopt::Error` at module boundaries. `main` turns it into one clear
/// message and a non-zero exit on every rank. An error is *collective* when every rank of the
/// communicator is known to throw it (e.g. a case-file error found by every rank); otherwise
/// `main` aborts the communicator so that no rank is left waiting in a collective call.
#include <petscsys.h>
#include <stdexcept>
#include <string>

namespace flexopt {

class Error : public std::runtime_error {
public:
  /// \param message   complete, user-facing text (names the file, key or step)
  /// \param collective true if every rank raises the same error at the same point
  explicit Error(const std::string &message, bool collective = false)
      : std::runtime_error(message), collective_(collective) {}
  bool collective() const { return collective_; }

private:
  bool collective_;
};

/// `message` fit for a terminal: bytes that are not valid UTF-8 (a mutated or binary file's
/// text quoted in a message) and control characters other than newline and tab become '?'.
std::string printable(const std::string &message);

/// Reports an error that only this rank has detected and ends the whole job at once
/// (MPI_Abort, exit status 1 on every rank). It does not throw: unwinding the stack would run
/// destructors that make collective calls (closing a parallel HDF5 file, destroying PETSc
/// objects) while the other ranks wait elsewhere, which deadlocks.
[[noreturn]] void abort_local(const std::string &message);

/// A PETSc/SLEPc call failed (PETSc has already printed its trace): abort_local with the
/// call, file and line. Whether the other ranks failed too is unknown, so this never throws.
[[noreturn]] void throw_petsc_error(PetscErrorCode code, const char *call, const char *file,
                                    int line);

} // namespace flexopt

/// Wrap a PETSc or SLEPc call made from C++ code: a non-zero code ends the job at once on this
/// rank (throw_petsc_error, abort_local: a message naming the call, file and line, MPI_Abort).
#define FX_PETSC(call)                                                                             \
  do {                                                                                             \
    PetscErrorCode fx_ierr_ = (call);                                                              \
    if (PetscUnlikely(fx_ierr_))                                                                   \
      ::flexopt::throw_petsc_error(fx_ierr_, #call, __FILE__, __LINE__);                           \
  } while (0)
