#include "flexopt/mesh/grid_layout.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <algorithm>

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

namespace flexopt::mesh {

namespace {

/// XDMF's code of a cell type in a Mixed topology.
int xdmf_mixed_code(ElementType type) {
  switch (type) {
  case ElementType::Tet4:
    return 6;
  case ElementType::Tet10:
    return 38;
  case ElementType::Hex8:
    return 9;
  }
  return 0;
}

} // namespace

io::GridLayout merged_grid_layout(const std::vector<const DistributedMesh *> &meshes,
                                  const std::vector<std::vector<double>> &placed) {
  auto layout = [&](std::size_t k) {
    io::GridLayout one = grid_layout(*meshes[k]);
    if (k < placed.size() && !placed[k].empty()) one.owned_coordinates = placed[k];
    return one;
  };
  if (meshes.size() == 1) return layout(0);
  const MPI_Comm comm = meshes.front()->comm;
  const auto size = static_cast<std::size_t>(comm_size(comm));
  const std::size_t rank = static_cast<std::size_t>(comm_rank(comm)), nb = meshes.size();
  // Owned nodes per rank and body; the merged numbering puts rank r's nodes of body 0, body 1,
  // ... after every node of the ranks before r.
  std::vector<std::vector<PetscInt>> owned(nb);
  for (std::size_t b = 0; b < nb; ++b) owned[b] = nodes_per_rank(*meshes[b]);
  std::vector<long long> rank_start(size + 1, 0);
  for (std::size_t r = 0; r < size; ++r) {
    rank_start[r + 1] = rank_start[r];
    for (std::size_t b = 0; b < nb; ++b) rank_start[r + 1] += owned[b][r];
  }
  // body b's node g: its owner r (body b numbers rank r's owned nodes from start_b[r]).
  std::vector<std::vector<long long>> body_start(nb, std::vector<long long>(size + 1, 0));
  for (std::size_t b = 0; b < nb; ++b)
    for (std::size_t r = 0; r < size; ++r) body_start[b][r + 1] = body_start[b][r] + owned[b][r];
  auto merged = [&](std::size_t b, long long g) {
    const auto &st = body_start[b];
    const auto r =
        static_cast<std::size_t>(std::upper_bound(st.begin(), st.end(), g) - st.begin() - 1);
    long long at = rank_start[r];
    for (std::size_t c = 0; c < b; ++c) at += owned[c][r];
    return at + (g - st[r]);
  };
  bool same = true;
  for (const DistributedMesh *m : meshes) same = same && m->type == meshes.front()->type;
  io::GridLayout g;
  g.comm = comm;
  g.global_nodes = rank_start[size];
  g.node_start = rank_start[rank];
  long long local_entries = 0;
  for (std::size_t b = 0; b < nb; ++b) {
    const io::GridLayout one = layout(b);
    g.owned_nodes += one.owned_nodes;
    g.owned_coordinates.insert(g.owned_coordinates.end(), one.owned_coordinates.begin(),
                               one.owned_coordinates.end());
    g.global_cells += one.global_cells;
    g.local_cells += one.local_cells;
    for (long long e = 0; e < one.local_cells; ++e) {
      if (!same) g.cell_nodes.push_back(xdmf_mixed_code(meshes[b]->type));
      for (int a = 0; a < one.nodes_per_cell; ++a)
        g.cell_nodes.push_back(
            merged(b, one.cell_nodes[static_cast<std::size_t>(e * one.nodes_per_cell + a)]));
    }
    if (same) {
      g.nodes_per_cell = one.nodes_per_cell;
      g.topology_type = one.topology_type;
    }
  }
  local_entries = static_cast<long long>(g.cell_nodes.size());
  MPI_Exscan(&g.local_cells, &g.cell_start, 1, MPI_LONG_LONG, MPI_SUM, comm);
  if (rank == 0) g.cell_start = 0;
  if (!same) { // XDMF's Mixed topology: each cell's type code, then its nodes
    g.topology_type = "Mixed";
    g.nodes_per_cell = 0;
    MPI_Allreduce(&local_entries, &g.global_topology, 1, MPI_LONG_LONG, MPI_SUM, comm);
    MPI_Exscan(&local_entries, &g.topology_start, 1, MPI_LONG_LONG, MPI_SUM, comm);
    if (rank == 0) g.topology_start = 0;
  }
  return g;
}

} // namespace flexopt::mesh
