#pragma once
/// \file A distributed mesh as the output writers see it (io::GridLayout), and how its elements
/// and nodes are spread over the ranks.
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

namespace flexopt::mesh {

/// The mesh as the XDMF writer needs it (owned node coordinates, cells in global node
/// numbers and VTK/XDMF node order). Not collective.
io::GridLayout grid_layout(const DistributedMesh &mesh);

/// Several meshes (the design bodies of one optimization) as one grid: on every rank its owned
/// nodes of each mesh in turn, its cells likewise (mesh 0's local cells, then mesh 1's); one
/// element type keeps its topology, several make an XDMF Mixed topology. One mesh: grid_layout.
/// `placed[k]`, when given and not empty: mesh k's owned node coordinates to write instead of its
/// own (a body in its placement). Collective.
io::GridLayout merged_grid_layout(const std::vector<const DistributedMesh *> &meshes,
                                  const std::vector<std::vector<double>> &placed = {});

/// Number of local elements on every rank (gathered to all). Collective.
std::vector<PetscInt> elements_per_rank(const DistributedMesh &mesh);
/// Number of owned nodes on every rank (gathered to all). Collective.
std::vector<PetscInt> nodes_per_rank(const DistributedMesh &mesh);

} // namespace flexopt::mesh
