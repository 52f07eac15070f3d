#include "flexopt/io/restart.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "h5_labels.hpp"
#include "hdf5_check.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <hdf5.h>
#include <unordered_map>

namespace flexopt::io {

namespace {

void check(herr_t status, const std::string &what) {
  if (status < 0) throw Error("restart file: " + what + " failed");
}

hid_t create_parallel(MPI_Comm comm, const std::string &path) {
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_fapl_mpio(fapl, comm, MPI_INFO_NULL);
  hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl);
  H5Pclose(fapl);
  return f;
}

/// Dataset of `global` entries of which this rank writes [start, start + n). Collective.
void write_slab(hid_t file, const std::string &name, hid_t mem_type, hid_t file_type,
                const void *data, long long global, long long start, long long n) {
  hsize_t g = static_cast<hsize_t>(global), off = static_cast<hsize_t>(start),
          cnt = static_cast<hsize_t>(n);
  hid_t fspace = H5Screate_simple(1, &g, nullptr);
  hid_t dset =
      H5Dcreate2(file, name.c_str(), file_type, fspace, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (dset < 0) throw Error("restart file: creating " + name + " failed");
  hid_t mspace = H5Screate_simple(1, &cnt, nullptr);
  if (n > 0) {
    H5Sselect_hyperslab(fspace, H5S_SELECT_SET, &off, nullptr, &cnt, nullptr);
  } else {
    H5Sselect_none(fspace);
    H5Sselect_none(mspace);
  }
  hid_t dxpl = H5Pcreate(H5P_DATASET_XFER);
  H5Pset_dxpl_mpio(dxpl, H5FD_MPIO_COLLECTIVE);
  check(H5Dwrite(dset, mem_type, mspace, fspace, dxpl, data), "writing " + name);
  H5Pclose(dxpl);
  H5Sclose(mspace);
  H5Sclose(fspace);
  H5Dclose(dset);
}

/// Reads a whole 1D dataset on every rank. Collective.
template <class T> std::vector<T> read_all(hid_t file, const std::string &name, hid_t mem_type) {
  hid_t dset = H5Dopen2(file, name.c_str(), H5P_DEFAULT);
  if (dset < 0) throw Error("dataset " + name + " is missing");
  hid_t space = H5Dget_space(dset);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(space, &n, nullptr);
  std::vector<T> v(static_cast<std::size_t>(n));
  if (n > 0)
    check(H5Dread(dset, mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), "reading " + name);
  H5Sclose(space);
  H5Dclose(dset);
  return v;
}

} // namespace

void write_restart(MPI_Comm comm, const std::string &path, const RestartData &data) {
  const std::string tmp = path + ".tmp";
  long long n = static_cast<long long>(data.tags.size()), start = 0, global = 0;
  MPI_Exscan(&n, &start, 1, MPI_LONG_LONG, MPI_SUM, comm);
  if (comm_rank(comm) == 0) start = 0;
  MPI_Allreduce(&n, &global, 1, MPI_LONG_LONG, MPI_SUM, comm);
  long long nd = static_cast<long long>(data.dof_keys.size()), dstart = 0, dglobal = 0;
  MPI_Exscan(&nd, &dstart, 1, MPI_LONG_LONG, MPI_SUM, comm);
  if (comm_rank(comm) == 0) dstart = 0;
  MPI_Allreduce(&nd, &dglobal, 1, MPI_LONG_LONG, MPI_SUM, comm);
  long long bytes = global * 8 * static_cast<long long>(1 + data.fields.size()) +
                    dglobal * 8 * static_cast<long long>(1 + data.dof_fields.size());
  for (const auto &entry : data.arrays) bytes += 8 * static_cast<long long>(entry.second.size());
  detail::SpaceGuard(comm, tmp).require(bytes); // before any collective write (hdf5_check.hpp)
  hid_t file = create_parallel(comm, tmp);
  if (file < 0)
    throw Error("cannot create restart file '" + tmp +
                    "': " + detail::unwritable_reason(comm, tmp) +
                    " (the previous restart.h5, if any, is intact)",
                true);
  H5Gclose(H5Gcreate2(file, "/fields", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  H5Gclose(H5Gcreate2(file, "/arrays", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
  for (const auto &[name, value] : data.labels) detail::write_label(file, name, value);
  write_slab(file, "/tags", H5T_NATIVE_UINT64, H5T_STD_U64LE, data.tags.data(), global, start, n);
  for (const auto &[name, values] : data.fields)
    write_slab(file, "/fields/" + name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, values.data(), global,
               start, n);
  if (dglobal > 0) {
    H5Gclose(H5Gcreate2(file, "/dof_fields", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT));
    write_slab(file, "/dof_keys", H5T_NATIVE_UINT64, H5T_STD_U64LE, data.dof_keys.data(), dglobal,
               dstart, nd);
    for (const auto &[name, values] : data.dof_fields)
      write_slab(file, "/dof_fields/" + name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, values.data(),
                 dglobal, dstart, nd);
  }
  const bool root = comm_rank(comm) == 0;
  for (const auto &[name, values] : data.arrays) {
    const long long len = static_cast<long long>(values.size());
    write_slab(file, "/arrays/" + name, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, values.data(), len, 0,
               root ? len : 0);
  }
  check(H5Fclose(file), "closing " + tmp);
  run_on_root(comm, 0, [&] {
    if (std::rename(tmp.c_str(), path.c_str()) != 0)
      throw Error("cannot rename '" + tmp + "' to '" + path + "'");
  });
}

namespace {

/// A restart file as rank 0 reads it.
struct Contents {
  std::map<std::string, std::string> labels;
  std::vector<std::uint64_t> tags, dof_keys;
  std::map<std::string, std::vector<double>> fields, arrays, dof_fields;
};

/// The names of the datasets in `group`.
std::vector<std::string> dataset_names(hid_t file, const char *group) {
  hid_t g = H5Gopen2(file, group, H5P_DEFAULT);
  if (g < 0) throw Error(std::string("group ") + group + " is missing");
  hsize_t count = 0;
  H5Gget_num_objs(g, &count);
  std::vector<std::string> names;
  for (hsize_t i = 0; i < count; ++i) {
    char name[256] = "";
    H5Gget_objname_by_idx(g, i, name, sizeof name);
    names.emplace_back(name);
  }
  H5Gclose(g);
  return names;
}

/// Rank 0's read of `path` with HDF5's serial driver, its own error printing off: a damaged file
/// gives a flexopt::Error here, never a collective HDF5 call that one rank leaves (a hang).
Contents read_on_root(const std::string &path, bool labels_only) {
  H5E_auto2_t handler = nullptr;
  void *data = nullptr;
  H5Eget_auto2(H5E_DEFAULT, &handler, &data);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  Contents c;
  std::string message;
  if (file < 0) {
    message = "cannot open the restart file (not an HDF5 file, or damaged)";
  } else {
    try {
      c.labels = detail::read_labels(file);
      if (!labels_only) {
        c.tags = read_all<std::uint64_t>(file, "/tags", H5T_NATIVE_UINT64);
        for (const std::string &name : dataset_names(file, "/fields")) {
          c.fields[name] = read_all<double>(file, "/fields/" + name, H5T_NATIVE_DOUBLE);
          if (c.fields[name].size() != c.tags.size())
            throw Error("field " + name + " has " + std::to_string(c.fields[name].size()) +
                        " values for " + std::to_string(c.tags.size()) + " elements (damaged)");
        }
        for (const std::string &name : dataset_names(file, "/arrays"))
          c.arrays[name] = read_all<double>(file, "/arrays/" + name, H5T_NATIVE_DOUBLE);
        if (H5Lexists(file, "/dof_keys", H5P_DEFAULT) > 0) {
          c.dof_keys = read_all<std::uint64_t>(file, "/dof_keys", H5T_NATIVE_UINT64);
          for (const std::string &name : dataset_names(file, "/dof_fields")) {
            c.dof_fields[name] = read_all<double>(file, "/dof_fields/" + name, H5T_NATIVE_DOUBLE);
            if (c.dof_fields[name].size() != c.dof_keys.size())
              throw Error("dof field " + name + " has " +
                          std::to_string(c.dof_fields[name].size()) + " values for " +
                          std::to_string(c.dof_keys.size()) + " keys (damaged)");
          }
        }
      }
    } catch (const std::exception &e) {
      message = e.what();
    }
    H5Fclose(file);
  }
  H5Eset_auto2(H5E_DEFAULT, handler, data);
  if (!message.empty()) throw Error(message);
  return c;
}

template <class T> void bcast_values(MPI_Comm comm, std::vector<T> &v, MPI_Datatype type) {
  long long n = static_cast<long long>(v.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  v.resize(static_cast<std::size_t>(n));
  if (n > 0) MPI_Bcast(v.data(), static_cast<int>(n), type, 0, comm);
}

template <class V>
void bcast_map(MPI_Comm comm, std::map<std::string, V> &m, const std::function<void(V &)> &value) {
  std::vector<std::string> keys;
  for (const auto &entry : m) keys.push_back(entry.first);
  long long n = static_cast<long long>(keys.size());
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  keys.resize(static_cast<std::size_t>(n));
  for (std::string &k : keys) {
    broadcast_text(comm, k);
    value(m[k]);
  }
}

/// `path` read by rank 0 and sent to every rank; collective errors for a missing, unreadable or
/// damaged file.
Contents load(MPI_Comm comm, const std::string &path, bool labels_only) {
  int state = 0; // 0 read, 1 missing, 2 unreadable
  std::string message;
  Contents c;
  if (comm_rank(comm) == 0) {
    if (!std::filesystem::is_regular_file(path)) {
      state = 1;
    } else {
      try {
        c = read_on_root(path, labels_only);
      } catch (const std::exception &e) {
        state = 2;
        message = e.what();
      }
    }
  }
  MPI_Bcast(&state, 1, MPI_INT, 0, comm);
  if (state == 1)
    throw Error(path + ": restart file not found (run without --restart first)", true);
  broadcast_text(comm, message);
  if (state == 2) throw Error(path + ": " + message, true);
  bcast_map<std::string>(comm, c.labels, [&](std::string &v) { broadcast_text(comm, v); });
  bcast_values(comm, c.tags, MPI_UINT64_T);
  bcast_values(comm, c.dof_keys, MPI_UINT64_T);
  for (auto *m : {&c.fields, &c.arrays, &c.dof_fields})
    bcast_map<std::vector<double>>(
        comm, *m, [&](std::vector<double> &v) { bcast_values(comm, v, MPI_DOUBLE); });
  return c;
}

} // namespace

std::map<std::string, std::string> read_restart_labels(MPI_Comm comm, const std::string &path) {
  return load(comm, path, true).labels;
}

namespace {

/// `fields` (aligned with `file_keys`) picked for `keys`, this rank's, in their order; the first
/// key that `file_keys` lacks on any rank instead (returned, the fields left empty). Collective.
long long pick(MPI_Comm comm, const std::vector<std::uint64_t> &file_keys,
               const std::map<std::string, std::vector<double>> &fields,
               const std::vector<std::uint64_t> &keys,
               std::map<std::string, std::vector<double>> &out) {
  std::unordered_map<std::uint64_t, std::size_t> where;
  for (std::size_t k = 0; k < file_keys.size(); ++k) where[file_keys[k]] = k;
  std::vector<std::size_t> index(keys.size());
  long long missing = -1;
  for (std::size_t k = 0; k < keys.size() && missing < 0; ++k) {
    const auto it = where.find(keys[k]);
    if (it == where.end())
      missing = static_cast<long long>(keys[k]);
    else
      index[k] = it->second;
  }
  MPI_Allreduce(MPI_IN_PLACE, &missing, 1, MPI_LONG_LONG, MPI_MAX, comm);
  if (missing >= 0) return missing;
  for (const auto &[name, values] : fields) {
    auto &f = out[name];
    f.resize(keys.size());
    for (std::size_t k = 0; k < keys.size(); ++k) f[k] = values[index[k]];
  }
  return -1;
}

} // namespace

RestartData read_restart(MPI_Comm comm, const std::string &path,
                         const std::vector<std::uint64_t> &tags,
                         const std::vector<std::uint64_t> &dof_keys) {
  Contents c = load(comm, path, false);
  RestartData out;
  out.tags = tags;
  out.labels = std::move(c.labels);
  out.arrays = std::move(c.arrays);
  const long long missing = pick(comm, c.tags, c.fields, tags, out.fields);
  if (missing >= 0)
    throw Error(path + ": element " + std::to_string(missing) +
                    " is not in the restart file (written for another mesh, or damaged)",
                true);
  out.dof_keys = dof_keys;
  // The solvers' state only if the file has all of it (else none: the first solves start afresh).
  if (!c.dof_fields.empty() && pick(comm, c.dof_keys, c.dof_fields, dof_keys, out.dof_fields) >= 0)
    out.dof_fields.clear();
  return out;
}

} // namespace flexopt::io
