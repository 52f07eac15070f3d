#include "flexopt/adjoint/dynamic_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/core/memory.hpp"
#include "flexopt/io/xdmf.hpp"
#include "flexopt/optimize/static_stress.hpp"
#include "passes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace flexopt::adjoint {

namespace {

/// A flexible design body's interfaces are tied rigidly by the joints: a design region that
/// touches one is refused (`refuse`, optimize) or warned about (the derivatives of such a
/// region are still right, and check-gradient and simulate take it).
void check_interfaces(const optimize::DesignField &f, const dynamics::BodyDescription &body,
                      const optimize::DesignSettings &d, bool refuse) {
  const optimize::DesignField::SurfaceContact c = f.touched_surface(body.interfaces);
  if (c.elements == 0) return;
  const std::string what =
      d.region_where.str() + ": design.region '" + d.region + "' of body '" + d.body +
      "' touches its interface '" + c.surface + "' (" + std::to_string(c.elements) +
      " design elements have nodes on it, e.g. Gmsh element " + std::to_string(c.tag) + ")";
  if (refuse)
    throw Error(what + ": a joint ties the interface rigidly, so the material around it must stay "
                       "solid for the design to hold the joint. Keep the interface out of the "
                       "design region: give the material around it (a boss around a pin) its own "
                       "physical volume",
                true);
  print0(f.mesh().comm,
         "design: warning: %s; optimize refuses such a region (a void there would cut the joint "
         "off)\n",
         what.c_str());
}

/// A mass bound on the design body that even an empty design region exceeds cannot hold: it is
/// refused before any computation, with the mass of the material outside the region.
void check_mass_bounds(const optimize::DesignField &f, const DynamicSettings &c) {
  const optimize::DesignSettings &d = c.design;
  const double density = c.scene.body(d.body).material.density;
  const std::vector<double> &volume = f.element_volumes();
  double mass[2] = {0, 0}; // outside the region, inside it
  for (PetscInt e = 0; e < f.mesh().local_elements(); ++e)
    mass[f.is_design(e) ? 1 : 0] += density * volume[static_cast<std::size_t>(e)];
  MPI_Allreduce(MPI_IN_PLACE, mass, 2, MPI_DOUBLE, MPI_SUM, f.mesh().comm);
  for (const optimize::ResponseSettings &r : c.constraints)
    if (r.type == optimize::ResponseType::Mass && r.body == d.body && r.max <= mass[0]) {
      std::ostringstream msg;
      msg << r.where.str() << ": constraint mass of body '" << d.body << "' <= " << r.max
          << " kg cannot hold: the material outside design.region '" << d.region
          << "' alone weighs " << mass[0] << " kg (the solid body " << mass[0] + mass[1]
          << " kg). Raise the bound or enlarge the design region";
      throw Error(msg.str(), true);
    }
}

} // namespace

std::unique_ptr<DynamicProblem> DynamicProblem::create(MPI_Comm comm, const DynamicSettings &c,
                                                       const std::string &scratch,
                                                       bool refuse_interfaces) {
  const optimize::DesignSettings &d = c.design;
  const dynamics::BodyDescription &body = c.scene.body(d.body);
  using dynamics::BodyModel;
  const BodyModel model = dynamics::simulated_model(body.model);
  if (model == BodyModel::Ffrf) {
    // What the FFRF design body's adjoint does not differentiate yet on the distributed
    // backend (docs/theory.md 9.8): say so before computing.
    bool given = false;
    for (const auto *f : {&body.initial.elastic_displacement, &body.initial.elastic_velocity})
      for (const std::string &e : *f) given = given || !e.empty();
    for (const dynamics::BodyDescription &b : c.scene.bodies)
      if (dynamics::simulated_model(b.model) == BodyModel::Acf && given)
        throw Error(d.where.str() + ": design.body '" + d.body +
                        "' is an FFRF body with initial elastic fields in a scene with ACF "
                        "bodies (body '" +
                        b.name +
                        "'), whose design sensitivities are not built yet (drop its "
                        "initial.elastic_displacement and elastic_velocity, or make the ACF "
                        "bodies FFRF)",
                    true);
  }
  std::unique_ptr<DynamicProblem> p(new DynamicProblem());
  p->settings_ = c;
  p->scratch_ = scratch;
  // An FFRF design body is reduced once, with its first design (the reduction is reused by
  // the first evaluation at that design).
  reduce::ElementFactors first;
  // The design field is made on the design body's mesh as soon as it is meshed (the scene keeps
  // its meshes at fixed addresses) and kept: its filter is built once.
  std::unique_ptr<optimize::DesignField> field;
  const dynamics::InitialDesign initial{d.body, [&](const mesh::DistributedMesh &m) {
                                          field = std::make_unique<optimize::DesignField>(m, d);
                                          optimize::DesignField &f = *field;
                                          check_interfaces(f, body, d, refuse_interfaces);
                                          check_mass_bounds(f, c);
                                          Vec x = f.create_design_vector();
                                          f.initial_design(x);
                                          f.update(x);
                                          std::vector<double> dw, ds;
                                          f.mass_factors(first.mass, dw);
                                          f.stiffness_factors(first.stiffness, ds);
                                          VecDestroy(&x);
                                          return first;
                                        }};
  p->scene_ = dynamics::build_scene(comm, c.scene, model == BodyModel::Ffrf ? &initial : nullptr);
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    if (c.scene.bodies[b].name == d.body) p->design_body_ = static_cast<int>(b);
  const dynamics::SceneBody &dsb = p->scene_.bodies[static_cast<std::size_t>(p->design_body_)];
  p->mechanism_body_ = dsb.mechanism;
  p->acf_design_ = dsb.acf;
  p->ffrf_design_ = model == BodyModel::Ffrf;
  if (p->ffrf_design_) {
    p->reduction_ = dsb.reduction;
    p->reduced_factors_ = first;
    p->reduction_s_ = p->scene_.reduction_seconds[static_cast<std::size_t>(p->design_body_)];
  }
  p->basis_ = c.adjoint.basis;
  const mesh::DistributedMesh &m = p->scene_.meshes[static_cast<std::size_t>(p->design_body_)];
  if (field && &field->mesh() != &m)
    throw Error("DynamicProblem: the design field's mesh is not the scene's", true);
  p->field_ = field ? std::move(field) : std::make_unique<optimize::DesignField>(m, d);
  // A flexible body's interfaces are tied rigidly (FFRF: checked before the reduction, above).
  if (model == BodyModel::Acf) check_interfaces(*p->field_, body, d, refuse_interfaces);
  if (model != BodyModel::Ffrf) check_mass_bounds(*p->field_, c);
  p->grad_physical_ = p->field_->filter().create_element_vector();

  if (model == BodyModel::Rigid) {
    // The design body keeps its solid centre of mass as its reference point (section 9.1).
    const auto &solid =
        dynamic_cast<const bodies::RigidBody &>(p->scene_.mechanism.body(p->mechanism_body_));
    p->reference_ = solid.center();
    const double density = body.material.density;
    p->element_theta_.resize(static_cast<std::size_t>(m.local_elements()));
    for (PetscInt e = 0; e < m.local_elements(); ++e)
      p->element_theta_[static_cast<std::size_t>(e)] =
          bodies::element_mass_parameters(m.type, m.element_coordinates(e), density, p->reference_);
  }

  p->bind_responses(model);
  p->integration_ = dynamics::IntegratorSettings::from(c.time);
  p->steps_ = p->integration_.steps;
  return p;
}

void DynamicProblem::bind_responses(dynamics::BodyModel model) {
  using dynamics::BodyModel;
  specs_.push_back(&settings_.objective);
  for (const auto &r : settings_.constraints) specs_.push_back(&r);
  names_.push_back(std::string("objective:") +
                   optimize::response_type_name(settings_.objective.type));
  for (std::size_t i = 0; i < settings_.constraints.size(); ++i)
    names_.push_back("constraint" + std::to_string(i) + ":" +
                     optimize::response_type_name(settings_.constraints[i].type));
  for (const optimize::ResponseSettings *r : specs_) {
    int sensor = -1;
    if (!r->sensor.empty())
      for (std::size_t k = 0; k < scene_.sensors.size(); ++k)
        if (scene_.sensors[k].name == r->sensor) sensor = static_cast<int>(k);
    sensor_of_.push_back(sensor);
    ev_.sensor_frames.emplace_back();
    bool on_design = false;
    if (sensor >= 0 && ffrf_design_) {
      const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor)];
      on_design = s.acf_body < 0 && s.body == mechanism_body_ &&
                  s.quantity != dynamics::SensorQuantity::RotationAngle;
    }
    sensor_on_design_.push_back(on_design);
    strain_body_.push_back(-1);
    if (r->type == optimize::ResponseType::StrainEnergyIntegral) {
      const BodyModel bm = dynamics::simulated_model(settings_.scene.body(r->body).model);
      if (bm == BodyModel::Rigid)
        throw Error(r->where.str() + ": strain_energy_integral of body '" + r->body +
                        "': a rigid body has no strain energy (ACF and FFRF bodies have)",
                    true);
      if (bm == BodyModel::Ffrf)
        for (std::size_t b = 0; b < settings_.scene.bodies.size(); ++b)
          if (settings_.scene.bodies[b].name == r->body)
            strain_body_.back() = scene_.bodies[b].mechanism;
    }
    bind_stress(*r);
    if (sensor >= 0 && model == BodyModel::Acf) {
      const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor)];
      if (s.acf_body >= 0 && s.quantity == dynamics::SensorQuantity::ElasticDisplacement)
        throw Error(r->where.str() + ": sensor '" + s.name +
                        "' measures the elastic displacement of an ACF body, which a response "
                        "cannot use yet (position, displacement)",
                    true);
    }
  }
}

void DynamicProblem::bind_stress(const optimize::ResponseSettings &r) {
  using dynamics::BodyModel;
  stress_.push_back(nullptr);
  stress_body_.push_back(-1);
  stress_case_body_.push_back(-1);
  if (r.type != optimize::ResponseType::Stress) return;
  std::size_t b = 0;
  while (settings_.scene.bodies[b].name != r.body) ++b;
  const dynamics::BodyDescription &body = settings_.scene.bodies[b];
  const BodyModel bm = dynamics::simulated_model(body.model);
  // `model: auto` resolved to rigid reaches here; an explicit rigid body is refused when read.
  if (bm == BodyModel::Rigid)
    throw Error(r.where.str() + ": stress of body '" + r.body +
                    "': a rigid body has no stress (the plan made it rigid: give it model: ffrf "
                    "or model: acf)",
                true);
  stress_case_body_.back() = static_cast<int>(b);
  if (bm == BodyModel::Acf) { // the co-rotated stress (docs/theory.md 8.3)
    const int a = scene_.bodies[b].acf;
    stress_.back() = std::make_unique<AcfStress>(r, *scene_.acf[static_cast<std::size_t>(a)]);
    stress_body_.back() = a;
    return;
  }
  if (static_cast<int>(b) == design_body_ &&
      settings_.adjoint.basis == reduce::BasisDerivative::Fixed)
    print0(scene_.meshes[b].comm,
           "%s: warning: adjoint.basis: fixed holds the stress shapes of body '%s' fixed, and "
           "their change with the design dominates a stress gradient (measured 110-150 %% off, "
           "63-90 degrees from the exact one on tests/gradient/ffrf_stress; docs/benchmarks.md): "
           "use basis: exact\n",
           r.where.str().c_str(), r.body.c_str());
  auto ffrf = std::make_unique<FfrfStress>(r, scene_.meshes[b], body.material);
  ffrf->set_basis(scene_.bodies[b].reduction->basis);
  stress_.back() = std::move(ffrf);
  stress_body_.back() = scene_.bodies[b].mechanism;
}

void DynamicProblem::end_iteration() {
  optimize::end_iterations(stress_);
}

std::vector<double> DynamicProblem::response_scales() const {
  return optimize::scales_of(stress_);
}

std::vector<std::pair<std::size_t, const optimize::StressAggregate *>>
DynamicProblem::design_stress() const {
  std::vector<std::pair<std::size_t, const optimize::StressAggregate *>> out;
  for (std::size_t i = 0; i < stress_.size(); ++i)
    if (stress_[i] && stress_case_body_[i] == design_body_)
      out.emplace_back(i, &stress_[i]->aggregate());
  return out;
}

void DynamicProblem::restore_response_scales(const std::vector<double> &scales) {
  optimize::restore_scales(stress_, scales);
}

DynamicProblem::~DynamicProblem() {
  VecDestroy(&grad_physical_);
}

const mesh::DistributedMesh &DynamicProblem::mesh() const {
  return scene_.meshes[static_cast<std::size_t>(design_body_)];
}

double DynamicProblem::response_value(std::size_t i) const {
  const optimize::ResponseSettings &r = *specs_[i];
  if (r.type == optimize::ResponseType::VolumeFraction) return field_->volume_fraction();
  if (r.type == optimize::ResponseType::Mass) {
    if (r.body == settings_.design.body && acf_design_ < 0 && !ffrf_design_) return ev_.theta(0);
    for (std::size_t b = 0; b < settings_.scene.bodies.size(); ++b)
      if (settings_.scene.bodies[b].name == r.body) {
        const dynamics::SceneBody &sb = scene_.bodies[b];
        if (sb.acf >= 0) return scene_.acf[static_cast<std::size_t>(sb.acf)]->total_mass();
        return scene_.mechanism.body(sb.mechanism).mass();
      }
  }
  return ev_.sampled[i].value;
}

void DynamicProblem::apply_design(Vec x) {
  field_->update(x);
  // Mass factors w (section 9.1) and, for an ACF body, SIMP modulus factors s (section 9.6).
  field_->mass_factors(ev_.w, ev_.dw);
  field_->stiffness_factors(ev_.s, ev_.ds);
  if (acf_design_ >= 0) {
    scene_.acf[static_cast<std::size_t>(acf_design_)]->set_factors(ev_.s, ev_.w);
  } else if (ffrf_design_) {
    // Collective: every rank compares its own elements (a change of one element's density
    // moves the factors on its rank only).
    int changed = ev_.s != reduced_factors_.stiffness || ev_.w != reduced_factors_.mass, any = 0;
    MPI_Allreduce(&changed, &any, 1, MPI_INT, MPI_LOR, mesh().comm);
    if (any) {
      const double t0 = wall_time();
      reduced_factors_ = reduce::ElementFactors{ev_.s, ev_.w};
      reduction_ =
          dynamics::set_ffrf_design(mesh().comm, settings_.scene, scene_,
                                    static_cast<std::size_t>(design_body_), reduced_factors_);
      reduction_s_ = wall_time() - t0;
      ev_.reduction_s = reduction_s_;
      for (std::size_t i = 0; i < stress_.size(); ++i)
        if (stress_[i] && stress_case_body_[i] == design_body_)
          ffrf_stress(i)->set_basis(reduction_->basis);
    }
  } else {
    set_rigid_design();
  }
}

void DynamicProblem::evaluate(Vec x, bool gradients, optimize::Evaluation &out) {
  LogScope log("FxDynamicEvaluate");
  ++evaluations_;
  ev_ = {};
  // The design into the scene (sections 9.1, 9.6, 10): mass and modulus factors, the rigid
  // design body's mass parameters or the FFRF design body's reduction.
  apply_design(x);
  ev_.element_gradient.assign(
      specs_.size(), std::vector<double>(static_cast<std::size_t>(mesh().local_elements()), 0.0));
  // The forward run from the consistent start, its samples and checkpoints, and the responses
  // on the time grid (sections 9.2-9.4).
  const double t_forward = wall_time();
  const std::unique_ptr<detail::Pass> pass = detail::make_pass(*this, gradients);
  pass->forward();
  finish_forward(wall_time() - t_forward, gradients, out);
  if (!gradients) return;
  // The backward sweep with the design partials, the adjoint of the start (sections 9.2, 9.5,
  // 9.7, 10), and dPsi/d(physical density) pulled back to the design variables (sections 4, 5).
  pass->backward();
  ev_.adjoint_s = adjoint_s_;
  pull_back(out);
}

void DynamicProblem::pull_back(optimize::Evaluation &out) {
  const mesh::DistributedMesh &m = mesh();
  const PetscInt ne = m.local_elements();
  const std::size_t nr = specs_.size();
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 0; i < settings_.constraints.size(); ++i)
      out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < nr; ++i) {
    if (specs_[i]->type == optimize::ResponseType::VolumeFraction) {
      field_->volume_fraction_gradient(grad_physical_);
    } else {
      PetscScalar *g;
      FX_PETSC(VecGetArray(grad_physical_, &g));
      for (PetscInt e = 0; e < ne; ++e) g[e] = ev_.element_gradient[i][static_cast<std::size_t>(e)];
      FX_PETSC(VecRestoreArray(grad_physical_, &g));
    }
    field_->pull_back(grad_physical_, out.gradient(i));
  }
}

void DynamicProblem::set_rigid_design() {
  const mesh::DistributedMesh &m = mesh();
  bodies::MassParameters local = bodies::MassParameters::Zero();
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    local += ev_.w[static_cast<std::size_t>(e)] * element_theta_[static_cast<std::size_t>(e)];
  MPI_Allreduce(local.data(), ev_.theta.data(), 10, MPI_DOUBLE, MPI_SUM, m.comm);
  dynamics::set_body_model(m.comm, settings_.scene, scene_, static_cast<std::size_t>(design_body_),
                           std::make_shared<bodies::RigidBody>(
                               settings_.scene.bodies[static_cast<std::size_t>(design_body_)].name,
                               bodies::from_parameters(ev_.theta, reference_)));
}

std::vector<char>
DynamicProblem::plan_checkpoints(std::unique_ptr<BinomialSchedule> &schedule) const {
  const int checkpoints = settings_.adjoint.checkpoints; // 0: all
  std::vector<char> keep(static_cast<std::size_t>(steps_ + 1), checkpoints == 0 ? 1 : 0);
  if (checkpoints > 0) {
    schedule = std::make_unique<BinomialSchedule>(
        steps_, static_cast<int>(std::min<long long>(checkpoints - 1, steps_)));
    for (long long j : schedule->first_descent()) keep[static_cast<std::size_t>(j)] = 1;
    keep.front() = keep.back() = 1;
  }
  return keep;
}

void DynamicProblem::check_checkpoint_memory(long long bytes, long long states) {
  if (checkpoint_memory_checked_) return;
  checkpoint_memory_checked_ = true;
  const NodeMemory per_state = node_memory(mesh().comm, bytes);
  const NodeMemory all{per_state.bytes * states, per_state.available};
  print0(mesh().comm,
         "adjoint: %lld states kept in memory for the backward sweep, %s each on a node: %s "
         "(%s available)\n",
         states, io::human_bytes(static_cast<double>(per_state.bytes)).c_str(),
         io::human_bytes(static_cast<double>(all.bytes)).c_str(),
         all.available > 0 ? io::human_bytes(static_cast<double>(all.available)).c_str()
                           : "unknown");
  if (all.fits(0.8)) return;
  // Half of the memory for the states leaves room for the rest of the run.
  const long long suggest =
      std::max<long long>(2, all.available / 2 / std::max(1LL, per_state.bytes));
  const io::Location &at = settings_.adjoint.where;
  throw Error((at.line > 0 ? at.str() + ": " : std::string()) + "adjoint.checkpoints: the " +
                  std::to_string(states) + " states to keep need " +
                  io::human_bytes(static_cast<double>(all.bytes)) +
                  " on a node, above 80 % of the memory available there: set adjoint: "
                  "{checkpoints: " +
                  std::to_string(suggest) +
                  "} (the binomial schedule recomputes the other states), or storage: disk",
              true);
}

std::string DynamicProblem::checkpoint_file() const {
  int rank = 0;
  MPI_Comm_rank(mesh().comm, &rank);
  return scratch_ + "/adjoint_checkpoints." + std::to_string(rank) + ".h5";
}

void DynamicProblem::finish_forward(double seconds, bool gradients, optimize::Evaluation &out) {
  forward_total_s_ += seconds;
  ev_.forward_s = seconds;
  out.constraints.assign(settings_.constraints.size(), 0.0);
  for (std::size_t i = 0; i < specs_.size(); ++i) out.value(i) = response_value(i);
  if (gradients) forward_s_ = seconds;
}

long long DynamicProblem::dofs() const {
  long long n = scene_.mechanism.coordinates();
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b)
    if (scene_.bodies[b].acf >= 0) n += 3LL * scene_.meshes[b].global_nodes;
  return n;
}

std::vector<std::string> DynamicProblem::solve_to_round_off() {
  // Newton's method proper: responses smooth in the design to round-off (docs/theory.md 9.5).
  set_newton_reuse(0);
  std::vector<std::string> limits;
  const std::string filter = field_->filter().solve_to_round_off();
  filter_limited_ = !filter.empty();
  if (filter_limited_) limits.push_back(filter);
  if (ffrf_design_) {
    // The reduction's fixed-interface modes are solved to 1e-13 (reduce_flexible_body) unless
    // -eps_tol says otherwise.
    PetscReal tol = 0;
    PetscBool given = PETSC_FALSE;
    FX_PETSC(PetscOptionsGetReal(nullptr, nullptr, "-eps_tol", &tol, &given));
    if (given && tol > 1e-13)
      limits.push_back("the FFRF reduction's eigenpairs stop at -eps_tol " + std::to_string(tol));
  }
  return limits;
}

bool DynamicProblem::set_random_start(unsigned long seed) {
  // Every other solve of a dynamic evaluation is direct, or Newton's to 1e-12, whatever its
  // start; the filter's own tolerance (1e-12) keeps its noise below noise_floor(). Only a
  // filter loosened by the user's options is worth two more runs to measure.
  return field_->filter().set_random_start(filter_limited_ ? seed : 0) && filter_limited_;
}

double DynamicProblem::noise_floor(std::size_t i) const {
  const optimize::ResponseType type = specs_[i]->type;
  // Volume and mass are sums over the n design elements: their round-off, and that of the
  // Taylor remainder R(x + h d) - R(x) - h g.d formed from them, grows like sqrt(n) eps
  // (measured 1.3e-14 relative at n = 1,870: 8 sqrt(n) eps = 7.7e-14).
  if (type == optimize::ResponseType::VolumeFraction || type == optimize::ResponseType::Mass)
    return std::max(1e-14, 8 * std::sqrt(static_cast<double>(design_size())) *
                               std::numeric_limits<double>::epsilon());
  return noise_floor();
}

std::vector<optimize::Timing> DynamicProblem::timings() const {
  std::vector<optimize::Timing> t;
  if (ffrf_design_) t.push_back({"reduction", "reduce", ev_.reduction_s});
  t.push_back({"forward", "forward", ev_.forward_s});
  t.push_back({"adjoint", "adjoint", ev_.adjoint_s});
  if (ffrf_design_) t.push_back({"reduction_adjoint", "red.adj", ev_.reduction_adjoint_s});
  return t;
}

double DynamicProblem::round_off_level(std::size_t i) const {
  const optimize::ResponseSettings &r = *specs_[i];
  const double level = 1e-12 * scene_.length_scale;
  if (r.type == optimize::ResponseType::TrackingError) return level * level;
  if (r.type != optimize::ResponseType::Sensor) return 0;
  return r.measure == optimize::SensorMeasure::MeanSquare ? level * level : level;
}

void DynamicProblem::describe(io::Json &s) const {
  s["dofs"] = dofs();
  s["elements"] = static_cast<long long>(mesh().global_elements);
  s["design_variables"] = static_cast<long long>(design_size());
  s["coordinates"] = scene_.mechanism.coordinates();
  s["constraint_rows"] = scene_.mechanism.constraints();
  s["steps"] = steps_;
  s["evaluations"] = evaluations_;
  s["forward_s"] = forward_s_; // of the last evaluation with gradients
  s["adjoint_s"] = adjoint_s_;
  s["forward_total_s"] = forward_total_s_;
  if (settings_.adjoint.checkpoints > 0)
    s["checkpoints"] = settings_.adjoint.checkpoints;
  else
    s["checkpoints"] = "all";
  s["storage"] = settings_.adjoint.storage == CheckpointStorage::Disk ? "disk" : "memory";
  s["recomputed_steps"] = recomputed_;
  s["adjoint_factorizations"] = adjoint_factorizations_;
  s["newton_reuse"] = integration_.newton.reuse_contraction;
  if (ffrf_design_) {
    s["reduction_s"] = reduction_s_; // of the last design
    s["reduction_adjoint_s"] = reduction_adjoint_s_;
    s["reduction_adjoint_cg_iterations"] = reduction_cg_iterations_;
    s["basis_derivative"] =
        settings_.adjoint.basis == reduce::BasisDerivative::Fixed ? "fixed" : "exact";
  }
  s["checkpoint_bytes"] = checkpoint_bytes_;
  const io::Json stress = stress_json();
  if (!stress.is_null()) s["stress"] = stress;
}

io::Json DynamicProblem::stress_json() const {
  return optimize::describe_stress(stress_, names_);
}

std::vector<DynamicProblem::StressSummary> DynamicProblem::stress_summaries() const {
  std::vector<StressSummary> out;
  for (std::size_t i = 0; i < stress_.size(); ++i)
    if (stress_[i]) {
      const optimize::StressAggregate &a = stress_[i]->aggregate();
      out.push_back({i == 0 ? "objective" : "constraint" + std::to_string(i - 1), specs_[i]->body,
                     a.peak(), a.peak_tag(), a.peak_time()});
    }
  return out;
}

} // namespace flexopt::adjoint
