#pragma once
/// \file Point evaluation of a nodal vector field (sensors).
#include "flexopt/mesh/distributed_mesh.hpp"

#include <array>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::fem {

/// Where a point lies: the lowest rank whose local elements contain it (`owner`, same on
/// every rank), and on that rank the local element and its shape-function values there.
struct PointLocation {
  int owner = 0;
  PetscInt element = -1;     ///< local element on the owner rank, -1 elsewhere
  std::vector<double> shape; ///< N_a at the point (owner rank only)
};

/// Locates a point given in undeformed coordinates. Collective. Throws a collective
/// flexopt::Error naming `what` if no element contains it.
PointLocation locate(const mesh::DistributedMesh &mesh, const std::array<double, 3> &point,
                     const std::string &what);

/// FE interpolation of a ghosted nodal vector field (ghosts up to date) at a located point;
/// the value is returned on every rank. Collective.
std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const PointLocation &location);

/// Adds to c (global, block size 3) the vector of the functional u -> d . u(point), i.e.
/// c_{3a+k} += N_a(point) d_k: the adjoint load of a displacement response. Collective.
void add_point_functional(const mesh::DistributedMesh &mesh, const PointLocation &location,
                          const std::array<double, 3> &direction, Vec c);

/// FE interpolation of a ghosted nodal vector field (ghosts up to date) at a point given in
/// the body's undeformed coordinates. The lowest rank whose elements contain the point
/// evaluates it; the value is returned on every rank. Collective. Throws a collective
/// flexopt::Error naming `what` if no element contains the point.
std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const std::array<double, 3> &point, const std::string &what);

} // namespace flexopt::fem
