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

std::string printable(const std::string &message) {
  std::string out;
  out.reserve(message.size());
  const auto *p = reinterpret_cast<const unsigned char *>(message.data());
  const std::size_t n = message.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = p[i];
    std::size_t len = c < 0x80           ? 1
                      : (c >> 5) == 0x6  ? 2
                      : (c >> 4) == 0xE  ? 3
                      : (c >> 3) == 0x1E ? 4
                                         : 0;
    bool ok = len > 0 && i + len <= n && !(len == 2 && c < 0xC2);
    for (std::size_t k = 1; ok && k < len; ++k) ok = (p[i + k] & 0xC0) == 0x80;
    if (!ok) {
      out += '?';
      ++i;
    } else if (len == 1 && (c < 0x20 || c == 0x7F) && c != '\n' && c != '\t') {
      out += '?';
      ++i;
    } else {
      out.append(message, i, len);
      i += len;
    }
  }
  return out;
}

void abort_local(const std::string &message) {
  int rank = 0, initialized = 0;
  MPI_Initialized(&initialized);
  if (initialized) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  std::fprintf(stderr, "flexopt: error on rank %d: %s\n", rank, printable(message).c_str());
  std::fflush(stderr);
  if (initialized) MPI_Abort(MPI_COMM_WORLD, 1);
  std::_Exit(1);
}

} // namespace flexopt
