#pragma once
/// \file Memory bounds checked before a large allocation (issue 42): what the ranks of each
/// node would hold against what that node reports available.
#include <mpi.h>

namespace flexopt {

/// The node where `bytes` (this rank's share of an allocation) weigh most against the memory
/// available there: the sum over its ranks and its MemAvailable (/proc/meminfo; the environment
/// variable FLEXOPT_MEMORY_AVAILABLE, in bytes, stands in for it in tests).
struct NodeMemory {
  long long bytes = 0;      ///< the sum over that node's ranks
  long long available = -1; ///< its available memory [bytes]; -1: unknown
  /// Whether the bytes stay within `fraction` of the available memory (true when unknown).
  bool fits(double fraction) const {
    return available < 0 || static_cast<double>(bytes) <= fraction * static_cast<double>(available);
  }
};

/// Collective over `comm`.
NodeMemory node_memory(MPI_Comm comm, long long bytes);

} // namespace flexopt
