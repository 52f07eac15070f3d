#include "flexopt/io/xdmf.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/io/json.hpp"
#include "h5_labels.hpp"
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

struct Field {
  std::string name;
  bool cell = false;
  bool vector = false;
  std::string dataset;
};

struct Step {
  double time = 0;
  std::vector<Field> fields;
};

/// Rank 0's serial read of an XdmfWriter file's steps (XdmfWriter::copy_steps), HDF5's error
/// printing off while it is open: a damaged or unfinished file gives a message, never a crash.
struct StepReader {
  hid_t file = -1;
  std::size_t cells = 0;
  std::vector<std::vector<double>> fields;
  H5E_auto2_t handler = nullptr;
  void *data = nullptr;

  std::string open(const std::string &path, std::size_t global_cells,
                   const std::map<std::string, std::string> &labels) {
    cells = global_cells;
    if (!std::filesystem::is_regular_file(path)) return "not found";
    H5Eget_auto2(H5E_DEFAULT, &handler, &data);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) {
      H5Eset_auto2(H5E_DEFAULT, handler, data);
      return "cannot be opened (not an HDF5 file, or damaged)";
    }
    const std::map<std::string, std::string> got = detail::read_labels(file);
    for (const auto &[name, value] : labels) {
      const auto it = got.find(name);
      if (it == got.end() || it->second != value)
        return "written for another design (its " + name + " is '" +
               (it == got.end() ? std::string("missing") : it->second) + "', this run's '" + value +
               "')";
    }
    return "";
  }

  /// 1 with step k's fields read, 0 at the end (its time not below `before`, or `problem` set).
  int step(std::size_t k, double before, const std::vector<std::string> &names, double &time,
           std::string &problem) {
    const std::string group = "/step_" + std::to_string(k);
    if (H5Lexists(file, group.c_str(), H5P_DEFAULT) <= 0) return 0; // the last step was k - 1
    hid_t a = H5Aopen_by_name(file, group.c_str(), "time", H5P_DEFAULT, H5P_DEFAULT);
    const bool timed = a >= 0 && H5Aread(a, H5T_NATIVE_DOUBLE, &time) >= 0;
    if (a >= 0) H5Aclose(a);
    if (!timed) {
      problem = group + " has no time (unfinished, or written by an older flexopt)";
      return 0;
    }
    if (!(time < before)) return 0;
    fields.assign(names.size(), std::vector<double>(cells));
    for (std::size_t f = 0; f < names.size(); ++f) {
      const std::string name = group + "/" + names[f];
      hid_t d = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
      hid_t sp = d >= 0 ? H5Dget_space(d) : -1;
      const bool fits = sp >= 0 && H5Sget_simple_extent_npoints(sp) == static_cast<hssize_t>(cells);
      const bool read = fits && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT,
                                        fields[f].data()) >= 0;
      if (sp >= 0) H5Sclose(sp);
      if (d >= 0) H5Dclose(d);
      if (!read) {
        problem = name + (fits ? " cannot be read (unfinished)"
                               : " is missing or has another cell count than the mesh");
        return 0;
      }
    }
    return 1;
  }

  void close() {
    if (file < 0) return;
    H5Fclose(file);
    H5Eset_auto2(H5E_DEFAULT, handler, data);
    file = -1;
  }
};

} // namespace

struct XdmfWriter::Impl {
  GridLayout layout;
  std::string directory, basename, h5_final, h5_tmp;
  hid_t file = -1;
  std::vector<Step> steps;
  bool closed = false;
  bool keep_unfinished = false;            ///< keep_unfinished_file()
  std::optional<detail::SpaceGuard> space; ///< of h5_tmp's file system

  /// Error path (also when the writer's constructor throws, which runs no writer destructor):
  /// drop the incomplete file so nothing valid-looking remains (it has a .tmp name; kept when
  /// asked, for copy_steps).
  ~Impl() {
    if (!closed && file >= 0) {
      H5Fclose(file);
      int rank = 0;
      MPI_Comm_rank(layout.comm, &rank);
      if (rank == 0 && !keep_unfinished) std::remove(h5_tmp.c_str());
    }
  }

  /// Writes a 2D dataset [global_rows x cols] of which this rank holds rows [start, start+rows).
  void write_rows(const std::string &path, hid_t mem_type, hid_t file_type, const void *data,
                  long long global_rows, long long start, long long rows, int cols) {
    space->require(global_rows * cols * 8);
    hsize_t gdims[2] = {static_cast<hsize_t>(global_rows), static_cast<hsize_t>(cols)};
    hid_t fspace = h5id(H5Screate_simple(cols == 1 ? 1 : 2, gdims, nullptr), "H5Screate_simple");
    hid_t lcpl = h5id(H5Pcreate(H5P_LINK_CREATE), "H5Pcreate");
    h5check(H5Pset_create_intermediate_group(lcpl, 1), "H5Pset_create_intermediate_group");
    hid_t dset =
        h5id(H5Dcreate2(file, path.c_str(), file_type, fspace, lcpl, H5P_DEFAULT, H5P_DEFAULT),
             "creating dataset " + path);
    hsize_t offset[2] = {static_cast<hsize_t>(start), 0};
    hsize_t count[2] = {static_cast<hsize_t>(rows), static_cast<hsize_t>(cols)};
    hid_t mspace = h5id(H5Screate_simple(cols == 1 ? 1 : 2, count, nullptr), "H5Screate_simple");
    if (rows > 0) {
      h5check(H5Sselect_hyperslab(fspace, H5S_SELECT_SET, offset, nullptr, count, nullptr),
              "H5Sselect_hyperslab");
    } else {
      h5check(H5Sselect_none(fspace), "H5Sselect_none");
      h5check(H5Sselect_none(mspace), "H5Sselect_none");
    }
    hid_t dxpl = h5id(H5Pcreate(H5P_DATASET_XFER), "H5Pcreate");
    h5check(H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE), "H5Pset_dxpl_mpio");
    h5check(H5Dwrite(dset, mem_type, mspace, fspace, dxpl, data), "writing dataset " + path);
    H5Pclose(dxpl);
    H5Sclose(mspace);
    H5Dclose(dset);
    H5Pclose(lcpl);
    H5Sclose(fspace);
  }

  /// The step's time as the attribute "time" of its group, written with its first field, so
  /// that the .tmp of a killed run tells each step's time (copy_steps).
  void write_step_time(std::size_t step) {
    const std::string group = "/step_" + std::to_string(step);
    hid_t g = h5id(H5Gopen2(file, group.c_str(), H5P_DEFAULT), "opening " + group);
    hid_t sp = h5id(H5Screate(H5S_SCALAR), "H5Screate");
    hid_t a = h5id(H5Acreate2(g, "time", H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT),
                   "creating " + group + "/time");
    h5check(H5Awrite(a, H5T_NATIVE_DOUBLE, &steps[step].time), "writing " + group + "/time");
    H5Aclose(a);
    H5Sclose(sp);
    H5Gclose(g);
  }

  /// The topology dataset's dimensions: cells x nodes per cell, or a Mixed list's length.
  std::string topology_dimensions() const {
    if (layout.nodes_per_cell == 0) return std::to_string(layout.global_topology);
    return std::to_string(layout.global_cells) + " " + std::to_string(layout.nodes_per_cell);
  }

  std::string xdmf_text() const {
    const std::string h5name = basename + ".h5";
    std::ostringstream x;
    const long long nn = layout.global_nodes, nc = layout.global_cells;
    x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
      << "    <Grid Name=\"" << basename
      << "\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (std::size_t s = 0; s < steps.size(); ++s) {
      char tbuf[40];
      std::snprintf(tbuf, sizeof tbuf, "%.17g", steps[s].time);
      x << "      <Grid Name=\"step_" << s << "\" GridType=\"Uniform\">\n"
        << "        <Time Value=\"" << tbuf << "\"/>\n"
        << "        <Topology TopologyType=\"" << layout.topology_type << "\" NumberOfElements=\""
        << nc << "\">\n"
        << "          <DataItem Dimensions=\"" << topology_dimensions()
        << "\" NumberType=\"Int\" Precision=\"8\" Format=\"HDF\">" << h5name
        << ":/mesh/topology</DataItem>\n"
        << "        </Topology>\n"
        << "        <Geometry GeometryType=\"XYZ\">\n"
        << "          <DataItem Dimensions=\"" << nn
        << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5name
        << ":/mesh/geometry</DataItem>\n"
        << "        </Geometry>\n";
      for (const Field &f : steps[s].fields) {
        const long long rows = f.cell ? nc : nn;
        x << "        <Attribute Name=\"" << f.name << "\" AttributeType=\""
          << (f.vector ? "Vector" : "Scalar") << "\" Center=\"" << (f.cell ? "Cell" : "Node")
          << "\">\n"
          << "          <DataItem Dimensions=\"" << rows << (f.vector ? " 3" : "")
          << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5name << ":" << f.dataset
          << "</DataItem>\n"
          << "        </Attribute>\n";
      }
      x << "      </Grid>\n";
    }
    x << "    </Grid>\n  </Domain>\n</Xdmf>\n";
    return x.str();
  }
};

std::string human_bytes(double bytes) {
  char buf[32];
  if (bytes >= 1e9)
    std::snprintf(buf, sizeof buf, "%.2f GB", bytes / 1e9);
  else if (bytes >= 1e6)
    std::snprintf(buf, sizeof buf, "%.1f MB", bytes / 1e6);
  else
    std::snprintf(buf, sizeof buf, "%.0f kB", bytes / 1e3);
  return buf;
}

double estimate_xdmf_bytes(const GridLayout &g, const std::string &basename,
                           const std::vector<std::string> &cell_scalars, long long frames) {
  using namespace detail;
  const auto cells = static_cast<double>(g.global_cells),
             nodes = static_cast<double>(g.global_nodes);
  const double h5 = static_cast<double>(basename.size()) + 3, k = digits(frames);
  const double topology =
      g.nodes_per_cell > 0 ? cells * g.nodes_per_cell : static_cast<double>(g.global_topology);
  const double once =
      kH5FileBytes + kH5GroupBytes + 24 * nodes + 8 * topology + 2 * kH5DatasetBytes;
  // A step: its group and datasets, and its grid in the XDMF text (Grid, Time, Topology and
  // Geometry with the mesh's sizes, one Attribute per field).
  double per_frame = kH5GroupBytes + kXdmfStepChars + kXdmfBodyChars + k + 2 * h5 +
                     2 * digits(g.global_cells) + digits(g.nodes_per_cell) +
                     digits(g.global_nodes) + static_cast<double>(g.topology_type.size());
  for (const std::string &f : cell_scalars)
    per_frame += 8 * cells + kH5DatasetBytes + kXdmfFieldChars + 2 * static_cast<double>(f.size()) +
                 k + h5 + digits(g.global_cells);
  return once + static_cast<double>(frames) * per_frame;
}

XdmfWriter::XdmfWriter(const GridLayout &layout, const std::string &directory,
                       const std::string &basename)
    : impl_(std::make_unique<Impl>()) {
  Impl &m = *impl_;
  m.layout = layout;
  m.directory = directory;
  m.basename = basename;
  m.h5_final = (std::filesystem::path(directory) / (basename + ".h5")).string();
  m.h5_tmp = m.h5_final + ".tmp";
  m.space.emplace(layout.comm, m.h5_tmp);
  hid_t fapl = h5id(H5Pcreate(H5P_FILE_ACCESS), "H5Pcreate");
  h5check(H5Pset_fapl_mpio(fapl, layout.comm, MPI_INFO_NULL), "H5Pset_fapl_mpio");
  m.file = H5Fcreate(m.h5_tmp.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  if (m.file < 0)
    throw Error("cannot create '" + m.h5_tmp + "': " + unwritable_reason(layout.comm, m.h5_tmp),
                true);
  m.write_rows("/mesh/geometry", H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, layout.owned_coordinates.data(),
               layout.global_nodes, layout.node_start, layout.owned_nodes, 3);
  if (layout.nodes_per_cell == 0) // Mixed: one flat list of type codes and nodes
    m.write_rows("/mesh/topology", H5T_NATIVE_LLONG, H5T_STD_I64LE, layout.cell_nodes.data(),
                 layout.global_topology, layout.topology_start,
                 static_cast<long long>(layout.cell_nodes.size()), 1);
  else
    m.write_rows("/mesh/topology", H5T_NATIVE_LLONG, H5T_STD_I64LE, layout.cell_nodes.data(),
                 layout.global_cells, layout.cell_start, layout.local_cells, layout.nodes_per_cell);
}

XdmfWriter::~XdmfWriter() = default;

void XdmfWriter::begin_step(double time) {
  impl_->steps.push_back(Step{time, {}});
}

void XdmfWriter::node_vector(const std::string &name, const double *owned_values) {
  Impl &m = *impl_;
  if (m.steps.empty()) begin_step(0.0);
  const std::string path = "/step_" + std::to_string(m.steps.size() - 1) + "/" + name;
  m.write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, owned_values, m.layout.global_nodes,
               m.layout.node_start, m.layout.owned_nodes, 3);
  if (m.steps.back().fields.empty()) m.write_step_time(m.steps.size() - 1);
  m.steps.back().fields.push_back(Field{name, false, true, path});
}

void XdmfWriter::cell_scalar(const std::string &name, const double *local_values) {
  Impl &m = *impl_;
  if (m.steps.empty()) begin_step(0.0);
  const std::string path = "/step_" + std::to_string(m.steps.size() - 1) + "/" + name;
  m.write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, local_values, m.layout.global_cells,
               m.layout.cell_start, m.layout.local_cells, 1);
  if (m.steps.back().fields.empty()) m.write_step_time(m.steps.size() - 1);
  m.steps.back().fields.push_back(Field{name, true, false, path});
}

void XdmfWriter::keep_unfinished_file() {
  impl_->keep_unfinished = true;
}

void XdmfWriter::flush() {
  h5check(H5Fflush(impl_->file, H5F_SCOPE_GLOBAL), "flushing " + impl_->h5_tmp);
}

void XdmfWriter::label(const std::string &name, const std::string &value) {
  try {
    detail::write_label(impl_->file, name, value);
  } catch (const std::exception &e) {
    abort_local(std::string(e.what()) + " in " + impl_->h5_tmp); // a collective sequence
  }
}

XdmfWriter::Copied XdmfWriter::copy_steps(const std::string &path, double before,
                                          const std::vector<std::string> &names,
                                          const std::map<std::string, std::string> &labels) {
  Impl &m = *impl_;
  MPI_Comm comm = m.layout.comm;
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  std::vector<int> counts(static_cast<std::size_t>(size)), offsets(counts.size(), 0);
  const int mine = static_cast<int>(m.layout.local_cells);
  MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
  for (std::size_t r = 1; r < counts.size(); ++r) offsets[r] = offsets[r - 1] + counts[r - 1];
  StepReader reader; // rank 0's
  Copied out;
  if (rank == 0)
    out.problem = reader.open(path, static_cast<std::size_t>(m.layout.global_cells), labels);
  std::vector<double> local(static_cast<std::size_t>(mine));
  for (std::size_t k = 0;; ++k) {
    double time = 0;
    int more = 0; // 1: step k is complete and below `before`
    if (rank == 0 && out.problem.empty()) more = reader.step(k, before, names, time, out.problem);
    MPI_Bcast(&more, 1, MPI_INT, 0, comm);
    if (!more) break;
    MPI_Bcast(&time, 1, MPI_DOUBLE, 0, comm);
    begin_step(time);
    for (std::size_t f = 0; f < names.size(); ++f) {
      MPI_Scatterv(rank == 0 ? reader.fields[f].data() : nullptr, counts.data(), offsets.data(),
                   MPI_DOUBLE, local.data(), mine, MPI_DOUBLE, 0, comm);
      cell_scalar(names[f], local.data());
    }
    ++out.steps;
    out.last_time = time;
  }
  if (rank == 0) reader.close();
  broadcast_text(comm, out.problem);
  return out;
}

std::string XdmfWriter::close() {
  Impl &m = *impl_;
  h5check(H5Fclose(m.file), "closing " + m.h5_tmp);
  m.file = -1;
  m.closed = true;
  const std::string xdmf_final =
      (std::filesystem::path(m.directory) / (m.basename + ".xdmf")).string();
  int rank = 0;
  MPI_Comm_rank(m.layout.comm, &rank);
  int ok = 1;
  std::string message;
  if (rank == 0) {
    try {
      if (std::rename(m.h5_tmp.c_str(), m.h5_final.c_str()) != 0)
        throw Error("cannot rename '" + m.h5_tmp + "' to '" + m.h5_final + "'");
      write_file_atomic(xdmf_final, m.xdmf_text());
    } catch (const std::exception &e) {
      ok = 0;
      message = e.what();
    }
  }
  MPI_Bcast(&ok, 1, MPI_INT, 0, m.layout.comm);
  if (!ok) throw Error(rank == 0 ? message : "writing " + xdmf_final + " failed on rank 0", true);
  return xdmf_final;
}

} // namespace flexopt::io
