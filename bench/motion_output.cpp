// Benchmark driver of the motion output's cost per step (docs/output.md, "Cost";
// scripts/bench/motion_output.sh): io::MotionWriter writing positions and a displacement field of
//   - 3 bodies of 1000 nodes each (9 x 9 x 9 hex cells) for STEPS steps, and
//   - 1 body of 100 000 nodes (99 x 99 x 9 cells) for BIG_STEPS steps,
// the nodes and cells split over the ranks. Prints per set the mesh write, the mean wall time per
// step (and of its first and last tenth), the bytes per step and the close.
//
//   mpirun -n N build/bench_motion_output -out DIR [-steps 200] [-big_steps 20]
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/io/motion_writer.hpp"
#include "flexopt/io/xdmf.hpp"
#include "harness.hpp"

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

using namespace flexopt;

namespace {

/// A structured nx x ny x nz hex block at `x0`: nodes and cells split into contiguous ranges
/// over the ranks (the cells' nodes are mostly owned elsewhere, which the writer does not mind).
io::GridLayout block_layout(MPI_Comm comm, long long nx, long long ny, long long nz, double x0) {
  const int rank = comm_rank(comm), size = comm_size(comm);
  io::GridLayout g;
  g.comm = comm;
  g.nodes_per_cell = 8;
  g.topology_type = "Hexahedron";
  const long long px = nx + 1, py = ny + 1, pz = nz + 1;
  g.global_nodes = px * py * pz;
  g.global_cells = nx * ny * nz;
  auto split = [&](long long n, long long &start, long long &count) {
    start = n * rank / size;
    count = n * (rank + 1) / size - start;
  };
  split(g.global_nodes, g.node_start, g.owned_nodes);
  split(g.global_cells, g.cell_start, g.local_cells);
  const double h = 0.01;
  for (long long n = g.node_start; n < g.node_start + g.owned_nodes; ++n) {
    g.owned_coordinates.push_back(x0 + h * static_cast<double>(n % px));
    g.owned_coordinates.push_back(h * static_cast<double>((n / px) % py));
    g.owned_coordinates.push_back(h * static_cast<double>(n / (px * py)));
  }
  auto id = [&](long long i, long long j, long long k) { return i + px * (j + py * k); };
  for (long long c = g.cell_start; c < g.cell_start + g.local_cells; ++c) {
    const long long i = c % nx, j = (c / nx) % ny, k = c / (nx * ny);
    for (long long v :
         {id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k), id(i, j, k + 1),
          id(i + 1, j, k + 1), id(i + 1, j + 1, k + 1), id(i, j + 1, k + 1)})
      g.cell_nodes.push_back(v);
  }
  return g;
}

/// Writes `steps` steps (positions and a displacement of every body) and prints the cost.
void time_motion(const std::vector<io::MotionBody> &bodies, int steps, const char *label,
                 const std::string &dir, const char *basename) {
  const MPI_Comm comm = PETSC_COMM_WORLD;
  MPI_Barrier(comm);
  const double t0 = wall_time();
  io::MotionWriter w(bodies, dir, basename);
  MPI_Barrier(comm);
  const double t1 = wall_time();
  std::vector<std::vector<double>> x(bodies.size());
  long long values = 0;
  const int tenth = std::max(1, steps / 10);
  double first = 0, last = 0; // wall time of the first and of the last tenth of the steps
  for (int k = 0; k < steps; ++k) {
    if (k == tenth) first = wall_time() - t1;
    if (k == steps - tenth) last = wall_time();
    w.begin_step(0.01 * k);
    for (std::size_t b = 0; b < bodies.size(); ++b) {
      const auto &X = bodies[b].layout.owned_coordinates;
      x[b].resize(X.size());
      for (std::size_t i = 0; i < X.size(); ++i) x[b][i] = X[i] + 1e-3 * k;
      w.positions(b, x[b].data());
      w.node_vector(b, "displacement", x[b].data());
      values += 2 * bodies[b].layout.global_nodes * 3;
    }
  }
  MPI_Barrier(comm);
  const double t2 = wall_time();
  last = t2 - last;
  w.close();
  const double t3 = wall_time();
  const double mb = static_cast<double>(values) * 8 / 1e6;
  print0(comm,
         "[ motion  ] %s, %d ranks, %d steps: mesh %.1f ms, %.2f ms per step (first tenth "
         "%.2f, last tenth %.2f; %.2f MB/step, %.0f MB/s), close %.1f ms\n",
         label, comm_size(comm), steps, 1e3 * (t1 - t0), 1e3 * (t2 - t1) / steps,
         1e3 * first / tenth, 1e3 * last / tenth, mb / steps, mb / (t2 - t1), 1e3 * (t3 - t2));
}

} // namespace

int main(int argc, char **argv) {
  return flexopt::bench::run_bench(argc, argv, "bench_motion_output", [&] {
    char dir[PETSC_MAX_PATH_LEN] = ".";
    PetscInt steps = 200, big_steps = 20;
    PetscOptionsGetString(nullptr, nullptr, "-out", dir, sizeof dir, nullptr);
    PetscOptionsGetInt(nullptr, nullptr, "-steps", &steps, nullptr);
    PetscOptionsGetInt(nullptr, nullptr, "-big_steps", &big_steps, nullptr);
    if (steps < 10 || big_steps < 10) throw Error("-steps, -big_steps: at least 10", true);
    const MPI_Comm comm = PETSC_COMM_WORLD;
    std::vector<io::MotionBody> small;
    for (int b = 0; b < 3; ++b) // 3 bodies x 1000 nodes (9 x 9 x 9 cells)
      small.push_back({"body" + std::to_string(b), block_layout(comm, 9, 9, 9, 0.2 * b)});
    time_motion(small, static_cast<int>(steps), "3 bodies x 1000 nodes", dir, "motion_small");
    // 1 body x 100 000 nodes (99 x 99 x 9 cells: 100 x 100 x 10 nodes).
    time_motion({{"big", block_layout(comm, 99, 99, 9, 0.0)}}, static_cast<int>(big_steps),
                "1 body x 100000 nodes", dir, "motion_big");
  });
}
