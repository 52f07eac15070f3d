// Benchmark driver of the matrix-free finest level of the lattice multigrid (issue 23;
// scripts/bench/matvec.sh, docs/benchmarks.md "Matrix-free Hex8 product"): on a Hex8 mesh whose
// cells are translates of a few shapes (a uniform transfinite box), the product y = K x with
// K = sum_e rho_e^3 K_e^0 (the SIMP stiffness; rho_e pseudo-random in [0.001, 1]) two ways:
//   assembled:   MatMult of the MPIAIJ matrix that assemble_stiffness builds;
//   matrix-free: fem::MatrixFreeStiffness (ghost exchange, one 24 x 24 unit matrix per shape,
//                the ghost rows added back to their owners), as the solver applies it.
// Prints the DOFs, the matrix's stored entries and their bytes (value and column index), the mean
// wall time of a product each way over REPEAT products (between MPI_Barriers, after one warm-up
// product), their ratio and the largest relative difference of the two results (round-off: the
// same sums in another order).
//
//   mpirun -n N build/bench_hex8_matvec -geo BOX.geo [-repeat 50]
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/matrix_free.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/mesh/mesh_data.hpp"
#include "harness.hpp"

#include <cmath>
#include <cstdio>
#include <petscmat.h>
#include <string>
#include <vector>

using namespace flexopt;

namespace {

/// A number in [0, 1) from x (an element's Gmsh tag): the same on every rank count.
double hashed(double x) {
  const double y = std::sin(x * 12.9898 + 0.5) * 43758.5453;
  return y - std::floor(y);
}

/// Mean wall time [s] of `repeat` calls of f, between barriers, after one warm-up call.
template <class F> double mean_time(int repeat, F &&f) {
  f();
  MPI_Barrier(PETSC_COMM_WORLD);
  const double t0 = MPI_Wtime();
  for (int k = 0; k < repeat; ++k) f();
  MPI_Barrier(PETSC_COMM_WORLD);
  return (MPI_Wtime() - t0) / repeat;
}

/// max |a - b| / max |b|.
double relative_difference(Vec a, Vec b) {
  Vec d = nullptr;
  FX_PETSC(VecDuplicate(a, &d));
  FX_PETSC(VecWAXPY(d, -1.0, b, a));
  double num = 0, den = 0;
  FX_PETSC(VecNorm(d, NORM_INFINITY, &num));
  FX_PETSC(VecNorm(b, NORM_INFINITY, &den));
  FX_PETSC(VecDestroy(&d));
  return num / den;
}

void run(const std::string &geo, int repeat) {
  mesh::MeshData data;
  const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
  run_on_root(PETSC_COMM_WORLD, 0, [&] { data = mesh::read_gmsh(geo, mesh::MeshOptions{}); });
  const mesh::DistributedMesh m = mesh::distribute_mesh(PETSC_COMM_WORLD, root ? &data : nullptr);
  data = mesh::MeshData{};
  if (m.type != fem::ElementType::Hex8) throw Error(geo + ": not a Hex8 mesh", true);

  const fem::IsotropicMaterial material{1.0, 0.3, 1.0};
  std::vector<double> factor;
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const double rho = 0.001 + 0.999 * hashed(static_cast<double>(m.element_tags[e]));
    factor.push_back(rho * rho * rho);
  }
  const auto mf = fem::MatrixFreeStiffness::create(m, material);
  if (!mf)
    throw Error(geo + ": the cells are not translates of a few shapes (a graded lattice?)", true);
  mf->set(factor, {}, 1.0);
  Mat A = fem::create_matrix(m);
  fem::assemble_stiffness(m, material, factor, A);
  Vec x = nullptr, y_assembled = nullptr, y_free = nullptr;
  FX_PETSC(MatCreateVecs(A, &x, &y_assembled));
  FX_PETSC(VecDuplicate(y_assembled, &y_free));
  PetscRandom rng = nullptr;
  FX_PETSC(PetscRandomCreate(PETSC_COMM_WORLD, &rng));
  FX_PETSC(VecSetRandom(x, rng));
  FX_PETSC(PetscRandomDestroy(&rng));

  const double t_assembled = mean_time(repeat, [&] { FX_PETSC(MatMult(A, x, y_assembled)); });
  const double t_free = mean_time(repeat, [&] { FX_PETSC(MatMult(mf->matrix(), x, y_free)); });
  const double difference = relative_difference(y_free, y_assembled);

  MatInfo info;
  FX_PETSC(MatGetInfo(A, MAT_GLOBAL_SUM, &info));
  if (root) {
    // AIJ storage: a double and a column index per entry (the row offsets are negligible).
    std::printf("DOFs %lld elements %lld entries %.0f MiB %.0f repeat %d\n",
                static_cast<long long>(3 * m.global_nodes),
                static_cast<long long>(m.global_elements), info.nz_used,
                info.nz_used * (sizeof(PetscScalar) + sizeof(PetscInt)) / 1048576.0, repeat);
    std::printf("assembled MatMult   %.3f ms\n", 1e3 * t_assembled);
    std::printf("matrix-free product %.3f ms (%.2f of MatMult)\n", 1e3 * t_free,
                t_free / t_assembled);
    std::printf("difference %.2e (max |y_free - y_assembled| / max |y_assembled|)\n", difference);
  }
  FX_PETSC(VecDestroy(&x));
  FX_PETSC(VecDestroy(&y_assembled));
  FX_PETSC(VecDestroy(&y_free));
  FX_PETSC(MatDestroy(&A));
}

} // namespace

int main(int argc, char **argv) {
  return flexopt::bench::run_bench(argc, argv, "bench_hex8_matvec", [&] {
    char geo[PETSC_MAX_PATH_LEN] = "";
    PetscInt repeat = 50;
    PetscBool has_geo = PETSC_FALSE;
    PetscOptionsGetString(nullptr, nullptr, "-geo", geo, sizeof geo, &has_geo);
    PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr);
    if (!has_geo) throw Error("-geo BOX.geo (a transfinite Hex8 box) is required", true);
    if (repeat < 1) throw Error("-repeat: at least 1", true);
    run(geo, static_cast<int>(repeat));
  });
}
