#pragma once
/// \file A whole body mesh as read from Gmsh, held on one rank before it is partitioned.
#include "flexopt/mesh/element_type.hpp"

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace flexopt::mesh {

/// Faces of one Gmsh physical surface (all of one face type).
struct SurfaceGroup {
  FaceType type = FaceType::Tri3;
  std::vector<std::int64_t>
      connectivity;         ///< nodes_per_face entries per face, MeshData node indices
  std::size_t size() const; ///< number of faces
};

/// A body's mesh: one volume element type, node coordinates, and named physical groups.
/// Node indices are 0-based and only nodes used by volume elements are kept.
struct MeshData {
  std::string source; ///< file the mesh came from (for messages)
  ElementType type = ElementType::Tet4;
  std::vector<double> coordinates;        ///< 3 per node [m]
  std::vector<std::int64_t> connectivity; ///< nodes_per_element per element, Gmsh node order
  std::vector<std::size_t> element_tags;  ///< Gmsh element tag of each element (for messages)
  std::map<std::string, std::vector<std::int64_t>> volume_groups; ///< name -> element indices
  std::map<std::string, SurfaceGroup> surface_groups;             ///< name -> faces

  std::int64_t node_count() const { return static_cast<std::int64_t>(coordinates.size() / 3); }
  std::int64_t element_count() const;
};

/// Estimate of the mesh Gmsh will make of a .geo, found before the volumes are meshed
/// (docs/case-format.md, "mesh size bound"). Every figure is for all 3D entities together.
///
/// volume: the volume enclosed by each 3D entity's boundary, from a coarse surface mesh
///   (divergence theorem; exact for planar faces, chord error for curved ones), so that it
///   works for both the built-in and the OpenCASCADE kernel.
/// size: the effective element size h per entity, the geometric mean over its boundary curves
///   (those with at least 2 segments) of each curve's mean 1D segment length, from the 1D mesh
///   at the run's settings: it follows mesh.size, the .geo's own sizes, transfinite curves and
///   extrusion layers alike. If that 1D mesh would exceed kMaxEstimateSegments segments,
///   mesh.size itself is taken.
/// elements: per entity, kTetsPerCube V / h^3 for tetrahedra, V / h^3 for hexahedra (an entity
///   whose coarse boundary mesh is all quadrangles is recombined). `size` reports the
///   volume-weighted h^3 mean, (sum V_i / sum (V_i / h_i^3))^(1/3).
struct MeshEstimate {
  double volume = 0;      ///< [m^3]
  double size = 0;        ///< effective element size [m]
  double elements = 0;    ///< estimated volume elements
  double nodes = 0;       ///< estimated nodes of those elements (order 2 edge nodes included)
  bool hexahedra = false; ///< true if every 3D entity is recombined (Hex8)
  int order = 1;          ///< element order the estimate is for
  std::string element_name() const; ///< "Tet4", "Tet10" or "Hex8"
};

/// Tetrahedra per h^3 of volume in Gmsh's Delaunay meshes with Mesh.MeshSizeMax = h, measured
/// on meshes/rod.geo: 4.6, 4.9 and 5.7 at 20, 10 and 4 elements across its section
/// (docs/case-format.md). A regular tetrahedron of edge h would give 6 sqrt(2) = 8.5: Gmsh's
/// elements are larger than that on average.
inline constexpr double kTetsPerCube = 5.2;

/// Tetrahedra per vertex in the same meshes (4.7 to 5.4), for the node estimate. Order 2 adds
/// one node per edge, and a tetrahedral mesh has about (vertices + tetrahedra) edges (Euler).
inline constexpr double kTetsPerVertex = 5.0;

/// Above this many 1D segments (total curve length / mesh.size), the estimate takes mesh.size
/// as the element size instead of meshing the curves.
inline constexpr double kMaxEstimateSegments = 1e6;

/// Options for meshing a .geo at run time.
struct MeshOptions {
  MeshOptions() = default;
  explicit MeshOptions(double size_, int order_ = 1) : size(size_), order(order_) {}
  double size = 0; ///< maximum element size [m]; 0 keeps the sizes the .geo sets
  int order = 1;   ///< element order: 1 or 2
  /// .geo only: called with the estimate before the volumes are meshed. It may throw to refuse
  /// the mesh (the exception passes through read_gmsh unchanged) and may print the estimate.
  std::function<void(const MeshEstimate &)> before_meshing;
  /// .geo only: called every kProgressInterval seconds while Gmsh meshes, with the stage
  /// ("geometry (curves, surfaces, volumes)", then "order 2") and the seconds elapsed. Called from
  /// another thread than the caller's (Gmsh itself runs on the caller's): it must only print.
  std::function<void(const char *stage, double seconds)> progress;
};

/// Seconds between two `MeshOptions::progress` calls.
inline constexpr double kProgressInterval = 10.0;

/// Estimates the mesh of a .geo at the given options without meshing its volumes (it meshes
/// the surfaces coarsely and the curves at the run's settings, in a Gmsh session of its own). Not
/// collective. Throws flexopt::Error naming the file if Gmsh fails or the geometry has no volume.
MeshEstimate estimate_gmsh(const std::string &path, const MeshOptions &options);

/// Reads a .msh (v4) or meshes a .geo with the Gmsh API. Not collective: call on one rank.
/// For a .geo, the estimate is made first (estimate_gmsh), passed to options.before_meshing
/// and kept in *estimate if given. Throws flexopt::Error naming the file for a missing file,
/// a Gmsh failure, a mesh without volume elements, mixed or unsupported element types, or
/// surface faces that do not lie on the volume mesh.
MeshData read_gmsh(const std::string &path, const MeshOptions &options,
                   MeshEstimate *estimate = nullptr);

} // namespace flexopt::mesh
