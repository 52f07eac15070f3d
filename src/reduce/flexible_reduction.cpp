#include "flexopt/reduce/flexible_reduction.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/reduce/craig_bampton.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"
#include "flexopt/reduce/modal.hpp"
#include "flexopt/reduce/reduction_adjoint.hpp"

#include <cstdio>
#include <set>
#include <string>

namespace flexopt::reduce {

namespace {

/// The chord frame (docs/theory.md section 7.1): every Craig-Bampton vector v_k gets the small
/// rigid rotation w_k x (x - o) about the frame origin o that brings the centroid of interface
/// 1 back onto the frame axis d = c_1 - o: w_k = -(d x t_k) / |d|^2, t_k the translation of
/// interface 1 in v_k (unit for the static modes of its translations, zero otherwise). The
/// rotation does not strain the body, so K_cb is unchanged; M_cb is projected again. T, R: the
/// translation and rotation of each interface's rigid node per Craig-Bampton vector.
void to_chord_frame(const mesh::DistributedMesh &mesh, Mat M, const Eigen::Vector3d &origin,
                    CraigBamptonBasis &cb, std::vector<Eigen::Matrix3Xd> &T,
                    std::vector<Eigen::Matrix3Xd> &R) {
  const int n = static_cast<int>(cb.vectors.size());
  const Eigen::Vector3d d = cb.centroids[1] - origin;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector3d w = -d.cross(T[1].col(k)) / d.squaredNorm();
    for (std::size_t i = 0; i < T.size(); ++i) {
      T[i].col(k) += w.cross(cb.centroids[i] - origin);
      R[i].col(k) += w;
    }
    PetscScalar *v;
    FX_PETSC(VecGetArray(cb.vectors[static_cast<std::size_t>(k)], &v));
    for (PetscInt a = 0; a < mesh.owned_nodes; ++a) {
      const Eigen::Vector3d x(&mesh.coordinates[3 * static_cast<std::size_t>(a)]);
      const Eigen::Vector3d u = w.cross(x - origin);
      for (int c = 0; c < 3; ++c) v[3 * a + c] += u(c);
    }
    FX_PETSC(VecRestoreArray(cb.vectors[static_cast<std::size_t>(k)], &v));
  }
  cb.M = project(M, cb.vectors);
}

} // namespace

FlexibleReduction::~FlexibleReduction() {
  for (Vec &v : basis) VecDestroy(&v);
}

Vec basis_combination(const std::vector<Vec> &basis, const Eigen::VectorXd &c) {
  Vec v;
  FX_PETSC(VecDuplicate(basis.front(), &v));
  FX_PETSC(VecZeroEntries(v));
  FX_PETSC(
      VecMAXPY(v, static_cast<PetscInt>(basis.size()), c.data(), const_cast<Vec *>(basis.data())));
  return v;
}

void reduce_flexible_body(const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &material,
                          const std::vector<std::string> &interfaces, int fixed_modes,
                          bool geometric_stiffening, FlexibleReduction &out, FrameCondition frame,
                          const ElementFactors *design, std::shared_ptr<ClampedProblem> reuse) {
  LogScope log("FxFlexReduce");
  if (frame == FrameCondition::Chord && (interfaces.size() < 2 || geometric_stiffening))
    throw Error("FFRF reduction: the chord frame needs a second interface and no centrifugal "
                "geometric stiffening",
                true);
  Mat K = fem::create_matrix(mesh), M = fem::create_matrix(mesh);
  const std::vector<double> none;
  const std::vector<double> &s = design ? design->stiffness : none;
  const std::vector<double> &w = design ? design->mass : none;
  fem::assemble_stiffness(mesh, material, s, K);
  fem::assemble_mass(mesh, material.density, w, M);
  CraigBamptonBasis cb;
  CraigBamptonOptions options;
  if (design) {
    options.tolerance = 1e-13;
    options.next_eigenvalue = true;
    options.reuse = std::move(reuse);
  }
  craig_bampton(mesh, K, M, interfaces, fixed_modes, cb, options);
  // With a single interface (the frame), the Craig-Bampton problem (every interface clamped) is
  // the frame-clamped one of the geometric stiffness: its factorization is kept for those solves
  // (one MUMPS factorization instead of two), otherwise released now (a design body keeps it for
  // its adjoint).
  const bool share_factorization = geometric_stiffening && interfaces.size() == 1;
  if (!share_factorization && !design) cb.interior.reset();
  std::shared_ptr<ReductionAdjointData> keep;
  if (design) {
    keep = std::make_shared<ReductionAdjointData>();
    keep->material = material;
    keep->factors = *design;
    keep->static_modes = cb.static_modes;
    keep->fixed_eigenvalues = cb.fixed_eigenvalues;
    keep->next_eigenvalue = cb.next_eigenvalue;
    keep->interface_dofs = cb.interface_dofs;
    keep->interior = cb.interior;
    for (Vec v : cb.vectors) {
      Vec c;
      FX_PETSC(VecDuplicate(v, &c));
      FX_PETSC(VecCopy(v, c));
      keep->vectors.push_back(c);
    }
  }
  out.static_modes = cb.static_modes;
  out.fixed_modes = cb.fixed_modes;
  out.centroids = cb.centroids;
  out.origin = cb.centroids.front();
  const int n = static_cast<int>(cb.vectors.size());
  // Interface nodes in Craig-Bampton coordinates: static mode 6 (k - 1) + c moves interface k by
  // unit translation (c < 3) or rotation (c >= 3) and no other interface; fixed-interface modes
  // move none.
  std::vector<Eigen::Matrix3Xd> T(interfaces.size(), Eigen::Matrix3Xd::Zero(3, n)),
      R(interfaces.size(), Eigen::Matrix3Xd::Zero(3, n));
  for (std::size_t k = 1; k < interfaces.size(); ++k)
    for (int c = 0; c < 3; ++c) {
      const int base = 6 * static_cast<int>(k - 1);
      T[k](c, base + c) = 1;
      R[k](c, base + 3 + c) = 1;
    }
  if (frame == FrameCondition::Chord) to_chord_frame(mesh, M, out.origin, cb, T, R);
  // M-orthonormal eigenbasis of the reduced problem, each column's sign fixed by its largest
  // entry (the same on every rank and rank count).
  Eigen::MatrixXd Y = Eigen::MatrixXd::Identity(n, n);
  if (n > 0) {
    const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(cb.K, cb.M);
    if (eig.info() != Eigen::Success)
      throw Error("FFRF reduction: the reduced eigenproblem failed (a singular reduced mass)",
                  true);
    Y = eig.eigenvectors();
    for (int k = 0; k < n; ++k) {
      Eigen::Index i;
      Y.col(k).cwiseAbs().maxCoeff(&i);
      if (Y(i, k) < 0) Y.col(k) *= -1;
    }
  }
  for (Vec &v : out.basis) FX_PETSC(VecDestroy(&v));
  out.basis.clear();
  for (int k = 0; k < n; ++k) out.basis.push_back(basis_combination(cb.vectors, Y.col(k)));
  // Psi = V Y: M_r follows from the Craig-Bampton matrix. K_r is projected again by element
  // energies (fem::project_stiffness): V^T (K V) through the assembled K carries an error of
  // eps ||K|| ||V||^2 (eps cond(K) relative: 1e-9 on a slender bar), a noise that reaches the
  // responses and their finite differences (docs/theory.md section 10, "Accuracy"); Y only
  // needs to span (its noise is a change of coordinates), K_r must be accurate.
  out.K = fem::project_stiffness(mesh, material, s, out.basis);
  out.M = Y.transpose() * cb.M * Y;
  out.craig_bampton = Y.transpose() * cb.M;
  out.eigenvalues = out.K.diagonal();
  out.invariants = ffrf_invariants(mesh, M, out.basis, out.origin);
  out.translation.resize(interfaces.size());
  out.rotation.resize(interfaces.size());
  for (std::size_t k = 0; k < interfaces.size(); ++k) {
    out.translation[k] = T[k] * Y;
    out.rotation[k] = R[k] * Y;
  }
  out.geometric.clear();
  if (geometric_stiffening) {
    const auto G = centrifugal_geometric_stiffness(
        mesh, material, K, M, interfaces.front(), out.origin, out.basis,
        share_factorization ? cb.interior.get() : nullptr, s, keep ? &keep->loads : nullptr);
    out.geometric.assign(G.begin(), G.end());
    if (keep && share_factorization) keep->loads.frame = cb.interior;
  }
  out.adjoint = keep;
  if (keep) {
    keep->Y = Y;
    keep->T = T;
    keep->R = R;
    keep->K = K;
    keep->M = M;
  } else {
    FX_PETSC(MatDestroy(&K));
    FX_PETSC(MatDestroy(&M));
  }
}

void check_modal_cut(const FlexibleReduction &r, const std::string &body, MPI_Comm comm) {
  if (!r.adjoint || r.fixed_modes == 0) return;
  const double lo = r.adjoint->fixed_eigenvalues.back(), hi = r.adjoint->next_eigenvalue;
  const double gap = (hi - lo) / lo;
  char line[512];
  std::snprintf(line, sizeof line,
                "FFRF body '%s': fixed-interface modes %d and %d have %.9g Hz and %.9g Hz "
                "(relative gap %.2e)",
                body.c_str(), r.fixed_modes, r.fixed_modes + 1, frequency_hz(lo), frequency_hz(hi),
                gap);
  if (!(gap > 1e-8))
    throw Error(std::string(line) +
                    ": a repeated eigenvalue is split by reduction.modes, and the reduced model "
                    "is not differentiable with respect to the densities there; use " +
                    std::to_string(r.fixed_modes + 1) + " or " + std::to_string(r.fixed_modes - 1) +
                    " modes",
                true);
  // Warned once per body and run: an optimization reduces the body at every evaluation.
  static std::set<std::string> warned;
  if (gap < 1e-2 && warned.insert(body).second)
    print0(comm,
           "%s: a close pair at the cut of reduction.modes; the gradient holds for designs that "
           "keep the order (another modes count avoids it)\n",
           line);
}

Eigen::MatrixXd owned_basis_values(const FlexibleReduction &r, PetscInt owned_nodes) {
  const int n = r.size();
  Eigen::MatrixXd out(3 * owned_nodes, n);
  for (int k = 0; k < n; ++k) {
    const PetscScalar *v;
    FX_PETSC(VecGetArrayRead(r.basis[static_cast<std::size_t>(k)], &v));
    for (PetscInt i = 0; i < 3 * owned_nodes; ++i) out(i, k) = v[i];
    FX_PETSC(VecRestoreArrayRead(r.basis[static_cast<std::size_t>(k)], &v));
  }
  return out;
}

Eigen::Matrix3Xd basis_at_point(const mesh::DistributedMesh &mesh, const FlexibleReduction &r,
                                const fem::PointLocation &where) {
  const int n = r.size();
  Eigen::Matrix3Xd out(3, n);
  Vec g = fem::create_ghosted_vector(mesh);
  for (int k = 0; k < n; ++k) {
    FX_PETSC(VecCopy(r.basis[static_cast<std::size_t>(k)], g));
    FX_PETSC(VecGhostUpdateBegin(g, INSERT_VALUES, SCATTER_FORWARD));
    FX_PETSC(VecGhostUpdateEnd(g, INSERT_VALUES, SCATTER_FORWARD));
    const auto u = fem::probe_vector(mesh, g, where);
    out.col(k) = Eigen::Vector3d(u[0], u[1], u[2]);
  }
  FX_PETSC(VecDestroy(&g));
  return out;
}

} // namespace flexopt::reduce
