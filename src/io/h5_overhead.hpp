#pragma once
/// \file The measured constants of the output size estimates (io::estimate_motion_bytes,
/// io::estimate_xdmf_bytes; docs/output.md "Size"): HDF5's metadata per file, group and dataset,
/// and the fixed characters of the XDMF text.

#include <string>

namespace flexopt::io::detail {

/// HDF5 metadata per step and body: the group /<body>/step_K (object header, its link in the
/// body group's symbol table with B-tree and name heap) [bytes, measured: docs/output.md].
constexpr double kH5GroupBytes = 1145;
/// HDF5 metadata once per file: superblock, root group, /time [bytes, measured].
constexpr double kH5FileBytes = 2048;
/// HDF5 metadata per dataset (object header with dataspace, datatype and layout messages; its
/// link in the step group) [bytes, measured].
constexpr double kH5DatasetBytes = 280;
/// The fixed characters of xdmf_text() per step (spatial collection, Time), per step and body
/// (Grid, Topology, Geometry) and per node field (Attribute); the names and numbers they hold
/// are added to them. A time printed with %.17g takes up to about 20 characters.
constexpr double kXdmfStepChars = 112 + 20, kXdmfBodyChars = 417, kXdmfFieldChars = 195;

/// The number of decimal digits of v (the XDMF text's numbers).
inline double digits(long long v) {
  return static_cast<double>(std::to_string(v).size());
}

} // namespace flexopt::io::detail
