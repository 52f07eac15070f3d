#pragma once
/// \file The loads a body of a mechanism carries at one state of it, in the body's own axes
/// (docs/theory.md section 14.2, equivalent static loads): the force and moment of every joint
/// (its driver's row included) and interface force acting on the body, and the consistent nodal
/// load of its d'Alembert inertia and gravity on its mesh. Their balance is the body's equations
/// of motion at that state.
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/scene.hpp"

#include <petscmat.h>
#include <string>
#include <vector>

namespace flexopt::dynamics {

/// A force and a moment applied at a point of the body, all in body axes; the point relative to
/// the body's origin (Body::origin(); for an FFRF body its deformed position), the moment about
/// the point.
struct PointLoad {
  std::string owner;     ///< "joint NAME" (with its driver's row) or "force K" (the case's forces)
  std::string interface; ///< the body's interface whose centroid the point is (empty: none)
  Vec3 point{0, 0, 0}, force{0, 0, 0}, moment{0, 0, 0};
};

struct BodyLoads {
  std::vector<PointLoad> points;
  /// f_i = sum_j m_ij (A^T g - a_j) at the mesh's owned nodes (block size 3, the layout of
  /// fem::create_matrix). Owned by this object.
  Vec nodal = nullptr;
  /// b_i = A^T g - a_i, the specific body force [m/s^2] whose consistent load is `nodal` (same
  /// layout; equivalent static loads apply it with the static design's mass). Owned.
  Vec body_force = nullptr;
  Vec3 inertia_force{0, 0, 0};  ///< sum_i f_i
  Vec3 inertia_moment{0, 0, 0}; ///< sum_i xbar_i x f_i (about the origin)
  /// The balance: inertia and gravity plus the point loads, force and moment about the origin
  /// (zero where the state satisfies the equations of motion), and the largest norm of a term in
  /// each sum (the scale of a relative check).
  Vec3 force_residual{0, 0, 0}, moment_residual{0, 0, 0};
  double force_scale = 0, moment_scale = 0;

  BodyLoads() = default;
  BodyLoads(const BodyLoads &) = delete;
  BodyLoads &operator=(const BodyLoads &) = delete;
  BodyLoads(BodyLoads &&other) noexcept;
  BodyLoads &operator=(BodyLoads &&other) noexcept;
  ~BodyLoads();
};

/// The loads of case body `b` (rigid or FFRF; ACF is refused) at state `s` of scene.mechanism
/// (q, v, the true accelerations `acc` and the multipliers of one step). `mass` is the consistent
/// mass matrix of the body's mesh with the density and design factors its model was built with
/// (fem::assemble_mass; an FFRF design body's reduction keeps it). Collective over the mesh's
/// communicator; throws a collective flexopt::Error for an ACF body or a matrix of another
/// layout.
BodyLoads body_loads(const Scene &scene, std::size_t b, const State &s, Mat mass);

} // namespace flexopt::dynamics
