#include "flexopt/optimize/topology_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"

#include <algorithm>
#include <cmath>

namespace flexopt::optimize {

namespace {
const char *kTopologySolverDefaults =
    "-mg_levels_ksp_type chebyshev -mg_levels_pc_type jacobi -pc_gamg_use_sa_esteig 0 "
    "-mg_levels_esteig_ksp_max_it 50 -mg_levels_ksp_chebyshev_esteig 0,0.1,0,1.3";
} // namespace

Evaluation::~Evaluation() {
  VecDestroy(&d_objective);
  for (Vec &v : d_constraints) VecDestroy(&v);
}

std::unique_ptr<TopologyProblem> TopologyProblem::create(MPI_Comm comm, const io::Case &c) {
  if (!c.design || !c.objective)
    throw Error(c.file + ": topology optimization needs design: and objective: sections", true);
  if (c.analysis != "static")
    throw Error(c.file + ": topology optimization is available for analysis: static only (so far)",
                true);
  if (c.gravity)
    throw Error(c.design->where.str() +
                    ": design: gravity with a design field is not supported yet (the self-weight "
                    "would depend on the densities)",
                true);
  // Multigrid smoothing that survives the 1e-9 stiffness contrast of void elements: GAMG's
  // default smoothed-aggregation eigenvalue estimate makes Chebyshev smoothing indefinite
  // after the first design update (DIVERGED_INDEFINITE_PC); a 50-step Krylov estimate with a
  // 1.3 safety factor does not (docs/solvers.md). Defaults only: the case's solver string
  // and the command line take precedence.
  insert_default_petsc_options(kTopologySolverDefaults, "topology optimization solver defaults");
  std::unique_ptr<TopologyProblem> p(new TopologyProblem());
  p->case_ = c;
  p->static_ = fem::StaticProblem::create(comm, c);
  const mesh::DistributedMesh &m = p->static_->mesh();
  const io::DesignSpec &d = *c.design;

  const auto &region = m.volume_group(d.region, d.where.str() + ": design.region");
  p->is_design_.assign(static_cast<std::size_t>(m.local_elements()), 0);
  for (PetscInt e : region) p->is_design_[static_cast<std::size_t>(e)] = 1;
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    if (p->is_design_[static_cast<std::size_t>(e)]) {
      p->design_elements_.push_back(e);
      p->design_tags_.push_back(m.element_tags[static_cast<std::size_t>(e)]);
    }
  PetscInt n_local = static_cast<PetscInt>(p->design_elements_.size());
  MPI_Allreduce(&n_local, &p->global_design_, 1, MPIU_INT, MPI_SUM, comm);
  if (p->global_design_ == 0)
    throw Error(d.where.str() + ": design.region '" + d.region + "' has no elements", true);

  p->volume_ = fem::element_volumes(m);
  double local_volume = 0;
  for (PetscInt e : p->design_elements_) local_volume += p->volume_[static_cast<std::size_t>(e)];
  MPI_Allreduce(&local_volume, &p->design_volume_, 1, MPI_DOUBLE, MPI_SUM, comm);

  p->names_.push_back("objective:" + c.objective->type);
  for (std::size_t i = 0; i < c.constraints.size(); ++i)
    p->names_.push_back("constraint" + std::to_string(i) + ":" + c.constraints[i].type);
  auto locate = [&](const io::ResponseSpec &r) {
    fem::PointLocation loc;
    if (r.type == "displacement")
      for (const auto &s : c.sensors)
        if (s.name == r.sensor)
          loc = fem::locate(m, s.point, s.where.str() + ": sensor '" + s.name + "'");
    return loc;
  };
  p->sensor_locations_.push_back(locate(*c.objective));
  for (const auto &r : c.constraints) p->sensor_locations_.push_back(locate(r));

  p->filter_ = create_density_filter(m, d.filter_type, d.filter_radius);
  p->rho_ = p->filter_->create_element_vector();
  FX_PETSC(VecDuplicate(p->rho_, &p->filtered_));
  FX_PETSC(VecDuplicate(p->rho_, &p->physical_));
  if (!d.beta.empty()) p->beta_ = d.beta.front();
  FX_PETSC(VecDuplicate(p->rho_, &p->grad_filtered_));
  FX_PETSC(VecDuplicate(p->rho_, &p->grad_full_));
  p->adjoint_ = fem::create_ghosted_vector(m);
  FX_PETSC(VecDuplicate(p->adjoint_, &p->adjoint_rhs_));
  return p;
}

TopologyProblem::~TopologyProblem() {
  VecDestroy(&rho_);
  VecDestroy(&filtered_);
  VecDestroy(&physical_);
  VecDestroy(&grad_filtered_);
  VecDestroy(&grad_full_);
  VecDestroy(&adjoint_);
  VecDestroy(&adjoint_rhs_);
}

Vec TopologyProblem::create_design_vector() const {
  Vec x;
  FX_PETSC(VecCreateMPI(mesh().comm, static_cast<PetscInt>(design_elements_.size()),
                        PETSC_DETERMINE, &x));
  return x;
}

void TopologyProblem::initial_design(Vec x) const {
  FX_PETSC(VecSet(x, case_.design->initial));
}

void TopologyProblem::embed(Vec x, Vec rho) const {
  FX_PETSC(VecSet(rho, 1.0)); // elements outside the design region stay solid
  const PetscScalar *xa;
  PetscScalar *r;
  FX_PETSC(VecGetArrayRead(x, &xa));
  FX_PETSC(VecGetArray(rho, &r));
  for (std::size_t k = 0; k < design_elements_.size(); ++k) r[design_elements_[k]] = xa[k];
  FX_PETSC(VecRestoreArray(rho, &r));
  FX_PETSC(VecRestoreArrayRead(x, &xa));
}

void TopologyProblem::restrict_to_design(Vec full, Vec x) const {
  const PetscScalar *f;
  PetscScalar *xa;
  FX_PETSC(VecGetArrayRead(full, &f));
  FX_PETSC(VecGetArray(x, &xa));
  for (std::size_t k = 0; k < design_elements_.size(); ++k) xa[k] = f[design_elements_[k]];
  FX_PETSC(VecRestoreArray(x, &xa));
  FX_PETSC(VecRestoreArrayRead(full, &f));
}

double TopologyProblem::volume_fraction() {
  io::ResponseSpec v;
  v.type = "volume_fraction";
  return response_value(v, 0);
}

double TopologyProblem::response_value(const io::ResponseSpec &r, std::size_t index) {
  if (r.type == "compliance") return static_->compliance();
  if (r.type == "volume_fraction") {
    const PetscScalar *rt;
    FX_PETSC(VecGetArrayRead(physical_, &rt));
    double local = 0;
    for (PetscInt e : design_elements_) local += rt[e] * volume_[static_cast<std::size_t>(e)];
    FX_PETSC(VecRestoreArrayRead(physical_, &rt));
    double total = 0;
    MPI_Allreduce(&local, &total, 1, MPI_DOUBLE, MPI_SUM, mesh().comm);
    return total / design_volume_;
  }
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
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    if (dfactor_[static_cast<std::size_t>(e)] == 0.0) continue; // no sensitivity there
    const fem::ElementMatrix Ke =
        fem::element_stiffness(m.type, m.element_coordinates(e), static_->material(), 1.0);
    const fem::ElementVector ku = Ke * fem::gather_element(m, e, u);
    std::copy(ku.data(), ku.data() + nd, element_ku_.begin() + static_cast<std::ptrdiff_t>(e * nd));
  }
  FX_PETSC(VecRestoreArrayRead(ul, &u));
  FX_PETSC(VecGhostRestoreLocalForm(static_->displacement(), &ul));
  element_ku_current_ = true;
  return element_ku_;
}

void TopologyProblem::response_gradient(const io::ResponseSpec &r, std::size_t index, Vec g) {
  LogScope log("FxSensitivities");
  const mesh::DistributedMesh &m = mesh();
  PetscScalar *ga;
  if (r.type == "volume_fraction") {
    FX_PETSC(VecZeroEntries(g));
    FX_PETSC(VecGetArray(g, &ga));
    for (PetscInt e : design_elements_)
      ga[e] = volume_[static_cast<std::size_t>(e)] / design_volume_;
    FX_PETSC(VecRestoreArray(g, &ga));
    return;
  }
  // Stiffness responses: dR/ds_e = -lambda_e^T K_e u_e, with lambda = u for the compliance
  // (self-adjoint) and K lambda = c (the point functional) for a displacement.
  Vec lambda = static_->displacement();
  if (r.type == "displacement") {
    FX_PETSC(VecZeroEntries(adjoint_rhs_));
    fem::add_point_functional(m, sensor_locations_[index], r.direction, adjoint_rhs_);
    static_->solve_adjoint(adjoint_rhs_, adjoint_);
    ++solves_;
    lambda = adjoint_;
  }
  const std::vector<double> &ku = element_ku();
  const int nd = 3 * m.nodes_per_element();
  Vec ll;
  const PetscScalar *l;
  FX_PETSC(VecGhostGetLocalForm(lambda, &ll));
  FX_PETSC(VecGetArrayRead(ll, &l));
  FX_PETSC(VecGetArray(g, &ga));
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const double ds = dfactor_[static_cast<std::size_t>(e)];
    const fem::ElementVector le = fem::gather_element(m, e, l);
    double dot = 0;
    for (int k = 0; k < nd; ++k) dot += le(k) * ku[static_cast<std::size_t>(e * nd + k)];
    ga[e] = ds == 0.0 ? 0.0 : -ds * dot;
  }
  FX_PETSC(VecRestoreArray(g, &ga));
  FX_PETSC(VecRestoreArrayRead(ll, &l));
  FX_PETSC(VecGhostRestoreLocalForm(lambda, &ll));
}

void TopologyProblem::evaluate(Vec x, bool gradients, Evaluation &out) {
  LogScope log("FxTopologyEvaluate");
  const mesh::DistributedMesh &m = mesh();
  const io::DesignSpec &d = *case_.design;
  embed(x, rho_);
  filter_->apply(rho_, filtered_);
  // Heaviside projection (Wang, Lazarov & Sigmund 2011), or the identity.
  const PetscInt n_el = m.local_elements();
  dprojection_.assign(static_cast<std::size_t>(n_el), 1.0);
  FX_PETSC(VecCopy(filtered_, physical_));
  if (beta_ > 0) {
    const double eta = d.eta, den = std::tanh(beta_ * eta) + std::tanh(beta_ * (1.0 - eta));
    PetscScalar *ph;
    FX_PETSC(VecGetArray(physical_, &ph));
    for (PetscInt e = 0; e < n_el; ++e) {
      const double th = std::tanh(beta_ * (ph[e] - eta));
      dprojection_[static_cast<std::size_t>(e)] = beta_ * (1.0 - th * th) / den;
      ph[e] = (std::tanh(beta_ * eta) + th) / den;
    }
    FX_PETSC(VecRestoreArray(physical_, &ph));
  }

  // SIMP: s = e_min + rho~^p (1 - e_min) on design elements; solid (s = 1) elsewhere.
  const PetscInt ne = m.local_elements();
  factor_.assign(static_cast<std::size_t>(ne), 1.0);
  dfactor_.assign(static_cast<std::size_t>(ne), 0.0);
  const PetscScalar *rt;
  FX_PETSC(VecGetArrayRead(physical_, &rt));
  for (PetscInt e : design_elements_) {
    const double r = std::max(rt[e], 0.0);
    factor_[static_cast<std::size_t>(e)] =
        d.min_stiffness + std::pow(r, d.penalty) * (1.0 - d.min_stiffness);
    dfactor_[static_cast<std::size_t>(e)] =
        r > 0 ? d.penalty * std::pow(r, d.penalty - 1.0) * (1.0 - d.min_stiffness) : 0.0;
  }
  FX_PETSC(VecRestoreArrayRead(physical_, &rt));
  static_->assemble_operator(factor_);
  static_->solve();
  element_ku_current_ = false;
  ++solves_;

  std::vector<const io::ResponseSpec *> specs{&*case_.objective};
  for (const auto &r : case_.constraints) specs.push_back(&r);
  out.constraints.assign(case_.constraints.size(), 0.0);
  for (std::size_t i = 0; i < specs.size(); ++i) {
    const double v = response_value(*specs[i], i);
    (i == 0 ? out.objective : out.constraints[i - 1]) = v;
  }
  if (!gradients) return;
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 0; i < case_.constraints.size(); ++i)
      out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < specs.size(); ++i) {
    response_gradient(*specs[i], i, grad_filtered_); // d/d(physical density)
    PetscScalar *g;
    FX_PETSC(VecGetArray(grad_filtered_, &g));
    for (PetscInt e = 0; e < m.local_elements(); ++e)
      g[e] *= dprojection_[static_cast<std::size_t>(e)];
    FX_PETSC(VecRestoreArray(grad_filtered_, &g));
    filter_->apply_transpose(grad_filtered_, grad_full_);
    restrict_to_design(grad_full_, i == 0 ? out.d_objective : out.d_constraints[i - 1]);
  }
}

} // namespace flexopt::optimize
