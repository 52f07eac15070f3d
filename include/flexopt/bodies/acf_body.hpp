#pragma once
/// \file An ACF body (docs/theory.md section 8): the absolute positions of all nodes of its mesh
/// as coordinates, distributed over the ranks with the mesh; constant consistent mass, the
/// co-rotated elastic force of its elements (fem/corotated.hpp), gravity as a constant load.
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <Eigen/Dense>
#include <petscmat.h>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::bodies {

class AcfBody {
public:
  /// Builds the co-rotated elements (E scaled by modulus_factor[e], empty: 1) and the mass
  /// matrix. Collective over the mesh's communicator.
  AcfBody(std::string name, const mesh::DistributedMesh &mesh,
          const fem::IsotropicMaterial &material, const std::vector<double> &modulus_factor = {});
  ~AcfBody();
  AcfBody(const AcfBody &) = delete;
  AcfBody &operator=(const AcfBody &) = delete;

  const std::string &name() const { return name_; }
  const mesh::DistributedMesh &mesh() const { return mesh_; }
  /// Number of coordinates owned by this rank (3 per owned node) and in all.
  PetscInt local_size() const { return 3 * mesh_.owned_nodes; }
  PetscInt global_size() const { return 3 * mesh_.global_nodes; }
  double total_mass() const { return mass_; }
  Mat mass_matrix() const { return M_; }
  /// The reference positions X of the owned nodes (mesh layout).
  Vec reference() const { return X_; }

  /// A vector of the body's layout (owned node-major DOFs); the caller destroys it.
  Vec create_vector() const;
  /// f_g = M (1 (x) g): the consistent load of gravity g [m/s^2], into f. Collective.
  void gravity_load(const Eigen::Vector3d &g, Vec f) const;
  /// Elastic energy and internal force F (and tangent T if not null, from create_matrix) at the
  /// positions x (body layout); see fem::assemble_corotated. Collective.
  fem::CorotatedSum internal(Vec x, Vec F, Mat T) const;
  /// A matrix of the element pattern (for the tangent); the caller destroys it.
  Mat create_matrix() const;
  /// Sum over the owned nodes of (M v) and of x_a x (M v)_a: linear and angular momentum
  /// (about the world origin), reduced over the ranks. Collective.
  void momentum(Vec x, Vec v, Eigen::Vector3d &linear, Eigen::Vector3d &angular) const;

private:
  std::string name_;
  const mesh::DistributedMesh &mesh_;
  std::vector<fem::CorotatedElement> elements_;
  Mat M_ = nullptr;
  Vec X_ = nullptr;
  mutable Vec u_ = nullptr; ///< ghosted x - X for the element loop
  double mass_ = 0;
};

} // namespace flexopt::bodies
