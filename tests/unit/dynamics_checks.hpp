#pragma once
// Checks shared by the rigid and the FFRF dynamics tests: the mechanism's and the step
// residual's Jacobians next to their central differences, and the dense and sparse Newton paths.
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <array>
#include <stdexcept>

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
  flexopt::dynamics::State dense, sparse; ///< final states
  int dense_iterations = 0, sparse_iterations = 0;
};

/// `steps` steps of size h from (q0, 0) with rho_inf = 0.8, once with every Newton system
/// dense and once sparse (dense_limit `sparse_limit`). Throws if a step fails.
inline NewtonPaths run_newton_paths(const flexopt::dynamics::Mechanism &m,
                                    const flexopt::dynamics::Vector &q0, double h, int steps,
                                    int sparse_limit) {
  using namespace flexopt::dynamics;
  NewtonSettings dense, sparse;
  dense.dense_limit = 1000;
  sparse.dense_limit = sparse_limit;
  const auto par = AlphaParameters::from_rho_inf(0.8);
  const GeneralizedAlpha gd(m, par, dense), gs(m, par, sparse);
  const Vector v0 = Vector::Zero(q0.size());
  NewtonPaths out;
  out.dense = gd.initial_state(q0, v0, 0);
  out.sparse = gs.initial_state(q0, v0, 0);
  State next;
  for (int k = 0; k < steps; ++k) {
    StepInfo a, b;
    if (!gd.advance(out.dense, h, next, a)) throw std::runtime_error("dense step failed");
    out.dense = next;
    if (!gs.advance(out.sparse, h, next, b)) throw std::runtime_error("sparse step failed");
    out.sparse = next;
    out.dense_iterations += a.iterations;
    out.sparse_iterations += b.iterations;
  }
  return out;
}

} // namespace test_support
