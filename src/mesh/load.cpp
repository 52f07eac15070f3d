#include "flexopt/mesh/load.hpp"

#include "flexopt/core/context.hpp"

namespace flexopt::mesh {

DistributedMesh load_body_mesh(MPI_Comm comm, const io::BodySpec &body) {
  MeshData data;
  run_on_root(comm, 0, [&] {
    try {
      data = read_gmsh(body.geometry, MeshOptions{body.mesh.size, body.mesh.order});
    } catch (const std::exception &e) {
      throw Error(body.where.str() + ": body '" + body.name + "': " + e.what());
    }
  });
  return distribute_mesh(comm, comm_rank(comm) == 0 ? &data : nullptr);
}

} // namespace flexopt::mesh
