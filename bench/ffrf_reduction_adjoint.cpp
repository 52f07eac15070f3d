// Benchmark driver of the FFRF reduction adjoint (scripts/bench/ffrf_adjoint.sh,
// docs/benchmarks.md "FFRF reduction adjoint"): the steel beam of meshes/beam.geo (Tet10,
// 1 m x 50 x 100 mm) meshed at SIZE, a design body with a pseudo-random density rho_e in
// [0.6, 1] per element (from its Gmsh tag; stiffness factor rho^3, mass factor rho), reduced by
// reduce::reduce_flexible_body with the element factors and differentiated by
// reduce::reduction_adjoint with cotangents that have random entries in every reduced quantity
// (K_r, M_r, every invariant, the interface maps, the geometric stiffness if any, the basis
// vectors). Configurations:
//   a: interfaces clamp and tip, chord frame, no geometric stiffening;
//   b: interface clamp alone, frame clamped there, centrifugal geometric stiffening.
// Per configuration one table row: DOFs, elements, basis size, the reduction's wall time, the
// adjoint's (exact basis derivative, 1 response), its ratio to the reduction, the same for 4
// responses at once, the adjoint with the basis held fixed, the conjugate-gradient iterations
// of the fixed-interface modes, the largest peak resident set of a rank after the reduction
// and after the adjoints (getrusage: MUMPS's Fortran allocations included), and the resident
// memory the reduction keeps (current resident set after it minus before it, summed over the
// ranks: K, M, the vectors and the MUMPS factorization of the adjoint data). Times: wall clock
// between MPI_Barriers, the best of REPEAT adjoint calls (default 1). -config: the configurations
// to run (a, b or ab, each a separate line; the peak memory is the process's). -gauge frozen: the
// basis differentiated in frozen Craig-Bampton coordinates (the dynamic adjoint's), else
// orthonormal.
//
//   mpirun -n N build/bench_ffrf_reduction_adjoint -size H [-modes 8] [-config ab] [-repeat 1]
//          [-gauge orthonormal|frozen] [PETSc options, e.g. -log_view or -eps_view ascii:FILE for
//          MUMPS's factor statistics]
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/mesh/mesh_data.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/reduction_adjoint.hpp"
#include "harness.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <petscsys.h>
#include <random>
#include <string>
#include <sys/resource.h>
#include <unistd.h>
#include <vector>

using namespace flexopt;

namespace {

using Matrix = Eigen::MatrixXd;

/// A number in [0, 1) from x (an element's Gmsh tag, a node's position): the same on every rank
/// count.
double hashed(double x, double salt) {
  const double y = std::sin(x * 12.9898 + salt) * 43758.5453;
  return y - std::floor(y);
}

/// Peak resident set of this process [MiB] (getrusage; kB on Linux).
double peak_rss_mib() {
  struct rusage usage;
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

/// Current resident set of this process [MiB] (/proc/self/statm).
double current_rss_mib() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0, resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) / 1048576.0;
}

double max_over_ranks(double x) {
  double y;
  MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  return y;
}

double sum_over_ranks(double x) {
  double y;
  MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, MPI_SUM, PETSC_COMM_WORLD);
  return y;
}

/// One cotangent with random entries (uniform in [-1, 1], seeded: the same on every rank) in
/// every reduced quantity of `r`; its basis part is written into `basis` (full-size vectors,
/// owned by the caller), a function of the node positions (the same on every rank count).
reduce::ReductionCotangent random_cotangent(const mesh::DistributedMesh &m,
                                            const reduce::FlexibleReduction &r, unsigned seed,
                                            std::vector<Vec> &basis) {
  const int n = r.size();
  std::mt19937 gen(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  auto random = [&](int rows, int cols) {
    Matrix A(rows, cols);
    for (int j = 0; j < cols; ++j)
      for (int i = 0; i < rows; ++i) A(i, j) = u(gen);
    return A;
  };
  const double kscale = 1.0 / r.K.cwiseAbs().maxCoeff();
  reduce::ReductionCotangent b;
  b.K = kscale * random(n, n);
  b.M = random(n, n);
  b.invariants.mass = u(gen);
  b.invariants.d0 = random(3, 1);
  b.invariants.S0 = random(3, 3);
  b.invariants.D = random(3, n);
  for (int k = 0; k < n; ++k) b.invariants.S1.push_back(random(3, 3));
  b.invariants.S2.assign(static_cast<std::size_t>(n), {});
  for (int k = 0; k < n; ++k)
    for (int l = 0; l < n; ++l)
      b.invariants.S2[static_cast<std::size_t>(k)].push_back(random(3, 3));
  for (std::size_t i = 0; i < r.translation.size(); ++i) b.translation.push_back(random(3, n));
  for (std::size_t i = 0; i < r.rotation.size(); ++i) b.rotation.push_back(random(3, n));
  for (std::size_t c = 0; c < r.geometric.size(); ++c) b.geometric.push_back(kscale * random(n, n));
  for (int k = 0; k < n; ++k) {
    Vec v;
    VecDuplicate(r.basis[0], &v);
    PetscScalar *a;
    VecGetArray(v, &a);
    for (PetscInt i = 0; i < m.owned_nodes; ++i)
      for (int c = 0; c < 3; ++c) {
        const double *X = &m.coordinates[3 * static_cast<std::size_t>(i)];
        a[3 * i + c] = 2 * hashed(1e3 * X[0] + 1e2 * X[1] + 1e1 * X[2] + c, seed + 0.1 * k) - 1;
      }
    VecRestoreArray(v, &a);
    basis.push_back(v);
    b.basis.push_back(v);
  }
  return b;
}

struct Configuration {
  std::string name;
  std::vector<std::string> interfaces;
  bool stiffening;
  reduce::FrameCondition frame;
};

/// The best wall time of `repeat` calls of the adjoint (barriers around each), in the -log_view
/// stage `stage`.
double time_adjoint(const mesh::DistributedMesh &m, const reduce::FlexibleReduction &r,
                    const std::vector<reduce::ReductionCotangent> &bars,
                    reduce::BasisDerivative mode, reduce::BasisGauge gauge, int repeat,
                    const std::string &stage, int &cg) {
  PetscLogStage id;
  PetscLogStageRegister(stage.c_str(), &id);
  PetscLogStagePush(id);
  double best = 1e300;
  std::vector<std::vector<double>> s_hat, w_hat;
  for (int k = 0; k < repeat; ++k) {
    MPI_Barrier(PETSC_COMM_WORLD);
    const double t0 = MPI_Wtime();
    const auto stats = reduce::reduction_adjoint(m, r, bars, mode, s_hat, w_hat, gauge);
    MPI_Barrier(PETSC_COMM_WORLD);
    best = std::min(best, MPI_Wtime() - t0);
    cg = stats.cg_iterations;
  }
  PetscLogStagePop();
  return best;
}

void run(const mesh::DistributedMesh &m, const Configuration &c, int modes, int repeat,
         reduce::BasisGauge gauge, double size) {
  const PetscInt ne = m.local_elements();
  reduce::ElementFactors f;
  for (PetscInt e = 0; e < ne; ++e) {
    const double tag = static_cast<double>(m.element_tags[static_cast<std::size_t>(e)]);
    const double rho = 0.6 + 0.4 * hashed(tag, 0.0);
    f.stiffness.push_back(rho * rho * rho);
    f.mass.push_back(rho);
  }
  const double rss_before = current_rss_mib();
  auto r = std::make_unique<reduce::FlexibleReduction>();
  // The reduction and each adjoint call in their own stages of -log_view.
  PetscLogStage reduction_stage;
  PetscLogStageRegister(("Reduction " + c.name).c_str(), &reduction_stage);
  PetscLogStagePush(reduction_stage);
  MPI_Barrier(PETSC_COMM_WORLD);
  const double t0 = MPI_Wtime();
  reduce::reduce_flexible_body(m, fem::IsotropicMaterial{2.1e11, 0.3, 7850}, c.interfaces, modes,
                               c.stiffening, *r, c.frame, &f);
  MPI_Barrier(PETSC_COMM_WORLD);
  const double reduction = MPI_Wtime() - t0;
  PetscLogStagePop();
  const double kept = sum_over_ranks(current_rss_mib() - rss_before);
  const double peak_reduction = max_over_ranks(peak_rss_mib());

  std::vector<Vec> basis_bars;
  std::vector<reduce::ReductionCotangent> bars;
  for (unsigned i = 0; i < 4; ++i) bars.push_back(random_cotangent(m, *r, 7 + i, basis_bars));
  const std::vector<reduce::ReductionCotangent> one(bars.begin(), bars.begin() + 1);
  int cg1 = 0, cg4 = 0, cg_fixed = 0;
  const std::string tag = c.name.substr(0, 1);
  const double exact1 = time_adjoint(m, *r, one, reduce::BasisDerivative::Exact, gauge, repeat,
                                     "Adjoint " + tag + " exact 1", cg1);
  const double exact4 = time_adjoint(m, *r, bars, reduce::BasisDerivative::Exact, gauge, repeat,
                                     "Adjoint " + tag + " exact 4", cg4);
  const double fixed = time_adjoint(m, *r, one, reduce::BasisDerivative::Fixed, gauge, repeat,
                                    "Adjoint " + tag + " fixed 1", cg_fixed);
  const double peak_adjoint = max_over_ranks(peak_rss_mib());
  for (Vec &v : basis_bars) VecDestroy(&v);

  print0(PETSC_COMM_WORLD,
         "| %s | %g | %lld | %lld | %d + %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.3f | %d / %d | "
         "%.0f | %.0f | %.0f |\n",
         c.name.c_str(), size, static_cast<long long>(3 * m.global_nodes),
         static_cast<long long>(m.global_elements), r->static_modes, r->fixed_modes, reduction,
         exact1, exact1 / reduction, exact4, exact4 / reduction, fixed, cg1, cg4, peak_reduction,
         peak_adjoint, kept);
}

} // namespace

int main(int argc, char **argv) {
  return flexopt::bench::run_bench(argc, argv, "bench_ffrf_reduction_adjoint", [&] {
    PetscReal size = 0;
    PetscInt modes = 8, repeat = 1;
    char config[16] = "ab", gauge_name[32] = "orthonormal";
    PetscBool has_size = PETSC_FALSE;
    PetscOptionsGetReal(nullptr, nullptr, "-size", &size, &has_size);
    PetscOptionsGetInt(nullptr, nullptr, "-modes", &modes, nullptr);
    PetscOptionsGetInt(nullptr, nullptr, "-repeat", &repeat, nullptr);
    PetscOptionsGetString(nullptr, nullptr, "-config", config, sizeof config, nullptr);
    PetscOptionsGetString(nullptr, nullptr, "-gauge", gauge_name, sizeof gauge_name, nullptr);
    const std::string gauge_option(gauge_name);
    if (gauge_option != "orthonormal" && gauge_option != "frozen")
      throw Error("-gauge: orthonormal or frozen, not '" + gauge_option + "'", true);
    const reduce::BasisGauge gauge = gauge_option == "frozen"
                                         ? reduce::BasisGauge::FrozenCoordinates
                                         : reduce::BasisGauge::Orthonormal;
    if (!has_size || size <= 0) throw Error("-size H (mesh size [m]) is required", true);
    mesh::MeshData data;
    const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/beam.geo";
    const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
    const double t0 = MPI_Wtime();
    run_on_root(PETSC_COMM_WORLD, 0, [&] {
      data = mesh::read_gmsh(geo, mesh::MeshOptions{size, 2});
    });
    const mesh::DistributedMesh m = mesh::distribute_mesh(PETSC_COMM_WORLD, root ? &data : nullptr);
    data = mesh::MeshData{};
    if (root)
      std::fprintf(stderr, "mesh size %g: %lld DOFs, %lld Tet10 elements, %.1f s (Gmsh, METIS)\n",
                   size, static_cast<long long>(3 * m.global_nodes),
                   static_cast<long long>(m.global_elements), MPI_Wtime() - t0);
    const std::string which(config);
    if (which.find('a') != std::string::npos)
      run(m,
          Configuration{
              "a: clamp + tip, chord", {"clamp", "tip"}, false, reduce::FrameCondition::Chord},
          static_cast<int>(modes), static_cast<int>(repeat), gauge, size);
    if (which.find('b') != std::string::npos)
      run(m,
          Configuration{
              "b: clamp, clamped, stiffened", {"clamp"}, true, reduce::FrameCondition::Clamped},
          static_cast<int>(modes), static_cast<int>(repeat), gauge, size);
  });
}
