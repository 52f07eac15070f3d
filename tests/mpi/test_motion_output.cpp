// Output of moving mechanisms (io::MotionWriter). Three bodies of different element types
// (Tet10 and Hex8 beams distributed over the ranks, a one-hex body kept on rank 0) move with
// prescribed rigid motions; the HDF5 file read back holds every body's reference mesh and
// topology exactly and, at each step, positions equal to the prescribed motion. An unclosed
// writer leaves no result; misuse is a collective error. A timing test prints the cost per
// step. With FLEXOPT_MOTION_OUT set, the rigid-motion test writes into that directory and keeps
// its files plus expected.json (the ParaView test tests/paraview_motion.py opens them).
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/io/json.hpp"
#include "flexopt/io/motion_writer.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/mesh/grid_layout.hpp"
#include "test_meshes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <hdf5.h>
#include <unistd.h>

using namespace flexopt;
namespace fs = std::filesystem;

namespace {

/// One unit hex at `origin`, every node and the cell on rank 0 (other ranks contribute
/// nothing).
io::GridLayout single_hex_on_rank0(MPI_Comm comm, std::array<double, 3> origin) {
  io::GridLayout g;
  g.comm = comm;
  g.global_nodes = 8;
  g.global_cells = 1;
  g.nodes_per_cell = 8;
  g.topology_type = "Hexahedron";
  if (comm_rank(comm) == 0) {
    g.owned_nodes = 8;
    g.local_cells = 1;
    const int corner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                              {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    for (int a = 0; a < 8; ++a) {
      for (int i = 0; i < 3; ++i) g.owned_coordinates.push_back(origin[i] + 0.1 * corner[a][i]);
      g.cell_nodes.push_back(a);
    }
  }
  return g;
}

/// x(t) = pivot + R(axis, omega t) (X - pivot) + velocity t.
struct RigidMotion {
  int axis; ///< 0, 1, 2: rotation about x, y, z
  double omega;
  std::array<double, 3> pivot, velocity;

  std::array<double, 3> at(const double *X, double t) const {
    const double c = std::cos(omega * t), s = std::sin(omega * t);
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    std::array<double, 3> d{X[0] - pivot[0], X[1] - pivot[1], X[2] - pivot[2]}, x = d;
    x[i] = c * d[i] - s * d[j];
    x[j] = s * d[i] + c * d[j];
    for (int k = 0; k < 3; ++k) x[k] += pivot[k] + velocity[k] * t;
    return x;
  }
  std::vector<double> apply(const std::vector<double> &X, double t) const {
    std::vector<double> x(X.size());
    for (std::size_t n = 0; n < X.size() / 3; ++n) {
      const auto p = at(&X[3 * n], t);
      for (int k = 0; k < 3; ++k) x[3 * n + static_cast<std::size_t>(k)] = p[k];
    }
    return x;
  }
  io::Json json() const {
    io::Json j = io::Json::object();
    j["axis"] = axis;
    j["omega"] = omega;
    j["pivot"] = std::vector<double>(pivot.begin(), pivot.end());
    j["velocity"] = std::vector<double>(velocity.begin(), velocity.end());
    return j;
  }
};

/// A directory every rank sees: the one named by the environment variable `keep_env` if that
/// is given and set (files kept), else a fresh one under the temporary directory (removed by
/// the destructor).
struct OutDir {
  fs::path path;
  bool keep = false;
  explicit OutDir(const char *tag, const char *keep_env = nullptr) {
    const char *env = keep_env ? std::getenv(keep_env) : nullptr;
    keep = env && *env;
    std::string p;
    if (comm_rank(PETSC_COMM_WORLD) == 0) {
      p = keep ? std::string(env)
               : (fs::temp_directory_path() /
                  ("flexopt_" + std::string(tag) + "_" + std::to_string(::getpid())))
                     .string();
      if (!keep) fs::remove_all(p);
      fs::create_directories(p);
    }
    int n = static_cast<int>(p.size());
    MPI_Bcast(&n, 1, MPI_INT, 0, PETSC_COMM_WORLD);
    p.resize(static_cast<std::size_t>(n));
    MPI_Bcast(p.data(), n, MPI_CHAR, 0, PETSC_COMM_WORLD);
    path = p;
  }
  ~OutDir() {
    MPI_Barrier(PETSC_COMM_WORLD);
    if (!keep && comm_rank(PETSC_COMM_WORLD) == 0) fs::remove_all(path);
  }
};

/// Reads a whole dataset (serial HDF5, read-only) as doubles or long longs, with its dims.
template <class T>
std::vector<T> read_all(hid_t file, const std::string &path, std::vector<hsize_t> *dims = nullptr) {
  hid_t d = H5Dopen2(file, path.c_str(), H5P_DEFAULT);
  EXPECT_GE(d, 0) << "no dataset " << path;
  if (d < 0) return {};
  hid_t space = H5Dget_space(d);
  const int rank = H5Sget_simple_extent_ndims(space);
  std::vector<hsize_t> dd(static_cast<std::size_t>(rank));
  H5Sget_simple_extent_dims(space, dd.data(), nullptr);
  std::size_t n = 1;
  for (hsize_t v : dd) n *= v;
  std::vector<T> out(n);
  H5Dread(d, std::is_same_v<T, double> ? H5T_NATIVE_DOUBLE : H5T_NATIVE_LLONG, H5S_ALL, H5S_ALL,
          H5P_DEFAULT, out.data());
  H5Sclose(space);
  H5Dclose(d);
  if (dims) *dims = dd;
  return out;
}

std::string read_string_attribute(hid_t file, const std::string &object, const char *name) {
  hid_t a = H5Aopen_by_name(file, object.c_str(), name, H5P_DEFAULT, H5P_DEFAULT);
  if (a < 0) return "<missing>";
  hid_t type = H5Aget_type(a);
  std::string s(H5Tget_size(type), '\0');
  H5Aread(a, type, s.data());
  H5Tclose(type);
  H5Aclose(a);
  return s;
}

bool exists_on_root(const fs::path &p) {
  int e = comm_rank(PETSC_COMM_WORLD) == 0 && fs::exists(p) ? 1 : 0;
  MPI_Bcast(&e, 1, MPI_INT, 0, PETSC_COMM_WORLD);
  return e != 0;
}

} // namespace

TEST(MotionOutput, RigidMotionOfThreeBodiesReadsBackExactly) {
  const MPI_Comm comm = PETSC_COMM_WORLD;
  const int rank = comm_rank(comm), size = comm_size(comm);
  const auto arm_mesh = test_support::load_test_mesh("beam.geo", 0.05, 2);     // Tet10
  const auto link_mesh = test_support::load_test_mesh("beam_hex.geo", 0.0, 1); // Hex8
  std::vector<io::MotionBody> bodies = {
      {"arm", mesh::grid_layout(arm_mesh)},
      {"link", mesh::grid_layout(link_mesh)},
      {"pin", single_hex_on_rank0(comm, {1.0, 0.0, 0.0})},
  };
  const std::vector<RigidMotion> motions = {
      {2, 0.7, {0, 0, 0}, {0.1, -0.2, 0.05}},
      {0, -1.3, {0.5, 0.025, 0.05}, {0.0, 0.3, 0.0}},
      {1, 2.0, {1.05, 0.05, 0.05}, {-0.4, 0.0, 0.1}},
  };
  const std::vector<double> times = {0.0, 0.25, 0.5, 0.75, 1.0, 1.5};
  OutDir out("motion_rigid", "FLEXOPT_MOTION_OUT");

  {
    io::MotionWriter w(bodies, out.path.string(), "motion");
    EXPECT_EQ(w.bodies(), 3u);
    for (double t : times) {
      w.begin_step(t);
      for (std::size_t b = 0; b < bodies.size(); ++b) {
        const auto x = motions[b].apply(bodies[b].layout.owned_coordinates, t);
        w.positions(b, x.data());
        if (b == 0) {
          std::vector<double> u(x.size());
          for (std::size_t i = 0; i < x.size(); ++i)
            u[i] = x[i] - bodies[b].layout.owned_coordinates[i];
          w.node_vector(b, "displacement", u.data());
        }
        std::vector<double> r(static_cast<std::size_t>(bodies[b].layout.local_cells), rank);
        w.cell_scalar(b, "rank", r.data());
      }
    }
    EXPECT_EQ(w.steps(), times.size());
    const std::string xdmf = w.close();
    EXPECT_EQ(fs::path(xdmf), out.path / "motion.xdmf");
  }
  EXPECT_TRUE(exists_on_root(out.path / "motion.xdmf"));
  EXPECT_TRUE(exists_on_root(out.path / "motion.h5"));
  EXPECT_FALSE(exists_on_root(out.path / "motion.h5.tmp"));

  // Every rank reads its own rows: the reference mesh and topology are the layout's, bit for bit.
  hid_t file = H5Fopen((out.path / "motion.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  ASSERT_GE(file, 0);
  const char *types[] = {"Tetrahedron_10", "Hexahedron", "Hexahedron"};
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const io::GridLayout &g = bodies[b].layout;
    const std::string name = "/" + bodies[b].name;
    std::vector<hsize_t> dims;
    const auto ref = read_all<double>(file, name + "/reference_geometry", &dims);
    ASSERT_EQ(dims, (std::vector<hsize_t>{static_cast<hsize_t>(g.global_nodes), 3}));
    for (long long i = 0; i < 3 * g.owned_nodes; ++i)
      ASSERT_EQ(ref[static_cast<std::size_t>(3 * g.node_start + i)],
                g.owned_coordinates[static_cast<std::size_t>(i)]);
    const auto top = read_all<long long>(file, name + "/topology", &dims);
    ASSERT_EQ(dims, (std::vector<hsize_t>{static_cast<hsize_t>(g.global_cells),
                                          static_cast<hsize_t>(g.nodes_per_cell)}));
    for (long long i = 0; i < g.local_cells * g.nodes_per_cell; ++i)
      ASSERT_EQ(top[static_cast<std::size_t>(g.cell_start * g.nodes_per_cell + i)],
                g.cell_nodes[static_cast<std::size_t>(i)]);
    EXPECT_EQ(read_string_attribute(file, name + "/topology", "topology_type"), types[b]);
    EXPECT_EQ(g.topology_type, types[b]);
  }
  // Rank 0 checks every step of every body against the motion of the reference written.
  if (rank == 0) {
    EXPECT_EQ(read_all<double>(file, "/time"), times);
    double worst = 0;
    for (std::size_t b = 0; b < bodies.size(); ++b) {
      const std::string name = "/" + bodies[b].name;
      const auto ref = read_all<double>(file, name + "/reference_geometry");
      for (std::size_t k = 0; k < times.size(); ++k) {
        const std::string step = name + "/step_" + std::to_string(k);
        const auto x = read_all<double>(file, step + "/positions");
        const auto expected = motions[b].apply(ref, times[k]);
        ASSERT_EQ(x.size(), ref.size());
        for (std::size_t i = 0; i < x.size(); ++i) {
          worst = std::max(worst, std::abs(x[i] - expected[i]));
          ASSERT_NEAR(x[i], expected[i], 1e-14) << step << " value " << i;
        }
        if (b == 0) {
          const auto u = read_all<double>(file, step + "/displacement");
          for (std::size_t i = 0; i < x.size(); ++i)
            ASSERT_NEAR(u[i], expected[i] - ref[i], 1e-14) << step << " displacement " << i;
        }
        // The rank field: contiguous cell ranges in rank order, every rank present for the
        // distributed bodies, only rank 0 for the body kept there.
        const auto r = read_all<double>(file, step + "/rank");
        ASSERT_EQ(static_cast<long long>(r.size()), bodies[b].layout.global_cells);
        for (std::size_t i = 1; i < r.size(); ++i) ASSERT_LE(r[i - 1], r[i]);
        EXPECT_EQ(r.back(), b == 2 ? 0.0 : size - 1.0);
      }
    }
    EXPECT_EQ(worst, 0.0) << "positions are written bit for bit";
  }
  H5Fclose(file);

  if (out.keep && rank == 0) {
    io::Json j = io::Json::object();
    j["times"] = times;
    j["bodies"] = io::Json::array();
    for (std::size_t b = 0; b < bodies.size(); ++b) {
      io::Json e = motions[b].json();
      e["name"] = bodies[b].name;
      e["points"] = bodies[b].layout.global_nodes;
      e["cells"] = bodies[b].layout.global_cells;
      e["topology_type"] = bodies[b].layout.topology_type;
      j["bodies"].push_back(e);
    }
    io::write_file_atomic((out.path / "expected.json").string(), j.dump(2));
  }
}

/// A design's densities on a moving body: written once, shown in every step (those begun
/// before the field and after it), and read back as written; a reserved name is refused.
TEST(MotionOutput, ConstantCellFieldIsShownInEveryStep) {
  const MPI_Comm comm = PETSC_COMM_WORLD;
  const auto arm_mesh = test_support::load_test_mesh("beam.geo", 0.05, 2);
  const io::GridLayout arm = mesh::grid_layout(arm_mesh);
  OutDir out("motion_constant");
  std::string xdmf;
  {
    io::MotionWriter w({{"arm", arm}}, out.path.string(), "motion");
    std::vector<double> value(static_cast<std::size_t>(arm.local_cells));
    for (std::size_t i = 0; i < value.size(); ++i)
      value[i] = 0.5 + static_cast<double>(arm.cell_start + static_cast<long long>(i));
    for (int k = 0; k < 3; ++k) {
      w.begin_step(0.1 * k);
      w.positions(0, arm.owned_coordinates.data());
      if (k == 0) w.constant_cell_scalar(0, "physical_density", value.data());
    }
    try {
      w.constant_cell_scalar(0, "step_1", value.data());
      ADD_FAILURE() << "a reserved name was accepted";
    } catch (const Error &e) {
      EXPECT_TRUE(e.collective());
      EXPECT_NE(std::string(e.what()).find("reserved"), std::string::npos) << e.what();
    }
    xdmf = w.close();
  }
  if (comm_rank(comm) == 0) {
    hid_t file = H5Fopen((out.path / "motion.h5").c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    const auto d = read_all<double>(file, "/arm/physical_density");
    ASSERT_EQ(static_cast<long long>(d.size()), arm.global_cells);
    for (std::size_t i = 0; i < d.size(); ++i) ASSERT_EQ(d[i], 0.5 + static_cast<double>(i));
    H5Fclose(file);
    std::ifstream in(xdmf);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::size_t shown = 0;
    for (std::size_t at = text.find("motion.h5:/arm/physical_density"); at != std::string::npos;
         at = text.find("motion.h5:/arm/physical_density", at + 1))
      ++shown;
    EXPECT_EQ(shown, 3u) << "one Attribute per step";
  }
}

TEST(MotionOutput, UnclosedWriterLeavesNoResult) {
  const MPI_Comm comm = PETSC_COMM_WORLD;
  OutDir out("motion_unclosed");
  // A result of an earlier run is removed as soon as a new one starts.
  if (comm_rank(comm) == 0) io::write_file_atomic((out.path / "motion.xdmf").string(), "stale");
  MPI_Barrier(comm);
  {
    io::MotionWriter w({{"pin", single_hex_on_rank0(comm, {0, 0, 0})}}, out.path.string(),
                       "motion");
    w.begin_step(0.0);
    const io::GridLayout pin = single_hex_on_rank0(comm, {0, 0, 0});
    w.positions(0, pin.owned_coordinates.data());
    EXPECT_TRUE(exists_on_root(out.path / "motion.h5.tmp"));
    EXPECT_FALSE(exists_on_root(out.path / "motion.xdmf"));
  }
  EXPECT_FALSE(exists_on_root(out.path / "motion.h5.tmp"));
  EXPECT_FALSE(exists_on_root(out.path / "motion.h5"));
  EXPECT_FALSE(exists_on_root(out.path / "motion.xdmf"));
}

TEST(MotionOutput, MisuseIsACollectiveError) {
  const MPI_Comm comm = PETSC_COMM_WORLD;
  OutDir out("motion_misuse");
  const auto pin = single_hex_on_rank0(comm, {0, 0, 0});
  auto expect_collective = [](auto &&f, const char *what) {
    try {
      f();
      ADD_FAILURE() << what << ": no error";
    } catch (const Error &e) {
      EXPECT_TRUE(e.collective()) << what << ": " << e.what();
    }
  };
  expect_collective([&] { io::MotionWriter w({}, out.path.string(), "motion"); }, "no bodies");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a/b", pin}}, out.path.string(), "motion");
      },
      "name with '/'");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}, {"a", pin}}, out.path.string(), "motion");
      },
      "duplicate name");
  expect_collective(
      [&] {
        io::MotionWriter w({{"time", pin}}, out.path.string(), "motion");
      },
      "reserved name");
  io::GridLayout broken = pin;
  broken.global_nodes = 9; // ranges no longer tile the numbering
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", broken}}, out.path.string(), "motion");
      },
      "bad tiling");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}, {"b", pin}}, out.path.string(), "motion");
        w.begin_step(0.0);
        w.positions(0, pin.owned_coordinates.data());
        w.begin_step(1.0); // body "b" has no positions in step 0
      },
      "missing positions");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
        w.begin_step(1.0);
        w.positions(0, pin.owned_coordinates.data());
        w.begin_step(1.0);
      },
      "time not increasing");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
        w.positions(0, pin.owned_coordinates.data());
      },
      "positions before begin_step");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
        w.begin_step(0.0);
        w.positions(1, pin.owned_coordinates.data());
      },
      "body index out of range");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
        w.begin_step(0.0);
        w.positions(0, pin.owned_coordinates.data());
        w.node_vector(0, "positions", pin.owned_coordinates.data());
      },
      "reserved field name");
  expect_collective(
      [&] {
        io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
        w.begin_step(0.0);
        w.close();
      },
      "close with missing positions");
  // Every failed writer removed its temporary file; none produced a result.
  EXPECT_FALSE(exists_on_root(out.path / "motion.h5.tmp"));
  EXPECT_FALSE(exists_on_root(out.path / "motion.xdmf"));
  // No steps at all is a valid (empty) result.
  {
    io::MotionWriter w({{"a", pin}}, out.path.string(), "motion");
    w.close();
  }
  EXPECT_TRUE(exists_on_root(out.path / "motion.xdmf"));
}
