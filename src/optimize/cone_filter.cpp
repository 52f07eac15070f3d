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
/// rank's mean element volume), each held as a (column, weight) pair while the rows are built
/// and again in the AIJ matrix. Collective.
void check_cone_memory(const mesh::DistributedMesh &mesh, const std::vector<Point> &mine,
                       double radius) {
  double volume = 0;
  for (const Point &p : mine) volume += p.volume;
  const double mean = mine.empty() ? 1.0 : volume / static_cast<double>(mine.size());
  const double per_element = std::min(4.0 / 3.0 * M_PI * radius * radius * radius / mean,
                                      static_cast<double>(mesh.global_elements));
  const double pair = sizeof(PetscInt) + sizeof(double);
  const auto bytes = static_cast<long long>(static_cast<double>(mine.size()) * per_element *
                                            (pair + sizeof(std::pair<PetscInt, double>)));
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

  // Bin every candidate into cubes of edge R: the neighbours of an element lie in the 27 cubes
  // around its own.
  auto cell = [radius](double v) { return static_cast<long long>(std::floor(v / radius)); };
  auto key = [](long long i, long long j, long long k) {
    // 21 bits per direction (offset so that negative indices fit): unique for |index| < 2^20.
    return ((i + (1LL << 20)) << 42) | ((j + (1LL << 20)) << 21) | (k + (1LL << 20));
  };
  std::unordered_map<long long, std::vector<std::size_t>> bins;
  for (std::size_t i = 0; i < all.size(); ++i) {
    const long long ci = cell(all[i].x), cj = cell(all[i].y), ck = cell(all[i].z);
    if (std::max({std::llabs(ci), std::llabs(cj), std::llabs(ck)}) >= (1LL << 20) - 1)
      abort_local("cone filter: the radius is too small for the extent of the mesh (more than "
                  "2^20 radii from the origin)");
    bins[key(ci, cj, ck)].push_back(i);
  }

  // Rows of H: columns (global element numbers) and weights, normalised to unit row sums.
  std::vector<std::vector<std::pair<PetscInt, double>>> rows(static_cast<std::size_t>(ne));
  std::vector<PetscInt> d_nnz(static_cast<std::size_t>(ne), 0), o_nnz(d_nnz);
  const PetscInt first = mesh.element_start, last = mesh.element_start + ne;
  PetscInt max_row = 0;
  for (PetscInt e = 0; e < ne; ++e) {
    const Point &p = mine[static_cast<std::size_t>(e)];
    auto &row = rows[static_cast<std::size_t>(e)];
    const long long ci = cell(p.x), cj = cell(p.y), ck = cell(p.z);
    for (long long di = -1; di <= 1; ++di)
      for (long long dj = -1; dj <= 1; ++dj)
        for (long long dk = -1; dk <= 1; ++dk) {
          const auto it = bins.find(key(ci + di, cj + dj, ck + dk));
          if (it == bins.end()) continue;
          for (std::size_t i : it->second) {
            const Point &q = all[i];
            const double d = std::sqrt((p.x - q.x) * (p.x - q.x) + (p.y - q.y) * (p.y - q.y) +
                                       (p.z - q.z) * (p.z - q.z));
            if (d < radius) row.emplace_back(static_cast<PetscInt>(q.gid), (radius - d) * q.volume);
          }
        }
    // A fixed column order makes the row sum, and so H, independent of the partition.
    std::sort(row.begin(), row.end());
    double sum = 0;
    for (const auto &[col, w] : row) sum += w;
    for (auto &[col, w] : row) {
      w /= sum;
      (col >= first && col < last ? d_nnz : o_nnz)[static_cast<std::size_t>(e)]++;
    }
    max_row = std::max(max_row, static_cast<PetscInt>(row.size()));
  }
  MPI_Allreduce(&max_row, &f->max_neighbours_, 1, MPIU_INT, MPI_MAX, mesh.comm);

  FX_PETSC(MatCreateAIJ(mesh.comm, ne, ne, PETSC_DETERMINE, PETSC_DETERMINE, 0, d_nnz.data(), 0,
                        o_nnz.data(), &f->H_));
  for (PetscInt e = 0; e < ne; ++e) {
    const auto &row = rows[static_cast<std::size_t>(e)];
    std::vector<PetscInt> cols(row.size());
    std::vector<PetscScalar> vals(row.size());
    for (std::size_t k = 0; k < row.size(); ++k) cols[k] = row[k].first, vals[k] = row[k].second;
    const PetscInt grow = first + e;
    FX_PETSC(MatSetValues(f->H_, 1, &grow, static_cast<PetscInt>(cols.size()), cols.data(),
                          vals.data(), INSERT_VALUES));
  }
  FX_PETSC(MatAssemblyBegin(f->H_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(f->H_, MAT_FINAL_ASSEMBLY));
  return f;
}

ConeFilter::~ConeFilter() {
  MatDestroy(&H_);
}

Vec ConeFilter::create_element_vector() const {
  Vec v;
  FX_PETSC(MatCreateVecs(H_, &v, nullptr));
  return v;
}

void ConeFilter::apply(Vec rho, Vec rho_filtered) const {
  LogScope log("FxFilterSolve");
  FX_PETSC(MatMult(H_, rho, rho_filtered));
}

void ConeFilter::apply_transpose(Vec g_filtered, Vec g) const {
  LogScope log("FxFilterSolve");
  FX_PETSC(MatMultTranspose(H_, g_filtered, g));
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
