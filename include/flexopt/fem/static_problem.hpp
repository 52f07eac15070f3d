#pragma once
/// \file Linear elastostatics of one body: K u = f with supports, tractions, gravity and the
/// d'Alembert force of a rigid motion (loads.inertia).
///
/// The operator, load and solver are kept so that later users (topology optimization)
/// re-assemble with new element modulus factors and solve again, reusing the preconditioner
/// set-up for adjoint solves.
#include "flexopt/fem/assembly.hpp"
#include "flexopt/io/location.hpp"
#include "flexopt/mesh/load.hpp"

#include <array>
#include <memory>
#include <optional>
#include <petscksp.h>
#include <string>
#include <vector>

namespace flexopt::fem {

class MatrixFreeStiffness;
class LatticeCoarseOperators;

/// Dirichlet support (`supports:`): the listed displacement components of every node of
/// `surface` are zero.
struct Support {
  std::string surface;
  std::array<bool, 3> fix{false, false, false};
  io::Location where;
};

/// A constant load on a physical surface (`tractions:`, [N/m^2], force per current = reference
/// area) or curve (`line_loads:`, [N/m]).
struct SurfaceLoad {
  std::string surface; ///< the physical surface or curve
  std::array<double, 3> value{0, 0, 0};
  /// `force:` given instead of `value:`: `value` is a total force, spread as a uniform
  /// traction over the surface (value / area).
  bool total = false;
  /// With `force:`, `moment:` [N m] about the surface's centroid, carried by a traction linear
  /// over the surface (fem::add_surface_force).
  std::array<double, 3> moment{0, 0, 0};
  io::Location where;
};

/// The d'Alembert body force of a body moving rigidly (`loads.inertia`),
/// b(x) = -rho (a + alpha x r + omega x (omega x r)), r = x - point, all in body axes
/// (equivalent static loads of a mechanism link at one instant).
struct RigidMotion {
  std::array<double, 3> point{0, 0, 0};
  std::array<double, 3> acceleration{0, 0, 0};
  std::array<double, 3> angular_velocity{0, 0, 0};
  std::array<double, 3> angular_acceleration{0, 0, 0};
  io::Location where;
};

/// A body force given node by node [m/s^2] (equivalent static loads, docs/theory.md 14.3: the
/// d'Alembert field of a flexible body): b at every local node of the mesh it was made on
/// (owned, then ghosts; 3 per node), applied as the consistent load M_e b_e of each element,
/// scaled with the element's mass factor as gravity is. It keeps that mesh's local coordinates:
/// the static problem refuses it unless it loaded the same mesh on the same ranks.
struct NodalBodyForce {
  std::vector<double> values;
  std::shared_ptr<const std::vector<double>> coordinates; ///< DistributedMesh::coordinates
};

/// What a static analysis applies to its body.
struct StaticLoads {
  std::vector<Support> supports;
  std::vector<SurfaceLoad> tractions;
  std::vector<SurfaceLoad> line_loads;          ///< on physical curves (`surface` = curve name)
  std::optional<std::array<double, 3>> gravity; ///< [m/s^2]
  std::optional<RigidMotion> inertia;           ///< loads.inertia
  std::optional<NodalBodyForce> body_force;     ///< added to gravity and inertia
};

/// The static problem of one body: its mesh, material and loads.
struct StaticSettings {
  mesh::MeshSource mesh;
  IsotropicMaterial material;
  StaticLoads loads;
  std::string case_file; ///< case.yaml, for messages about the whole case
};

class StaticProblem {
public:
  /// Loads the body's mesh, assembles K and f and sets up the solver. Collective.
  static std::unique_ptr<StaticProblem> create(MPI_Comm comm, const StaticSettings &settings);
  /// Another load case of `first`'s body (equivalent static loads' N instants): `settings`'
  /// loads on `first`'s mesh, stiffness matrix and solver, shared (one assembly and one
  /// factorization per design for every load case; each problem keeps its load, displacement and
  /// warm start). The mesh source is not read again. Settings with other supports or material,
  /// or a matrix-free `first`, get a problem of their own (create()). Collective.
  static std::unique_ptr<StaticProblem> create_sharing(const StaticProblem &first,
                                                       const StaticSettings &settings);
  ~StaticProblem();

  /// Re-assembles K with one modulus factor per local element (empty: all 1); does nothing if the
  /// operator (shared with create_sharing's problems) was last assembled with these factors.
  /// Collective.
  void assemble_operator(const std::vector<double> &modulus_factor);
  /// Solves K u = f. Throws (collectively) if the linear solver does not converge. Collective.
  void solve();
  /// Sets the solver up for the current K (its preconditioner) without solving. Collective.
  void set_up_solver();
  /// `on`: every later Krylov solve (state and adjoint) starts from the vector it writes into
  /// (its previous solution) instead of zero (the warm start); the stopping test stays relative
  /// to the right-hand side. Topology optimization: successive designs have nearby solutions.
  /// Off by default; no effect with a direct solver (-ksp_type preonly).
  void set_warm_start(bool on) { warm_start_ = on; }
  bool warm_start() const { return warm_start_; }
  /// seed != 0: the later state and adjoint solves start from random vectors drawn with `seed`
  /// (of the size of their previous solution) instead, until called with 0 (check-gradient's
  /// measurement of the evaluation noise). Returns whether the solves are iterative (a direct
  /// solver has no start to perturb).
  bool set_random_start(unsigned long seed);
  /// check-gradient: the state and adjoint solves to a relative residual of 1e-12, unless the
  /// options set -ksp_rtol (then that). Returns what limits their accuracy, in words ("":
  /// round-off). Collective.
  std::string solve_to_round_off();
  /// Solves the adjoint system K lambda = rhs with the forward operator and preconditioner
  /// (K is symmetric); the supported DOFs of rhs are zeroed first (rhs is modified).
  /// `lambda` must be a ghosted vector from this problem's layout; its ghosts are updated.
  /// Collective.
  void solve_adjoint(Vec rhs, Vec lambda);

  const mesh::DistributedMesh &mesh() const { return mesh_; }
  const IsotropicMaterial &material() const { return material_; }
  const std::vector<double> &modulus_factor() const { return factor_; }
  Vec displacement() const { return u_; } ///< ghosted; ghosts current after solve()
  Vec load() const { return f_; }         ///< external load (unmodified by supports)
  Mat stiffness() const { return K_; }    ///< with supports applied (identity-scaled rows)
  KSP solver() const { return ksp_; }
  /// The linear solver in words ("CG + geometric multigrid on the ... lattice, ..."; printed at
  /// create()).
  const std::string &solver_description() const { return solver_; }
  const std::vector<PetscInt> &fixed_dofs() const { return fixed_; }
  PetscInt global_dofs() const { return 3 * mesh_.global_nodes; }
  int iterations() const { return iterations_; }
  /// Wall-clock seconds of the phases: mesh (read + distribute), assemble (K and f),
  /// setup (preconditioner / factorization), solve (Krylov iterations or triangular solves).
  struct Timings {
    double mesh = 0, assemble = 0, setup = 0, solve = 0;
  };
  const Timings &timings() const { return timings_; }
  /// Body forces (gravity, loads.inertia): whether the case has any. Their load is
  /// f_b = sum_e w_e f_e with f_e = M_e b(X_e) (M_e the element mass matrix, b the body
  /// acceleration field g - a(X) at the element's nodes; exact for b affine in X).
  bool has_body_load() const { return !body_load_.empty(); }
  /// Re-assembles f = f_surface + sum_e w_e f_e with one factor per local element (the design's
  /// mass interpolation; empty: all 1). Collective.
  void set_body_load_factors(const std::vector<double> &w);
  /// f_e of local element e (3 * nodes_per_element entries, the element's DOF order); only
  /// if has_body_load().
  const double *element_body_load(PetscInt e) const {
    return body_load_.data() + e * 3 * mesh_.nodes_per_element();
  }
  double compliance() const;       ///< f . u [J]
  double max_displacement() const; ///< max over nodes of |u| [m]

private:
  StaticProblem() = default;
  /// Sets the supported DOFs of a right-hand side to zero (all prescribed values are 0).
  void zero_supported(Vec rhs) const;
  /// Gives the matrix-free operator the current factors and supports, and forms the coarse
  /// operators from K.
  void update_matrix_free();
  /// The start of the next Krylov solve into x: x itself (warm start), random (set_random_start)
  /// or zero.
  void prepare_start(Vec x);
  /// The load vectors, tractions and body loads of `settings` on mesh_ (material_ set).
  void set_up_loads(const StaticSettings &settings);
  /// The factors K was last assembled with, shared by the problems that share K.
  struct OperatorState {
    std::vector<double> factor;
    bool assembled = false;
  };
  std::shared_ptr<OperatorState> operator_;
  mesh::DistributedMesh mesh_;
  IsotropicMaterial material_{};
  std::vector<double> factor_;
  std::vector<PetscInt> fixed_;
  Mat K_ = nullptr;
  Vec f_ = nullptr, rhs_ = nullptr, u_ = nullptr;
  Vec f_surface_ = nullptr;       ///< the tractions and line loads (no body forces)
  std::vector<double> body_load_; ///< f_e of every local element, flat (empty: no body force)
  KSP ksp_ = nullptr;
  double support_diagonal_ = 1.0; ///< the supported rows' diagonal entry in K
  /// Lattice multigrid with the finest level matrix-free (-lattice_mg_matrix_free, default on):
  /// the KSP's operator, and the coarse levels' Galerkin operators of K.
  std::unique_ptr<MatrixFreeStiffness> mf_;
  std::unique_ptr<LatticeCoarseOperators> coarse_;
  std::string solver_;
  int iterations_ = 0;
  bool warm_start_ = false;
  unsigned long random_start_ = 0; ///< seed of the random starts (0: none)
  unsigned long random_draws_ = 0; ///< random starts drawn with it so far
  Timings timings_;
};

/// Global DOFs of all `supports` (owned by this rank, sorted, unique).
std::vector<PetscInt> support_dofs(const mesh::DistributedMesh &mesh,
                                   const std::vector<Support> &supports);

/// Sets the default solver for an SPD elasticity operator: CG with geometric multigrid where the
/// mesh is a structured Hex8 lattice (lattice_multigrid.hpp; -lattice_mg_levels N or
/// -lattice_mg_coarse_dofs N (default 20000) set its depth), else algebraic multigrid (GAMG) with
/// the rigid-body near-null space built from the node coordinates; a -pc_type option selects
/// the preconditioner instead. Relative tolerance 1e-8 (the compliance error is quadratic in it:
/// CG is a Galerkin method in the energy norm). Options from the case's `solver:` string and the
/// command line are applied afterwards (KSPSetFromOptions). Returns the solver in words.
/// Collective.
/// `lattice_multigrid` (optional) tells whether the lattice's geometric multigrid was chosen.
std::string configure_elasticity_solver(KSP ksp, Mat A, const mesh::DistributedMesh &mesh,
                                        bool *lattice_multigrid = nullptr);

/// Throws a collective flexopt::Error naming `what` if the last KSPSolve diverged.
void check_converged(KSP ksp, const std::string &what);

} // namespace flexopt::fem
