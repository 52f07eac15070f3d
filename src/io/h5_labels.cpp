// String attributes of an HDF5 file's root (h5_labels.hpp).
#include "h5_labels.hpp"

#include "flexopt/core/error.hpp"

#include <algorithm>

namespace flexopt::io::detail {

void write_label(hid_t file, const std::string &name, const std::string &value) {
  hid_t type = H5Tcopy(H5T_C_S1);
  H5Tset_size(type, std::max<std::size_t>(1, value.size()));
  hid_t space = H5Screate(H5S_SCALAR);
  hid_t attr = H5Acreate2(file, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT);
  if (attr < 0) throw Error("HDF5: creating the label " + name + " failed");
  const std::string padded = value.empty() ? std::string(1, '\0') : value;
  if (H5Awrite(attr, type, padded.data()) < 0)
    throw Error("HDF5: writing the label " + name + " failed");
  H5Aclose(attr);
  H5Sclose(space);
  H5Tclose(type);
}

namespace {

/// H5Aiterate2's visit: a fixed-length string attribute into the map `data`.
herr_t collect_label(hid_t location, const char *name, const H5A_info_t *, void *data) {
  auto &labels = *static_cast<std::map<std::string, std::string> *>(data);
  hid_t attr = H5Aopen(location, name, H5P_DEFAULT);
  if (attr < 0) return 0;
  hid_t type = H5Aget_type(attr);
  if (H5Tget_class(type) == H5T_STRING && H5Tis_variable_str(type) <= 0) {
    std::string value(H5Tget_size(type), '\0');
    if (H5Aread(attr, type, value.data()) >= 0) labels[name] = value.substr(0, value.find('\0'));
  }
  H5Tclose(type);
  H5Aclose(attr);
  return 0;
}

} // namespace

std::map<std::string, std::string> read_labels(hid_t file) {
  std::map<std::string, std::string> labels;
  hsize_t index = 0;
  H5Aiterate2(file, H5_INDEX_NAME, H5_ITER_INC, &index, collect_label, &labels);
  return labels;
}

} // namespace flexopt::io::detail
