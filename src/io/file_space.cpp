// The free-space check before the HDF5 writers' collective writes (hdf5_check.hpp).
#include "hdf5_check.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <sys/statvfs.h>
#include <unistd.h>

namespace flexopt::io::detail {

namespace {

/// What rank 0 found: the free bytes beyond the margin (when `reason` is empty).
struct Found {
  long long available = 0;
  char reason[200] = "";
};

Found look(const std::string &file) {
  Found f;
  std::filesystem::path dir = std::filesystem::path(file).parent_path();
  if (dir.empty()) dir = ".";
  struct statvfs s {};
  if (statvfs(dir.c_str(), &s) != 0) {
    std::snprintf(f.reason, sizeof f.reason, "cannot examine its directory: %s",
                  std::strerror(errno));
  } else if (s.f_flag & ST_RDONLY) {
    std::snprintf(f.reason, sizeof f.reason, "%s", std::strerror(EROFS));
  } else {
    f.available = static_cast<long long>(s.f_bavail) * static_cast<long long>(s.f_frsize);
  }
  return f;
}

} // namespace

std::string why_unwritable(const std::string &file) {
  const Found f = look(file);
  if (f.reason[0] != '\0') return f.reason;
  std::filesystem::path dir = std::filesystem::path(file).parent_path();
  if (dir.empty()) dir = ".";
  if (access(dir.c_str(), W_OK) != 0) return std::strerror(errno);
  return "";
}

std::string unwritable_reason(MPI_Comm comm, const std::string &file) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  char text[200] = "";
  if (rank == 0) {
    const std::string why = why_unwritable(file);
    std::snprintf(text, sizeof text, "%s",
                  why.empty() ? "is the output directory writable?" : why.c_str());
  }
  MPI_Bcast(text, sizeof text, MPI_CHAR, 0, comm);
  return text;
}

void SpaceGuard::require(long long bytes) {
  // HDF5's headers and B-tree nodes for a dataset, and the page rounding of small files.
  const long long need = bytes + 64 * 1024;
  if (budget_ >= need) {
    budget_ -= need;
    return;
  }
  int rank = 0;
  MPI_Comm_rank(comm_, &rank);
  Found f;
  if (rank == 0) f = look(file_);
  MPI_Bcast(&f, sizeof f, MPI_BYTE, 0, comm_);
  if (f.reason[0] != '\0')
    throw Error("writing '" + file_ + "': " + f.reason +
                    " (the output directory must exist and be writable; --out gives another)",
                true);
  // A margin of 1 MiB plus 1 % of the free space stays untouched.
  const long long usable = f.available - (1 << 20) - f.available / 100;
  if (usable < need) {
    char msg[240];
    std::snprintf(msg, sizeof msg,
                  "%s: %lld bytes to write, %lld free on its file system (of which 1 MiB and "
                  "1 %% stay free)",
                  std::strerror(ENOSPC), bytes, f.available);
    throw Error("writing '" + file_ + "': " + msg +
                    " (free space, or give another output directory with --out)",
                true);
  }
  budget_ = std::min(usable, f.available / 8 + need) - need;
}

} // namespace flexopt::io::detail
