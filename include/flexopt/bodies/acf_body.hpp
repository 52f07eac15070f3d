#pragma once
/// \file An ACF body (docs/theory.md section 8): the absolute positions of all nodes of its mesh
/// as coordinates, distributed over the ranks with the mesh; constant consistent mass, the
/// co-rotated elastic force of its elements (fem/corotated.hpp), gravity as a constant load.
/// The body holds its element data; the integrator (dynamics::DistributedAlpha) places its
/// coordinates in the mechanism's layout and assembles.
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <string>
#include <vector>

namespace flexopt::bodies {

class AcfBody {
public:
  /// Builds the co-rotated elements (E scaled by modulus_factor[e], empty: 1). Collective over
  /// the mesh's communicator. The mesh must outlive the body. damping: the coefficient b [s] of
  /// stiffness-proportional damping on the co-rotated velocities (fem::corotated_damping; 0:
  /// none).
  AcfBody(std::string name, const mesh::DistributedMesh &mesh,
          const fem::IsotropicMaterial &material, const std::vector<double> &modulus_factor = {},
          double damping = 0);

  const std::string &name() const { return name_; }
  const mesh::DistributedMesh &mesh() const { return mesh_; }
  const std::vector<fem::CorotatedElement> &elements() const { return elements_; }
  const fem::IsotropicMaterial &material() const { return material_; }
  /// density x volume [kg] (the same on every rank).
  double total_mass() const { return mass_; }
  /// The stiffness-proportional damping coefficient b [s] (0: none).
  double damping() const { return damping_; }

private:
  std::string name_;
  const mesh::DistributedMesh &mesh_;
  fem::IsotropicMaterial material_;
  std::vector<fem::CorotatedElement> elements_;
  double mass_ = 0;
  double damping_ = 0;
};

} // namespace flexopt::bodies
