#include "flexopt/fem/lattice_multigrid.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace flexopt::fem {

namespace {

/// Sorted values merged where they differ by at most tol (the first of a run is kept).
void unique_within(std::vector<double> &v, double tol) {
  std::sort(v.begin(), v.end());
  std::size_t n = 0;
  for (std::size_t k = 0; k < v.size(); ++k)
    if (n == 0 || v[k] - v[n - 1] > tol) v[n++] = v[k];
  v.resize(n);
}

/// Index of x among the lattice lines `axis` (within tol), or -1.
PetscInt line_of(const std::vector<double> &axis, double x, double tol) {
  const auto it = std::lower_bound(axis.begin(), axis.end(), x - tol);
  if (it == axis.end() || std::abs(*it - x) > tol) return -1;
  return static_cast<PetscInt>(it - axis.begin());
}

} // namespace

std::optional<Lattice> find_lattice(const mesh::DistributedMesh &m) {
  const MPI_Comm comm = m.comm;
  int ok = m.type == mesh::ElementType::Hex8 ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_MIN, comm);
  if (!ok) return std::nullopt;

  // Tolerance: 1e-9 of the bounding box's largest side.
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (PetscInt i = 0; i < m.owned_nodes; ++i)
    for (int a = 0; a < 3; ++a) {
      const double x = m.coordinates[static_cast<std::size_t>(3 * i + a)];
      lo[a] = std::min(lo[a], x), hi[a] = std::max(hi[a], x);
    }
  MPI_Allreduce(MPI_IN_PLACE, lo, 3, MPI_DOUBLE, MPI_MIN, comm);
  MPI_Allreduce(MPI_IN_PLACE, hi, 3, MPI_DOUBLE, MPI_MAX, comm);
  const double tol = 1e-9 * std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});

  // The lattice lines: the distinct node coordinates per axis over all ranks.
  Lattice L;
  const int size = comm_size(comm);
  for (int a = 0; a < 3; ++a) {
    std::vector<double> v(static_cast<std::size_t>(m.owned_nodes));
    for (PetscInt i = 0; i < m.owned_nodes; ++i)
      v[static_cast<std::size_t>(i)] = m.coordinates[static_cast<std::size_t>(3 * i + a)];
    unique_within(v, tol);
    int n = static_cast<int>(v.size());
    std::vector<int> counts(static_cast<std::size_t>(size)), displs(static_cast<std::size_t>(size));
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
    for (int p = 1; p < size; ++p)
      displs[static_cast<std::size_t>(p)] =
          displs[static_cast<std::size_t>(p - 1)] + counts[static_cast<std::size_t>(p - 1)];
    std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
    MPI_Allgatherv(v.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                   comm);
    unique_within(all, tol);
    L.axis[static_cast<std::size_t>(a)] = std::move(all);
  }
  const PetscInt nx = L.points(0), ny = L.points(1), nz = L.points(2);
  if (nx < 2 || ny < 2 || nz < 2 || nx * ny * nz != m.global_nodes ||
      L.cells(0) * L.cells(1) * L.cells(2) != m.global_elements)
    return std::nullopt; // the same figures on every rank: a collective answer

  // Lattice point of every local node (owned and ghost).
  std::vector<PetscInt> point(static_cast<std::size_t>(m.local_nodes()));
  ok = 1;
  for (PetscInt i = 0; i < m.local_nodes() && ok; ++i) {
    PetscInt ijk[3];
    for (int a = 0; a < 3; ++a) {
      ijk[a] = line_of(L.axis[static_cast<std::size_t>(a)],
                       m.coordinates[static_cast<std::size_t>(3 * i + a)], tol);
      if (ijk[a] < 0) ok = 0;
    }
    point[static_cast<std::size_t>(i)] = ijk[0] + nx * (ijk[1] + ny * ijk[2]);
  }
  // Every element spans one cell: its 8 nodes are the 8 corners of (i0..i0+1) x (j0..) x (k0..).
  const int npe = m.nodes_per_element();
  for (PetscInt e = 0; e < m.local_elements() && ok; ++e) {
    PetscInt ijk[8][3], first[3] = {nx, ny, nz};
    for (int c = 0; c < npe; ++c) {
      PetscInt p =
          point[static_cast<std::size_t>(m.connectivity[static_cast<std::size_t>(e * npe + c)])];
      ijk[c][0] = p % nx, ijk[c][1] = (p / nx) % ny, ijk[c][2] = p / (nx * ny);
      for (int a = 0; a < 3; ++a) first[a] = std::min(first[a], ijk[c][a]);
    }
    unsigned corners = 0;
    for (int c = 0; c < npe; ++c) {
      unsigned bit = 0;
      for (int a = 0; a < 3; ++a) {
        const PetscInt d = ijk[c][a] - first[a];
        if (d > 1) ok = 0;
        bit |= static_cast<unsigned>(d == 1) << a;
      }
      corners |= 1u << bit;
    }
    if (corners != 0xFFu) ok = 0;
  }
  MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_MIN, comm);
  if (!ok) return std::nullopt;

  // The global node number of every lattice point; a point left at -1 means two nodes share
  // one (as many nodes as points, so then another is empty).
  L.node.assign(static_cast<std::size_t>(m.global_nodes), -1);
  for (PetscInt i = 0; i < m.owned_nodes; ++i)
    L.node[static_cast<std::size_t>(point[static_cast<std::size_t>(i)])] = m.node_start + i;
  MPI_Allreduce(MPI_IN_PLACE, L.node.data(), static_cast<int>(L.node.size()), MPIU_INT, MPI_MAX,
                comm);
  if (std::find(L.node.begin(), L.node.end(), PetscInt(-1)) != L.node.end()) return std::nullopt;
  return L;
}

std::vector<std::array<PetscInt, 3>> lattice_levels(const Lattice &L, int levels,
                                                    PetscInt coarse_dofs) {
  std::vector<std::array<PetscInt, 3>> out{{L.cells(0), L.cells(1), L.cells(2)}};
  for (;;) {
    const auto &c = out.back();
    const bool even = c[0] % 2 == 0 && c[1] % 2 == 0 && c[2] % 2 == 0;
    const PetscInt dofs = 3 * (c[0] + 1) * (c[1] + 1) * (c[2] + 1);
    if (!even) break;
    const int halvings = static_cast<int>(out.size()) - 1;
    if (levels > 0 ? halvings + 1 >= levels : halvings >= 2 && dofs <= coarse_dofs) break;
    out.push_back({c[0] / 2, c[1] / 2, c[2] / 2});
  }
  return out;
}

namespace {

/// Points of the level with lattice stride s (indices multiples of s), numbered in the order of
/// their fine global node numbers: contiguous per rank, as the fine mesh numbers its nodes.
struct LevelNumbering {
  std::vector<PetscInt> number; ///< per fine global node: its number on this level, or -1
  PetscInt owned = 0;           ///< points of this level owned by this rank
};

LevelNumbering number_level(const Lattice &L, PetscInt s, PetscInt node_start, PetscInt owned) {
  const PetscInt nx = L.points(0), ny = L.points(1), nz = L.points(2);
  std::vector<PetscInt> nodes;
  for (PetscInt k = 0; k < nz; k += s)
    for (PetscInt j = 0; j < ny; j += s)
      for (PetscInt i = 0; i < nx; i += s)
        nodes.push_back(L.node[static_cast<std::size_t>(i + nx * (j + ny * k))]);
  std::sort(nodes.begin(), nodes.end());
  LevelNumbering n;
  n.number.assign(L.node.size(), -1);
  for (std::size_t q = 0; q < nodes.size(); ++q) {
    n.number[static_cast<std::size_t>(nodes[q])] = static_cast<PetscInt>(q);
    if (nodes[q] >= node_start && nodes[q] < node_start + owned) ++n.owned;
  }
  return n;
}

/// The trilinear interpolation from the level of stride 2s to the level of stride s (rows: the
/// fine level's DOFs owned here, 3 per point; columns: the coarse level's).
Mat interpolation(MPI_Comm comm, const Lattice &L, PetscInt s, const LevelNumbering &fine,
                  const LevelNumbering &coarse, PetscInt node_start, PetscInt owned) {
  const PetscInt n[3] = {L.points(0), L.points(1), L.points(2)};
  Mat P;
  FX_PETSC(MatCreateAIJ(comm, 3 * fine.owned, 3 * coarse.owned, PETSC_DETERMINE, PETSC_DETERMINE, 8,
                        nullptr, 8, nullptr, &P));
  FX_PETSC(MatSetBlockSizes(P, 3, 3));
  // Owned fine points, visited in lattice order.
  for (PetscInt k = 0; k < n[2]; k += s)
    for (PetscInt j = 0; j < n[1]; j += s)
      for (PetscInt i = 0; i < n[0]; i += s) {
        const PetscInt g = L.node[static_cast<std::size_t>(i + n[0] * (j + n[1] * k))];
        if (g < node_start || g >= node_start + owned) continue;
        // Per axis: the coarse lines around the point and their weights.
        PetscInt parent[3][2];
        double weight[3][2];
        int count[3];
        const PetscInt idx[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          const PetscInt x = idx[a];
          if (x % (2 * s) == 0) {
            count[a] = 1, parent[a][0] = x, weight[a][0] = 1.0;
          } else {
            const auto &ax = L.axis[static_cast<std::size_t>(a)];
            const double x0 = ax[static_cast<std::size_t>(x - s)],
                         x1 = ax[static_cast<std::size_t>(x + s)],
                         xm = ax[static_cast<std::size_t>(x)];
            count[a] = 2, parent[a][0] = x - s, parent[a][1] = x + s;
            weight[a][0] = (x1 - xm) / (x1 - x0), weight[a][1] = (xm - x0) / (x1 - x0);
          }
        }
        PetscInt cols[8];
        double w[8];
        int nc = 0;
        for (int c = 0; c < count[2]; ++c)
          for (int b = 0; b < count[1]; ++b)
            for (int a = 0; a < count[0]; ++a) {
              const PetscInt q = parent[0][a] + n[0] * (parent[1][b] + n[1] * parent[2][c]);
              cols[nc] =
                  coarse.number[static_cast<std::size_t>(L.node[static_cast<std::size_t>(q)])];
              w[nc++] = weight[0][a] * weight[1][b] * weight[2][c];
            }
        const PetscInt row = fine.number[static_cast<std::size_t>(g)];
        for (int d = 0; d < 3; ++d) {
          const PetscInt r = 3 * row + d;
          PetscInt cd[8];
          for (int q = 0; q < nc; ++q) cd[q] = 3 * cols[q] + d;
          FX_PETSC(MatSetValues(P, 1, &r, nc, cd, w, INSERT_VALUES));
        }
      }
  FX_PETSC(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  return P;
}

} // namespace

std::string set_lattice_multigrid(PC pc, const mesh::DistributedMesh &m, const Lattice &L,
                                  const std::vector<std::array<PetscInt, 3>> &cells) {
  const int nl = static_cast<int>(cells.size());
  FX_PETSC(PCSetType(pc, PCMG));
  FX_PETSC(PCMGSetLevels(pc, nl, nullptr));
  FX_PETSC(PCMGSetType(pc, PC_MG_MULTIPLICATIVE));
  FX_PETSC(PCMGSetCycleType(pc, PC_MG_CYCLE_V));
  FX_PETSC(PCMGSetGalerkin(pc, PC_MG_GALERKIN_BOTH));
  LevelNumbering fine = number_level(L, 1, m.node_start, m.owned_nodes);
  for (int l = 1; l < nl; ++l) { // l: from the finest (stride 1) down
    const PetscInt s = PetscInt(1) << (l - 1);
    LevelNumbering coarse = number_level(L, 2 * s, m.node_start, m.owned_nodes);
    Mat P = interpolation(m.comm, L, s, fine, coarse, m.node_start, m.owned_nodes);
    FX_PETSC(PCMGSetInterpolation(pc, nl - l, P)); // PCMG: level 0 is the coarsest
    FX_PETSC(MatDestroy(&P));
    fine = std::move(coarse);
  }
  std::ostringstream d;
  d << "geometric multigrid on the " << cells[0][0] << " x " << cells[0][1] << " x " << cells[0][2]
    << " Hex8 lattice, " << nl << " levels (coarsest " << cells.back()[0] << " x "
    << cells.back()[1] << " x " << cells.back()[2] << " cells, "
    << 3 * (cells.back()[0] + 1) * (cells.back()[1] + 1) * (cells.back()[2] + 1) << " DOFs)";
  return d.str();
}

LatticeCoarseOperators::LatticeCoarseOperators(PC pc) : pc_(pc) {
  FX_PETSC(PCMGSetGalerkin(pc, PC_MG_GALERKIN_EXTERNAL));
  FX_PETSC(PCSetUseAmat(pc, PETSC_TRUE));
}

LatticeCoarseOperators::~LatticeCoarseOperators() {
  for (Mat &A : coarse_) MatDestroy(&A);
}

void LatticeCoarseOperators::update(Mat fine) {
  LogScope log("FxLatticeGalerkin");
  PetscInt nl = 0;
  FX_PETSC(PCMGGetLevels(pc_, &nl));
  const bool first = coarse_.empty();
  if (first) coarse_.assign(static_cast<std::size_t>(nl - 1), nullptr);
  Mat A = fine;
  for (PetscInt l = nl - 1; l > 0; --l) { // from the finest down: level l - 1 = P^T A_l P
    Mat P = nullptr;
    FX_PETSC(PCMGGetInterpolation(pc_, l, &P));
    Mat &C = coarse_[static_cast<std::size_t>(l - 1)];
    FX_PETSC(MatPtAP(A, P, first ? MAT_INITIAL_MATRIX : MAT_REUSE_MATRIX, PETSC_DEFAULT, &C));
    // Set again for every operator, not only the first: C is refilled in place, and a smoother
    // not told so keeps its set-up, a Chebyshev smoother the eigenvalue estimate of the first
    // design (found by scripts/study_kill_resume.py: a resumed run's estimate came from another
    // design, docs/solvers.md "Warm start").
    KSP smoother = nullptr;
    FX_PETSC(PCMGGetSmoother(pc_, l - 1, &smoother));
    FX_PETSC(KSPSetOperators(smoother, C, C));
    A = C;
  }
}

} // namespace flexopt::fem
