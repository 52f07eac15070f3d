#include "flexopt/optimize/cone_filter.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/core/memory.hpp"
#include "flexopt/fem/element.hpp"
#include "flexopt/optimize/helmholtz_filter.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <unordered_map>

namespace flexopt::optimize {

namespace {

/// An element as the neighbour search sees it: global index, centroid, volume.
struct Point {
  double gid, x, y, z, volume;
};
static_assert(sizeof(Point) == 5 * sizeof(double), "Point is sent as 5 doubles");

/// Centroid (the image of the reference centroid) and volume of every local element.
std::vector<Point> local_points(const mesh::DistributedMesh &mesh) {
  const PetscInt ne = mesh.local_elements();
  const int npe = mesh.nodes_per_element();
  const Eigen::Vector3d xi = fem::reference_centroid(mesh.type);
  std::vector<double> N(static_cast<std::size_t>(npe)), dN(static_cast<std::size_t>(3 * npe));
  fem::shape_functions(mesh.type, xi, N.data(), dN.data());
  std::vector<Point> pts(static_cast<std::size_t>(ne));
  for (PetscInt e = 0; e < ne; ++e) {
    const fem::ElementCoords X = mesh.element_coordinates(e);
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int a = 0; a < npe; ++a) c += N[static_cast<std::size_t>(a)] * X.row(a).transpose();
    const double v = fem::element_volume(mesh.type, X);
    if (!(v > 0))
      abort_local("cone filter: element " +
                  std::to_string(mesh.element_tags[static_cast<std::size_t>(e)]) +
                  " has a non-positive volume");
    pts[static_cast<std::size_t>(e)] = {static_cast<double>(mesh.element_start + e), c.x(), c.y(),
                                        c.z(), v};
  }
  return pts;
}

/// Refuses, before any weight is computed, a cone filter whose weights would take more than
/// 80 % of a node's available memory: per element about (4/3) pi R^3 / V neighbours (V this
/// rank's mean element volume), each pair stored once (W's upper triangle). Collective.
void check_cone_memory(const mesh::DistributedMesh &mesh, const std::vector<Point> &mine,
                       double radius) {
  double volume = 0;
  for (const Point &p : mine) volume += p.volume;
  const double mean = mine.empty() ? 1.0 : volume / static_cast<double>(mine.size());
  const double per_element = std::min(4.0 / 3.0 * M_PI * radius * radius * radius / mean,
                                      static_cast<double>(mesh.global_elements));
  // W's upper triangle: half the pairs, a column index and a value each (docs/theory.md
  // section 4.2); the rows are built one at a time.
  const double entry = sizeof(PetscInt) + sizeof(double);
  const auto bytes =
      static_cast<long long>(static_cast<double>(mine.size()) * 0.5 * (per_element + 1) * entry);
  const NodeMemory need = node_memory(mesh.comm, bytes);
  if (need.fits(0.8)) return;
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "design.filter: the cone filter of radius %g m would hold about %.0f weights per "
                "element, %.3g GB on a node, above 80 %% of the %.3g GB available there: use "
                "type: helmholtz (its cost does not grow with the radius) or a smaller radius",
                radius, per_element, static_cast<double>(need.bytes) / 1e9,
                static_cast<double>(need.available) / 1e9);
  throw Error(buf, true);
}

/// The elements of other ranks whose centroids lie within `radius` of this rank's bounding
/// box of centroids (exchanged with MPI_Alltoallv; each rank sends only what others need).
std::vector<Point> remote_points(MPI_Comm comm, const std::vector<Point> &mine, double radius) {
  int size = 1, rank = 0;
  MPI_Comm_size(comm, &size);
  MPI_Comm_rank(comm, &rank);
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<double, 6> box{inf, inf, inf, -inf, -inf, -inf};
  for (const Point &p : mine) {
    const double c[3] = {p.x, p.y, p.z};
    for (int k = 0; k < 3; ++k) {
      box[static_cast<std::size_t>(k)] = std::min(box[static_cast<std::size_t>(k)], c[k]);
      box[static_cast<std::size_t>(k + 3)] = std::max(box[static_cast<std::size_t>(k + 3)], c[k]);
    }
  }
  std::vector<double> boxes(static_cast<std::size_t>(6 * size));
  MPI_Allgather(box.data(), 6, MPI_DOUBLE, boxes.data(), 6, MPI_DOUBLE, comm);

  std::vector<std::vector<Point>> out(static_cast<std::size_t>(size));
  for (int r = 0; r < size; ++r) {
    if (r == rank) continue;
    const double *b = &boxes[static_cast<std::size_t>(6 * r)];
    for (const Point &p : mine)
      if (p.x >= b[0] - radius && p.x <= b[3] + radius && p.y >= b[1] - radius &&
          p.y <= b[4] + radius && p.z >= b[2] - radius && p.z <= b[5] + radius)
        out[static_cast<std::size_t>(r)].push_back(p);
  }
  std::vector<int> send_counts(static_cast<std::size_t>(size)), send_displs(send_counts),
      recv_counts(send_counts), recv_displs(send_counts);
  std::vector<double> send;
  for (int r = 0; r < size; ++r) {
    send_displs[static_cast<std::size_t>(r)] = static_cast<int>(send.size());
    for (const Point &p : out[static_cast<std::size_t>(r)])
      send.insert(send.end(), {p.gid, p.x, p.y, p.z, p.volume});
    send_counts[static_cast<std::size_t>(r)] =
        static_cast<int>(send.size()) - send_displs[static_cast<std::size_t>(r)];
  }
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, comm);
  int total = 0;
  for (int r = 0; r < size; ++r) {
    recv_displs[static_cast<std::size_t>(r)] = total;
    total += recv_counts[static_cast<std::size_t>(r)];
  }
  std::vector<double> recv(static_cast<std::size_t>(total));
  MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), MPI_DOUBLE, recv.data(),
                recv_counts.data(), recv_displs.data(), MPI_DOUBLE, comm);
  std::vector<Point> pts(static_cast<std::size_t>(total / 5));
  for (std::size_t i = 0; i < pts.size(); ++i)
    pts[i] = {recv[5 * i], recv[5 * i + 1], recv[5 * i + 2], recv[5 * i + 3], recv[5 * i + 4]};
  return pts;
}

/// One neighbour of an element: its global number and its weight w = R - distance.
struct Neighbour {
  PetscInt column;
  double weight, volume;
  bool operator<(const Neighbour &o) const { return column < o.column; }
};

/// The cone filter's neighbour search: every candidate (own and received elements) binned in
/// cubes of edge R; the neighbours of an element lie in the 27 cubes around its own.
class NeighbourSearch {
public:
  NeighbourSearch(std::vector<Point> candidates, double radius)
      : all_(std::move(candidates)), radius_(radius) {
    for (std::size_t i = 0; i < all_.size(); ++i) {
      const long long ci = cell(all_[i].x), cj = cell(all_[i].y), ck = cell(all_[i].z);
      if (std::max({std::llabs(ci), std::llabs(cj), std::llabs(ck)}) >= (1LL << 20) - 1)
        abort_local("cone filter: the radius is too small for the extent of the mesh (more than "
                    "2^20 radii from the origin)");
      bins_[key(ci, cj, ck)].push_back(i);
    }
  }

  /// The neighbours of p (|c_p - c_q| < R, p itself included) sorted by global number, and
  /// d_p = sum of w V in that order: a fixed order makes d_p independent of the partition.
  double row(const Point &p, std::vector<Neighbour> &out) const {
    out.clear();
    const long long ci = cell(p.x), cj = cell(p.y), ck = cell(p.z);
    for (long long di = -1; di <= 1; ++di)
      for (long long dj = -1; dj <= 1; ++dj)
        for (long long dk = -1; dk <= 1; ++dk) {
          const auto it = bins_.find(key(ci + di, cj + dj, ck + dk));
          if (it == bins_.end()) continue;
          for (std::size_t i : it->second) {
            const Point &q = all_[i];
            const double d = std::sqrt((p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) +
                                       (p.z - q.z) * (p.z - q.z));
            if (d < radius_) out.push_back({static_cast<PetscInt>(q.gid), radius_ - d, q.volume});
          }
        }
    std::sort(out.begin(), out.end());
    double sum = 0;
    for (const Neighbour &n : out) sum += n.weight * n.volume;
    return sum;
  }

private:
  long long cell(double v) const { return static_cast<long long>(std::floor(v / radius_)); }
  static long long key(long long i, long long j, long long k) {
    // 21 bits per direction (offset so that negative indices fit): unique for |index| < 2^20.
    return ((i + (1LL << 20)) << 42) | ((j + (1LL << 20)) << 21) | (k + (1LL << 20));
  }
  std::vector<Point> all_;
  double radius_;
  std::unordered_map<long long, std::vector<std::size_t>> bins_;
};

/// An element vector of `mesh`'s element layout holding `values` (its owned entries).
Vec element_vector(const mesh::DistributedMesh &mesh, const std::vector<double> &values) {
  Vec v;
  FX_PETSC(VecCreateMPI(mesh.comm, mesh.local_elements(), PETSC_DETERMINE, &v));
  PetscScalar *a;
  FX_PETSC(VecGetArrayWrite(v, &a));
  std::copy(values.begin(), values.end(), a);
  FX_PETSC(VecRestoreArrayWrite(v, &a));
  return v;
}

} // namespace

std::unique_ptr<ConeFilter> ConeFilter::create(const mesh::DistributedMesh &mesh, double radius) {
  if (!(radius > 0)) throw Error("cone filter: the radius must be positive", true);
  LogScope log("FxFilterSetUp");
  std::unique_ptr<ConeFilter> f(new ConeFilter());
  f->radius_ = radius;
  const PetscInt ne = mesh.local_elements();
  const std::vector<Point> mine = local_points(mesh);
  check_cone_memory(mesh, mine, radius);
  std::vector<Point> all = mine;
  const std::vector<Point> remote = remote_points(mesh.comm, mine, radius);
  all.insert(all.end(), remote.begin(), remote.end());
  const NeighbourSearch search(std::move(all), radius);

  // H = D^-1 W V (docs/theory.md section 4.2). First pass: the row sums d_e and the exact
  // preallocation of W's upper triangle (columns >= the row), diagonal and off-diagonal blocks.
  const PetscInt first = mesh.element_start, last = mesh.element_start + ne;
  std::vector<PetscInt> d_nnz(static_cast<std::size_t>(ne), 0), o_nnz(d_nnz);
  std::vector<double> dinv(static_cast<std::size_t>(ne)), volume(dinv);
  std::vector<Neighbour> row;
  PetscInt max_row = 0;
  for (PetscInt e = 0; e < ne; ++e) {
    const auto ee = static_cast<std::size_t>(e);
    dinv[ee] = 1.0 / search.row(mine[ee], row);
    volume[ee] = mine[ee].volume;
    for (const Neighbour &n : row)
      if (n.column >= first + e) (n.column < last ? d_nnz : o_nnz)[ee]++;
    max_row = std::max(max_row, static_cast<PetscInt>(row.size()));
  }
  MPI_Allreduce(&max_row, &f->max_neighbours_, 1, MPIU_INT, MPI_MAX, mesh.comm);
  f->dinv_ = element_vector(mesh, dinv);
  f->volume_ = element_vector(mesh, volume);
  FX_PETSC(VecDuplicate(f->volume_, &f->work_));

  // Second pass: each row again, its upper part inserted (W's entries, in column order).
  FX_PETSC(MatCreateSBAIJ(mesh.comm, 1, ne, ne, PETSC_DETERMINE, PETSC_DETERMINE, 0, d_nnz.data(),
                          0, o_nnz.data(), &f->W_));
  std::vector<PetscInt> cols;
  std::vector<PetscScalar> vals;
  for (PetscInt e = 0; e < ne; ++e) {
    search.row(mine[static_cast<std::size_t>(e)], row);
    cols.clear();
    vals.clear();
    for (const Neighbour &n : row)
      if (n.column >= first + e) {
        cols.push_back(n.column);
        vals.push_back(n.weight);
      }
    const PetscInt grow = first + e;
    FX_PETSC(MatSetValues(f->W_, 1, &grow, static_cast<PetscInt>(cols.size()), cols.data(),
                          vals.data(), INSERT_VALUES));
  }
  FX_PETSC(MatAssemblyBegin(f->W_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(f->W_, MAT_FINAL_ASSEMBLY));
  return f;
}

ConeFilter::~ConeFilter() {
  MatDestroy(&W_);
  VecDestroy(&dinv_);
  VecDestroy(&volume_);
  VecDestroy(&work_);
}

Vec ConeFilter::create_element_vector() const {
  Vec v;
  FX_PETSC(VecDuplicate(volume_, &v));
  return v;
}

void ConeFilter::apply(Vec rho, Vec rho_filtered) const {
  LogScope log("FxFilterSolve");
  // D^-1 (W (V rho)).
  FX_PETSC(VecPointwiseMult(work_, volume_, rho));
  FX_PETSC(MatMult(W_, work_, rho_filtered));
  FX_PETSC(VecPointwiseMult(rho_filtered, dinv_, rho_filtered));
}

void ConeFilter::apply_transpose(Vec g_filtered, Vec g) const {
  LogScope log("FxFilterSolve");
  // V (W (D^-1 g)).
  FX_PETSC(VecPointwiseMult(work_, dinv_, g_filtered));
  FX_PETSC(MatMult(W_, work_, g));
  FX_PETSC(VecPointwiseMult(g, volume_, g));
}

std::string ConeFilter::describe() const {
  std::ostringstream s;
  s << "cone filter R = " << radius_ << " (up to " << max_neighbours_ << " neighbours)";
  return s.str();
}

std::unique_ptr<DensityFilter> create_density_filter(const mesh::DistributedMesh &mesh,
                                                     FilterType type, double radius) {
  if (type == FilterType::Cone) return ConeFilter::create(mesh, radius);
  return HelmholtzFilter::create(mesh, radius);
}

} // namespace flexopt::optimize
