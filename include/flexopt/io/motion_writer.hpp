#pragma once
/// \file Parallel HDF5 + XDMF output of a moving mechanism that ParaView plays directly.
///
/// Several bodies, each with its own distributed mesh (any of the GridLayout topology types),
/// move through time. One HDF5 file `<basename>.h5` holds, per body, the reference mesh once
/// (/<body>/reference_geometry, /<body>/topology) and one group per output step with the
/// current node coordinates and optional fields (/<body>/step_K/positions,
/// /<body>/step_K/<field>); /time holds the step times. The XDMF file `<basename>.xdmf` is a
/// temporal collection whose every step is a spatial collection of one Uniform grid per body
/// (Name = body name) whose Geometry is that step's positions: ParaView shows the bodies
/// moving without a Warp filter. Both files are written under temporary names and renamed when
/// complete, so an interrupted run never leaves a valid-looking result. docs/output.md
/// describes the layout.
#include "flexopt/io/xdmf.hpp"

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace flexopt::io {

/// One body of the mechanism: its name and its reference (undeformed, initial placement) mesh.
struct MotionBody {
  /// HDF5 group and XDMF grid (ParaView block) name: non-empty, no '/', not "." or "..", not
  /// "time", unique among the bodies.
  std::string name;
  /// The reference mesh. Every body's `comm` must be the same communicator (the writer's).
  /// A rank may own no nodes and no cells of a body (a small body kept on one rank).
  GridLayout layout;
};

/// Estimated size in bytes of `motion.h5` plus `motion.xdmf` after `frames` steps in which
/// body b writes its positions, the node vector fields named in `node_vectors[b]` and the cell
/// scalar fields named in `cell_scalars[b]` (missing entries: none): the reference meshes once
/// (float64 coordinates, int64 cell nodes), 24 bytes per node and 8 per cell, field and frame,
/// and per frame and body the HDF5 group and dataset headers (measured constants) and the XDMF
/// text (counted). Linear in `frames`. docs/output.md ("Size") gives its accuracy. Not
/// collective.
double estimate_motion_bytes(const std::vector<MotionBody> &bodies,
                             const std::vector<std::vector<std::string>> &node_vectors,
                             long long frames,
                             const std::vector<std::vector<std::string>> &cell_scalars = {});

class MotionWriter {
public:
  /// Creates `<directory>/<basename>.h5` (under a temporary name; an existing
  /// `<basename>.xdmf`/`.h5` of an earlier run is removed first) and writes every body's
  /// reference mesh. Collective on the bodies' communicator. Throws a collective
  /// flexopt::Error for invalid names or layouts whose ranges do not tile the global ones.
  MotionWriter(const std::vector<MotionBody> &bodies, const std::string &directory,
               const std::string &basename = "motion");
  /// Without close(): closes the HDF5 file and removes the temporary file (the error path;
  /// collective, like every other member).
  ~MotionWriter();
  MotionWriter(const MotionWriter &) = delete;
  MotionWriter &operator=(const MotionWriter &) = delete;

  /// Starts output step K = steps() at `time` (seconds; rank 0's value is used, and it must
  /// be greater than the previous step's). Every body needs positions() in every step.
  /// Collective.
  void begin_step(double time);
  /// Current coordinates of the owned nodes of body `body` (index into the constructor's
  /// list): 3 per owned node, in the order of the layout's owned nodes. Once per body and
  /// step. Collective.
  void positions(std::size_t body, const double *owned_xyz);
  /// A nodal vector field of body `body` in the current step (e.g. "displacement"): 3 values
  /// per owned node. Collective.
  void node_vector(std::size_t body, const std::string &name, const double *owned_values);
  /// A cell scalar field of body `body` in the current step: one value per local cell.
  /// Collective.
  void cell_scalar(std::size_t body, const std::string &name, const double *local_values);
  /// A cell scalar field of body `body` that does not change with time (a design's densities):
  /// written once, to /<body>/<name>, and shown in every step, those begun before and after.
  /// Collective.
  void constant_cell_scalar(std::size_t body, const std::string &name, const double *local_values);
  /// constant_cell_scalar with one value in every cell (a body outside the design: density 1).
  /// Collective.
  void constant_cell_value(std::size_t body, const std::string &name, double value);
  /// Writes /time, closes the HDF5 file, writes the XDMF file and renames both to their final
  /// names. Collective. Returns the path of the XDMF file.
  std::string close();

  /// Number of steps begun so far.
  std::size_t steps() const;
  /// Number of bodies.
  std::size_t bodies() const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

} // namespace flexopt::io
