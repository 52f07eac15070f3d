#pragma once
/// \file PETSc log events for flexopt's own phases, so that -log_view shows them.
#include <petsclog.h>

namespace flexopt {

/// Registers (once) and returns the PETSc log event of the given name (class "flexopt").
PetscLogEvent log_event(const char *name);

/// Scoped begin/end of a PETSc log event.
class LogScope {
public:
  explicit LogScope(const char *name) : event_(log_event(name)) {
    PetscLogEventBegin(event_, 0, 0, 0, 0);
  }
  ~LogScope() { PetscLogEventEnd(event_, 0, 0, 0, 0); }
  LogScope(const LogScope &) = delete;
  LogScope &operator=(const LogScope &) = delete;

private:
  PetscLogEvent event_;
};

} // namespace flexopt
