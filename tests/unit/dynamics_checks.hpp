#pragma once
// Checks shared by the rigid and the FFRF dynamics tests: the mechanism's and the step
// residual's Jacobians next to their central differences, and the dense and sparse Newton paths.
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <array>
#include <cstdio>
#include <gtest/gtest.h>
#include <memory>
#include <stdexcept>
#include <string>

namespace test_support {

/// An analytic Jacobian and its central-difference counterpart.
struct Derivative {
  flexopt::dynamics::Matrix analytic, differences;
};

/// Central-difference Jacobian (step 1e-6) of f at x.
template <class F>
flexopt::dynamics::Matrix central_differences(F f, const flexopt::dynamics::Vector &x) {
  const flexopt::dynamics::Vector f0 = f(x);
  flexopt::dynamics::Matrix J(f0.size(), x.size());
  for (int j = 0; j < x.size(); ++j) {
    flexopt::dynamics::Vector a = x, b = x;
    a(j) += 1e-6, b(j) -= 1e-6;
    J.col(j) = (f(a) - f(b)) / 2e-6;
  }
  return J;
}

/// K = dr/dq, C = dr/dv, M = dr/da of the mechanism's dynamics residual at (q, v, a, t).
inline std::array<Derivative, 3> dynamics_derivatives(const flexopt::dynamics::Mechanism &m,
                                                      const flexopt::dynamics::Vector &q,
                                                      const flexopt::dynamics::Vector &v,
                                                      const flexopt::dynamics::Vector &a,
                                                      double t) {
  using flexopt::dynamics::Vector;
  std::array<Derivative, 3> out;
  Vector r;
  m.dynamics(q, v, a, t, r, &out[0].analytic, &out[1].analytic, &out[2].analytic);
  auto res = [&](const Vector &qq, const Vector &vv, const Vector &aa) {
    Vector x;
    m.dynamics(qq, vv, aa, t, x, nullptr, nullptr, nullptr);
    return x;
  };
  out[0].differences = central_differences([&](const Vector &x) { return res(x, v, a); }, q);
  out[1].differences = central_differences([&](const Vector &x) { return res(q, x, a); }, v);
  out[2].differences = central_differences([&](const Vector &x) { return res(q, v, x); }, a);
  return out;
}

/// dR/ds_{n+1} and dR/ds_n of the generalized-alpha step residual R(s1, s0).
inline std::array<Derivative, 2> step_derivatives(const flexopt::dynamics::GeneralizedAlpha &ga,
                                                  const flexopt::dynamics::State &s1,
                                                  const flexopt::dynamics::State &s0, double h) {
  using flexopt::dynamics::State;
  using flexopt::dynamics::Vector;
  const int n = static_cast<int>(s1.q.size()), m = static_cast<int>(s1.lambda.size());
  std::array<Derivative, 2> out;
  Vector R;
  ga.residual(s1, s0, h, R, &out[0].analytic, &out[1].analytic);
  out[0].differences = central_differences(
      [&](const Vector &x) {
        State s = s1;
        s.unpack(x, n, m);
        Vector r;
        ga.residual(s, s0, h, r, nullptr, nullptr);
        return r;
      },
      s1.pack());
  out[1].differences = central_differences(
      [&](const Vector &x) {
        State s = s0;
        s.unpack(x, n, m);
        Vector r;
        ga.residual(s1, s, h, r, nullptr, nullptr);
        return r;
      },
      s0.pack());
  return out;
}

struct NewtonPaths {
  flexopt::dynamics::State a, b; ///< final states
  int a_iterations = 0, b_iterations = 0;
  int a_factorizations = 0, b_factorizations = 0;
};

/// `steps` steps of size h from (q0, 0) with rho_inf = 0.8, once with Newton settings `sa` and
/// once with `sb`. Throws if a step fails.
inline NewtonPaths run_newton_paths(const flexopt::dynamics::Mechanism &m,
                                    const flexopt::dynamics::Vector &q0, double h, int steps,
                                    const flexopt::dynamics::NewtonSettings &sa,
                                    const flexopt::dynamics::NewtonSettings &sb) {
  using namespace flexopt::dynamics;
  const auto par = AlphaParameters::from_rho_inf(0.8);
  const GeneralizedAlpha ga(m, par, sa), gb(m, par, sb);
  const Vector v0 = Vector::Zero(q0.size());
  NewtonPaths out;
  out.a = ga.initial_state(q0, v0, 0);
  out.b = gb.initial_state(q0, v0, 0);
  State next;
  for (int k = 0; k < steps; ++k) {
    StepInfo ia, ib;
    if (!ga.advance(out.a, h, next, ia)) throw std::runtime_error("step failed (settings a)");
    out.a = next;
    if (!gb.advance(out.b, h, next, ib)) throw std::runtime_error("step failed (settings b)");
    out.b = next;
    out.a_iterations += ia.iterations;
    out.b_iterations += ib.iterations;
    out.a_factorizations += ia.factorizations;
    out.b_factorizations += ib.factorizations;
  }
  return out;
}

/// Newton proper (a new matrix every iteration), every system dense (a) and sparse above
/// `sparse_limit` unknowns (b): with exact matrices both converge quadratically in the same
/// number of iterations.
inline NewtonPaths run_dense_sparse_paths(const flexopt::dynamics::Mechanism &m,
                                          const flexopt::dynamics::Vector &q0, double h, int steps,
                                          int sparse_limit) {
  flexopt::dynamics::NewtonSettings dense, sparse;
  dense.reuse_contraction = sparse.reuse_contraction = 0;
  dense.dense_limit = 1000;
  sparse.dense_limit = sparse_limit;
  return run_newton_paths(m, q0, h, steps, dense, sparse);
}

/// Runs `steps` steps of h with Newton proper (reuse_contraction 0) and with the kept matrix
/// (the default settings) and expects: the kept path within ten times the drift estimate
/// N (gamma / beta) (T / h) kept_tolerance (1 + max|q|) of Newton's positions (docs/theory.md
/// section 6.4), its multipliers within 1e-7 relative (round-off of the index-3 multipliers:
/// ~1e-8), the deviation at kept_tolerance 1e-13 at least 20 times that at the default 1e-15 (the
/// kept path converges to Newton's solution with the tolerance), Newton factorizing at every
/// iteration and the kept path at fewer than one step in two.
inline void expect_kept_matrix_reaches_newton(const flexopt::dynamics::Mechanism &m,
                                              const flexopt::dynamics::Vector &q0, double h,
                                              int steps, const char *scene) {
  flexopt::dynamics::NewtonSettings newton, kept, loose;
  newton.reuse_contraction = 0;
  loose.kept_tolerance = 1e-13;
  const auto r = run_newton_paths(m, q0, h, steps, newton, kept);
  const auto l = run_newton_paths(m, q0, h, steps, newton, loose);
  const double dq = (r.a.q - r.b.q).cwiseAbs().maxCoeff();
  const auto par = flexopt::dynamics::AlphaParameters::from_rho_inf(0.8);
  const double bound = 10 * steps * (par.gamma / par.beta) * steps * kept.kept_tolerance *
                       (1 + r.a.q.cwiseAbs().maxCoeff());
  const double dq_loose = (l.a.q - l.b.q).cwiseAbs().maxCoeff();
  std::printf("%s, %d steps: Newton %d iterations; kept matrix %d iterations on %d "
              "factorizations; max |q_kept - q_Newton| %.3e (bound %.1e; %.3e at kept_tolerance "
              "1e-13)\n",
              scene, steps, r.a_iterations, r.b_iterations, r.b_factorizations, dq, bound,
              dq_loose);
  EXPECT_GT((r.a.q - q0).cwiseAbs().maxCoeff(), 0.01) << scene << ": it has moved";
  EXPECT_LT(dq, bound) << scene;
  EXPECT_GT(dq_loose, 20 * dq) << scene;
  EXPECT_LT((r.a.lambda - r.b.lambda).cwiseAbs().maxCoeff(),
            1e-7 * r.a.lambda.cwiseAbs().maxCoeff())
      << scene;
  EXPECT_EQ(r.a_factorizations, r.a_iterations) << scene;
  EXPECT_LT(2 * r.b_factorizations, steps) << scene;
}

/// A chain of `links` rigid links of 1 m (2 kg) hinged end to end about z, the first to the
/// ground at the origin, lying along x (q0), under gravity -9.81 y.
inline flexopt::dynamics::Mechanism chain(int links, flexopt::dynamics::Vector &q0) {
  using namespace flexopt;
  using bodies::Vec3;
  dynamics::Mechanism m;
  bodies::MassProperties p;
  p.mass = 2.0;
  p.center = Vec3(0.5, 0, 0);
  p.inertia = Vec3(0.001, 0.17, 0.17).asDiagonal();
  q0.resize(7 * links);
  for (int b = 0; b < links; ++b) {
    m.bodies.push_back(std::make_shared<bodies::RigidBody>("l" + std::to_string(b), p));
    q0.segment<3>(7 * b) = Vec3(b + 0.5, 0, 0);
    q0.segment<4>(7 * b + 3) = bodies::Vec4(1, 0, 0, 0);
    joints::Equation n;
    n.kind = joints::Equation::Kind::Normalize;
    n.a = b;
    m.equations.push_back(n);
  }
  for (int b = 0; b < links; ++b) {
    joints::Equation e;
    e.a = b - 1, e.b = b;
    e.sa = b == 0 ? Vec3(0, 0, 0) : Vec3(0.5, 0, 0);
    e.sb = Vec3(-0.5, 0, 0);
    e.kind = joints::Equation::Kind::Coincide;
    m.equations.push_back(e);
    e.kind = joints::Equation::Kind::Perpendicular;
    e.vb = Vec3::UnitZ();
    for (const Vec3 &u : {Vec3::UnitX(), Vec3::UnitY()}) {
      e.ua = u;
      m.equations.push_back(e);
    }
  }
  m.gravity = Vec3(0, -9.81, 0);
  m.finalize();
  return m;
}

} // namespace test_support
