#pragma once
/// \file Loading a case body's mesh: Gmsh on rank 0, then partitioned and distributed.
#include "flexopt/io/case.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <functional>

namespace flexopt::mesh {

/// True if the body's geometry is a .geo that Gmsh meshes (at `mesh.size`), false for a .msh.
bool meshed_from_geo(const io::BodySpec &body);

/// Reads or meshes the body's geometry on rank 0 (Gmsh) and distributes it. Collective; any
/// failure is raised on every rank with the body's case.yaml location.
/// `on_root`, if given, is called on rank 0 with the whole mesh before it is distributed
/// (e.g. to integrate mass properties in one fixed order, independent of the rank count); an
/// exception it throws is raised on every rank like a meshing failure.
/// A .geo is estimated first (estimate_gmsh); the estimate is printed, a mesh above the body's
/// `mesh.max_elements` is refused before Gmsh meshes its volumes (one message naming the case
/// file, body and key), and Gmsh's progress is printed every kProgressInterval seconds.
/// `estimate`, if given, receives the estimate on rank 0 (a .msh file: left untouched).
DistributedMesh load_body_mesh(MPI_Comm comm, const io::BodySpec &body,
                               const std::function<void(const MeshData &)> &on_root = {},
                               MeshEstimate *estimate = nullptr);

} // namespace flexopt::mesh
