#include "flexopt/mesh/load.hpp"

#include "flexopt/core/context.hpp"

namespace flexopt::mesh {

DistributedMesh load_body_mesh(MPI_Comm comm, const io::BodySpec &body,
                               const std::function<void(const MeshData &)> &on_root) {
  MeshData data;
  const double t0 = wall_time();
  if (body.mesh.given)
    print0(comm, "mesh: body %s: meshing %s with Gmsh (size %g m, order %d) on rank 0 ...\n",
           body.name.c_str(), body.geometry_key.c_str(), body.mesh.size, body.mesh.order);
  else
    print0(comm, "mesh: body %s: reading %s with Gmsh on rank 0 ...\n", body.name.c_str(),
           body.geometry_key.c_str());
  run_on_root(comm, 0, [&] {
    try {
      data = read_gmsh(body.geometry, MeshOptions{body.mesh.size, body.mesh.order});
      if (on_root) on_root(data);
    } catch (const std::exception &e) {
      throw Error(body.where.str() + ": body '" + body.name + "': " + e.what());
    }
  });
  const double t1 = wall_time();
  DistributedMesh mesh = distribute_mesh(comm, comm_rank(comm) == 0 ? &data : nullptr);
  print0(comm,
         "mesh: %lld %s elements, %lld nodes (Gmsh %.2f s); partitioned over %d rank(s) (%.2f s)\n",
         static_cast<long long>(mesh.global_elements), fem::element_name(mesh.type),
         static_cast<long long>(mesh.global_nodes), t1 - t0, comm_size(comm), wall_time() - t1);
  return mesh;
}

} // namespace flexopt::mesh
