#include "flexopt/io/xdmf.hpp"

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

} // namespace

struct XdmfWriter::Impl {
  GridLayout layout;
  std::string directory, basename, h5_final, h5_tmp;
  hid_t file = -1;
  std::vector<Step> steps;
  bool closed = false;
  std::optional<detail::SpaceGuard> space; ///< of h5_tmp's file system

  /// Error path (also when the writer's constructor throws, which runs no writer destructor):
  /// drop the incomplete file so nothing valid-looking remains.
  ~Impl() {
    if (!closed && file >= 0) {
      H5Fclose(file);
      int rank = 0;
      MPI_Comm_rank(layout.comm, &rank);
      if (rank == 0) std::remove(h5_tmp.c_str());
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
        << "          <DataItem Dimensions=\"" << nc << " " << layout.nodes_per_cell
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
  const double once = kH5FileBytes + kH5GroupBytes + 24 * nodes + 8 * cells * g.nodes_per_cell +
                      2 * kH5DatasetBytes;
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
  m.steps.back().fields.push_back(Field{name, false, true, path});
}

void XdmfWriter::cell_scalar(const std::string &name, const double *local_values) {
  Impl &m = *impl_;
  if (m.steps.empty()) begin_step(0.0);
  const std::string path = "/step_" + std::to_string(m.steps.size() - 1) + "/" + name;
  m.write_rows(path, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, local_values, m.layout.global_cells,
               m.layout.cell_start, m.layout.local_cells, 1);
  m.steps.back().fields.push_back(Field{name, true, false, path});
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
