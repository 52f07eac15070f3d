#include "flexopt/mesh/grid_layout.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

namespace flexopt::mesh {

namespace {

/// Position in the Gmsh node order of each XDMF/VTK node. Gmsh's Tet10 numbers its last two
/// edge nodes (3,2), (3,1); VTK's quadratic tetra numbers them (1,3), (2,3).
const int kTet10GmshOfVtk[10] = {0, 1, 2, 3, 4, 5, 6, 7, 9, 8};

} // namespace

io::GridLayout grid_layout(const DistributedMesh &mesh) {
  io::GridLayout g;
  g.comm = mesh.comm;
  g.global_nodes = mesh.global_nodes;
  g.node_start = mesh.node_start;
  g.owned_nodes = mesh.owned_nodes;
  g.owned_coordinates.assign(mesh.coordinates.begin(),
                             mesh.coordinates.begin() + 3 * mesh.owned_nodes);
  g.global_cells = mesh.global_elements;
  g.cell_start = mesh.element_start;
  g.local_cells = mesh.local_elements();
  const int npe = mesh.nodes_per_element();
  g.nodes_per_cell = npe;
  switch (mesh.type) {
  case ElementType::Tet4:
    g.topology_type = "Tetrahedron";
    break;
  case ElementType::Tet10:
    g.topology_type = "Tetrahedron_10";
    break;
  case ElementType::Hex8:
    g.topology_type = "Hexahedron";
    break;
  }
  g.cell_nodes.resize(mesh.connectivity.size());
  for (PetscInt e = 0; e < mesh.local_elements(); ++e)
    for (int a = 0; a < npe; ++a) {
      const int src = mesh.type == ElementType::Tet10 ? kTet10GmshOfVtk[a] : a;
      g.cell_nodes[static_cast<std::size_t>(e * npe + a)] =
          mesh.local_to_global(mesh.connectivity[static_cast<std::size_t>(e * npe + src)]);
    }
  return g;
}

static std::vector<PetscInt> gather_count(MPI_Comm comm, PetscInt n) {
  std::vector<PetscInt> all(static_cast<std::size_t>(comm_size(comm)));
  MPI_Allgather(&n, 1, MPIU_INT, all.data(), 1, MPIU_INT, comm);
  return all;
}

std::vector<PetscInt> elements_per_rank(const DistributedMesh &mesh) {
  return gather_count(mesh.comm, mesh.local_elements());
}

std::vector<PetscInt> nodes_per_rank(const DistributedMesh &mesh) {
  return gather_count(mesh.comm, mesh.owned_nodes);
}

} // namespace flexopt::mesh
