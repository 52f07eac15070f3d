#pragma once
/// \file A dynamic case turned into a Mechanism: bodies meshed and their mass properties
/// integrated (rank 0, broadcast), interfaces located, joints and drivers expanded into
/// constraint equations, loads and sensors bound (docs/theory.md section 6.3).
#include "flexopt/dynamics/mechanism.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <memory>
#include <mpi.h>
#include <string>
#include <vector>

namespace flexopt::dynamics {

/// A sensor bound to a body: `point` in body (mesh) coordinates.
struct BoundSensor {
  std::string name;
  std::string quantity; ///< position | displacement | rotation_angle
  int body = 0;
  Vec3 point{0, 0, 0};
};

struct Scene {
  Mechanism mechanism;
  std::vector<mesh::DistributedMesh> meshes; ///< per body (for output)
  Vector q0, v0;                             ///< placed coordinates and velocities at t = 0
  std::vector<BoundSensor> sensors;
  std::vector<std::string> redundant_rows; ///< constraint rows found redundant and not enforced
  double length_scale = 1;                 ///< largest extent of the placed scene [m]
};

/// Where a joint attaches, in the initial placement: the body (-1: ground), the interface point
/// relative to the body's centre of mass in body axes (ground: world), the body's initial
/// rotation and the point's initial world position.
struct Attachment {
  int body = -1;
  Vec3 s{0, 0, 0};
  bodies::Mat3 R = bodies::Mat3::Identity();
  Vec3 world{0, 0, 0};
  /// A world direction in the initial placement, expressed in the body's axes.
  Vec3 local(const Vec3 &world_vector) const { return R.transpose() * world_vector; }
};

/// The equations of a joint (docs/theory.md section 6.3): spherical 3 rows, revolute 5,
/// prismatic 5, fixed 6, with vectors fixed from the initial placement and the world `axis`
/// (revolute, prismatic). Satisfied at the initial placement when the interface points
/// coincide (prismatic: for any interface points).
std::vector<joints::Equation> joint_equations(const std::string &type, const Attachment &a,
                                              const Attachment &b, const Vec3 &axis,
                                              const std::string &owner);
/// The equation of a driver f(t) on a revolute joint (angle from the initial placement) or a
/// prismatic joint (displacement along the axis from the initial placement).
joints::Equation driver_equation(const std::string &joint_type, const Attachment &a,
                                 const Attachment &b, const Vec3 &axis,
                                 std::shared_ptr<const Expression> f, const std::string &owner);

/// Builds the scene of a dynamic case. Collective; throws collective flexopt::Errors naming the
/// case key for scene-level problems (an interface without area, a sensor on a missing body).
Scene build_scene(MPI_Comm comm, const io::Case &c);

/// Value of a sensor at coordinates q (3 numbers): position (world), displacement from the
/// initial position, or rotation_angle (the rotation vector of the body relative to its
/// initial orientation, world frame).
Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q);

} // namespace flexopt::dynamics
