#pragma once
/// \file Point evaluation of a nodal vector field (sensors).
#include "flexopt/mesh/distributed_mesh.hpp"

#include <array>
#include <petscvec.h>
#include <string>

namespace flexopt::fem {

/// FE interpolation of a ghosted nodal vector field (ghosts up to date) at a point given in
/// the body's undeformed coordinates. The lowest rank whose elements contain the point
/// evaluates it; the value is returned on every rank. Collective. Throws a collective
/// flexopt::Error naming `what` if no element contains the point.
std::array<double, 3> probe_vector(const mesh::DistributedMesh &mesh, Vec field_ghosted,
                                   const std::array<double, 3> &point, const std::string &what);

} // namespace flexopt::fem
