#pragma once
/// \file Files that carry a design (restart.h5, read by `--restart` and `--design`): the
/// fingerprint that ties them to the case's design field, and the checks made before one is
/// used (issue 42): a file from another case or mesh, or with densities that are not finite or
/// outside [0, 1], is refused naming what differs or the element and its value.
#include "flexopt/io/restart.hpp"
#include "flexopt/optimize/design.hpp"

#include <map>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// design_body, design_region, design_elements (the global count) and design_positions (a
/// hash of every design element's Gmsh tag and centroid, independent of the rank count and of
/// the elements' order). Collective.
/// Several design bodies: their names and regions joined by commas, the total count, and the
/// hashes combined. Collective.
std::map<std::string, std::string> design_fingerprint(const Design &design);

/// Refuses (a collective flexopt::Error naming `path` and what differs) the file `path` when its
/// fingerprint is not the field's; a file without one (written before fingerprints) passes with
/// a warning. Call it before io::read_restart, which would stop at the first element it misses.
/// Collective.
void check_design_file(const Design &design, const std::string &path);

/// Refuses values (one per local design variable, aligned with design.design_keys()) that are
/// not finite or lie outside [0, 1]: a collective flexopt::Error naming `path`, the field
/// `what`, the element's Gmsh tag (the lowest such tag) and its value. Collective.
void check_design_values(const Design &design, const std::vector<double> &values,
                         const std::string &path, const std::string &what);

/// A key per owned degree of freedom of `mesh` (`components` per node, node-major): a 64-bit
/// hash of the node's position (its coordinates' bits) and the component, the same on any rank
/// count, for values kept in a restart file (io::RestartData::dof_keys). Not collective.
std::vector<std::uint64_t> dof_keys(const mesh::DistributedMesh &mesh, int components);

} // namespace flexopt::optimize
