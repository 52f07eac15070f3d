#include "flexopt/dynamics/generalized_alpha.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/consistent_start.hpp"
#include "flexopt/dynamics/newton_loop.hpp"

#include <Eigen/LU>
#include <Eigen/SparseLU>
#include <algorithm>
#include <cmath>
#include <sstream>

namespace flexopt::dynamics {

std::string newton_failure_message(long long step, double t0, double t1, const StepInfo &info,
                                   int max_halvings) {
  std::ostringstream msg;
  msg << "integrate: Newton did not converge in step " << step << " (t = " << t0 << " s -> " << t1
      << " s) after " << (1 << max_halvings)
      << "-fold step halving; increments of the last attempt:";
  for (double v : info.increment) msg << ' ' << v;
  msg << "; constraint residuals:";
  for (double v : info.violation) msg << ' ' << v;
  msg << ". Reduce time.step or check the scene (a singular configuration, a driver demanding "
         "impossible motion, or with a design, void elements of an ACF body: "
         "docs/theory.md section 11)";
  return msg.str();
}

namespace detail {

/// The sparse iteration matrix with its fixed structural pattern and the positions of every
/// body block and constraint row in its values.
struct SparseIteration {
  Eigen::SparseMatrix<double> S;
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> lu;
  int bodies = 0;
  std::vector<int> size;         ///< per body: coordinate block size
  std::vector<int> block_offset; ///< per (bi, bj): start in block_index, or -1
  std::vector<int> block_index;  ///< size_i * size_j value indices per coupled block, row-major
  /// Per enforced row k: (body, start in row_index) for each body it touches; row_index holds
  /// size_b value indices of S(n + k, o_b + j) followed by size_b of S(o_b + j, n + k).
  std::vector<std::vector<std::pair<int, int>>> row_entries;
  std::vector<int> row_index;
};

/// What the Newton iterations reuse: the work vectors, the dense iteration matrix (factorized
/// in place) and the step size parameters of the current factorization.
struct NewtonWork {
  Vector r, jtl, rhs, x, phi;
  std::vector<Matrix> K, C, M; ///< body blocks
  Matrix A;
  Eigen::PartialPivLU<Eigen::Ref<Matrix>> lu;
  bool factored = false; ///< lu (or the sparse LU) holds a matrix for (bp, gp)
  double bp = 0, gp = 0;
  explicit NewtonWork(int dense_size) : A(Matrix::Zero(dense_size, dense_size)), lu(A) {}
};

} // namespace detail

using detail::NewtonWork;
using detail::SparseIteration;

AlphaParameters AlphaParameters::from_rho_inf(double rho) {
  AlphaParameters p;
  p.rho_inf = rho;
  p.alpha_m = (2 * rho - 1) / (rho + 1);
  p.alpha_f = rho / (rho + 1);
  p.gamma = 0.5 + p.alpha_f - p.alpha_m;
  p.beta = 0.25 * (p.gamma + 0.5) * (p.gamma + 0.5);
  return p;
}

NewtonScaling AlphaParameters::newton_scaling(double h) const {
  NewtonScaling k;
  k.bp = (1 - alpha_m) / (beta * h * h * (1 - alpha_f));
  k.gp = gamma / (beta * h);
  k.ap = (1 - alpha_f) / (1 - alpha_m) * k.bp;
  return k;
}

Vector State::pack() const {
  const auto n = q.size(), m = lambda.size();
  Vector s(4 * n + m);
  s << q, v, a, acc, lambda;
  return s;
}

void State::unpack(const Vector &s, int n, int m) {
  q = s.segment(0, n);
  v = s.segment(n, n);
  a = s.segment(2 * n, n);
  acc = s.segment(3 * n, n);
  lambda = s.segment(4 * n, m);
}

GeneralizedAlpha::GeneralizedAlpha(const Mechanism &mechanism, AlphaParameters parameters,
                                   NewtonSettings settings)
    : mech_(mechanism), par_(parameters), settings_(settings) {
  const int n = mech_.coordinates(), m = mech_.constraints();
  const bool dense = n + m <= settings_.dense_limit;
  work_ = std::make_unique<NewtonWork>(dense ? n + m : 0);
  if (dense) return;
  // Structural pattern: body blocks coupled through an equation (and each body with itself),
  // the constraint rows' body columns and their transposes.
  const int nb = static_cast<int>(mech_.bodies.size());
  std::vector<std::vector<char>> coupled(static_cast<std::size_t>(nb),
                                         std::vector<char>(static_cast<std::size_t>(nb), 0));
  for (int b = 0; b < nb; ++b)
    coupled[static_cast<std::size_t>(b)][static_cast<std::size_t>(b)] = 1;
  std::vector<Eigen::Triplet<double>> t;
  int row = 0, k = 0;
  for (const auto &e : mech_.equations) {
    if (e.a >= 0 && e.b >= 0)
      coupled[static_cast<std::size_t>(e.a)][static_cast<std::size_t>(e.b)] =
          coupled[static_cast<std::size_t>(e.b)][static_cast<std::size_t>(e.a)] = 1;
    for (int i = 0; i < e.rows(); ++i, ++row) {
      if (!mech_.enforced(row)) continue;
      for (int b : {e.a, e.b})
        if (b >= 0)
          for (int j = 0; j < mech_.size(b); ++j) {
            t.emplace_back(n + k, mech_.offset(b) + j, 1.0);
            t.emplace_back(mech_.offset(b) + j, n + k, 1.0);
          }
      ++k;
    }
  }
  for (int a = 0; a < nb; ++a)
    for (int b = 0; b < nb; ++b)
      if (coupled[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)])
        for (int i = 0; i < mech_.size(a); ++i)
          for (int j = 0; j < mech_.size(b); ++j)
            t.emplace_back(mech_.offset(a) + i, mech_.offset(b) + j, 1.0);
  sparse_ = std::make_unique<SparseIteration>();
  SparseIteration &sp = *sparse_;
  sp.S.resize(n + m, n + m);
  sp.S.setFromTriplets(t.begin(), t.end(), [](double x, double) { return x; });
  sp.S.makeCompressed();
  sp.lu.analyzePattern(sp.S);
  // Value indices of every block and row entry, so that assembly writes straight into S.
  const double *base = sp.S.valuePtr();
  auto index = [&](int i, int j) { return static_cast<int>(&sp.S.coeffRef(i, j) - base); };
  sp.bodies = nb;
  for (int b = 0; b < nb; ++b) sp.size.push_back(mech_.size(b));
  sp.block_offset.assign(static_cast<std::size_t>(nb * nb), -1);
  for (int a = 0; a < nb; ++a)
    for (int b = 0; b < nb; ++b)
      if (coupled[static_cast<std::size_t>(a)][static_cast<std::size_t>(b)]) {
        sp.block_offset[static_cast<std::size_t>(a * nb + b)] =
            static_cast<int>(sp.block_index.size());
        for (int i = 0; i < mech_.size(a); ++i)
          for (int j = 0; j < mech_.size(b); ++j)
            sp.block_index.push_back(index(mech_.offset(a) + i, mech_.offset(b) + j));
      }
  sp.row_entries.assign(static_cast<std::size_t>(m), {});
  row = 0, k = 0;
  for (const auto &e : mech_.equations)
    for (int i = 0; i < e.rows(); ++i, ++row) {
      if (!mech_.enforced(row)) continue;
      for (int b : {e.a, e.b})
        if (b >= 0) {
          sp.row_entries[static_cast<std::size_t>(k)].emplace_back(
              b, static_cast<int>(sp.row_index.size()));
          for (int j = 0; j < mech_.size(b); ++j)
            sp.row_index.push_back(index(n + k, mech_.offset(b) + j));
          for (int j = 0; j < mech_.size(b); ++j)
            sp.row_index.push_back(index(mech_.offset(b) + j, n + k));
        }
      ++k;
    }
}

namespace {

/// Gauss-Newton on the smallest correction of the positions q onto Phi(q, t0) = 0,
/// q <- q - J^T (J J^T)^-1 Phi, to `tol`; the iterations taken (50: not converged).
int gauss_newton_placement(const Mechanism &mech, Vector &q, double t0, double tol) {
  Vector phi;
  Matrix J;
  int it = 0;
  for (; it < 50; ++it) {
    mech.constraint(q, t0, phi, &J);
    if (mech.constraints() == 0 || phi.cwiseAbs().maxCoeff() <= tol) break;
    const Matrix JJt = J * J.transpose();
    q -= J.transpose() * JJt.partialPivLu().solve(phi);
  }
  return it;
}

/// The Gauss-Newton point is near, not at, the smallest correction, and where it lands depends
/// on the iterations taken. Newton on the conditions of the smallest change, q - q0 + J^T mu = 0
/// and Phi = 0, from there makes q the closest point, a function of q0 whose derivative the
/// adjoint has exactly (docs/theory.md section 9.2 item 6). Returns whether it converged to
/// `tol`; mu: the multipliers.
bool closest_placement(const Mechanism &mech, const Vector &q0, double t0, double tol, Vector &q,
                       Vector &mu) {
  const int n = mech.coordinates(), m = mech.constraints();
  Vector phi;
  Matrix J;
  mech.constraint(q, t0, phi, &J);
  const Matrix JJt = J * J.transpose();
  mu = -JJt.partialPivLu().solve(J * (q - q0));
  for (int k = 0; k < 8; ++k) {
    mech.constraint(q, t0, phi, &J);
    const Vector g = q - q0 + J.transpose() * mu;
    if (g.cwiseAbs().maxCoeff() <= tol && phi.cwiseAbs().maxCoeff() <= tol) return true;
    Matrix A = Matrix::Zero(n + m, n + m);
    A.topLeftCorner(n, n) = Matrix::Identity(n, n);
    mech.add_constraint_hessian(q, t0, mu, A); // writes into the top-left n x n block
    A.topRightCorner(n, m) = J.transpose();
    A.bottomLeftCorner(m, n) = J;
    Vector rhs(n + m);
    rhs << -g, -phi;
    const Vector d = A.partialPivLu().solve(rhs);
    if (!d.allFinite()) break;
    q += d.head(n);
    mu += d.tail(m);
  }
  return false;
}

/// Throws a collective flexopt::Error naming (up to six of) the constraints that the placed
/// positions q violate by more than 1e-9 `scale`, or if Gauss-Newton took all its iterations.
void check_placement(const Mechanism &mech, const Vector &q, double t0, double scale, int it) {
  Vector all;
  mech.all_constraint_values(q, t0, all);
  std::ostringstream bad;
  int nbad = 0;
  for (int r = 0; r < all.size(); ++r)
    if (!(std::abs(all(r)) <= 1e-9 * scale)) {
      if (nbad++ < 6) bad << "\n  " << mech.describe_row(r) << ": residual " << all(r);
    }
  if (nbad > 0 || it == 50)
    throw Error("initial conditions: the joints cannot all be satisfied by the initial placement "
                "(an over-constrained mechanism whose redundant joints disagree, or bodies placed "
                "too far from an assembled configuration); after " +
                    std::to_string(it) +
                    " position corrections these constraints remain violated:" + bad.str(),
                true);
}

} // namespace

State GeneralizedAlpha::initial_state(const Vector &q0, const Vector &v0, double t0,
                                      StartReport *report, StartTrace *trace) const {
  const int n = mech_.coordinates(), m = mech_.constraints();
  State s;
  s.t = t0;
  s.q = q0;
  if (trace) *trace = StartTrace{};
  // Positions: the closest point of q0 on Phi(q, t0) = 0.
  double scale = 1;
  for (int b = 0; b < static_cast<int>(mech_.bodies.size()); ++b)
    scale = std::max(scale, q0.segment<3>(mech_.offset(b)).cwiseAbs().maxCoeff());
  const double tol = 1e-13 * scale;
  const int it = gauss_newton_placement(mech_, s.q, t0, tol);
  Vector mu = Vector::Zero(m);
  bool closest = true;
  if (it > 0 && it < 50) closest = closest_placement(mech_, q0, t0, tol, s.q, mu);
  if (trace) {
    trace->given = q0;
    trace->multipliers = mu;
    trace->closest = closest;
  }
  check_placement(mech_, s.q, t0, scale, it);
  Vector phi;
  Matrix J;
  // Velocities: the rigid-body velocities corrected onto Phi_q v + Phi_t = 0 with the least
  // change of kinetic energy, the elastic ones kept (section 6.4).
  Vector r;
  Matrix M;
  mech_.dynamics(s.q, v0, Vector::Zero(n), t0, r, nullptr, nullptr, &M);
  StartReport rep;
  rep.kinetic_given = 0.5 * v0.dot(M * v0);
  const VelocityCorrection rigid = rigid_velocity_correction(mech_, s.q, v0, t0);
  if (trace) {
    trace->rigid = rigid;
    trace->fallback = Vector();
  }
  s.v = v0 + rigid.dv;
  rep.rigid_residual = rigid.residual;
  rep.given_violation = rigid.scale;
  mech_.constraint(s.q, t0, phi, &J);
  // One factorization of [M J^T; J 0] serves the fallback velocity correction and the
  // accelerations (q and so M and J are fixed from here on).
  Matrix A = Matrix::Zero(n + m, n + m);
  A.topLeftCorner(n, n) = M;
  A.topRightCorner(n, m) = J.transpose();
  A.bottomLeftCorner(m, n) = J;
  const Eigen::PartialPivLU<Matrix> lu(A);
  Vector phi_t, phi_tt, phi_qt_v;
  if (m > 0 && rigid.residual > kVelocityTolerance * (1 + rigid.scale)) {
    // The joints prescribe elastic velocities: the smallest change in kinetic energy of all
    // velocities, [M J^T; J 0] [dv; mu] = [0; -(J v + Phi_t)].
    mech_.constraint_time_terms(s.q, s.v, t0, phi_t, phi_tt, phi_qt_v);
    Vector rhs = Vector::Zero(n + m);
    rhs.tail(m) = -(J * s.v + phi_t);
    const Vector dv = lu.solve(rhs).head(n);
    s.v += dv;
    rep.elastic_corrected = true;
    if (trace) trace->fallback = dv;
  }
  rep.kinetic = 0.5 * s.v.dot(M * s.v);
  if (report) *report = rep;
  mech_.constraint_time_terms(s.q, s.v, t0, phi_t, phi_tt, phi_qt_v);
  // Accelerations and multipliers: [M J^T; J 0] [acc; lambda] = [-r0; -(J v)_q v - 2 Phi_qt v -
  // Phi_tt].
  mech_.dynamics(s.q, s.v, Vector::Zero(n), t0, r, nullptr, nullptr, nullptr);
  Vector rhs(n + m);
  rhs.head(n) = -r;
  rhs.tail(m) = -mech_.constraint_convective(s.q, s.v, t0) - 2 * phi_qt_v - phi_tt;
  const Vector x = lu.solve(rhs);
  if (!x.allFinite())
    throw Error("initial conditions: the acceleration system is singular (a body without mass "
                "or inertia, or a mechanism whose joints leave no consistent acceleration)",
                true);
  s.acc = x.head(n);
  s.lambda = x.tail(m);
  s.a = s.acc;
  return s;
}

bool GeneralizedAlpha::step(const State &s, double h, State &next, StepInfo &info) const {
  return step_once(s, h, next, info);
}

namespace {

/// Writes the Newton iteration matrix block by block, either into a dense matrix or straight
/// into the values of the sparse one (through the index maps built by the constructor), and
/// accumulates Phi_q^T lambda. Gradient rows go to row n + k and, transposed, to column n + k;
/// body blocks are scaled by `block_scale`.
struct IterationAssembly : joints::Sink {
  Matrix *A;           ///< dense target, or null
  SparseIteration *sp; ///< sparse target (with its value indices), or null
  double *values;      ///< the sparse matrix's values
  int n;
  double block_scale = 1;
  const Vector &lambda;
  Vector &jt_lambda;
  /// PETSc target (distributed backend), or null: coordinate k at coord0 + k, row k at row0 + k.
  Mat petsc = nullptr;
  PetscInt coord0 = 0, row0 = 0;
  IterationAssembly(Matrix *A_, SparseIteration *sp_, int n_, const Vector &l, Vector &jtl)
      : A(A_), sp(sp_), values(sp_ ? sp_->S.valuePtr() : nullptr), n(n_), lambda(l),
        jt_lambda(jtl) {}
  /// B (scaled by `scale`) at global rows i0.., columns j0.. of the PETSc target.
  void add_petsc(PetscInt i0, PetscInt j0, const Matrix &B) const {
    std::vector<PetscInt> rows(static_cast<std::size_t>(B.rows())),
        cols(static_cast<std::size_t>(B.cols()));
    for (std::size_t i = 0; i < rows.size(); ++i) rows[i] = i0 + static_cast<PetscInt>(i);
    for (std::size_t j = 0; j < cols.size(); ++j) cols[j] = j0 + static_cast<PetscInt>(j);
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> R = B;
    FX_PETSC(MatSetValues(petsc, static_cast<PetscInt>(rows.size()), rows.data(),
                          static_cast<PetscInt>(cols.size()), cols.data(), R.data(), ADD_VALUES));
  }
  void add_row(int row, const joints::BodyRef &body, const joints::Row &g) override {
    const int size = static_cast<int>(g.size());
    jt_lambda.segment(body.offset, size) += g.transpose() * lambda(row);
    if (petsc) {
      add_petsc(row0 + row, coord0 + body.offset, g);
      add_petsc(coord0 + body.offset, row0 + row, g.transpose());
      return;
    }
    if (!A && !sp) return; // Phi_q^T lambda alone
    if (A) {
      A->block(n + row, body.offset, 1, size) += g;
      A->block(body.offset, n + row, size, 1) += g.transpose();
      return;
    }
    for (const auto &[bb, start] : sp->row_entries[static_cast<std::size_t>(row)])
      if (bb == body.index) {
        for (int j = 0; j < size; ++j) {
          values[sp->row_index[static_cast<std::size_t>(start + j)]] += g(j);
          values[sp->row_index[static_cast<std::size_t>(start + size + j)]] += g(j);
        }
        return;
      }
  }
  /// Value index of entry (i, j) of the block of bodies (bi, bj).
  int value_index(const joints::BodyRef &bi, const joints::BodyRef &bj, int i, int j) const {
    const int off = sp->block_offset[static_cast<std::size_t>(bi.index * sp->bodies + bj.index)];
    return sp->block_index[static_cast<std::size_t>(
        off + i * sp->size[static_cast<std::size_t>(bj.index)] + j)];
  }
  void add_block(const joints::BodyRef &bi, const joints::BodyRef &bj, int i0, int j0,
                 const Eigen::Ref<const Matrix> &B) override {
    if (petsc) {
      add_petsc(coord0 + bi.offset + i0, coord0 + bj.offset + j0, block_scale * B);
      return;
    }
    if (A) {
      A->block(bi.offset + i0, bj.offset + j0, B.rows(), B.cols()) += block_scale * B;
      return;
    }
    for (Eigen::Index i = 0; i < B.rows(); ++i)
      for (Eigen::Index j = 0; j < B.cols(); ++j)
        values[value_index(bi, bj, i0 + static_cast<int>(i), j0 + static_cast<int>(j))] +=
            block_scale * B(i, j);
  }
  void add_product(const joints::BodyRef &bi, const joints::BodyRef &bj, double scale,
                   const joints::Jacobian &X, const joints::Jacobian &Y) override {
    const double s = block_scale * scale;
    if (petsc) {
      add_petsc(coord0 + bi.offset, coord0 + bj.offset, s * X.transpose() * Y);
      return;
    }
    if (A) {
      // Inner dimension 3: a coefficient-wise product (the blocked GEMM only adds packing).
      A->block(bi.offset, bj.offset, X.cols(), Y.cols()).noalias() +=
          (s * X.transpose()).lazyProduct(Y);
      return;
    }
    for (Eigen::Index i = 0; i < X.cols(); ++i)
      for (Eigen::Index j = 0; j < Y.cols(); ++j)
        values[value_index(bi, bj, static_cast<int>(i), static_cast<int>(j))] +=
            s * X.col(i).dot(Y.col(j));
  }
};

} // namespace

GeneralizedAlpha::~GeneralizedAlpha() = default;

namespace {

/// The scaled iteration matrix of section 6.4 at `next` into the target of `assembly` (body
/// blocks M + (gamma'/beta') C + K / beta', constraint rows and their transposes, the
/// constraint Hessian / beta'), and rhs = -[(R_d + Phi_q^T lambda) / beta'; Phi], phi = Phi.
/// K, C, M: the body blocks (work space).
void assemble_system(const Mechanism &mech, const State &next, double bp, double gp,
                     IterationAssembly &assembly, Vector &r, Vector &phi, Vector &rhs,
                     std::vector<Matrix> &K, std::vector<Matrix> &C, std::vector<Matrix> &M) {
  const int n = mech.coordinates(), m = mech.constraints();
  const int nb = static_cast<int>(mech.bodies.size());
  assembly.jt_lambda.setZero(n);
  mech.dynamics_blocks(next.q, next.v, next.acc, next.t, r, K, C, M);
  for (int b = 0; b < nb; ++b) {
    const auto k = static_cast<std::size_t>(b);
    M[k] += (gp / bp) * C[k] + (1.0 / bp) * K[k];
    const joints::BodyRef ref{b, mech.offset(b)};
    assembly.add_block(ref, ref, 0, 0, M[k]);
  }
  assembly.block_scale = 1.0 / bp;
  mech.constraint(next.q, next.t, phi, assembly);
  mech.add_constraint_hessian(next.q, next.t, next.lambda, assembly);
  rhs.resize(n + m);
  rhs.head(n) = -(r + assembly.jt_lambda) / bp;
  rhs.tail(m) = -phi;
}

} // namespace

void add_newton_system(const Mechanism &mech, const State &next, double bp, double gp, Mat A,
                       PetscInt coord0, PetscInt row0, Vector &rhs) {
  Vector r, phi, jtl;
  std::vector<Matrix> K, C, M;
  IterationAssembly assembly(nullptr, nullptr, mech.coordinates(), next.lambda, jtl);
  assembly.petsc = A;
  assembly.coord0 = coord0;
  assembly.row0 = row0;
  assemble_system(mech, next, bp, gp, assembly, r, phi, rhs, K, C, M);
}

void add_mass_system(const Mechanism &mech, const State &s, Mat A, PetscInt coord0, PetscInt row0) {
  const int n = mech.coordinates(), m = mech.constraints();
  Vector r, phi, jtl;
  const Vector zero = Vector::Zero(m);
  std::vector<Matrix> K, C, M;
  IterationAssembly assembly(nullptr, nullptr, n, zero, jtl);
  assembly.petsc = A;
  assembly.coord0 = coord0;
  assembly.row0 = row0;
  jtl.setZero(n);
  mech.dynamics_blocks(s.q, s.v, Vector::Zero(n), s.t, r, K, C, M);
  for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b) {
    const joints::BodyRef ref{b, mech.offset(b)};
    assembly.add_block(ref, ref, 0, 0, M[static_cast<std::size_t>(b)]);
  }
  mech.constraint(s.q, s.t, phi, assembly);
}

bool GeneralizedAlpha::factorize(const State &next, double bp, double gp) const {
  NewtonWork &w = *work_;
  w.factored = false;
  if (sparse_)
    std::fill(sparse_->S.valuePtr(), sparse_->S.valuePtr() + sparse_->S.nonZeros(), 0.0);
  else
    w.A.setZero();
  IterationAssembly assembly(sparse_ ? nullptr : &w.A, sparse_.get(), mech_.coordinates(),
                             next.lambda, w.jtl);
  assemble_system(mech_, next, bp, gp, assembly, w.r, w.phi, w.rhs, w.K, w.C, w.M);
  if (sparse_) {
    sparse_->lu.factorize(sparse_->S);
    if (sparse_->lu.info() != Eigen::Success) return false;
  } else {
    w.lu.compute(w.A);
  }
  w.factored = true;
  w.bp = bp;
  w.gp = gp;
  return true;
}

namespace {

/// rhs = -[(R_d + Phi_q^T lambda) / beta'; Phi] and phi = Phi at `next`, without derivatives
/// (an iteration on a kept matrix). r, jtl: work vectors.
void system_rhs(const Mechanism &mech, const State &next, double bp, Vector &r, Vector &jtl,
                Vector &phi, Vector &rhs) {
  const int n = mech.coordinates(), m = mech.constraints();
  mech.dynamics_residual(next.q, next.v, next.acc, next.t, r);
  jtl.setZero(n);
  IterationAssembly transpose_product(nullptr, nullptr, n, next.lambda, jtl);
  mech.constraint(next.q, next.t, phi, transpose_product);
  rhs.resize(n + m);
  rhs.head(n) = -(r + jtl) / bp;
  rhs.tail(m) = -phi;
}

} // namespace

void newton_system_rhs(const Mechanism &mech, const State &next, double bp, Vector &rhs) {
  Vector r, jtl, phi;
  system_rhs(mech, next, bp, r, jtl, phi, rhs);
}

void GeneralizedAlpha::newton_rhs(const State &next, double bp) const {
  NewtonWork &w = *work_;
  system_rhs(mech_, next, bp, w.r, w.jtl, w.phi, w.rhs);
}

bool GeneralizedAlpha::solve() const {
  NewtonWork &w = *work_;
  if (sparse_)
    w.x = sparse_->lu.solve(w.rhs);
  else
    w.x = w.lu.solve(w.rhs);
  return w.x.allFinite();
}

bool GeneralizedAlpha::step_once(const State &s, double h, State &next, StepInfo &info) const {
  // The Newton loop (detail::newton_loop) on the replicated dense or sparse system.
  struct Backend {
    const GeneralizedAlpha &ga;
    const State &s;
    State &next;
    double h;
    void predict() { // acc1 = acc0, lambda1 = lambda0
      const double am = ga.par_.alpha_m, af = ga.par_.alpha_f, g = ga.par_.gamma, b = ga.par_.beta;
      next.t = s.t + h;
      next.acc = s.acc;
      next.lambda = s.lambda;
      next.a = (af * s.acc - am * s.a + (1 - af) * next.acc) / (1 - am);
      next.v = s.v + h * (1 - g) * s.a + h * g * next.a;
      next.q = s.q + h * s.v + h * h * (0.5 - b) * s.a + h * h * b * next.a;
    }
    bool has_matrix(const NewtonScaling &k) const {
      const NewtonWork &w = *ga.work_;
      return w.factored && w.bp == k.bp && w.gp == k.gp;
    }
    bool factorize(const NewtonScaling &k) { return ga.factorize(next, k.bp, k.gp); }
    bool rhs(const NewtonScaling &k) {
      ga.newton_rhs(next, k.bp);
      return true;
    }
    bool solve_update(const NewtonScaling &k, double &increment, double &violation) {
      const int n = ga.mech_.coordinates(), m = ga.mech_.constraints();
      NewtonWork &w = *ga.work_;
      violation = m > 0 ? w.phi.cwiseAbs().maxCoeff() : 0.0;
      if (!ga.solve()) return false;
      const auto dq = w.x.head(n);
      next.q += dq;
      next.v += k.gp * dq;
      next.acc += k.bp * dq;
      next.a += k.ap * dq;
      next.lambda += k.bp * w.x.tail(m);
      increment = dq.cwiseAbs().maxCoeff() / (1 + next.q.cwiseAbs().maxCoeff());
      return true;
    }
    void drop_matrix() { ga.work_->factored = false; }
  } backend{*this, s, next, h};
  return detail::newton_loop(backend, settings_, par_.newton_scaling(h), info);
}

void GeneralizedAlpha::jacobian_blocks(const State &next, Matrix &K, Matrix &C, Matrix &M,
                                       Matrix &J) const {
  Vector r, phi;
  mech_.dynamics(next.q, next.v, next.acc, next.t, r, &K, &C, &M);
  mech_.add_constraint_hessian(next.q, next.t, next.lambda, K);
  mech_.constraint(next.q, next.t, phi, &J);
}

bool GeneralizedAlpha::advance(const State &s, double h, State &next, StepInfo &info,
                               std::vector<std::pair<State, double>> *substeps) const {
  return detail::advance_with_halving(
      s, h, next, info, settings_.max_halvings,
      [this](const State &from, double dt, State &to, StepInfo &i) {
        return step_once(from, dt, to, i);
      },
      substeps);
}

void GeneralizedAlpha::residual(const State &next, const State &prev, double h, Vector &R,
                                Matrix *dR_dnext, Matrix *dR_dprev) const {
  const int n = mech_.coordinates(), m = mech_.constraints();
  const double am = par_.alpha_m, af = par_.alpha_f, g = par_.gamma, b = par_.beta;
  R.resize(4 * n + m);
  R.segment(0, n) = next.q - prev.q - h * prev.v - h * h * (0.5 - b) * prev.a - h * h * b * next.a;
  R.segment(n, n) = next.v - prev.v - h * (1 - g) * prev.a - h * g * next.a;
  R.segment(2 * n, n) = (1 - am) * next.a + am * prev.a - (1 - af) * next.acc - af * prev.acc;
  Vector r, phi;
  Matrix K, C, M, J;
  mech_.dynamics(next.q, next.v, next.acc, next.t, r, nullptr, nullptr, nullptr);
  mech_.constraint(next.q, next.t, phi, &J);
  R.segment(3 * n, n) = r + J.transpose() * next.lambda;
  R.segment(4 * n, m) = phi;
  const Matrix I = Matrix::Identity(n, n);
  if (dR_dnext) {
    jacobian_blocks(next, K, C, M, J);
    Matrix &D = *dR_dnext;
    D.setZero(4 * n + m, 4 * n + m);
    D.block(0, 0, n, n) = I;
    D.block(0, 2 * n, n, n) = -h * h * b * I;
    D.block(n, n, n, n) = I;
    D.block(n, 2 * n, n, n) = -h * g * I;
    D.block(2 * n, 2 * n, n, n) = (1 - am) * I;
    D.block(2 * n, 3 * n, n, n) = -(1 - af) * I;
    D.block(3 * n, 0, n, n) = K;
    D.block(3 * n, n, n, n) = C;
    D.block(3 * n, 3 * n, n, n) = M;
    D.block(3 * n, 4 * n, n, m) = J.transpose();
    D.block(4 * n, 0, m, n) = J;
  }
  if (dR_dprev) {
    Matrix &D = *dR_dprev;
    D.setZero(4 * n + m, 4 * n + m);
    D.block(0, 0, n, n) = -I;
    D.block(0, n, n, n) = -h * I;
    D.block(0, 2 * n, n, n) = -h * h * (0.5 - b) * I;
    D.block(n, n, n, n) = -I;
    D.block(n, 2 * n, n, n) = -h * (1 - g) * I;
    D.block(2 * n, 2 * n, n, n) = am * I;
    D.block(2 * n, 3 * n, n, n) = -af * I;
  }
}

} // namespace flexopt::dynamics
