#pragma once
/// \file Loading a case body's mesh: Gmsh on rank 0, then partitioned and distributed.
#include "flexopt/io/case.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

namespace flexopt::mesh {

/// Reads or meshes the body's geometry on rank 0 (Gmsh) and distributes it. Collective; any
/// failure is raised on every rank with the body's case.yaml location.
DistributedMesh load_body_mesh(MPI_Comm comm, const io::BodySpec &body);

} // namespace flexopt::mesh
