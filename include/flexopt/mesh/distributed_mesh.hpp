#pragma once
/// \file A body mesh partitioned over the ranks of a communicator.
///
/// Elements are partitioned with METIS (dual graph, shared faces) on rank 0 and sent to their
/// ranks. Nodes are renumbered so that each rank owns a contiguous range of global node
/// numbers (PETSc ownership); a node is owned by the lowest rank among the elements that
/// touch it. Local node numbering: owned nodes [0, owned_nodes) in global order, then ghost
/// nodes (touched by local elements, owned elsewhere) in ascending global order — the layout
/// of VecCreateGhostBlock.
#include "flexopt/mesh/element_type.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <map>
#include <mpi.h>
#include <petscsys.h>
#include <string>
#include <vector>

namespace flexopt::mesh {

/// The faces of one physical surface that this rank integrates (each face lives on exactly
/// one rank), with their global node numbers and coordinates.
struct LocalSurface {
  FaceType type = FaceType::Tri3;
  std::vector<PetscInt> global_nodes; ///< nodes_per_face per face
  std::vector<double> coordinates;    ///< 3 per face node
  std::size_t size() const {
    return global_nodes.size() / static_cast<std::size_t>(nodes_per_face(type));
  }
  /// Coordinates of face f, one row per node.
  FaceCoords face_coordinates(std::size_t f) const;
};

struct DistributedMesh {
  MPI_Comm comm = MPI_COMM_NULL;
  std::string source;
  ElementType type = ElementType::Tet4;

  PetscInt global_nodes = 0;       ///< over all ranks
  PetscInt owned_nodes = 0;        ///< owned by this rank
  PetscInt node_start = 0;         ///< first owned global node number
  std::vector<PetscInt> ghosts;    ///< global numbers of ghost nodes (local index owned_nodes + k)
  std::vector<double> coordinates; ///< 3 per local node (owned, then ghosts)

  PetscInt global_elements = 0;
  PetscInt element_start = 0;            ///< global number of the first local element
  std::vector<PetscInt> connectivity;    ///< local node indices, nodes_per_element per element
  std::vector<std::size_t> element_tags; ///< Gmsh tags (for messages)
  std::map<std::string, std::vector<PetscInt>> volume_groups; ///< name -> local element indices

  std::map<std::string, LocalSurface> surfaces;               ///< every group on every rank
  std::map<std::string, std::vector<PetscInt>> surface_nodes; ///< name -> owned global nodes on it

  PetscInt local_nodes() const { return owned_nodes + static_cast<PetscInt>(ghosts.size()); }
  PetscInt local_elements() const;
  int nodes_per_element() const { return mesh::nodes_per_element(type); }
  PetscInt local_to_global(PetscInt local) const {
    return local < owned_nodes ? node_start + local
                               : ghosts[static_cast<std::size_t>(local - owned_nodes)];
  }
  /// Coordinates of local element e, one row per node.
  ElementCoords element_coordinates(PetscInt e) const;
  /// Throws a collective flexopt::Error naming `where` if the group does not exist.
  const LocalSurface &surface(const std::string &name, const std::string &where) const;
  const std::vector<PetscInt> &volume_group(const std::string &name,
                                            const std::string &where) const;
};

/// The diagonal of the bounding box of all of the mesh's nodes [m]: the body's size. Collective.
double mesh_extent(const DistributedMesh &mesh);

/// Partitions `root_mesh` (significant on rank 0 only) over `comm` and distributes it.
/// Collective.
DistributedMesh distribute_mesh(MPI_Comm comm, const MeshData *root_mesh);

} // namespace flexopt::mesh
