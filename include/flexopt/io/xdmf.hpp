#pragma once
/// \file Parallel HDF5 + XDMF output that ParaView opens directly.
///
/// One HDF5 file holds the mesh once (/mesh/geometry, /mesh/topology) and one group per step
/// (/step_K/<field>); the XDMF file describes a temporal collection of grids that all share
/// the mesh. Both files are written under temporary names and renamed when complete, so an
/// interrupted run never leaves a valid-looking result.
#include <map>
#include <memory>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::io {

/// A distributed unstructured grid as the writer needs it. Each rank contributes a
/// contiguous range of nodes and of cells.
struct GridLayout {
  MPI_Comm comm = MPI_COMM_NULL;
  long long global_nodes = 0, node_start = 0, owned_nodes = 0;
  std::vector<double> owned_coordinates; ///< 3 per owned node
  long long global_cells = 0, cell_start = 0, local_cells = 0;
  int nodes_per_cell = 0;
  std::vector<long long> cell_nodes; ///< global node numbers, XDMF/VTK node order
  std::string topology_type;         ///< XDMF name: Tetrahedron, Tetrahedron_10, Hexahedron
  /// topology_type "Mixed" (nodes_per_cell 0): cell_nodes holds each cell's XDMF type code, then
  /// its nodes; this rank's entries start at topology_start of global_topology.
  long long global_topology = 0, topology_start = 0;
};

/// "12.3 MB", "1.76 GB": a size in decimal units, as file managers show them.
std::string human_bytes(double bytes);

/// Estimated size in bytes of `<basename>.h5` plus `.xdmf` written by XdmfWriter over `layout`
/// with `frames` steps of the cell scalar fields `cell_scalars` each: the mesh once (float64
/// coordinates, int64 cell nodes), 8 bytes per cell, field and frame, HDF5's metadata per step
/// group and dataset (measured constants) and the XDMF text (counted; the mesh's grid repeated
/// in every step). Linear in `frames`. docs/output.md ("Size") gives its accuracy. Not
/// collective.
double estimate_xdmf_bytes(const GridLayout &layout, const std::string &basename,
                           const std::vector<std::string> &cell_scalars, long long frames);

class XdmfWriter {
public:
  /// Creates `<directory>/<basename>.h5` (under a temporary name) and writes the mesh. Collective.
  XdmfWriter(const GridLayout &layout, const std::string &directory, const std::string &basename);
  ~XdmfWriter();
  XdmfWriter(const XdmfWriter &) = delete;
  XdmfWriter &operator=(const XdmfWriter &) = delete;

  /// Starts a new step of the temporal collection at `time` (seconds, or any increasing label).
  void begin_step(double time);
  /// A nodal vector field: 3 values per owned node. Collective.
  void node_vector(const std::string &name, const double *owned_values);
  /// A cell scalar field: one value per local cell. Collective.
  void cell_scalar(const std::string &name, const double *local_values);
  /// A string attribute `name` = `value` on the HDF5 file's root (the fingerprint of the design
  /// a file belongs to, checked by copy_steps). Collective (the same on every rank).
  void label(const std::string &name, const std::string &value);
  /// On an error before close(), leave `<basename>.h5.tmp` in place instead of removing it: its
  /// flushed steps can be read back (copy_steps) by a run that resumes. Not collective.
  void keep_unfinished_file();
  /// Writes the HDF5 file's buffered data and metadata out, so that a run killed after this
  /// leaves the steps written so far readable in `<basename>.h5.tmp` (copy_steps). Collective.
  void flush();
  /// What copy_steps carried over.
  struct Copied {
    int steps = 0;         ///< steps appended
    double last_time = -1; ///< the last one's time (-1: none)
    std::string problem;   ///< why it stopped before `before`, or "" (read to the end)
  };
  /// Appends, in order, the steps of `path` (an HDF5 file of an XdmfWriter over the same layout:
  /// a complete one, or the `.tmp` of a run that was killed) whose time is below `before`, with
  /// their cell scalar fields `names`. Stops at the first step that is missing a field, a time or
  /// its cells' count (the step a killed run was writing), and says why in `problem`. Rank 0
  /// reads the file with HDF5's serial driver, its error printing off, and sends each rank its
  /// cells: a damaged file is a `problem`, never a hang. Collective.
  /// With `labels`, a file whose root lacks one of them or holds another value is not read (its
  /// `problem` names the label).
  Copied copy_steps(const std::string &path, double before, const std::vector<std::string> &names,
                    const std::map<std::string, std::string> &labels = {});
  /// Closes the HDF5 file, writes the XDMF file, renames both to their final names. Collective.
  /// Returns the path of the XDMF file.
  std::string close();

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

} // namespace flexopt::io
