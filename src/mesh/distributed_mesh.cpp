#include "flexopt/mesh/distributed_mesh.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <cstring>
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

void broadcast_string(MPI_Comm comm, std::string &s) {
  int len = static_cast<int>(s.size());
  MPI_Bcast(&len, 1, MPI_INT, 0, comm);
  s.resize(static_cast<std::size_t>(len));
  MPI_Bcast(s.data(), len, MPI_CHAR, 0, comm);
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

} // namespace

DistributedMesh distribute_mesh(MPI_Comm comm, const MeshData *root_mesh) {
  const int rank = comm_rank(comm), size = comm_size(comm);
  DistributedMesh dm;
  dm.comm = comm;

  // Everything every rank needs to know first: type, sizes, group names.
  int type = 0;
  long long n_nodes = 0;
  std::string volume_names, surface_names;
  std::vector<int> face_types;
  if (rank == 0) {
    dm.source = root_mesh->source;
    type = static_cast<int>(root_mesh->type);
    n_nodes = root_mesh->node_count();
    for (const auto &kv : root_mesh->volume_groups) volume_names += kv.first + '\n';
    for (const auto &kv : root_mesh->surface_groups) {
      surface_names += kv.first + '\n';
      face_types.push_back(static_cast<int>(kv.second.type));
    }
  }
  broadcast_string(comm, dm.source);
  broadcast_string(comm, volume_names);
  broadcast_string(comm, surface_names);
  MPI_Bcast(&type, 1, MPI_INT, 0, comm);
  MPI_Bcast(&n_nodes, 1, MPI_LONG_LONG, 0, comm);
  dm.type = static_cast<ElementType>(type);
  dm.global_nodes = static_cast<PetscInt>(n_nodes);
  auto split = [](const std::string &s) {
    std::vector<std::string> out;
    std::size_t a = 0;
    for (std::size_t b; (b = s.find('\n', a)) != std::string::npos; a = b + 1)
      out.push_back(s.substr(a, b - a));
    return out;
  };
  const auto vnames = split(volume_names), snames = split(surface_names);
  int n_faces_types = static_cast<int>(snames.size());
  face_types.resize(snames.size());
  MPI_Bcast(face_types.data(), n_faces_types, MPI_INT, 0, comm);

  const int npe = dm.nodes_per_element();
  std::vector<std::vector<PetscInt>> conn_parts(static_cast<std::size_t>(size)),
      ghost_parts(static_cast<std::size_t>(size));
  std::vector<std::vector<double>> coord_parts(static_cast<std::size_t>(size));
  std::vector<std::vector<std::size_t>> tag_parts(static_cast<std::size_t>(size));
  std::vector<std::vector<PetscInt>> meta_parts(
      static_cast<std::size_t>(size)); // owned count, start
  std::vector<std::vector<std::vector<PetscInt>>> vgroup_parts(
      vnames.size(), std::vector<std::vector<PetscInt>>(static_cast<std::size_t>(size)));
  std::vector<std::vector<std::vector<PetscInt>>> sface_parts(
      snames.size(), std::vector<std::vector<PetscInt>>(static_cast<std::size_t>(size)));
  std::vector<std::vector<std::vector<double>>> scoord_parts(
      snames.size(), std::vector<std::vector<double>>(static_cast<std::size_t>(size)));
  std::vector<std::vector<std::vector<PetscInt>>> snode_parts(
      snames.size(), std::vector<std::vector<PetscInt>>(static_cast<std::size_t>(size)));

  run_on_root(comm, 0, [&] {
    const MeshData &m = *root_mesh;
    const std::int64_t ne = m.element_count(), nn = m.node_count();
    const std::vector<int> part = partition_elements(m, size);

    // Owner of a node: the lowest part among the elements touching it.
    std::vector<int> owner(static_cast<std::size_t>(nn), size);
    for (std::int64_t e = 0; e < ne; ++e)
      for (int a = 0; a < npe; ++a) {
        int &o =
            owner[static_cast<std::size_t>(m.connectivity[static_cast<std::size_t>(e * npe + a)])];
        o = std::min(o, part[static_cast<std::size_t>(e)]);
      }
    // New global numbering: by owner rank, then by original index.
    std::vector<PetscInt> owned_count(static_cast<std::size_t>(size), 0),
        start(static_cast<std::size_t>(size), 0);
    for (int o : owner) ++owned_count[static_cast<std::size_t>(o)];
    for (int p = 1; p < size; ++p)
      start[static_cast<std::size_t>(p)] =
          start[static_cast<std::size_t>(p - 1)] + owned_count[static_cast<std::size_t>(p - 1)];
    std::vector<PetscInt> new_number(static_cast<std::size_t>(nn));
    {
      std::vector<PetscInt> next = start;
      for (std::int64_t i = 0; i < nn; ++i)
        new_number[static_cast<std::size_t>(i)] =
            next[static_cast<std::size_t>(owner[static_cast<std::size_t>(i)])]++;
    }
    // Elements per part, in original order; their local element index for volume groups.
    std::vector<PetscInt> local_index(static_cast<std::size_t>(ne));
    std::vector<std::vector<std::int64_t>> elements_of(static_cast<std::size_t>(size));
    for (std::int64_t e = 0; e < ne; ++e) {
      auto &list = elements_of[static_cast<std::size_t>(part[static_cast<std::size_t>(e)])];
      local_index[static_cast<std::size_t>(e)] = static_cast<PetscInt>(list.size());
      list.push_back(e);
    }
    std::vector<std::int64_t> old_of_new(static_cast<std::size_t>(nn));
    for (std::int64_t i = 0; i < nn; ++i)
      old_of_new[static_cast<std::size_t>(new_number[static_cast<std::size_t>(i)])] = i;

    for (int p = 0; p < size; ++p) {
      const PetscInt s = start[static_cast<std::size_t>(p)],
                     n_own = owned_count[static_cast<std::size_t>(p)];
      auto &conn = conn_parts[static_cast<std::size_t>(p)];
      auto &ghosts = ghost_parts[static_cast<std::size_t>(p)];
      for (std::int64_t e : elements_of[static_cast<std::size_t>(p)]) {
        tag_parts[static_cast<std::size_t>(p)].push_back(
            m.element_tags[static_cast<std::size_t>(e)]);
        for (int a = 0; a < npe; ++a) {
          const PetscInt g = new_number[static_cast<std::size_t>(
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
          g = n_own + static_cast<PetscInt>(std::lower_bound(ghosts.begin(), ghosts.end(), g) -
                                            ghosts.begin());
      }
      auto &xyz = coord_parts[static_cast<std::size_t>(p)];
      xyz.reserve(static_cast<std::size_t>(3 * (n_own + static_cast<PetscInt>(ghosts.size()))));
      auto push_node = [&](PetscInt g) {
        const std::int64_t old = old_of_new[static_cast<std::size_t>(g)];
        for (int k = 0; k < 3; ++k)
          xyz.push_back(m.coordinates[static_cast<std::size_t>(3 * old + k)]);
      };
      for (PetscInt g = s; g < s + n_own; ++g) push_node(g);
      for (PetscInt g : ghosts) push_node(g);
      meta_parts[static_cast<std::size_t>(p)] = {n_own, s};
    }
    std::size_t gi = 0;
    for (const auto &kv : m.volume_groups) {
      for (std::int64_t e : kv.second)
        vgroup_parts[gi][static_cast<std::size_t>(part[static_cast<std::size_t>(e)])].push_back(
            local_index[static_cast<std::size_t>(e)]);
      ++gi;
    }
    std::size_t si = 0;
    for (const auto &kv : m.surface_groups) {
      const SurfaceGroup &g = kv.second;
      const int npf = nodes_per_face(g.type);
      std::vector<PetscInt> nodes_on;
      for (std::size_t f = 0; f < g.size(); ++f) {
        const PetscInt first =
            new_number[static_cast<std::size_t>(g.connectivity[f * static_cast<std::size_t>(npf)])];
        const int p = owner[static_cast<std::size_t>(old_of_new[static_cast<std::size_t>(first)])];
        for (int a = 0; a < npf; ++a) {
          const std::int64_t old =
              g.connectivity[f * static_cast<std::size_t>(npf) + static_cast<std::size_t>(a)];
          sface_parts[si][static_cast<std::size_t>(p)].push_back(
              new_number[static_cast<std::size_t>(old)]);
          nodes_on.push_back(new_number[static_cast<std::size_t>(old)]);
          for (int k = 0; k < 3; ++k)
            scoord_parts[si][static_cast<std::size_t>(p)].push_back(
                m.coordinates[static_cast<std::size_t>(3 * old + k)]);
        }
      }
      std::sort(nodes_on.begin(), nodes_on.end());
      nodes_on.erase(std::unique(nodes_on.begin(), nodes_on.end()), nodes_on.end());
      for (PetscInt gnode : nodes_on)
        snode_parts[si][static_cast<std::size_t>(owner[static_cast<std::size_t>(
                            old_of_new[static_cast<std::size_t>(gnode)])])]
            .push_back(gnode);
      ++si;
    }
  });

  const auto meta = scatter_parts(comm, meta_parts);
  dm.owned_nodes = meta[0];
  dm.node_start = meta[1];
  dm.connectivity = scatter_parts(comm, conn_parts);
  dm.ghosts = scatter_parts(comm, ghost_parts);
  dm.coordinates = scatter_parts(comm, coord_parts);
  dm.element_tags = scatter_parts(comm, tag_parts);
  for (std::size_t g = 0; g < vnames.size(); ++g)
    dm.volume_groups[vnames[g]] = scatter_parts(comm, vgroup_parts[g]);
  for (std::size_t g = 0; g < snames.size(); ++g) {
    LocalSurface &s = dm.surfaces[snames[g]];
    s.type = static_cast<FaceType>(face_types[g]);
    s.global_nodes = scatter_parts(comm, sface_parts[g]);
    s.coordinates = scatter_parts(comm, scoord_parts[g]);
    dm.surface_nodes[snames[g]] = scatter_parts(comm, snode_parts[g]);
  }
  PetscInt n_local = dm.local_elements();
  MPI_Allreduce(&n_local, &dm.global_elements, 1, MPIU_INT, MPI_SUM, comm);
  MPI_Exscan(&n_local, &dm.element_start, 1, MPIU_INT, MPI_SUM, comm);
  if (rank == 0) dm.element_start = 0;
  return dm;
}

} // namespace flexopt::mesh
