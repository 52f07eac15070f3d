// Benchmark driver for ACF bodies (scripts/bench/acf.sh, docs/benchmarks.md): the steel beam of
// meshes/beam.geo (Tet10, 1 m x 50 x 100 mm) meshed at SIZE, thrown spinning under gravity and
// integrated for STEPS steps of 1 ms (rho_inf 0.8) by dynamics::DistributedAlpha on the ranks
// of the run. Prints one table row: DOFs, ranks, steps, Newton iterations and factorizations per
// step, wall time per step and per iteration, the largest memory of a rank.
//
//   mpirun -n N build/bench_acf_free_body SIZE STEPS [REUSE]
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <cstdio>
#include <cstdlib>
#include <petscsys.h>
#include <string>
#include <sys/resource.h>

using namespace flexopt;

int main(int argc, char **argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SIZE STEPS [REUSE]\n", argv[0]);
    return 2;
  }
  PetscInitialize(&argc, &argv, nullptr, nullptr);
  int status = 0;
  try {
    const double size = std::atof(argv[1]);
    const int steps = std::atoi(argv[2]);
    dynamics::NewtonSettings settings;
    if (argc > 3) settings.reuse_contraction = std::atof(argv[3]);
    mesh::MeshData data;
    const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/beam.geo";
    const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
    run_on_root(PETSC_COMM_WORLD, 0, [&] {
      data = mesh::read_gmsh(geo, mesh::MeshOptions{size, 2});
    });
    const mesh::DistributedMesh m = mesh::distribute_mesh(PETSC_COMM_WORLD, root ? &data : nullptr);
    data = mesh::MeshData{};
    const bodies::AcfBody body("beam", m, fem::IsotropicMaterial{2.1e11, 0.3, 7850});
    const dynamics::DistributedAlpha da({&body}, Eigen::Vector3d(0, -9.81, 0),
                                        dynamics::AlphaParameters::from_rho_inf(0.8), settings);
    Vec x0 = da.create_vector(), v0 = da.create_vector();
    const Eigen::Vector3d w(0.5, 3, 1), c0(0.5, 0.025, 0.05);
    da.set_nodal(x0, 0, [](const Eigen::Vector3d &X) { return X; });
    da.set_nodal(v0, 0, [&](const Eigen::Vector3d &X) { return Eigen::Vector3d(w.cross(X - c0)); });
    dynamics::DistState s = da.initial_state(x0, v0, 0.0), next;
    long iterations = 0, factorizations = 0;
    // The time steps in their own stage of -log_view (set-up and initial state apart).
    PetscLogStage stage;
    PetscLogStageRegister("Time steps", &stage);
    PetscLogStagePush(stage);
    const double t0 = MPI_Wtime();
    for (int n = 0; n < steps; ++n) {
      dynamics::StepInfo info;
      if (!da.advance(s, 1e-3, next, info))
        throw Error("step " + std::to_string(n + 1) + " failed");
      iterations += info.iterations;
      factorizations += info.factorizations;
      s = next;
    }
    const double wall = MPI_Wtime() - t0;
    PetscLogStagePop();
    // The peak resident set of each process (getrusage: MUMPS's Fortran allocations included,
    // which PETSc's own memory counters miss), the largest over the ranks.
    struct rusage usage;
    getrusage(RUSAGE_SELF, &usage);
    const double mem = 1024.0 * static_cast<double>(usage.ru_maxrss); // kB on Linux
    double maxmem;
    MPI_Allreduce(&mem, &maxmem, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
    if (root)
      std::printf("| %g | %lld | %d | %d | %.2f | %.2f | %.1f | %.2f | %.0f |\n", size,
                  static_cast<long long>(3 * m.global_nodes), comm_size(PETSC_COMM_WORLD), steps,
                  static_cast<double>(iterations) / steps,
                  static_cast<double>(factorizations) / steps, 1e3 * wall / steps,
                  1e3 * wall / static_cast<double>(iterations), maxmem / 1048576.0);
    VecDestroy(&x0);
    VecDestroy(&v0);
  } catch (const std::exception &e) {
    std::fprintf(stderr, "bench_acf_free_body: %s\n", e.what());
    status = 1;
  }
  PetscFinalize();
  return status;
}
