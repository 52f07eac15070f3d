#include "flexopt/fem/assembly.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <sstream>
#include <utility>

namespace flexopt::fem {

namespace {

void set_local_to_global(const mesh::DistributedMesh &mesh, Mat A, int block_size) {
  std::vector<PetscInt> l2g(static_cast<std::size_t>(mesh.local_nodes()));
  for (PetscInt i = 0; i < mesh.local_nodes(); ++i)
    l2g[static_cast<std::size_t>(i)] = mesh.local_to_global(i);
  ISLocalToGlobalMapping map;
  FX_PETSC(ISLocalToGlobalMappingCreate(mesh.comm, block_size, mesh.local_nodes(), l2g.data(),
                                        PETSC_COPY_VALUES, &map));
  FX_PETSC(MatSetLocalToGlobalMapping(A, map, map));
  FX_PETSC(ISLocalToGlobalMappingDestroy(&map));
}

std::string element_context(const mesh::DistributedMesh &mesh, PetscInt e,
                            const std::exception &err) {
  std::ostringstream s;
  s << mesh.source << ": element " << mesh.element_tags[static_cast<std::size_t>(e)] << " ("
    << element_name(mesh.type) << "): " << err.what();
  return s.str();
}

} // namespace

namespace {

/// Exact block sparsity of the stiffness pattern: for every owned node, the sorted global
/// numbers of the nodes it shares an element with. Rows of shared nodes also get columns
/// from elements on other ranks: every rank sends the adjacency of its ghost nodes to their
/// owners. Collective.
std::vector<std::vector<PetscInt>> node_graph(const mesh::DistributedMesh &mesh) {
  const PetscInt n_local = mesh.local_nodes(), n_owned = mesh.owned_nodes;
  const int npe = mesh.nodes_per_element();
  const PetscInt n_elem = mesh.local_elements();
  // Node -> elements (CSR).
  std::vector<PetscInt> start(static_cast<std::size_t>(n_local + 1), 0), elems;
  for (PetscInt k = 0; k < n_elem * npe; ++k)
    ++start[static_cast<std::size_t>(mesh.connectivity[static_cast<std::size_t>(k)] + 1)];
  for (PetscInt i = 0; i < n_local; ++i)
    start[static_cast<std::size_t>(i + 1)] += start[static_cast<std::size_t>(i)];
  elems.resize(static_cast<std::size_t>(start.back()));
  {
    std::vector<PetscInt> next(start.begin(), start.end() - 1);
    for (PetscInt e = 0; e < n_elem; ++e)
      for (int a = 0; a < npe; ++a)
        elems[static_cast<std::size_t>(next[static_cast<std::size_t>(
            mesh.connectivity[static_cast<std::size_t>(e * npe + a)])]++)] = e;
  }
  // Global column lists of every local node's row, from local elements only.
  std::vector<PetscInt> marker(static_cast<std::size_t>(n_local), -1);
  std::vector<std::vector<PetscInt>> columns(static_cast<std::size_t>(n_local));
  for (PetscInt i = 0; i < n_local; ++i) {
    auto &cols = columns[static_cast<std::size_t>(i)];
    for (PetscInt k = start[static_cast<std::size_t>(i)];
         k < start[static_cast<std::size_t>(i + 1)]; ++k) {
      const PetscInt e = elems[static_cast<std::size_t>(k)];
      for (int a = 0; a < npe; ++a) {
        const PetscInt j = mesh.connectivity[static_cast<std::size_t>(e * npe + a)];
        if (marker[static_cast<std::size_t>(j)] == i) continue;
        marker[static_cast<std::size_t>(j)] = i;
        cols.push_back(mesh.local_to_global(j));
      }
    }
  }
  // Ghost rows go to their owners as [row, count, columns...].
  const int size = comm_size(mesh.comm);
  std::vector<PetscInt> ranges(static_cast<std::size_t>(size) + 1, 0);
  MPI_Allgather(&mesh.node_start, 1, MPIU_INT, ranges.data(), 1, MPIU_INT, mesh.comm);
  ranges[static_cast<std::size_t>(size)] = mesh.global_nodes;
  std::vector<std::vector<PetscInt>> outgoing(static_cast<std::size_t>(size));
  for (PetscInt i = n_owned; i < n_local; ++i) {
    const PetscInt g = mesh.local_to_global(i);
    const int owner =
        static_cast<int>(std::upper_bound(ranges.begin(), ranges.end(), g) - ranges.begin()) - 1;
    auto &buf = outgoing[static_cast<std::size_t>(owner)];
    const auto &cols = columns[static_cast<std::size_t>(i)];
    buf.push_back(g);
    buf.push_back(static_cast<PetscInt>(cols.size()));
    buf.insert(buf.end(), cols.begin(), cols.end());
  }
  std::vector<int> send_counts(static_cast<std::size_t>(size)),
      recv_counts(static_cast<std::size_t>(size));
  for (int p = 0; p < size; ++p)
    send_counts[static_cast<std::size_t>(p)] =
        static_cast<int>(outgoing[static_cast<std::size_t>(p)].size());
  MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, mesh.comm);
  std::vector<int> send_displs(static_cast<std::size_t>(size), 0),
      recv_displs(static_cast<std::size_t>(size), 0);
  for (int p = 1; p < size; ++p) {
    send_displs[static_cast<std::size_t>(p)] =
        send_displs[static_cast<std::size_t>(p - 1)] + send_counts[static_cast<std::size_t>(p - 1)];
    recv_displs[static_cast<std::size_t>(p)] =
        recv_displs[static_cast<std::size_t>(p - 1)] + recv_counts[static_cast<std::size_t>(p - 1)];
  }
  std::vector<PetscInt> send_buf,
      recv_buf(static_cast<std::size_t>(recv_displs.back() + recv_counts.back()));
  for (const auto &b : outgoing) send_buf.insert(send_buf.end(), b.begin(), b.end());
  MPI_Alltoallv(send_buf.data(), send_counts.data(), send_displs.data(), MPIU_INT, recv_buf.data(),
                recv_counts.data(), recv_displs.data(), MPIU_INT, mesh.comm);
  for (std::size_t k = 0; k < recv_buf.size();) {
    const PetscInt row = recv_buf[k] - mesh.node_start, count = recv_buf[k + 1];
    auto &cols = columns[static_cast<std::size_t>(row)];
    cols.insert(cols.end(), recv_buf.begin() + static_cast<std::ptrdiff_t>(k + 2),
                recv_buf.begin() +
                    static_cast<std::ptrdiff_t>(k + 2 + static_cast<std::size_t>(count)));
    k += 2 + static_cast<std::size_t>(count);
  }
  columns.resize(static_cast<std::size_t>(n_owned));
  for (auto &cols : columns) {
    std::sort(cols.begin(), cols.end());
    cols.erase(std::unique(cols.begin(), cols.end()), cols.end());
  }
  return columns;
}

} // namespace

Mat create_matrix(const mesh::DistributedMesh &mesh, int block_size) {
  LogScope log("FxCreateMatrix");
  // Block counts per owned node row, split into the diagonal (owned columns) and
  // off-diagonal parts that MPIAIJ stores separately.
  std::vector<PetscInt> diag(static_cast<std::size_t>(mesh.owned_nodes), 0),
      offdiag(diag.size(), 0);
  {
    const auto graph = node_graph(mesh);
    const PetscInt lo = mesh.node_start, hi = mesh.node_start + mesh.owned_nodes;
    for (std::size_t i = 0; i < graph.size(); ++i)
      for (PetscInt g : graph[i]) ++((g >= lo && g < hi) ? diag : offdiag)[i];
  }
  const PetscInt n = block_size * mesh.owned_nodes;
  Mat A;
  FX_PETSC(MatCreate(mesh.comm, &A));
  FX_PETSC(MatSetSizes(A, n, n, PETSC_DETERMINE, PETSC_DETERMINE));
  FX_PETSC(MatSetBlockSize(A, block_size));
  FX_PETSC(MatSetType(A, MATAIJ));
  FX_PETSC(MatXAIJSetPreallocation(A, block_size, diag.data(), offdiag.data(), nullptr, nullptr));
  set_local_to_global(mesh, A, block_size);
  FX_PETSC(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
  return A;
}

Vec create_ghosted_vector(const mesh::DistributedMesh &mesh) {
  Vec v;
  FX_PETSC(VecCreateGhostBlock(mesh.comm, 3, 3 * mesh.owned_nodes, PETSC_DETERMINE,
                               static_cast<PetscInt>(mesh.ghosts.size()), mesh.ghosts.data(), &v));
  return v;
}

namespace {

/// The global DOF numbers of element e's nodes in ascending order, and for each the row of the
/// element matrix it comes from. MatSetValues searches each matrix row for the columns it is
/// given; in ascending order every search starts where the previous one ended (about 10 %
/// faster at 500k DOFs than the element's own node order), and the global numbers skip the
/// local-to-global mapping of MatSetValuesBlockedLocal. Only the order of distinct entries
/// changes, so the assembled matrix is the same to the last bit.
struct SortedElementDofs {
  int n = 0;                 ///< DOFs of the element
  PetscInt global[kMaxDofs]; ///< ascending global DOF numbers
  int source[kMaxDofs];      ///< element-matrix row (node-major) of global[k]

  /// `node_dof` (per local node: the DOF number of its x component in the target's layout) or
  /// null: the mesh's own numbering 3 g.
  SortedElementDofs(const mesh::DistributedMesh &mesh, PetscInt e,
                    const PetscInt *node_dof = nullptr) {
    const int npe = mesh.nodes_per_element();
    const PetscInt *idx = &mesh.connectivity[static_cast<std::size_t>(e * npe)];
    PetscInt g[kMaxNodes];
    int order[kMaxNodes];
    for (int a = 0; a < npe; ++a) {
      g[a] = node_dof ? node_dof[idx[a]] : 3 * mesh.local_to_global(idx[a]);
      order[a] = a;
    }
    for (int a = 1; a < npe; ++a) // insertion sort: at most 10 nodes
      for (int b = a; b > 0 && g[order[b]] < g[order[b - 1]]; --b)
        std::swap(order[b], order[b - 1]);
    n = 3 * npe;
    for (int a = 0; a < npe; ++a)
      for (int i = 0; i < 3; ++i) {
        global[3 * a + i] = g[order[a]] + i;
        source[3 * a + i] = 3 * order[a] + i;
      }
  }
};

/// Adds factor * Ke to A in the sorted order of d.
void add_sorted(Mat A, const SortedElementDofs &d, const ElementMatrix &Ke, double factor) {
  double sorted[kMaxDofs * kMaxDofs];
  for (int r = 0; r < d.n; ++r)
    for (int c = 0; c < d.n; ++c) sorted[r * d.n + c] = factor * Ke(d.source[r], d.source[c]);
  FX_PETSC(MatSetValues(A, d.n, d.global, d.n, d.global, sorted, ADD_VALUES));
}

/// Adds element matrices straight into the value arrays of an assembled AIJ matrix with
/// create_matrix's pattern (rows in node triples with equal columns, columns in full 3 x 3 node
/// blocks): one binary search per element node pair for the block's place in its rows, where
/// MatSetValues searches per entry (about 10x the time: 11 us per Hex8 element at 92k DOFs).
/// Rows of nodes owned by another rank go through MatSetValues (its stash). Contributions are
/// added in the same order as MatSetValues would, so the matrix is the same to the last bit.
class DirectAdder {
public:
  DirectAdder(const mesh::DistributedMesh &mesh, Mat A) : mesh_(mesh), A_(A) {
    PetscBool assembled = PETSC_FALSE, mpi = PETSC_FALSE, seq = PETSC_FALSE;
    FX_PETSC(MatAssembled(A, &assembled));
    FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(A), MATMPIAIJ, &mpi));
    FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(A), MATSEQAIJ, &seq));
    if (!assembled || !(mpi || seq)) return; // the first assembly sets the pattern: MatSetValues
    PetscInt cend = 0;
    FX_PETSC(MatGetOwnershipRangeColumn(A, &cstart_, &cend));
    ncols_ = cend - cstart_;
    parts_[0].M = A;
    if (mpi) {
      const PetscInt *garray = nullptr;
      FX_PETSC(MatMPIAIJGetSeqAIJ(A, &parts_[0].M, &parts_[1].M, &garray));
      PetscInt n = 0;
      FX_PETSC(MatGetSize(parts_[1].M, nullptr, &n));
      garray_.assign(garray, garray + n);
    }
    ok_ = true;
    for (Part &p : parts_) {
      if (!p.M) continue;
      PetscInt n = 0;
      PetscBool done = PETSC_FALSE;
      FX_PETSC(MatGetRowIJ(p.M, 0, PETSC_FALSE, PETSC_FALSE, &n, &p.ia, &p.ja, &done));
      if (!done) ok_ = false;
      FX_PETSC(MatSeqAIJGetArray(p.M, &p.a));
      p.rows = n;
    }
    if (ok_) ok_ = pattern_fits(A);
  }
  ~DirectAdder() {
    for (Part &p : parts_) {
      if (!p.M || !p.ia) continue;
      PetscInt n = 0;
      PetscBool done = PETSC_FALSE;
      MatSeqAIJRestoreArray(p.M, &p.a);
      MatRestoreRowIJ(p.M, 0, PETSC_FALSE, PETSC_FALSE, &n, &p.ia, &p.ja, &done);
    }
  }
  /// Whether the arrays can be written (else add() must not be called).
  bool usable() const { return ok_; }

  /// Adds factor * Ke of local element e.
  void add(PetscInt e, const ElementMatrix &Ke, double factor) {
    const int npe = mesh_.nodes_per_element();
    const PetscInt *idx = &mesh_.connectivity[static_cast<std::size_t>(e * npe)];
    PetscInt g[kMaxNodes];
    for (int b = 0; b < npe; ++b) g[b] = 3 * mesh_.local_to_global(idx[b]);
    bool remote = false;
    for (int a = 0; a < npe; ++a) remote = remote || idx[a] >= mesh_.owned_nodes;
    if (remote) {
      // Another rank's rows go through the stash exactly as add_sorted sends them (rows and
      // columns ascending): the stash sums duplicates in its own order, so the same input
      // gives the same bits.
      const SortedElementDofs d(mesh_, e);
      PetscInt rows[kMaxDofs];
      double values[kMaxDofs * kMaxDofs];
      int nr = 0;
      for (int r = 0; r < d.n; ++r) {
        if (idx[d.source[r] / 3] < mesh_.owned_nodes) continue;
        rows[nr] = d.global[r];
        for (int c = 0; c < d.n; ++c) values[nr * d.n + c] = factor * Ke(d.source[r], d.source[c]);
        ++nr;
      }
      FX_PETSC(MatSetValues(A_, nr, rows, d.n, d.global, values, ADD_VALUES));
    }
    for (int a = 0; a < npe; ++a) {
      if (idx[a] >= mesh_.owned_nodes) continue; // sent above
      const PetscInt r = 3 * idx[a];
      for (int b = 0; b < npe; ++b) {
        const bool diag = g[b] >= cstart_ && g[b] < cstart_ + ncols_;
        Part &p = parts_[diag ? 0 : 1];
        PetscInt key = g[b] - cstart_;
        if (!diag) {
          const auto it = std::lower_bound(garray_.begin(), garray_.end(), g[b]);
          key = static_cast<PetscInt>(it - garray_.begin());
        }
        const PetscInt *lo = p.ja + p.ia[r], *hi = p.ja + p.ia[r + 1];
        const PetscInt off = static_cast<PetscInt>(std::lower_bound(lo, hi, key) - lo);
        for (int i = 0; i < 3; ++i) {
          double *v = p.a + p.ia[r + i] + off;
          for (int j = 0; j < 3; ++j) v[j] += factor * Ke(3 * a + i, 3 * b + j);
        }
      }
    }
  }

private:
  struct Part {
    Mat M = nullptr;
    const PetscInt *ia = nullptr, *ja = nullptr;
    double *a = nullptr;
    PetscInt rows = 0;
  };

  /// Whether the pattern has rows in triples with equal columns and columns in runs of 3 from a
  /// multiple of 3. The check reads every column index (O(nnz): 0.03 of 0.25 s per assembly at
  /// 212k DOFs, 2 ranks), so its verdict is kept per matrix (PETSc object id) and nonzero state:
  /// it runs again only when the pattern changes.
  bool pattern_fits(Mat A) const {
    struct Verdict {
      PetscObjectId id;
      PetscObjectState state;
      bool fits;
    };
    static std::vector<Verdict> kept; // the latest 16 matrices assembled in place
    PetscObjectId id = 0;
    PetscObjectState state = 0;
    FX_PETSC(PetscObjectGetId(reinterpret_cast<PetscObject>(A), &id));
    FX_PETSC(MatGetNonzeroState(A, &state));
    for (const Verdict &v : kept)
      if (v.id == id && v.state == state) return v.fits;
    bool fits = true;
    for (const Part &p : parts_) {
      if (!p.M) continue;
      for (PetscInt r = 0; fits && r + 2 < p.rows; r += 3) {
        const PetscInt len = p.ia[r + 1] - p.ia[r];
        if (len % 3 || p.ia[r + 2] - p.ia[r + 1] != len || p.ia[r + 3] - p.ia[r + 2] != len) {
          fits = false;
          break;
        }
        for (PetscInt k = 0; k < len && fits; k += 3) {
          const PetscInt c = p.ja[p.ia[r] + k];
          const PetscInt g = &p == &parts_[0] ? c + cstart_ : garray_[static_cast<std::size_t>(c)];
          for (int i = 0; i < 3 && fits; ++i)
            for (int j = 0; j < 3 && fits; ++j) {
              const PetscInt cj = p.ja[p.ia[r + i] + k + j];
              const PetscInt gj =
                  &p == &parts_[0] ? cj + cstart_ : garray_[static_cast<std::size_t>(cj)];
              if (gj != g + j || g % 3) fits = false;
            }
        }
      }
    }
    const auto same = [id](const Verdict &v) { return v.id == id; };
    kept.erase(std::remove_if(kept.begin(), kept.end(), same), kept.end());
    if (kept.size() >= 16) kept.erase(kept.begin()); // the oldest: matrices destroyed since
    kept.push_back({id, state, fits});
    return fits;
  }
  const mesh::DistributedMesh &mesh_;
  Mat A_;
  Part parts_[2];
  std::vector<PetscInt> garray_; ///< global column of each off-diagonal-part column
  PetscInt cstart_ = 0, ncols_ = 0;
  bool ok_ = false;
};

/// Assembles sum_e factor(e) K(e) into A (zeroed first): `kernel(e, X)` returns the element
/// matrix of element e with node coordinates X, `factor(e)` its scale.
template <class Kernel, class Factor>
void assemble_matrix(const mesh::DistributedMesh &mesh, Mat A, Kernel &&kernel, Factor &&factor) {
  LogScope log("FxAssembleMatrix");
  FX_PETSC(MatZeroEntries(A));
  {
    DirectAdder direct(mesh, A);
    for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
      const ElementMatrix *Ke = nullptr;
      try {
        Ke = &kernel(e, mesh.element_coordinates(e));
      } catch (const std::exception &err) {
        abort_local(element_context(mesh, e, err)); // only this rank holds the element
      }
      if (direct.usable())
        direct.add(e, *Ke, factor(e));
      else
        add_sorted(A, SortedElementDofs(mesh, e), *Ke, factor(e));
    }
  }
  FX_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
}

} // namespace

int UnitStiffness::shape(const ElementCoords &X) {
  ElementCoords d = X;
  for (int a = 0; a < X.rows(); ++a) d.row(a) -= X.row(0);
  const double tol = 1e-12 * d.cwiseAbs().maxCoeff();
  for (std::size_t s = 0; s < shapes_.size(); ++s)
    if ((shapes_[s].offsets - d).cwiseAbs().maxCoeff() <= tol) {
      ++hits_;
      return static_cast<int>(s);
    }
  if (shapes_.size() >= kMaxShapes) return -1;
  ++computed_;
  shapes_.push_back({d, element_stiffness(type_, X, material_, 1.0)});
  return static_cast<int>(shapes_.size()) - 1;
}

const ElementMatrix &UnitStiffness::operator()(const ElementCoords &X) {
  if (hits_ > 0 || computed_ < 64) { // still looking for repeats
    const int s = shape(X);
    if (s >= 0) return shapes_[static_cast<std::size_t>(s)].K;
  }
  ++computed_;
  scratch_ = element_stiffness(type_, X, material_, 1.0);
  return scratch_;
}

void assemble_stiffness(const mesh::DistributedMesh &mesh, const IsotropicMaterial &material,
                        const std::vector<double> &modulus_factor, Mat A) {
  UnitStiffness unit(mesh.type, material);
  assemble_matrix(
      mesh, A, [&](PetscInt, const ElementCoords &X) -> const ElementMatrix & { return unit(X); },
      [&](PetscInt e) {
        return modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
      });
}

void add_mass(const mesh::DistributedMesh &mesh, double density,
              const std::vector<double> &density_factor, const std::vector<PetscInt> &node_dof,
              Mat A) {
  // The consistent mass is m_ab I_3 per node pair (element_mass): two thirds of every element
  // matrix are exact zeros. Only the nonzeros are added, one component at a time, which makes
  // the assembly about 3x cheaper and leaves those zeros out of A's stored pattern (assembly
  // drops preallocated entries that were never set), so every product with M is cheaper too.
  // The values are the same to the last bit (the skipped terms were exact zeros).
  PetscInt rows[kMaxNodes];
  double m[kMaxNodes * kMaxNodes];
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    ElementMatrix Me;
    try {
      const double f = density_factor.empty() ? 1.0 : density_factor[static_cast<std::size_t>(e)];
      Me = element_mass(mesh.type, mesh.element_coordinates(e), density * f);
    } catch (const std::exception &err) {
      abort_local(element_context(mesh, e, err)); // only this rank holds the element
    }
    const SortedElementDofs d(mesh, e, node_dof.empty() ? nullptr : node_dof.data());
    const int npe = d.n / 3;
    for (int r = 0; r < npe; ++r)
      for (int c = 0; c < npe; ++c)
        m[r * npe + c] = Me(d.source[3 * r], d.source[3 * c]); // component 0 of both nodes
    for (int i = 0; i < 3; ++i) {
      for (int a = 0; a < npe; ++a) rows[a] = d.global[3 * a + i];
      FX_PETSC(MatSetValues(A, npe, rows, npe, rows, m, ADD_VALUES));
    }
  }
}

void assemble_mass(const mesh::DistributedMesh &mesh, double density,
                   const std::vector<double> &density_factor, Mat A) {
  LogScope log("FxAssembleMatrix");
  FX_PETSC(MatZeroEntries(A));
  add_mass(mesh, density, density_factor, {}, A);
  FX_PETSC(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY));
}

void add_element_pattern(const mesh::DistributedMesh &mesh, const std::vector<PetscInt> &node_dof,
                         Mat A) {
  const double zeros[kMaxDofs * kMaxDofs] = {};
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const SortedElementDofs d(mesh, e, node_dof.empty() ? nullptr : node_dof.data());
    FX_PETSC(MatSetValues(A, d.n, d.global, d.n, d.global, zeros, ADD_VALUES));
  }
}

void assemble_stiffness_and_mass(const mesh::DistributedMesh &mesh,
                                 const IsotropicMaterial &material, Mat &K, Mat &M) {
  // Two fresh matrices: MatDuplicate of the preallocated, not yet assembled K goes through
  // MatConvert and costs several times the exact preallocation (1.8 s against 0.2 s at 500k DOFs).
  K = create_matrix(mesh);
  M = create_matrix(mesh);
  assemble_stiffness(mesh, material, {}, K);
  assemble_mass(mesh, material.density, {}, M);
}

Eigen::Vector3d surface_centroid(const mesh::DistributedMesh &mesh, const std::string &name,
                                 const std::string &where) {
  const mesh::LocalSurface &s = mesh.surface(name, where);
  const int nf = nodes_per_face(s.type);
  double local[4] = {0, 0, 0, 0};
  for (std::size_t f = 0; f < s.size(); ++f) {
    const FaceCoords Xf = s.face_coordinates(f);
    // int N_a dA from the consistent load of a unit traction (1, 0, 0).
    const ElementVector w = face_traction_load(s.type, Xf, Eigen::Vector3d(1, 0, 0));
    for (int a = 0; a < nf; ++a) {
      local[3] += w(3 * a);
      for (int k = 0; k < 3; ++k) local[k] += w(3 * a) * Xf(a, k);
    }
  }
  double global[4];
  MPI_Allreduce(local, global, 4, MPI_DOUBLE, MPI_SUM, mesh.comm);
  if (!(global[3] > 0))
    throw Error(where + ": surface '" + name + "' of " + mesh.source + " has no area", true);
  return Eigen::Vector3d(global[0], global[1], global[2]) / global[3];
}

double surface_area(const mesh::DistributedMesh &mesh, const std::string &surface,
                    const std::string &where) {
  const mesh::LocalSurface &s = mesh.surface(surface, where);
  double local = 0, global = 0;
  for (std::size_t k = 0; k < s.size(); ++k) local += face_area(s.type, s.face_coordinates(k));
  MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_SUM, mesh.comm);
  return global;
}

namespace {

/// Adds face_load(type, face coordinates) of every face of `surface` into f. Collective.
template <class FaceLoad>
void add_face_loads(const mesh::DistributedMesh &mesh, const std::string &surface,
                    const std::string &where, Vec f, FaceLoad &&face_load) {
  const mesh::LocalSurface &s = mesh.surface(surface, where);
  const int npf = nodes_per_face(s.type);
  for (std::size_t k = 0; k < s.size(); ++k) {
    const ElementVector fe = face_load(s.type, s.face_coordinates(k));
    FX_PETSC(VecSetValuesBlocked(f, npf, &s.global_nodes[k * static_cast<std::size_t>(npf)],
                                 fe.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(f));
  FX_PETSC(VecAssemblyEnd(f));
}

} // namespace

void add_surface_traction(const mesh::DistributedMesh &mesh, const std::string &surface,
                          const Eigen::Vector3d &t, const std::string &where, Vec f) {
  add_face_loads(mesh, surface, where, f, [&](FaceType type, const FaceCoords &Xf) {
    return face_traction_load(type, Xf, t);
  });
}

void add_surface_force(const mesh::DistributedMesh &mesh, const std::string &surface,
                       const Eigen::Vector3d &F, const Eigen::Vector3d &M, const std::string &where,
                       Vec f) {
  const double area = surface_area(mesh, surface, where);
  if (!(area > 0)) throw Error(where + ": surface '" + surface + "' has zero area", true);
  if (M.isZero(0.0)) {
    add_surface_traction(mesh, surface, F / area, where, f);
    return;
  }
  const Eigen::Vector3d c = surface_centroid(mesh, surface, where);
  const mesh::LocalSurface &s = mesh.surface(surface, where);
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < s.size(); ++k)
    J += face_second_moment(s.type, s.face_coordinates(k), c);
  MPI_Allreduce(MPI_IN_PLACE, J.data(), 9, MPI_DOUBLE, MPI_SUM, mesh.comm);
  // J is symmetric positive semi-definite; a flat surface has full rank, a line of faces not.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(J);
  if (!(eig.eigenvalues()(0) > 1e-10 * eig.eigenvalues()(2)))
    throw Error(where + ": surface '" + surface +
                    "' cannot carry a moment (its faces lie on a "
                    "line: the second moment of area is singular)",
                true);
  const Eigen::Vector3d beta = J.ldlt().solve(M);
  Eigen::Matrix3d T;
  T << 0, -beta(2), beta(1), beta(2), 0, -beta(0), -beta(1), beta(0), 0;
  add_face_loads(mesh, surface, where, f, [&](FaceType type, const FaceCoords &Xf) {
    return face_linear_traction_load(type, Xf, F / area, T, c);
  });
}

std::vector<PetscInt> surface_dofs(const mesh::DistributedMesh &mesh, const std::string &surface,
                                   const std::array<bool, 3> &components,
                                   const std::string &where) {
  mesh.surface(surface, where); // existence check with a clear message
  std::vector<PetscInt> dofs;
  for (PetscInt g : mesh.surface_nodes.at(surface))
    for (int k = 0; k < 3; ++k)
      if (components[static_cast<std::size_t>(k)]) dofs.push_back(3 * g + k);
  return dofs;
}

Vec create_coordinate_vector(const mesh::DistributedMesh &mesh) {
  Vec x;
  FX_PETSC(VecCreateMPI(mesh.comm, 3 * mesh.owned_nodes, PETSC_DETERMINE, &x));
  FX_PETSC(VecSetBlockSize(x, 3));
  PetscScalar *a;
  FX_PETSC(VecGetArray(x, &a));
  for (PetscInt i = 0; i < 3 * mesh.owned_nodes; ++i)
    a[i] = mesh.coordinates[static_cast<std::size_t>(i)];
  FX_PETSC(VecRestoreArray(x, &a));
  return x;
}

std::vector<double> element_volumes(const mesh::DistributedMesh &mesh) {
  std::vector<double> v(static_cast<std::size_t>(mesh.local_elements()));
  for (PetscInt e = 0; e < mesh.local_elements(); ++e)
    v[static_cast<std::size_t>(e)] = element_volume(mesh.type, mesh.element_coordinates(e));
  return v;
}

std::vector<CorotatedElement> corotated_elements(const mesh::DistributedMesh &mesh,
                                                 const IsotropicMaterial &material,
                                                 const std::vector<double> &modulus_factor) {
  std::vector<CorotatedElement> out;
  out.reserve(static_cast<std::size_t>(mesh.local_elements()));
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
    try {
      out.push_back(corotated_element(mesh.type, mesh.element_coordinates(e), material, f));
    } catch (const std::exception &err) {
      abort_local(element_context(mesh, e, err)); // only this rank holds the element
    }
  }
  return out;
}

double add_corotated(const mesh::DistributedMesh &mesh,
                     const std::vector<CorotatedElement> &elements, const PetscScalar *u,
                     const std::vector<PetscInt> &node_dof, Vec F, Mat T, std::string &failure,
                     const CorotatedDamping *damping) {
  double energy = 0;
  // Two events: the loops with the tangent (a Newton matrix) and those of the force alone.
  LogScope log(T ? "FxCorotTangent" : "FxCorotForce");
  double fsorted[kMaxDofs];
  ElementVector fe, fd;
  ElementMatrix Te, Cv, Cx;
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const CorotatedElement &ce = elements[static_cast<std::size_t>(e)];
    const ElementVector ue = gather_element(mesh, e, u);
    ElementCoords x = ce.X;
    for (int a = 0; a < x.rows(); ++a) x.row(a) += ue.segment<3>(3 * a).transpose();
    try {
      energy += corotated_state(ce, x, &fe, T ? &Te : nullptr);
      if (damping) {
        corotated_damping(ce, x, gather_element(mesh, e, damping->v), damping->beta, &fd,
                          T ? &Cv : nullptr, T ? &Cx : nullptr);
        fe += fd;
        if (T) Te += Cx + damping->gp * Cv;
      }
    } catch (const Error &err) {
      if (failure.empty()) failure = element_context(mesh, e, err);
      continue;
    }
    const SortedElementDofs d(mesh, e, node_dof.empty() ? nullptr : node_dof.data());
    for (int r = 0; r < d.n; ++r) fsorted[r] = fe(d.source[r]);
    FX_PETSC(VecSetValues(F, d.n, d.global, fsorted, ADD_VALUES));
    if (T) add_sorted(T, d, Te, 1.0);
  }
  return energy;
}

CorotatedSum reduce_corotated(MPI_Comm comm, double energy, std::string failure) {
  CorotatedSum sum;
  MPI_Allreduce(&energy, &sum.energy, 1, MPI_DOUBLE, MPI_SUM, comm);
  // The lowest rank with a failure sends its message to all.
  const int rank = comm_rank(comm), size = comm_size(comm);
  int mine = failure.empty() ? size : rank, first = size;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first < size) {
    sum.ok = false;
    int length = static_cast<int>(failure.size());
    MPI_Bcast(&length, 1, MPI_INT, first, comm);
    failure.resize(static_cast<std::size_t>(length));
    MPI_Bcast(failure.data(), length, MPI_CHAR, first, comm);
    sum.failure = failure;
  }
  return sum;
}

CorotatedSum assemble_corotated(const mesh::DistributedMesh &mesh,
                                const std::vector<CorotatedElement> &elements, Vec u_ghosted, Vec F,
                                Mat T) {
  FX_PETSC(VecZeroEntries(F));
  if (T) FX_PETSC(MatZeroEntries(T));
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(u_ghosted, &local));
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(local, &u));
  std::string failure;
  const double energy = add_corotated(mesh, elements, u, {}, F, T, failure);
  FX_PETSC(VecRestoreArrayRead(local, &u));
  FX_PETSC(VecGhostRestoreLocalForm(u_ghosted, &local));
  FX_PETSC(VecAssemblyBegin(F));
  FX_PETSC(VecAssemblyEnd(F));
  if (T) {
    FX_PETSC(MatAssemblyBegin(T, MAT_FINAL_ASSEMBLY));
    FX_PETSC(MatAssemblyEnd(T, MAT_FINAL_ASSEMBLY));
  }
  return reduce_corotated(mesh.comm, energy, failure);
}

ElementGather::ElementGather(const mesh::DistributedMesh &mesh, const std::vector<Vec> &vectors)
    : mesh_(mesh) {
  // One ghosted layout, duplicated: the copies share its scatter (its set-up was 7-8 % of a
  // reduction adjoint's time when every copy built its own).
  for (Vec x : vectors) {
    Vec g;
    if (ghosted_.empty())
      g = create_ghosted_vector(mesh);
    else
      FX_PETSC(VecDuplicate(ghosted_.front(), &g));
    FX_PETSC(VecCopy(x, g));
    FX_PETSC(VecGhostUpdateBegin(g, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecGhostUpdateEnd(g, INSERT_VALUES, SCATTER_FORWARD));
    Vec local;
    FX_PETSC(VecGhostGetLocalForm(g, &local));
    const PetscScalar *a;
    FX_PETSC(VecGetArrayRead(local, &a));
    ghosted_.push_back(g);
    local_.push_back(local);
    values_.push_back(a);
  }
}

ElementGather::~ElementGather() {
  for (std::size_t k = 0; k < ghosted_.size(); ++k) {
    VecRestoreArrayRead(local_[k], &values_[k]);
    VecGhostRestoreLocalForm(ghosted_[k], &local_[k]);
    VecDestroy(&ghosted_[k]);
  }
}

void ElementGather::element(PetscInt e, Eigen::MatrixXd &out) const {
  const int npe = mesh_.nodes_per_element();
  out.resize(3 * npe, static_cast<Eigen::Index>(values_.size()));
  for (std::size_t k = 0; k < values_.size(); ++k)
    for (int a = 0; a < npe; ++a) {
      const PetscInt node = mesh_.connectivity[static_cast<std::size_t>(e * npe + a)];
      for (int i = 0; i < 3; ++i)
        out(3 * a + i, static_cast<Eigen::Index>(k)) = values_[k][3 * node + i];
    }
}

Eigen::MatrixXd project_stiffness(const mesh::DistributedMesh &mesh,
                                  const IsotropicMaterial &material,
                                  const std::vector<double> &modulus_factor,
                                  const std::vector<Vec> &vectors) {
  const auto n = static_cast<Eigen::Index>(vectors.size());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(n, n);
  if (n == 0) return P;
  const ElementGather v(mesh, vectors);
  Eigen::MatrixXd Ve;
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
    v.element(e, Ve);
    const ElementMatrix Ke = element_stiffness(mesh.type, mesh.element_coordinates(e), material, f);
    P.noalias() += Ve.transpose() * (Ke * Ve);
  }
  MPI_Allreduce(MPI_IN_PLACE, P.data(), static_cast<int>(P.size()), MPI_DOUBLE, MPI_SUM, mesh.comm);
  return 0.5 * (P + P.transpose());
}

ElementVector gather_element(const mesh::DistributedMesh &mesh, PetscInt e,
                             const PetscScalar *u_local) {
  const int npe = mesh.nodes_per_element();
  ElementVector ue(3 * npe);
  for (int a = 0; a < npe; ++a) {
    const PetscInt n = mesh.connectivity[static_cast<std::size_t>(e * npe + a)];
    for (int k = 0; k < 3; ++k) ue(3 * a + k) = u_local[3 * n + k];
  }
  return ue;
}

void add_element(const mesh::DistributedMesh &mesh, PetscInt e, const double *f,
                 PetscScalar *local) {
  const int npe = mesh.nodes_per_element();
  for (int a = 0; a < npe; ++a) {
    const PetscInt n = mesh.connectivity[static_cast<std::size_t>(e * npe + a)];
    for (int k = 0; k < 3; ++k) local[3 * n + k] += f[3 * a + k];
  }
}

std::vector<double> element_von_mises(const mesh::DistributedMesh &mesh,
                                      const IsotropicMaterial &material,
                                      const std::vector<double> &modulus_factor, Vec u_ghosted) {
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(u_ghosted, &local));
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(local, &u));
  std::vector<double> vm(static_cast<std::size_t>(mesh.local_elements()));
  const Eigen::Vector3d xi = reference_centroid(mesh.type);
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const double f = modulus_factor.empty() ? 1.0 : modulus_factor[static_cast<std::size_t>(e)];
    vm[static_cast<std::size_t>(e)] = von_mises(element_stress(
        mesh.type, mesh.element_coordinates(e), material, f, gather_element(mesh, e, u), xi));
  }
  FX_PETSC(VecRestoreArrayRead(local, &u));
  FX_PETSC(VecGhostRestoreLocalForm(u_ghosted, &local));
  return vm;
}

std::vector<double> element_rotations(const mesh::DistributedMesh &mesh, Vec u_ghosted) {
  Vec local;
  FX_PETSC(VecGhostGetLocalForm(u_ghosted, &local));
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(local, &u));
  std::vector<double> theta(static_cast<std::size_t>(mesh.local_elements()));
  const Eigen::Vector3d xi = reference_centroid(mesh.type);
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const Eigen::Matrix3d H =
        displacement_gradient(mesh.type, mesh.element_coordinates(e), gather_element(mesh, e, u),
                              xi, "element_rotations");
    const Eigen::Vector3d w(H(2, 1) - H(1, 2), H(0, 2) - H(2, 0), H(1, 0) - H(0, 1));
    theta[static_cast<std::size_t>(e)] = 0.5 * w.norm();
  }
  FX_PETSC(VecRestoreArrayRead(local, &u));
  FX_PETSC(VecGhostRestoreLocalForm(u_ghosted, &local));
  return theta;
}

} // namespace flexopt::fem
