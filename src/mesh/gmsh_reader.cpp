#include "flexopt/core/error.hpp"
#include "flexopt/mesh/mesh_data.hpp"

#include <algorithm>
#include <filesystem>
#include <gmsh.h>
#include <set>
#include <unordered_map>

namespace flexopt::mesh {

std::size_t SurfaceGroup::size() const {
  return connectivity.size() / static_cast<std::size_t>(fem::nodes_per_face(type));
}

std::int64_t MeshData::element_count() const {
  return static_cast<std::int64_t>(connectivity.size()) / fem::nodes_per_element(type);
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

fem::ElementType volume_type(int gmsh_type, const std::string &path) {
  switch (gmsh_type) {
  case kGmshTet4:
    return fem::ElementType::Tet4;
  case kGmshTet10:
    return fem::ElementType::Tet10;
  case kGmshHex8:
    return fem::ElementType::Hex8;
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

fem::FaceType face_type(int gmsh_type, const std::string &path, const std::string &group) {
  switch (gmsh_type) {
  case kGmshTri3:
    return fem::FaceType::Tri3;
  case kGmshTri6:
    return fem::FaceType::Tri6;
  case kGmshQuad4:
    return fem::FaceType::Quad4;
  case kGmshLine2:
    return fem::FaceType::Line2;
  case kGmshLine3:
    return fem::FaceType::Line3;
  default:
    throw Error(path + ": physical surface '" + group + "' has face elements of Gmsh type " +
                std::to_string(gmsh_type) +
                " (supported: Tri3, Tri6, Quad4 faces; Line2, Line3 edges)");
  }
}

} // namespace

MeshData read_gmsh(const std::string &path, const MeshOptions &options) {
  namespace fs = std::filesystem;
  if (!fs::is_regular_file(path)) throw Error(path + ": geometry file not found");
  const std::string ext = fs::path(path).extension().string();

  MeshData mesh;
  mesh.source = path;
  GmshSession session;
  try {
    if (ext == ".geo") {
      if (options.size > 0) {
        gmsh::option::setNumber("Mesh.MeshSizeMax", options.size);
        gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", 0);
      }
      gmsh::open(path);
      gmsh::model::mesh::generate(3);
      if (options.order == 2) {
        gmsh::option::setNumber("Mesh.SecondOrderLinear", 0);
        gmsh::model::mesh::setOrder(2);
      }
    } else {
      gmsh::open(path);
    }
  } catch (...) {
    std::string err = gmsh_last_error();
    throw Error(path + ": Gmsh failed" + (err.empty() ? std::string() : ": " + err));
  }

  // Volume elements: every 3D entity of the model belongs to the body.
  std::vector<int> types;
  std::vector<std::vector<std::size_t>> tags, nodes;
  gmsh::model::mesh::getElements(types, tags, nodes, 3, -1);
  std::size_t n_volume = 0;
  int vtype = -1;
  for (std::size_t k = 0; k < types.size(); ++k) {
    if (tags[k].empty()) continue;
    if (vtype != -1 && vtype != types[k])
      throw Error(path + ": the mesh mixes volume element types; flexopt needs one type per body "
                         "(all Tet4, all Tet10 or all Hex8)");
    vtype = types[k];
    n_volume += tags[k].size();
  }
  if (n_volume == 0)
    throw Error(path + ": the mesh has no volume elements (is there a Volume in the geometry, "
                       "and was it meshed in 3D?)");
  mesh.type = volume_type(vtype, path);
  const int npe = fem::nodes_per_element(mesh.type);

  // Gmsh node tags -> compact indices over the nodes that volume elements use.
  std::unordered_map<std::size_t, std::int64_t> index_of;
  index_of.reserve(n_volume * 2);
  std::vector<std::size_t> used_tags;
  for (std::size_t k = 0; k < types.size(); ++k)
    for (std::size_t t : nodes[k])
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

  mesh.connectivity.reserve(n_volume * static_cast<std::size_t>(npe));
  std::unordered_map<std::size_t, std::int64_t> element_index;
  for (std::size_t k = 0; k < types.size(); ++k) {
    for (std::size_t e = 0; e < tags[k].size(); ++e) {
      element_index[tags[k][e]] = static_cast<std::int64_t>(mesh.element_tags.size());
      mesh.element_tags.push_back(tags[k][e]);
      for (int a = 0; a < npe; ++a)
        mesh.connectivity.push_back(
            index_of.at(nodes[k][e * static_cast<std::size_t>(npe) + static_cast<std::size_t>(a)]));
    }
  }

  // Physical groups by name.
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
      auto &list = mesh.volume_groups[name];
      for (int ent : entities) {
        std::vector<int> et;
        std::vector<std::vector<std::size_t>> etags, enodes;
        gmsh::model::mesh::getElements(et, etags, enodes, 3, ent);
        for (const auto &tv : etags)
          for (std::size_t t : tv) list.push_back(element_index.at(t));
      }
      std::sort(list.begin(), list.end());
    } else {
      // Physical surfaces and physical curves share one namespace of boundary groups.
      if (mesh.surface_groups.count(name))
        throw Error(path + ": a physical curve and a physical surface are both named '" + name +
                    "'");
      SurfaceGroup &group = mesh.surface_groups[name];
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
              throw Error(
                  path + ": physical surface '" + name +
                  "' has nodes that belong to no volume element (a surface outside the body?)");
            group.connectivity.push_back(it->second);
          }
        }
      }
      if (group.connectivity.empty())
        throw Error(path + ": physical surface '" + name + "' has no mesh faces");
    }
  }
  return mesh;
}

} // namespace flexopt::mesh
