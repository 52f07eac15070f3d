#include "flexopt/optimize/topology_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/krylov.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/core/vec_values.hpp"
#include "flexopt/optimize/design_file.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

namespace flexopt::optimize {

namespace {
/// The responses whose gradient needs an adjoint solve (the compliance is self-adjoint).
bool needs_adjoint(ResponseType t) {
  return t == ResponseType::Displacement || t == ResponseType::Stress;
}
const char *kTopologySolverDefaults =
    "-mg_levels_ksp_type chebyshev -mg_levels_pc_type jacobi -pc_gamg_use_sa_esteig 0 "
    "-mg_levels_esteig_ksp_type cg -mg_levels_esteig_ksp_max_it 10 "
    "-mg_levels_ksp_chebyshev_esteig 0,0.1,0,1.3";
/// -fx_warm_start, if the options give it.
std::optional<bool> warm_start_option() {
  PetscBool on = PETSC_TRUE, set = PETSC_FALSE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_warm_start", &on, &set));
  if (!set) return std::nullopt;
  return on == PETSC_TRUE;
}
} // namespace

std::unique_ptr<TopologyProblem> TopologyProblem::create(MPI_Comm comm, const TopologySettings &c) {
  // Multigrid smoothing that survives the 1e-9 stiffness contrast of void elements: GAMG's
  // default smoothed-aggregation eigenvalue estimate makes Chebyshev smoothing indefinite
  // after the first design update (DIVERGED_INDEFINITE_PC); a 10-step CG (Lanczos) estimate
  // of each level's largest eigenvalue with a 1.3 safety factor does not, for the lattice's
  // geometric multigrid and for GAMG (docs/solvers.md; the estimate is redone for every design,
  // the lattice's coarse levels included since issue 42:
  // at 212k DOFs 10 steps take 0.26 s of a 2-4 s iteration, 50 steps took 1.4 s). Defaults only:
  // the case's solver string and the command line take precedence.
  insert_default_petsc_options(kTopologySolverDefaults, "topology optimization solver defaults");
  std::unique_ptr<TopologyProblem> p(new TopologyProblem());
  p->responses_.push_back(c.objective);
  p->responses_.insert(p->responses_.end(), c.constraints.begin(), c.constraints.end());
  p->static_ = c.share_operator
                   ? fem::StaticProblem::create_sharing(*c.share_operator->static_, c.problem)
                   : fem::StaticProblem::create(comm, c.problem);
  // Each design's solve starts from the last design's displacement (and adjoint): the
  // reference code does the same; late in a run it halves the Krylov iterations
  // (docs/solvers.md). -fx_warm_start 0 starts every solve from zero.
  p->static_->set_warm_start(warm_start_option().value_or(true));
  const mesh::DistributedMesh &m = p->static_->mesh();
  {
    std::vector<std::unique_ptr<DesignField>> fields;
    fields.push_back(std::make_unique<DesignField>(m, c.design));
    p->design_ = std::make_unique<Design>(std::move(fields));
    p->field_ = &p->design_->field(0);
  }
  p->needs_mass_ = p->static_->has_body_load();
  for (std::size_t i = 0; i < p->responses_.size(); ++i) {
    const ResponseSettings &r = p->responses_[i];
    p->names_.push_back((i == 0 ? std::string("objective") : "constraint" + std::to_string(i - 1)) +
                        ":" + response_type_name(r.type));
    fem::PointLocation loc;
    if (r.type == ResponseType::Displacement)
      loc = fem::locate(m, r.point, r.point_where.str() + ": sensor '" + r.sensor + "'");
    p->sensor_locations_.push_back(loc);
    p->stress_.push_back(r.type == ResponseType::Stress
                             ? std::make_unique<StaticStress>(m, p->static_->material(), r)
                             : nullptr);
    if (r.type == ResponseType::Mass) {
      if (!(p->static_->material().density > 0))
        throw Error(r.where.str() + ": a mass response needs the body's material density > 0",
                    true);
      p->needs_mass_ = true;
    }
  }
  // One adjoint per response that needs a solve (its warm start is that response's last one).
  for (const ResponseSettings &r : p->responses_) {
    Vec a = nullptr;
    if (needs_adjoint(r.type)) {
      a = fem::create_ghosted_vector(m);
      FX_PETSC(VecZeroEntries(a));
    }
    p->adjoints_.push_back(a);
  }
  p->grad_physical_ = p->field_->filter().create_element_vector();
  p->adjoint_rhs_ = fem::create_ghosted_vector(m);
  return p;
}

std::vector<std::string> TopologyProblem::solve_to_round_off() {
  // Never warm-started, whatever -fx_warm_start says: a warm start's error follows the previous
  // design, which in a central difference is the other side of the same difference, so it
  // biases the quotient instead of averaging out (measured: 2e-3 on tests/gradient/plate_hole
  // with -ksp_rtol 1e-8, where cold starts at 1e-8 gave 2.3e-7).
  static_->set_warm_start(false);
  std::vector<std::string> limits;
  for (const std::string &l :
       {static_->solve_to_round_off(), field_->filter().solve_to_round_off()})
    if (!l.empty()) limits.push_back(l);
  return limits;
}

namespace {

/// Sets the owned values of a ghosted vector and updates its ghosts. Collective.
void set_owned_values(Vec v, const std::vector<double> &values) {
  set_local_values(v, values);
  FX_PETSC(VecGhostUpdateBegin(v, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(v, INSERT_VALUES, SCATTER_FORWARD));
}

} // namespace

/// The restart state's name of response i's adjoint: "adjoint" for the first response with
/// one (the name of the files before issue 43), "adjoint_<i>" for the others.
std::string TopologyProblem::adjoint_key(std::size_t i) const {
  for (std::size_t j = 0; j < i; ++j)
    if (needs_adjoint(responses_[j].type)) return "adjoint_" + std::to_string(i);
  return "adjoint";
}

std::map<std::string, std::vector<double>> TopologyProblem::solver_state() const {
  if (!static_->warm_start()) return {};
  std::map<std::string, std::vector<double>> state{{"u", local_values(static_->displacement())}};
  for (std::size_t i = 0; i < adjoints_.size(); ++i)
    if (adjoints_[i]) state[adjoint_key(i)] = local_values(adjoints_[i]);
  return state;
}

std::vector<std::uint64_t> TopologyProblem::solver_state_keys() const {
  if (!static_->warm_start()) return {};
  return dof_keys(mesh(), 3); // the displacement's layout: 3 DOFs per owned node, node-major
}

void TopologyProblem::restore_solver_state(
    const std::map<std::string, std::vector<double>> &state) {
  const auto n = static_cast<std::size_t>(3 * mesh().owned_nodes);
  const auto u = state.find("u");
  if (u != state.end() && u->second.size() == n)
    set_owned_values(static_->displacement(), u->second);
  for (std::size_t i = 0; i < responses_.size(); ++i) {
    const auto a = state.find(adjoint_key(i));
    if (adjoints_[i] && a != state.end() && a->second.size() == n)
      set_owned_values(adjoints_[i], a->second);
  }
}

void TopologyProblem::end_iteration() {
  end_iterations(stress_);
}

std::vector<DesignProblem::DesignStress> TopologyProblem::design_stress() const {
  std::vector<DesignStress> out;
  for (std::size_t i = 0; i < stress_.size(); ++i)
    if (stress_[i]) out.push_back({i, 0, &stress_[i]->aggregate()});
  return out;
}

std::vector<double> TopologyProblem::response_scales() const {
  return scales_of(stress_);
}

void TopologyProblem::restore_response_scales(const std::vector<double> &scales) {
  restore_scales(stress_, scales);
}

std::vector<std::string> TopologyProblem::cell_field_names() const {
  for (const auto &s : stress_)
    if (s) return {"von_mises"};
  return {};
}

std::vector<std::pair<std::string, std::vector<double>>> TopologyProblem::cell_fields() const {
  if (eta_.empty()) return {};
  return {{"von_mises",
           fem::element_von_mises(mesh(), static_->material(), eta_, static_->displacement())}};
}

void TopologyProblem::assemble_stiffness() {
  // SIMP: s = e_min + rho~^p (1 - e_min) on design elements; solid (s = 1) elsewhere.
  field_->stiffness_factors(factor_, dfactor_);
  static_->assemble_operator(factor_);
}

void TopologyProblem::prepare_resume(Vec x0) {
  field_->update(x0);
  assemble_stiffness();
  static_->set_up_solver();
}

bool TopologyProblem::set_random_start(unsigned long seed) {
  const bool state = static_->set_random_start(seed);
  const bool filter = field_->filter().set_random_start(seed);
  return state || filter;
}

TopologyProblem::~TopologyProblem() {
  VecDestroy(&grad_physical_);
  for (Vec &a : adjoints_) VecDestroy(&a);
  VecDestroy(&adjoint_rhs_);
}

void TopologyProblem::describe(io::Json &s) const {
  s["dofs"] = static_cast<long long>(static_->global_dofs());
  s["elements"] = static_cast<long long>(mesh().global_elements);
  s["design_variables"] = static_cast<long long>(design_size());
  s["state_solves"] = solves_;
  s["krylov_iterations"] = krylov_;
  const io::Json stress = describe_stress(stress_, names_);
  if (!stress.is_null()) s["stress"] = stress;
}

double TopologyProblem::response_value(const ResponseSettings &r, std::size_t index) {
  if (r.type == ResponseType::Compliance) return static_->compliance();
  if (r.type == ResponseType::VolumeFraction) return field_->volume_fraction();
  if (r.type == ResponseType::Stress)
    return stress_[index]->evaluate(static_->displacement(), eta_);
  if (r.type == ResponseType::Mass) return mass();
  // displacement: d . u(sensor point), at the location found once in create()
  const auto u = fem::probe_vector(mesh(), static_->displacement(), sensor_locations_[index]);
  return u[0] * r.direction[0] + u[1] * r.direction[1] + u[2] * r.direction[2];
}

const std::vector<double> &TopologyProblem::element_ku() {
  if (element_ku_current_) return element_ku_;
  const mesh::DistributedMesh &m = mesh();
  const int nd = 3 * m.nodes_per_element();
  element_ku_.assign(static_cast<std::size_t>(m.local_elements() * nd), 0.0);
  Vec ul;
  const PetscScalar *u;
  FX_PETSC(VecGhostGetLocalForm(static_->displacement(), &ul));
  FX_PETSC(VecGetArrayRead(ul, &u));
  fem::UnitStiffness unit(m.type, static_->material()); // the assembly's K_e^0
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    if (dfactor_[static_cast<std::size_t>(e)] == 0.0) continue; // no sensitivity there
    const fem::ElementVector ku = unit(m.element_coordinates(e)) * fem::gather_element(m, e, u);
    std::copy(ku.data(), ku.data() + nd, element_ku_.begin() + static_cast<std::ptrdiff_t>(e * nd));
  }
  FX_PETSC(VecRestoreArrayRead(ul, &u));
  FX_PETSC(VecGhostRestoreLocalForm(static_->displacement(), &ul));
  element_ku_current_ = true;
  return element_ku_;
}

double TopologyProblem::mass() const {
  const std::vector<double> &v = field_->element_volumes();
  double local = 0;
  for (std::size_t e = 0; e < mass_.size(); ++e) local += mass_[e] * v[e];
  double total = 0;
  MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, mesh().comm);
  return static_->material().density * total;
}

void TopologyProblem::response_gradient(const ResponseSettings &r, std::size_t index, Vec g) {
  LogScope log("FxSensitivities");
  const mesh::DistributedMesh &m = mesh();
  PetscScalar *ga;
  if (r.type == ResponseType::VolumeFraction) {
    field_->volume_fraction_gradient(g);
    return;
  }
  if (r.type == ResponseType::Mass) { // density * w'(rho_e) V_e
    const std::vector<double> &v = field_->element_volumes();
    FX_PETSC(VecGetArray(g, &ga));
    for (std::size_t e = 0; e < dmass_.size(); ++e)
      ga[e] = static_->material().density * dmass_[e] * v[e];
    FX_PETSC(VecRestoreArray(g, &ga));
    return;
  }
  // Stiffness responses: dR/ds_e = -lambda_e^T K_e u_e, with lambda = u for the compliance
  // (self-adjoint) and K lambda = dR/du for a displacement (the point functional c) or a
  // stress (section 5.1). A body force f_b = sum_e w_e f_e depends on the design through the
  // mass factors w: it adds dR/dw_e = lambda_e . f_e, twice for the compliance f . u (its
  // explicit f; docs/theory.md section 5).
  Vec lambda = static_->displacement();
  if (r.type == ResponseType::Displacement || r.type == ResponseType::Stress) {
    if (r.type == ResponseType::Displacement) {
      FX_PETSC(VecZeroEntries(adjoint_rhs_));
      fem::add_point_functional(m, sensor_locations_[index], r.direction, adjoint_rhs_);
    } else {
      stress_[index]->adjoint_load(eta_, adjoint_rhs_);
    }
    lambda = adjoints_[index];
    static_->solve_adjoint(adjoint_rhs_, lambda);
    ++solves_;
  }
  const std::vector<double> &ku = element_ku();
  const int nd = 3 * m.nodes_per_element();
  Vec ll;
  const PetscScalar *l;
  FX_PETSC(VecGhostGetLocalForm(lambda, &ll));
  FX_PETSC(VecGetArrayRead(ll, &l));
  FX_PETSC(VecGetArray(g, &ga));
  const bool body = static_->has_body_load();
  const double load_weight = r.type == ResponseType::Compliance ? 2.0 : 1.0;
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const double ds = dfactor_[static_cast<std::size_t>(e)];
    const double dw = body ? dmass_[static_cast<std::size_t>(e)] : 0.0;
    if (ds == 0.0 && dw == 0.0) {
      ga[e] = 0.0;
      continue;
    }
    const fem::ElementVector le = fem::gather_element(m, e, l);
    double dot = 0;
    for (int k = 0; k < nd; ++k) dot += le(k) * ku[static_cast<std::size_t>(e * nd + k)];
    ga[e] = -ds * dot;
    if (dw != 0.0) {
      const double *fe = static_->element_body_load(e);
      double lf = 0;
      for (int k = 0; k < nd; ++k) lf += le(k) * fe[k];
      ga[e] += load_weight * dw * lf;
    }
  }
  if (r.type == ResponseType::Stress) stress_[index]->add_explicit(eta_, deta_, ga);
  FX_PETSC(VecRestoreArray(g, &ga));
  FX_PETSC(VecRestoreArrayRead(ll, &l));
  FX_PETSC(VecGhostRestoreLocalForm(lambda, &ll));
}

void TopologyProblem::evaluate(Vec x, bool gradients, Evaluation &out) {
  LogScope log("FxTopologyEvaluate");
  field_->update(x);
  const double t_solve = wall_time();
  assemble_stiffness();
  if (needs_mass_) field_->mass_factors(mass_, dmass_);
  if (static_->has_body_load()) // self-weight, inertia: scaled by the mass interpolation
    static_->set_body_load_factors(mass_);
  if (std::any_of(stress_.begin(), stress_.end(), [](const auto &p) { return p != nullptr; }))
    field_->stress_factors(eta_, deta_);
  static_->solve();
  krylov_.push_back(static_->iterations());
  element_ku_current_ = false;
  ++solves_;
  solve_s_ = wall_time() - t_solve;
  adjoint_s_ = 0;

  const std::size_t constraints = responses_.size() - 1;
  out.constraints.assign(constraints, 0.0);
  for (std::size_t i = 0; i < responses_.size(); ++i)
    out.value(i) = response_value(responses_[i], i);
  if (!gradients) return;
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 0; i < constraints; ++i)
      out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < responses_.size(); ++i) {
    const double t_adjoint = wall_time();
    response_gradient(responses_[i], i, grad_physical_); // d/d(physical density)
    adjoint_s_ += wall_time() - t_adjoint;
    field_->pull_back(grad_physical_, out.gradient(i));
  }
}

} // namespace flexopt::optimize
