#pragma once
/// \file Generalized-alpha time integration on the distributed backend (docs/theory.md sections
/// 6.4 and 8.2): the state is a set of PETSc Vecs over all ranks and the Newton matrix one
/// PETSc Mat, solved by a KSP (a direct MUMPS LU by default, options prefix `mech_`); the
/// Newton iteration, its kept matrix and the step halving are those of GeneralizedAlpha
/// (detail::newton_loop).
///
/// This first version integrates one free ACF body under gravity, without constraints:
///   M acc + f(x) - M (1 (x) g) = 0.
/// Joints, interface nodes and the small (rigid, FFRF) part of a scene come with the
/// mechanism layout of section 8.2.
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <petscksp.h>

namespace flexopt::dynamics {

/// The state of a step: t and the PETSc vectors q, v, a, acc (the body's layout). Copies are
/// deep (new vectors with the same values).
struct DistState {
  double t = 0;
  Vec q = nullptr, v = nullptr, a = nullptr, acc = nullptr;
  DistState() = default;
  DistState(const DistState &o);
  DistState &operator=(const DistState &o);
  ~DistState();
};

class DistributedAlpha {
public:
  DistributedAlpha(const bodies::AcfBody &body, const Eigen::Vector3d &gravity,
                   AlphaParameters parameters, NewtonSettings settings = {});
  ~DistributedAlpha();
  DistributedAlpha(const DistributedAlpha &) = delete;
  DistributedAlpha &operator=(const DistributedAlpha &) = delete;

  /// Positions x0 and velocities v0 at t0, acc = a = M^-1 (f_g - f(x0)). Collective; throws a
  /// collective flexopt::Error if an element of x0 is inverted.
  DistState initial_state(Vec x0, Vec v0, double t0) const;
  /// Advances s by h to `next`, halving the step (recursively, up to max_halvings) when Newton
  /// fails. Returns false (and fills `info`) if even the smallest substep fails. Collective.
  bool advance(const DistState &s, double h, DistState &next, StepInfo &info) const;
  /// Kinetic energy 1/2 v^T M v, elastic energy and the potential of gravity -f_g . x at a
  /// state. Collective.
  void energies(const DistState &s, double &kinetic, double &elastic, double &potential) const;

private:
  bool step_once(const DistState &s, double h, DistState &next, StepInfo &info) const;

  const bodies::AcfBody &body_;
  AlphaParameters par_;
  NewtonSettings settings_;
  Vec fg_ = nullptr;                                     ///< gravity load
  mutable Vec F_ = nullptr, r_ = nullptr, dq_ = nullptr; ///< work vectors
  mutable Mat A_ = nullptr;                              ///< the iteration matrix M + T / beta'
  mutable KSP ksp_ = nullptr;
  mutable bool factored_ = false, bad_ = false;
  mutable double bp_ = 0, gp_ = 0;
};

} // namespace flexopt::dynamics
