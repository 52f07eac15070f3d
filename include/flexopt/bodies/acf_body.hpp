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

  /// A design's element factors (docs/theory.md section 9.6): E scaled by modulus_factor[e],
  /// the density by mass_factor[e] (local elements; empty: 1). Collective (the total mass).
  void set_factors(const std::vector<double> &modulus_factor,
                   const std::vector<double> &mass_factor);
  /// Per local element (empty: 1).
  const std::vector<double> &modulus_factor() const { return modulus_factor_; }
  const std::vector<double> &mass_factor() const { return mass_factor_; }

  /// The design partials of mu_r . R_d (section 9.6) at displacements u, velocities v (may be
  /// null: no damping force) and accelerations acc, for every multiplier mu[r] (each 3 per local
  /// node in the mesh's local numbering): per local element, d_modulus[r][e] = mu_r,e . (f_e +
  /// f_d,e) / s_e and d_mass[r][e] = mu_r,e . M0_e (acc_e - g). One element loop serves all the
  /// multipliers. Throws flexopt::Error for an inverted element. Not collective.
  void design_partials(const double *u, const double *v, const double *acc,
                       const std::vector<const double *> &mu, const Eigen::Vector3d &gravity,
                       std::vector<std::vector<double>> &d_modulus,
                       std::vector<std::vector<double>> &d_mass) const;
  /// The elastic energy of every local element at displacements u (3 per local node), with its
  /// modulus factor, and, if `force` is non-null, the elements' forces added into it (3 per
  /// local node). Not collective.
  std::vector<double> element_energies(const double *u, double *force = nullptr) const;

  /// Local element e's current node positions (one row per node) at the local displacements u.
  fem::ElementCoords positions(PetscInt e, const double *u) const;

  const std::string &name() const { return name_; }
  const mesh::DistributedMesh &mesh() const { return mesh_; }
  const std::vector<fem::CorotatedElement> &elements() const { return elements_; }
  const fem::IsotropicMaterial &material() const { return material_; }
  /// density x volume, with the mass factors [kg] (the same on every rank).
  double total_mass() const { return mass_; }
  /// The stiffness-proportional damping coefficient b [s] (0: none).
  double damping() const { return damping_; }

private:
  std::string name_;
  const mesh::DistributedMesh &mesh_;
  fem::IsotropicMaterial material_;
  std::vector<fem::CorotatedElement> elements_;
  std::vector<double> modulus_factor_, mass_factor_;
  double mass_ = 0;
  double damping_ = 0;
};

} // namespace flexopt::bodies
