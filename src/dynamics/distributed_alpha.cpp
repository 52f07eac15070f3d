#include "flexopt/dynamics/distributed_alpha.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/direct_solver.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/dynamics/newton_loop.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <utility>

namespace flexopt::dynamics {

namespace {

Vec copy_of(Vec v) {
  if (!v) return nullptr;
  Vec c;
  FX_PETSC(VecDuplicate(v, &c));
  FX_PETSC(VecCopy(v, c));
  return c;
}

/// Copies the values of `from` into `to`, creating `to` if it does not exist yet.
void assign(Vec &to, Vec from) {
  if (!from) {
    VecDestroy(&to);
    return;
  }
  if (!to) FX_PETSC(VecDuplicate(from, &to));
  FX_PETSC(VecCopy(from, to));
}

double max_abs(Vec v) {
  PetscReal n;
  FX_PETSC(VecNorm(v, NORM_INFINITY, &n));
  return n;
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

namespace detail {

/// The layout of the unknowns (see the header). Rank r's local block: [ACF coordinates
/// (acf_local) | small coordinates (rank 0: small_n) | tie multipliers | small multipliers (rank
/// 0: small_m)]; the coordinates are the first `coords_local` entries. Body b's owned node i has
/// the DOFs offset[b] + 3 i + (0, 1, 2); node_dof[b][l] is that first DOF for every local node l
/// (owned, then ghosts: from the owner's offset), and `gather[b]` scatters the positions of all
/// local nodes into `local_x[b]` (3 per local node). ties[i]: interface i's ties of the owned
/// nodes of its surface.
struct AcfLayout {
  PetscInt local = 0, start = 0, global = 0;
  PetscInt acf_local = 0, coords_local = 0;
  int small_n = 0, small_m = 0;              ///< the small part's coordinates and enforced rows
  PetscInt small_coord0 = 0, small_row0 = 0; ///< their first global numbers (every rank)
  std::vector<PetscInt> offset;
  std::vector<std::vector<PetscInt>> node_dof;
  std::vector<Vec> local_x, local_v; ///< positions, velocities of the local nodes
  std::vector<VecScatter> gather;
  std::vector<TieSet> ties;
  ~AcfLayout() {
    for (Vec &v : local_x) VecDestroy(&v);
    for (Vec &v : local_v) VecDestroy(&v);
    for (VecScatter &g : gather) VecScatterDestroy(&g);
  }
};

} // namespace detail

namespace {

/// Newton systems of at most this many unknowns use KLU on one rank (the constructor).
constexpr PetscInt kKluLimit = 2000;

/// Factorizes the KSP's operator (if it changed); false if the factorization failed (a zero
/// pivot, MUMPS out of workspace, a singular matrix for KLU). PCSetUp is called here, not left to
/// the next KSPSolve (KSPSetUp does not set the PC up again for a refilled operator), so that a
/// failure is seen here and -log_view shows the factorizations apart from the solves. KLU (one
/// rank only) reports a singular matrix as a PETSc error: on one rank that is returned as a
/// failure, not thrown; on more ranks an error still throws (and aborts every rank) rather than
/// leave the others waiting in a collective.
bool factorized(KSP ksp) {
  FX_PETSC(KSPSetUp(ksp));
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
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

/// Records the entries (rows x cols) in a MATPREALLOCATOR matrix.
void touch(Mat P, const std::vector<PetscInt> &rows, const std::vector<PetscInt> &cols) {
  std::vector<PetscScalar> zeros(rows.size() * cols.size(), 0.0);
  FX_PETSC(MatSetValues(P, static_cast<PetscInt>(rows.size()), rows.data(),
                        static_cast<PetscInt>(cols.size()), cols.data(), zeros.data(), ADD_VALUES));
}

} // namespace

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
  // The tied nodes: every owned node of each interface's surface; two interfaces of one body
  // must not share a node (its rows would repeat and the matrix would be singular).
  std::vector<std::vector<char>> used(nb);
  for (std::size_t b = 0; b < nb; ++b)
    used[b].assign(static_cast<std::size_t>(bodies_[b]->mesh().owned_nodes), 0);
  std::vector<std::vector<PetscInt>> tied(interfaces_.size());
  int shared = static_cast<int>(interfaces_.size()); // the first interface with a shared node
  PetscInt ntie = 0;
  for (std::size_t i = 0; i < interfaces_.size(); ++i) {
    const AcfInterface &f = interfaces_[i];
    if (f.body >= nb) throw Error("DistributedAlpha: interface of a missing body");
    const mesh::DistributedMesh &m = bodies_[f.body]->mesh();
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
  MPI_Allreduce(&shared, &first_shared, 1, MPI_INT, MPI_MIN, comm_);
  if (first_shared < static_cast<int>(interfaces_.size())) {
    const AcfInterface &f = interfaces_[static_cast<std::size_t>(first_shared)];
    throw Error(f.where + ": interface surface '" + f.surface +
                    "' shares nodes with another interface of the same ACF body; their rigid "
                    "ties would repeat. Give every interface its own surface.",
                true);
  }
  L.local = L.coords_local + ntie + L.small_m;
  MPI_Exscan(&L.local, &L.start, 1, MPIU_INT, MPI_SUM, comm_);
  if (rank == 0) L.start = 0;
  MPI_Allreduce(&L.local, &L.global, 1, MPIU_INT, MPI_SUM, comm_);
  PetscInt small0[2] = {L.acf_local, L.coords_local + ntie};
  MPI_Bcast(small0, 2, MPIU_INT, 0, comm_);
  L.small_coord0 = small0[0];
  L.small_row0 = small0[1];
  // Every rank's offset and first owned node of every body, for the ghosts' owners.
  std::vector<PetscInt> mine(2 * nb), all(2 * nb * static_cast<std::size_t>(size));
  PetscInt o = L.start;
  for (std::size_t b = 0; b < nb; ++b) {
    L.offset.push_back(o);
    mine[2 * b] = o;
    mine[2 * b + 1] = bodies_[b]->mesh().node_start;
    o += 3 * bodies_[b]->mesh().owned_nodes;
  }
  MPI_Allgather(mine.data(), static_cast<int>(2 * nb), MPIU_INT, all.data(),
                static_cast<int>(2 * nb), MPIU_INT, comm_);
  for (std::size_t b = 0; b < nb; ++b) {
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
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
  // The ties in this numbering.
  PetscInt row = L.start + L.coords_local;
  for (std::size_t i = 0; i < interfaces_.size(); ++i) {
    const AcfInterface &f = interfaces_[i];
    const mesh::DistributedMesh &m = bodies_[f.body]->mesh();
    TieSet t;
    t.row0 = row;
    t.coord0 = L.small_coord0 + (small_ ? small_->offset(f.node_body) : 0);
    for (PetscInt l : tied[i]) {
      t.x_dof.push_back(L.offset[f.body] + 3 * l);
      t.s.emplace_back(Vec3(&m.coordinates[3 * static_cast<std::size_t>(l)]) - f.centroid);
    }
    row += 3 * static_cast<PetscInt>(t.s.size());
    L.ties.push_back(std::move(t));
  }
  // The pattern: every element's full block (the mass and the tangent), the ties' rows, their
  // transposes and (p, p) blocks, and the small part's coupled body blocks and rows.
  Mat P;
  FX_PETSC(MatCreate(comm_, &P));
  FX_PETSC(MatSetSizes(P, L.local, L.local, L.global, L.global));
  FX_PETSC(MatSetType(P, MATPREALLOCATOR));
  FX_PETSC(MatSetUp(P));
  for (std::size_t b = 0; b < nb; ++b)
    fem::add_element_pattern(bodies_[b]->mesh(), L.node_dof[b], P);
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
  if (small_ && rank == 0) {
    const Mechanism &mech = *small_;
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
  FX_PETSC(MatAssemblyBegin(P, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(P, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatCreate(comm_, &A_));
  FX_PETSC(MatSetSizes(A_, L.local, L.local, L.global, L.global));
  FX_PETSC(MatSetType(A_, MATAIJ));
  // Fill: A is assembled with explicit zeros on the pattern, so it can be duplicated.
  FX_PETSC(MatPreallocatorPreallocate(P, PETSC_TRUE, A_));
  FX_PETSC(MatDuplicate(A_, MAT_DO_NOT_COPY_VALUES, &M_));
  FX_PETSC(MatDestroy(&P));
  FX_PETSC(MatZeroEntries(M_));
  for (std::size_t b = 0; b < nb; ++b)
    fem::add_mass(bodies_[b]->mesh(), bodies_[b]->material().density, bodies_[b]->mass_factor(),
                  L.node_dof[b], M_);
  FX_PETSC(MatAssemblyBegin(M_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(M_, MAT_FINAL_ASSEMBLY));
  // The scatters of every body's local-node positions.
  F_ = create_vector();
  for (std::size_t b = 0; b < nb; ++b) {
    const auto &dof = L.node_dof[b];
    std::vector<PetscInt> idx(3 * dof.size());
    for (std::size_t l = 0; l < dof.size(); ++l)
      for (std::size_t k = 0; k < 3; ++k) idx[3 * l + k] = dof[l] + static_cast<PetscInt>(k);
    IS is;
    FX_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(idx.size()), idx.data(),
                             PETSC_COPY_VALUES, &is));
    VecScatter sc;
    FX_PETSC(VecScatterCreate(F_, is, L.local_x[b], nullptr, &sc));
    FX_PETSC(ISDestroy(&is));
    L.gather.push_back(sc);
  }
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

struct DistributedAlpha::KeptFrame {
  Vec q = nullptr;                    ///< the positions at which the kept matrix was assembled
  bool rotated = false;               ///< rotation[b] is not the identity
  std::vector<bodies::Mat3> rotation; ///< of each ACF body since then (docs/theory.md 8.2)
  /// The same rotation acting on Euler parameters, p -> q p: L(q) = [q0, -qv^T; qv, q0 I + [qv]x]
  std::vector<Eigen::Matrix4d> quaternion;
  KeptFrame(Vec like, std::size_t bodies)
      : rotation(bodies, bodies::Mat3::Identity()),
        quaternion(bodies, Eigen::Matrix4d::Identity()) {
    FX_PETSC(VecDuplicate(like, &q));
    FX_PETSC(VecCopy(like, q));
  }
  KeptFrame(const KeptFrame &) = delete;
  KeptFrame &operator=(const KeptFrame &) = delete;
  ~KeptFrame() { VecDestroy(&q); }
  void reset(Vec at) {
    FX_PETSC(VecCopy(at, q));
    std::fill(rotation.begin(), rotation.end(), bodies::Mat3::Identity());
    std::fill(quaternion.begin(), quaternion.end(), Eigen::Matrix4d::Identity());
    rotated = false;
  }
};

void DistributedAlpha::kept_rotations(Vec q) const {
  const detail::AcfLayout &L = *layout_;
  KeptFrame &a = *kept_;
  const PetscScalar *x, *x0;
  FX_PETSC(VecGetArrayRead(q, &x));
  FX_PETSC(VecGetArrayRead(a.q, &x0));
  // Per body the centroids and the 3x3 sum of (x - c)(x0 - c0)^T = sum x x0^T - n c c0^T, from
  // sums of x, x0 and x x0^T over the owned nodes.
  const std::size_t nb = bodies_.size();
  std::vector<double> sums(nb * 16, 0.0), all(nb * 16);
  for (std::size_t b = 0; b < nb; ++b) {
    double *m = &sums[16 * b];
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
      const PetscScalar *xi = x + base + 3 * i, *yi = x0 + base + 3 * i;
      for (int r = 0; r < 3; ++r) {
        m[9 + r] += xi[r];
        m[12 + r] += yi[r];
        for (int c = 0; c < 3; ++c) m[3 * r + c] += xi[r] * yi[c];
      }
      m[15] += 1;
    }
  }
  FX_PETSC(VecRestoreArrayRead(q, &x));
  FX_PETSC(VecRestoreArrayRead(a.q, &x0));
  MPI_Allreduce(sums.data(), all.data(), static_cast<int>(sums.size()), MPI_DOUBLE, MPI_SUM, comm_);
  a.rotated = false;
  for (std::size_t b = 0; b < nb; ++b) {
    const double *m = &all[16 * b];
    const Vec3 c(m[9], m[10], m[11]), c0(m[12], m[13], m[14]);
    bodies::Mat3 H;
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) H(r, k) = m[3 * r + k];
    H -= c * c0.transpose() / m[15];
    // The rotation nearest to H (Kabsch): U V^T with the sign of det fixed.
    const Eigen::JacobiSVD<bodies::Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    bodies::Mat3 D = bodies::Mat3::Identity();
    D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
    a.rotation[b] = svd.matrixU() * D * svd.matrixV().transpose();
    const Eigen::Quaterniond qr(a.rotation[b]);
    const Vec3 qv(qr.x(), qr.y(), qr.z());
    Eigen::Matrix4d &Lq = a.quaternion[b];
    Lq(0, 0) = qr.w();
    Lq.block<1, 3>(0, 1) = -qv.transpose();
    Lq.block<3, 1>(1, 0) = qv;
    Lq.block<3, 3>(1, 1) = qr.w() * bodies::Mat3::Identity() + bodies::skew(qv);
    if (!a.rotation[b].isIdentity(0)) a.rotated = true;
  }
}

void DistributedAlpha::rotate_kept(Vec v, bool transpose) const {
  const detail::AcfLayout &L = *layout_;
  const KeptFrame &a = *kept_;
  PetscScalar *x;
  FX_PETSC(VecGetArray(v, &x));
  auto turn = [&](PetscScalar *y, const bodies::Mat3 &R) {
    const Vec3 w =
        transpose ? Vec3(R.transpose() * Vec3(y[0], y[1], y[2])) : Vec3(R * Vec3(y[0], y[1], y[2]));
    y[0] = w(0), y[1] = w(1), y[2] = w(2);
  };
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i)
      turn(x + base + 3 * i, a.rotation[b]);
  }
  for (std::size_t i = 0; i < L.ties.size(); ++i) {
    const TieSet &t = L.ties[i];
    const bodies::Mat3 &R = a.rotation[interfaces_[i].body];
    for (std::size_t j = 0; j < t.s.size(); ++j)
      turn(x + t.row0 - L.start + static_cast<PetscInt>(3 * j), R);
    // The interface node: r turns with R, the Euler parameters by the quaternion product
    // p -> q p (R(q p) = R(q) R(p)).
    const PetscInt o = L.small_coord0 + small_->offset(interfaces_[i].node_body);
    if (o >= L.start && o + 7 <= L.start + L.local) {
      turn(x + o - L.start, R);
      const Eigen::Matrix4d &Lq = a.quaternion[interfaces_[i].body];
      PetscScalar *y = x + o - L.start + 3;
      const Eigen::Vector4d w =
          transpose ? Eigen::Vector4d(Lq.transpose() * Eigen::Vector4d(y[0], y[1], y[2], y[3]))
                    : Eigen::Vector4d(Lq * Eigen::Vector4d(y[0], y[1], y[2], y[3]));
      for (int k = 0; k < 4; ++k) y[k] = w(k);
    }
  }
  FX_PETSC(VecRestoreArray(v, &x));
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

fem::CorotatedSum DistributedAlpha::internal(Vec x, Mat T, Vec v, double gp) const {
  detail::AcfLayout &L = *layout_;
  FX_PETSC(VecZeroEntries(F_));
  if (T) FX_PETSC(MatZeroEntries(T));
  double energy = 0;
  std::string failure;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
    gather(x, b);
    PetscScalar *u;
    FX_PETSC(VecGetArray(L.local_x[b], &u));
    for (PetscInt l = 0; l < 3 * m.local_nodes(); ++l)
      u[l] -= m.coordinates[static_cast<std::size_t>(l)];
    fem::CorotatedDamping damping;
    const bool damped = v && bodies_[b]->damping() > 0;
    if (damped) {
      gather(v, b, L.local_v[b]);
      FX_PETSC(VecGetArrayRead(L.local_v[b], &damping.v));
      damping.beta = bodies_[b]->damping();
      damping.gp = gp;
    }
    energy += fem::add_corotated(m, bodies_[b]->elements(), u, L.node_dof[b], F_, T, failure,
                                 damped ? &damping : nullptr);
    if (damped) FX_PETSC(VecRestoreArrayRead(L.local_v[b], &damping.v));
    FX_PETSC(VecRestoreArray(L.local_x[b], &u));
  }
  FX_PETSC(VecAssemblyBegin(F_));
  FX_PETSC(VecAssemblyEnd(F_));
  if (T) {
    FX_PETSC(MatAssemblyBegin(T, MAT_FINAL_ASSEMBLY));
    FX_PETSC(MatAssemblyEnd(T, MAT_FINAL_ASSEMBLY));
  }
  return fem::reduce_corotated(comm_, energy, failure);
}

double DistributedAlpha::add_all_ties(const DistState &s, const State &small, bool multipliers,
                                      double bp, Mat A, Vec rhs) const {
  const detail::AcfLayout &L = *layout_;
  const PetscScalar *q, *l = nullptr;
  FX_PETSC(VecGetArrayRead(s.q, &q));
  if (multipliers) FX_PETSC(VecGetArrayRead(s.lambda, &l));
  double violation = 0;
  std::vector<double> x, lambda;
  for (std::size_t i = 0; i < L.ties.size(); ++i) {
    const TieSet &t = L.ties[i];
    if (t.s.empty()) continue;
    // The tied nodes and their rows are owned: their values are in the local arrays.
    x.resize(3 * t.s.size());
    lambda.assign(3 * t.s.size(), 0.0);
    for (std::size_t j = 0; j < t.s.size(); ++j)
      for (std::size_t k = 0; k < 3; ++k) {
        x[3 * j + k] = q[t.x_dof[j] - L.start + static_cast<PetscInt>(k)];
        if (l) lambda[3 * j + k] = l[t.row0 - L.start + static_cast<PetscInt>(3 * j + k)];
      }
    const int o = small_->offset(interfaces_[i].node_body);
    violation = std::max(violation, add_ties(t, x.data(), small.q.segment<3>(o),
                                             small.q.segment<4>(o + 3), lambda.data(), bp, A, rhs));
  }
  FX_PETSC(VecRestoreArrayRead(s.q, &q));
  if (l) FX_PETSC(VecRestoreArrayRead(s.lambda, &l));
  return violation;
}

double DistributedAlpha::add_constraints(const DistState &next, double bp, double gp,
                                         bool matrix) const {
  const detail::AcfLayout &L = *layout_;
  double violation = 0;
  if (small_) {
    const State sm = small_state(next);
    violation = add_all_ties(next, sm, true, bp, matrix ? A_ : nullptr, r_);
    if (comm_rank(comm_) == 0) {
      Vector rhs;
      if (matrix)
        add_newton_system(*small_, sm, bp, gp, A_, L.small_coord0, L.small_row0, rhs);
      else
        newton_system_rhs(*small_, sm, bp, rhs);
      const int n = L.small_n, m = L.small_m;
      const auto ic = range(L.small_coord0, n), ir = range(L.small_row0, m);
      FX_PETSC(VecSetValues(r_, n, ic.data(), rhs.data(), ADD_VALUES));
      FX_PETSC(VecSetValues(r_, m, ir.data(), rhs.data() + n, ADD_VALUES));
      if (m > 0) violation = std::max(violation, rhs.tail(m).cwiseAbs().maxCoeff());
    }
  }
  FX_PETSC(VecAssemblyBegin(r_));
  FX_PETSC(VecAssemblyEnd(r_));
  if (matrix) {
    FX_PETSC(MatAssemblyBegin(A_, MAT_FINAL_ASSEMBLY));
    FX_PETSC(MatAssemblyEnd(A_, MAT_FINAL_ASSEMBLY));
  }
  double global;
  MPI_Allreduce(&violation, &global, 1, MPI_DOUBLE, MPI_MAX, comm_);
  return global;
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

Mat DistributedAlpha::acceleration_matrix(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  // The matrix [M Phi_q^T; Phi_q 0] (ties with zero multipliers: no Hessian).
  factored_ = false;
  FX_PETSC(MatZeroEntries(A_));
  FX_PETSC(MatAXPY(A_, 1.0, M_, SAME_NONZERO_PATTERN));
  const State sm = small_state(s);
  if (small_) add_all_ties(s, sm, false, 1.0, A_, w_); // w_: the ties' right-hand side, unused
  if (comm_rank(comm_) == 0 && small_)
    add_mass_system(*small_, sm, A_, L.small_coord0, L.small_row0);
  FX_PETSC(VecAssemblyBegin(w_));
  FX_PETSC(VecAssemblyEnd(w_));
  FX_PETSC(MatAssemblyBegin(A_, MAT_FINAL_ASSEMBLY));
  FX_PETSC(MatAssemblyEnd(A_, MAT_FINAL_ASSEMBLY));
  return A_;
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

DistState DistributedAlpha::initial_state(Vec q0, Vec v0, double t0, StartReport *report,
                                          DistStartTrace *trace) const {
  const detail::AcfLayout &L = *layout_;
  const bool root = comm_rank(comm_) == 0;
  DistState s;
  s.t = t0;
  s.q = copy_of(q0);
  s.v = copy_of(v0);
  FX_PETSC(VecPointwiseMult(s.q, s.q, cmask_)); // no values on the multiplier entries
  FX_PETSC(VecPointwiseMult(s.v, s.v, cmask_));
  s.acc = create_vector();
  s.a = create_vector();
  s.lambda = create_vector();
  const fem::CorotatedSum sum = internal(s.q, nullptr);
  if (!sum.ok) throw Error("initial state: " + sum.failure, true);
  // Positions: every constraint must hold (the ties do by construction of the placement).
  const double scale = 1 + max_abs(s.q);
  State sm = small_state(s);
  {
    const double ties = tie_violation(s);
    std::string bad;
    int nbad = 0;
    auto sci = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.3e", v);
      return std::string(buf);
    };
    if (ties > 1e-9 * scale)
      bad += "\n  the ties of the ACF interfaces: residual " + sci(ties), ++nbad;
    if (small_) {
      Vector all;
      small_->all_constraint_values(sm.q, t0, all);
      for (int r = 0; r < all.size(); ++r)
        if (!(std::abs(all(r)) <= 1e-9 * scale) && nbad++ < 6)
          bad += "\n  " + small_->describe_row(r) + ": residual " + sci(all(r));
    }
    if (nbad > 0)
      throw Error("initial conditions: a scene with ACF bodies must be placed assembled (its "
                  "joints closed to 1e-9 of the scene's size; positions are not projected); "
                  "these constraints are violated:" +
                      bad +
                      "\n(an interface's point is the centroid of its meshed surface placed with "
                      "the body; gaps below 1e-4 of the scene's size count as meeting, larger ones "
                      "are not closed in a scene with ACF bodies: place the bodies assembled, or "
                      "give the body with an initial elastic field the field that closes them; "
                      "docs/case-format.md \"joints\")",
                  true);
  }
  acceleration_matrix(s);
  if (!factorized(ksp_))
    throw Error("initial conditions: the acceleration system [M Phi_q^T; Phi_q 0] is singular "
                "(a body without mass, an interface node held by nothing, or joints that "
                "leave no consistent acceleration)",
                true);
  auto solve = [&](const char *what) {
    FX_PETSC(KSPSolve(ksp_, r_, dz_));
    KSPConvergedReason reason;
    FX_PETSC(KSPGetConvergedReason(ksp_, &reason));
    if (reason < 0 || !std::isfinite(max_abs(dz_)))
      throw Error(std::string("initial conditions: the solve for the ") + what + " failed (" +
                      KSPConvergedReasons[reason] + ")",
                  true);
  };
  // Velocities: the rigid-body velocities corrected onto Phi_q v + Phi_t = 0 with the least
  // change of kinetic energy, the elastic ones kept (section 6.4).
  StartReport rep;
  rep.kinetic_given = kinetic_energy(s);
  const double given = velocity_violation(s, sm);
  rep.given_violation = given;
  if (small_) {
    const std::vector<RigidField> fields = rigid_fields(s);
    const VelocityCorrection c = rigid_velocity_correction(*small_, sm.q, sm.v, t0, fields);
    if (trace) {
      trace->rigid = c;
      trace->fields = fields;
    }
    if (root) {
      PetscScalar *v;
      FX_PETSC(VecGetArray(s.v, &v));
      for (int k = 0; k < L.small_n; ++k) v[L.small_coord0 - L.start + k] += c.dv(k);
      FX_PETSC(VecRestoreArray(s.v, &v));
    }
    for (std::size_t b = 0; b < bodies_.size(); ++b)
      add_rigid_field(s, b, c.field[b], fields[b].centre, s.v);
    sm = small_state(s);
  }
  rep.rigid_residual = velocity_violation(s, sm);
  if (rep.rigid_residual > kVelocityTolerance * (1 + given)) {
    // The joints (or ties holding a surface that the given elastic velocities deform) need
    // elastic velocities: the smallest change in kinetic energy of all velocities,
    // S [dv; mu] = [0; -(Phi_q v + Phi_t)] (massless interface nodes change freely).
    solve("velocity projection");
    FX_PETSC(VecPointwiseMult(w_, dz_, cmask_));
    FX_PETSC(VecAXPY(s.v, 1.0, w_));
    sm = small_state(s);
    rep.elastic_corrected = true;
    if (trace) {
      FX_PETSC(VecDestroy(&trace->fallback));
      trace->fallback = copy_of(w_);
    }
  }
  rep.kinetic = kinetic_energy(s);
  if (report) *report = rep;
  // Accelerations and multipliers: [M Phi_q^T; Phi_q 0] [acc; lambda] = [Q; gamma].
  start_rhs(s, r_);
  solve("initial accelerations");
  FX_PETSC(VecPointwiseMult(s.acc, dz_, cmask_));
  FX_PETSC(VecPointwiseMult(s.lambda, dz_, lmask_));
  FX_PETSC(VecCopy(s.acc, s.a));
  return s;
}

void DistributedAlpha::add_rigid_field(const DistState &s, std::size_t b, const Vector6 &p,
                                       const Vec3 &centre, Vec v) const {
  const detail::AcfLayout &L = *layout_;
  const Vec3 du = p.head<3>(), dw = p.tail<3>();
  const PetscInt base = L.offset[b] - L.start;
  PetscScalar *va;
  const PetscScalar *x;
  FX_PETSC(VecGetArray(v, &va));
  FX_PETSC(VecGetArrayRead(s.q, &x));
  for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
    const Vec3 d =
        du + dw.cross(Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - centre);
    for (int k = 0; k < 3; ++k) va[base + 3 * i + k] += d(k);
  }
  FX_PETSC(VecRestoreArrayRead(s.q, &x));
  FX_PETSC(VecRestoreArray(v, &va));
}

Vector DistributedAlpha::small_values(Vec v) const {
  const detail::AcfLayout &L = *layout_;
  const int n = small_ ? small_->coordinates() : 0;
  Vector out(n);
  if (comm_rank(comm_) == 0 && n > 0) {
    const PetscScalar *a;
    FX_PETSC(VecGetArrayRead(v, &a));
    for (int i = 0; i < n; ++i) out(i) = a[L.small_coord0 - L.start + i];
    FX_PETSC(VecRestoreArrayRead(v, &a));
  }
  MPI_Bcast(out.data(), n, MPI_DOUBLE, 0, comm_);
  return out;
}

void DistributedAlpha::start_rhs(const DistState &s, Vec r) const {
  const detail::AcfLayout &L = *layout_;
  const bool root = comm_rank(comm_) == 0;
  const State sm = small_state(s);
  const double t0 = s.t;
  Vector phi_t, phi_tt, phi_qt_v;
  internal(s.q, nullptr, s.v);          // the damping force at the velocities of s
  FX_PETSC(VecWAXPY(r, -1.0, F_, fg_)); // f_g - f(x) - f_d(x, v) on the ACF rows, 0 elsewhere
  {
    PetscScalar *ra;
    FX_PETSC(VecGetArray(r, &ra));
    std::vector<double> gamma;
    for (std::size_t i = 0; i < L.ties.size(); ++i) {
      const TieSet &t = L.ties[i];
      gamma.resize(3 * t.s.size());
      const int o = small_ ? small_->offset(interfaces_[i].node_body) : 0;
      if (!t.s.empty()) tie_accelerations(t, sm.v.segment<4>(o + 3), gamma.data());
      for (std::size_t k = 0; k < gamma.size(); ++k)
        ra[t.row0 - L.start + static_cast<PetscInt>(k)] = gamma[k];
    }
    if (root && small_) {
      const int n = L.small_n, m = L.small_m;
      Vector r0;
      small_->dynamics(sm.q, sm.v, Vector::Zero(n), t0, r0, nullptr, nullptr, nullptr);
      small_->constraint_time_terms(sm.q, sm.v, t0, phi_t, phi_tt, phi_qt_v);
      const Vector gamma_s = -small_->constraint_convective(sm.q, sm.v, t0) - 2 * phi_qt_v - phi_tt;
      for (int k = 0; k < n; ++k) ra[L.small_coord0 + k] = -r0(k);
      for (int k = 0; k < m; ++k) ra[L.small_row0 + k] = gamma_s(k);
    }
    FX_PETSC(VecRestoreArray(r, &ra));
  }
}

void DistributedAlpha::start_velocity_transpose(const DistState &s0, Vec nu, Vec gv) const {
  const detail::AcfLayout &L = *layout_;
  // Q = f_g - f - f_d(x, v) on the ACF rows and -r(q, v, 0) on the small part's: -C^T nu.
  FX_PETSC(VecPointwiseMult(w_, nu, cmask_));
  velocity_transpose_multiply(s0, w_, dz_);
  FX_PETSC(VecAXPY(gv, -1.0, dz_));
  if (!small_) return;
  const State sm = small_state(s0);
  const int n = small_->coordinates(), m = small_->constraints(); // on every rank
  // The ties: gamma_j = D(p', s_j) p' (3 rows per tied node), d gamma_j / dp' = 2 D(p', s_j);
  // each rank sums over its tied nodes, rank 0 adds the total to the interface nodes' rates.
  Vector local = Vector::Zero(n), total(n);
  {
    const PetscScalar *l;
    FX_PETSC(VecGetArrayRead(nu, &l));
    for (std::size_t i = 0; i < L.ties.size(); ++i) {
      const TieSet &t = L.ties[i];
      const int o = small_->offset(interfaces_[i].node_body);
      const bodies::Vec4 pd = sm.v.segment<4>(o + 3);
      for (std::size_t j = 0; j < t.s.size(); ++j) {
        const PetscInt row = t.row0 - L.start + 3 * static_cast<PetscInt>(j);
        const Vec3 w(l[row], l[row + 1], l[row + 2]);
        local.segment<4>(o + 3) += 2 * bodies::rotate_jacobian(pd, t.s[j]).transpose() * w;
      }
    }
    FX_PETSC(VecRestoreArrayRead(nu, &l));
  }
  MPI_Allreduce(local.data(), total.data(), n, MPI_DOUBLE, MPI_SUM, comm_);
  if (comm_rank(comm_) == 0 && m > 0) {
    // The small part's gamma = -(Phi_q v)_q v - 2 Phi_qt v - Phi_tt: gamma_v^T nu_c =
    // -2 (sum_i nu_c,i H_i) v - 2 Phi_qt^T nu_c, Phi_qt column by column from v -> Phi_qt v.
    Vector nc(m);
    const PetscScalar *l;
    FX_PETSC(VecGetArrayRead(nu, &l));
    for (int k = 0; k < m; ++k) nc(k) = l[L.small_row0 - L.start + k];
    FX_PETSC(VecRestoreArrayRead(nu, &l));
    Matrix H = Matrix::Zero(n, n);
    small_->add_constraint_hessian(sm.q, s0.t, nc, H);
    total -= 2 * H * sm.v;
    Vector phi_t, phi_tt, phi_qt_v;
    for (int j = 0; j < n; ++j) {
      small_->constraint_time_terms(sm.q, Vector::Unit(n, j), s0.t, phi_t, phi_tt, phi_qt_v);
      total(j) -= 2 * phi_qt_v.dot(nc);
    }
  }
  // gv += gamma_v^T nu (the constraint rows' right-hand side is +gamma).
  if (comm_rank(comm_) == 0) {
    PetscScalar *g;
    FX_PETSC(VecGetArray(gv, &g));
    for (int k = 0; k < n; ++k) g[L.small_coord0 - L.start + k] += total(k);
    FX_PETSC(VecRestoreArray(gv, &g));
  }
}

Vector DistributedAlpha::rigid_parameters_transpose(const DistState &s0,
                                                    const DistStartTrace &trace, Vec g) const {
  const detail::AcfLayout &L = *layout_;
  const auto k = trace.rigid.T.cols();
  const Eigen::Index field0 = k - 6 * static_cast<Eigen::Index>(trace.fields.size());
  Vector local = Vector::Zero(k), out(k);
  const PetscScalar *ga, *x;
  FX_PETSC(VecGetArrayRead(g, &ga));
  FX_PETSC(VecGetArrayRead(s0.q, &x));
  if (comm_rank(comm_) == 0 && small_)
    for (int i = 0; i < L.small_n; ++i)
      local += ga[L.small_coord0 - L.start + i] * trace.rigid.T.row(i).transpose();
  for (std::size_t b = 0; b < trace.fields.size(); ++b) {
    const PetscInt base = L.offset[b] - L.start;
    for (PetscInt i = 0; i < bodies_[b]->mesh().owned_nodes; ++i) {
      const Vec3 gi(ga[base + 3 * i], ga[base + 3 * i + 1], ga[base + 3 * i + 2]);
      const Vec3 arm =
          Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - trace.fields[b].centre;
      local.segment<3>(field0 + 6 * static_cast<Eigen::Index>(b)) += gi;
      local.segment<3>(field0 + 6 * static_cast<Eigen::Index>(b) + 3) += arm.cross(gi);
    }
  }
  FX_PETSC(VecRestoreArrayRead(s0.q, &x));
  FX_PETSC(VecRestoreArrayRead(g, &ga));
  MPI_Allreduce(local.data(), out.data(), static_cast<int>(k), MPI_DOUBLE, MPI_SUM, comm_);
  return out;
}

double DistributedAlpha::velocity_violation(const DistState &s, const State &small) const {
  const detail::AcfLayout &L = *layout_;
  FX_PETSC(MatMult(A_, s.v, w_)); // multiplier rows: Phi_q v
  FX_PETSC(VecPointwiseMult(r_, w_, lmask_));
  FX_PETSC(VecScale(r_, -1.0));
  if (comm_rank(comm_) == 0 && small_) {
    Vector phi_t, phi_tt, phi_qt_v;
    small_->constraint_time_terms(small.q, small.v, small.t, phi_t, phi_tt, phi_qt_v);
    const Vector m_phi_t = -phi_t;
    const auto ir = range(L.small_row0, L.small_m);
    FX_PETSC(VecSetValues(r_, L.small_m, ir.data(), m_phi_t.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(r_));
  FX_PETSC(VecAssemblyEnd(r_));
  return max_abs(r_);
}

std::vector<RigidField> DistributedAlpha::rigid_fields(const DistState &s) const {
  const detail::AcfLayout &L = *layout_;
  std::vector<RigidField> fields(bodies_.size());
  const PetscScalar *x;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    RigidField &f = fields[b];
    for (const AcfInterface &i : interfaces_)
      if (i.body == b) f.nodes.push_back(i.node_body);
    const PetscInt base = L.offset[b] - L.start, nodes = bodies_[b]->mesh().owned_nodes;
    double sum[4] = {0, 0, 0, static_cast<double>(nodes)}, all[4];
    FX_PETSC(VecGetArrayRead(s.q, &x));
    for (PetscInt i = 0; i < nodes; ++i)
      for (int k = 0; k < 3; ++k) sum[k] += x[base + 3 * i + k];
    FX_PETSC(VecRestoreArrayRead(s.q, &x));
    MPI_Allreduce(sum, all, 4, MPI_DOUBLE, MPI_SUM, comm_);
    f.centre = Vec3(all[0], all[1], all[2]) / all[3];
    // V: unit translations and unit spins about the centre on body b's nodes; metric V^T M V.
    std::array<Vec, 6> V{}, MV{};
    FX_PETSC(VecGetArrayRead(s.q, &x));
    std::vector<Vec3> arm(static_cast<std::size_t>(nodes));
    for (PetscInt i = 0; i < nodes; ++i)
      arm[static_cast<std::size_t>(i)] =
          Vec3(x[base + 3 * i], x[base + 3 * i + 1], x[base + 3 * i + 2]) - f.centre;
    FX_PETSC(VecRestoreArrayRead(s.q, &x));
    for (int c = 0; c < 6; ++c) {
      V[static_cast<std::size_t>(c)] = create_vector();
      MV[static_cast<std::size_t>(c)] = create_vector();
      PetscScalar *a;
      FX_PETSC(VecGetArray(V[static_cast<std::size_t>(c)], &a));
      for (PetscInt i = 0; i < nodes; ++i) {
        const Vec3 d = c < 3 ? Vec3(Vec3::Unit(c))
                             : Vec3(Vec3::Unit(c - 3).cross(arm[static_cast<std::size_t>(i)]));
        for (int k = 0; k < 3; ++k) a[base + 3 * i + k] = d(k);
      }
      FX_PETSC(VecRestoreArray(V[static_cast<std::size_t>(c)], &a));
      FX_PETSC(MatMult(M_, V[static_cast<std::size_t>(c)], MV[static_cast<std::size_t>(c)]));
    }
    for (int c = 0; c < 6; ++c) {
      PetscScalar dots[6];
      FX_PETSC(VecMDot(V[static_cast<std::size_t>(c)], 6, MV.data(), dots));
      for (int d = 0; d < 6; ++d) f.metric(c, d) = dots[d];
    }
    f.metric = 0.5 * (f.metric + f.metric.transpose()).eval();
    for (int c = 0; c < 6; ++c) {
      FX_PETSC(VecDestroy(&V[static_cast<std::size_t>(c)]));
      FX_PETSC(VecDestroy(&MV[static_cast<std::size_t>(c)]));
    }
  }
  return fields;
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

bool DistributedAlpha::assemble(const DistState &next, const NewtonScaling &k, bool matrix,
                                double &violation) const {
  LogScope log(matrix ? "FxNewtonMatrix" : "FxNewtonRhs"); // the element loops included
  // An inverted element fails the evaluation.
  if (!internal(next.q, matrix ? A_ : nullptr, next.v, k.gp).ok) return false;
  if (matrix) {
    // A = M + (T + df_d/dx + gamma' df_d/dv) / beta' on the ACF bodies; M_ has A_'s stored
    // pattern.
    FX_PETSC(MatScale(A_, 1.0 / k.bp));
    FX_PETSC(MatAXPY(A_, 1.0, M_, SAME_NONZERO_PATTERN));
  }
  // r = -(M acc + f(q) + f_d(q, v) - f_g) / beta' on the ACF rows (0 elsewhere), then the
  // constraints.
  FX_PETSC(MatMult(M_, next.acc, r_));
  FX_PETSC(VecAXPY(r_, 1.0, F_));
  FX_PETSC(VecAXPY(r_, -1.0, fg_));
  FX_PETSC(VecScale(r_, -1.0 / k.bp));
  violation = add_constraints(next, k.bp, k.gp, matrix);
  return true;
}

void DistributedAlpha::equations(const DistState &s, Vec R) const {
  double violation;
  NewtonScaling unit;
  unit.bp = 1;
  if (!assemble(s, unit, false, violation))
    throw Error("DistributedAlpha::equations: an inverted element", true);
  FX_PETSC(VecAXPBY(R, -1.0, 0.0, r_));
}

Mat DistributedAlpha::newton_matrix(const DistState &s, double h) const {
  double violation;
  factored_ = false;
  if (!assemble(s, par_.newton_scaling(h), true, violation))
    throw Error("DistributedAlpha::newton_matrix: an inverted element", true);
  return A_;
}

void DistributedAlpha::solve_transpose(Vec rhs, Vec z) const {
  factored_ = false; // the factorization below is not a kept Newton matrix of the forward run
  if (!factorized(ksp_))
    throw Error("adjoint: the transposed Newton matrix of a step is singular", true);
  FX_PETSC(KSPSolveTranspose(ksp_, rhs, z));
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(ksp_, &reason));
  if (reason < 0 || !std::isfinite(max_abs(z)))
    throw Error("adjoint: the transposed solve of a step failed (" +
                    std::string(KSPConvergedReasons[reason]) + ")",
                true);
}

void DistributedAlpha::velocity_transpose_multiply(const DistState &s, Vec x, Vec y) const {
  detail::AcfLayout &L = *layout_;
  FX_PETSC(VecZeroEntries(y));
  std::vector<double> xl, vl, pos;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const double beta = bodies_[b]->damping();
    if (!(beta > 0)) continue;
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
    local_values(x, b, xl);
    local_values(s.v, b, vl);
    local_values(s.q, b, pos);
    fem::ElementMatrix Cv;
    std::vector<double> out(xl.size(), 0.0);
    const int npe = m.nodes_per_element();
    for (PetscInt e = 0; e < m.local_elements(); ++e) {
      const fem::CorotatedElement &ce = bodies_[b]->elements()[static_cast<std::size_t>(e)];
      fem::ElementCoords xe(npe, 3);
      for (int a = 0; a < npe; ++a) {
        const PetscInt l = m.connectivity[static_cast<std::size_t>(e * npe + a)];
        for (int k = 0; k < 3; ++k) xe(a, k) = pos[static_cast<std::size_t>(3 * l + k)];
      }
      fem::corotated_damping(ce, xe, fem::gather_element(m, e, vl.data()), beta, nullptr, &Cv,
                             nullptr);
      const fem::ElementVector ye = Cv.transpose() * fem::gather_element(m, e, xl.data());
      for (int a = 0; a < npe; ++a) {
        const PetscInt l = m.connectivity[static_cast<std::size_t>(e * npe + a)];
        for (int k = 0; k < 3; ++k) out[static_cast<std::size_t>(3 * l + k)] += ye(3 * a + k);
      }
    }
    add_local_values(y, b, out);
  }
  if (small_) {
    const State sm = small_state(s);
    if (comm_rank(comm_) == 0) {
      const int n = L.small_n;
      Vector r, xs(n);
      Matrix C;
      small_->dynamics(sm.q, sm.v, sm.acc, sm.t, r, nullptr, &C, nullptr);
      const PetscScalar *xa;
      FX_PETSC(VecGetArrayRead(x, &xa));
      for (int i = 0; i < n; ++i) xs(i) = xa[L.small_coord0 + i];
      FX_PETSC(VecRestoreArrayRead(x, &xa));
      add_small(y, C.transpose() * xs);
    }
  }
  FX_PETSC(VecAssemblyBegin(y));
  FX_PETSC(VecAssemblyEnd(y));
}

void DistributedAlpha::mass_multiply(const DistState &s, Vec x, Vec y) const {
  const detail::AcfLayout &L = *layout_;
  FX_PETSC(MatMult(M_, x, y)); // the ACF rows (M_ is zero elsewhere)
  if (!small_) return;
  const State sm = small_state(s);
  if (comm_rank(comm_) == 0) {
    const int n = L.small_n;
    Vector r, xs(n);
    Matrix Ms;
    small_->dynamics(sm.q, sm.v, Vector::Zero(n), sm.t, r, nullptr, nullptr, &Ms);
    const PetscScalar *xa;
    FX_PETSC(VecGetArrayRead(x, &xa));
    for (int i = 0; i < n; ++i) xs(i) = xa[L.small_coord0 + i];
    FX_PETSC(VecRestoreArrayRead(x, &xa));
    const Vector ys = Ms * xs;
    const auto ic = range(L.small_coord0, n);
    FX_PETSC(VecSetValues(y, n, ic.data(), ys.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(y));
  FX_PETSC(VecAssemblyEnd(y));
}

bool DistributedAlpha::step_once(const DistState &s, double h, DistState &next,
                                 StepInfo &info) const {
  if (!next.q) next = s; // vectors of the right layout
  struct Backend {
    const DistributedAlpha &da;
    const DistState &s;
    DistState &next;
    double h;
    double violation = 0; ///< max |Phi| at the last right-hand side
    void predict() {      // acc1 = acc0, lambda1 = lambda0
      predict_state();
      // A kept matrix is applied in the bodies' present orientation (co-rotated kept matrix).
      if (da.factored_ && da.settings_.corotate_kept) da.kept_rotations(next.q);
    }
    void predict_state() {
      const double am = da.par_.alpha_m, g = da.par_.gamma, b = da.par_.beta;
      next.t = s.t + h;
      FX_PETSC(VecCopy(s.acc, next.acc));
      FX_PETSC(VecCopy(s.lambda, next.lambda));
      // a1 = (af acc0 - am a0 + (1 - af) acc1) / (1 - am) = (acc0 - am a0) / (1 - am)
      FX_PETSC(VecAXPBYPCZ(next.a, 1 / (1 - am), -am / (1 - am), 0.0, s.acc, s.a));
      // v1 = v0 + h (1 - g) a0 + h g a1
      FX_PETSC(VecCopy(s.v, next.v));
      FX_PETSC(VecAXPBYPCZ(next.v, h * (1 - g), h * g, 1.0, s.a, next.a));
      // q1 = q0 + h v0 + h^2 (1/2 - b) a0 + h^2 b a1
      FX_PETSC(VecCopy(s.q, next.q));
      const PetscScalar coef[3] = {h, h * h * (0.5 - b), h * h * b};
      Vec vecs[3] = {s.v, s.a, next.a};
      FX_PETSC(VecMAXPY(next.q, 3, coef, vecs));
    }
    bool has_matrix(const NewtonScaling &k) const {
      return da.factored_ && da.bp_ == k.bp && da.gp_ == k.gp;
    }
    bool factorize(const NewtonScaling &k) {
      da.kept_->reset(next.q);
      da.factored_ = false;
      if (!da.assemble(next, k, true, violation) || !factorized(da.ksp_)) return false;
      da.factored_ = true;
      da.bp_ = k.bp;
      da.gp_ = k.gp;
      return true;
    }
    bool rhs(const NewtonScaling &k) { return da.assemble(next, k, false, violation); }
    bool solve_update(const NewtonScaling &k, double &increment, double &phi) {
      phi = violation;
      const bool turn = da.kept_->rotated;
      if (turn) da.rotate_kept(da.r_, true); // into the frame of the kept matrix
      FX_PETSC(KSPSolve(da.ksp_, da.r_, da.dz_));
      if (turn) da.rotate_kept(da.dz_, false);
      KSPConvergedReason reason;
      FX_PETSC(KSPGetConvergedReason(da.ksp_, &reason));
      if (reason < 0) return false;
      FX_PETSC(VecPointwiseMult(da.w_, da.dz_, da.cmask_)); // dq
      const double d = max_abs(da.w_);
      if (!std::isfinite(d)) return false;
      FX_PETSC(VecAXPY(next.q, 1.0, da.w_));
      FX_PETSC(VecAXPY(next.v, k.gp, da.w_));
      FX_PETSC(VecAXPY(next.acc, k.bp, da.w_));
      FX_PETSC(VecAXPY(next.a, k.ap, da.w_));
      FX_PETSC(VecPointwiseMult(da.w_, da.dz_, da.lmask_)); // the scaled multipliers' update
      FX_PETSC(VecAXPY(next.lambda, k.bp, da.w_));
      increment = d / (1 + max_abs(next.q));
      return true;
    }
    void drop_matrix() { da.factored_ = false; }
  } backend{*this, s, next, h};
  return detail::newton_loop(backend, settings_, par_.newton_scaling(h), info);
}

bool DistributedAlpha::advance(const DistState &s, double h, DistState &next, StepInfo &info,
                               std::vector<std::pair<DistState, double>> *substeps) const {
  return detail::advance_with_halving(
      s, h, next, info, settings_.max_halvings,
      [this](const DistState &from, double dt, DistState &to, StepInfo &i) {
        return step_once(from, dt, to, i);
      },
      substeps);
}

bool DistributedAlpha::step(const DistState &s, double h, DistState &next, StepInfo &info) const {
  return step_once(s, h, next, info);
}

} // namespace flexopt::dynamics
