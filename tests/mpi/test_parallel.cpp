// Parallel mesh distribution and assembly, checked against exact facts on any number of
// ranks: the partition covers every element once, ghost coordinates agree with their owners,
// K annihilates rigid-body motion, M integrates the mass exactly, tractions integrate to
// force = traction x area, and a linear field is probed exactly.
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "test_meshes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <gmsh.h>
#include <gtest/gtest.h>
#include <numeric>

using namespace flexopt;

namespace {

// Beam of meshes/beam.geo: L x h x b.
constexpr double kL = 1.0, kH = 0.05, kB = 0.1;

struct MeshCase {
  int order;
  double size;
  const char *geometry = "beam.geo";
};

mesh::DistributedMesh load(MeshCase mc, mesh::MeshData *root_copy = nullptr) {
  return test_support::load_test_mesh(mc.geometry, mc.size, mc.order, root_copy);
}

class Parallel : public ::testing::TestWithParam<MeshCase> {};

} // namespace

TEST_P(Parallel, PartitionCoversEveryElementOnce) {
  mesh::MeshData root;
  auto m = load(GetParam(), &root);
  const int size = comm_size(m.comm), rank = comm_rank(m.comm);
  int n = static_cast<int>(m.element_tags.size());
  std::vector<int> counts(static_cast<std::size_t>(size)),
      displs(static_cast<std::size_t>(size), 0);
  MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, m.comm);
  std::vector<unsigned long> mine(m.element_tags.begin(), m.element_tags.end()), all;
  if (rank == 0) {
    for (int p = 1; p < size; ++p)
      displs[static_cast<std::size_t>(p)] =
          displs[static_cast<std::size_t>(p - 1)] + counts[static_cast<std::size_t>(p - 1)];
    all.resize(static_cast<std::size_t>(displs.back() + counts.back()));
  }
  MPI_Gatherv(mine.data(), n, MPI_UNSIGNED_LONG, all.data(), counts.data(), displs.data(),
              MPI_UNSIGNED_LONG, 0, m.comm);
  if (rank == 0) {
    std::sort(all.begin(), all.end());
    EXPECT_EQ(std::adjacent_find(all.begin(), all.end()), all.end())
        << "an element is on two ranks";
    std::vector<unsigned long> expected(root.element_tags.begin(), root.element_tags.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(all, expected);
    EXPECT_EQ(static_cast<long long>(all.size()), static_cast<long long>(m.global_elements));
    for (int p = 0; p < size; ++p)
      EXPECT_GT(counts[static_cast<std::size_t>(p)], 0) << "rank " << p << " got no elements";
  }
  // Owned node ranges are contiguous and cover all nodes.
  PetscInt owned = m.owned_nodes, total = 0, start = 0;
  MPI_Allreduce(&owned, &total, 1, MPIU_INT, MPI_SUM, m.comm);
  MPI_Exscan(&owned, &start, 1, MPIU_INT, MPI_SUM, m.comm);
  if (rank == 0) start = 0;
  EXPECT_EQ(total, m.global_nodes);
  EXPECT_EQ(start, m.node_start);
}

TEST_P(Parallel, GhostCoordinatesMatchOwners) {
  auto m = load(GetParam());
  Vec x = fem::create_ghosted_vector(m);
  PetscScalar *a;
  VecGetArray(x, &a);
  for (PetscInt i = 0; i < 3 * m.owned_nodes; ++i)
    a[i] = m.coordinates[static_cast<std::size_t>(i)];
  VecRestoreArray(x, &a);
  VecGhostUpdateBegin(x, INSERT_VALUES, SCATTER_FORWARD);
  VecGhostUpdateEnd(x, INSERT_VALUES, SCATTER_FORWARD);
  Vec local;
  VecGhostGetLocalForm(x, &local);
  const PetscScalar *l;
  VecGetArrayRead(local, &l);
  for (PetscInt i = 0; i < 3 * m.local_nodes(); ++i)
    ASSERT_EQ(l[i], m.coordinates[static_cast<std::size_t>(i)]);
  VecRestoreArrayRead(local, &l);
  VecGhostRestoreLocalForm(x, &local);
  VecDestroy(&x);
}

TEST_P(Parallel, StiffnessAnnihilatesRigidBodyMotion) {
  auto m = load(GetParam());
  Mat K = fem::create_matrix(m);
  fem::assemble_stiffness(m, fem::IsotropicMaterial{2.1e11, 0.3, 7850}, {}, K);
  Vec coords = fem::create_coordinate_vector(m);
  MatNullSpace ns;
  MatNullSpaceCreateRigidBody(coords, &ns);
  PetscBool has_const;
  PetscInt n;
  const Vec *vecs;
  MatNullSpaceGetVecs(ns, &has_const, &n, &vecs);
  ASSERT_EQ(n, 6);
  PetscReal knorm;
  MatNorm(K, NORM_INFINITY, &knorm);
  Vec r;
  VecDuplicate(coords, &r);
  for (PetscInt k = 0; k < n; ++k) {
    MatMult(K, vecs[k], r);
    PetscReal rn, vn;
    VecNorm(r, NORM_INFINITY, &rn);
    VecNorm(vecs[k], NORM_INFINITY, &vn);
    // Round-off of summing O(50) entries of size ||K|| per row.
    EXPECT_LT(rn, 1e-12 * knorm * vn) << "rigid mode " << k;
  }
  VecDestroy(&r);
  MatNullSpaceDestroy(&ns);
  VecDestroy(&coords);
  MatDestroy(&K);
}

TEST_P(Parallel, MassMatrixIntegratesTotalMass) {
  auto m = load(GetParam());
  const double rho = 7850;
  Mat M = fem::create_matrix(m);
  fem::assemble_mass(m, rho, {}, M);
  Vec ex, Mex;
  MatCreateVecs(M, &ex, &Mex);
  for (int dir = 0; dir < 3; ++dir) {
    VecZeroEntries(ex);
    VecStrideSet(ex, dir, 1.0);
    MatMult(M, ex, Mex);
    PetscScalar mass;
    VecDot(ex, Mex, &mass);
    EXPECT_NEAR(mass, rho * kL * kH * kB, 1e-12 * rho * kL * kH * kB) << "direction " << dir;
  }
  VecDestroy(&ex);
  VecDestroy(&Mex);
  MatDestroy(&M);
}

TEST_P(Parallel, TractionIntegratesToForce) {
  auto m = load(GetParam());
  Vec f = fem::create_ghosted_vector(m);
  VecZeroEntries(f);
  const Eigen::Vector3d t(1.0e6, -2.0e6, 3.0e5);
  fem::add_surface_traction(m, "tip", t, "test", f);
  for (int dir = 0; dir < 3; ++dir) {
    Vec comp;
    PetscScalar sum;
    VecCreateMPI(m.comm, m.owned_nodes, PETSC_DETERMINE, &comp);
    VecStrideGather(f, dir, comp, INSERT_VALUES);
    VecSum(comp, &sum);
    EXPECT_NEAR(sum, t[dir] * kH * kB, 1e-12 * std::abs(t[dir] * kH * kB)) << "direction " << dir;
    VecDestroy(&comp);
  }
  VecDestroy(&f);
}

// A total force F and a moment M about the centroid on the beam's tip face (fem::add_surface_force,
// the linear traction of docs/theory.md section 14.3): the consistent nodal loads sum to F and
// their moment about the centroid is M, to rounding (the traction is linear and the rule exact
// for N_a times a linear field on the flat straight-sided faces; Tet10's quadratic faces too).
TEST_P(Parallel, ForceAndMomentOnASurfaceIntegrateToThem) {
  auto m = load(GetParam());
  Vec f = fem::create_ghosted_vector(m);
  VecZeroEntries(f);
  const Eigen::Vector3d F(1.0e3, -2.0e3, 5.0e2), M(30.0, -20.0, 10.0);
  fem::add_surface_force(m, "tip", F, M, "test", f);
  const Eigen::Vector3d c = fem::surface_centroid(m, "tip", "test");
  double sum[6] = {0, 0, 0, 0, 0, 0};
  const PetscScalar *a = nullptr;
  VecGetArrayRead(f, &a);
  for (PetscInt i = 0; i < m.owned_nodes; ++i) {
    const Eigen::Vector3d fi(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
    const Eigen::Vector3d xi(m.coordinates[3 * i], m.coordinates[3 * i + 1],
                             m.coordinates[3 * i + 2]);
    const Eigen::Vector3d mi = (xi - c).cross(fi);
    for (int k = 0; k < 3; ++k) sum[k] += fi(k), sum[3 + k] += mi(k);
  }
  VecRestoreArrayRead(f, &a);
  MPI_Allreduce(MPI_IN_PLACE, sum, 6, MPI_DOUBLE, MPI_SUM, m.comm);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(sum[k], F(k), 1e-12 * F.norm()) << "force " << k;
    EXPECT_NEAR(sum[3 + k], M(k), 1e-12 * M.norm()) << "moment " << k;
  }
  VecDestroy(&f);
}

TEST_P(Parallel, ProbeInterpolatesLinearFieldExactly) {
  auto m = load(GetParam());
  Vec u = fem::create_ghosted_vector(m);
  Vec local;
  VecGhostGetLocalForm(u, &local);
  PetscScalar *a;
  VecGetArray(local, &a);
  auto field = [](const double *x, int k) {
    return 0.1 * (k + 1) * x[0] - 0.2 * x[1] + 0.3 * k * x[2] + 0.01 * k;
  };
  for (PetscInt i = 0; i < m.local_nodes(); ++i)
    for (int k = 0; k < 3; ++k)
      a[3 * i + k] = field(&m.coordinates[static_cast<std::size_t>(3 * i)], k);
  VecRestoreArray(local, &a);
  VecGhostRestoreLocalForm(u, &local);
  for (const std::array<double, 3> p :
       {std::array<double, 3>{0.37, 0.011, 0.093}, {1.0, 0.025, 0.05}, {0.0, 0.0, 0.0}}) {
    auto v = fem::probe_vector(m, u, p, "test probe");
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR(v[static_cast<std::size_t>(k)], field(p.data(), k), 1e-12);
  }
  EXPECT_THROW(fem::probe_vector(m, u, {2.0, 0.0, 0.0}, "outside"), Error);
  VecDestroy(&u);
}

// A line load on a physical curve integrates to force per length x length (the box's load
// edge has length 1), and matches the reference code's nodal loads: 0.001 per node, half at
// the two ends.
TEST(LineLoad, IntegratesToForceTimesLength) {
  auto m = test_support::load_test_mesh("box_2x1x1_hex.geo");
  Vec f = fem::create_ghosted_vector(m);
  VecZeroEntries(f);
  fem::add_surface_traction(m, "load_edge", Eigen::Vector3d(0, 0, -0.016), "test", f);
  PetscReal sum_abs, max_abs;
  VecNorm(f, NORM_1, &sum_abs);
  VecNorm(f, NORM_INFINITY, &max_abs);
  EXPECT_NEAR(sum_abs, 0.016, 1e-15);
  EXPECT_NEAR(max_abs, 0.001, 1e-16);
  VecDestroy(&f);
}

// A .msh (v4) file holds the same mesh as the .geo it was written from: the same elements,
// nodes and physical groups, and the same mesh once distributed.
TEST(MshFile, SameMeshAsTheGeoItCameFrom) {
  const std::string geo = std::string(FLEXOPT_SOURCE_DIR) + "/meshes/beam.geo";
  const std::string msh = (std::filesystem::temp_directory_path() /
                           ("flexopt_beam_" + std::to_string(::getpid()) + ".msh"))
                              .string();
  mesh::MeshData from_geo, from_msh;
  run_on_root(PETSC_COMM_WORLD, 0, [&] {
    from_geo = mesh::read_gmsh(geo, mesh::MeshOptions{0.04, 2});
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("Mesh.MeshSizeMax", 0.04);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
    gmsh::open(geo);
    gmsh::model::mesh::generate(3);
    gmsh::model::mesh::setOrder(2);
    gmsh::option::setNumber("Mesh.MshFileVersion", 4.1);
    gmsh::write(msh);
    gmsh::finalize();
    from_msh = mesh::read_gmsh(msh, mesh::MeshOptions{});
    std::remove(msh.c_str());
  });
  if (comm_rank(PETSC_COMM_WORLD) == 0) {
    EXPECT_EQ(from_msh.type, fem::ElementType::Tet10);
    EXPECT_EQ(from_msh.element_count(), from_geo.element_count());
    EXPECT_EQ(from_msh.node_count(), from_geo.node_count());
    ASSERT_EQ(from_msh.surface_groups.size(), 2u);
    for (const char *name : {"clamp", "tip"}) {
      ASSERT_TRUE(from_msh.surface_groups.count(name)) << name;
      EXPECT_EQ(from_msh.surface_groups.at(name).size(), from_geo.surface_groups.at(name).size())
          << name;
      EXPECT_EQ(from_msh.surface_groups.at(name).type, fem::FaceType::Tri6) << name;
    }
    EXPECT_EQ(from_msh.volume_groups.at("beam").size(),
              static_cast<std::size_t>(from_msh.element_count()));
    double volume = 0;
    const int npe = fem::nodes_per_element(from_msh.type);
    for (std::int64_t e = 0; e < from_msh.element_count(); ++e) {
      fem::ElementCoords X(npe, 3);
      for (int a = 0; a < npe; ++a)
        for (int k = 0; k < 3; ++k)
          X(a, k) = from_msh.coordinates[static_cast<std::size_t>(
              3 * from_msh.connectivity[static_cast<std::size_t>(e * npe + a)] + k)];
      volume += fem::element_volume(from_msh.type, X);
    }
    EXPECT_NEAR(volume, kL * kH * kB, 1e-12 * kL * kH * kB);
  }
  auto m = mesh::distribute_mesh(PETSC_COMM_WORLD,
                                 comm_rank(PETSC_COMM_WORLD) == 0 ? &from_msh : nullptr);
  long long n_geo = from_geo.element_count();
  MPI_Bcast(&n_geo, 1, MPI_LONG_LONG, 0, PETSC_COMM_WORLD);
  EXPECT_EQ(static_cast<long long>(m.global_elements), n_geo);
}

INSTANTIATE_TEST_SUITE_P(Meshes, Parallel,
                         ::testing::Values(MeshCase{1, 0.04}, MeshCase{2, 0.04},
                                           MeshCase{1, 0.0, "beam_hex.geo"}),
                         [](const auto &info) {
                           if (std::string(info.param.geometry) == "beam_hex.geo")
                             return std::string("Hex8");
                           return info.param.order == 1 ? std::string("Tet4")
                                                        : std::string("Tet10");
                         });
