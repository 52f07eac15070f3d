// Benchmark driver of the matrix-free Hex8 candidate of issue 23 (scripts/bench/matvec.sh,
// docs/solvers.md "Candidates"): on a structured Hex8 lattice (a transfinite box, every cell a
// translate of the first), the product y = K x with K = sum_e rho_e^3 K_e^0 (the SIMP stiffness;
// rho_e pseudo-random in [0.001, 1]) two ways:
//   assembled:   MatMult of the MPIAIJ matrix that assemble_stiffness builds (what the lattice
//                multigrid's fine level and CG apply);
//   matrix-free: the ghost values of x exchanged (VecGhostUpdate), then per element
//                y_e += rho_e^3 K^0 x_e with the one 24 x 24 unit matrix of the lattice, the
//                ghost rows added back to their owners (reverse scatter).
// Prints the DOFs, the matrix's stored entries and their bytes (value and column index), the mean
// wall time of a product each way over REPEAT products (between MPI_Barriers, after one warm-up
// product), their ratio and the largest relative difference of the two results (round-off: the same
// sums in another order). Also the matrix-free diagonal (what Jacobi or Chebyshev smoothing needs)
// against MatGetDiagonal.
//
//   mpirun -n N build/bench_hex8_matvec -geo BOX.geo [-repeat 50]
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <petscmat.h>
#include <string>
#include <vector>

using namespace flexopt;

namespace {

using Matrix24 = Eigen::Matrix<double, 24, 24>;
using Vector24 = Eigen::Matrix<double, 24, 1>;

/// A number in [0, 1) from x (an element's Gmsh tag): the same on every rank count.
double hashed(double x) {
  const double y = std::sin(x * 12.9898 + 0.5) * 43758.5453;
  return y - std::floor(y);
}

/// The matrix-free SIMP stiffness of a uniform Hex8 lattice.
struct MatrixFree {
  const mesh::DistributedMesh *mesh = nullptr;
  Matrix24 K0;                ///< the lattice's unit-modulus element matrix
  std::vector<double> factor; ///< rho_e^3 per local element
  Vec xg = nullptr, yg = nullptr;

  /// y = K x.
  void apply(Vec x, Vec y) const {
    const PetscInt owned = 3 * mesh->owned_nodes;
    {
      const double *xa = nullptr;
      double *g = nullptr;
      FX_PETSC(VecGetArrayRead(x, &xa));
      FX_PETSC(VecGetArray(xg, &g));
      std::copy(xa, xa + owned, g);
      FX_PETSC(VecRestoreArray(xg, &g));
      FX_PETSC(VecRestoreArrayRead(x, &xa));
    }
    FX_PETSC(VecGhostUpdateBegin(xg, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecGhostUpdateEnd(xg, INSERT_VALUES, SCATTER_FORWARD));
    Vec xl = nullptr, yl = nullptr;
    FX_PETSC(VecGhostGetLocalForm(xg, &xl));
    FX_PETSC(VecGhostGetLocalForm(yg, &yl));
    FX_PETSC(VecSet(yl, 0.0));
    const double *u = nullptr;
    double *v = nullptr;
    FX_PETSC(VecGetArrayRead(xl, &u));
    FX_PETSC(VecGetArray(yl, &v));
    const PetscInt *conn = mesh->connectivity.data();
    for (PetscInt e = 0; e < mesh->local_elements(); ++e, conn += 8) {
      Vector24 ue;
      for (int a = 0; a < 8; ++a)
        for (int i = 0; i < 3; ++i) ue[3 * a + i] = u[3 * conn[a] + i];
      const Vector24 ye = factor[static_cast<std::size_t>(e)] * (K0 * ue);
      for (int a = 0; a < 8; ++a)
        for (int i = 0; i < 3; ++i) v[3 * conn[a] + i] += ye[3 * a + i];
    }
    FX_PETSC(VecRestoreArray(yl, &v));
    FX_PETSC(VecRestoreArrayRead(xl, &u));
    FX_PETSC(VecGhostRestoreLocalForm(yg, &yl));
    FX_PETSC(VecGhostRestoreLocalForm(xg, &xl));
    sum_into(y);
  }

  /// diag(K), element by element (the ghost rows added back to their owners).
  void diagonal(Vec d) const {
    Vec yl = nullptr;
    FX_PETSC(VecGhostGetLocalForm(yg, &yl));
    FX_PETSC(VecSet(yl, 0.0));
    double *v = nullptr;
    FX_PETSC(VecGetArray(yl, &v));
    const PetscInt *conn = mesh->connectivity.data();
    for (PetscInt e = 0; e < mesh->local_elements(); ++e, conn += 8)
      for (int a = 0; a < 8; ++a)
        for (int i = 0; i < 3; ++i)
          v[3 * conn[a] + i] += factor[static_cast<std::size_t>(e)] * K0(3 * a + i, 3 * a + i);
    FX_PETSC(VecRestoreArray(yl, &v));
    FX_PETSC(VecGhostRestoreLocalForm(yg, &yl));
    sum_into(d);
  }

  /// out = the owned part of yg after its ghost rows are added to their owners.
  void sum_into(Vec out) const {
    FX_PETSC(VecGhostUpdateBegin(yg, ADD_VALUES, SCATTER_REVERSE));
    FX_PETSC(VecGhostUpdateEnd(yg, ADD_VALUES, SCATTER_REVERSE));
    const double *ya = nullptr;
    double *o = nullptr;
    FX_PETSC(VecGetArrayRead(yg, &ya));
    FX_PETSC(VecGetArray(out, &o));
    std::copy(ya, ya + 3 * mesh->owned_nodes, o);
    FX_PETSC(VecRestoreArray(out, &o));
    FX_PETSC(VecRestoreArrayRead(yg, &ya));
  }
};

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

  // The unit matrix of the lattice: every element must be a translate of the first.
  const fem::IsotropicMaterial material{1.0, 0.3, 1.0};
  fem::UnitStiffness unit(m.type, material);
  MatrixFree mf;
  mf.mesh = &m;
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const fem::ElementMatrix &K = unit(m.element_coordinates(e));
    if (e == 0) mf.K0 = K;
    const double rho = 0.001 + 0.999 * hashed(static_cast<double>(m.element_tags[e]));
    mf.factor.push_back(rho * rho * rho);
  }
  int shapes = unit.computed(), most = 0;
  MPI_Allreduce(&shapes, &most, 1, MPI_INT, MPI_MAX, PETSC_COMM_WORLD);
  if (most != 1)
    throw Error(geo + ": the cells are not translates of one another (" + std::to_string(most) +
                    " element shapes): not a uniform lattice",
                true);

  Mat A = fem::create_matrix(m);
  fem::assemble_stiffness(m, material, mf.factor, A);
  mf.xg = fem::create_ghosted_vector(m);
  FX_PETSC(VecDuplicate(mf.xg, &mf.yg));
  Vec x = nullptr, y_assembled = nullptr, y_free = nullptr;
  FX_PETSC(MatCreateVecs(A, &x, &y_assembled));
  FX_PETSC(VecDuplicate(y_assembled, &y_free));
  PetscRandom rng = nullptr;
  FX_PETSC(PetscRandomCreate(PETSC_COMM_WORLD, &rng));
  FX_PETSC(VecSetRandom(x, rng));
  FX_PETSC(PetscRandomDestroy(&rng));

  const double t_assembled = mean_time(repeat, [&] { FX_PETSC(MatMult(A, x, y_assembled)); });
  const double t_free = mean_time(repeat, [&] { mf.apply(x, y_free); });
  const double difference = relative_difference(y_free, y_assembled);
  FX_PETSC(MatGetDiagonal(A, y_assembled));
  mf.diagonal(y_free);
  const double diagonal_difference = relative_difference(y_free, y_assembled);

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
    std::printf("difference %.2e (max |y_free - y_assembled| / max |y_assembled|), diagonal %.2e\n",
                difference, diagonal_difference);
  }
  FX_PETSC(VecDestroy(&x));
  FX_PETSC(VecDestroy(&y_assembled));
  FX_PETSC(VecDestroy(&y_free));
  FX_PETSC(VecDestroy(&mf.xg));
  FX_PETSC(VecDestroy(&mf.yg));
  FX_PETSC(MatDestroy(&A));
}

} // namespace

int main(int argc, char **argv) {
  int status = 0;
  try {
    Context ctx(&argc, &argv, nullptr);
    try {
      char geo[PETSC_MAX_PATH_LEN] = "";
      PetscInt repeat = 50;
      PetscBool has_geo = PETSC_FALSE;
      PetscOptionsGetString(nullptr, nullptr, "-geo", geo, sizeof geo, &has_geo);
      PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr);
      if (!has_geo) throw Error("-geo BOX.geo (a transfinite Hex8 box) is required", true);
      if (repeat < 1) throw Error("-repeat: at least 1", true);
      run(geo, static_cast<int>(repeat));
    } catch (const std::exception &e) {
      if (comm_rank(PETSC_COMM_WORLD) == 0)
        std::fprintf(stderr, "bench_hex8_matvec: %s\n", e.what());
      status = 1;
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "bench_hex8_matvec: %s\n", e.what());
    status = 1;
  }
  return status;
}
