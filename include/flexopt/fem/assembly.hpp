#pragma once
/// \file Assembly of element kernels into PETSc objects on a DistributedMesh.
///
/// DOFs are node-major with block size 3: global DOF 3*g + k is component k of global node g.
/// Matrices are MATAIJ (MPIAIJ on several ranks) with block size 3, preallocated exactly from
/// the node graph of the mesh (shared rows completed by their owners), and carry the
/// local-to-global mapping of the mesh's local nodes (for MatSetValuesLocal). The kernels here
/// add element matrices with global DOF numbers in ascending order.
#include "flexopt/fem/corotated.hpp"
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <array>
#include <petscmat.h>
#include <petscvec.h>
#include <string>
#include <vector>

namespace flexopt::fem {

/// Creates an empty, exactly preallocated matrix with the node graph's pattern and
/// `block_size` DOFs per node (3: displacements; 1: a scalar nodal field). Collective.
Mat create_matrix(const mesh::DistributedMesh &mesh, int block_size = 3);

/// Creates a ghosted vector (block size 3) over the mesh's local nodes. Collective.
Vec create_ghosted_vector(const mesh::DistributedMesh &mesh);

/// The unit-modulus stiffness matrices K_e^0 of a mesh's elements (K_e = factor K_e^0), computed
/// once per element shape: elements that are translates of one another (node offsets from the
/// first node equal to 1e-12 of the element's size; every cell of a structured Hex8 lattice) share
/// one matrix. Keeps up to 8 shapes; on a mesh whose first 64 elements give no repeat it stops
/// looking and computes every element (an unstructured mesh pays nothing).
class UnitStiffness {
public:
  UnitStiffness(ElementType type, const IsotropicMaterial &material)
      : type_(type), material_(material) {}
  static constexpr std::size_t kMaxShapes = 8;
  /// K_e^0 of the element with node coordinates X; the reference is valid until the next call.
  /// Throws for a degenerate element (element_stiffness).
  const ElementMatrix &operator()(const ElementCoords &X);
  /// The number of X's shape among the kept ones (a new shape is kept while there are fewer than
  /// kMaxShapes), or -1. Throws for a degenerate element.
  int shape(const ElementCoords &X);
  /// K^0 of kept shape s (shape()'s number); valid while this object lives.
  const ElementMatrix &matrix(int s) const { return shapes_[static_cast<std::size_t>(s)].K; }
  int computed() const { return computed_; } ///< element matrices computed so far

private:
  ElementType type_;
  IsotropicMaterial material_;
  struct Shape {
    ElementCoords offsets; ///< X - X_0 per node
    ElementMatrix K;
  };
  std::vector<Shape> shapes_;
  ElementMatrix scratch_;
  int computed_ = 0, hits_ = 0;
};

/// Adds K = sum_e factor_e K_e into A (zeroed first). `modulus_factor` holds one factor per
/// local element (the SIMP interpolation later), or is empty for 1. Collective.
void assemble_stiffness(const mesh::DistributedMesh &mesh, const IsotropicMaterial &material,
                        const std::vector<double> &modulus_factor, Mat A);

/// Consistent mass matrix, M = sum_e factor_e M_e (factor empty: 1), into A (zeroed first).
/// Only the nonzeros m_ab of M_e = m (x) I_3 are added, so once assembled A stores the
/// same-component entries of the pattern only (a third of a stiffness matrix's). Collective.
void assemble_mass(const mesh::DistributedMesh &mesh, double density,
                   const std::vector<double> &density_factor, Mat A);

/// Adds the consistent mass (as assemble_mass, without zeroing A or assembling it) at the DOFs
/// node_dof[local node] + component of another layout (empty: the mesh's own numbering).
/// Not collective (MatSetValues).
void add_mass(const mesh::DistributedMesh &mesh, double density,
              const std::vector<double> &density_factor, const std::vector<PetscInt> &node_dof,
              Mat A);

/// Adds explicit zeros on every element's full 3n x 3n block at the DOFs of node_dof (empty:
/// the mesh's own numbering): the pattern of the tangent, for preallocation (MATPREALLOCATOR).
void add_element_pattern(const mesh::DistributedMesh &mesh, const std::vector<PetscInt> &node_dof,
                         Mat A);

/// Creates and assembles the body's stiffness K and consistent mass M (same layout, no
/// factors). Collective; the caller destroys both.
void assemble_stiffness_and_mass(const mesh::DistributedMesh &mesh,
                                 const IsotropicMaterial &material, Mat &K, Mat &M);

/// Area-weighted centroid of a physical surface over all ranks (each face lives on one rank).
/// Collective; throws a collective flexopt::Error naming `where` for a missing surface or one
/// without area.
Eigen::Vector3d surface_centroid(const mesh::DistributedMesh &mesh, const std::string &name,
                                 const std::string &where);

/// The area of a physical surface (its faces summed over all ranks) [m^2]. Collective.
double surface_area(const mesh::DistributedMesh &mesh, const std::string &surface,
                    const std::string &where);

/// Adds the consistent load of a constant traction t [N/m^2] on the named surface to f.
/// Collective. Throws (collectively) if the surface does not exist.
void add_surface_traction(const mesh::DistributedMesh &mesh, const std::string &surface,
                          const Eigen::Vector3d &t, const std::string &where, Vec f);

/// Adds the consistent load of a total force F [N] and a moment M [N m] about the surface's
/// centroid C, carried by the named surface as the linear traction
/// t(x) = F / area + (J^-1 M) x (x - C), J = int (|x - C|^2 I - (x - C)(x - C)^T) dA: it has the
/// resultant F and the moment M about C and nothing else (docs/theory.md section 14.3). M = 0
/// gives the uniform spread of `force:`. Collective; throws a collective flexopt::Error naming
/// `where` for a missing surface, one without area, or a moment on a surface that cannot carry
/// it (J singular: a line of faces).
void add_surface_force(const mesh::DistributedMesh &mesh, const std::string &surface,
                       const Eigen::Vector3d &F, const Eigen::Vector3d &M, const std::string &where,
                       Vec f);

/// Global DOF numbers (owned by this rank) of the given components of the nodes of `surface`.
std::vector<PetscInt> surface_dofs(const mesh::DistributedMesh &mesh, const std::string &surface,
                                   const std::array<bool, 3> &components, const std::string &where);

/// Vector of the owned node coordinates (block size 3): used for the rigid-body near-null
/// space of algebraic multigrid. Collective.
Vec create_coordinate_vector(const mesh::DistributedMesh &mesh);

/// Element-wise volume of the local elements [m^3].
std::vector<double> element_volumes(const mesh::DistributedMesh &mesh);

/// Von Mises stress at the centroid of each local element from a ghosted displacement vector
/// whose ghost values are up to date. [Pa]
std::vector<double> element_von_mises(const mesh::DistributedMesh &mesh,
                                      const IsotropicMaterial &material,
                                      const std::vector<double> &modulus_factor, Vec u_ghosted);

/// The small rotation |(1/2) curl u| [rad] at the centroid of each local element from a ghosted
/// displacement vector whose ghost values are up to date.
std::vector<double> element_rotations(const mesh::DistributedMesh &mesh, Vec u_ghosted);

/// The co-rotated elements (fem::corotated_element) of the local elements, in local order, with
/// E scaled by modulus_factor[e] (empty: 1). Throws like element_stiffness (abort_local with the
/// element named: only this rank holds it).
std::vector<CorotatedElement> corotated_elements(const mesh::DistributedMesh &mesh,
                                                 const IsotropicMaterial &material,
                                                 const std::vector<double> &modulus_factor);

/// What assemble_corotated found, the same on every rank.
struct CorotatedSum {
  double energy = 0;   ///< sum of the elements' co-rotated energies [J]
  bool ok = true;      ///< false if an element is inverted (det F <= 0) on some rank
  std::string failure; ///< then: the first such element (lowest rank), with its mesh tag
};

/// Damping in the element loop (corotated_damping): the velocities (3 per local node, like u),
/// the coefficient beta [s] and the weight gp of df/dv in the tangent, T += df/dx + gp df/dv.
struct CorotatedDamping {
  const PetscScalar *v = nullptr;
  double beta = 0, gp = 0;
};

/// The element loop of assemble_corotated without its zeroing, final assembly and reductions:
/// adds the force (and the tangent if T is not null) of the local elements at the displacement
/// u (3 per local node: owned, then ghosts) at the DOFs node_dof[local node] + component
/// (empty: the mesh's own numbering), and with `damping` its force (and Jacobians). Returns this
/// rank's energy; the first inverted element's message goes to `failure` (if empty). Not
/// collective.
double add_corotated(const mesh::DistributedMesh &mesh,
                     const std::vector<CorotatedElement> &elements, const PetscScalar *u,
                     const std::vector<PetscInt> &node_dof, Vec F, Mat T, std::string &failure,
                     const CorotatedDamping *damping = nullptr);

/// Sums the energies over the ranks and spreads the first failure (lowest rank). Collective.
CorotatedSum reduce_corotated(MPI_Comm comm, double energy, std::string failure);

/// Internal force F = dE/dx (global vector of the mesh layout, zeroed first) and, if T is not
/// null, the tangent T = d^2E/dx^2 (zeroed first, from create_matrix) of the body's co-rotated
/// elastic energy at the displacement u (ghosted, ghost values up to date): positions
/// x = X + u. Collective. An inverted element does not throw: it is left out, and every rank
/// gets ok = false and the message (a Newton iteration would take a smaller step).
CorotatedSum assemble_corotated(const mesh::DistributedMesh &mesh,
                                const std::vector<CorotatedElement> &elements, Vec u_ghosted, Vec F,
                                Mat T);

/// Ghosted copies of full-size vectors (block size 3, the mesh's layout) for element gathers.
/// Collective to construct.
class ElementGather {
public:
  ElementGather(const mesh::DistributedMesh &mesh, const std::vector<Vec> &vectors);
  ~ElementGather();
  ElementGather(const ElementGather &) = delete;
  ElementGather &operator=(const ElementGather &) = delete;
  int size() const { return static_cast<int>(values_.size()); }
  /// The 3 npe x size() block of local element e (node-major rows, one column per vector).
  void element(PetscInt e, Eigen::MatrixXd &out) const;

private:
  const mesh::DistributedMesh &mesh_;
  std::vector<Vec> ghosted_, local_;
  std::vector<const PetscScalar *> values_;
};

/// sum_e f_e V_e^T K_e V_e (f: modulus factors, empty: 1; V: full-size vectors) summed over all
/// ranks: the projection of the stiffness by element energies, without the cancellation of
/// the assembled K's rows (every row of K V sums element forces that balance), which leaves
/// V^T (K V) an error of eps ||K|| ||V||^2 against eps |V^T K V| here. Collective.
Eigen::MatrixXd project_stiffness(const mesh::DistributedMesh &mesh,
                                  const IsotropicMaterial &material,
                                  const std::vector<double> &modulus_factor,
                                  const std::vector<Vec> &vectors);

/// Displacement of local element e from the local form of a ghosted vector.
ElementVector gather_element(const mesh::DistributedMesh &mesh, PetscInt e,
                             const PetscScalar *u_local);
/// Adds the element vector f (3 nodes_per_element entries, node-major) of local element e into
/// the local form of a ghosted vector (the transpose of gather_element).
void add_element(const mesh::DistributedMesh &mesh, PetscInt e, const double *f,
                 PetscScalar *local);
/// Sets the ghosted vector v to the sum over the ranks of what `fill(local)` adds into its
/// zeroed local form (owned and ghost entries: the ghosts' shares go to their owners).
/// Collective.
template <class Fill> void assemble_ghosted(Vec v, Fill &&fill) {
  Vec local;
  PetscScalar *a;
  FX_PETSC(VecZeroEntries(v));
  FX_PETSC(VecGhostGetLocalForm(v, &local));
  FX_PETSC(VecZeroEntries(local));
  FX_PETSC(VecGetArray(local, &a));
  fill(a);
  FX_PETSC(VecRestoreArray(local, &a));
  FX_PETSC(VecGhostRestoreLocalForm(v, &local));
  FX_PETSC(VecGhostUpdateBegin(v, ADD_VALUES, SCATTER_REVERSE));
  FX_PETSC(VecGhostUpdateEnd(v, ADD_VALUES, SCATTER_REVERSE));
}

} // namespace flexopt::fem
