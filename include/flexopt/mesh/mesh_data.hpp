#pragma once
/// \file A whole body mesh as read from Gmsh, held on one rank before it is partitioned.
#include "flexopt/fem/element.hpp"

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace flexopt::mesh {

/// Faces of one Gmsh physical surface (all of one face type).
struct SurfaceGroup {
  fem::FaceType type = fem::FaceType::Tri3;
  std::vector<std::int64_t>
      connectivity;         ///< nodes_per_face entries per face, MeshData node indices
  std::size_t size() const; ///< number of faces
};

/// A body's mesh: one volume element type, node coordinates, and named physical groups.
/// Node indices are 0-based and only nodes used by volume elements are kept.
struct MeshData {
  std::string source; ///< file the mesh came from (for messages)
  fem::ElementType type = fem::ElementType::Tet4;
  std::vector<double> coordinates;        ///< 3 per node [m]
  std::vector<std::int64_t> connectivity; ///< nodes_per_element per element, Gmsh node order
  std::vector<std::size_t> element_tags;  ///< Gmsh element tag of each element (for messages)
  std::map<std::string, std::vector<std::int64_t>> volume_groups; ///< name -> element indices
  std::map<std::string, SurfaceGroup> surface_groups;             ///< name -> faces

  std::int64_t node_count() const { return static_cast<std::int64_t>(coordinates.size() / 3); }
  std::int64_t element_count() const;
};

/// Options for meshing a .geo at run time.
struct MeshOptions {
  double size = 0; ///< maximum element size [m]; 0 keeps the sizes the .geo sets
  int order = 1;   ///< element order: 1 or 2
};

/// Reads a .msh (v4) or meshes a .geo with the Gmsh API. Not collective: call on one rank.
/// Throws flexopt::Error naming the file for a missing file, a Gmsh failure, a mesh without
/// volume elements, mixed or unsupported element types, or surface faces that do not lie on
/// the volume mesh.
MeshData read_gmsh(const std::string &path, const MeshOptions &options);

} // namespace flexopt::mesh
