#pragma once
/// \file A dynamic case turned into a Mechanism: bodies meshed and their mass properties
/// integrated (rank 0, broadcast), interfaces located, joints and drivers expanded into
/// constraint equations, loads and sensors bound (docs/theory.md section 6.3).
#include "flexopt/dynamics/mechanism.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

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
  Vector q0, v0;                              ///< placed coordinates and velocities at t = 0
  std::vector<BoundSensor> sensors;
  std::vector<std::string> redundant_rows; ///< constraint rows found redundant and not enforced
  double length_scale = 1;                 ///< largest extent of the placed scene [m]
};

/// Builds the scene of a dynamic case. Collective; throws collective flexopt::Errors naming the
/// case key for scene-level problems (an interface without area, a sensor on a missing body).
Scene build_scene(MPI_Comm comm, const io::Case &c);

/// Value of a sensor at coordinates q (3 numbers): position (world), displacement from the
/// initial position, or rotation_angle (the rotation vector of the body relative to its
/// initial orientation, world frame).
Vec3 sensor_value(const Scene &scene, const BoundSensor &s, const Vector &q);

} // namespace flexopt::dynamics
