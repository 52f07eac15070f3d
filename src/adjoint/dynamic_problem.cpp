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
#include <map>
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

/// What the FFRF design bodies' adjoint does not differentiate yet on the distributed backend
/// (docs/theory.md 9.8): an FFRF design body with initial elastic fields in a scene with ACF
/// bodies is refused before computing.
void check_ffrf_designs(const DynamicSettings &c) {
  using dynamics::BodyModel;
  const dynamics::BodyDescription *acf = nullptr;
  for (const dynamics::BodyDescription &b : c.scene.bodies)
    if (dynamics::simulated_model(b.model) == BodyModel::Acf) acf = &b;
  if (!acf) return;
  for (const optimize::DesignSettings &d : c.design) {
    const dynamics::BodyDescription &body = c.scene.body(d.body);
    if (dynamics::simulated_model(body.model) != BodyModel::Ffrf) continue;
    bool given = false;
    for (const auto *f : {&body.initial.elastic_displacement, &body.initial.elastic_velocity})
      for (const std::string &e : *f) given = given || !e.empty();
    if (given)
      throw Error(d.where.str() + ": design.body '" + d.body +
                      "' is an FFRF body with initial elastic fields in a scene with ACF "
                      "bodies (body '" +
                      acf->name +
                      "'), whose design sensitivities are not built yet (drop its "
                      "initial.elastic_displacement and elastic_velocity, or make the ACF "
                      "bodies FFRF)",
                  true);
  }
}

/// The case body index of `name`.
int case_body(const DynamicSettings &c, const std::string &name) {
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    if (c.scene.bodies[b].name == name) return static_cast<int>(b);
  throw Error("DynamicProblem: no body '" + name + "'", true);
}

/// A design field's mass and stiffness factors at its initial design (its first update).
reduce::ElementFactors initial_factors(optimize::DesignField &f) {
  reduce::ElementFactors first;
  Vec x = f.create_design_vector();
  f.initial_design(x);
  f.update(x);
  std::vector<double> dw, ds;
  f.mass_factors(first.mass, dw);
  f.stiffness_factors(first.stiffness, ds);
  VecDestroy(&x);
  return first;
}

} // namespace

std::unique_ptr<DynamicProblem> DynamicProblem::create(MPI_Comm comm, const DynamicSettings &c,
                                                       const std::string &scratch,
                                                       bool refuse_interfaces) {
  using dynamics::BodyModel;
  check_ffrf_designs(c);
  std::unique_ptr<DynamicProblem> p(new DynamicProblem());
  p->settings_ = c;
  p->scratch_ = scratch;
  // An FFRF design body is reduced once, with its first design (the reduction is reused by the
  // first evaluation at that design): its design field is made on its mesh as soon as it is
  // meshed (the scene keeps its meshes at fixed addresses) and kept, its filter built once.
  std::map<std::string, std::unique_ptr<optimize::DesignField>> made;
  std::map<std::string, reduce::ElementFactors> first;
  dynamics::InitialDesign initial;
  for (const optimize::DesignSettings &d : c.design)
    if (dynamics::simulated_model(c.scene.body(d.body).model) == BodyModel::Ffrf)
      initial.bodies.push_back(d.body);
  initial.factors = [&](const std::string &name, const mesh::DistributedMesh &m) {
    const optimize::DesignSettings &d =
        *std::find_if(c.design.begin(), c.design.end(),
                      [&](const optimize::DesignSettings &e) { return e.body == name; });
    auto f = std::make_unique<optimize::DesignField>(m, d);
    check_interfaces(*f, c.scene.body(name), d, refuse_interfaces);
    first[name] = initial_factors(*f);
    made[name] = std::move(f);
    return first[name];
  };
  p->scene_ = dynamics::build_scene(comm, c.scene, initial.bodies.empty() ? nullptr : &initial);
  std::vector<std::unique_ptr<optimize::DesignField>> fields;
  for (const optimize::DesignSettings &d : c.design) {
    const mesh::DistributedMesh &m =
        p->scene_.meshes[static_cast<std::size_t>(case_body(c, d.body))];
    auto it = made.find(d.body);
    if (it != made.end()) {
      if (&it->second->mesh() != &m)
        throw Error("DynamicProblem: the design field's mesh is not the scene's", true);
      fields.push_back(std::move(it->second));
      continue;
    }
    fields.push_back(std::make_unique<optimize::DesignField>(m, d));
    // A flexible body's interfaces are tied rigidly (FFRF: checked before the reduction).
    if (dynamics::simulated_model(c.scene.body(d.body).model) == BodyModel::Acf)
      check_interfaces(*fields.back(), c.scene.body(d.body), d, refuse_interfaces);
  }
  p->design_ = std::make_unique<optimize::Design>(std::move(fields));
  p->design_of_body_.assign(c.scene.bodies.size(), -1);
  p->designs_.resize(c.design.size());
  for (std::size_t k = 0; k < c.design.size(); ++k) p->bind_design_body(k, first[c.design[k].body]);
  p->check_mass_bounds();
  p->basis_ = c.adjoint.basis;
  p->bind_responses();
  p->integration_ = dynamics::IntegratorSettings::from(c.time);
  p->steps_ = p->integration_.steps;
  return p;
}

void DynamicProblem::bind_design_body(std::size_t k, const reduce::ElementFactors &first) {
  const optimize::DesignSettings &d = settings_.design[k];
  DesignBody &db = designs_[k];
  db.field = &design_->field(k);
  db.index = k;
  db.body = case_body(settings_, d.body);
  design_of_body_[static_cast<std::size_t>(db.body)] = static_cast<int>(k);
  const dynamics::SceneBody &sb = scene_.bodies[static_cast<std::size_t>(db.body)];
  const dynamics::BodyDescription &spec = settings_.scene.bodies[static_cast<std::size_t>(db.body)];
  db.mechanism = sb.mechanism;
  db.acf = sb.acf;
  db.model = dynamics::simulated_model(spec.model);
  db.grad_physical = db.field->filter().create_element_vector();
  int row = 0; // the rows of the bodies before this one in the stacked partials
  for (std::size_t j = 0; j < k; ++j) row += designs_[j].rows;
  db.row = row;
  if (db.ffrf()) {
    ffrf_design_ = true;
    db.reduction = sb.reduction;
    db.reduced_factors = first;
    db.reduction_s = scene_.reduction_seconds[static_cast<std::size_t>(db.body)];
    db.rows = design_parameters_of(db);
  } else if (db.rigid()) {
    // The design body keeps its solid centre of mass as its reference point (section 9.1).
    const auto &solid =
        dynamic_cast<const bodies::RigidBody &>(scene_.mechanism.body(db.mechanism));
    db.reference = solid.center();
    const mesh::DistributedMesh &m = db.field->mesh();
    db.element_theta.resize(static_cast<std::size_t>(m.local_elements()));
    for (PetscInt e = 0; e < m.local_elements(); ++e)
      db.element_theta[static_cast<std::size_t>(e)] = bodies::element_mass_parameters(
          m.type, m.element_coordinates(e), spec.material.density, db.reference);
    db.rows = 10;
  }
}

void DynamicProblem::check_mass_bounds() const {
  // A mass bound that even empty design regions exceed cannot hold: refused before any
  // computation, with the mass of the material outside the regions.
  for (const optimize::ResponseSettings &r : settings_.constraints) {
    if (r.type != optimize::ResponseType::Mass) continue;
    double least = 0, solid = 0; // the bodies' mass with empty design regions, and solid
    for (const std::string &name : r.bodies) {
      const DesignBody *db = design_of(case_body(settings_, name));
      if (!db) {
        least += body_mass(name);
        solid += body_mass(name);
        continue;
      }
      const optimize::DesignField &f = *db->field;
      const double density = settings_.scene.body(name).material.density;
      double mass[2] = {0, 0}; // outside the region, inside it
      for (PetscInt e = 0; e < f.mesh().local_elements(); ++e)
        mass[f.is_design(e) ? 1 : 0] += density * f.element_volumes()[static_cast<std::size_t>(e)];
      MPI_Allreduce(MPI_IN_PLACE, mass, 2, MPI_DOUBLE, MPI_SUM, f.mesh().comm);
      least += mass[0];
      solid += mass[0] + mass[1];
    }
    if (r.max > least) continue;
    std::string names;
    for (const std::string &name : r.bodies) names += (names.empty() ? "'" : ", '") + name + "'";
    const DesignBody *one =
        r.bodies.size() == 1 ? design_of(case_body(settings_, r.bodies[0])) : nullptr;
    std::ostringstream msg;
    msg << r.where.str() << ": constraint mass of bod" << (r.bodies.size() > 1 ? "ies " : "y ")
        << names << " <= " << r.max << " kg cannot hold: the material outside "
        << (one ? "design.region '" + one->field->settings().region + "'"
                : std::string("the design regions"))
        << " alone weighs " << least << " kg (solid " << solid
        << " kg). Raise the bound or enlarge the design region";
    throw Error(msg.str(), true);
  }
}

bool DynamicProblem::counts_mass(std::size_t i, const DesignBody &db) const {
  const optimize::ResponseSettings &r = *specs_[i];
  if (r.type != optimize::ResponseType::Mass) return false;
  const std::string &name = settings_.scene.bodies[static_cast<std::size_t>(db.body)].name;
  return std::find(r.bodies.begin(), r.bodies.end(), name) != r.bodies.end();
}

double DynamicProblem::body_mass(const std::string &name) const {
  const int b = case_body(settings_, name);
  const DesignBody *db = design_of(b);
  if (db && db->rigid()) return db->ev.theta(0);
  const dynamics::SceneBody &sb = scene_.bodies[static_cast<std::size_t>(b)];
  if (sb.acf >= 0) return scene_.acf[static_cast<std::size_t>(sb.acf)]->total_mass();
  return scene_.mechanism.body(sb.mechanism).mass();
}

void DynamicProblem::bind_responses() {
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
    sensor_design_.push_back(-1);
    if (sensor >= 0) {
      const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor)];
      for (const DesignBody &db : designs_)
        if (db.ffrf() && s.acf_body < 0 && s.body == db.mechanism &&
            s.quantity != dynamics::SensorQuantity::RotationAngle)
          sensor_design_.back() = static_cast<int>(db.index);
    }
    strain_bodies_.emplace_back();
    acf_strain_bodies_.emplace_back();
    if (r->type == optimize::ResponseType::StrainEnergyIntegral)
      for (const std::string &name : r->bodies) {
        const BodyModel bm = dynamics::simulated_model(settings_.scene.body(name).model);
        if (bm == BodyModel::Rigid)
          throw Error(r->where.str() + ": strain_energy_integral of body '" + name +
                          "': a rigid body has no strain energy (ACF and FFRF bodies have)",
                      true);
        const dynamics::SceneBody &sb =
            scene_.bodies[static_cast<std::size_t>(case_body(settings_, name))];
        if (bm == BodyModel::Ffrf) strain_bodies_.back().push_back(sb.mechanism);
        if (bm == BodyModel::Acf) acf_strain_bodies_.back().push_back(sb.acf);
      }
    bind_stress(*r);
  }
}

void DynamicProblem::bind_stress(const optimize::ResponseSettings &r) {
  using dynamics::BodyModel;
  stress_.push_back(nullptr);
  stress_body_.push_back(-1);
  stress_case_body_.push_back(-1);
  if (r.type != optimize::ResponseType::Stress) return;
  const auto b = static_cast<std::size_t>(case_body(settings_, r.body));
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
  if (design_of(static_cast<int>(b)) && settings_.adjoint.basis == reduce::BasisDerivative::Fixed)
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

std::vector<optimize::DesignProblem::DesignStress> DynamicProblem::design_stress() const {
  std::vector<DesignStress> out;
  for (std::size_t i = 0; i < stress_.size(); ++i)
    if (const DesignBody *db = stress_[i] ? design_of(stress_case_body_[i]) : nullptr)
      out.push_back({i, db->index, &stress_[i]->aggregate()});
  return out;
}

void DynamicProblem::restore_response_scales(const std::vector<double> &scales) {
  optimize::restore_scales(stress_, scales);
}

std::vector<std::array<double, 12>> DynamicProblem::design_placements() const {
  // One design body keeps its mesh coordinates (its own frame, as a static design's).
  std::vector<std::array<double, 12>> out;
  if (designs_.size() == 1) return out;
  for (const DesignBody &db : designs_) {
    const dynamics::SceneBody &sb = scene_.bodies[static_cast<std::size_t>(db.body)];
    std::array<double, 12> pl{};
    for (int r = 0; r < 3; ++r) {
      pl[static_cast<std::size_t>(r)] = sb.position(r);
      for (int c = 0; c < 3; ++c) pl[static_cast<std::size_t>(3 + 3 * r + c)] = sb.R(r, c);
    }
    out.push_back(pl);
  }
  return out;
}

io::GridLayout DynamicProblem::design_layout() const {
  const auto placements = design_placements();
  if (placements.empty()) return design_->grid_layout();
  return design_->grid_layout(design_->placed_coordinates(placements));
}

DynamicProblem::~DynamicProblem() {
  for (DesignBody &db : designs_) VecDestroy(&db.grad_physical);
}

double DynamicProblem::response_value(std::size_t i) const {
  const optimize::ResponseSettings &r = *specs_[i];
  // The listed design regions together, all without a list (section 9.9).
  if (r.type == optimize::ResponseType::VolumeFraction) return design_->volume_fraction(r.bodies);
  if (r.type == optimize::ResponseType::Mass) {
    double m = 0;
    for (const std::string &name : r.bodies) m += body_mass(name);
    return m;
  }
  return ev_.sampled[i].value;
}

void DynamicProblem::apply_design(Vec x) {
  design_->update(x);
  for (DesignBody &db : designs_) {
    // Mass factors w (section 9.1) and SIMP modulus factors s (sections 9.6, 10).
    db.field->mass_factors(db.ev.w, db.ev.dw);
    db.field->stiffness_factors(db.ev.s, db.ev.ds);
    if (db.acf_model())
      scene_.acf[static_cast<std::size_t>(db.acf)]->set_factors(db.ev.s, db.ev.w);
    else if (db.ffrf())
      set_ffrf_design(db);
    else
      set_rigid_design(db);
  }
}

void DynamicProblem::set_ffrf_design(DesignBody &db) {
  // Collective: every rank compares its own elements (a change of one element's density moves
  // the factors on its rank only).
  int changed = db.ev.s != db.reduced_factors.stiffness || db.ev.w != db.reduced_factors.mass;
  int any = 0;
  const MPI_Comm comm = db.field->mesh().comm;
  MPI_Allreduce(&changed, &any, 1, MPI_INT, MPI_LOR, comm);
  if (!any) return;
  const double t0 = wall_time();
  db.reduced_factors = reduce::ElementFactors{db.ev.s, db.ev.w};
  db.reduction = dynamics::set_ffrf_design(comm, settings_.scene, scene_,
                                           static_cast<std::size_t>(db.body), db.reduced_factors);
  db.reduction_s = wall_time() - t0;
  db.ev.reduction_s = db.reduction_s;
  for (std::size_t i = 0; i < stress_.size(); ++i)
    if (stress_[i] && stress_case_body_[i] == db.body)
      ffrf_stress(i)->set_basis(db.reduction->basis);
}

void DynamicProblem::evaluate(Vec x, bool gradients, optimize::Evaluation &out) {
  LogScope log("FxDynamicEvaluate");
  ++evaluations_;
  ev_ = {};
  for (DesignBody &db : designs_) db.ev = {};
  // The design into the scene (sections 9.1, 9.6, 10): mass and modulus factors, the rigid
  // design bodies' mass parameters, the FFRF ones' reductions.
  apply_design(x);
  for (DesignBody &db : designs_) {
    db.ev.element_gradient.assign(
        specs_.size(),
        std::vector<double>(static_cast<std::size_t>(db.field->mesh().local_elements()), 0.0));
    db.ev.strain_kbar.assign(specs_.size(), Matrix());
  }
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
  const std::size_t nr = specs_.size();
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 0; i < settings_.constraints.size(); ++i)
      out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < nr; ++i) {
    const optimize::ResponseSettings &r = *specs_[i];
    for (DesignBody &db : designs_) {
      if (r.type == optimize::ResponseType::VolumeFraction) {
        // The listed design regions together (all without a list; section 9.9).
        design_->volume_fraction_gradient(r.bodies, db.index, db.grad_physical);
      } else {
        PetscScalar *g;
        FX_PETSC(VecGetArray(db.grad_physical, &g));
        std::copy(db.ev.element_gradient[i].begin(), db.ev.element_gradient[i].end(), g);
        FX_PETSC(VecRestoreArray(db.grad_physical, &g));
      }
      design_->pull_back(db.index, db.grad_physical, out.gradient(i));
    }
  }
}

void DynamicProblem::set_rigid_design(DesignBody &db) {
  const mesh::DistributedMesh &m = db.field->mesh();
  bodies::MassParameters local = bodies::MassParameters::Zero();
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    local += db.ev.w[static_cast<std::size_t>(e)] * db.element_theta[static_cast<std::size_t>(e)];
  MPI_Allreduce(local.data(), db.ev.theta.data(), 10, MPI_DOUBLE, MPI_SUM, m.comm);
  dynamics::set_body_model(m.comm, settings_.scene, scene_, static_cast<std::size_t>(db.body),
                           std::make_shared<bodies::RigidBody>(
                               settings_.scene.bodies[static_cast<std::size_t>(db.body)].name,
                               bodies::from_parameters(db.ev.theta, db.reference)));
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
  const NodeMemory per_state = node_memory(comm(), bytes);
  const NodeMemory all{per_state.bytes * states, per_state.available};
  print0(comm(),
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
  MPI_Comm_rank(comm(), &rank);
  const std::string &tag = settings_.adjoint.file_tag;
  return scratch_ + "/adjoint_checkpoints." + (tag.empty() ? "" : tag + ".") +
         std::to_string(rank) + ".h5";
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
  filter_limited_ = false;
  for (std::size_t k = 0; k < design_->size(); ++k) {
    const std::string filter = design_->field(k).filter().solve_to_round_off();
    if (filter.empty() || filter_limited_) continue; // one phrase for the filters' option
    filter_limited_ = true;
    limits.push_back(filter);
  }
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
  bool any = false;
  for (std::size_t k = 0; k < design_->size(); ++k)
    any = design_->field(k).filter().set_random_start(filter_limited_ ? seed : 0) || any;
  return any && filter_limited_;
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
  double reduction = 0, reduction_adjoint = 0; // every FFRF design body's
  for (const DesignBody &db : designs_) {
    reduction += db.ev.reduction_s;
    reduction_adjoint += db.ev.reduction_adjoint_s;
  }
  if (ffrf_design_) t.push_back({"reduction", "reduce", reduction});
  t.push_back({"forward", "forward", ev_.forward_s});
  t.push_back({"adjoint", "adjoint", ev_.adjoint_s});
  if (ffrf_design_) t.push_back({"reduction_adjoint", "red.adj", reduction_adjoint});
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
  s["elements"] = design_->global_elements(); // of the design bodies
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
  io::Json bodies = io::Json::array();
  double reduction = 0, reduction_adjoint = 0;
  int cg = 0;
  for (const DesignBody &db : designs_) {
    io::Json b = io::Json::object();
    b["body"] = db.field->settings().body;
    b["model"] = dynamics::model_name(db.model);
    b["design_variables"] = static_cast<long long>(db.field->design_size());
    bodies.push_back(b);
    reduction += db.reduction_s;
    reduction_adjoint += db.reduction_adjoint_s;
    cg += db.reduction_cg_iterations;
  }
  s["design_bodies"] = bodies;
  if (ffrf_design_) {
    s["reduction_s"] = reduction; // of the last design, every FFRF design body's
    s["reduction_adjoint_s"] = reduction_adjoint;
    s["reduction_adjoint_cg_iterations"] = cg;
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
