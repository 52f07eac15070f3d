#include "flexopt/core/error.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <gmsh.h>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <unordered_map>

namespace flexopt::mesh {

std::size_t SurfaceGroup::size() const {
  return connectivity.size() / static_cast<std::size_t>(nodes_per_face(type));
}

std::int64_t MeshData::element_count() const {
  return static_cast<std::int64_t>(connectivity.size()) / nodes_per_element(type);
}

std::string MeshEstimate::element_name() const {
  return hexahedra ? "Hex8" : (order == 2 ? "Tet10" : "Tet4");
}

namespace {

/// Gmsh element type codes (see the Gmsh reference manual, "MSH file format").
constexpr int kGmshLine2 = 1, kGmshTri3 = 2, kGmshQuad4 = 3, kGmshTet4 = 4, kGmshHex8 = 5,
              kGmshLine3 = 8, kGmshTri6 = 9, kGmshTet10 = 11;

std::string gmsh_last_error() {
  std::string err;
  try {
    gmsh::logger::getLastError(err);
  } catch (...) {
  }
  return err;
}

/// Scoped Gmsh session: initialised quietly, finalised on every exit path.
struct GmshSession {
  GmshSession() {
    gmsh::initialize(0, nullptr, false);
    gmsh::option::setNumber("General.Terminal", 0);
    gmsh::option::setNumber("General.Verbosity", 1);
  }
  ~GmshSession() {
    try {
      gmsh::finalize();
    } catch (...) {
    }
  }
};

ElementType volume_type(int gmsh_type, const std::string &path) {
  switch (gmsh_type) {
  case kGmshTet4:
    return ElementType::Tet4;
  case kGmshTet10:
    return ElementType::Tet10;
  case kGmshHex8:
    return ElementType::Hex8;
  default: {
    std::string name;
    int dim, order, nn, npn;
    std::vector<double> xi;
    gmsh::model::mesh::getElementProperties(gmsh_type, name, dim, order, nn, xi, npn);
    throw Error(path + ": volume element type '" + name +
                "' is not supported (supported: Tet4, Tet10, Hex8)");
  }
  }
}

FaceType face_type(int gmsh_type, const std::string &path, const std::string &group) {
  switch (gmsh_type) {
  case kGmshTri3:
    return FaceType::Tri3;
  case kGmshTri6:
    return FaceType::Tri6;
  case kGmshQuad4:
    return FaceType::Quad4;
  case kGmshLine2:
    return FaceType::Line2;
  case kGmshLine3:
    return FaceType::Line3;
  default:
    throw Error(path + ": physical surface '" + group + "' has face elements of Gmsh type " +
                std::to_string(gmsh_type) +
                " (supported: Tri3, Tri6, Quad4 faces; Line2, Line3 edges)");
  }
}

/// Node coordinates of the current mesh by Gmsh node tag.
std::unordered_map<std::size_t, std::array<double, 3>> node_coordinates() {
  std::vector<std::size_t> tags;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(tags, coords, param, -1, -1, true, false);
  std::unordered_map<std::size_t, std::array<double, 3>> at;
  at.reserve(tags.size());
  for (std::size_t i = 0; i < tags.size(); ++i)
    at[tags[i]] = {coords[3 * i], coords[3 * i + 1], coords[3 * i + 2]};
  return at;
}

/// Signed volume of the tetrahedron (origin, a, b, c): a . (b x c) / 6.
double cone_volume(const std::array<double, 3> &a, const std::array<double, 3> &b,
                   const std::array<double, 3> &c) {
  return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
          a[2] * (b[0] * c[1] - b[1] * c[0])) /
         6.0;
}

/// A 3D entity as the estimate sees it.
struct EntityEstimate {
  int tag = 0;
  double volume = 0;     ///< [m^3]
  bool hexahedra = true; ///< every face of its coarse boundary mesh is a quadrangle
  double size = 0;       ///< effective element size [m]
};

/// Volume and recombination of every 3D entity from a coarse surface mesh, and the total
/// length of the curves; the mesh is cleared afterwards and the size options restored.
std::vector<EntityEstimate> coarse_pass(double &curve_length) {
  double x0, y0, z0, x1, y1, z1;
  gmsh::model::getBoundingBox(-1, -1, x0, y0, z0, x1, y1, z1);
  const double diagonal = std::hypot(x1 - x0, y1 - y0, z1 - z0);
  double size_min, size_max;
  gmsh::option::getNumber("Mesh.MeshSizeMin", size_min);
  gmsh::option::getNumber("Mesh.MeshSizeMax", size_max);
  // Every size pinned to diagonal / 20 (transfinite curves and extrusion layers keep theirs):
  // a few hundred faces for a compact body, enough for planar faces to be exact.
  gmsh::option::setNumber("Mesh.MeshSizeMin", diagonal / 20);
  gmsh::option::setNumber("Mesh.MeshSizeMax", diagonal / 20);
  gmsh::model::mesh::generate(2);
  const auto at = node_coordinates();

  curve_length = 0;
  {
    std::vector<int> types;
    std::vector<std::vector<std::size_t>> tags, nodes;
    gmsh::model::mesh::getElements(types, tags, nodes, 1, -1);
    for (std::size_t k = 0; k < types.size(); ++k) {
      const std::size_t n = nodes[k].size() / std::max<std::size_t>(tags[k].size(), 1);
      for (std::size_t e = 0; e < tags[k].size(); ++e) {
        const auto &a = at.at(nodes[k][e * n]), &b = at.at(nodes[k][e * n + 1]);
        curve_length += std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
      }
    }
  }

  gmsh::vectorpair volumes;
  gmsh::model::getEntities(volumes, 3);
  std::vector<EntityEstimate> out;
  for (const auto &[dim, tag] : volumes) {
    EntityEstimate v;
    v.tag = tag;
    gmsh::vectorpair faces;
    gmsh::model::getBoundary({{dim, tag}}, faces, false, true, false);
    double signed_volume = 0;
    for (const auto &face : faces) {
      std::vector<int> types;
      std::vector<std::vector<std::size_t>> tags, nodes;
      gmsh::model::mesh::getElements(types, tags, nodes, 2, std::abs(face.second));
      const double sign = face.second < 0 ? -1.0 : 1.0;
      for (std::size_t k = 0; k < types.size(); ++k) {
        if (tags[k].empty()) continue;
        if (types[k] != kGmshQuad4) v.hexahedra = false;
        const std::size_t n = nodes[k].size() / tags[k].size();
        const int corners = types[k] == kGmshQuad4 ? 4 : 3;
        for (std::size_t e = 0; e < tags[k].size(); ++e) {
          const auto &a = at.at(nodes[k][e * n]);
          for (int c = 1; c + 1 < corners; ++c)
            signed_volume +=
                sign * cone_volume(a, at.at(nodes[k][e * n + c]), at.at(nodes[k][e * n + c + 1]));
        }
      }
    }
    v.volume = std::abs(signed_volume);
    // An OpenCASCADE entity has its exact volume (and the sum above can mix orientations on
    // faces shared by two volumes after BooleanFragments); built-in entities are not known to
    // OpenCASCADE and keep the sum.
    try {
      double mass = 0;
      gmsh::model::occ::getMass(dim, tag, mass);
      if (mass > 0) v.volume = mass;
    } catch (...) {
    }
    out.push_back(v);
  }
  gmsh::model::mesh::clear();
  gmsh::option::setNumber("Mesh.MeshSizeMin", size_min);
  gmsh::option::setNumber("Mesh.MeshSizeMax", size_max);
  return out;
}

/// Effective element size of each entity from the 1D mesh at the run's settings.
void curve_sizes(std::vector<EntityEstimate> &entities) {
  gmsh::model::mesh::generate(1);
  const auto at = node_coordinates();
  std::map<int, std::pair<double, std::size_t>> curves; // tag -> (length, segments)
  for (auto &v : entities) {
    gmsh::vectorpair faces, edges;
    gmsh::model::getBoundary({{3, v.tag}}, faces, false, false, false);
    gmsh::model::getBoundary(faces, edges, false, false, false);
    std::set<int> tags;
    for (const auto &e : edges) tags.insert(std::abs(e.second));
    double log_sum_long = 0, log_sum_all = 0;
    int n_long = 0, n_all = 0;
    for (int c : tags) {
      auto it = curves.find(c);
      if (it == curves.end()) {
        std::vector<int> types;
        std::vector<std::vector<std::size_t>> etags, nodes;
        gmsh::model::mesh::getElements(types, etags, nodes, 1, c);
        double length = 0;
        std::size_t segments = 0;
        for (std::size_t k = 0; k < types.size(); ++k) {
          if (etags[k].empty()) continue;
          const std::size_t n = nodes[k].size() / etags[k].size();
          for (std::size_t e = 0; e < etags[k].size(); ++e) {
            const auto &a = at.at(nodes[k][e * n]), &b = at.at(nodes[k][e * n + 1]);
            length += std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]);
          }
          segments += etags[k].size();
        }
        it = curves.emplace(c, std::make_pair(length, segments)).first;
      }
      const auto [length, segments] = it->second;
      if (segments == 0 || !(length > 0)) continue;
      const double h = std::log(length / static_cast<double>(segments));
      log_sum_all += h;
      ++n_all;
      if (segments >= 2) {
        log_sum_long += h;
        ++n_long;
      }
    }
    // Curves of one segment are shorter than the size (small features, or the mesh is coarser
    // than the body): they tell its size only if no curve has two segments.
    if (n_long > 0)
      v.size = std::exp(log_sum_long / n_long);
    else if (n_all > 0)
      v.size = std::exp(log_sum_all / n_all);
  }
}

/// The estimate of the model open in Gmsh (the session is discarded afterwards).
MeshEstimate estimate_open_model(const std::string &path, const MeshOptions &options) {
  double curve_length = 0;
  std::vector<EntityEstimate> entities = coarse_pass(curve_length);
  if (entities.empty())
    throw Error(path + ": the mesh has no volume elements (the .geo defines no Volume; flexopt "
                       "meshes the 3D entities of a .geo)");
  if (options.size > 0 && curve_length / options.size > kMaxEstimateSegments)
    for (auto &v : entities) v.size = options.size;
  else
    curve_sizes(entities);

  MeshEstimate est;
  est.order = options.order;
  est.hexahedra = true;
  double vertices = 0, cubes = 0;
  for (const auto &v : entities) {
    if (!(v.size > 0))
      throw Error(path + ": no element size could be found for volume " + std::to_string(v.tag) +
                  " (its curves have no 1D mesh)");
    const double n_cubes = v.volume / (v.size * v.size * v.size);
    const double elements = (v.hexahedra ? 1.0 : kTetsPerCube) * n_cubes;
    est.volume += v.volume;
    est.elements += elements;
    cubes += n_cubes;
    est.hexahedra = est.hexahedra && v.hexahedra;
    // Hexahedra: one vertex per element; tetrahedra: kTetsPerVertex elements per vertex.
    const double verts = v.hexahedra ? elements : elements / kTetsPerVertex;
    vertices += verts;
    // Order 2 adds a node per edge: about vertices + elements edges (Euler: V - E + F - T = 1
    // with F ~ 2T); hexahedra: order 2 is refused by the reader, count their vertices.
    est.nodes += verts + (options.order == 2 && !v.hexahedra ? verts + elements : 0.0);
  }
  est.size = cubes > 0 ? std::cbrt(est.volume / cubes) : 0;
  return est;
}

/// Calls `progress(stage, seconds)` every kProgressInterval s from a thread of its own until
/// destroyed; `stage(name)` names what Gmsh does now.
class ProgressTicker {
public:
  explicit ProgressTicker(std::function<void(const char *, double)> progress)
      : progress_(std::move(progress)), start_(std::chrono::steady_clock::now()) {
    if (progress_) thread_ = std::thread([this] { run(); });
  }
  ~ProgressTicker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  void stage(const char *name) {
    std::lock_guard<std::mutex> lock(mutex_);
    stage_ = name;
  }
  ProgressTicker(const ProgressTicker &) = delete;
  ProgressTicker &operator=(const ProgressTicker &) = delete;

private:
  void run() {
    std::unique_lock<std::mutex> lock(mutex_);
    const auto interval = std::chrono::duration<double>(kProgressInterval);
    auto next = start_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(interval);
    while (!cv_.wait_until(lock, next, [this] { return done_; })) {
      const double s =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
      progress_(stage_, s);
      next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(interval);
    }
  }
  std::function<void(const char *, double)> progress_;
  std::chrono::steady_clock::time_point start_;
  std::mutex mutex_;
  std::condition_variable cv_;
  const char *stage_ = "curves";
  bool done_ = false;
  std::thread thread_;
};

/// Opens a .geo with the options' sizes applied.
void open_geo(const std::string &path, const MeshOptions &options) {
  if (options.size > 0) {
    gmsh::option::setNumber("Mesh.MeshSizeMax", options.size);
    gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
  }
  gmsh::open(path);
}

std::string gmsh_failure(const std::string &path) {
  std::string err = gmsh_last_error();
  return path + ": Gmsh failed" + (err.empty() ? std::string() : ": " + err);
}

/// Meshes the .geo (with the options' sizes and order) or opens the .msh in the current Gmsh
/// session; any Gmsh failure becomes a flexopt::Error naming the file.
void mesh_or_open(const std::string &path, const std::string &ext, const MeshOptions &options) {
  if (ext == ".geo") {
    try {
      ProgressTicker ticker(options.progress);
      open_geo(path, options);
      ticker.stage("geometry (curves, surfaces, volumes)");
      gmsh::model::mesh::generate(3);
      if (options.order == 2) {
        ticker.stage("order 2");
        gmsh::option::setNumber("Mesh.SecondOrderLinear", 0);
        gmsh::model::mesh::setOrder(2);
      }
    } catch (...) {
      throw Error(gmsh_failure(path));
    }
  } else {
    try {
      gmsh::open(path);
    } catch (...) {
      throw Error(gmsh_failure(path));
    }
  }
}

/// The volume elements of the model by Gmsh type block: every 3D entity belongs to the body,
/// and all its elements have one type.
struct VolumeElements {
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> tags, nodes;
  std::size_t count = 0; ///< elements over all blocks
  int gmsh_type = -1;

  explicit VolumeElements(const std::string &path) {
    gmsh::model::mesh::getElements(types, tags, nodes, 3, -1);
    for (std::size_t k = 0; k < types.size(); ++k) {
      if (tags[k].empty()) continue;
      if (gmsh_type != -1 && gmsh_type != types[k])
        throw Error(path + ": the mesh mixes volume element types; flexopt needs one type per "
                           "body (all Tet4, all Tet10 or all Hex8)");
      gmsh_type = types[k];
      count += tags[k].size();
    }
    if (count == 0)
      throw Error(path + ": the mesh has no volume elements (is there a Volume in the geometry, "
                         "and was it meshed in 3D?)");
  }
};

/// Gmsh node tags -> compact indices over the nodes that volume elements use, and their
/// coordinates into mesh.coordinates.
std::unordered_map<std::size_t, std::int64_t>
compact_nodes(const std::string &path, const VolumeElements &volume, MeshData &mesh) {
  // Gmsh node tags -> compact indices over the nodes that volume elements use.
  std::unordered_map<std::size_t, std::int64_t> index_of;
  index_of.reserve(volume.count * 2);
  std::vector<std::size_t> used_tags;
  for (std::size_t k = 0; k < volume.types.size(); ++k)
    for (std::size_t t : volume.nodes[k])
      if (index_of.emplace(t, static_cast<std::int64_t>(used_tags.size())).second)
        used_tags.push_back(t);

  std::vector<std::size_t> node_tags;
  std::vector<double> coords, param;
  gmsh::model::mesh::getNodes(node_tags, coords, param, -1, -1, true, false);
  mesh.coordinates.assign(3 * used_tags.size(), 0.0);
  std::size_t found = 0;
  for (std::size_t i = 0; i < node_tags.size(); ++i) {
    auto it = index_of.find(node_tags[i]);
    if (it == index_of.end()) continue;
    std::copy_n(&coords[3 * i], 3, &mesh.coordinates[3 * static_cast<std::size_t>(it->second)]);
    ++found;
  }
  if (found < used_tags.size()) throw Error(path + ": some element nodes have no coordinates");
  return index_of;
}

/// The elements' tags and connectivity (compact node indices) into mesh; returns the element
/// index of each Gmsh element tag.
std::unordered_map<std::size_t, std::int64_t>
element_connectivity(const VolumeElements &volume,
                     const std::unordered_map<std::size_t, std::int64_t> &index_of,
                     MeshData &mesh) {
  const int npe = nodes_per_element(mesh.type);
  mesh.connectivity.reserve(volume.count * static_cast<std::size_t>(npe));
  std::unordered_map<std::size_t, std::int64_t> element_index;
  for (std::size_t k = 0; k < volume.types.size(); ++k) {
    for (std::size_t e = 0; e < volume.tags[k].size(); ++e) {
      element_index[volume.tags[k][e]] = static_cast<std::int64_t>(mesh.element_tags.size());
      mesh.element_tags.push_back(volume.tags[k][e]);
      for (int a = 0; a < npe; ++a)
        mesh.connectivity.push_back(index_of.at(
            volume.nodes[k][e * static_cast<std::size_t>(npe) + static_cast<std::size_t>(a)]));
    }
  }
  return element_index;
}

/// The sorted element indices of a physical volume's entities.
void read_volume_group(const std::vector<int> &entities,
                       const std::unordered_map<std::size_t, std::int64_t> &element_index,
                       std::vector<std::int64_t> &list) {
  for (int ent : entities) {
    std::vector<int> et;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(et, etags, enodes, 3, ent);
    for (const auto &tv : etags)
      for (std::size_t t : tv) list.push_back(element_index.at(t));
  }
  std::sort(list.begin(), list.end());
}

/// A physical surface's (dim 2) or curve's (dim 1) faces of one type, in compact node indices;
/// throws unless every face node is a volume element's.
void read_surface_group(const std::string &path, const std::string &name, int dim,
                        const std::vector<int> &entities,
                        const std::unordered_map<std::size_t, std::int64_t> &index_of,
                        SurfaceGroup &group) {
  int ftype = -1;
  for (int ent : entities) {
    std::vector<int> et;
    std::vector<std::vector<std::size_t>> etags, enodes;
    gmsh::model::mesh::getElements(et, etags, enodes, dim, ent);
    for (std::size_t k = 0; k < et.size(); ++k) {
      if (etags[k].empty()) continue;
      if (ftype != -1 && ftype != et[k])
        throw Error(path + ": physical surface '" + name + "' mixes face element types");
      ftype = et[k];
      group.type = face_type(et[k], path, name);
      for (std::size_t t : enodes[k]) {
        auto it = index_of.find(t);
        if (it == index_of.end())
          throw Error(path + ": physical surface '" + name +
                      "' has nodes that belong to no volume element (a surface outside the body?)");
        group.connectivity.push_back(it->second);
      }
    }
  }
  if (group.connectivity.empty())
    throw Error(path + ": physical surface '" + name + "' has no mesh faces");
}

/// The physical groups by name: volumes as element lists, surfaces and curves as face groups
/// (one namespace of boundary groups).
void read_physical_groups(const std::string &path,
                          const std::unordered_map<std::size_t, std::int64_t> &index_of,
                          const std::unordered_map<std::size_t, std::int64_t> &element_index,
                          MeshData &mesh) {
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups, -1);
  for (const auto &[dim, tag] : groups) {
    if (dim < 1 || dim > 3) continue;
    std::string name;
    gmsh::model::getPhysicalName(dim, tag, name);
    if (name.empty()) name = std::to_string(tag);
    std::vector<int> entities;
    gmsh::model::getEntitiesForPhysicalGroup(dim, tag, entities);
    if (dim == 3) {
      read_volume_group(entities, element_index, mesh.volume_groups[name]);
    } else {
      // Physical surfaces and physical curves share one namespace of boundary groups.
      if (mesh.surface_groups.count(name))
        throw Error(path + ": a physical curve and a physical surface are both named '" + name +
                    "'");
      read_surface_group(path, name, dim, entities, index_of, mesh.surface_groups[name]);
    }
  }
}

} // namespace

MeshData read_gmsh(const std::string &path, const MeshOptions &options, MeshEstimate *estimate) {
  namespace fs = std::filesystem;
  if (!fs::is_regular_file(path)) throw Error(path + ": geometry file not found");
  const std::string ext = fs::path(path).extension().string();

  MeshData mesh;
  mesh.source = path;
  if (ext == ".geo") {
    // The estimate runs in a Gmsh session of its own, so that the mesh made afterwards is
    // exactly the one Gmsh makes of the .geo without it.
    const MeshEstimate est = estimate_gmsh(path, options);
    if (estimate) *estimate = est;
    if (options.before_meshing) options.before_meshing(est); // may refuse: not Gmsh's failure
  }
  GmshSession session;
  mesh_or_open(path, ext, options);

  // Volume elements: every 3D entity of the model belongs to the body.
  const VolumeElements volume(path);
  mesh.type = volume_type(volume.gmsh_type, path);
  const auto index_of = compact_nodes(path, volume, mesh);
  const auto element_index = element_connectivity(volume, index_of, mesh);
  read_physical_groups(path, index_of, element_index, mesh);
  return mesh;
}

MeshEstimate estimate_gmsh(const std::string &path, const MeshOptions &options) {
  if (!std::filesystem::is_regular_file(path)) throw Error(path + ": geometry file not found");
  GmshSession session;
  try {
    open_geo(path, options);
    return estimate_open_model(path, options);
  } catch (const Error &) {
    throw;
  } catch (...) {
    throw Error(gmsh_failure(path));
  }
}

} // namespace flexopt::mesh
