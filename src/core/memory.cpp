// Memory bounds checked before a large allocation (core/memory.hpp).
#include "flexopt/core/memory.hpp"

#include <cstdio>
#include <cstdlib>

namespace flexopt {

namespace {

/// MemAvailable of this machine [bytes], or FLEXOPT_MEMORY_AVAILABLE; -1 where neither is read.
long long memory_available() {
  if (const char *given = std::getenv("FLEXOPT_MEMORY_AVAILABLE")) return std::atoll(given);
  std::FILE *f = std::fopen("/proc/meminfo", "r");
  if (!f) return -1;
  char line[256];
  long long kib = -1;
  while (std::fgets(line, sizeof line, f))
    if (std::sscanf(line, "MemAvailable: %lld kB", &kib) == 1) break;
  std::fclose(f);
  return kib < 0 ? -1 : kib * 1024;
}

} // namespace

NodeMemory node_memory(MPI_Comm comm, long long bytes) {
  MPI_Comm node;
  MPI_Comm_split_type(comm, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
  NodeMemory mine;
  MPI_Allreduce(&bytes, &mine.bytes, 1, MPI_LONG_LONG, MPI_SUM, node);
  int node_rank = 0;
  MPI_Comm_rank(node, &node_rank);
  if (node_rank == 0) mine.available = memory_available();
  MPI_Bcast(&mine.available, 1, MPI_LONG_LONG, 0, node);
  MPI_Comm_free(&node);
  // The node with the largest share of its memory taken (unknown memory counts as none taken).
  struct {
    double ratio;
    int rank;
  } local{mine.available > 0 ? static_cast<double>(mine.bytes) / static_cast<double>(mine.available)
                             : 0.0,
          0},
      worst{};
  MPI_Comm_rank(comm, &local.rank);
  MPI_Allreduce(&local, &worst, 1, MPI_DOUBLE_INT, MPI_MAXLOC, comm);
  long long pair[2] = {mine.bytes, mine.available};
  MPI_Bcast(pair, 2, MPI_LONG_LONG, worst.rank, comm);
  return NodeMemory{pair[0], pair[1]};
}

} // namespace flexopt
