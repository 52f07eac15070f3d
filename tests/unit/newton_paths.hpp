#pragma once
// Runs the same mechanism through the dense and the sparse Newton paths of generalized-alpha
// (shared by the rigid and the FFRF tests).
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <stdexcept>

namespace test_support {

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
