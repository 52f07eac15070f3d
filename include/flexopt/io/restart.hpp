#pragma once
/// \file Restart files: per-element fields keyed by Gmsh element tag (so that a run may be
/// resumed on any number of ranks) plus replicated arrays, in one HDF5 file written in
/// parallel under a temporary name and renamed when complete.
#include <cstdint>
#include <map>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::io {

struct RestartData {
  std::vector<std::uint64_t> tags;                   ///< this rank's elements
  std::map<std::string, std::vector<double>> fields; ///< aligned with tags
  std::map<std::string, std::vector<double>> arrays; ///< the same on every rank
  /// A second keyed set, optional: values per degree of freedom of the solvers' state (a warm
  /// start; DesignProblem::solver_state), each keyed by its node's position and component
  /// (optimize::dof_keys), so that a run on another rank count finds them.
  std::vector<std::uint64_t> dof_keys;
  std::map<std::string, std::vector<double>> dof_fields; ///< aligned with dof_keys
  /// Short texts, the same on every rank (attributes of the file's root): the fingerprint of
  /// the design the file belongs to (optimize::design_fingerprint).
  std::map<std::string, std::string> labels;
};

/// Writes `data` to `path` atomically (path.tmp, then renamed). Collective.
void write_restart(MPI_Comm comm, const std::string &path, const RestartData &data);

/// Reads `path`; the fields are returned for `tags` (this rank's elements, in that order), and
/// the dof fields for `dof_keys` when the file has every one of them (else none: the state
/// belongs to another mesh, or the file has none). Throws a collective flexopt::Error naming
/// the file if it is missing, unreadable, or lacks one of the tags. Collective.
RestartData read_restart(MPI_Comm comm, const std::string &path,
                         const std::vector<std::uint64_t> &tags,
                         const std::vector<std::uint64_t> &dof_keys = {});

/// The labels of `path` alone (before its fields are matched to this run's elements). Throws
/// as read_restart for a missing or unreadable file. Collective.
std::map<std::string, std::string> read_restart_labels(MPI_Comm comm, const std::string &path);

} // namespace flexopt::io
