#pragma once
/// \file String attributes of an HDF5 file's root (private to src/io): the labels that tie a
/// file to the design it belongs to (restart.h5, design.h5; optimize::design_fingerprint).
#include <hdf5.h>
#include <map>
#include <string>

namespace flexopt::io::detail {

/// A string attribute `name` = `value` of the file's root. Throws flexopt::Error on failure.
/// Collective for a file opened in parallel (the same on every rank).
void write_label(hid_t file, const std::string &name, const std::string &value);

/// Every fixed-length string attribute of the file's root.
std::map<std::string, std::string> read_labels(hid_t file);

} // namespace flexopt::io::detail
