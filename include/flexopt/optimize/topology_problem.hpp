#pragma once
/// \file Static SIMP topology optimization: design field -> filter -> SIMP -> K u = f ->
/// responses, with adjoint gradients (docs/theory.md, section 5).
#include "flexopt/fem/probe.hpp"
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/io/case.hpp"
#include "flexopt/optimize/density_filter.hpp"

#include <memory>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// Values of the objective and constraints at one design, and optionally their gradients
/// with respect to the design variables (Vecs in the design layout, owned by the caller
/// through `TopologyProblem::evaluate`).
struct Evaluation {
  double objective = 0;
  std::vector<double> constraints; ///< response values (the bound is in the spec)
  Vec d_objective = nullptr;
  std::vector<Vec> d_constraints;
  ~Evaluation();
};

class TopologyProblem {
public:
  /// Sets up the body, its static problem, the design region and the filter. Collective.
  static std::unique_ptr<TopologyProblem> create(MPI_Comm comm, const io::Case &c);
  ~TopologyProblem();

  /// A vector over the design variables (one per element of the design region). Collective.
  Vec create_design_vector() const;
  /// The initial design (design.initial everywhere). Collective.
  void initial_design(Vec x) const;
  /// Global number of design variables.
  PetscInt design_size() const { return global_design_; }

  /// Evaluates the objective and every constraint at x; with `gradients`, also their
  /// derivatives by the adjoint method (one extra solve per displacement response).
  /// Collective.
  void evaluate(Vec x, bool gradients, Evaluation &out);

  /// Gmsh tag of each local design variable (stable across rank counts).
  const std::vector<std::size_t> &design_tags() const { return design_tags_; }
  const std::vector<std::string> &response_names() const { return names_; }
  const io::Case &case_spec() const { return case_; }
  const mesh::DistributedMesh &mesh() const { return static_->mesh(); }
  fem::StaticProblem &static_problem() { return *static_; }
  /// Filtered densities of all local elements at the last evaluation.
  Vec filtered_density() const { return filtered_; }
  const DensityFilter &filter() const { return *filter_; }
  /// Physical densities (projected filtered densities; = filtered without projection).
  Vec physical_density() const { return physical_; }
  /// Projection sharpness in use (0: no projection). Set by the optimizer's continuation.
  void set_beta(double beta) { beta_ = beta; }
  double beta() const { return beta_; }
  /// Design densities of all local elements at the last evaluation (1 outside the region).
  Vec density() const { return rho_; }
  /// Volume fraction of the design region at the last evaluation (filtered densities).
  /// Collective.
  double volume_fraction();
  int state_solves() const { return solves_; }

private:
  TopologyProblem() = default;
  void embed(Vec x, Vec rho) const;
  void restrict_to_design(Vec full, Vec x) const;
  /// Value of response `index` (0: objective, i: constraint i - 1).
  double response_value(const io::ResponseSpec &r, std::size_t index);
  /// K_e^0 u_e of every local element, computed once per evaluation for all stiffness
  /// responses (their gradients are -ds_e lambda_e . K_e^0 u_e).
  const std::vector<double> &element_ku();
  /// d(response)/d(filtered density) of all local elements into g.
  void response_gradient(const io::ResponseSpec &r, std::size_t index, Vec g);

  io::Case case_;
  std::unique_ptr<fem::StaticProblem> static_;
  std::unique_ptr<DensityFilter> filter_;
  std::vector<PetscInt> design_elements_; ///< local element index of each local design variable
  std::vector<char> is_design_;           ///< per local element
  std::vector<std::size_t> design_tags_;
  std::vector<std::string> names_; ///< objective, then constraints
  std::vector<double> volume_;     ///< element volumes
  double design_volume_ = 0;       ///< total volume of the design region
  PetscInt global_design_ = 0;
  std::vector<fem::PointLocation> sensor_locations_; ///< per response (displacement only)
  Vec rho_ = nullptr, filtered_ = nullptr, physical_ = nullptr, grad_filtered_ = nullptr,
      grad_full_ = nullptr;
  double beta_ = 0;                 ///< 0: no projection
  std::vector<double> dprojection_; ///< d physical / d filtered, all local elements
  Vec adjoint_rhs_ = nullptr, adjoint_ = nullptr;
  std::vector<double> factor_;      ///< SIMP modulus factors (all local elements)
  std::vector<double> dfactor_;     ///< d factor / d filtered density
  std::vector<double> element_ku_;  ///< K_e^0 u_e, 3 * nodes_per_element per element
  bool element_ku_current_ = false; ///< element_ku_ belongs to the current state
  int solves_ = 0;
};

} // namespace flexopt::optimize
