#pragma once
/// \file The interface every body formulation implements for the mechanism (docs/theory.md
/// sections 6.2 and 7.3). A body owns a block of coordinates q_b = [r, p, zeta]: the world
/// position r of its reference point, its Euler parameters p and its elastic coordinates zeta
/// (none for a rigid body), with velocities v_b = q_b' and accelerations a_b = q_b''.
#include "flexopt/bodies/quaternion.hpp"

#include <Eigen/Dense>
#include <string>

namespace flexopt::bodies {

using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
using ConstVectorRef = Eigen::Ref<const Vector>;

/// Largest coordinate block of one body (7 frame coordinates plus elastic coordinates). The
/// joints' Jacobian rows are fixed-capacity arrays of this size (no heap allocation per
/// Newton iteration).
constexpr int kMaxBodyCoordinates = 7 + 120;

class Body {
public:
  explicit Body(std::string name) : name_(std::move(name)) {}
  virtual ~Body() = default;

  const std::string &name() const { return name_; }
  /// "rigid", "ffrf".
  virtual const char *model() const = 0;
  /// Size of the coordinate block: 7 plus the elastic coordinates.
  virtual int coordinates() const = 0;
  int elastic_coordinates() const { return coordinates() - 7; }
  virtual double mass() const = 0;
  /// Mesh coordinates of the point whose world position is r (rigid: the centre of mass;
  /// FFRF: the frame origin).
  virtual Vec3 origin() const = 0;

  /// The body's equations of motion without constraint forces and point loads:
  ///   res = M(q) a + Q_v(q, v) + Q_int(q, v) - Q_gravity(q)
  /// and its exact derivatives K = d res/dq, C = d res/dv, M = d res/da (coordinates() square),
  /// each of which may be null. `res` has coordinates() entries.
  virtual void residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                        const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                        Matrix *M) const = 0;
  /// Kinetic energy plus strain energy plus the potential of gravity, -g . (sum of m x).
  virtual double energy(const ConstVectorRef &q, const ConstVectorRef &v,
                        const Vec3 &gravity) const = 0;

  /// Coordinates of the body placed with its mesh origin at `origin` and rotated by R (mesh
  /// point X at origin + R X), undeformed.
  Vector placement(const Vec3 &origin, const Mat3 &R) const;
  /// Velocities for the velocity `velocity` of the mesh origin and the world angular
  /// velocity `omega`, at coordinates q from placement(), no elastic velocity.
  Vector placement_velocity(const Vector &q, const Vec3 &velocity, const Vec3 &omega) const;

private:
  std::string name_;
};

} // namespace flexopt::bodies
