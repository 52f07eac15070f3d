#include "flexopt/fem/static_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/krylov.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/lattice_multigrid.hpp"
#include "flexopt/fem/matrix_free.hpp"
#include "flexopt/mesh/load.hpp"

#include <algorithm>
#include <cmath>

namespace flexopt::fem {

std::vector<PetscInt> support_dofs(const mesh::DistributedMesh &mesh,
                                   const std::vector<Support> &supports) {
  std::vector<PetscInt> dofs;
  for (const auto &s : supports) {
    auto d = surface_dofs(mesh, s.surface, s.fix, s.where.str() + ": supports");
    dofs.insert(dofs.end(), d.begin(), d.end());
  }
  std::sort(dofs.begin(), dofs.end());
  dofs.erase(std::unique(dofs.begin(), dofs.end()), dofs.end());
  return dofs;
}

namespace {
/// Largest coarsest level of a lattice hierarchy that gets geometric multigrid.
constexpr PetscInt kLatticeMaxCoarseDofs = 50000;
} // namespace

std::string configure_elasticity_solver(KSP ksp, Mat A, const mesh::DistributedMesh &mesh,
                                        bool *lattice_multigrid) {
  Vec coords = create_coordinate_vector(mesh);
  MatNullSpace near_null;
  FX_PETSC(MatNullSpaceCreateRigidBody(coords, &near_null));
  FX_PETSC(MatSetNearNullSpace(A, near_null));
  FX_PETSC(MatNullSpaceDestroy(&near_null));
  FX_PETSC(VecDestroy(&coords));
  FX_PETSC(MatSetOption(A, MAT_SPD, PETSC_TRUE));
  FX_PETSC(KSPSetOperators(ksp, A, A));
  FX_PETSC(KSPSetType(ksp, KSPCG));
  PC pc;
  FX_PETSC(KSPGetPC(ksp, &pc));
  // A structured Hex8 box gets geometric multigrid (its hierarchy is free and does not change
  // with the operator); any other mesh, or a -pc_type option, algebraic multigrid.
  const char *prefix = nullptr;
  FX_PETSC(KSPGetOptionsPrefix(ksp, &prefix));
  PetscBool pc_given = PETSC_FALSE;
  FX_PETSC(PetscOptionsHasName(nullptr, prefix, "-pc_type", &pc_given));
  std::string how = "CG + algebraic multigrid (GAMG, rigid-body near-null space)";
  std::optional<Lattice> lattice;
  if (!pc_given) lattice = find_lattice(mesh);
  bool geometric = false;
  if (lattice) {
    PetscInt levels = 0, coarse_dofs = 20000;
    FX_PETSC(PetscOptionsGetInt(nullptr, prefix, "-lattice_mg_levels", &levels, nullptr));
    FX_PETSC(PetscOptionsGetInt(nullptr, prefix, "-lattice_mg_coarse_dofs", &coarse_dofs, nullptr));
    const auto cells = lattice_levels(*lattice, static_cast<int>(levels), coarse_dofs);
    const auto &c = cells.back();
    const PetscInt coarsest = 3 * (c[0] + 1) * (c[1] + 1) * (c[2] + 1);
    // The coarsest level is factorized for every operator: a lattice with odd cell counts
    // that leaves it large is better served by GAMG.
    if (cells.size() >= 2 && coarsest <= kLatticeMaxCoarseDofs) {
      // Its factorization: MUMPS Cholesky on every rank's copy (PCMG's redundant coarse solve;
      // sequential MUMPS, so repeatable), about 10x faster than PETSc's own LU at 4k DOFs.
      const std::string p = std::string("-") + (prefix ? prefix : "") + "mg_coarse_";
      insert_default_petsc_options(p + "pc_factor_mat_solver_type mumps " + p +
                                       "redundant_pc_type cholesky " + p +
                                       "redundant_pc_factor_mat_solver_type mumps",
                                   "lattice multigrid defaults");
      how = "CG + " + set_lattice_multigrid(pc, mesh, *lattice, cells);
      geometric = true;
    } else {
      how += " (the " + std::to_string(lattice->cells(0)) + " x " +
             std::to_string(lattice->cells(1)) + " x " + std::to_string(lattice->cells(2)) +
             " Hex8 lattice " +
             (cells.size() < 2 ? std::string("gets no coarser level")
                               : "coarsens only to " + std::to_string(coarsest) + " DOFs") +
             ")";
    }
  }
  if (!geometric) FX_PETSC(PCSetType(pc, PCGAMG));
  if (lattice_multigrid) *lattice_multigrid = geometric;
  FX_PETSC(KSPSetTolerances(ksp, 1e-8, 1e-50, PETSC_DEFAULT, 1000));
  FX_PETSC(KSPSetFromOptions(ksp));
  if (pc_given) {
    // The options chose the solver: name what runs (KSP, PC and a factorization's package).
    KSPType ktype;
    PCType ptype;
    FX_PETSC(KSPGetType(ksp, &ktype));
    FX_PETSC(PCGetType(pc, &ptype));
    how = std::string(ktype) + " + " + ptype;
    MatSolverType package = nullptr;
    PetscBool factor = PETSC_FALSE;
    FX_PETSC(PetscObjectTypeCompareAny(reinterpret_cast<PetscObject>(pc), &factor, PCLU, PCCHOLESKY,
                                       ""));
    if (factor) FX_PETSC(PCFactorGetMatSolverType(pc, &package));
    if (package) how += " (" + std::string(package) + ")";
    if (std::string(ptype) == PCGAMG) how += " (rigid-body near-null space)";
    how += ", from the solver options";
  }
  return how;
}

void check_converged(KSP ksp, const std::string &what) {
  KSPConvergedReason reason;
  FX_PETSC(KSPGetConvergedReason(ksp, &reason));
  if (reason < 0) {
    PetscInt its = 0;
    FX_PETSC(KSPGetIterationNumber(ksp, &its));
    throw Error(what + ": the linear solver did not converge (" + KSPConvergedReasons[reason] +
                    " after " + std::to_string(its) +
                    " iterations). Is the body supported against rigid motion? Try "
                    "-ksp_monitor_true_residual, a direct solver (-ksp_type preonly -pc_type lu "
                    "-pc_factor_mat_solver_type mumps), or for SIMP designs with void regions the "
                    "smoother -mg_levels_ksp_type richardson -mg_levels_pc_type sor",
                true);
  }
}

namespace {

/// Every local element's consistent body load f_e = M_e b_e (flat, 3 per element node; empty
/// without a body force) of the specific body force b(X) = g - (a + alpha x r + omega x (omega x
/// r)), r = X - point (gravity, loads.inertia), plus the nodal field loads.body_force. Collective
/// (the nodal field's mesh check).
std::vector<double> element_body_loads(const mesh::DistributedMesh &m, double density,
                                       const StaticLoads &loads, const std::string &case_file) {
  if (!loads.gravity && !loads.inertia && !loads.body_force) return {};
  Eigen::Vector3d g = Eigen::Vector3d::Zero(), a = g, w = g, al = g, x0 = g;
  auto v3 = [](const std::array<double, 3> &v) { return Eigen::Vector3d(v[0], v[1], v[2]); };
  if (loads.gravity) g = v3(*loads.gravity);
  if (loads.inertia) {
    a = v3(loads.inertia->acceleration), w = v3(loads.inertia->angular_velocity);
    al = v3(loads.inertia->angular_acceleration), x0 = v3(loads.inertia->point);
  }
  const double *nodal = nullptr;
  if (loads.body_force) {
    const NodalBodyForce &field = *loads.body_force;
    int other = !field.coordinates || *field.coordinates != m.coordinates ||
                field.values.size() != m.coordinates.size();
    MPI_Allreduce(MPI_IN_PLACE, &other, 1, MPI_INT, MPI_MAX, m.comm);
    if (other)
      throw Error(case_file + ": a nodal body force made on another mesh or distribution (the "
                              "static problem must load the body's mesh on the same ranks)",
                  true);
    nodal = field.values.data();
  }
  const int npe = m.nodes_per_element(), nd = 3 * npe;
  std::vector<double> out(static_cast<std::size_t>(m.local_elements() * nd), 0.0);
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const ElementCoords X = m.element_coordinates(e);
    ElementVector b(nd);
    for (int k = 0; k < npe; ++k) {
      const Eigen::Vector3d r = X.row(k).transpose() - x0;
      b.segment<3>(3 * k) = g - (a + al.cross(r) + w.cross(w.cross(r)));
      if (nodal)
        b.segment<3>(3 * k) += Eigen::Map<const Eigen::Vector3d>(
            nodal + 3 * m.connectivity[static_cast<std::size_t>(e * npe + k)]);
    }
    const ElementVector fe = element_mass(m.type, X, density) * b;
    std::copy(fe.data(), fe.data() + nd, out.begin() + e * nd);
  }
  return out;
}

} // namespace

void StaticProblem::set_up_loads(const StaticSettings &c) {
  const mesh::DistributedMesh &m = mesh_;
  const StaticLoads &loads = c.loads;
  f_ = create_ghosted_vector(m);
  FX_PETSC(VecDuplicate(f_, &u_));
  FX_PETSC(VecZeroEntries(u_));
  FX_PETSC(VecDuplicate(f_, &rhs_));
  FX_PETSC(VecDuplicate(f_, &f_surface_));
  FX_PETSC(VecZeroEntries(f_surface_));
  for (const auto &t : loads.line_loads)
    add_surface_traction(m, t.surface, Eigen::Vector3d(t.value[0], t.value[1], t.value[2]),
                         t.where.str() + ": line_loads", f_surface_);
  for (const auto &t : loads.tractions) {
    const Eigen::Vector3d value(t.value[0], t.value[1], t.value[2]);
    const std::string where = t.where.str() + ": tractions";
    if (t.total) // a total force (and moment), spread over the surface
      add_surface_force(m, t.surface, value, Eigen::Vector3d(t.moment[0], t.moment[1], t.moment[2]),
                        where, f_surface_);
    else
      add_surface_traction(m, t.surface, value, where, f_surface_);
  }
  body_load_ = element_body_loads(m, material_.density, loads, c.case_file);
  set_body_load_factors({});
}

std::unique_ptr<StaticProblem> StaticProblem::create_sharing(const StaticProblem &first,
                                                             const StaticSettings &c) {
  const MPI_Comm comm = first.mesh_.comm;
  int other = support_dofs(first.mesh_, c.loads.supports) != first.fixed_ || first.mf_ ||
              c.material.E != first.material_.E || c.material.nu != first.material_.nu ||
              c.material.density != first.material_.density;
  MPI_Allreduce(MPI_IN_PLACE, &other, 1, MPI_INT, MPI_MAX, comm);
  if (other) // another operator (or a matrix-free one, which keeps its own state): its own
    return create(comm, c);
  std::unique_ptr<StaticProblem> p(new StaticProblem());
  const double t = wall_time();
  p->material_ = first.material_;
  p->mesh_ = first.mesh_;
  p->fixed_ = first.fixed_;
  p->K_ = first.K_;
  p->ksp_ = first.ksp_;
  FX_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(p->K_)));
  FX_PETSC(PetscObjectReference(reinterpret_cast<PetscObject>(p->ksp_)));
  p->operator_ = first.operator_;
  p->support_diagonal_ = first.support_diagonal_;
  p->factor_ = first.factor_;
  p->solver_ = first.solver_;
  p->set_up_loads(c);
  p->timings_.assemble = wall_time() - t;
  return p;
}

std::unique_ptr<StaticProblem> StaticProblem::create(MPI_Comm comm, const StaticSettings &c) {
  std::unique_ptr<StaticProblem> p(new StaticProblem());
  p->material_ = c.material;
  double t = wall_time();
  p->mesh_ = mesh::load_body_mesh(comm, c.mesh);
  p->timings_.mesh = wall_time() - t;
  t = wall_time();
  const mesh::DistributedMesh &m = p->mesh_;
  const StaticLoads &loads = c.loads;

  p->fixed_ = support_dofs(m, loads.supports);
  PetscInt n_fixed = static_cast<PetscInt>(p->fixed_.size()), total_fixed = 0;
  MPI_Allreduce(&n_fixed, &total_fixed, 1, MPIU_INT, MPI_SUM, comm);
  if (total_fixed == 0)
    throw Error(c.case_file +
                    ": a static analysis needs supports (the body is free to move as a rigid body)",
                true);

  p->K_ = create_matrix(m);
  p->set_up_loads(c);
  p->operator_ = std::make_shared<OperatorState>();

  FX_PETSC(KSPCreate(comm, &p->ksp_));
  FX_PETSC(KSPSetOptionsPrefix(p->ksp_, ""));
  p->assemble_operator({});
  p->timings_.assemble = wall_time() - t;
  bool lattice = false;
  p->solver_ = configure_elasticity_solver(p->ksp_, p->K_, m, &lattice);
  PetscBool matrix_free = PETSC_TRUE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-lattice_mg_matrix_free", &matrix_free, nullptr));
  if (lattice && matrix_free) p->mf_ = MatrixFreeStiffness::create(m, p->material_);
  if (p->mf_) {
    // The finest level applies K element by element; the coarse levels and the smoothers'
    // diagonals come from the assembled K.
    PC pc;
    FX_PETSC(KSPGetPC(p->ksp_, &pc));
    p->coarse_ = std::make_unique<LatticeCoarseOperators>(pc);
    p->update_matrix_free();
    FX_PETSC(KSPSetOperators(p->ksp_, p->mf_->matrix(), p->K_));
    p->solver_ += "; the finest level matrix-free";
  }
  print0(comm, "static solver: %s\n", p->solver_.c_str());
  return p;
}

StaticProblem::~StaticProblem() {
  KSPDestroy(&ksp_);
  coarse_.reset();
  mf_.reset();
  MatDestroy(&K_);
  VecDestroy(&f_);
  VecDestroy(&f_surface_);
  VecDestroy(&rhs_);
  VecDestroy(&u_);
}

void StaticProblem::set_body_load_factors(const std::vector<double> &w) {
  FX_PETSC(VecCopy(f_surface_, f_));
  if (body_load_.empty()) return;
  const int npe = mesh_.nodes_per_element(), nd = 3 * npe;
  std::vector<PetscInt> rows(static_cast<std::size_t>(npe));
  std::vector<double> fe(static_cast<std::size_t>(nd));
  for (PetscInt e = 0; e < mesh_.local_elements(); ++e) {
    const double we = w.empty() ? 1.0 : w[static_cast<std::size_t>(e)];
    const double *f = element_body_load(e);
    for (int k = 0; k < nd; ++k) fe[static_cast<std::size_t>(k)] = we * f[k];
    for (int a = 0; a < npe; ++a)
      rows[static_cast<std::size_t>(a)] =
          mesh_.local_to_global(mesh_.connectivity[static_cast<std::size_t>(e * npe + a)]);
    FX_PETSC(VecSetValuesBlocked(f_, npe, rows.data(), fe.data(), ADD_VALUES));
  }
  FX_PETSC(VecAssemblyBegin(f_));
  FX_PETSC(VecAssemblyEnd(f_));
}

void StaticProblem::assemble_operator(const std::vector<double> &modulus_factor) {
  factor_ = modulus_factor;
  // A problem that shares the operator (create_sharing) finds it assembled for these factors
  // (on every rank: a design change may touch one rank's elements only).
  int same = operator_->assembled && operator_->factor == factor_;
  MPI_Allreduce(MPI_IN_PLACE, &same, 1, MPI_INT, MPI_MIN, mesh_.comm);
  if (same) return;
  operator_->factor = factor_;
  operator_->assembled = true;
  assemble_stiffness(mesh_, material_, factor_, K_);
  LogScope log("FxApplySupports");
  // Supports: rows and columns of fixed DOFs replaced by a scaled identity (keeps K symmetric
  // and its diagonal scale, which matters for multigrid smoothers).
  PetscReal diag_sum = 0;
  Vec d;
  FX_PETSC(MatCreateVecs(K_, &d, nullptr));
  FX_PETSC(MatGetDiagonal(K_, d));
  FX_PETSC(VecSum(d, &diag_sum));
  PetscInt n = 0;
  FX_PETSC(VecGetSize(d, &n));
  FX_PETSC(VecDestroy(&d));
  const PetscScalar scale = diag_sum / static_cast<PetscReal>(n);
  FX_PETSC(MatZeroRowsColumns(K_, static_cast<PetscInt>(fixed_.size()), fixed_.data(), scale,
                              nullptr, nullptr));
  support_diagonal_ = scale;
  if (mf_) update_matrix_free();
}

void StaticProblem::update_matrix_free() {
  mf_->set(factor_, fixed_, support_diagonal_);
  coarse_->update(K_);
}

bool StaticProblem::set_random_start(unsigned long seed) {
  random_start_ = seed;
  random_draws_ = 0;
  return !is_direct(ksp_);
}

std::string StaticProblem::solve_to_round_off() {
  return tighten_krylov(ksp_, 1e-12, 10000, "the state and adjoint solves");
}

void StaticProblem::prepare_start(Vec x) {
  const bool iterative = !is_direct(ksp_);
  if (iterative && random_start_ != 0) {
    PetscReal scale = 0;
    FX_PETSC(VecNorm(x, NORM_INFINITY, &scale));
    // A start as far from the solution as zero is, in another direction.
    fill_random(x, random_start_ * 1000003UL + random_draws_++, scale > 0 ? scale : 1.0);
  }
  FX_PETSC(KSPSetInitialGuessNonzero(
      ksp_, iterative && (warm_start_ || random_start_ != 0) ? PETSC_TRUE : PETSC_FALSE));
}

void StaticProblem::zero_supported(Vec rhs) const {
  std::vector<PetscScalar> zeros(fixed_.size(), 0.0);
  FX_PETSC(VecSetValues(rhs, static_cast<PetscInt>(fixed_.size()), fixed_.data(), zeros.data(),
                        INSERT_VALUES));
  FX_PETSC(VecAssemblyBegin(rhs));
  FX_PETSC(VecAssemblyEnd(rhs));
}

void StaticProblem::set_up_solver() {
  FX_PETSC(KSPSetUp(ksp_));
  FX_PETSC(KSPSetUpOnBlocks(ksp_));
}

void StaticProblem::solve() {
  LogScope log("FxStateSolve");
  FX_PETSC(VecCopy(f_, rhs_));
  zero_supported(rhs_);
  double t = wall_time();
  set_up_solver();
  timings_.setup = wall_time() - t;
  t = wall_time();
  prepare_start(u_);
  FX_PETSC(KSPSolve(ksp_, rhs_, u_));
  timings_.solve = wall_time() - t;
  check_converged(ksp_, "static solve");
  PetscInt its = 0;
  FX_PETSC(KSPGetIterationNumber(ksp_, &its));
  iterations_ = static_cast<int>(its);
  FX_PETSC(VecGhostUpdateBegin(u_, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(u_, INSERT_VALUES, SCATTER_FORWARD));
}

void StaticProblem::solve_adjoint(Vec rhs, Vec lambda) {
  LogScope log("FxAdjointSolve");
  zero_supported(rhs);
  prepare_start(lambda);
  FX_PETSC(KSPSolve(ksp_, rhs, lambda));
  check_converged(ksp_, "adjoint solve");
  FX_PETSC(VecGhostUpdateBegin(lambda, INSERT_VALUES, SCATTER_FORWARD));
  FX_PETSC(VecGhostUpdateEnd(lambda, INSERT_VALUES, SCATTER_FORWARD));
}

double StaticProblem::compliance() const {
  PetscScalar c = 0;
  FX_PETSC(VecDot(f_, u_, &c));
  return c;
}

double StaticProblem::max_displacement() const {
  const PetscScalar *u;
  FX_PETSC(VecGetArrayRead(u_, &u));
  double local = 0;
  for (PetscInt i = 0; i < mesh_.owned_nodes; ++i)
    local = std::max(local, std::sqrt(u[3 * i] * u[3 * i] + u[3 * i + 1] * u[3 * i + 1] +
                                      u[3 * i + 2] * u[3 * i + 2]));
  FX_PETSC(VecRestoreArrayRead(u_, &u));
  double global = 0;
  MPI_Allreduce(&local, &global, 1, MPI_DOUBLE, MPI_MAX, mesh_.comm);
  return global;
}

} // namespace flexopt::fem
