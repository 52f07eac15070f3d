#pragma once
/// \file The design field of a topology optimization on one body's mesh: the design variables
/// (one per element of the design region), their embedding in the body (solid outside the
/// region), the density filter and the Heaviside projection, and the pull-back of
/// sensitivities through them (docs/theory.md sections 4 and 5). Shared by the static problem
/// and the dynamic one (docs/theory.md section 9).
#include "flexopt/io/location.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/optimize/density_filter.hpp"

#include <memory>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// How an element's mass follows its density (section 9.1): linear, or Pedersen's (rho above
/// 0.1, 1e5 rho^6 below, so that void elements carry no spurious mass modes).
enum class MassInterpolation { Linear, Pedersen };

/// The design field of a topology optimization (`design:`).
struct DesignSettings {
  std::string body;
  std::string region = "design"; ///< physical volume holding the design elements
  double initial = 0.5;          ///< initial density of every design element
  double penalty = 3.0;          ///< SIMP exponent p
  double min_stiffness = 1e-9;   ///< E_min / E_0
  /// The stress relaxation exponent q of the qp-approach (stress responses; 0 < q < penalty):
  /// an element's measured stress is ~ rho^q times its solid stress (docs/theory.md 5.1). 0:
  /// not given, DesignField takes default_stress_exponent(penalty).
  double stress_exponent = 0;
  /// Mass interpolation (dynamic analyses; static body forces); default pedersen for an FFRF or
  /// ACF design body and for a static design under gravity or loads.inertia, linear otherwise.
  MassInterpolation mass = MassInterpolation::Linear;
  FilterType filter_type = FilterType::Helmholtz;
  double filter_radius = 0;  ///< Helmholtz length scale r, or cone radius R [m]; 0: not given
                             ///< (DesignField derives it from the design elements' size)
  std::vector<double> beta;  ///< Heaviside projection continuation (empty: no projection)
  double eta = 0.5;          ///< projection threshold
  int beta_every = 25;       ///< iterations per beta value (continuation)
  io::Location where;        ///< the design: map
  io::Location region_where; ///< its region: key (the design: map where none is given)
};

class DesignField {
public:
  /// The design region `spec.region` of `mesh` (which must outlive the field), its filter and
  /// projection (sharpness spec.beta.front(), or none). Collective; throws a collective
  /// flexopt::Error naming design.region for a missing or empty region.
  DesignField(const mesh::DistributedMesh &mesh, const DesignSettings &spec);
  ~DesignField();
  DesignField(const DesignField &) = delete;
  DesignField &operator=(const DesignField &) = delete;

  /// The first of `surfaces` (physical surfaces of the mesh) that a design element touches
  /// with a node, how many design elements do and the Gmsh tag of one; `elements` 0: none does.
  /// (A flexible body's interfaces are tied rigidly by the joints: the material there must stay
  /// solid for a design to mean anything.) Collective.
  struct SurfaceContact {
    std::string surface;
    long long elements = 0, tag = -1;
  };
  SurfaceContact touched_surface(const std::vector<std::string> &surfaces) const;

  /// A vector over the design variables (caller destroys it). Collective.
  Vec create_design_vector() const;
  /// design.initial everywhere. Collective.
  void initial_design(Vec x) const;
  PetscInt design_size() const { return global_design_; }
  const mesh::DistributedMesh &mesh() const { return mesh_; }
  /// Gmsh tag of each local design variable (stable across rank counts).
  const std::vector<std::size_t> &design_tags() const { return design_tags_; }
  /// Local element index of each local design variable.
  const std::vector<PetscInt> &design_elements() const { return design_elements_; }
  bool is_design(PetscInt e) const { return is_design_[static_cast<std::size_t>(e)] != 0; }

  /// x -> the densities of all local elements (1 outside the region) -> filtered -> physical
  /// (projected), and the projection's derivative. Collective.
  void update(Vec x);
  /// Element vectors of the last update (all local elements).
  Vec density() const { return rho_; }
  Vec filtered() const { return filtered_; }
  Vec physical() const { return physical_; }
  /// Projection sharpness (0: none). Set by the optimizer's continuation.
  void set_beta(double beta) { beta_ = beta; }
  double beta() const { return beta_; }
  /// The settings the field was made with (the filter radius filled in when it was derived).
  const DesignSettings &settings() const { return spec_; }
  const DensityFilter &filter() const { return *filter_; }
  DensityFilter &filter() { return *filter_; }
  /// The filter's description, and where its radius came from when design.filter.radius was
  /// not given (the default below).
  std::string filter_description() const;
  /// The default filter radius: the cone radius R = 2.5 h of the mean edge length h of the
  /// design elements, or the Helmholtz r = R / (2 sqrt 3) of the same smoothing. Collective.
  static double default_filter_radius(const mesh::DistributedMesh &mesh,
                                      const std::vector<PetscInt> &elements, FilterType type,
                                      double *mean_edge = nullptr);

  const std::vector<double> &element_volumes() const { return volume_; }
  double design_volume() const { return design_volume_; }
  /// Volume fraction of the design region (physical densities). Collective.
  double volume_fraction() const;
  /// d(volume fraction)/d(physical density) into the element vector g.
  void volume_fraction_gradient(Vec g) const;

  /// The SIMP modulus factors s = E_min/E_0 + rho^p (1 - E_min/E_0) of the physical densities
  /// of all local elements and their derivatives (1 and 0 outside the design region).
  void stiffness_factors(std::vector<double> &s, std::vector<double> &ds) const;
  /// The stress relaxation factors eta = ((rho + d)^q - d^q) / ((1 + d)^q - d^q), d =
  /// kStressShift, q = stress_exponent, of the physical densities of all local elements and
  /// their derivatives, as stiffness_factors (docs/theory.md 5.1).
  void stress_factors(std::vector<double> &eta, std::vector<double> &deta) const;
  static constexpr double kStressShift = 1e-6;
  /// q = max(p - 3/2, p/2): below p - 1, so that grey material carries no load more cheaply
  /// than solid (docs/theory.md 5.1, "Relaxation"), and as close to it as the measured L-bracket
  /// designs allow; 1.5 at p = 3.
  static double default_stress_exponent(double penalty);
  /// The mass factors of `interpolation.mass` (linear: rho; pedersen: rho above 0.1, 1e5 rho^6
  /// below; docs/theory.md section 9.1) and their derivatives, as stiffness_factors.
  void mass_factors(std::vector<double> &w, std::vector<double> &dw) const;

  /// g_x = R F^T (P' g_physical): a sensitivity with respect to the physical densities of all
  /// local elements (element vector, overwritten) pulled back to the design variables.
  /// Collective.
  void pull_back(Vec g_physical, Vec g_x) const;

private:
  const mesh::DistributedMesh &mesh_;
  DesignSettings spec_;
  double default_edge_ = 0; ///< mean edge length behind a default filter radius (0: given)
  std::unique_ptr<DensityFilter> filter_;
  std::vector<PetscInt> design_elements_;
  std::vector<char> is_design_;
  std::vector<std::size_t> design_tags_;
  std::vector<double> volume_;
  double design_volume_ = 0;
  PetscInt global_design_ = 0;
  Vec rho_ = nullptr, filtered_ = nullptr, physical_ = nullptr, work_ = nullptr;
  double beta_ = 0;
  std::vector<double> dprojection_;
};

} // namespace flexopt::optimize
