#include "flexopt/dynamics/distributed_alpha.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/direct_solver.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/newton_loop.hpp"

#include <algorithm>
#include <cmath>
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
    : t(o.t), q(copy_of(o.q)), v(copy_of(o.v)), a(copy_of(o.a)), acc(copy_of(o.acc)) {}

DistState &DistState::operator=(const DistState &o) {
  if (this == &o) return *this;
  t = o.t;
  assign(q, o.q);
  assign(v, o.v);
  assign(a, o.a);
  assign(acc, o.acc);
  return *this;
}

DistState::~DistState() {
  VecDestroy(&q);
  VecDestroy(&v);
  VecDestroy(&a);
  VecDestroy(&acc);
}

namespace detail {

/// Rank r owns the coordinates of its owned nodes of body 0, then body 1, ...: body b's owned
/// node i has the DOFs offset[b] + 3 i + (0, 1, 2). node_dof[b][l] is that first DOF for every
/// local node l (owned, then ghosts: from the owner's offset), and `gather[b]` scatters the
/// positions of all local nodes into `local[b]` (3 per local node).
struct AcfLayout {
  PetscInt local = 0, start = 0, global = 0;
  std::vector<PetscInt> offset;
  std::vector<std::vector<PetscInt>> node_dof;
  std::vector<Vec> local_x;
  std::vector<VecScatter> gather;
  ~AcfLayout() {
    for (Vec &v : local_x) VecDestroy(&v);
    for (VecScatter &g : gather) VecScatterDestroy(&g);
  }
};

} // namespace detail

DistributedAlpha::DistributedAlpha(std::vector<const bodies::AcfBody *> bodies,
                                   const Eigen::Vector3d &gravity, AlphaParameters parameters,
                                   NewtonSettings settings)
    : bodies_(std::move(bodies)), layout_(std::make_unique<detail::AcfLayout>()), par_(parameters),
      settings_(settings) {
  if (bodies_.empty()) throw Error("DistributedAlpha: no ACF body");
  comm_ = bodies_.front()->mesh().comm;
  const int size = comm_size(comm_);
  detail::AcfLayout &L = *layout_;
  const std::size_t nb = bodies_.size();
  for (const auto *b : bodies_) L.local += 3 * b->mesh().owned_nodes;
  MPI_Exscan(&L.local, &L.start, 1, MPIU_INT, MPI_SUM, comm_);
  if (comm_rank(comm_) == 0) L.start = 0;
  MPI_Allreduce(&L.local, &L.global, 1, MPIU_INT, MPI_SUM, comm_);
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
    Vec lx;
    FX_PETSC(VecCreateSeq(PETSC_COMM_SELF, 3 * m.local_nodes(), &lx));
    L.node_dof.push_back(std::move(dof));
    L.local_x.push_back(lx);
  }
  // The mass (its pattern preallocated from every element's full block, which the tangent
  // needs too) and the iteration matrix.
  Mat P;
  FX_PETSC(MatCreate(comm_, &P));
  FX_PETSC(MatSetSizes(P, L.local, L.local, L.global, L.global));
  FX_PETSC(MatSetType(P, MATPREALLOCATOR));
  FX_PETSC(MatSetUp(P));
  for (std::size_t b = 0; b < nb; ++b)
    fem::add_element_pattern(bodies_[b]->mesh(), L.node_dof[b], P);
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
    fem::add_mass(bodies_[b]->mesh(), bodies_[b]->material().density, {}, L.node_dof[b], M_);
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
  r_ = create_vector();
  dq_ = create_vector();
  // The operator is A_ itself: refilled in place, refactorized at the next solve after that.
  ksp_ = create_direct_solver(A_, Factorization::LU, "mech_");
}

DistributedAlpha::~DistributedAlpha() {
  KSPDestroy(&ksp_);
  MatDestroy(&A_);
  MatDestroy(&M_);
  VecDestroy(&fg_);
  VecDestroy(&F_);
  VecDestroy(&r_);
  VecDestroy(&dq_);
}

Vec DistributedAlpha::create_vector() const {
  Vec v;
  FX_PETSC(VecCreateMPI(comm_, layout_->local, layout_->global, &v));
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

fem::CorotatedSum DistributedAlpha::internal(Vec x, Mat T) const {
  detail::AcfLayout &L = *layout_;
  FX_PETSC(VecZeroEntries(F_));
  if (T) FX_PETSC(MatZeroEntries(T));
  double energy = 0;
  std::string failure;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const mesh::DistributedMesh &m = bodies_[b]->mesh();
    FX_PETSC(VecScatterBegin(L.gather[b], x, L.local_x[b], INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecScatterEnd(L.gather[b], x, L.local_x[b], INSERT_VALUES, SCATTER_FORWARD));
    PetscScalar *u;
    FX_PETSC(VecGetArray(L.local_x[b], &u));
    for (PetscInt l = 0; l < 3 * m.local_nodes(); ++l)
      u[l] -= m.coordinates[static_cast<std::size_t>(l)];
    energy += fem::add_corotated(m, bodies_[b]->elements(), u, L.node_dof[b], F_, T, failure);
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

DistState DistributedAlpha::initial_state(Vec x0, Vec v0, double t0) const {
  DistState s;
  s.t = t0;
  s.q = copy_of(x0);
  s.v = copy_of(v0);
  s.acc = create_vector();
  const fem::CorotatedSum sum = internal(s.q, nullptr);
  if (!sum.ok) throw Error("initial state: " + sum.failure, true);
  // M acc = f_g - f(x0), with a direct solve of the constant mass.
  FX_PETSC(VecWAXPY(r_, -1.0, F_, fg_));
  KSP k = create_direct_solver(M_, Factorization::Cholesky, nullptr);
  FX_PETSC(KSPSolve(k, r_, s.acc));
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(k, &reason));
  FX_PETSC(KSPDestroy(&k));
  if (reason < 0)
    throw Error(std::string("initial state: the mass-matrix solve failed (") +
                    KSPConvergedReasons[reason] + ")",
                true);
  s.a = copy_of(s.acc);
  return s;
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

void DistributedAlpha::momentum(const DistState &s, Eigen::Vector3d &linear,
                                Eigen::Vector3d &angular) const {
  FX_PETSC(MatMult(M_, s.v, r_));
  const PetscScalar *p, *x;
  FX_PETSC(VecGetArrayRead(r_, &p));
  FX_PETSC(VecGetArrayRead(s.q, &x));
  double sums[6] = {0, 0, 0, 0, 0, 0}, g[6];
  for (PetscInt i = 0; i < layout_->local; i += 3) {
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
  for (PetscInt i = 0; i < layout_->local; ++i) sums[i % 3] += p[i];
  FX_PETSC(VecRestoreArrayRead(r_, &p));
  MPI_Allreduce(sums, g, 3, MPI_DOUBLE, MPI_SUM, comm_);
  return Eigen::Vector3d(g[0], g[1], g[2]) / mass_;
}

bool DistributedAlpha::step_once(const DistState &s, double h, DistState &next,
                                 StepInfo &info) const {
  if (!next.q) next = s; // vectors of the right layout
  struct Backend {
    const DistributedAlpha &da;
    const DistState &s;
    DistState &next;
    double h;
    void predict() { // acc1 = acc0
      const double am = da.par_.alpha_m, g = da.par_.gamma, b = da.par_.beta;
      next.t = s.t + h;
      FX_PETSC(VecCopy(s.acc, next.acc));
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
    /// r = -(M acc + f(q) - f_g) / beta' (F_ holds f(q)).
    void residual(double bp_) {
      FX_PETSC(MatMult(da.M_, next.acc, da.r_));
      FX_PETSC(VecAXPY(da.r_, 1.0, da.F_));
      FX_PETSC(VecAXPY(da.r_, -1.0, da.fg_));
      FX_PETSC(VecScale(da.r_, -1.0 / bp_));
    }
    bool factorize(const NewtonScaling &k) {
      da.factored_ = false;
      if (!da.internal(next.q, da.A_).ok) return false;
      // A = M + T / beta' (no damping yet: C = 0).
      FX_PETSC(MatScale(da.A_, 1.0 / k.bp));
      // M_ was duplicated from A_: the same stored pattern (explicit zeros off the mass).
      FX_PETSC(MatAXPY(da.A_, 1.0, da.M_, SAME_NONZERO_PATTERN));
      FX_PETSC(KSPSetUp(da.ksp_));
      PC pc;
      FX_PETSC(KSPGetPC(da.ksp_, &pc));
      PCFailedReason failed;
      FX_PETSC(PCGetFailedReason(pc, &failed));
      if (failed != PC_NOERROR) return false;
      residual(k.bp);
      da.factored_ = true;
      da.bp_ = k.bp;
      da.gp_ = k.gp;
      return true;
    }
    bool rhs(const NewtonScaling &k) {
      if (!da.internal(next.q, nullptr).ok) return false; // an inverted element
      residual(k.bp);
      return true;
    }
    bool solve_update(const NewtonScaling &k, double &increment, double &violation) {
      violation = 0; // no constraints
      FX_PETSC(KSPSolve(da.ksp_, da.r_, da.dq_));
      KSPConvergedReason reason;
      FX_PETSC(KSPGetConvergedReason(da.ksp_, &reason));
      if (reason < 0) return false;
      FX_PETSC(VecAXPY(next.q, 1.0, da.dq_));
      FX_PETSC(VecAXPY(next.v, k.gp, da.dq_));
      FX_PETSC(VecAXPY(next.acc, k.bp, da.dq_));
      FX_PETSC(VecAXPY(next.a, k.ap, da.dq_));
      const double d = max_abs(da.dq_);
      if (!std::isfinite(d)) return false;
      increment = d / (1 + max_abs(next.q));
      return true;
    }
    void drop_matrix() { da.factored_ = false; }
  } backend{*this, s, next, h};
  return detail::newton_loop(backend, settings_, par_.newton_scaling(h), info);
}

bool DistributedAlpha::advance(const DistState &s, double h, DistState &next,
                               StepInfo &info) const {
  return detail::advance_with_halving(s, h, next, info, settings_.max_halvings,
                                      [this](const DistState &from, double dt, DistState &to,
                                             StepInfo &i) { return step_once(from, dt, to, i); });
}

} // namespace flexopt::dynamics
