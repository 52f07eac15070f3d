#pragma once
/// \file Loading a case body's mesh: Gmsh on rank 0, then partitioned and distributed.
#include "flexopt/io/location.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <cstdint>
#include <functional>
#include <string>

namespace flexopt::mesh {

/// A body's mesh as the case gives it (`bodies[].geometry` and `bodies[].mesh`).
struct MeshSource {
  std::string body;         ///< the body's name (messages)
  std::string geometry;     ///< path, resolved against the case directory
  std::string geometry_key; ///< as written in case.yaml
  double size = 0;          ///< target element size [m] (.geo only); 0: the .geo's own sizes
  int order = 1;            ///< 1: Tet4 (Hex8 if the .geo recombines), 2: Tet10
  bool given = false;       ///< true if the `mesh:` key was present
  /// Largest estimated element count meshed (.geo only); 0: default_max_elements().
  std::int64_t max_elements = 0;
  io::Location where;      ///< of the `mesh:` key, or of the body if it has none
  io::Location body_where; ///< of the body
};

/// Default `mesh.max_elements` for the element type Gmsh will make (order 1 tetrahedra, order
/// 2 tetrahedra, or recombined hexahedra): 2 000 000 Tet4, 400 000 Tet10, 500 000 Hex8, each
/// about 1.5 million DOFs, what the static benchmark solves on 2 ranks within 6 GiB of this
/// 24 GiB machine (docs/case-format.md, "Mesh size bound"; docs/benchmarks.md).
std::int64_t default_max_elements(int order, bool hexahedra);

/// True if the body's geometry is a .geo that Gmsh meshes (at `size`), false for a .msh.
bool meshed_from_geo(const MeshSource &source);

/// Reads or meshes the body's geometry on rank 0 (Gmsh) and distributes it. Collective; any
/// failure is raised on every rank with the body's case.yaml location.
/// `on_root`, if given, is called on rank 0 with the whole mesh before it is distributed
/// (e.g. to integrate mass properties in one fixed order, independent of the rank count); an
/// exception it throws is raised on every rank like a meshing failure.
/// A .geo is estimated first (estimate_gmsh); the estimate is printed, a mesh above the body's
/// `mesh.max_elements` is refused before Gmsh meshes its volumes (one message naming the case
/// file, body and key), and Gmsh's progress is printed every kProgressInterval seconds.
/// `estimate`, if given, receives the estimate on rank 0 (a .msh file: left untouched).
DistributedMesh load_body_mesh(MPI_Comm comm, const MeshSource &source,
                               const std::function<void(const MeshData &)> &on_root = {},
                               MeshEstimate *estimate = nullptr);

} // namespace flexopt::mesh
