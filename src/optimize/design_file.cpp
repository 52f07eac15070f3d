// The fingerprint of a design and the checks of a design file before use (issue 42).
#include "flexopt/optimize/design_file.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace flexopt::optimize {

namespace {

/// SplitMix64's finalizer: a well-mixed 64-bit value of z.
std::uint64_t mix(std::uint64_t z) {
  z += 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// The XOR over the design elements of a hash of (tag, centroid rounded to float): the same for
/// any partition and element order; rounding to 7 digits makes it blind to the last bits of
/// the coordinates (a centroid summed in another order).
std::uint64_t positions_hash(const DesignField &field) {
  const mesh::DistributedMesh &m = field.mesh();
  std::uint64_t local = 0;
  for (std::size_t k = 0; k < field.design_elements().size(); ++k) {
    const mesh::ElementCoords X = m.element_coordinates(field.design_elements()[k]);
    const Eigen::RowVector3d centroid = X.colwise().mean();
    std::uint64_t h = mix(static_cast<std::uint64_t>(field.design_tags()[k]));
    for (int d = 0; d < 3; ++d) {
      const float c = static_cast<float>(centroid(d));
      std::uint32_t bits = 0;
      std::memcpy(&bits, &c, sizeof bits);
      h = mix(h ^ bits);
    }
    local ^= h;
  }
  std::uint64_t global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_UINT64_T, MPI_BXOR, m.comm);
  return global;
}

std::string hex(std::uint64_t v) {
  char s[17];
  std::snprintf(s, sizeof s, "%016llx", static_cast<unsigned long long>(v));
  return s;
}

} // namespace

std::map<std::string, std::string> design_fingerprint(const Design &design) {
  // Several design bodies: their names and regions joined, the positions' hashes mixed with the
  // field's index (field 0 alone: the one-body fingerprint).
  std::string bodies, regions;
  std::uint64_t positions = 0;
  for (std::size_t k = 0; k < design.size(); ++k) {
    const DesignField &field = design.field(k);
    bodies += (k ? "," : "") + field.settings().body;
    regions += (k ? "," : "") + field.settings().region;
    const std::uint64_t h = positions_hash(field);
    positions ^= k == 0 ? h : mix(h ^ k);
  }
  return {{"design_body", bodies},
          {"design_region", regions},
          {"design_elements", std::to_string(static_cast<long long>(design.design_size()))},
          {"design_positions", hex(positions)}};
}

void check_design_file(const Design &design, const std::string &path) {
  const auto labels = io::read_restart_labels(design.comm(), path);
  const auto expected = design_fingerprint(design);
  if (labels.count("design_elements") == 0) {
    print0(design.comm(),
           "warning: %s carries no design fingerprint (written by an earlier flexopt): whether it "
           "belongs to this case's design is not checked\n",
           path.c_str());
  } else {
    const auto got = [&](const char *key) {
      const auto it = labels.find(key);
      return it == labels.end() ? std::string("(none)") : it->second;
    };
    std::string differs;
    for (const char *key : {"design_body", "design_region", "design_elements"})
      if (got(key) != expected.at(key))
        differs += std::string(differs.empty() ? "" : "; ") + key + " '" + got(key) +
                   "' in the file, '" + expected.at(key) + "' in this case";
    if (differs.empty() && got("design_positions") != expected.at("design_positions"))
      differs = "the design elements' tags or positions differ (the same body, region and "
                "element count on another mesh: mesh.size, mesh.order or the geometry changed)";
    if (!differs.empty()) throw Error(path + ": written for another design: " + differs, true);
  }
}

void check_design_values(const Design &design, const std::vector<double> &values,
                         const std::string &path, const std::string &what) {
  const MPI_Comm comm = design.comm();
  long long bad_tag = LLONG_MAX; // the lowest key: (field, Gmsh tag)
  double bad_value = 0;
  const std::vector<std::uint64_t> &keys = design.design_keys();
  for (std::size_t k = 0; k < values.size() && k < keys.size(); ++k) {
    const double v = values[k];
    const auto key = static_cast<long long>(keys[k]);
    if ((!std::isfinite(v) || v < 0 || v > 1) && key < bad_tag) bad_tag = key, bad_value = v;
  }
  long long first = LLONG_MAX;
  MPI_Allreduce(&bad_tag, &first, 1, MPI_LONG_LONG, MPI_MIN, comm);
  if (first == LLONG_MAX) return;
  int owner = bad_tag == first ? comm_rank(comm) : comm_size(comm);
  int root = 0;
  MPI_Allreduce(&owner, &root, 1, MPI_INT, MPI_MIN, comm);
  MPI_Bcast(&bad_value, 1, MPI_DOUBLE, root, comm);
  char value[64];
  std::snprintf(value, sizeof value, "%.17g", bad_value);
  // The key's field and Gmsh tag (Design::design_keys: tag + field 2^48).
  const std::size_t field = Design::key_field(static_cast<std::uint64_t>(first));
  const long long tag = Design::key_tag(static_cast<std::uint64_t>(first));
  const std::string body =
      design.size() > 1 ? " of body '" + design.field(field).settings().body + "'" : "";
  throw Error(path + ": field '" + what + "': element " + std::to_string(tag) + body + " has " +
                  value + ", not a density in [0, 1]",
              true);
}

std::vector<std::uint64_t> dof_keys(const mesh::DistributedMesh &mesh, int components) {
  std::vector<std::uint64_t> keys;
  keys.reserve(static_cast<std::size_t>(mesh.owned_nodes * components));
  for (PetscInt n = 0; n < mesh.owned_nodes; ++n) {
    std::uint64_t h = 0x6a09e667f3bcc909ULL;
    for (int d = 0; d < 3; ++d) {
      std::uint64_t bits = 0;
      const double x = mesh.coordinates[static_cast<std::size_t>(3 * n + d)];
      std::memcpy(&bits, &x, sizeof bits);
      h = mix(h ^ bits);
    }
    for (int c = 0; c < components; ++c) keys.push_back(mix(h ^ static_cast<std::uint64_t>(c + 1)));
  }
  return keys;
}

} // namespace flexopt::optimize
