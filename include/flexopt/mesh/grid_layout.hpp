#pragma once
/// \file A distributed mesh as the output writers see it (io::GridLayout), and how its elements
/// and nodes are spread over the ranks.
#include "flexopt/io/xdmf.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

namespace flexopt::mesh {

/// The mesh as the XDMF writer needs it (owned node coordinates, cells in global node
/// numbers and VTK/XDMF node order). Not collective.
io::GridLayout grid_layout(const DistributedMesh &mesh);

/// Number of local elements on every rank (gathered to all). Collective.
std::vector<PetscInt> elements_per_rank(const DistributedMesh &mesh);
/// Number of owned nodes on every rank (gathered to all). Collective.
std::vector<PetscInt> nodes_per_rank(const DistributedMesh &mesh);

} // namespace flexopt::mesh
