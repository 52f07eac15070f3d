// The element-count estimate made before Gmsh meshes a .geo's volumes (mesh.max_elements):
// within a factor of 2 of the real count for the repository's geometries at their case sizes,
// exact for structured hexahedral meshes, and without side effects on the mesh that follows.
#include "flexopt/core/error.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <cmath>
#include <cstdio>
#include <gmsh.h>
#include <gtest/gtest.h>
#include <string>

namespace {

using namespace flexopt;

/// A path relative to meshes/ (or to the source tree if it starts with "../").
std::string geometry(const std::string &name) {
  return std::string(FLEXOPT_SOURCE_DIR) + "/meshes/" + name;
}

struct Sample {
  const char *geo;
  double size;
  int order;
  double volume; ///< exact volume of the box [m^3]
  const char *cases;
};

// Tetrahedral meshes of the cases' bodies, at least 2 elements across. The factor kTetsPerCube
// was measured on rod.geo; beam.geo, bar.geo, simeon_rod.geo and bridge.geo check it. (A body
// one element thick is boundary-dominated and the estimate is low: link.geo at 0.05 m, its
// section, 0.27 times the count; docs/case-format.md.)
const Sample kTetSamples[] = {
    {"beam.geo", 0.0125, 2, 1.0 * 0.05 * 0.1, "cantilever, beam_modes"},
    {"bar.geo", 0.01, 2, 1.0 * 0.02 * 0.02, "flexible_pendulum"},
    {"simeon_rod.geo", 0.004, 2, 0.30 * 0.008 * 0.008, "slider_crank_flexible"},
    // Two volumes, a half-cylinder channel cut out (curved faces): the volume is the exact
    // 4 x 1 x 0.5 block minus the half cylinder of radius 0.6, to the chord error of the
    // coarse surface mesh (1 % allowed: sagitta of 0.21 m chords on a 0.6 m radius, 0.3 %).
    {"../cases/bridge_topopt/bridge.geo", 0.08, 1, 4.0 * 1.0 * 0.5 - M_PI * 0.36 / 2 * 0.5,
     "bridge_topopt"},
};

TEST(MeshEstimate, WithinAFactorOfTwoOfTheTetrahedralMeshesOfTheCases) {
  for (const Sample &s : kTetSamples) {
    SCOPED_TRACE(std::string(s.geo) + " at " + std::to_string(s.size) + " m (" + s.cases + ")");
    mesh::MeshEstimate seen, kept;
    mesh::MeshOptions options{s.size, s.order};
    options.before_meshing = [&](const mesh::MeshEstimate &e) { seen = e; };
    const mesh::MeshData m = mesh::read_gmsh(geometry(s.geo), options, &kept);
    const double elements = static_cast<double>(m.element_count());
    const double nodes = static_cast<double>(m.node_count());
    // Planar faces: the divergence-theorem volume is exact to round-off; curved: see above.
    const bool curved = std::string(s.geo).find("bridge") != std::string::npos;
    EXPECT_NEAR(kept.volume, s.volume, (curved ? 1e-2 : 1e-9) * s.volume);
    EXPECT_FALSE(kept.hexahedra);
    EXPECT_EQ(kept.element_name(), s.order == 2 ? "Tet10" : "Tet4");
    // The boundary curves are meshed at mesh.size (rounded up to whole segments).
    EXPECT_LE(kept.size, s.size * (1 + 1e-9));
    EXPECT_GT(kept.size, 0.5 * s.size);
    EXPECT_GT(kept.elements, 0.5 * elements);
    EXPECT_LT(kept.elements, 2.0 * elements);
    EXPECT_GT(kept.nodes, 0.5 * nodes);
    EXPECT_LT(kept.nodes, 2.0 * nodes);
    EXPECT_EQ(seen.elements, kept.elements); // the callback saw the same estimate
    std::printf("%s at %g m, order %d: estimate %.0f elements %.0f nodes, mesh %.0f elements "
                "%.0f nodes (ratio %.2f, %.2f)\n",
                s.geo, s.size, s.order, kept.elements, kept.nodes, elements, nodes,
                kept.elements / elements, kept.nodes / nodes);
  }
}

// Structured meshes: the 1D mesh fixes the count, and the geometric mean of the curves' segment
// lengths gives it exactly for a box with 4 curves per direction, in both Gmsh kernels.
TEST(MeshEstimate, ExactForStructuredHexahedra) {
  struct Hex {
    const char *geo;
    double volume;
    double elements;
  };
  for (const Hex &s : {Hex{"box_2x1x1_hex.geo", 2.0, 32.0 * 16 * 16},          // OpenCASCADE
                       Hex{"beam_hex.geo", 1.0 * 0.05 * 0.1, 40.0 * 4 * 6}}) { // built-in
    SCOPED_TRACE(s.geo);
    const mesh::MeshEstimate e = mesh::estimate_gmsh(geometry(s.geo), mesh::MeshOptions{});
    EXPECT_TRUE(e.hexahedra);
    EXPECT_EQ(e.element_name(), "Hex8");
    EXPECT_NEAR(e.volume, s.volume, 1e-9 * s.volume);
    EXPECT_NEAR(e.elements, s.elements, 1e-6 * s.elements);
    const mesh::MeshData m = mesh::read_gmsh(geometry(s.geo), mesh::MeshOptions{});
    EXPECT_EQ(static_cast<double>(m.element_count()), s.elements);
  }
}

// The estimate's coarse surface mesh is cleared and the size options restored: the mesh made
// afterwards is the one Gmsh makes without it.
TEST(MeshEstimate, LeavesTheMeshUnchanged) {
  const std::string geo = geometry("beam.geo");
  const mesh::MeshData m = mesh::read_gmsh(geo, mesh::MeshOptions{0.04, 2});
  gmsh::initialize(0, nullptr, false);
  gmsh::option::setNumber("General.Terminal", 0);
  gmsh::option::setNumber("Mesh.MeshSizeMax", 0.04);
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  gmsh::open(geo);
  gmsh::model::mesh::generate(3);
  gmsh::model::mesh::setOrder(2);
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> tags, nodes;
  gmsh::model::mesh::getElements(types, tags, nodes, 3, -1);
  std::vector<std::size_t> node_tags;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(node_tags, coords, param, -1, -1, false, false);
  gmsh::finalize();
  ASSERT_EQ(types.size(), 1u);
  EXPECT_EQ(static_cast<std::size_t>(m.element_count()), tags[0].size());
  EXPECT_EQ(static_cast<std::size_t>(m.node_count()), node_tags.size());
}

// A refusal in before_meshing passes through read_gmsh unchanged, before any volume meshing.
TEST(MeshEstimate, RefusalPassesThrough) {
  mesh::MeshOptions options{0.001, 1};
  double estimated = 0;
  options.before_meshing = [&](const mesh::MeshEstimate &e) {
    estimated = e.elements;
    throw Error("refused by the test");
  };
  try {
    mesh::read_gmsh(geometry("rod.geo"), options);
    FAIL() << "no exception";
  } catch (const Error &e) {
    EXPECT_STREQ(e.what(), "refused by the test");
  }
  // rod.geo: 0.5 x 0.04 x 0.04 m at 1 mm.
  EXPECT_NEAR(estimated, mesh::kTetsPerCube * 8e-4 / 1e-9, 0.01 * estimated);
}

// A size whose 1D mesh alone would be too large is estimated from mesh.size directly.
TEST(MeshEstimate, AbsurdSizeSkipsThe1DMesh) {
  const mesh::MeshEstimate e = mesh::estimate_gmsh(geometry("rod.geo"), mesh::MeshOptions{1e-7, 1});
  EXPECT_DOUBLE_EQ(e.size, 1e-7);
  EXPECT_NEAR(e.elements, mesh::kTetsPerCube * 8e-4 / 1e-21, 1e-9 * e.elements);
}

} // namespace
