#include "flexopt/io/motion_writer.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/io/json.hpp"
#include "h5_overhead.hpp"
#include "hdf5_check.hpp"

#include <cstdio>
#include <filesystem>
#include <hdf5.h>
#include <optional>
#include <sstream>

namespace flexopt::io {

namespace {

using detail::h5check;
using detail::h5id;
using detail::unwritable_reason;

/// Text for an XML attribute value or element content.
std::string xml_escape(const std::string &s) {
  std::string out;
  for (char c : s) {
    switch (c) {
    case '&':
      out += "&amp;";
      break;
    case '<':
      out += "&lt;";
      break;
    case '>':
      out += "&gt;";
      break;
    case '"':
      out += "&quot;";
      break;
    case '\'':
      out += "&apos;";
      break;
    default:
      out += c;
    }
  }
  return out;
}

/// Empty if `name` can be an HDF5 link name of ours, else why not.
std::string bad_name(const std::string &name) {
  if (name.empty()) return "is empty";
  if (name == "." || name == "..") return "is '" + name + "'";
  if (name.find('/') != std::string::npos) return "contains '/'";
  return {};
}

struct Field {
  std::string name;
  bool cell = false;
  bool vector = false;
  std::string dataset;
};

struct BodyStep {
  bool has_positions = false;
  std::vector<Field> fields;
};

struct Step {
  double time = 0;
  std::vector<BodyStep> bodies;
};

} // namespace

struct MotionWriter::Impl {
  std::vector<MotionBody> bodies;
  MPI_Comm comm = MPI_COMM_NULL;
  int rank = 0;
  std::string directory, basename, h5_final, h5_tmp, xdmf_final;
  hid_t file = -1;
  hid_t dxpl = -1; ///< independent MPI-IO transfer (each rank writes one contiguous block)
  hid_t dcpl = -1; ///< no fill value: every element is written once
  hid_t lcpl = -1; ///< creates /<body>/step_K on the first dataset of a step
  std::vector<Step> steps;
  std::vector<std::vector<Field>> constants; ///< per body: fields shown in every step
  bool closed = false;
  std::optional<detail::SpaceGuard> space; ///< of h5_tmp's file system

  /// Error path (also when the writer's constructor throws, which runs no writer destructor):
  /// drop the incomplete file so nothing valid-looking remains.
  ~Impl() {
    release_properties();
    if (!closed && file >= 0) {
      H5Fclose(file);
      if (rank == 0) std::remove(h5_tmp.c_str());
    }
  }

  /// Creates a dataset [global_rows x cols] (1D if cols == 1) and writes this rank's rows
  /// [start, start + rows) into it. The creation is collective; the write is independent (a
  /// rank without rows writes nothing), which measured about twice as fast as a collective
  /// write for these contiguous blocks. `data` may be null when rows == 0.
  void write_rows(const std::string &path, hid_t mem_type, hid_t file_type, const void *data,
                  long long global_rows, long long start, long long rows, int cols) {
    space->require(global_rows * cols * 8);
    const int rank_dims = cols == 1 ? 1 : 2;
    hsize_t gdims[2] = {static_cast<hsize_t>(global_rows), static_cast<hsize_t>(cols)};
    hid_t fspace = h5id(H5Screate_simple(rank_dims, gdims, nullptr), "H5Screate_simple");
    hid_t dset = h5id(H5Dcreate2(file, path.c_str(), file_type, fspace, lcpl, dcpl, H5P_DEFAULT),
                      "creating dataset " + path);
    if (rows > 0) {
      hsize_t offset[2] = {static_cast<hsize_t>(start), 0};
      hsize_t count[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
      hid_t mspace = h5id(H5Screate_simple(rank_dims, count, nullptr), "H5Screate_simple");
      h5check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, offset, nullptr, count, nullptr),
              "H5Sselect_hyperslab");
      h5check(H5Dwrite(dset, mem_type, mspace, fspace, dxpl, data), "writing dataset " + path);
      H5Sclose(mspace);
    }
    H5Dclose(dset);
    H5Sclose(fspace);
  }

  const MotionBody &body(std::size_t b, const char *what) const {
    if (b >= bodies.size())
      throw Error("motion output: " + std::string(what) + " for body " + std::to_string(b) +
                      ", but there are " + std::to_string(bodies.size()) + " bodies",
                  true);
    return bodies[b];
  }

  Step &current(const char *what) {
    if (steps.empty())
      throw Error("motion output: " + std::string(what) + " before the first begin_step", true);
    return steps.back();
  }

  void check_complete(const char *when) const {
    if (steps.empty()) return;
    for (std::size_t b = 0; b < bodies.size(); ++b)
      if (!steps.back().bodies[b].has_positions)
        throw Error("motion output: step " + std::to_string(steps.size() - 1) +
                        " has no positions of body '" + bodies[b].name + "' (" + when + ")",
                    true);
  }

  std::string step_group(std::size_t b) const {
    return "/" + bodies[b].name + "/step_" + std::to_string(steps.size() - 1);
  }

  void add_field(std::size_t b, const std::string &name, bool cell, bool vector,
                 const double *values) {
    const MotionBody &mb = body(b, cell ? "cell_scalar" : "node_vector");
    Step &s = current(cell ? "cell_scalar" : "node_vector");
    std::string why = bad_name(name);
    if (why.empty() && name == "positions") why = "is reserved for the coordinates";
    for (const Field &f : s.bodies[b].fields)
      if (why.empty() && f.name == name) why = "is written twice in this step";
    if (!why.empty())
      throw Error("motion output: field name '" + name + "' of body '" + mb.name + "' " + why,
                  true);
    const GridLayout &g = mb.layout;
    const std::string path = step_group(b) + "/" + name;
    if (cell)
      write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, values, g.global_cells, g.cell_start,
                 g.local_cells, 1);
    else
      write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, values, g.global_nodes, g.node_start,
                 g.owned_nodes, 3);
    s.bodies[b].fields.push_back(Field{name, cell, vector, path});
  }

  std::string xdmf_text() const {
    const std::string h5 = xml_escape(basename + ".h5");
    std::ostringstream x;
    x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
      << "    <Grid Name=\"" << xml_escape(basename)
      << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (std::size_t k = 0; k < steps.size(); ++k) {
      char tbuf[40];
      std::snprintf(tbuf, sizeof tbuf, "%.17g", steps[k].time);
      x << "      <Grid Name=\"step_" << k
        << "\" GridType=\"Collection\" CollectionType=\"Spatial\">\n"
        << "        <Time Value=\"" << tbuf << "\"/>\n";
      for (std::size_t b = 0; b < bodies.size(); ++b) {
        const GridLayout &g = bodies[b].layout;
        const std::string name = xml_escape(bodies[b].name);
        const long long nn = g.global_nodes, nc = g.global_cells;
        x << "        <Grid Name=\"" << name << "\" GridType=\"Uniform\">\n"
          << "          <Topology TopologyType=\"" << g.topology_type << "\" NumberOfElements=\""
          << nc << "\">\n"
          << "            <DataItem Dimensions=\"" << nc << " " << g.nodes_per_cell
          << "\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/" << name
          << "/topology</DataItem>\n"
          << "          </Topology>\n"
          << "          <Geometry GeometryType=\"XYZ\">\n"
          << "            <DataItem Dimensions=\"" << nn
          << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":/" << name
          << "/step_" << k << "/positions</DataItem>\n"
          << "          </Geometry>\n";
        std::vector<Field> shown = constants[b];
        shown.insert(shown.end(), steps[k].bodies[b].fields.begin(),
                     steps[k].bodies[b].fields.end());
        for (const Field &f : shown) {
          const long long rows = f.cell ? nc : nn;
          x << "          <Attribute Name=\"" << xml_escape(f.name) << "\" AttributeType=\""
            << (f.vector ? "Vector" : "Scalar") << "\" Center=\"" << (f.cell ? "Cell" : "Node")
            << "\">\n"
            << "            <DataItem Dimensions=\"" << rows << (f.vector ? " 3" : "")
            << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5 << ":"
            << xml_escape(f.dataset) << "</DataItem>\n"
            << "          </Attribute>\n";
        }
        x << "        </Grid>\n";
      }
      x << "      </Grid>\n";
    }
    x << "    </Grid>\n  </Domain>\n</Xdmf>\n";
    return x.str();
  }

  void release_properties() {
    for (hid_t *p : {&dxpl, &dcpl, &lcpl})
      if (*p >= 0) {
        H5Pclose(*p);
        *p = -1;
      }
  }
};

MotionWriter::MotionWriter(const std::vector<MotionBody> &bodies, const std::string &directory,
                           const std::string &basename)
    : impl_(std::make_unique<Impl>()) {
  Impl &m = *impl_;
  if (bodies.empty()) throw Error("motion output: no bodies", true);
  m.bodies = bodies;
  m.constants.assign(bodies.size(), {});
  m.comm = bodies[0].layout.comm;
  if (m.comm == MPI_COMM_NULL)
    abort_local("motion output: body '" + bodies[0].name + "' has no communicator");
  MPI_Comm_rank(m.comm, &m.rank);
  m.directory = directory;
  m.basename = basename;
  const std::filesystem::path dir(directory);
  m.h5_final = (dir / (basename + ".h5")).string();
  m.h5_tmp = m.h5_final + ".tmp";
  m.xdmf_final = (dir / (basename + ".xdmf")).string();
  m.space.emplace(m.comm, m.h5_tmp);

  // Names: the same on every rank, so these errors are collective.
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const std::string &name = bodies[b].name;
    std::string why = bad_name(name);
    if (why.empty() && name == "time") why = "is reserved for the step times";
    for (std::size_t c = 0; c < b && why.empty(); ++c)
      if (bodies[c].name == name) why = "is used by two bodies";
    if (!why.empty()) throw Error("motion output: body name '" + name + "' " + why, true);
  }
  // Layouts: what one rank can check alone ends the job; the tiling of the global ranges is
  // checked together and is a collective error.
  std::vector<long long> local, sum(2 * bodies.size()), start(2 * bodies.size(), 0);
  for (const MotionBody &mb : bodies) {
    const GridLayout &g = mb.layout;
    const std::string who = "motion output: body '" + mb.name + "': ";
    int same = MPI_UNEQUAL;
    if (g.comm != MPI_COMM_NULL) MPI_Comm_compare(g.comm, m.comm, &same);
    if (same != MPI_IDENT && same != MPI_CONGRUENT)
      abort_local(who + "its layout's communicator is not the first body's");
    if (g.owned_coordinates.size() != static_cast<std::size_t>(3 * g.owned_nodes) ||
        g.cell_nodes.size() != static_cast<std::size_t>(g.local_cells * g.nodes_per_cell))
      abort_local(who + "layout arrays do not match its owned node and local cell counts");
    for (long long n : g.cell_nodes)
      if (n < 0 || n >= g.global_nodes)
        abort_local(who + "cell node " + std::to_string(n) + " outside [0, " +
                    std::to_string(g.global_nodes) + ")");
    if (g.topology_type.empty() || g.nodes_per_cell <= 0)
      abort_local(who + "layout has no topology type");
    local.push_back(g.owned_nodes);
    local.push_back(g.local_cells);
  }
  MPI_Allreduce(local.data(), sum.data(), static_cast<int>(local.size()), MPI_LONG_LONG, MPI_SUM,
                m.comm);
  MPI_Exscan(local.data(), start.data(), static_cast<int>(local.size()), MPI_LONG_LONG, MPI_SUM,
             m.comm);
  if (m.rank == 0) std::fill(start.begin(), start.end(), 0);
  int bad = 0;
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const GridLayout &g = bodies[b].layout;
    // The start of an empty contribution does not matter.
    if (sum[2 * b] != g.global_nodes || (g.owned_nodes > 0 && start[2 * b] != g.node_start) ||
        sum[2 * b + 1] != g.global_cells || (g.local_cells > 0 && start[2 * b + 1] != g.cell_start))
      bad = 1;
  }
  MPI_Allreduce(MPI_IN_PLACE, &bad, 1, MPI_INT, MPI_MAX, m.comm);
  if (bad)
    throw Error("motion output: the owned node or cell ranges of a body do not tile its global "
                "numbering",
                true);

  // A stale result of an earlier run must not stay next to the new, incomplete one.
  if (m.rank == 0) {
    std::error_code ec;
    std::filesystem::remove(m.xdmf_final, ec);
    std::filesystem::remove(m.h5_final, ec);
  }
  hid_t fapl = h5id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate");
  h5check(H5Pset_fapl_mpio(fapl, m.comm, MPI_INFO_NULL), "H5Pset_fapl_mpio");
  m.file = H5Fcreate(m.h5_tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  int created = m.file >= 0 ? 1 : 0, any_created = 0;
  MPI_Allreduce(&created, &any_created, 1, MPI_INT, MPI_MAX, m.comm);
  if (!any_created)
    throw Error("cannot create '" + m.h5_tmp + "': " + unwritable_reason(m.comm, m.h5_tmp), true);
  if (!created) abort_local("cannot create '" + m.h5_tmp + "' on this rank");

  m.dxpl = h5id(H5Pcreate(H5P_DATASET_XFER), "H5Pcreate");
  h5check(H5Pset_dxpl_mpio(m.dxpl, H5FD_MPIO_INDEPENDENT), "H5Pset_dxpl_mpio");
  m.dcpl = h5id(H5Pcreate(H5P_DATASET_CREATE), "H5Pcreate");
  h5check(H5Pset_fill_time(m.dcpl, H5D_FILL_TIME_NEVER), "H5Pset_fill_time");
  m.lcpl = h5id(H5Pcreate(H5P_LINK_CREATE), "H5Pcreate");
  h5check(H5Pset_create_intermediate_group(m.lcpl, 1), "H5Pset_create_intermediate_group");

  for (const MotionBody &mb : m.bodies) {
    const GridLayout &g = mb.layout;
    m.write_rows("/" + mb.name + "/reference_geometry", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE,
                 g.owned_coordinates.data(), g.global_nodes, g.node_start, g.owned_nodes, 3);
    m.write_rows("/" + mb.name + "/topology", H5T_NATIVE_LLONG, H5T_STD_I64LE, g.cell_nodes.data(),
                 g.global_cells, g.cell_start, g.local_cells, g.nodes_per_cell);
    // The XDMF topology name, for readers of the HDF5 file alone.
    const std::string path = "/" + mb.name + "/topology";
    hid_t dset = h5id(H5Dopen2(m.file, path.c_str(), H5P_DEFAULT), "opening " + path);
    hid_t type = h5id(H5Tcopy(H5T_C_S1), "H5Tcopy");
    h5check(H5Tset_size(type, g.topology_type.size()), "H5Tset_size");
    hid_t space = h5id(H5Screate(H5S_SCALAR), "H5Screate");
    hid_t attr = h5id(H5Acreate2(dset, "topology_type", type, space, H5P_DEFAULT, H5P_DEFAULT),
                      "creating attribute topology_type");
    h5check(H5Awrite(attr, type, g.topology_type.c_str()), "writing attribute topology_type");
    H5Aclose(attr);
    H5Sclose(space);
    H5Tclose(type);
    H5Dclose(dset);
  }
}

MotionWriter::~MotionWriter() = default;

void MotionWriter::begin_step(double time) {
  Impl &m = *impl_;
  m.check_complete("at the next begin_step");
  MPI_Bcast(&time, 1, MPI_DOUBLE, 0, m.comm);
  if (!m.steps.empty() && !(time > m.steps.back().time)) {
    char buf[120];
    std::snprintf(buf, sizeof buf, "motion output: step time %.17g does not follow %.17g", time,
                  m.steps.back().time);
    throw Error(buf, true);
  }
  m.steps.push_back(Step{time, std::vector<BodyStep>(m.bodies.size())});
}

void MotionWriter::positions(std::size_t body, const double *owned_xyz) {
  Impl &m = *impl_;
  const MotionBody &mb = m.body(body, "positions");
  Step &s = m.current("positions");
  if (s.bodies[body].has_positions)
    throw Error("motion output: positions of body '" + mb.name + "' written twice in step " +
                    std::to_string(m.steps.size() - 1),
                true);
  const GridLayout &g = mb.layout;
  m.write_rows(m.step_group(body) + "/positions", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, owned_xyz,
               g.global_nodes, g.node_start, g.owned_nodes, 3);
  s.bodies[body].has_positions = true;
}

void MotionWriter::node_vector(std::size_t body, const std::string &name,
                               const double *owned_values) {
  impl_->add_field(body, name, false, true, owned_values);
}

void MotionWriter::cell_scalar(std::size_t body, const std::string &name,
                               const double *local_values) {
  impl_->add_field(body, name, true, false, local_values);
}

void MotionWriter::constant_cell_scalar(std::size_t body, const std::string &name,
                                        const double *local_values) {
  Impl &m = *impl_;
  const MotionBody &mb = m.body(body, "constant_cell_scalar");
  std::string why = bad_name(name);
  if (why.empty() && (name == "positions" || name == "topology" || name == "reference_geometry" ||
                      name.rfind("step_", 0) == 0))
    why = "is reserved";
  for (const Field &f : m.constants[body])
    if (why.empty() && f.name == name) why = "is written twice";
  if (!why.empty())
    throw Error("motion output: field name '" + name + "' of body '" + mb.name + "' " + why, true);
  const GridLayout &g = mb.layout;
  const std::string path = "/" + mb.name + "/" + name;
  m.write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, local_values, g.global_cells, g.cell_start,
               g.local_cells, 1);
  m.constants[body].push_back(Field{name, true, false, path});
}

void MotionWriter::constant_cell_value(std::size_t body, const std::string &name, double value) {
  const MotionBody &mb = impl_->body(body, "constant_cell_value");
  const std::vector<double> values(static_cast<std::size_t>(mb.layout.local_cells), value);
  constant_cell_scalar(body, name, values.data());
}

std::size_t MotionWriter::steps() const {
  return impl_->steps.size();
}

std::size_t MotionWriter::bodies() const {
  return impl_->bodies.size();
}

std::string MotionWriter::close() {
  Impl &m = *impl_;
  if (m.closed) throw Error("motion output: '" + m.xdmf_final + "' closed twice", true);
  m.check_complete("at close");
  std::vector<double> times;
  for (const Step &s : m.steps) times.push_back(s.time);
  m.write_rows("/time", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, times.data(),
               static_cast<long long>(times.size()), 0,
               m.rank == 0 ? static_cast<long long>(times.size()) : 0, 1);
  m.release_properties();
  m.closed = true;
  h5check(H5Fclose(m.file), "closing " + m.h5_tmp);
  m.file = -1;
  int ok = 1;
  std::string message;
  if (m.rank == 0) {
    try {
      if (std::rename(m.h5_tmp.c_str(), m.h5_final.c_str()) != 0)
        throw Error("cannot rename '" + m.h5_tmp + "' to '" + m.h5_final + "'");
      write_file_atomic(m.xdmf_final, m.xdmf_text());
    } catch (const std::exception &e) {
      ok = 0;
      message = e.what();
    }
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, m.comm);
  if (!ok)
    throw Error(m.rank == 0 ? message : "writing " + m.xdmf_final + " failed on rank 0", true);
  return m.xdmf_final;
}

using namespace detail;

double estimate_motion_bytes(const std::vector<MotionBody> &bodies,
                             const std::vector<std::vector<std::string>> &node_vectors,
                             long long frames,
                             const std::vector<std::vector<std::string>> &cell_scalars) {
  const double h5 = 9;             // "motion.h5"
  const double k = digits(frames); // step number K, at most this many digits
  double once = kH5FileBytes, per_frame = 8 + kXdmfStepChars + k; // /time and the step's XDMF text
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    const GridLayout &g = bodies[b].layout;
    const auto nodes = static_cast<double>(g.global_nodes);
    const double name = static_cast<double>(bodies[b].name.size());
    const double nn = digits(g.global_nodes);
    // The reference mesh: coordinates (float64) and cell nodes (int64).
    once += kH5GroupBytes + 24 * nodes +
            8 * static_cast<double>(g.global_cells) * g.nodes_per_cell + 2 * kH5DatasetBytes;
    // Positions: float64 x, y, z per node, and its grid in the XDMF text.
    per_frame += kH5GroupBytes + 24 * nodes + kH5DatasetBytes;
    per_frame += kXdmfBodyChars + 3 * name + 2 * h5 + 2 * digits(g.global_cells) +
                 digits(g.nodes_per_cell) + nn + static_cast<double>(g.topology_type.size()) + k;
    if (b < node_vectors.size())
      for (const std::string &field : node_vectors[b]) {
        const auto f = static_cast<double>(field.size());
        per_frame += 24 * nodes + kH5DatasetBytes;
        per_frame += kXdmfFieldChars + 2 * f + name + h5 + nn + k;
      }
    if (b < cell_scalars.size())
      for (const std::string &field : cell_scalars[b]) {
        // float64 per cell; the attribute's text as a vector's without its " 3".
        const auto f = static_cast<double>(field.size());
        per_frame += 8 * static_cast<double>(g.global_cells) + kH5DatasetBytes;
        per_frame += kXdmfFieldChars - 2 + 2 * f + name + h5 + digits(g.global_cells) + k;
      }
  }
  return once + static_cast<double>(frames) * per_frame;
}

} // namespace flexopt::io
