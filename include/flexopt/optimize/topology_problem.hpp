#pragma once
/// \file Static SIMP topology optimization: design field -> filter -> SIMP -> K u = f ->
/// responses, with adjoint gradients (docs/theory.md, section 5).
#include "flexopt/fem/probe.hpp"
#include "flexopt/fem/static_problem.hpp"
#include "flexopt/optimize/design.hpp"
#include "flexopt/optimize/design_problem.hpp"
#include "flexopt/optimize/response.hpp"
#include "flexopt/optimize/static_stress.hpp"

#include <memory>
#include <string>
#include <vector>

namespace flexopt::optimize {

/// A static topology optimization: the static problem, the design field and the responses.
class TopologyProblem;

struct TopologySettings {
  fem::StaticSettings problem;
  DesignSettings design;
  ResponseSettings objective;
  std::vector<ResponseSettings> constraints;
  /// Another load case of this problem's body (equivalent static loads): its mesh, stiffness
  /// and solver are shared (fem::StaticProblem::create_sharing).
  const TopologyProblem *share_operator = nullptr;
};

class TopologyProblem : public DesignProblem {
public:
  /// Sets up the body, its static problem, the design region and the filter. Collective.
  static std::unique_ptr<TopologyProblem> create(MPI_Comm comm, const TopologySettings &settings);
  ~TopologyProblem();

  /// Evaluates the objective and every constraint at x; with `gradients`, also their
  /// derivatives by the adjoint method (one extra solve per displacement or stress response).
  /// Collective.
  void evaluate(Vec x, bool gradients, Evaluation &out) override;
  /// dofs, elements, design_variables, state_solves, krylov_iterations (of every state solve,
  /// in order: how the solver copes as the design gains contrast), and for each stress response
  /// its aggregate, peak and the peak's element at the last evaluation ("stress").
  void describe(io::Json &summary) const override;
  /// 1e-10: the state solve is accurate to about eps cond(K), measured ~1e-11 relative on the
  /// test cases.
  double noise_floor() const override { return 1e-10; }
  /// The state and adjoint solves from zero (never warm-started: -fx_warm_start does not apply)
  /// to a relative residual of 1e-12, the filter's too, unless the options set their tolerances.
  std::vector<std::string> solve_to_round_off() override;
  /// Random starts for the state, adjoint and filter solves (those that are iterative).
  bool set_random_start(unsigned long seed) override;
  long long dofs() const override { return static_cast<long long>(static_->global_dofs()); }
  /// With the warm start on: the last displacement ("u") and adjoint ("adjoint") solutions,
  /// where the next evaluation's solves start.
  std::map<std::string, std::vector<double>> solver_state() const override;
  std::vector<std::uint64_t> solver_state_keys() const override;
  void restore_solver_state(const std::map<std::string, std::vector<double>> &state) override;
  /// K at x0 assembled and the state solver set up on it (no solve).
  void prepare_resume(Vec x0) override;
  /// The stress responses' adaptive normalization (docs/theory.md 5.1).
  void end_iteration() override;
  std::vector<double> response_scales() const override;
  std::vector<DesignStress> design_stress() const override;
  void restore_response_scales(const std::vector<double> &scales) override;
  /// Cell fields of design.xdmf beyond the densities: with a stress response, "von_mises", the
  /// relaxed von Mises stress eta(rho) v of every element [Pa] (docs/theory.md 5.1).
  std::vector<std::pair<std::string, std::vector<double>>> cell_fields() const override;
  std::vector<std::string> cell_field_names() const override;
  /// solve (assembly and state solve), adjoint (the sensitivities and their adjoint solves).
  std::vector<Timing> timings() const override {
    return {{"solve", "solve", solve_s_}, {"adjoint", "adjoint", adjoint_s_}};
  }

  Design &design() override { return *design_; }
  const Design &design() const override { return *design_; }
  const std::vector<std::string> &response_names() const override { return names_; }
  const mesh::DistributedMesh &mesh() const { return static_->mesh(); }
  fem::StaticProblem &static_problem() { return *static_; }
  int state_solves() const { return solves_; }
  /// Response i's stress (null unless it is a stress response).
  const StaticStress *stress_response(std::size_t i) const { return stress_[i].get(); }

private:
  TopologyProblem() = default;
  /// K with the SIMP factors of the field's current physical densities. Collective.
  void assemble_stiffness();
  /// The body's mass sum_e w(rho_e) density V_e [kg] (all elements; w the mass interpolation).
  /// Collective.
  double mass() const;
  /// Value of response `index` (0: objective, i: constraint i - 1).
  double response_value(const ResponseSettings &r, std::size_t index);
  /// The restart state's key of response i's adjoint ("adjoint", "adjoint_<i>").
  std::string adjoint_key(std::size_t i) const;
  /// K_e^0 u_e of every local element, computed once per evaluation for all stiffness
  /// responses (their gradients are -ds_e lambda_e . K_e^0 u_e).
  const std::vector<double> &element_ku();
  /// d(response)/d(filtered density) of all local elements into g.
  void response_gradient(const ResponseSettings &r, std::size_t index, Vec g);

  std::vector<ResponseSettings> responses_; ///< objective, then constraints
  std::unique_ptr<fem::StaticProblem> static_;
  std::unique_ptr<Design> design_;
  DesignField *field_ = nullptr;                     ///< the design's one field
  std::vector<std::string> names_;                   ///< objective, then constraints
  std::vector<fem::PointLocation> sensor_locations_; ///< per response (displacement only)
  Vec grad_physical_ = nullptr;
  Vec adjoint_rhs_ = nullptr;
  std::vector<Vec> adjoints_;                         ///< per response (null: none)
  std::vector<std::unique_ptr<StaticStress>> stress_; ///< per response (null: not stress)
  std::vector<double> eta_, deta_;                    ///< stress relaxation factors
  std::vector<double> factor_;                        ///< SIMP modulus factors (all local elements)
  std::vector<double> dfactor_;                       ///< d factor / d filtered density
  std::vector<double> mass_, dmass_; ///< mass factors (body forces, mass) and derivatives
  bool needs_mass_ = false;          ///< a body load or a mass response
  std::vector<double> element_ku_;   ///< K_e^0 u_e, 3 * nodes_per_element per element
  bool element_ku_current_ = false;  ///< element_ku_ belongs to the current state
  int solves_ = 0;
  std::vector<double> krylov_;         ///< Krylov iterations of every state solve
  double solve_s_ = 0, adjoint_s_ = 0; ///< of the last evaluation
};

} // namespace flexopt::optimize
