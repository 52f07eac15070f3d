// The Method of Moving Asymptotes over distributed PETSc Vecs. The algorithm follows Svanberg's
// 2007 notes ("MMA and GCMMA - two methods for nonlinear optimization"): mmasub (asymptotes,
// move bounds, approximation coefficients) and subsolv (primal-dual interior-point method on the
// subproblem, Newton system reduced to (m+1) x (m+1)). docs/theory-mma.md gives the formulas.
#include "flexopt/optimize/mma.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace flexopt::optimize {

namespace {

constexpr double kAlbefa = 0.1;        // move bounds at least this fraction away from L, U
constexpr double kRaa0 = 1e-5;         // regularisation of p0, q0, p_ij, q_ij
constexpr double kXmamiMin = 1e-5;     // lower limit of xmax - xmin in the regularisation
constexpr double kAsymptoteMin = 0.01; // |x - L|, |U - x| >= 0.01 (xmax - xmin)
constexpr double kAsymptoteMax = 10.0; // |x - L|, |U - x| <= 10 (xmax - xmin)
constexpr int kMaxNewton = 200;        // Newton steps per barrier level
constexpr int kMaxLineSearch = 50;     // step halvings per Newton step

/// Read access to a Vec's local array, restored on scope exit (also when an exception passes).
class ReadArray {
public:
  explicit ReadArray(Vec v) : v_(v) { FX_PETSC(VecGetArrayRead(v_, &a_)); }
  ~ReadArray() { VecRestoreArrayRead(v_, &a_); }
  ReadArray(const ReadArray &) = delete;
  ReadArray &operator=(const ReadArray &) = delete;
  const double &operator[](PetscInt j) const { return a_[j]; }
  const double *data() const { return a_; }

private:
  Vec v_;
  const PetscScalar *a_ = nullptr;
};

class WriteArray {
public:
  explicit WriteArray(Vec v) : v_(v) { FX_PETSC(VecGetArray(v_, &a_)); }
  ~WriteArray() { VecRestoreArray(v_, &a_); }
  WriteArray(const WriteArray &) = delete;
  WriteArray &operator=(const WriteArray &) = delete;
  double &operator[](PetscInt j) { return a_[j]; }

private:
  Vec v_;
  PetscScalar *a_ = nullptr;
};

void sum_all(MPI_Comm comm, std::vector<double> &buffer) {
  if (!buffer.empty())
    MPI_Allreduce(MPI_IN_PLACE, buffer.data(), static_cast<int>(buffer.size()), MPI_DOUBLE, MPI_SUM,
                  comm);
}

double max_all(MPI_Comm comm, double value) {
  double result = value;
  MPI_Allreduce(&value, &result, 1, MPI_DOUBLE, MPI_MAX, comm);
  return result;
}

} // namespace

/// The MMA subproblem (as built by mmasub in the 2007 notes) and its primal-dual
/// interior-point solver ("subsolv"). Arrays indexed by j are this rank's components of x;
/// P and Q are stored component-major: P[j m + i] = p_ij. The m-sized unknowns
/// (y, z, lambda, mu, zeta, s) are held, and updated identically, on every rank. The object
/// lives as long as its Mma so that its arrays are allocated once, but carries nothing from one
/// solve() to the next (every array is written before it is read).
class detail::MmaSubsolver {
public:
  MmaSubsolver(MPI_Comm comm, int m, std::size_t n, const MmaSettings &settings)
      : comm_(comm), m_(static_cast<std::size_t>(m)), n_(n),
        epsilon_min_(settings.subproblem_epsilon), a0_(settings.a0), a_(settings.a), c_(settings.c),
        d_(settings.d) {
    low.resize(n_), upp.resize(n_), alfa.resize(n_), beta.resize(n_);
    p0.resize(n_), q0.resize(n_), P.resize(n_ * m_), Q.resize(n_ * m_), b.resize(m_);
    x_.resize(n_), xsi_.resize(n_), eta_.resize(n_);
    dx_.resize(n_), dxsi_.resize(n_), deta_.resize(n_);
    x_old_.resize(n_), xsi_old_.resize(n_), eta_old_.resize(n_);
    delx_.resize(n_), diagx_inv_.resize(n_), xa_inv_.resize(n_), bx_inv_.resize(n_);
    G_.resize(n_ * m_);
    y_.resize(m_), lam_.resize(m_), mu_.resize(m_), s_.resize(m_);
    dy_.resize(m_), dlam_.resize(m_), dmu_.resize(m_), ds_.resize(m_);
    y_old_.resize(m_), lam_old_.resize(m_), mu_old_.resize(m_), s_old_.resize(m_);
  }

  // Subproblem data, set by the caller.
  std::vector<double> low, upp, alfa, beta, p0, q0, P, Q, b;

  MmaSubproblemInfo solve();
  const std::vector<double> &x() const { return x_; }
  const std::vector<double> &y() const { return y_; }
  const std::vector<double> &lam() const { return lam_; }
  double z() const { return z_; }

private:
  double residual_norm(double epsi);
  double residual_max();
  void newton_direction(double epsi);
  double max_step_inverse();
  void save_point();
  void take_step(double step);
  void fail(const std::string &what) const { throw Error("MMA subproblem solver: " + what, true); }

  MPI_Comm comm_;
  std::size_t m_, n_;
  double epsilon_min_, a0_;
  const std::vector<double> &a_, &c_, &d_;
  // Primal-dual point and Newton direction.
  std::vector<double> x_, xsi_, eta_, y_, lam_, mu_, s_;
  double z_ = 1, zet_ = 1;
  std::vector<double> dx_, dxsi_, deta_, dy_, dlam_, dmu_, ds_;
  double dz_ = 0, dzet_ = 0;
  std::vector<double> x_old_, xsi_old_, eta_old_, y_old_, lam_old_, mu_old_, s_old_;
  double z_old_ = 0, zet_old_ = 0;
  // Work arrays of the Newton step: delta_x, 1/D_x, 1/(x-alpha), 1/(beta-x), G.
  std::vector<double> delx_, diagx_inv_, xa_inv_, bx_inv_, G_;
  // Local max |residual| over the x-components and max over the m-sized part, of the last
  // residual_norm() call.
  double last_local_max_ = 0, last_small_max_ = 0;
};

/// 2-norm of the residual of the relaxed (epsilon-perturbed) KKT conditions of the subproblem at
/// the current point. One Allreduce of m + 1 numbers.
double detail::MmaSubsolver::residual_norm(double epsi) {
  const std::size_t m = m_;
  std::vector<double> red(m + 1, 0.0); // gvec_i = sum_j p_ij/(U_j-x_j) + q_ij/(x_j-L_j); |r_x|^2
  double local_sq = 0, local_max = 0;
  for (std::size_t j = 0; j < n_; ++j) {
    const double ux1 = upp[j] - x_[j], xl1 = x_[j] - low[j];
    const double uxinv = 1.0 / ux1, xlinv = 1.0 / xl1;
    double plam = p0[j], qlam = q0[j];
    const double *pj = P.data() + j * m, *qj = Q.data() + j * m;
    for (std::size_t i = 0; i < m; ++i) {
      plam += pj[i] * lam_[i];
      qlam += qj[i] * lam_[i];
      red[i] += pj[i] * uxinv + qj[i] * xlinv;
    }
    const double dpsidx = plam * uxinv * uxinv - qlam * xlinv * xlinv;
    const double rex = dpsidx - xsi_[j] + eta_[j];
    const double rexsi = xsi_[j] * (x_[j] - alfa[j]) - epsi;
    const double reeta = eta_[j] * (beta[j] - x_[j]) - epsi;
    local_sq += rex * rex + rexsi * rexsi + reeta * reeta;
    local_max = std::max({local_max, std::abs(rex), std::abs(rexsi), std::abs(reeta)});
  }
  red[m] = local_sq;
  sum_all(comm_, red);

  double small_sq = 0, small_max = 0;
  auto add = [&](double r) {
    small_sq += r * r;
    small_max = std::max(small_max, std::abs(r));
  };
  double alam = 0;
  for (std::size_t i = 0; i < m; ++i) {
    add(c_[i] + d_[i] * y_[i] - mu_[i] - lam_[i]);   // rey
    add(red[i] - a_[i] * z_ - y_[i] + s_[i] - b[i]); // relam
    add(mu_[i] * y_[i] - epsi);                      // remu
    add(lam_[i] * s_[i] - epsi);                     // res
    alam += a_[i] * lam_[i];
  }
  add(a0_ - zet_ - alam); // rez
  add(zet_ * z_ - epsi);  // rezet
  last_local_max_ = local_max;
  last_small_max_ = small_max;
  return std::sqrt(red[m] + small_sq);
}

/// Max-norm of the residual evaluated by the last residual_norm(). One Allreduce (MPI_MAX).
double detail::MmaSubsolver::residual_max() {
  return std::max(max_all(comm_, last_local_max_), last_small_max_);
}

/// Newton direction of the relaxed KKT system, reduced to (m+1) x (m+1) (the "m < n" variant
/// of subsolv, used here for every m and n). One Allreduce of 2m + m(m+1)/2 numbers; the small
/// system is solved by every rank with the same data, so every rank gets the same direction.
void detail::MmaSubsolver::newton_direction(double epsi) {
  const std::size_t m = m_;
  const std::size_t n_upper = m * (m + 1) / 2;
  // red = [gvec (m), G D_x^-1 delx (m), upper triangle of G D_x^-1 G^T (row-major)]
  std::vector<double> red(2 * m + n_upper, 0.0);
  for (std::size_t j = 0; j < n_; ++j) {
    const double ux1 = upp[j] - x_[j], xl1 = x_[j] - low[j];
    const double uxinv1 = 1.0 / ux1, xlinv1 = 1.0 / xl1;
    const double uxinv2 = uxinv1 * uxinv1, xlinv2 = xlinv1 * xlinv1;
    double plam = p0[j], qlam = q0[j];
    const double *pj = P.data() + j * m, *qj = Q.data() + j * m;
    double *gj = G_.data() + j * m;
    for (std::size_t i = 0; i < m; ++i) {
      plam += pj[i] * lam_[i];
      qlam += qj[i] * lam_[i];
      red[i] += pj[i] * uxinv1 + qj[i] * xlinv1;
      gj[i] = pj[i] * uxinv2 - qj[i] * xlinv2;
    }
    const double dpsidx = plam * uxinv2 - qlam * xlinv2;
    const double xa_inv = 1.0 / (x_[j] - alfa[j]), bx_inv = 1.0 / (beta[j] - x_[j]);
    xa_inv_[j] = xa_inv, bx_inv_[j] = bx_inv;
    delx_[j] = dpsidx - epsi * xa_inv + epsi * bx_inv;
    const double diagx = 2.0 * (plam * uxinv2 * uxinv1 + qlam * xlinv2 * xlinv1) +
                         xsi_[j] * xa_inv + eta_[j] * bx_inv;
    const double dinv = 1.0 / diagx;
    diagx_inv_[j] = dinv;
    const double w = delx_[j] * dinv;
    std::size_t k = 2 * m;
    for (std::size_t i = 0; i < m; ++i) {
      red[m + i] += gj[i] * w;
      const double gi = gj[i] * dinv;
      for (std::size_t l = i; l < m; ++l) red[k++] += gi * gj[l];
    }
  }
  sum_all(comm_, red);

  // The (m+1) system [Alam a; a^T -zet/z] [dlam; dz] = [blam; delz].
  const int mm = static_cast<int>(m);
  Eigen::MatrixXd AA(mm + 1, mm + 1);
  Eigen::VectorXd bb(mm + 1);
  std::vector<double> dely(m), diagy(m);
  double alam = 0;
  std::size_t k = 2 * m;
  for (std::size_t i = 0; i < m; ++i) {
    const int ii = static_cast<int>(i);
    dely[i] = c_[i] + d_[i] * y_[i] - lam_[i] - epsi / y_[i];
    const double dellam = red[i] - a_[i] * z_ - y_[i] - b[i] + epsi / lam_[i];
    diagy[i] = d_[i] + mu_[i] / y_[i];
    const double diaglamyi = s_[i] / lam_[i] + 1.0 / diagy[i];
    bb(ii) = dellam + dely[i] / diagy[i] - red[m + i];
    for (std::size_t l = i; l < m; ++l) {
      const int ll = static_cast<int>(l);
      AA(ii, ll) = red[k];
      AA(ll, ii) = red[k];
      ++k;
    }
    AA(ii, ii) += diaglamyi;
    AA(ii, mm) = a_[i];
    AA(mm, ii) = a_[i];
    alam += a_[i] * lam_[i];
  }
  AA(mm, mm) = -zet_ / z_;
  bb(mm) = a0_ - alam - epsi / z_;
  if (!AA.allFinite() || !bb.allFinite()) fail("non-finite values in the reduced Newton system");
  const Eigen::VectorXd sol = AA.partialPivLu().solve(bb);
  if (!sol.allFinite()) fail("the reduced Newton system is singular");

  for (std::size_t i = 0; i < m; ++i) dlam_[i] = sol(static_cast<int>(i));
  dz_ = sol(mm);
  for (std::size_t j = 0; j < n_; ++j) {
    const double *gj = G_.data() + j * m;
    double gtdlam = 0;
    for (std::size_t i = 0; i < m; ++i) gtdlam += gj[i] * dlam_[i];
    dx_[j] = -(delx_[j] + gtdlam) * diagx_inv_[j];
    dxsi_[j] = -xsi_[j] + (epsi - xsi_[j] * dx_[j]) * xa_inv_[j];
    deta_[j] = -eta_[j] + (epsi + eta_[j] * dx_[j]) * bx_inv_[j];
  }
  for (std::size_t i = 0; i < m; ++i) {
    dy_[i] = (dlam_[i] - dely[i]) / diagy[i];
    dmu_[i] = -mu_[i] + epsi / y_[i] - mu_[i] * dy_[i] / y_[i];
    ds_[i] = -s_[i] + epsi / lam_[i] - s_[i] * dlam_[i] / lam_[i];
  }
  dzet_ = -zet_ + epsi / z_ - zet_ * dz_ / z_;
}

/// 1 / (largest step keeping every positive quantity positive with the factor 1.01), at least 1.
/// One Allreduce (MPI_MAX).
double detail::MmaSubsolver::max_step_inverse() {
  double local = 0;
  for (std::size_t j = 0; j < n_; ++j) {
    local = std::max({local, -1.01 * dx_[j] * xa_inv_[j], 1.01 * dx_[j] * bx_inv_[j],
                      -1.01 * dxsi_[j] / xsi_[j], -1.01 * deta_[j] / eta_[j]});
  }
  double small = std::max(-1.01 * dz_ / z_, -1.01 * dzet_ / zet_);
  for (std::size_t i = 0; i < m_; ++i) {
    small = std::max({small, -1.01 * dy_[i] / y_[i], -1.01 * dlam_[i] / lam_[i],
                      -1.01 * dmu_[i] / mu_[i], -1.01 * ds_[i] / s_[i]});
  }
  return std::max({max_all(comm_, local), small, 1.0});
}

void detail::MmaSubsolver::save_point() {
  x_old_ = x_, xsi_old_ = xsi_, eta_old_ = eta_;
  y_old_ = y_, lam_old_ = lam_, mu_old_ = mu_, s_old_ = s_;
  z_old_ = z_, zet_old_ = zet_;
}

void detail::MmaSubsolver::take_step(double step) {
  for (std::size_t j = 0; j < n_; ++j) {
    x_[j] = x_old_[j] + step * dx_[j];
    xsi_[j] = xsi_old_[j] + step * dxsi_[j];
    eta_[j] = eta_old_[j] + step * deta_[j];
  }
  for (std::size_t i = 0; i < m_; ++i) {
    y_[i] = y_old_[i] + step * dy_[i];
    lam_[i] = lam_old_[i] + step * dlam_[i];
    mu_[i] = mu_old_[i] + step * dmu_[i];
    s_[i] = s_old_[i] + step * ds_[i];
  }
  z_ = z_old_ + step * dz_;
  zet_ = zet_old_ + step * dzet_;
}

MmaSubproblemInfo detail::MmaSubsolver::solve() {
  MmaSubproblemInfo info;
  // Starting point of subsolv.
  for (std::size_t j = 0; j < n_; ++j) {
    x_[j] = 0.5 * (alfa[j] + beta[j]);
    xsi_[j] = std::max(1.0 / (x_[j] - alfa[j]), 1.0);
    eta_[j] = std::max(1.0 / (beta[j] - x_[j]), 1.0);
  }
  for (std::size_t i = 0; i < m_; ++i) {
    y_[i] = 1, lam_[i] = 1, s_[i] = 1;
    mu_[i] = std::max(1.0, 0.5 * c_[i]);
  }
  z_ = 1, zet_ = 1;

  // Barrier levels epsilon = 10^-k, k = 0, 1, ..., down to epsilon_min (1e-7 by default).
  const int levels = 1 + static_cast<int>(std::floor(-std::log10(epsilon_min_) + 1e-9));
  for (int level = 0; level < levels; ++level) {
    const double epsi = std::pow(10.0, -level);
    double norm = residual_norm(epsi);
    double rmax = residual_max();
    if (!std::isfinite(norm)) fail("non-finite KKT residual (check the gradients)");
    for (int it = 0; rmax > 0.9 * epsi && it < kMaxNewton; ++it) {
      ++info.newton_iterations;
      newton_direction(epsi);
      double step = 1.0 / max_step_inverse();
      save_point();
      double trial = 2.0 * norm;
      for (int t = 0; trial > norm && t < kMaxLineSearch; ++t) {
        take_step(step);
        trial = residual_norm(epsi);
        ++info.line_search_trials;
        step *= 0.5;
      }
      if (!std::isfinite(trial)) fail("non-finite KKT residual in the line search");
      norm = trial;
      rmax = residual_max();
    }
    if (level == levels - 1) {
      info.kkt_residual_max = rmax;
      info.converged = rmax <= 0.9 * epsi;
    }
  }
  return info;
}

namespace {

// Input validation with one Allreduce: every rank finds its first failing check (by index),
// the smallest index over the ranks is reported by every rank.
struct Checks {
  std::vector<std::string> messages;
  int first_failed = std::numeric_limits<int>::max();
  void expect(bool ok, const std::string &message) {
    if (!ok && first_failed == std::numeric_limits<int>::max())
      first_failed = static_cast<int>(messages.size());
    messages.push_back(message);
  }
  void throw_if_failed(MPI_Comm comm, const std::string &where) const {
    int global = first_failed;
    MPI_Allreduce(&first_failed, &global, 1, MPI_INT, MPI_MIN, comm);
    if (global != std::numeric_limits<int>::max())
      throw Error(where + ": " + messages[static_cast<std::size_t>(global)], true);
  }
};

bool same_layout(Vec v, PetscInt n_local, PetscInt n_global) {
  if (!v) return false;
  PetscInt nl = 0, ng = 0;
  FX_PETSC(VecGetLocalSize(v, &nl));
  FX_PETSC(VecGetSize(v, &ng));
  return nl == n_local && ng == n_global;
}

} // namespace

std::unique_ptr<Mma> Mma::create(Vec x_template, int m, const MmaSettings &settings) {
  if (!x_template) throw Error("Mma::create: no template vector", true);
  MPI_Comm comm = MPI_COMM_NULL;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(x_template), &comm));
  std::unique_ptr<Mma> mma(new Mma());
  mma->comm_ = comm;
  mma->m_ = m;
  FX_PETSC(VecGetLocalSize(x_template, &mma->n_local_));
  FX_PETSC(VecGetSize(x_template, &mma->n_global_));

  MmaSettings &s = mma->settings_;
  s = settings;
  const auto mu = static_cast<std::size_t>(std::max(m, 0));
  if (s.a.empty()) s.a.assign(mu, 0.0);
  if (s.c.empty()) s.c.assign(mu, 1000.0);
  if (s.d.empty()) s.d.assign(mu, 1.0);
  Checks checks;
  checks.expect(m >= 0, "the number of constraints is negative");
  checks.expect(s.move_limit > 0 && s.move_limit <= 1, "move_limit must be in (0, 1]");
  checks.expect(s.asymptote_init > 0 && s.asymptote_init <= 1, "asymptote_init must be in (0, 1]");
  checks.expect(s.asymptote_increase >= 1 && std::isfinite(s.asymptote_increase),
                "asymptote_increase must be >= 1");
  checks.expect(s.asymptote_decrease > 0 && s.asymptote_decrease <= 1,
                "asymptote_decrease must be in (0, 1]");
  checks.expect(s.subproblem_epsilon > 0 && s.subproblem_epsilon <= 1,
                "subproblem_epsilon must be in (0, 1]");
  checks.expect(s.a0 > 0 && std::isfinite(s.a0), "a0 must be positive");
  checks.expect(s.a.size() == mu && s.c.size() == mu && s.d.size() == mu,
                "a, c and d must be empty or have one entry per constraint");
  bool coefficients_ok = true;
  for (std::size_t i = 0; i < std::min({mu, s.a.size(), s.c.size(), s.d.size()}); ++i) {
    coefficients_ok = coefficients_ok && s.a[i] >= 0 && s.c[i] >= 0 && s.d[i] >= 0 &&
                      s.c[i] + s.d[i] > 0 && std::isfinite(s.a[i]) && std::isfinite(s.c[i]) &&
                      std::isfinite(s.d[i]);
  }
  checks.expect(coefficients_ok, "a_i, c_i, d_i must be finite and >= 0 with c_i + d_i > 0");
  checks.throw_if_failed(comm, "Mma::create");

  FX_PETSC(VecDuplicate(x_template, &mma->xold1_));
  FX_PETSC(VecDuplicate(x_template, &mma->xold2_));
  FX_PETSC(VecDuplicate(x_template, &mma->low_));
  FX_PETSC(VecDuplicate(x_template, &mma->upp_));
  FX_PETSC(VecZeroEntries(mma->xold1_));
  FX_PETSC(VecZeroEntries(mma->xold2_));
  FX_PETSC(VecZeroEntries(mma->low_));
  FX_PETSC(VecZeroEntries(mma->upp_));
  mma->sub_ = std::make_unique<detail::MmaSubsolver>(
      comm, m, static_cast<std::size_t>(mma->n_local_), mma->settings_);
  mma->lam_.assign(mu, 0.0);
  mma->y_.assign(mu, 0.0);
  return mma;
}

Mma::~Mma() {
  VecDestroy(&xold1_);
  VecDestroy(&xold2_);
  VecDestroy(&low_);
  VecDestroy(&upp_);
}

void Mma::update(Vec x, Vec xmin, Vec xmax, double f0, Vec df0, const std::vector<double> &f,
                 const std::vector<Vec> &df) {
  LogScope scope("MMA update");
  const auto m = static_cast<std::size_t>(m_);
  const auto n = static_cast<std::size_t>(n_local_);

  // Arguments: counts and layouts first (the arrays are only read if they are right).
  Checks checks;
  checks.expect(f.size() == m && df.size() == m,
                "f and df must have one entry per constraint (m = " + std::to_string(m_) + ")");
  checks.expect(same_layout(x, n_local_, n_global_), "x does not have the template's layout");
  checks.expect(same_layout(xmin, n_local_, n_global_), "xmin does not have the template's layout");
  checks.expect(same_layout(xmax, n_local_, n_global_), "xmax does not have the template's layout");
  checks.expect(same_layout(df0, n_local_, n_global_), "df0 does not have the template's layout");
  for (std::size_t i = 0; i < m; ++i) {
    checks.expect(i < df.size() && same_layout(df[i], n_local_, n_global_),
                  "df[" + std::to_string(i) + "] does not have the template's layout");
  }
  checks.throw_if_failed(comm_, "Mma::update");

  const MmaSettings &s = settings_;
  const int iter = iteration_ + 1; // Svanberg's iteration number (1-based)
  detail::MmaSubsolver &sub = *sub_;
  {
    ReadArray xa(x), xmina(xmin), xmaxa(xmax), df0a(df0);
    std::vector<std::unique_ptr<ReadArray>> dfa;
    for (std::size_t i = 0; i < m; ++i) dfa.push_back(std::make_unique<ReadArray>(df[i]));

    bool bounds_ok = true, inside = true, finite = std::isfinite(f0);
    for (std::size_t i = 0; i < m; ++i) finite = finite && std::isfinite(f[i]);
    for (std::size_t j = 0; j < n; ++j) {
      const auto jj = static_cast<PetscInt>(j);
      bounds_ok = bounds_ok && xmina[jj] < xmaxa[jj];
      inside = inside && xmina[jj] <= xa[jj] && xa[jj] <= xmaxa[jj];
      bool fin = std::isfinite(df0a[jj]) && std::isfinite(xmina[jj]) && std::isfinite(xmaxa[jj]);
      for (std::size_t i = 0; i < m; ++i) fin = fin && std::isfinite((*dfa[i])[jj]);
      finite = finite && fin;
    }
    Checks values;
    values.expect(finite, "non-finite value in f0, f, df0, df, xmin or xmax");
    values.expect(bounds_ok, "xmin_j < xmax_j is violated for some j");
    values.expect(inside, "x is outside [xmin, xmax] for some j");
    values.throw_if_failed(comm_, "Mma::update");

    // Asymptotes, move bounds and approximation (mmasub).
    ReadArray xold1a(iter > 2 ? xold1_ : x), xold2a(iter > 2 ? xold2_ : x);
    ReadArray lowa(low_), uppa(upp_);
    std::vector<double> b_local(m, 0.0);
    for (std::size_t j = 0; j < n; ++j) {
      const auto jj = static_cast<PetscInt>(j);
      const double xv = xa[jj], range = xmaxa[jj] - xmina[jj];
      double low, upp;
      if (iter <= 2) {
        low = xv - s.asymptote_init * range;
        upp = xv + s.asymptote_init * range;
      } else {
        const double zzz = (xv - xold1a[jj]) * (xold1a[jj] - xold2a[jj]);
        const double factor =
            zzz > 0 ? s.asymptote_increase : (zzz < 0 ? s.asymptote_decrease : 1.0);
        low = xv - factor * (xold1a[jj] - lowa[jj]);
        upp = xv + factor * (uppa[jj] - xold1a[jj]);
        low = std::min(std::max(low, xv - kAsymptoteMax * range), xv - kAsymptoteMin * range);
        upp = std::max(std::min(upp, xv + kAsymptoteMax * range), xv + kAsymptoteMin * range);
      }
      sub.low[j] = low;
      sub.upp[j] = upp;
      sub.alfa[j] = std::max({low + kAlbefa * (xv - low), xv - s.move_limit * range, xmina[jj]});
      sub.beta[j] = std::min({upp - kAlbefa * (upp - xv), xv + s.move_limit * range, xmaxa[jj]});

      const double xmamiinv = 1.0 / std::max(range, kXmamiMin);
      const double ux1 = upp - xv, xl1 = xv - low;
      const double ux2 = ux1 * ux1, xl2 = xl1 * xl1;
      const double g0 = df0a[jj];
      const double p0 = std::max(g0, 0.0), q0 = std::max(-g0, 0.0);
      const double pq0 = 0.001 * (p0 + q0) + kRaa0 * xmamiinv;
      sub.p0[j] = (p0 + pq0) * ux2;
      sub.q0[j] = (q0 + pq0) * xl2;
      for (std::size_t i = 0; i < m; ++i) {
        const double g = (*dfa[i])[jj];
        const double p = std::max(g, 0.0), q = std::max(-g, 0.0);
        const double pq = 0.001 * (p + q) + kRaa0 * xmamiinv;
        const double pij = (p + pq) * ux2, qij = (q + pq) * xl2;
        sub.P[j * m + i] = pij;
        sub.Q[j * m + i] = qij;
        b_local[i] += pij / ux1 + qij / xl1;
      }
    }
    sum_all(comm_, b_local);
    for (std::size_t i = 0; i < m; ++i) sub.b[i] = b_local[i] - f[i];
  } // the input arrays are restored here

  const MmaSubproblemInfo info = sub.solve(); // throws (collectively) on breakdown

  // Commit: shift the history, store the asymptotes, write the new iterate.
  {
    WriteArray lowa(low_), uppa(upp_);
    for (std::size_t j = 0; j < n; ++j) {
      lowa[static_cast<PetscInt>(j)] = sub.low[j];
      uppa[static_cast<PetscInt>(j)] = sub.upp[j];
    }
  }
  if (iter == 1) FX_PETSC(VecCopy(x, xold1_));
  FX_PETSC(VecCopy(xold1_, xold2_));
  FX_PETSC(VecCopy(x, xold1_));
  {
    WriteArray xw(x);
    for (std::size_t j = 0; j < n; ++j) xw[static_cast<PetscInt>(j)] = sub.x()[j];
  }
  lam_ = sub.lam();
  y_ = sub.y();
  z_ = sub.z();
  info_ = info;
  iteration_ = iter;
}

void Mma::restore(const State &state) {
  Checks checks;
  checks.expect(state.iteration >= 0, "negative iteration count");
  const bool need_vecs = state.iteration > 0;
  checks.expect(!need_vecs || (same_layout(state.xold1, n_local_, n_global_) &&
                               same_layout(state.xold2, n_local_, n_global_) &&
                               same_layout(state.low, n_local_, n_global_) &&
                               same_layout(state.upp, n_local_, n_global_)),
                "the state's vectors do not have the design vector's layout");
  checks.throw_if_failed(comm_, "Mma::restore");
  if (need_vecs) {
    FX_PETSC(VecCopy(state.xold1, xold1_));
    FX_PETSC(VecCopy(state.xold2, xold2_));
    FX_PETSC(VecCopy(state.low, low_));
    FX_PETSC(VecCopy(state.upp, upp_));
  }
  iteration_ = state.iteration;
}

double max_abs_change(Vec a, Vec b) {
  MPI_Comm comm = MPI_COMM_NULL;
  FX_PETSC(PetscObjectGetComm(reinterpret_cast<PetscObject>(a), &comm));
  PetscInt na = 0, nb = 0;
  FX_PETSC(VecGetLocalSize(a, &na));
  FX_PETSC(VecGetLocalSize(b, &nb));
  Checks checks;
  checks.expect(na == nb, "the vectors have different layouts");
  checks.throw_if_failed(comm, "max_abs_change");
  ReadArray aa(a), ba(b);
  double local = 0;
  for (PetscInt j = 0; j < na; ++j) {
    const double diff = std::abs(aa[j] - ba[j]);
    if (std::isnan(diff)) {
      local = std::numeric_limits<double>::infinity();
      break;
    }
    local = std::max(local, diff);
  }
  return max_all(comm, local);
}

} // namespace flexopt::optimize
