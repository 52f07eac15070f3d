#include "flexopt/dynamics/distributed_alpha.hpp"

#include "distributed_alpha_detail.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/direct_solver.hpp"
#include "flexopt/core/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <utility>

namespace flexopt::dynamics {

namespace detail {

Vec copy_of(Vec v) {
  if (!v) return nullptr;
  Vec c;
  FX_PETSC(VecDuplicate(v, &c));
  FX_PETSC(VecCopy(v, c));
  return c;
}

double max_abs(Vec v) {
  PetscReal n;
  FX_PETSC(VecNorm(v, NORM_INFINITY, &n));
  return n;
}

/// MUMPS's estimate of the Newton matrix's factors, checked against the memory before the first
/// factorization of its pattern (check_factor_memory caches the pattern). Collective.
void check_newton_memory(KSP ksp, PC pc) {
  PetscBool lu = PETSC_FALSE, redundant = PETSC_FALSE;
  FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), PCLU, &lu));
  FX_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(pc), PCREDUNDANT, &redundant));
  MatSolverType solver = nullptr;
  if (lu) FX_PETSC(PCFactorGetMatSolverType(pc, &solver));
  if (!redundant && !(solver && std::strcmp(solver, MATSOLVERMUMPS) == 0)) return; // KLU, ...
  Mat A = nullptr;
  FX_PETSC(KSPGetOperators(ksp, &A, nullptr));
  check_factor_memory(A, Factorization::LU, "mech_", "the ACF scene's Newton matrix",
                      "a coarser mesh.size for the ACF bodies, or ranks on more nodes");
}

bool factorized(KSP ksp) {
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  check_newton_memory(ksp, pc);
  FX_PETSC(KSPSetUp(ksp));
  MPI_Comm comm;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(ksp), &comm));
  if (comm_size(comm) == 1) {
    FX_PETSC(PetscPushErrorHandler(PetscReturnErrorHandler, nullptr));
    const PetscErrorCode setup = PCSetUp(pc);
    FX_PETSC(PetscPopErrorHandler());
    if (setup != 0) return false;
  } else {
    FX_PETSC(PCSetUp(pc));
  }
  PCFailedReason failed;
  FX_PETSC(PCGetFailedReason(pc, &failed));
  return failed == PC_NOERROR;
}

/// The PETSc indices first .. first + n - 1.
std::vector<PetscInt> range(PetscInt first, int n) {
  std::vector<PetscInt> idx(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) idx[static_cast<std::size_t>(k)] = first + k;
  return idx;
}

} // namespace detail

using detail::copy_of;
using detail::factorized;
using detail::max_abs;
using detail::range;

namespace {

/// Copies the values of `from` into `to`, creating `to` if it does not exist yet.
void assign(Vec &to, Vec from) {
  if (!from) {
    VecDestroy(&to);
    return;
  }
  if (!to) FX_PETSC(VecDuplicate(from, &to));
  FX_PETSC(VecCopy(from, to));
}

/// Newton systems of at most this many unknowns use KLU on one rank (the constructor).
constexpr PetscInt kKluLimit = 2000;

/// Records the entries (rows x cols) in a MATPREALLOCATOR matrix.
void touch(Mat P, const std::vector<PetscInt> &rows, const std::vector<PetscInt> &cols) {
  std::vector<PetscScalar> zeros(rows.size() * cols.size(), 0.0);
  FX_PETSC(MatSetValues(P, static_cast<PetscInt>(rows.size()), rows.data(),
                        static_cast<PetscInt>(cols.size()), cols.data(), zeros.data(), ADD_VALUES));
}

using Bodies = std::vector<const bodies::AcfBody *>;

/// The owned nodes (local numbers) of every interface's surface; ntie: their tie rows on this
/// rank. Collective: a missing surface, or two interfaces of one body sharing a node (their rows
/// would repeat and the matrix would be singular), throws on every rank.
std::vector<std::vector<PetscInt>> tied_nodes(const Bodies &bodies,
                                              const std::vector<AcfInterface> &interfaces,
                                              MPI_Comm comm, PetscInt &ntie) {
  const std::size_t nb = bodies.size();
  ntie = 0;
  std::vector<std::vector<char>> used(nb);
  for (std::size_t b = 0; b < nb; ++b)
    used[b].assign(static_cast<std::size_t>(bodies[b]->mesh().owned_nodes), 0);
  std::vector<std::vector<PetscInt>> tied(interfaces.size());
  int shared = static_cast<int>(interfaces.size()); // the first interface with a shared node
  for (std::size_t i = 0; i < interfaces.size(); ++i) {
    const AcfInterface &f = interfaces[i];
    if (f.body >= nb) throw Error("DistributedAlpha: interface of a missing body");
    const mesh::DistributedMesh &m = bodies[f.body]->mesh();
    (void)m.surface(f.surface, f.where); // a collective error if the surface does not exist
    const auto it = m.surface_nodes.find(f.surface);
    if (it != m.surface_nodes.end())
      for (PetscInt g : it->second) {
        const PetscInt l = g - m.node_start;
        char &u = used[f.body][static_cast<std::size_t>(l)];
        if (u) shared = std::min(shared, static_cast<int>(i));
        u = 1;
        tied[i].push_back(l);
      }
    ntie += 3 * static_cast<PetscInt>(tied[i].size());
  }
  int first_shared;
  MPI_Allreduce(&shared, &first_shared, 1, MPI_INT, MPI_MIN, comm);
  if (first_shared < static_cast<int>(interfaces.size())) {
    const AcfInterface &f = interfaces[static_cast<std::size_t>(first_shared)];
    throw Error(f.where + ": interface surface '" + f.surface +
                    "' shares nodes with another interface of the same ACF body; their rigid "
                    "ties would repeat. Give every interface its own surface.",
                true);
  }
  return tied;
}

/// The global numbers of the unknowns (L.acf_local, small_n, small_m and coords_local set):
/// this rank's block and its start, the small part's first numbers, every body's offset and the
/// first DOF of every local node (a ghost's from its owner's offset), and the local position
/// and velocity vectors. Collective.
void number_unknowns(const Bodies &bodies, PetscInt ntie, MPI_Comm comm, detail::AcfLayout &L) {
  const std::size_t nb = bodies.size();
  const int size = comm_size(comm), rank = comm_rank(comm);
  L.local = L.coords_local + ntie + L.small_m;
  MPI_Exscan(&L.local, &L.start, 1, MPIU_INT, MPI_SUM, comm);
  if (rank == 0) L.start = 0;
  MPI_Allreduce(&L.local, &L.global, 1, MPIU_INT, MPI_SUM, comm);
  PetscInt small0[2] = {L.acf_local, L.coords_local + ntie};
  MPI_Bcast(small0, 2, MPIU_INT, 0, comm);
  L.small_coord0 = small0[0];
  L.small_row0 = small0[1];
  // Every rank's offset and first owned node of every body, for the ghosts' owners.
  std::vector<PetscInt> mine(2 * nb), all(2 * nb * static_cast<std::size_t>(size));
  PetscInt o = L.start;
  for (std::size_t b = 0; b < nb; ++b) {
    L.offset.push_back(o);
    mine[2 * b] = o;
    mine[2 * b + 1] = bodies[b]->mesh().node_start;
    o += 3 * bodies[b]->mesh().owned_nodes;
  }
  MPI_Allgather(mine.data(), static_cast<int>(2 * nb), MPIU_INT, all.data(),
                static_cast<int>(2 * nb), MPIU_INT, comm);
  for (std::size_t b = 0; b < nb; ++b) {
    const mesh::DistributedMesh &m = bodies[b]->mesh();
    std::vector<PetscInt> starts(static_cast<std::size_t>(size)), offs(starts.size());
    for (std::size_t r = 0; r < starts.size(); ++r) {
      offs[r] = all[2 * nb * r + 2 * b];
      starts[r] = all[2 * nb * r + 2 * b + 1];
    }
    std::vector<PetscInt> dof(static_cast<std::size_t>(m.local_nodes()));
    for (PetscInt l = 0; l < m.local_nodes(); ++l) {
      const PetscInt g = m.local_to_global(l);
      // The owner: the last rank whose first owned node is <= g (a rank owning no node has the
      // same first node as the next one, so the last of equal entries is the owner).
      const auto r = static_cast<std::size_t>(std::upper_bound(starts.begin(), starts.end(), g) -
                                              starts.begin() - 1);
      dof[static_cast<std::size_t>(l)] = offs[r] + 3 * (g - starts[r]);
    }
    Vec lx, lv;
    FX_PETSC(VecCreateSeq(PETSC_COMM_SELF, 3 * m.local_nodes(), &lx));
    FX_PETSC(VecDuplicate(lx, &lv));
    L.node_dof.push_back(std::move(dof));
    L.local_x.push_back(lx);
    L.local_v.push_back(lv);
  }
}

/// The ties of the interfaces' owned nodes `tied` in L's numbering.
std::vector<TieSet> tie_sets(const Bodies &bodies, const Mechanism *small,
                             const std::vector<AcfInterface> &interfaces,
                             const std::vector<std::vector<PetscInt>> &tied,
                             const detail::AcfLayout &L) {
  std::vector<TieSet> sets;
  PetscInt row = L.start + L.coords_local;
  for (std::size_t i = 0; i < interfaces.size(); ++i) {
    const AcfInterface &f = interfaces[i];
    const mesh::DistributedMesh &m = bodies[f.body]->mesh();
    TieSet t;
    t.row0 = row;
    t.coord0 = L.small_coord0 + (small ? small->offset(f.node_body) : 0);
    for (PetscInt l : tied[i]) {
      t.x_dof.push_back(L.offset[f.body] + 3 * l);
      t.s.emplace_back(Vec3(&m.coordinates[3 * static_cast<std::size_t>(l)]) - f.centroid);
    }
    row += 3 * static_cast<PetscInt>(t.s.size());
    sets.push_back(std::move(t));
  }
  return sets;
}

/// Touches the small part's pattern (rank 0): its coupled body blocks and its enforced rows and
/// their transposes.
void touch_small(Mat P, const Mechanism &mech, const detail::AcfLayout &L) {
  const int nbs = static_cast<int>(mech.bodies.size());
  std::vector<char> coupled(static_cast<std::size_t>(nbs * nbs), 0);
  for (int b = 0; b < nbs; ++b) coupled[static_cast<std::size_t>(b * nbs + b)] = 1;
  int r = 0, k = 0;
  for (const auto &e : mech.equations) {
    if (e.a >= 0 && e.b >= 0)
      coupled[static_cast<std::size_t>(e.a * nbs + e.b)] =
          coupled[static_cast<std::size_t>(e.b * nbs + e.a)] = 1;
    for (int i = 0; i < e.rows(); ++i, ++r) {
      if (!mech.enforced(r)) continue;
      const std::vector<PetscInt> one{L.small_row0 + k};
      for (int b : {e.a, e.b})
        if (b >= 0) {
          const auto cols = range(L.small_coord0 + mech.offset(b), mech.size(b));
          touch(P, one, cols);
          touch(P, cols, one);
        }
      ++k;
    }
  }
  for (int a = 0; a < nbs; ++a)
    for (int b = 0; b < nbs; ++b)
      if (coupled[static_cast<std::size_t>(a * nbs + b)])
        touch(P, range(L.small_coord0 + mech.offset(a), mech.size(a)),
              range(L.small_coord0 + mech.offset(b), mech.size(b)));
}

/// The Newton matrix's AIJ operator, preallocated and filled with explicit zeros on the
/// pattern: every element's full block (the mass and the tangent), the ties' rows, their
/// transposes and (p, p) blocks, and the small part's coupled body blocks and rows. Collective.
Mat preallocated_operator(const Bodies &bodies, const Mechanism *small, MPI_Comm comm,
                          const detail::AcfLayout &L) {
  const std::size_t nb = bodies.size();
  Mat P;
  FX_PETSC(MatCreate(comm, &P));
  FX_PETSC(MatSetSizes(P, L.local, L.local, L.global, L.global));
  FX_PETSC(MatSetType(P, MATPREALLOCATOR));
  FX_PETSC(MatSetUp(P));
  for (std::size_t b = 0; b < nb; ++b)
    fem::add_element_pattern(bodies[b]->mesh(), L.node_dof[b], P);
  for (const TieSet &t : L.ties) {
    const auto node = range(t.coord0, 7), p = range(t.coord0 + 3, 4);
    for (std::size_t j = 0; j < t.s.size(); ++j) {
      const auto rows = range(t.row0 + 3 * static_cast<PetscInt>(j), 3), x = range(t.x_dof[j], 3);
      touch(P, rows, x);
      touch(P, x, rows);
      touch(P, rows, node);
      touch(P, node, rows);
    }
    if (!t.s.empty()) touch(P, p, p);
  }
  if (small && comm_rank(comm) == 0) touch_small(P, *small, L);
  FX_PETSC(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  Mat A;
  FX_PETSC(MatCreate(comm, &A));
  FX_PETSC(MatSetSizes(A, L.local, L.local, L.global, L.global));
  FX_PETSC(MatSetType(A, MATAIJ));
  // Fill: A is assembled with explicit zeros on the pattern, so it can be duplicated.
  FX_PETSC(MatPreallocatorPreallocate(P, PETSC_TRUE, A));
  FX_PETSC(MatDestroy(&P));
  return A;
}

/// The scatters of every body's local-node positions from a vector like `like` into
/// L.local_x.
void make_gathers(Vec like, detail::AcfLayout &L) {
  for (std::size_t b = 0; b < L.node_dof.size(); ++b) {
    const auto &dof = L.node_dof[b];
    std::vector<PetscInt> idx(3 * dof.size());
    for (std::size_t l = 0; l < dof.size(); ++l)
      for (std::size_t k = 0; k < 3; ++k) idx[3 * l + k] = dof[l] + static_cast<PetscInt>(k);
    IS is;
    FX_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(idx.size()), idx.data(),
                             PETSC_COPY_VALUES, &is));
    VecScatter sc;
    FX_PETSC(VecScatterCreate(like, is, L.local_x[b], nullptr, &sc));
    FX_PETSC(ISDestroy(&is));
    L.gather.push_back(sc);
  }
}

} // namespace

DistState::DistState(const DistState &o)
    : t(o.t), q(copy_of(o.q)), v(copy_of(o.v)), a(copy_of(o.a)), acc(copy_of(o.acc)),
      lambda(copy_of(o.lambda)) {}

DistState &DistState::operator=(const DistState &o) {
  if (this == &o) return *this;
  t = o.t;
  assign(q, o.q);
  assign(v, o.v);
  assign(a, o.a);
  assign(acc, o.acc);
  assign(lambda, o.lambda);
  return *this;
}

DistState::~DistState() {
  VecDestroy(&q);
  VecDestroy(&v);
  VecDestroy(&a);
  VecDestroy(&acc);
  VecDestroy(&lambda);
}

DistributedAlpha::DistributedAlpha(std::vector<const bodies::AcfBody *> bodies,
                                   const Eigen::Vector3d &gravity, AlphaParameters parameters,
                                   NewtonSettings settings)
    : DistributedAlpha(std::move(bodies), nullptr, {}, gravity, parameters, settings) {}

DistributedAlpha::DistributedAlpha(std::vector<const bodies::AcfBody *> bodies,
                                   const Mechanism *small, std::vector<AcfInterface> interfaces,
                                   const Eigen::Vector3d &gravity, AlphaParameters parameters,
                                   NewtonSettings settings)
    : bodies_(std::move(bodies)), small_(small), interfaces_(std::move(interfaces)),
      layout_(std::make_unique<detail::AcfLayout>()), par_(parameters), settings_(settings) {
  if (bodies_.empty()) throw Error("DistributedAlpha: no ACF body");
  if (small_ && small_->bodies.empty()) small_ = nullptr;
  if (!interfaces_.empty() && !small_)
    throw Error("DistributedAlpha: ACF interfaces need the small mechanism of their nodes");
  comm_ = bodies_.front()->mesh().comm;
  const int size = comm_size(comm_), rank = comm_rank(comm_);
  detail::AcfLayout &L = *layout_;
  const std::size_t nb = bodies_.size();
  for (const auto *b : bodies_) L.acf_local += 3 * b->mesh().owned_nodes;
  if (small_ && rank == 0) {
    L.small_n = small_->coordinates();
    L.small_m = small_->constraints();
  }
  L.coords_local = L.acf_local + L.small_n;
  PetscInt ntie = 0;
  const std::vector<std::vector<PetscInt>> tied = tied_nodes(bodies_, interfaces_, comm_, ntie);
  number_unknowns(bodies_, ntie, comm_, L);
  L.ties = tie_sets(bodies_, small_, interfaces_, tied, L);
  A_ = preallocated_operator(bodies_, small_, comm_, L);
  FX_PETSC(MatDuplicate(A_, MAT_DO_NOT_COPY_VALUES, &M_));
  FX_PETSC(MatZeroEntries(M_));
  for (std::size_t b = 0; b < nb; ++b)
    fem::add_mass(bodies_[b]->mesh(), bodies_[b]->material().density, bodies_[b]->mass_factor(),
                  L.node_dof[b], M_);
  FX_PETSC(MatAssemblyBegin(M_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(M_, MAT_FINAL_ASSEMBLY));
  F_ = create_vector();
  make_gathers(F_, L);
  fg_ = create_vector();
  Vec G = create_vector();
  for (std::size_t b = 0; b < nb; ++b)
    set_nodal(G, b, [&](const Eigen::Vector3d &) { return gravity; });
  FX_PETSC(MatMult(M_, G, fg_));
  for (std::size_t b = 0; b < nb; ++b) mass_ += bodies_[b]->total_mass();
  FX_PETSC(VecDestroy(&G));
  cmask_ = create_vector();
  lmask_ = create_vector();
  {
    PetscScalar *c, *l;
    FX_PETSC(VecGetArray(cmask_, &c));
    FX_PETSC(VecGetArray(lmask_, &l));
    for (PetscInt i = 0; i < L.local; ++i) {
      c[i] = i < L.coords_local ? 1.0 : 0.0;
      l[i] = 1.0 - c[i];
    }
    FX_PETSC(VecRestoreArray(cmask_, &c));
    FX_PETSC(VecRestoreArray(lmask_, &l));
  }
  r_ = create_vector();
  dz_ = create_vector();
  kept_ = std::make_unique<KeptFrame>(dz_, nb);
  w_ = create_vector();
  // The operator is A_ itself: refilled in place, refactorized at the next solve after that.
  // MUMPS delays the pivots of the saddle point's zero diagonal (multipliers, massless
  // interface nodes) to later fronts, beyond its default workspace estimate (INFOG(1) = -9 on
  // 2 ranks for a Tet4 link with two interfaces): twice the estimate again by default.
  insert_default_petsc_options("-mech_mat_mumps_icntl_14 200",
                               "the distributed backend's default MUMPS workspace relaxation");
  ksp_ = create_direct_solver(A_, Factorization::LU, "mech_");
  // On one rank and for small systems KLU (SuiteSparse's LU for circuit-sized sparse matrices)
  // unless the options choose a solver: there its solves cost a fifth of MUMPS's, whose fixed
  // cost per call dominates; without BLAS its factorization falls behind MUMPS's already at a
  // 2.8k-DOF Tet10 beam (docs/benchmarks.md, "ACF steps").
  if (size == 1 && L.global <= kKluLimit) {
    PetscBool chosen = PETSC_FALSE;
    FX_PETSC(PetscOptionsHasName(nullptr, "mech_", "-pc_factor_mat_solver_type", &chosen));
    PC pc;
    FX_PETSC(KSPGetPC(ksp_, &pc));
    if (!chosen) FX_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERKLU));
  }
}

DistributedAlpha::~DistributedAlpha() {
  kept_.reset();
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
  MatDestroy(&M_);
  VecDestroy(&fg_);
  VecDestroy(&cmask_);
  VecDestroy(&lmask_);
  VecDestroy(&F_);
  VecDestroy(&r_);
  VecDestroy(&dz_);
  VecDestroy(&w_);
}

void DistributedAlpha::coordinate_mask(Vec out) const {
  FX_PETSC(VecCopy(cmask_, out));
}

PetscInt DistributedAlpha::global_size() const {
  return layout_->global;
}

Vec DistributedAlpha::create_vector() const {
  Vec v;
  FX_PETSC(VecCreateMPI(comm_, layout_->local, layout_->global, &v));
  FX_PETSC(VecZeroEntries(v));
  return v;
}

void DistributedAlpha::set_nodal(
    Vec v, std::size_t body,
    const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &field) const {
  const mesh::DistributedMesh &m = bodies_[body]->mesh();
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  const PetscInt base = layout_->offset[body] - layout_->start;
  for (PetscInt i = 0; i < m.owned_nodes; ++i) {
    const Eigen::Vector3d X(&m.coordinates[3 * static_cast<std::size_t>(i)]);
    const Eigen::Vector3d f = field(X);
    for (int k = 0; k < 3; ++k) a[base + 3 * i + k] = f(k);
  }
  FX_PETSC(VecRestoreArray(v, &a));
}

void DistributedAlpha::set_small(Vec v, const Vector &values) const {
  const detail::AcfLayout &L = *layout_;
  if (L.small_n == 0) return;
  if (values.size() != L.small_n) throw Error("DistributedAlpha::set_small: wrong size");
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  for (int k = 0; k < L.small_n; ++k) a[L.small_coord0 - L.start + k] = values(k);
  FX_PETSC(VecRestoreArray(v, &a));
}

State DistributedAlpha::small_state(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  State out;
  out.t = s.t;
  if (!small_) return out;
  const int n = small_->coordinates(), m = small_->constraints();
  Vector buf(4 * n + m);
  if (comm_rank(comm_) == 0) {
    Vec vecs[4] = {s.q, s.v, s.a, s.acc};
    for (int k = 0; k < 4; ++k) {
      const PetscScalar *x;
      FX_PETSC(VecGetArrayRead(vecs[k], &x));
      for (int i = 0; i < n; ++i) buf(k * n + i) = x[L.small_coord0 + i];
      FX_PETSC(VecRestoreArrayRead(vecs[k], &x));
    }
    const PetscScalar *l;
    FX_PETSC(VecGetArrayRead(s.lambda, &l));
    for (int i = 0; i < m; ++i) buf(4 * n + i) = l[L.small_row0 + i];
    FX_PETSC(VecRestoreArrayRead(s.lambda, &l));
  }
  MPI_Bcast(buf.data(), static_cast<int>(buf.size()), MPI_DOUBLE, 0, comm_);
  out.unpack(buf, n, m);
  return out;
}

std::vector<double> DistributedAlpha::owned_positions(const DistState &s, std::size_t body) const {
  return owned_values(s.q, body);
}

std::vector<double> DistributedAlpha::owned_values(Vec v, std::size_t body) const {
  const PetscInt n = 3 * bodies_[body]->mesh().owned_nodes;
  std::vector<double> x(static_cast<std::size_t>(n));
  const PetscScalar *a;
  FX_PETSC(VecGetArrayRead(v, &a));
  std::copy(a + (layout_->offset[body] - layout_->start),
            a + (layout_->offset[body] - layout_->start) + n, x.begin());
  FX_PETSC(VecRestoreArrayRead(v, &a));
  return x;
}

void DistributedAlpha::gather(Vec x, std::size_t b, Vec local) const {
  detail::AcfLayout &L = *layout_;
  if (!local) local = L.local_x[b];
  FX_PETSC(VecScatterBegin(L.gather[b], x, local, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecScatterEnd(L.gather[b], x, local, INSERT_VALUES, SCATTER_FORWARD));
}

Vec3 DistributedAlpha::point_position(const DistState &s, std::size_t body,
                                      const fem::PointLocation &p) const {
  gather(s.q, body);
  double x[3] = {0, 0, 0};
  if (comm_rank(comm_) == p.owner) {
    const mesh::DistributedMesh &m = bodies_[body]->mesh();
    const int npe = m.nodes_per_element();
    const PetscScalar *u;
    FX_PETSC(VecGetArrayRead(layout_->local_x[body], &u));
    for (int a = 0; a < npe; ++a) {
      const PetscInt l = m.connectivity[static_cast<std::size_t>(p.element * npe + a)];
      for (int k = 0; k < 3; ++k) x[k] += p.shape[static_cast<std::size_t>(a)] * u[3 * l + k];
    }
    FX_PETSC(VecRestoreArrayRead(layout_->local_x[body], &u));
  }
  MPI_Bcast(x, 3, MPI_DOUBLE, p.owner, comm_);
  return Vec3(x[0], x[1], x[2]);
}

DistState DistributedAlpha::zero_state() const {
  DistState s;
  s.q = create_vector();
  s.v = create_vector();
  s.a = create_vector();
  s.acc = create_vector();
  s.lambda = create_vector();
  return s;
}

void DistributedAlpha::local_values(Vec v, std::size_t body, std::vector<double> &out) const {
  detail::AcfLayout &L = *layout_;
  gather(v, body, L.local_v[body]);
  const PetscScalar *a;
  PetscInt n = 0;
  FX_PETSC(VecGetLocalSize(L.local_v[body], &n));
  FX_PETSC(VecGetArrayRead(L.local_v[body], &a));
  out.assign(a, a + n);
  FX_PETSC(VecRestoreArrayRead(L.local_v[body], &a));
}

void DistributedAlpha::add_local_values(Vec v, std::size_t body,
                                        const std::vector<double> &local) const {
  const auto &dof = layout_->node_dof[body];
  for (std::size_t l = 0; l < dof.size(); ++l) {
    const PetscInt idx[3] = {dof[l], dof[l] + 1, dof[l] + 2};
    FX_PETSC(VecSetValues(v, 3, idx, local.data() + 3 * l, ADD_VALUES));
  }
}

void DistributedAlpha::add_point_weights(Vec v, std::size_t body, const fem::PointLocation &p,
                                         const Vec3 &w) const {
  if (comm_rank(comm_) != p.owner) return;
  const mesh::DistributedMesh &m = bodies_[body]->mesh();
  const int npe = m.nodes_per_element();
  for (int a = 0; a < npe; ++a) {
    const PetscInt l = m.connectivity[static_cast<std::size_t>(p.element * npe + a)];
    const PetscInt d = layout_->node_dof[body][static_cast<std::size_t>(l)];
    const PetscInt idx[3] = {d, d + 1, d + 2};
    const double val[3] = {p.shape[static_cast<std::size_t>(a)] * w.x(),
                           p.shape[static_cast<std::size_t>(a)] * w.y(),
                           p.shape[static_cast<std::size_t>(a)] * w.z()};
    FX_PETSC(VecSetValues(v, 3, idx, val, ADD_VALUES));
  }
}

void DistributedAlpha::add_small(Vec v, const Vector &values) const {
  if (comm_rank(comm_) != 0 || !small_) return;
  const auto ic = range(layout_->small_coord0, layout_->small_n);
  FX_PETSC(VecSetValues(v, layout_->small_n, ic.data(), values.data(), ADD_VALUES));
}

double DistributedAlpha::kinetic_energy(const DistState &s) const {
  double acf;
  FX_PETSC(MatMult(M_, s.v, r_));
  FX_PETSC(VecDot(s.v, r_, &acf));
  double small = 0;
  if (small_) {
    const State sm = small_state(s);
    Vector r;
    Matrix M;
    const int n = small_->coordinates();
    small_->dynamics(sm.q, sm.v, Vector::Zero(n), s.t, r, nullptr, nullptr, &M);
    small = sm.v.dot(M * sm.v);
  }
  return 0.5 * (acf + small);
}

double DistributedAlpha::tie_violation(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  double violation = 0;
  if (small_) {
    const State sm = small_state(s);
    const PetscScalar *q;
    FX_PETSC(VecGetArrayRead(s.q, &q));
    for (std::size_t i = 0; i < L.ties.size(); ++i) {
      const TieSet &t = L.ties[i];
      const int o = small_->offset(interfaces_[i].node_body);
      const Vec3 r = sm.q.segment<3>(o);
      const bodies::Mat3 R = bodies::rotation(sm.q.segment<4>(o + 3));
      for (std::size_t j = 0; j < t.s.size(); ++j) {
        const Vec3 x(q[t.x_dof[j] - L.start], q[t.x_dof[j] - L.start + 1],
                     q[t.x_dof[j] - L.start + 2]);
        violation = std::max(violation, (x - r - R * t.s[j]).cwiseAbs().maxCoeff());
      }
    }
    FX_PETSC(VecRestoreArrayRead(s.q, &q));
  }
  double global;
  MPI_Allreduce(&violation, &global, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return global;
}

void DistributedAlpha::energies(const DistState &s, double &kinetic, double &elastic,
                                double &potential) const {
  FX_PETSC(MatMult(M_, s.v, r_));
  FX_PETSC(VecDot(s.v, r_, &kinetic));
  kinetic *= 0.5;
  elastic = internal(s.q, nullptr).energy;
  FX_PETSC(VecDot(fg_, s.q, &potential));
  potential = -potential;
}

double DistributedAlpha::damping_work(const DistState &a, const DistState &b) const {
  // dz_ = f_d(a) + f_d(b), each as the force with velocities less the force without.
  FX_PETSC(VecZeroEntries(dz_));
  for (const DistState *s : {&a, &b}) {
    internal(s->q, nullptr, s->v);
    FX_PETSC(VecAXPY(dz_, 1.0, F_));
    internal(s->q, nullptr);
    FX_PETSC(VecAXPY(dz_, -1.0, F_));
  }
  FX_PETSC(VecWAXPY(w_, -1.0, a.q, b.q));
  double work;
  FX_PETSC(VecDot(w_, dz_, &work));
  return 0.5 * work;
}

double DistributedAlpha::energy(const DistState &s) const {
  double k, e, p;
  energies(s, k, e, p);
  double total = k + e + p;
  if (small_) {
    const State sm = small_state(s);
    total += small_->energy(sm.q, sm.v);
  }
  return total;
}

void DistributedAlpha::momentum(const DistState &s, Eigen::Vector3d &linear,
                                Eigen::Vector3d &angular) const {
  FX_PETSC(MatMult(M_, s.v, r_));
  const PetscScalar *p, *x;
  FX_PETSC(VecGetArrayRead(r_, &p));
  FX_PETSC(VecGetArrayRead(s.q, &x));
  double sums[6] = {0, 0, 0, 0, 0, 0}, g[6];
  for (PetscInt i = 0; i < layout_->acf_local; i += 3) {
    const Eigen::Vector3d pa(p[i], p[i + 1], p[i + 2]), xa(x[i], x[i + 1], x[i + 2]);
    const Eigen::Vector3d l = xa.cross(pa);
    for (int k = 0; k < 3; ++k) sums[k] += pa(k), sums[3 + k] += l(k);
  }
  FX_PETSC(VecRestoreArrayRead(s.q, &x));
  FX_PETSC(VecRestoreArrayRead(r_, &p));
  MPI_Allreduce(sums, g, 6, MPI_DOUBLE, MPI_SUM, comm_);
  linear = Eigen::Vector3d(g[0], g[1], g[2]);
  angular = Eigen::Vector3d(g[3], g[4], g[5]);
}

Eigen::Vector3d DistributedAlpha::centre_of_mass(Vec x) const {
  FX_PETSC(MatMult(M_, x, r_));
  const PetscScalar *p;
  FX_PETSC(VecGetArrayRead(r_, &p));
  double sums[3] = {0, 0, 0}, g[3];
  for (PetscInt i = 0; i < layout_->acf_local; ++i) sums[i % 3] += p[i];
  FX_PETSC(VecRestoreArrayRead(r_, &p));
  MPI_Allreduce(sums, g, 3, MPI_DOUBLE, MPI_SUM, comm_);
  return Eigen::Vector3d(g[0], g[1], g[2]) / mass_;
}

} // namespace flexopt::dynamics
