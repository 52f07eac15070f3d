// The Method of Moving Asymptotes on problems with known optima, on any number of ranks:
// Svanberg's toy problem (2007 notes) and five-segment cantilever (1987), a separable problem
// with 1000 variables and an analytic optimum, the same iterates on a distributed and a
// sequential vector, bit-identical restart, the bound-constrained case m = 0, and input errors.
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/optimize/mma.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <gtest/gtest.h>
#include <petscvec.h>
#include <vector>

using namespace flexopt;
using optimize::Mma;
using optimize::MmaSettings;

namespace {

/// A separable test problem: f_k(x) = sum_j term_k(j, x_j) + constant_k for k = 0 (objective)
/// and k = 1..m (constraints, <= 0 when satisfied).
struct Problem {
  PetscInt n = 0;
  int m = 0;
  std::function<double(PetscInt)> lower, upper, start;
  /// Adds the terms of component j (global index) at value x to f[0..m]; sets g[k] to their
  /// derivative with respect to x.
  std::function<void(PetscInt j, double x, double *f, double *g)> term;
  std::vector<double> constant; // m + 1 entries
};

/// Owns the vectors of one MMA run of a Problem on a communicator.
class Driver {
public:
  Driver(MPI_Comm comm, const Problem &p, const MmaSettings &settings) : comm_(comm), p_(p) {
    FX_PETSC(VecCreate(comm, &x_));
    FX_PETSC(VecSetSizes(x_, PETSC_DECIDE, p.n));
    FX_PETSC(VecSetType(x_, VECSTANDARD));
    for (Vec *v : {&x_prev_, &xmin_, &xmax_, &df0_}) FX_PETSC(VecDuplicate(x_, v));
    df_.resize(static_cast<std::size_t>(p.m));
    for (Vec &v : df_) FX_PETSC(VecDuplicate(x_, &v));
    PetscInt lo = 0, hi = 0;
    FX_PETSC(VecGetOwnershipRange(x_, &lo, &hi));
    PetscScalar *xa, *la, *ua;
    FX_PETSC(VecGetArray(x_, &xa));
    FX_PETSC(VecGetArray(xmin_, &la));
    FX_PETSC(VecGetArray(xmax_, &ua));
    for (PetscInt j = lo; j < hi; ++j) {
      xa[j - lo] = p.start(j);
      la[j - lo] = p.lower(j);
      ua[j - lo] = p.upper(j);
    }
    FX_PETSC(VecRestoreArray(x_, &xa));
    FX_PETSC(VecRestoreArray(xmin_, &la));
    FX_PETSC(VecRestoreArray(xmax_, &ua));
    mma = Mma::create(x_, p.m, settings);
  }
  ~Driver() {
    mma.reset();
    for (Vec *v : {&x_, &x_prev_, &xmin_, &xmax_, &df0_}) VecDestroy(v);
    for (Vec &v : df_) VecDestroy(&v);
  }
  Driver(const Driver &) = delete;
  Driver &operator=(const Driver &) = delete;

  /// f (objective, constraints) at x on every rank; gradients into df0, df. Collective.
  void evaluate() {
    const auto m1 = static_cast<std::size_t>(p_.m) + 1;
    values.assign(m1, 0.0);
    std::vector<double> g(m1);
    PetscInt lo = 0, hi = 0;
    FX_PETSC(VecGetOwnershipRange(x_, &lo, &hi));
    const PetscScalar *xa;
    PetscScalar *g0;
    std::vector<PetscScalar *> gi(df_.size());
    FX_PETSC(VecGetArrayRead(x_, &xa));
    FX_PETSC(VecGetArray(df0_, &g0));
    for (std::size_t i = 0; i < df_.size(); ++i) FX_PETSC(VecGetArray(df_[i], &gi[i]));
    for (PetscInt j = lo; j < hi; ++j) {
      p_.term(j, xa[j - lo], values.data(), g.data());
      g0[j - lo] = g[0];
      for (std::size_t i = 0; i < df_.size(); ++i) gi[i][j - lo] = g[i + 1];
    }
    for (std::size_t i = 0; i < df_.size(); ++i) FX_PETSC(VecRestoreArray(df_[i], &gi[i]));
    FX_PETSC(VecRestoreArray(df0_, &g0));
    FX_PETSC(VecRestoreArrayRead(x_, &xa));
    MPI_Allreduce(MPI_IN_PLACE, values.data(), static_cast<int>(m1), MPI_DOUBLE, MPI_SUM, comm_);
    for (std::size_t k = 0; k < m1; ++k) values[k] += p_.constant[k];
  }

  /// One MMA iteration; returns max |x_new - x_old|. Collective.
  double iterate() {
    evaluate();
    FX_PETSC(VecCopy(x_, x_prev_));
    const std::vector<double> f(values.begin() + 1, values.end());
    mma->update(x_, xmin_, xmax_, values[0], df0_, f, df_);
    return optimize::max_abs_change(x_, x_prev_);
  }

  /// Iterates until max |x_new - x_old| < tol (or max_iterations); evaluates the final x.
  /// Returns the number of iterations. Collective.
  int solve(int max_iterations, double tol) {
    int k = 0;
    while (k < max_iterations) {
      ++k;
      if (iterate() < tol) break;
    }
    evaluate();
    return k;
  }

  /// The global x on every rank. Collective.
  std::vector<double> gather_all() const { return gather(true); }
  /// The global x on rank 0 (empty elsewhere). Collective.
  std::vector<double> gather_zero() const { return gather(false); }

  Vec x() const { return x_; }
  std::unique_ptr<Mma> mma;
  std::vector<double> values; // of the last evaluate(): f0, f_1..f_m

private:
  std::vector<double> gather(bool to_all) const {
    VecScatter scatter;
    Vec full;
    if (to_all)
      FX_PETSC(VecScatterCreateToAll(x_, &scatter, &full));
    else
      FX_PETSC(VecScatterCreateToZero(x_, &scatter, &full));
    FX_PETSC(VecScatterBegin(scatter, x_, full, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecScatterEnd(scatter, x_, full, INSERT_VALUES, SCATTER_FORWARD));
    PetscInt n = 0;
    FX_PETSC(VecGetLocalSize(full, &n));
    const PetscScalar *a;
    FX_PETSC(VecGetArrayRead(full, &a));
    std::vector<double> out(a, a + n);
    FX_PETSC(VecRestoreArrayRead(full, &a));
    FX_PETSC(VecScatterDestroy(&scatter));
    FX_PETSC(VecDestroy(&full));
    return out;
  }

  MPI_Comm comm_;
  Problem p_;
  Vec x_ = nullptr, x_prev_ = nullptr, xmin_ = nullptr, xmax_ = nullptr, df0_ = nullptr;
  std::vector<Vec> df_;
};

bool is_root() {
  return comm_rank(PETSC_COMM_WORLD) == 0;
}

/// Svanberg's toy problem (2007 notes): minimize |x|^2 subject to two balls of
/// radius 3 around (5, 2, 1) and (3, 4, 3), 0 <= x_j <= 5, from (4, 3, 2).
Problem toy_problem() {
  Problem p;
  p.n = 3, p.m = 2;
  p.lower = [](PetscInt) { return 0.0; };
  p.upper = [](PetscInt) { return 5.0; };
  p.start = [](PetscInt j) { return 4.0 - static_cast<double>(j); };
  p.term = [](PetscInt j, double x, double *f, double *g) {
    static const double c1[3] = {5, 2, 1}, c2[3] = {3, 4, 3};
    const double d1 = x - c1[j], d2 = x - c2[j];
    f[0] += x * x, f[1] += d1 * d1, f[2] += d2 * d2;
    g[0] = 2 * x, g[1] = 2 * d1, g[2] = 2 * d2;
  };
  p.constant = {0.0, -9.0, -9.0};
  return p;
}

/// The toy problem's minimizer, derived independently: both spheres have radius 3, so they
/// meet in the plane -x1 + x2 + x3 = 1 on a circle of radius sqrt(6) around the midpoint
/// m = (4, 3, 2) of the centres; the point of that circle closest to the origin lies in the
/// direction of the origin's projection p = (-1, 1, 1)/3 onto the plane, seen from m.
std::vector<double> toy_minimizer() {
  const double m[3] = {4, 3, 2}, p[3] = {-1.0 / 3, 1.0 / 3, 1.0 / 3};
  double d[3], len = 0;
  for (int k = 0; k < 3; ++k) d[k] = p[k] - m[k], len += d[k] * d[k];
  len = std::sqrt(len);
  std::vector<double> x(3);
  for (int k = 0; k < 3; ++k) x[static_cast<std::size_t>(k)] = m[k] + std::sqrt(6.0) * d[k] / len;
  return x;
}

/// Svanberg's (1987) five-segment cantilever: minimize C1 sum x_j subject to
/// sum c_j / x_j^3 <= C2 = 1, 1 <= x_j <= 10, from x_j = 5.
constexpr double kC1 = 0.0624;
constexpr double kCantileverC[5] = {61, 37, 19, 7, 1};

Problem cantilever_problem() {
  Problem p;
  p.n = 5, p.m = 1;
  p.lower = [](PetscInt) { return 1.0; };
  p.upper = [](PetscInt) { return 10.0; };
  p.start = [](PetscInt) { return 5.0; };
  p.term = [](PetscInt j, double x, double *f, double *g) {
    const double c = kCantileverC[j];
    f[0] += kC1 * x, f[1] += c / (x * x * x);
    g[0] = kC1, g[1] = -3 * c / (x * x * x * x);
  };
  p.constant = {0.0, -1.0};
  return p;
}

/// A separable problem with n variables: minimize (1/n) sum_j w_j / x_j subject to
/// sum_j v_j x_j <= V (written as sum_j v_j x_j / V - 1 <= 0), 0.2 <= x_j <= 4, from x_j = 1,
/// with V = sum_j v_j (so the start is feasible, and the constraint is active at the optimum).
/// Lagrange: x*_j = V sqrt(w_j / v_j) / S with S = sum_j sqrt(w_j v_j), f0* = S^2 / (n V), and
/// the multiplier of the normalised constraint equals f0*. With w, v in [0.5, 1.5] x*_j lies in
/// [0.60, 1.79]: the bounds are inactive.
constexpr PetscInt kLargeN = 1000;
double weight_w(PetscInt j) {
  return 1.0 + 0.5 * std::sin(0.7 * static_cast<double>(j));
}
double weight_v(PetscInt j) {
  return 1.0 + 0.5 * std::cos(1.3 * static_cast<double>(j) + 0.2);
}
double large_volume() {
  double v = 0;
  for (PetscInt j = 0; j < kLargeN; ++j) v += weight_v(j);
  return v;
}

Problem large_problem() {
  Problem p;
  p.n = kLargeN, p.m = 1;
  p.lower = [](PetscInt) { return 0.2; };
  p.upper = [](PetscInt) { return 4.0; };
  p.start = [](PetscInt) { return 1.0; };
  const double volume = large_volume();
  p.term = [volume](PetscInt j, double x, double *f, double *g) {
    const double w = weight_w(j) / static_cast<double>(kLargeN), v = weight_v(j) / volume;
    f[0] += w / x, f[1] += v * x;
    g[0] = -w / (x * x), g[1] = v;
  };
  p.constant = {0.0, -1.0};
  return p;
}

struct LargeOptimum {
  std::vector<double> x;
  double f0;
};

LargeOptimum large_optimum() {
  const double volume = large_volume();
  double s = 0;
  for (PetscInt j = 0; j < kLargeN; ++j) s += std::sqrt(weight_w(j) * weight_v(j));
  LargeOptimum o;
  for (PetscInt j = 0; j < kLargeN; ++j)
    o.x.push_back(volume * std::sqrt(weight_w(j) / weight_v(j)) / s);
  o.f0 = s * s / (static_cast<double>(kLargeN) * volume);
  return o;
}

double max_abs(const std::vector<double> &a) {
  double r = 0;
  for (double v : a) r = std::max(r, std::abs(v));
  return r;
}

double max_abs_diff(const std::vector<double> &a, const std::vector<double> &b) {
  double r = 0;
  for (std::size_t k = 0; k < std::min(a.size(), b.size()); ++k)
    r = std::max(r, std::abs(a[k] - b[k]));
  return r;
}

void report(const char *name, const Driver &d, int iterations, double seconds) {
  const auto &info = d.mma->last_subproblem();
  if (is_root())
    std::printf("[   info   ] %s: %d MMA iterations, f0 = %.10f, last subproblem %d Newton steps "
                "(KKT residual %.1e), %.3f s\n",
                name, iterations, d.values[0], info.newton_iterations, info.kkt_residual_max,
                seconds);
}

} // namespace

// 1. With 3 variables on 2 ranks the vector is split 2 + 1. The optimum is known in closed form
// (toy_minimizer): f* = 8.770246... The iteration stops when no x_j moves by 1e-9; MMA
// converges to the KKT point, so f0 meets f* to 1e-6 relative (it is a smooth function of x,
// |grad f0| ~ 6, so an x error of 1e-7 is a relative error of ~1e-7) and both constraints are
// active to 1e-5 (and not violated by more than 1e-6); the multipliers satisfy stationarity.
TEST(Mma, ToyProblemOfSvanberg2007) {
  const double t0 = wall_time();
  Driver d(PETSC_COMM_WORLD, toy_problem(), MmaSettings{});
  const int iterations = d.solve(100, 1e-9);
  report("toy problem", d, iterations, wall_time() - t0);
  const auto x = d.gather_all();
  const auto x_star = toy_minimizer();
  const double f_star = x_star[0] * x_star[0] + x_star[1] * x_star[1] + x_star[2] * x_star[2];
  EXPECT_NEAR(f_star, 8.770246, 1e-6); // the published value, to its 7 digits
  EXPECT_NEAR(d.values[0], f_star, 1e-6 * f_star);
  const double published[3] = {2.0175, 1.7800, 1.2375}; // 2007 notes, 4 decimals
  for (std::size_t j = 0; j < 3; ++j) {
    EXPECT_NEAR(x[j], x_star[j], 1e-6) << "j = " << j;
    EXPECT_NEAR(x[j], published[j], 1e-3) << "j = " << j;
  }
  for (int i = 1; i <= 2; ++i) {
    EXPECT_GE(d.values[static_cast<std::size_t>(i)], -1e-5) << "constraint " << i << " inactive";
    EXPECT_LE(d.values[static_cast<std::size_t>(i)], 1e-6) << "constraint " << i << " violated";
    EXPECT_GT(d.mma->multipliers()[static_cast<std::size_t>(i - 1)], 0.0);
  }
  // Stationarity with the subproblem's multipliers: grad f0 + sum_i lambda_i grad f_i = 0. The
  // Hessian of the Lagrangian is 2 (1 + lambda_1 + lambda_2) I ~ 4.4 I, so x errors of 1e-7 give
  // 5e-7; checked to 1e-5.
  const auto &lam = d.mma->multipliers();
  const double c1[3] = {5, 2, 1}, c2[3] = {3, 4, 3};
  for (std::size_t j = 0; j < 3; ++j)
    EXPECT_NEAR(2 * x[j] + 2 * lam[0] * (x[j] - c1[j]) + 2 * lam[1] * (x[j] - c2[j]), 0.0, 1e-5)
        << "j = " << j;
  EXPECT_LE(d.mma->y()[0], 1e-6); // the artificial variables vanish: the problem is feasible
  EXPECT_LE(d.mma->y()[1], 1e-6);
  EXPECT_LT(iterations, 100);
}

// 2. Optimum by Lagrange: x_j = k c_j^(1/4) with k = (sum c^(1/4))^(1/3), f* = C1 (sum
// c^(1/4))^(4/3) = 1.339956, multiplier lambda = f*/3. Tolerances as in the toy problem.
TEST(Mma, CantileverOfSvanberg1987) {
  const double t0 = wall_time();
  Driver d(PETSC_COMM_WORLD, cantilever_problem(), MmaSettings{});
  const int iterations = d.solve(100, 1e-7);
  report("cantilever", d, iterations, wall_time() - t0);
  const auto x = d.gather_all();
  double s = 0;
  for (double c : kCantileverC) s += std::pow(c, 0.25);
  const double k = std::cbrt(s), f_star = kC1 * std::pow(s, 4.0 / 3.0);
  EXPECT_NEAR(f_star, 1.339956, 1e-6);
  EXPECT_NEAR(d.values[0], f_star, 1e-5 * f_star);
  const double published[5] = {6.016, 5.3092, 4.4943, 3.5015, 2.1527};
  for (std::size_t j = 0; j < 5; ++j) {
    EXPECT_NEAR(x[j], k * std::pow(kCantileverC[j], 0.25), 1e-5) << "j = " << j;
    EXPECT_NEAR(x[j], published[j], 1e-3) << "j = " << j;
  }
  EXPECT_NEAR(d.values[1], 0.0, 1e-6);
  EXPECT_NEAR(d.mma->multipliers()[0], f_star / 3, 1e-5 * f_star);
}

// 3. 1000 variables distributed over the ranks: every sum over x goes through the reductions.
// 30 iterations (MMA reaches the optimum's neighbourhood after ~10). The subproblem is solved
// to an absolute KKT accuracy of about epsilon (MmaSettings::subproblem_epsilon), which limits
// what the iterates can show:
//  * the constraint slack of the subproblem is s = epsilon / lambda, and f0 - f0* ~ lambda s =
//    epsilon (absolute; f0* = 0.94): f0 to 10 epsilon relative;
//  * x_j is determined to ~ epsilon / (curvature of the approximation in x_j) and the smallest
//    curvature, 2 w_j / (n x_j^3) >= 2 * 0.5 / (1000 * 1.79^3) = 1.7e-4, gives 6e3 epsilon;
//    checked to 1e4 epsilon;
//  * the multiplier lambda = f0* to 1e3 epsilon relative.
// With the default epsilon = 1e-7 this is f0 to 1e-6 relative and x to 1e-3; with 1e-10 the
// same run shows the optimum to 1e-9 / 1e-6.
class MmaLarge : public ::testing::TestWithParam<double> {};

TEST_P(MmaLarge, SeparableProblemReachesTheLagrangeOptimum) {
  const double epsilon = GetParam();
  MmaSettings settings;
  settings.subproblem_epsilon = epsilon;
  const double t0 = wall_time();
  Driver d(PETSC_COMM_WORLD, large_problem(), settings);
  const int iterations = d.solve(30, 0.0);
  report(epsilon < 1e-8 ? "1000 variables, epsilon 1e-10" : "1000 variables", d, iterations,
         wall_time() - t0);
  const auto x = d.gather_all();
  const LargeOptimum o = large_optimum();
  EXPECT_NEAR(d.values[0], o.f0, 10 * epsilon * o.f0);
  EXPECT_LE(max_abs_diff(x, o.x), 1e4 * epsilon);
  EXPECT_LE(d.values[1], 0.0);           // feasible: the slack is positive
  EXPECT_GE(d.values[1], -10 * epsilon); // and of the size of the barrier parameter
  EXPECT_NEAR(d.mma->multipliers()[0], o.f0, 1e3 * epsilon * o.f0);
  if (is_root())
    std::printf("[   info   ] |x - x*| = %.2e, f0/f0* - 1 = %.2e\n", max_abs_diff(x, o.x),
                d.values[0] / o.f0 - 1);
}

INSTANTIATE_TEST_SUITE_P(Mma, MmaLarge, ::testing::Values(1e-7, 1e-10));

// 4. The same iterates whatever the distribution: every rank solves the whole problem on
// PETSC_COMM_SELF, then all ranks solve it together on PETSC_COMM_WORLD; each distributed
// iterate, gathered on rank 0, must equal rank 0's sequential iterate to 1e-12 relative. Only
// the order of summation in the reductions differs (relative rounding ~ n eps = 2e-13 at worst
// per sum, ~1e-15 typical; every branch of the solver, Newton-step and line-search counts, is
// taken identically), and on this problem MMA's iteration map does not amplify perturbations
// (measured: 2e-14). It can: with the bounds [0.1, 10] instead of [0.2, 4] the early iterates
// swing between the move limits and the same rounding grows to 4e-11 (docs/theory-mma.md).
TEST(Mma, IteratesDoNotDependOnTheDistribution) {
  const Problem p = large_problem();
  constexpr int kIterations = 30;
  std::vector<std::vector<double>> sequential;
  {
    Driver d(PETSC_COMM_SELF, p, MmaSettings{});
    for (int k = 0; k < kIterations; ++k) {
      d.iterate();
      sequential.push_back(d.gather_all());
    }
  }
  Driver d(PETSC_COMM_WORLD, p, MmaSettings{});
  double worst = 0;
  for (int k = 0; k < kIterations; ++k) {
    d.iterate();
    const auto x = d.gather_zero();
    if (is_root()) {
      const auto &xs = sequential[static_cast<std::size_t>(k)];
      ASSERT_EQ(x.size(), xs.size());
      const double rel = max_abs_diff(x, xs) / max_abs(xs);
      worst = std::max(worst, rel);
      EXPECT_LE(rel, 1e-12) << "iteration " << k + 1;
    }
  }
  if (is_root())
    std::printf("[   info   ] %d ranks vs 1: largest relative difference of an iterate %.2e\n",
                comm_size(PETSC_COMM_WORLD), worst);
}

// 5. Restart: the state after k iterations, copied out, the Mma destroyed, restored into a new
// one: the continued run equals the uninterrupted run bit for bit (k = 1, 2 cover the
// iterations in which the asymptotes are re-initialised).
class MmaRestart : public ::testing::TestWithParam<int> {};

TEST_P(MmaRestart, ContinuesBitIdentically) {
  const int k = GetParam();
  constexpr int kMore = 10;
  const Problem p = large_problem();
  Driver reference(PETSC_COMM_WORLD, p, MmaSettings{});
  for (int it = 0; it < k; ++it) reference.iterate();

  Driver restarted(PETSC_COMM_WORLD, p, MmaSettings{});
  for (int it = 0; it < k; ++it) restarted.iterate();
  // Copy the state out (as a restart file would), then replace the optimizer.
  const Mma::State live = restarted.mma->state();
  Mma::State saved{live.iteration, nullptr, nullptr, nullptr, nullptr};
  for (auto [from, to] : {std::pair{live.xold1, &saved.xold1}, std::pair{live.xold2, &saved.xold2},
                          std::pair{live.low, &saved.low}, std::pair{live.upp, &saved.upp}}) {
    FX_PETSC(VecDuplicate(from, to));
    FX_PETSC(VecCopy(from, *to));
  }
  restarted.mma = Mma::create(restarted.x(), p.m, MmaSettings{});
  EXPECT_EQ(restarted.mma->iteration(), 0);
  restarted.mma->restore(saved);
  EXPECT_EQ(restarted.mma->iteration(), k);
  for (Vec *v : {&saved.xold1, &saved.xold2, &saved.low, &saved.upp}) VecDestroy(v);

  for (int it = 0; it < kMore; ++it) {
    reference.iterate();
    restarted.iterate();
    EXPECT_EQ(optimize::max_abs_change(reference.x(), restarted.x()), 0.0)
        << "iteration " << k + it + 1;
  }
  EXPECT_EQ(restarted.mma->iteration(), k + kMore);
}

INSTANTIATE_TEST_SUITE_P(Mma, MmaRestart, ::testing::Values(1, 2, 5));

// 6. m = 0: minimize sum (x_j - t_j)^2 in a box with every t_j outside it, so the minimizer is
// t clipped to the box. The (m+1) system degenerates to the z-row. The iterate reaches the bound
// up to the barrier: x_j - xmin_j = epsilon / xsi_j with xsi_j = |f0'| >= 2, so to 1e-7. (An
// interior minimizer of a problem without constraints is only found to ~1% of xmax - xmin by
// MMA: see docs/theory-mma.md, "Limitations".)
TEST(Mma, BoundConstrainedProblemWithoutConstraints) {
  Problem p;
  p.n = 7, p.m = 0;
  p.lower = [](PetscInt) { return -1.0; };
  p.upper = [](PetscInt) { return 2.0; };
  p.start = [](PetscInt j) { return -0.5 + 0.3 * static_cast<double>(j); };
  auto target = [](PetscInt j) { return j % 2 ? -2.0 - static_cast<double>(j) : 3.0 + 0.5 * j; };
  p.term = [target](PetscInt j, double x, double *f, double *g) {
    const double r = x - target(j);
    f[0] += r * r, g[0] = 2 * r;
  };
  p.constant = {0.0};
  Driver d(PETSC_COMM_WORLD, p, MmaSettings{});
  const int iterations = d.solve(100, 1e-9);
  EXPECT_LT(iterations, 100);
  const auto x = d.gather_all();
  for (PetscInt j = 0; j < p.n; ++j)
    EXPECT_NEAR(x[static_cast<std::size_t>(j)], std::clamp(target(j), -1.0, 2.0), 1e-7)
        << "j = " << j;
}

// 7. Invalid input is reported on every rank as a collective flexopt::Error, and leaves x and
// the state unchanged.
TEST(Mma, InvalidInputIsACollectiveError) {
  Vec x;
  FX_PETSC(VecCreate(PETSC_COMM_WORLD, &x));
  FX_PETSC(VecSetSizes(x, PETSC_DECIDE, 5));
  FX_PETSC(VecSetType(x, VECSTANDARD));
  MmaSettings bad;
  bad.move_limit = 0;
  try {
    Mma::create(x, 1, bad);
    ADD_FAILURE() << "no error for move_limit = 0";
  } catch (const Error &e) {
    EXPECT_TRUE(e.collective());
    EXPECT_NE(std::string(e.what()).find("move_limit"), std::string::npos) << e.what();
  }
  MmaSettings wrong_size;
  wrong_size.c = {1000, 1000};
  EXPECT_THROW(Mma::create(x, 1, wrong_size), Error);

  Driver d(PETSC_COMM_WORLD, cantilever_problem(), MmaSettings{});
  d.iterate();
  // x outside its bounds on the last rank only: still an error on every rank.
  Vec xmin, xmax, g;
  for (Vec *v : {&xmin, &xmax, &g}) FX_PETSC(VecDuplicate(d.x(), v));
  FX_PETSC(VecSet(xmin, 1.0));
  FX_PETSC(VecSet(xmax, 10.0));
  FX_PETSC(VecSet(g, 1.0));
  if (comm_rank(PETSC_COMM_WORLD) == comm_size(PETSC_COMM_WORLD) - 1) {
    PetscInt lo = 0, hi = 0;
    FX_PETSC(VecGetOwnershipRange(d.x(), &lo, &hi));
    if (hi > lo) FX_PETSC(VecSetValue(d.x(), lo, 11.0, INSERT_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(d.x()));
  FX_PETSC(VecAssemblyEnd(d.x()));
  Vec before;
  FX_PETSC(VecDuplicate(d.x(), &before));
  FX_PETSC(VecCopy(d.x(), before));
  try {
    d.mma->update(d.x(), xmin, xmax, 1.0, g, {0.0}, {g});
    ADD_FAILURE() << "no error for x outside its bounds";
  } catch (const Error &e) {
    EXPECT_TRUE(e.collective());
    EXPECT_NE(std::string(e.what()).find("outside"), std::string::npos) << e.what();
  }
  EXPECT_EQ(optimize::max_abs_change(d.x(), before), 0.0);
  EXPECT_EQ(d.mma->iteration(), 1);
  // Wrong number of constraint values.
  EXPECT_THROW(d.mma->update(d.x(), xmin, xmax, 1.0, g, {}, {}), Error);
  for (Vec *v : {&xmin, &xmax, &g, &before, &x}) VecDestroy(v);
}
