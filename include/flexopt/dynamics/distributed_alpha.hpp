#pragma once
/// \file Generalized-alpha time integration on the distributed backend (docs/theory.md sections
/// 6.4 and 8.2): the state is a set of PETSc Vecs over all ranks and the Newton matrix one
/// PETSc Mat, solved by a KSP (a direct MUMPS LU by default, options prefix `mech_`); the
/// Newton iteration, its kept matrix and the step halving are those of GeneralizedAlpha
/// (detail::newton_loop).
///
/// This version integrates free ACF bodies under gravity, without constraints:
///   M acc + f(x) - M (1 (x) g) = 0.
/// The layout: each rank owns the coordinates of its owned nodes of body 0, then body 1, ...
/// Joints, interface nodes and the small (rigid, FFRF) part of a scene come with section 8.2.
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <functional>
#include <memory>
#include <petscksp.h>
#include <vector>

namespace flexopt::dynamics {

/// The state of a step: t and the PETSc vectors q, v, a, acc (the integrator's layout). Copies
/// are deep (new vectors with the same values).
struct DistState {
  double t = 0;
  Vec q = nullptr, v = nullptr, a = nullptr, acc = nullptr;
  DistState() = default;
  DistState(const DistState &o);
  DistState &operator=(const DistState &o);
  ~DistState();
};

namespace detail {
struct AcfLayout; ///< the DOF numbers of every body's local nodes and the scatters to them
}

class DistributedAlpha {
public:
  /// The bodies must share one communicator and outlive the integrator. Collective.
  DistributedAlpha(std::vector<const bodies::AcfBody *> bodies, const Eigen::Vector3d &gravity,
                   AlphaParameters parameters, NewtonSettings settings = {});
  ~DistributedAlpha();
  DistributedAlpha(const DistributedAlpha &) = delete;
  DistributedAlpha &operator=(const DistributedAlpha &) = delete;

  /// A vector of the integrator's layout; the caller destroys it. Collective.
  Vec create_vector() const;
  /// Sets field(X) at the owned nodes of body b (X: reference position) in v. Not collective.
  void set_nodal(Vec v, std::size_t body,
                 const std::function<Eigen::Vector3d(const Eigen::Vector3d &)> &field) const;

  /// Positions x0 and velocities v0 at t0, acc = a = M^-1 (f_g - f(x0)). Collective; throws a
  /// collective flexopt::Error if an element of x0 is inverted.
  DistState initial_state(Vec x0, Vec v0, double t0) const;
  /// Advances s by h to `next`, halving the step (recursively, up to max_halvings) when Newton
  /// fails. Returns false (and fills `info`) if even the smallest substep fails. Collective.
  bool advance(const DistState &s, double h, DistState &next, StepInfo &info) const;
  /// Kinetic energy 1/2 v^T M v, elastic energy and the potential of gravity -f_g . x at a
  /// state. Collective.
  void energies(const DistState &s, double &kinetic, double &elastic, double &potential) const;
  /// Linear momentum M v summed over all nodes and angular momentum sum_a x_a x (M v)_a about
  /// the world origin. Collective.
  void momentum(const DistState &s, Eigen::Vector3d &linear, Eigen::Vector3d &angular) const;
  /// 1_k^T M x / m: the centre of mass of all bodies. Collective.
  Eigen::Vector3d centre_of_mass(Vec x) const;

private:
  bool step_once(const DistState &s, double h, DistState &next, StepInfo &info) const;
  /// Energy and force (and tangent) of all bodies at positions x into F_ (and A_). Collective.
  fem::CorotatedSum internal(Vec x, Mat T) const;

  std::vector<const bodies::AcfBody *> bodies_;
  MPI_Comm comm_;
  std::unique_ptr<detail::AcfLayout> layout_;
  AlphaParameters par_;
  NewtonSettings settings_;
  double mass_ = 0;
  Mat M_ = nullptr;                                      ///< the consistent mass, this layout
  Vec fg_ = nullptr;                                     ///< gravity load
  mutable Vec F_ = nullptr, r_ = nullptr, dq_ = nullptr; ///< work vectors
  mutable Mat A_ = nullptr;                              ///< the iteration matrix M + T / beta'
  mutable KSP ksp_ = nullptr;
  mutable bool factored_ = false;
  mutable double bp_ = 0, gp_ = 0;
};

} // namespace flexopt::dynamics
