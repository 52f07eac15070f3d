#include "flexopt/mesh/distributed_mesh.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <metis.h>
#include <numeric>

namespace flexopt::mesh {

PetscInt DistributedMesh::local_elements() const {
  return static_cast<PetscInt>(connectivity.size()) / nodes_per_element();
}

ElementCoords DistributedMesh::element_coordinates(PetscInt e) const {
  const int npe = nodes_per_element();
  ElementCoords X(npe, 3);
  for (int a = 0; a < npe; ++a) {
    const PetscInt n = connectivity[static_cast<std::size_t>(e * npe + a)];
    for (int k = 0; k < 3; ++k) X(a, k) = coordinates[static_cast<std::size_t>(3 * n + k)];
  }
  return X;
}

namespace {

std::string group_list(const std::vector<std::string> &names) {
  std::string s;
  for (const auto &n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

} // namespace

namespace {

/// A named physical group of `groups`, or a collective error listing the names there are.
template <class Map>
const typename Map::mapped_type &find_group(const Map &groups, const std::string &name,
                                            const char *kind, const std::string &source,
                                            const std::string &where) {
  auto it = groups.find(name);
  if (it != groups.end()) return it->second;
  std::vector<std::string> names;
  for (const auto &kv : groups) names.push_back(kv.first);
  throw Error(where + ": no physical " + kind + " '" + name + "' in " + source + " (physical " +
                  kind + "s there: " + group_list(names) + ")",
              true);
}

} // namespace

const LocalSurface &DistributedMesh::surface(const std::string &name,
                                             const std::string &where) const {
  return find_group(surfaces, name, "surface", source, where);
}

FaceCoords LocalSurface::face_coordinates(std::size_t f) const {
  const auto nf = static_cast<std::size_t>(nodes_per_face(type));
  FaceCoords X(static_cast<Eigen::Index>(nf), 3);
  for (std::size_t a = 0; a < nf; ++a)
    for (std::size_t k = 0; k < 3; ++k)
      X(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(k)) =
          coordinates[3 * (f * nf + a) + k];
  return X;
}

const std::vector<PetscInt> &DistributedMesh::volume_group(const std::string &name,
                                                           const std::string &where) const {
  return find_group(volume_groups, name, "volume", source, where);
}

namespace {

/// Root sends per_rank[p] to rank p; every rank returns its part. Collective.
template <class T>
std::vector<T> scatter_parts(MPI_Comm comm, const std::vector<std::vector<T>> &per_rank) {
  const int rank = comm_rank(comm), size = comm_size(comm);
  std::vector<long long> counts(static_cast<std::size_t>(size), 0);
  if (rank == 0)
    for (int p = 0; p < size; ++p)
      counts[static_cast<std::size_t>(p)] =
          static_cast<long long>(per_rank[static_cast<std::size_t>(p)].size());
  long long my_count = 0;
  MPI_Scatter(counts.data(), 1, MPI_LONG_LONG, &my_count, 1, MPI_LONG_LONG, 0, comm);
  std::vector<T> mine(static_cast<std::size_t>(my_count));
  if (rank == 0) {
    mine = per_rank[0];
    std::vector<MPI_Request> requests;
    for (int p = 1; p < size; ++p) {
      const auto &v = per_rank[static_cast<std::size_t>(p)];
      // Chunked sends keep every message below the 2 GiB count limit of MPI.
      const std::size_t bytes = v.size() * sizeof(T);
      const std::size_t chunk = std::size_t(1) << 30;
      for (std::size_t off = 0; off < bytes; off += chunk) {
        requests.emplace_back();
        MPI_Isend(reinterpret_cast<const char *>(v.data()) + off,
                  static_cast<int>(std::min(chunk, bytes - off)), MPI_BYTE, p, 7, comm,
                  &requests.back());
      }
    }
    MPI_Waitall(static_cast<int>(requests.size()), requests.data(), MPI_STATUSES_IGNORE);
  } else {
    const std::size_t bytes = mine.size() * sizeof(T);
    const std::size_t chunk = std::size_t(1) << 30;
    for (std::size_t off = 0; off < bytes; off += chunk)
      MPI_Recv(reinterpret_cast<char *>(mine.data()) + off,
               static_cast<int>(std::min(chunk, bytes - off)), MPI_BYTE, 0, 7, comm,
               MPI_STATUS_IGNORE);
  }
  return mine;
}

/// Element partition with METIS_PartMeshDual on corner nodes: two elements are neighbours if
/// they share a face (3 corners for tets, 4 for hexes).
std::vector<int> partition_elements(const MeshData &m, int parts) {
  const std::int64_t ne = m.element_count();
  std::vector<int> part(static_cast<std::size_t>(ne), 0);
  if (parts == 1 || ne == 0) return part;
  if (ne < parts)
    throw Error(m.source + ": the mesh has fewer elements (" + std::to_string(ne) +
                ") than ranks (" + std::to_string(parts) + ")");
  const int npe = nodes_per_element(m.type), nc = corner_nodes(m.type);
  std::vector<idx_t> eptr(static_cast<std::size_t>(ne + 1)),
      eind(static_cast<std::size_t>(ne * nc));
  for (std::int64_t e = 0; e < ne; ++e) {
    eptr[static_cast<std::size_t>(e)] = static_cast<idx_t>(e * nc);
    for (int a = 0; a < nc; ++a)
      eind[static_cast<std::size_t>(e * nc + a)] =
          static_cast<idx_t>(m.connectivity[static_cast<std::size_t>(e * npe + a)]);
  }
  eptr[static_cast<std::size_t>(ne)] = static_cast<idx_t>(ne * nc);
  idx_t n_el = static_cast<idx_t>(ne), n_nodes = static_cast<idx_t>(m.node_count());
  idx_t ncommon = (m.type == ElementType::Hex8) ? 4 : 3;
  idx_t nparts = parts, objval = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_SEED] = 1; // deterministic partitions
  std::vector<idx_t> epart(static_cast<std::size_t>(ne)), npart(static_cast<std::size_t>(n_nodes));
  int status =
      METIS_PartMeshDual(&n_el, &n_nodes, eptr.data(), eind.data(), nullptr, nullptr, &ncommon,
                         &nparts, nullptr, options, &objval, epart.data(), npart.data());
  if (status != METIS_OK)
    throw Error(m.source + ": METIS_PartMeshDual failed (status " + std::to_string(status) + ")");
  for (std::int64_t e = 0; e < ne; ++e)
    part[static_cast<std::size_t>(e)] = static_cast<int>(epart[static_cast<std::size_t>(e)]);
  return part;
}

/// The lines of s, each ended by '\n'.
std::vector<std::string> split_lines(const std::string &s) {
  std::vector<std::string> out;
  std::size_t a = 0;
  for (std::size_t b; (b = s.find('\n', a)) != std::string::npos; a = b + 1)
    out.push_back(s.substr(a, b - a));
  return out;
}

/// What every rank needs to know before its part: type, sizes, group names (and the face type
/// of each surface group). Collective; root_mesh significant on rank 0 only.
struct MeshHeader {
  std::vector<std::string> vnames, snames;
  std::vector<int> face_types;

  MeshHeader(MPI_Comm comm, const MeshData *root_mesh, DistributedMesh &dm) {
    // Everything every rank needs to know first: type, sizes, group names.
    int type = 0;
    long long n_nodes = 0;
    std::string volume_names, surface_names;
    if (comm_rank(comm) == 0) {
      dm.source = root_mesh->source;
      type = static_cast<int>(root_mesh->type);
      n_nodes = root_mesh->node_count();
      for (const auto &kv : root_mesh->volume_groups) volume_names += kv.first + '\n';
      for (const auto &kv : root_mesh->surface_groups) {
        surface_names += kv.first + '\n';
        face_types.push_back(static_cast<int>(kv.second.type));
      }
    }
    broadcast_text(comm, dm.source);
    broadcast_text(comm, volume_names);
    broadcast_text(comm, surface_names);
    MPI_Bcast(&type, 1, MPI_INT, 0, comm);
    MPI_Bcast(&n_nodes, 1, MPI_LONG_LONG, 0, comm);
    dm.type = static_cast<ElementType>(type);
    dm.global_nodes = static_cast<PetscInt>(n_nodes);
    vnames = split_lines(volume_names);
    snames = split_lines(surface_names);
    int n_faces_types = static_cast<int>(snames.size());
    face_types.resize(snames.size());
    MPI_Bcast(face_types.data(), n_faces_types, MPI_INT, 0, comm);
  }
};

/// Per rank p, what the root sends it (docs/theory.md section 2): elements (connectivity in
/// the local numbering, tags), ghosts, node coordinates, the owned range, and its share of every
/// volume and surface group.
struct MeshParts {
  template <class T> using PerRank = std::vector<std::vector<T>>;
  PerRank<PetscInt> conn, ghosts;
  PerRank<double> coords;
  PerRank<std::size_t> tags;
  PerRank<PetscInt> meta; ///< owned count, start
  std::vector<PerRank<PetscInt>> vgroups, sfaces, snodes;
  std::vector<PerRank<double>> scoords;

  MeshParts(int size, std::size_t volume_groups, std::size_t surface_groups)
      : conn(static_cast<std::size_t>(size)), ghosts(static_cast<std::size_t>(size)),
        coords(static_cast<std::size_t>(size)), tags(static_cast<std::size_t>(size)),
        meta(static_cast<std::size_t>(size)),
        vgroups(volume_groups, PerRank<PetscInt>(static_cast<std::size_t>(size))),
        sfaces(surface_groups, PerRank<PetscInt>(static_cast<std::size_t>(size))),
        snodes(surface_groups, PerRank<PetscInt>(static_cast<std::size_t>(size))),
        scoords(surface_groups, PerRank<double>(static_cast<std::size_t>(size))) {}
};

/// The node ownership and the global renumbering (docs/theory.md section 2, "Ownership"): a
/// node belongs to the lowest part among the elements touching it; nodes are numbered by owner
/// rank, then by original index.
struct NodeNumbering {
  std::vector<int> owner;               ///< by original node
  std::vector<PetscInt> owned_count;    ///< per rank
  std::vector<PetscInt> start;          ///< per rank: first owned global node
  std::vector<PetscInt> new_number;     ///< by original node
  std::vector<std::int64_t> old_of_new; ///< by new number

  NodeNumbering(const MeshData &m, const std::vector<int> &part, int size) {
    const std::int64_t ne = m.element_count(), nn = m.node_count();
    const int npe = nodes_per_element(m.type);
    // Owner of a node: the lowest part among the elements touching it.
    owner.assign(static_cast<std::size_t>(nn), size);
    for (std::int64_t e = 0; e < ne; ++e)
      for (int a = 0; a < npe; ++a) {
        int &o =
            owner[static_cast<std::size_t>(m.connectivity[static_cast<std::size_t>(e * npe + a)])];
        o = std::min(o, part[static_cast<std::size_t>(e)]);
      }
    // New global numbering: by owner rank, then by original index.
    owned_count.assign(static_cast<std::size_t>(size), 0);
    start.assign(static_cast<std::size_t>(size), 0);
    for (int o : owner) ++owned_count[static_cast<std::size_t>(o)];
    for (int p = 1; p < size; ++p)
      start[static_cast<std::size_t>(p)] =
          start[static_cast<std::size_t>(p - 1)] + owned_count[static_cast<std::size_t>(p - 1)];
    new_number.resize(static_cast<std::size_t>(nn));
    {
      std::vector<PetscInt> next = start;
      for (std::int64_t i = 0; i < nn; ++i)
        new_number[static_cast<std::size_t>(i)] =
            next[static_cast<std::size_t>(owner[static_cast<std::size_t>(i)])]++;
    }
    old_of_new.resize(static_cast<std::size_t>(nn));
    for (std::int64_t i = 0; i < nn; ++i)
      old_of_new[static_cast<std::size_t>(new_number[static_cast<std::size_t>(i)])] = i;
  }
};

/// Part p's elements (tags, connectivity in the local numbering: owned nodes, then the ghosts
/// in ascending global order), ghosts, node coordinates and owned range (docs/theory.md
/// section 2, "Local numbering").
void fill_element_part(const MeshData &m, const NodeNumbering &nodes,
                       const std::vector<std::int64_t> &elements, int p, MeshParts &parts) {
  const int npe = nodes_per_element(m.type);
  const PetscInt s = nodes.start[static_cast<std::size_t>(p)],
                 n_own = nodes.owned_count[static_cast<std::size_t>(p)];
  auto &conn = parts.conn[static_cast<std::size_t>(p)];
  auto &ghosts = parts.ghosts[static_cast<std::size_t>(p)];
  for (std::int64_t e : elements) {
    parts.tags[static_cast<std::size_t>(p)].push_back(m.element_tags[static_cast<std::size_t>(e)]);
    for (int a = 0; a < npe; ++a) {
      const PetscInt g = nodes.new_number[static_cast<std::size_t>(
          m.connectivity[static_cast<std::size_t>(e * npe + a)])];
      conn.push_back(g);
      if (g < s || g >= s + n_own) ghosts.push_back(g);
    }
  }
  std::sort(ghosts.begin(), ghosts.end());
  ghosts.erase(std::unique(ghosts.begin(), ghosts.end()), ghosts.end());
  // Global -> local node index for this part.
  for (PetscInt &g : conn) {
    if (g >= s && g < s + n_own)
      g -= s;
    else
      g = n_own +
          static_cast<PetscInt>(std::lower_bound(ghosts.begin(), ghosts.end(), g) - ghosts.begin());
  }
  auto &xyz = parts.coords[static_cast<std::size_t>(p)];
  xyz.reserve(static_cast<std::size_t>(3 * (n_own + static_cast<PetscInt>(ghosts.size()))));
  auto push_node = [&](PetscInt g) {
    const std::int64_t old = nodes.old_of_new[static_cast<std::size_t>(g)];
    for (int k = 0; k < 3; ++k) xyz.push_back(m.coordinates[static_cast<std::size_t>(3 * old + k)]);
  };
  for (PetscInt g = s; g < s + n_own; ++g) push_node(g);
  for (PetscInt g : ghosts) push_node(g);
  parts.meta[static_cast<std::size_t>(p)] = {n_own, s};
}

/// Every surface group's faces, by the rank owning their first node (with their global node
/// numbers and coordinates), and its nodes, by owner (docs/theory.md section 2, "Surface
/// faces").
void fill_surface_parts(const MeshData &m, const NodeNumbering &nodes, MeshParts &parts) {
  std::size_t si = 0;
  for (const auto &kv : m.surface_groups) {
    const SurfaceGroup &g = kv.second;
    const int npf = nodes_per_face(g.type);
    std::vector<PetscInt> nodes_on;
    for (std::size_t f = 0; f < g.size(); ++f) {
      const PetscInt first = nodes.new_number[static_cast<std::size_t>(
          g.connectivity[f * static_cast<std::size_t>(npf)])];
      const int p =
          nodes.owner[static_cast<std::size_t>(nodes.old_of_new[static_cast<std::size_t>(first)])];
      for (int a = 0; a < npf; ++a) {
        const std::int64_t old =
            g.connectivity[f * static_cast<std::size_t>(npf) + static_cast<std::size_t>(a)];
        parts.sfaces[si][static_cast<std::size_t>(p)].push_back(
            nodes.new_number[static_cast<std::size_t>(old)]);
        nodes_on.push_back(nodes.new_number[static_cast<std::size_t>(old)]);
        for (int k = 0; k < 3; ++k)
          parts.scoords[si][static_cast<std::size_t>(p)].push_back(
              m.coordinates[static_cast<std::size_t>(3 * old + k)]);
      }
    }
    std::sort(nodes_on.begin(), nodes_on.end());
    nodes_on.erase(std::unique(nodes_on.begin(), nodes_on.end()), nodes_on.end());
    for (PetscInt gnode : nodes_on)
      parts
          .snodes[si][static_cast<std::size_t>(nodes.owner[static_cast<std::size_t>(
              nodes.old_of_new[static_cast<std::size_t>(gnode)])])]
          .push_back(gnode);
    ++si;
  }
}

/// The root's side (docs/theory.md section 2): partition, ownership and numbering, then every
/// rank's elements, nodes, volume groups and surface groups.
void partition_on_root(const MeshData &m, int size, MeshParts &parts) {
  const std::int64_t ne = m.element_count();
  const std::vector<int> part = partition_elements(m, size);
  const NodeNumbering nodes(m, part, size);
  // Elements per part, in original order; their local element index for volume groups.
  std::vector<PetscInt> local_index(static_cast<std::size_t>(ne));
  std::vector<std::vector<std::int64_t>> elements_of(static_cast<std::size_t>(size));
  for (std::int64_t e = 0; e < ne; ++e) {
    auto &list = elements_of[static_cast<std::size_t>(part[static_cast<std::size_t>(e)])];
    local_index[static_cast<std::size_t>(e)] = static_cast<PetscInt>(list.size());
    list.push_back(e);
  }
  for (int p = 0; p < size; ++p)
    fill_element_part(m, nodes, elements_of[static_cast<std::size_t>(p)], p, parts);
  std::size_t gi = 0;
  for (const auto &kv : m.volume_groups) {
    for (std::int64_t e : kv.second)
      parts.vgroups[gi][static_cast<std::size_t>(part[static_cast<std::size_t>(e)])].push_back(
          local_index[static_cast<std::size_t>(e)]);
    ++gi;
  }
  fill_surface_parts(m, nodes, parts);
}

/// Every rank's part from the root into dm, and the element counts and offsets. Collective.
void receive_parts(MPI_Comm comm, const MeshHeader &header, const MeshParts &parts,
                   DistributedMesh &dm) {
  const auto meta = scatter_parts(comm, parts.meta);
  dm.owned_nodes = meta[0];
  dm.node_start = meta[1];
  dm.connectivity = scatter_parts(comm, parts.conn);
  dm.ghosts = scatter_parts(comm, parts.ghosts);
  dm.coordinates = scatter_parts(comm, parts.coords);
  dm.element_tags = scatter_parts(comm, parts.tags);
  for (std::size_t g = 0; g < header.vnames.size(); ++g)
    dm.volume_groups[header.vnames[g]] = scatter_parts(comm, parts.vgroups[g]);
  for (std::size_t g = 0; g < header.snames.size(); ++g) {
    LocalSurface &s = dm.surfaces[header.snames[g]];
    s.type = static_cast<FaceType>(header.face_types[g]);
    s.global_nodes = scatter_parts(comm, parts.sfaces[g]);
    s.coordinates = scatter_parts(comm, parts.scoords[g]);
    dm.surface_nodes[header.snames[g]] = scatter_parts(comm, parts.snodes[g]);
  }
  PetscInt n_local = dm.local_elements();
  MPI_Allreduce(&n_local, &dm.global_elements, 1, MPIU_INT, MPI_SUM, comm);
  MPI_Exscan(&n_local, &dm.element_start, 1, MPIU_INT, MPI_SUM, comm);
  if (comm_rank(comm) == 0) dm.element_start = 0;
}

} // namespace

DistributedMesh distribute_mesh(MPI_Comm comm, const MeshData *root_mesh) {
  const int size = comm_size(comm);
  DistributedMesh dm;
  dm.comm = comm;
  const MeshHeader header(comm, root_mesh, dm);
  MeshParts parts(size, header.vnames.size(), header.snames.size());
  run_on_root(comm, 0, [&] { partition_on_root(*root_mesh, size, parts); });
  receive_parts(comm, header, parts, dm);
  return dm;
}

double mesh_extent(const DistributedMesh &mesh) {
  double lo[3] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
                  std::numeric_limits<double>::max()},
         hi[3] = {-lo[0], -lo[1], -lo[2]};
  for (std::size_t k = 0; k < mesh.coordinates.size(); ++k)
    lo[k % 3] = std::min(lo[k % 3], mesh.coordinates[k]),
           hi[k % 3] = std::max(hi[k % 3], mesh.coordinates[k]);
  MPI_Allreduce(MPI_IN_PLACE, lo, 3, MPI_DOUBLE, MPI_MIN, mesh.comm);
  MPI_Allreduce(MPI_IN_PLACE, hi, 3, MPI_DOUBLE, MPI_MAX, mesh.comm);
  return std::hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
}

} // namespace flexopt::mesh
