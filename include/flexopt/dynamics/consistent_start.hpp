#pragma once
/// \file The velocity correction of the consistent start (docs/theory.md section 6.4,
/// "Consistent initial conditions"): the given velocities are made to satisfy
/// Phi_q v + Phi_t = 0 by changing only the bodies' rigid-body velocities, with the least
/// change of kinetic energy. Elastic velocities (FFRF coordinates, the deformation of ACF
/// bodies) stay as given. Shared by the dense (GeneralizedAlpha) and the distributed
/// (DistributedAlpha) backends.
#include "flexopt/dynamics/mechanism.hpp"

#include <vector>

namespace flexopt::dynamics {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

/// The rigid-body correction is taken as consistent when it leaves max |Phi_q v + Phi_t| at or
/// below this fraction of 1 + the largest violation it started from (round-off of the least-
/// squares solve is ~1e-15 of it); otherwise the joints prescribe elastic velocities, and both
/// backends follow with the mass-weighted correction of all velocities.
constexpr double kVelocityTolerance = 1e-10;

/// The rigid-body velocity fields of a body that is not a body of the mechanism (an ACF body):
/// a change (du, dw) moves its points by du + dw x (x - centre) (world axes). `metric` is
/// V^T M V for the six fields V (the kinetic energy of the change is 1/2 y^T metric y), and
/// `nodes` are the mechanism's bodies that move with it (its interface nodes: their velocities
/// change by the field at their origin and by the spin dw).
struct RigidField {
  Matrix6 metric = Matrix6::Zero();
  Vec3 centre{0, 0, 0};
  std::vector<int> nodes;
};

/// The result of rigid_velocity_correction.
struct VelocityCorrection {
  Vector dv;                  ///< the change of the mechanism's velocities
  std::vector<Vector6> field; ///< per RigidField: its change (du, dw)
  double residual = 0;        ///< max |Phi_q (v + dv) + Phi_t| over the enforced rows
  double scale = 0;           ///< max |Phi_q v + Phi_t| before the correction
  /// The parts its derivative with respect to the mass matrix needs (docs/theory.md section
  /// 9.2; empty when there is nothing to correct): dv = T y, the parameters y, and
  /// Pi = L^-T (I - B^+ B) L^-1,
  /// with which dy = -Pi dW y for a change dW of the metric W = T^T M T.
  Matrix T;
  Vector y;
  Matrix Pi;
  /// And what its derivative with respect to q and the given v needs (section 9.2, item 6):
  /// the metric W, P = Phi_q T, b = -(Phi_q v + Phi_t), B = P L^-T (W = L L^T) and the
  /// pseudo-inverse B^+ of the complete orthogonal decomposition the correction used.
  Matrix W, P, B, Bp;
  Vector b;
};

/// The smallest change of kinetic energy of the rigid-body velocities that satisfies
/// Phi_q v + Phi_t = 0 at (q, t): each rigid or FFRF body of `mech` changes its frame
/// velocity (translation and spin, the 7 frame coordinates' rates), each RigidField its six
/// fields; elastic coordinates and massless bodies not listed in a field keep their rates.
/// Minimizes 1/2 y^T W y over the parameters y subject to (least squares) Phi_q T y = b with
/// b = -(Phi_q v + Phi_t): where the joints leave speeds undetermined (a spin about an axis
/// through two spherical joints) it leaves them as given; where rigid-body velocities cannot
/// satisfy the joints (an elastic body held at two places whose speeds the joints prescribe
/// independently) `residual` says how far the result is from consistent. Throws flexopt::Error
/// for a massless body that no field moves.
VelocityCorrection rigid_velocity_correction(const Mechanism &mech, const Vector &q,
                                             const Vector &v, double t,
                                             const std::vector<RigidField> &fields = {});

} // namespace flexopt::dynamics
