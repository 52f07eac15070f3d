// Geometric multigrid on a structured Hex8 lattice (fem/lattice_multigrid.hpp) and the fast
// stiffness assembly, checked against exact facts on any number of ranks: the lattice of a
// transfinite box is found (and none in a tetrahedral mesh), the trilinear interpolation
// reproduces affine fields exactly on a graded lattice, a SIMP-contrast solve converges to the
// direct solver's answer, and the direct-array assembly gives MatSetValues' matrix bit for bit.
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/lattice_multigrid.hpp"
#include "flexopt/fem/matrix_free.hpp"
#include "flexopt/fem/static_problem.hpp"
#include "test_meshes.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <memory>
#include <unistd.h>

using namespace flexopt;

namespace {

/// A 2 x 1 x 1 transfinite Hex8 box of nx x ny x nz cells; with `graded`, the x and y lines
/// cluster towards both ends (Gmsh "Bump": symmetric, so opposite edges match and the nodes
/// still form a tensor lattice, with unequal spacing). Collective.
mesh::DistributedMesh box(int nx, int ny, int nz, bool graded) {
  const std::string dir = std::filesystem::temp_directory_path().string();
  const std::string geo = dir + "/flexopt_lattice_" + std::to_string(nx) + "_" +
                          std::to_string(graded) + "_" + std::to_string(::getpid()) + ".geo";
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    std::ofstream f(geo);
    f << "SetFactory(\"OpenCASCADE\");\nBox(1) = {0, 0, 0, 2, 1, 1};\neps = 1e-6;\n";
    // The 4 edges along each axis (ends at 0 and length[axis]) at the corners of the other two:
    // nx, ny, nz cells, the x and y edges graded.
    const int length[3] = {2, 1, 1}, cells[3] = {nx, ny, nz};
    for (int axis = 0; axis < 3; ++axis)
      for (int corner = 0; corner < 4; ++corner) {
        std::string lo[3], hi[3];
        for (int k = 0; k < 3; ++k) {
          const int at =
              k == axis ? 0 : ((k == (axis + 1) % 3 ? corner & 1 : corner & 2) ? length[k] : 0);
          lo[k] = std::to_string(at) + " - eps";
          hi[k] = std::to_string(k == axis ? length[k] : at) + " + eps";
        }
        f << "Transfinite Curve{Curve In BoundingBox{" << lo[0] << ", " << lo[1] << ", " << lo[2]
          << ", " << hi[0] << ", " << hi[1] << ", " << hi[2] << "}} = " << cells[axis] + 1
          << (graded && axis < 2 ? " Using Bump 0.4" : "") << ";\n";
      }
    f << "Transfinite Surface{:};\nRecombine Surface{:};\nTransfinite Volume{1};\n"
      << "Physical Volume(\"design\") = {1};\n"
      << "Physical Surface(\"clamp\") = Surface In BoundingBox{-eps, -eps, -eps, eps, 1 + eps, 1 + "
         "eps};\n";
  });
  mesh::MeshData data;
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    data = mesh::read_gmsh(geo, mesh::MeshOptions{0, 1});
    std::filesystem::remove(geo);
  });
  return mesh::distribute_mesh(PETSC_COMM_WORLD,
                               comm_rank(PETSC_COMM_WORLD) == 0 ? &data : nullptr);
}

/// The numbers of the points of stride s, as set_lattice_multigrid numbers them (ascending
/// fine global node number), with their coordinates.
std::vector<std::array<double, 3>> level_points(const fem::Lattice &L, PetscInt s) {
  std::vector<std::pair<PetscInt, std::array<double, 3>>> pts;
  for (PetscInt k = 0; k < L.points(2); k += s)
    for (PetscInt j = 0; j < L.points(1); j += s)
      for (PetscInt i = 0; i < L.points(0); i += s)
        pts.push_back(
            {L.node[static_cast<std::size_t>(i + L.points(0) * (j + L.points(1) * k))],
             {L.axis[0][static_cast<std::size_t>(i)], L.axis[1][static_cast<std::size_t>(j)],
              L.axis[2][static_cast<std::size_t>(k)]}});
  std::sort(pts.begin(), pts.end(), [](const auto &a, const auto &b) { return a.first < b.first; });
  std::vector<std::array<double, 3>> out;
  for (const auto &p : pts) out.push_back(p.second);
  return out;
}

/// u(x) = a + B x at each point, 3 components per point, into the rows [lo, hi) of v.
void set_affine(Vec v, const std::vector<std::array<double, 3>> &pts) {
  PetscInt lo = 0, hi = 0;
  FX_PETSC(VecGetOwnershipRange(v, &lo, &hi));
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  const double B[3][3] = {{0.3, -1.1, 0.7}, {2.0, 0.5, -0.4}, {-0.9, 1.3, 0.2}},
               c[3] = {1, -2, 0.5};
  for (PetscInt r = lo; r < hi; ++r) {
    const auto &x = pts[static_cast<std::size_t>(r / 3)];
    const int d = static_cast<int>(r % 3);
    a[r - lo] = c[d] + B[d][0] * x[0] + B[d][1] * x[1] + B[d][2] * x[2];
  }
  FX_PETSC(VecRestoreArray(v, &a));
}

} // namespace

TEST(LatticeMultigrid, FindsTheLatticeOfATransfiniteBoxAndNoneInATetMesh) {
  const auto m = box(8, 4, 6, false);
  const auto L = fem::find_lattice(m);
  ASSERT_TRUE(L.has_value());
  EXPECT_EQ(L->cells(0), 8);
  EXPECT_EQ(L->cells(1), 4);
  EXPECT_EQ(L->cells(2), 6);
  // 8 x 4 x 6 -> 4 x 2 x 3: the odd 3 stops the coarsening.
  const auto levels = fem::lattice_levels(*L, 0, 1);
  ASSERT_EQ(levels.size(), 2u);
  EXPECT_EQ(levels[1], (std::array<PetscInt, 3>{4, 2, 3}));
  EXPECT_EQ(fem::lattice_levels(*L, 1, 1).size(), 1u); // -lattice_mg_levels 1

  const auto tets = test_support::load_test_mesh("beam.geo", 0.03, 1);
  EXPECT_FALSE(fem::find_lattice(tets).has_value());
}

TEST(LatticeMultigrid, InterpolationReproducesAffineFieldsOnAGradedLattice) {
  const auto m = box(8, 8, 4, true);
  const auto L = fem::find_lattice(m);
  ASSERT_TRUE(L.has_value());
  // Graded: the x lines are not equally spaced.
  EXPECT_GT(std::abs((L->axis[0][1] - L->axis[0][0]) - (L->axis[0][4] - L->axis[0][3])), 1e-3);
  const auto levels = fem::lattice_levels(*L, 3, 0); // 8x8x4 -> 4x4x2 -> 2x2x1
  ASSERT_EQ(levels.size(), 3u);
  PC pc;
  // By default at least two halvings, however small the problem (a coarsest spacing of 4 cells).
  EXPECT_EQ(fem::lattice_levels(*L, 0, 1000000).size(), 3u);
  FX_PETSC(PCCreate(PETSC_COMM_WORLD, &pc));
  fem::set_lattice_multigrid(pc, m, *L, levels);
  for (int l = 1; l < 3; ++l) { // PCMG level l: from level l - 1 (coarser) to l
    Mat P;
    FX_PETSC(PCMGGetInterpolation(pc, l, &P));
    const PetscInt fine_stride = PetscInt(1) << (2 - l), coarse_stride = 2 * fine_stride;
    Vec xc, xf, expected;
    FX_PETSC(MatCreateVecs(P, &xc, &xf));
    FX_PETSC(VecDuplicate(xf, &expected));
    set_affine(xc, level_points(*L, coarse_stride));
    set_affine(expected, level_points(*L, fine_stride));
    FX_PETSC(MatMult(P, xc, xf));
    FX_PETSC(VecAXPY(xf, -1.0, expected));
    PetscReal err = 0, scale = 0;
    FX_PETSC(VecNorm(xf, NORM_INFINITY, &err));
    FX_PETSC(VecNorm(expected, NORM_INFINITY, &scale));
    EXPECT_LT(err, 1e-13 * scale) << "level " << l;
    VecDestroy(&xc), VecDestroy(&xf), VecDestroy(&expected);
  }
  PCDestroy(&pc);
}

TEST(LatticeMultigrid, SimpContrastSolveMatchesTheDirectSolver) {
  // Clamped at x = 0, a unit load on every DOF, modulus factors 1e-9 .. 1 in a checkerboard of
  // 2 x 2 x 2-cell blocks: the void/solid contrast of a SIMP design.
  const auto m = box(16, 8, 8, false);
  const fem::IsotropicMaterial mat{1.0, 0.3, 1.0};
  std::vector<double> factor(static_cast<std::size_t>(m.local_elements()));
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const fem::ElementCoords X = m.element_coordinates(e);
    const Eigen::Vector3d c = X.colwise().mean().transpose();
    const int block = static_cast<int>(c[0] / 0.25) + static_cast<int>(c[1] / 0.25) +
                      static_cast<int>(c[2] / 0.25);
    factor[static_cast<std::size_t>(e)] = block % 2 ? 1.0 : 1e-9;
  }
  std::vector<PetscInt> fixed;
  for (PetscInt g : m.surface_nodes.at("clamp"))
    for (int d = 0; d < 3; ++d) fixed.push_back(3 * g + d);
  enum Mode { direct, assembled, matrix_free };
  auto solve = [&](Mode mode, int *iterations) {
    Mat K = fem::create_matrix(m);
    fem::assemble_stiffness(m, mat, factor, K);
    FX_PETSC(MatZeroRowsColumns(K, static_cast<PetscInt>(fixed.size()), fixed.data(), 1.0, nullptr,
                                nullptr));
    Vec b, x;
    FX_PETSC(MatCreateVecs(K, &x, &b));
    FX_PETSC(VecSet(b, 1.0));
    std::vector<PetscScalar> zeros(fixed.size(), 0.0);
    FX_PETSC(VecSetValues(b, static_cast<PetscInt>(fixed.size()), fixed.data(), zeros.data(),
                          INSERT_VALUES));
    FX_PETSC(VecAssemblyBegin(b));
    FX_PETSC(VecAssemblyEnd(b));
    KSP ksp;
    FX_PETSC(KSPCreate(PETSC_COMM_WORLD, &ksp));
    FX_PETSC(KSPSetOptionsPrefix(ksp, "lattice_test_"));
    // 16 x 8 x 8 has 4131 DOFs, below the default coarsest size: ask for 2 levels.
    FX_PETSC(PetscOptionsSetValue(nullptr, "-lattice_test_lattice_mg_levels", "2"));
    const std::string how = fem::configure_elasticity_solver(ksp, K, m);
    std::unique_ptr<fem::MatrixFreeStiffness> mf;
    std::unique_ptr<fem::LatticeCoarseOperators> coarse;
    if (mode == matrix_free) { // the finest level without its matrix, the coarse ones from K
      mf = fem::MatrixFreeStiffness::create(m, mat);
      EXPECT_TRUE(mf);
      mf->set(factor, fixed, 1.0);
      PC pc;
      FX_PETSC(KSPGetPC(ksp, &pc));
      coarse = std::make_unique<fem::LatticeCoarseOperators>(pc);
      coarse->update(K);
      FX_PETSC(KSPSetOperators(ksp, mf->matrix(), K));
    }
    if (mode == direct) {
      FX_PETSC(KSPSetType(ksp, KSPPREONLY));
      PC pc;
      FX_PETSC(KSPGetPC(ksp, &pc));
      FX_PETSC(PCSetType(pc, PCLU));
      FX_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
    } else {
      EXPECT_NE(how.find("geometric multigrid on the 16 x 8 x 8 Hex8 lattice, 2 levels"),
                std::string::npos)
          << how;
      FX_PETSC(KSPSetTolerances(ksp, 1e-10, 1e-50, PETSC_DEFAULT, 500));
    }
    FX_PETSC(KSPSolve(ksp, b, x));
    KSPConvergedReason reason;
    FX_PETSC(KSPGetConvergedReason(ksp, &reason));
    EXPECT_GT(reason, 0) << how;
    PetscInt its = 0;
    FX_PETSC(KSPGetIterationNumber(ksp, &its));
    *iterations = static_cast<int>(its);
    KSPDestroy(&ksp), MatDestroy(&K), VecDestroy(&b);
    return x;
  };
  int its_direct = 0, its_mg = 0, its_mf = 0;
  Vec xd = solve(direct, &its_direct), xm = solve(assembled, &its_mg),
      xf = solve(matrix_free, &its_mf);
  PetscReal scale = 0, err = 0, err_mf = 0;
  FX_PETSC(VecNorm(xd, NORM_INFINITY, &scale));
  FX_PETSC(VecAXPY(xm, -1.0, xd));
  FX_PETSC(VecNorm(xm, NORM_INFINITY, &err));
  FX_PETSC(VecAXPY(xf, -1.0, xd));
  FX_PETSC(VecNorm(xf, NORM_INFINITY, &err_mf));
  // rtol 1e-10 on the preconditioned residual; the void blocks' displacements are 1e9 times
  // larger than the solid's and as accurate relative to the largest.
  EXPECT_LT(err, 1e-6 * scale) << its_mg << " iterations";
  EXPECT_LT(err_mf, 1e-6 * scale) << its_mf << " iterations";
  // The same operator and preconditioner to round-off: the same iterations (one more or less
  // where the residual crosses the tolerance within round-off).
  EXPECT_LE(std::abs(its_mf - its_mg), 1) << its_mf << " vs " << its_mg;
  VecDestroy(&xd), VecDestroy(&xm), VecDestroy(&xf);
}

// The matrix-free product is the assembled K with supports (rows and columns of the supported
// DOFs replaced by a scaled identity) to round-off, for SIMP factors of 1e9 contrast; a mesh
// with more element shapes than kept (a graded lattice) or of another type gets none.
TEST(MatrixFreeStiffness, ProductIsTheAssembledOperator) {
  const auto m = box(8, 4, 4, false);
  const fem::IsotropicMaterial mat{2.0, 0.3, 1.0};
  std::vector<double> factor(static_cast<std::size_t>(m.local_elements()));
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    factor[static_cast<std::size_t>(e)] = std::pow(
        1e-3 +
            std::fmod(0.37 * static_cast<double>(m.element_tags[static_cast<std::size_t>(e)]), 1.0),
        3);
  std::vector<PetscInt> fixed;
  for (PetscInt g : m.surface_nodes.at("clamp"))
    for (int d = 0; d < 3; ++d) fixed.push_back(3 * g + d);
  Mat K = fem::create_matrix(m);
  fem::assemble_stiffness(m, mat, factor, K);
  FX_PETSC(MatZeroRowsColumns(K, static_cast<PetscInt>(fixed.size()), fixed.data(), 0.7, nullptr,
                              nullptr));
  const auto mf = fem::MatrixFreeStiffness::create(m, mat);
  ASSERT_TRUE(mf);
  mf->set(factor, fixed, 0.7);
  Vec x, y, z;
  FX_PETSC(MatCreateVecs(K, &x, &y));
  FX_PETSC(VecDuplicate(y, &z));
  PetscRandom rng;
  FX_PETSC(PetscRandomCreate(PETSC_COMM_WORLD, &rng));
  FX_PETSC(VecSetRandom(x, rng));
  FX_PETSC(MatMult(K, x, y));
  FX_PETSC(MatMult(mf->matrix(), x, z));
  PetscReal scale = 0, err = 0;
  FX_PETSC(VecNorm(y, NORM_INFINITY, &scale));
  FX_PETSC(VecAXPY(z, -1.0, y));
  FX_PETSC(VecNorm(z, NORM_INFINITY, &err));
  // Sums of 8 element contributions of at most |K^0| |x| each, in another order.
  EXPECT_LT(err, 1e-14 * scale);
  PetscRandomDestroy(&rng), VecDestroy(&x), VecDestroy(&y), VecDestroy(&z), MatDestroy(&K);

  EXPECT_FALSE(fem::MatrixFreeStiffness::create(box(8, 8, 4, true), mat));
  EXPECT_FALSE(
      fem::MatrixFreeStiffness::create(test_support::load_test_mesh("beam.geo", 0.03, 1), mat));
}

TEST(LatticeMultigrid, DirectArrayAssemblyGivesMatSetValuesMatrixBitForBit) {
  const auto m = box(8, 4, 4, false);
  const fem::IsotropicMaterial mat{2.1e11, 0.3, 7850};
  std::vector<double> factor(static_cast<std::size_t>(m.local_elements()));
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    factor[static_cast<std::size_t>(e)] =
        1e-9 +
        std::fmod(0.37 * static_cast<double>(m.element_tags[static_cast<std::size_t>(e)]), 1.0);
  Mat A = fem::create_matrix(m), B = fem::create_matrix(m);
  fem::assemble_stiffness(m, mat, factor, A); // first assembly: MatSetValues
  fem::assemble_stiffness(m, mat, {}, B);     // sets B's pattern ...
  fem::assemble_stiffness(m, mat, factor, B); // ... then the direct adds
  FX_PETSC(MatAXPY(B, -1.0, A, SAME_NONZERO_PATTERN));
  PetscReal diff = 1;
  FX_PETSC(MatNorm(B, NORM_FROBENIUS, &diff));
  EXPECT_EQ(diff, 0.0);
  MatDestroy(&A), MatDestroy(&B);
}
