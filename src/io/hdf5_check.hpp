#pragma once
/// \file Checks of HDF5 return values for the io module's writers (private to src/io).
///
/// Every HDF5 call after a file exists is part of a collective sequence; a failure may be seen
/// by one rank only, so it ends the job (abort_local) instead of throwing: unwinding would run
/// collective destructors (closing the file) while the other ranks wait elsewhere.
#include "flexopt/core/error.hpp"

#include <hdf5.h>
#include <mpi.h>
#include <string>

namespace flexopt::io::detail {

inline void h5check(herr_t status, const std::string &what) {
  if (status < 0) abort_local("HDF5: " + what + " failed");
}

inline hid_t h5id(hid_t id, const std::string &what) {
  if (id < 0) abort_local("HDF5: " + what + " failed");
  return id;
}

/// Why `file` cannot be created or written, as the OS says it of its directory (missing,
/// read-only, not writable), or "" when nothing is wrong there. Not collective.
std::string why_unwritable(const std::string &file);

/// why_unwritable on rank 0, known to every rank ("is the output directory writable?" when
/// the OS finds nothing wrong). Collective.
std::string unwritable_reason(MPI_Comm comm, const std::string &file);

/// Space for the writes into one file, checked before they start (issue 42): a full disk
/// found inside a collective HDF5 write leaves the ranks in different calls (a hang), so each
/// write first asks for its bytes here. Rank 0 reads the free space of the file's file system
/// (statvfs) when the budget it last granted is spent, and every rank learns the new budget,
/// so all ranks decide alike. At most an eighth of the free space is granted at a time, so that
/// space taken by other programs is seen. Collective (every rank asks for the same bytes).
class SpaceGuard {
public:
  SpaceGuard(MPI_Comm comm, std::string file) : comm_(comm), file_(std::move(file)) {}
  /// Throws a collective flexopt::Error naming the file, the bytes and the free space (or the
  /// OS's reason the file system cannot be written) when `bytes` do not fit.
  void require(long long bytes);

private:
  MPI_Comm comm_;
  std::string file_;
  long long budget_ = 0;
};

} // namespace flexopt::io::detail
