#include "flexopt/reduce/craig_bampton.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/reduce/modal.hpp"

#include <petscksp.h>

namespace flexopt::reduce {

CraigBamptonBasis::~CraigBamptonBasis() {
  for (Vec &v : vectors) VecDestroy(&v);
}

void craig_bampton(const mesh::DistributedMesh &mesh, Mat K, Mat M,
                   const std::vector<std::string> &interfaces, int fixed_modes,
                   CraigBamptonBasis &out, const CraigBamptonOptions &options) {
  LogScope log("FxCraigBampton");
  if (interfaces.empty())
    throw Error("Craig-Bampton: a flexible body needs at least one interface (its frame)", true);
  const std::size_t ni = interfaces.size();
  out.centroids.clear();
  for (const auto &name : interfaces)
    out.centroids.push_back(fem::surface_centroid(mesh, name, "Craig-Bampton interface"));

  // Owned DOFs of every interface surface, and the union of all of them.
  std::vector<std::vector<PetscInt>> nodes(ni);
  std::vector<PetscInt> constrained;
  for (std::size_t k = 0; k < ni; ++k) {
    const auto d =
        fem::surface_dofs(mesh, interfaces[k], {true, true, true}, "Craig-Bampton interface");
    constrained.insert(constrained.end(), d.begin(), d.end());
    for (std::size_t i = 0; i < d.size(); i += 3) nodes[k].push_back(d[i] / 3);
  }

  // Every interface clamped: K_ii (the interior) factorized ONCE by MUMPS Cholesky, which
  // serves the static modes and the shift-and-invert of the fixed-interface modes alike.
  for (Vec &v : out.vectors) FX_PETSC(VecDestroy(&v));
  out.vectors.clear();
  out.fixed_modes = fixed_modes;
  out.fixed_eigenvalues.clear();
  const std::size_t ns = 6 * (ni - 1);
  out.static_modes = static_cast<int>(ns);
  out.interior.reset();
  if (ns == 0 && fixed_modes <= 0) { // no elastic coordinates: nothing to factorize
    out.K.resize(0, 0);
    out.M.resize(0, 0);
    return;
  }
  out.interface_dofs = constrained;
  out.next_eigenvalue = std::numeric_limits<double>::quiet_NaN();
  if (options.reuse &&
      options.reuse->update(K, M, constrained, fixed_modes, options.next_eigenvalue))
    out.interior = options.reuse;
  else
    out.interior = std::make_shared<ClampedProblem>(K, M, constrained, fixed_modes, "cb_",
                                                    options.tolerance, options.next_eigenvalue);
  ClampedProblem &clamped = *out.interior;
  // Static modes: prescribed rigid motion u_D of interface k, the others clamped.
  std::vector<Vec> rhs(ns), x(ns);
  for (std::size_t k = 1; k < ni; ++k)
    for (int c = 0; c < 6; ++c) {
      Vec ud, b;
      FX_PETSC(MatCreateVecs(K, &ud, &b));
      // Unit translation e_c, or unit rotation about e_{c-3} through the centroid:
      // u = e x (x - centroid).
      FX_PETSC(VecZeroEntries(ud));
      for (PetscInt node : nodes[k]) {
        const PetscInt local = node - mesh.node_start;
        const Eigen::Vector3d xn(mesh.coordinates[3 * static_cast<std::size_t>(local)],
                                 mesh.coordinates[3 * static_cast<std::size_t>(local) + 1],
                                 mesh.coordinates[3 * static_cast<std::size_t>(local) + 2]);
        Eigen::Vector3d u = Eigen::Vector3d::Zero();
        if (c < 3)
          u(c) = 1;
        else
          u = Eigen::Vector3d::Unit(c - 3).cross(xn - out.centroids[k]);
        const PetscInt rows[3] = {3 * node, 3 * node + 1, 3 * node + 2};
        FX_PETSC(VecSetValues(ud, 3, rows, u.data(), INSERT_VALUES));
      }
      FX_PETSC(VecAssemblyBegin(ud));
      FX_PETSC(VecAssemblyEnd(ud));
      // Lifting: K_ii x_i = -K_iD u_D; constrained rows carry u_D itself.
      FX_PETSC(MatMult(K, ud, b));
      FX_PETSC(VecScale(b, -1.0));
      {
        PetscScalar *ba;
        const PetscScalar *ua;
        PetscInt lo;
        FX_PETSC(VecGetOwnershipRange(b, &lo, nullptr));
        FX_PETSC(VecGetArray(b, &ba));
        FX_PETSC(VecGetArrayRead(ud, &ua));
        for (PetscInt dof : constrained) ba[dof - lo] = ua[dof - lo];
        FX_PETSC(VecRestoreArrayRead(ud, &ua));
        FX_PETSC(VecRestoreArray(b, &ba));
      }
      FX_PETSC(VecDestroy(&ud));
      const std::size_t j = 6 * (k - 1) + static_cast<std::size_t>(c);
      rhs[j] = b;
      FX_PETSC(VecDuplicate(b, &x[j]));
    }
  try {
    clamped.solve(rhs, x, "Craig-Bampton: the static-mode solve");
  } catch (const Error &) {
    for (Vec &v : rhs) VecDestroy(&v);
    for (Vec &v : x) VecDestroy(&v);
    throw;
  }
  for (Vec &v : rhs) FX_PETSC(VecDestroy(&v));
  out.vectors = x;

  // Fixed-interface modes: every interface surface clamped.
  if (fixed_modes > 0) {
    ModalResult modes;
    clamped.lowest_modes(modes);
    out.next_eigenvalue = modes.next_eigenvalue;
    for (int i = 0; i < fixed_modes; ++i) {
      out.fixed_eigenvalues.push_back(modes.eigenvalues[static_cast<std::size_t>(i)]);
      // Take the vector over instead of copying it.
      out.vectors.push_back(modes.modes[static_cast<std::size_t>(i)]);
      modes.modes[static_cast<std::size_t>(i)] = nullptr;
    }
  }

  out.K = project(K, out.vectors);
  out.M = project(M, out.vectors);
}

} // namespace flexopt::reduce
