#include "flexopt/mesh/load.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <cmath>
#include <cstdio>

namespace flexopt::mesh {

namespace {

/// A count for messages: 12345678 -> "12.3 million", below a million as it is.
std::string count_text(double n) {
  char buf[64];
  if (n >= 1e6)
    std::snprintf(buf, sizeof buf, "%.3g million", n / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.0f", n);
  return buf;
}

/// Refuses a mesh whose estimate is above the body's limit, before Gmsh meshes the volumes.
void check_limit(const MeshSource &source, const MeshEstimate &est) {
  const std::int64_t limit = source.max_elements > 0
                                 ? source.max_elements
                                 : default_max_elements(source.order, est.hexahedra);
  if (est.elements <= static_cast<double>(limit)) return;
  char size[160];
  if (source.size > 0)
    std::snprintf(size, sizeof size, "mesh.size %g m", source.size);
  else
    std::snprintf(size, sizeof size, "the sizes the .geo sets (effective size %.3g m)", est.size);
  char figures[200];
  std::snprintf(figures, sizeof figures, "volume %.4g m^3, effective element size %.3g m",
                est.volume, est.size);
  throw Error(source.where.str() + ": body '" + source.body + "': mesh.max_elements: " +
                  source.geometry_key + " at " + size + " would make about " +
                  count_text(est.elements) + " " + est.element_name() + " elements (" + figures +
                  "), above the limit of " + count_text(static_cast<double>(limit)) +
                  (source.max_elements > 0 ? "" : " (the default for " + est.element_name() + ")") +
                  "; it was not meshed. Use a larger mesh.size, or raise the limit with "
                  "`mesh: {max_elements: N}` on this body if the machine has the memory "
                  "(docs/case-format.md, mesh size bound)",
              true);
}

} // namespace

std::int64_t default_max_elements(int order, bool hexahedra) {
  if (hexahedra) return 500000;
  return order == 2 ? 400000 : 2000000;
}

bool meshed_from_geo(const MeshSource &source) {
  return source.geometry.size() >= 4 && source.geometry.rfind(".geo") == source.geometry.size() - 4;
}

DistributedMesh load_body_mesh(MPI_Comm comm, const MeshSource &source,
                               const std::function<void(const MeshData &)> &on_root,
                               MeshEstimate *estimate_out) {
  MeshData data;
  const double t0 = wall_time();
  const bool geo = meshed_from_geo(source);
  if (!geo)
    print0(comm, "mesh: body %s: reading %s with Gmsh on rank 0 ...\n", source.body.c_str(),
           source.geometry_key.c_str());
  MeshEstimate estimate;
  bool refused = false;
  std::string refusal;
  MeshOptions options{source.size, source.order};
  // Rank 0 runs Gmsh and prints directly (print0 is collective-free but the other ranks wait
  // in run_on_root's broadcast meanwhile).
  options.before_meshing = [&](const MeshEstimate &est) {
    try {
      check_limit(source, est);
    } catch (const Error &e) {
      refused = true;
      refusal = e.what();
      throw;
    }
    // (on rank 0 of comm, which print0 prints on)
    char size[48] = "";
    if (source.size > 0) std::snprintf(size, sizeof size, "size %g m, ", source.size);
    print0(comm,
           "mesh: body %s: meshing %s with Gmsh on rank 0 (%sorder %d; estimated %s %s "
           "elements, %s nodes) ...\n",
           source.body.c_str(), source.geometry_key.c_str(), size, source.order,
           count_text(est.elements).c_str(), est.element_name().c_str(),
           count_text(est.nodes).c_str());
  };
  options.progress = [&](const char *stage, double seconds) {
    print0(comm, "mesh: body %s: Gmsh still meshing the %s, %.0f s so far ...\n",
           source.body.c_str(), stage, seconds);
  };
  run_on_root(comm, 0, [&] {
    try {
      data = read_gmsh(source.geometry, options, &estimate);
      if (estimate_out && geo) *estimate_out = estimate;
      if (on_root) on_root(data);
    } catch (const std::exception &e) {
      if (refused) throw Error(refusal);
      throw Error(source.body_where.str() + ": body '" + source.body + "': " + e.what());
    }
  });
  const double t1 = wall_time();
  DistributedMesh mesh = distribute_mesh(comm, comm_rank(comm) == 0 ? &data : nullptr);
  // One write for the whole line: mpirun forwards stdout and stderr apart, and a line written in
  // pieces can be split by another rank's error message.
  char estimate_text[128] = "";
  if (geo)
    std::snprintf(estimate_text, sizeof estimate_text,
                  " (estimate %s elements, %.2f times the count)",
                  count_text(estimate.elements).c_str(),
                  estimate.elements / static_cast<double>(mesh.global_elements));
  print0(comm,
         "mesh: body %s: %s in %.2f s: %lld %s elements, %lld nodes%s; partitioned over %d "
         "rank(s) (%.2f s)\n",
         source.body.c_str(), geo ? "meshed" : "read", t1 - t0,
         static_cast<long long>(mesh.global_elements), element_name(mesh.type),
         static_cast<long long>(mesh.global_nodes), estimate_text, comm_size(comm),
         wall_time() - t1);
  return mesh;
}

} // namespace flexopt::mesh
