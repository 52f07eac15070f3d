#include "flexopt/reduce/reduction_adjoint.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/fem/assembly.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace flexopt::reduce {

ReductionAdjointData::~ReductionAdjointData() {
  for (Vec &v : vectors) VecDestroy(&v);
  MatDestroy(&K);
  MatDestroy(&M);
}

namespace {

using Matrix = Eigen::MatrixXd;

Matrix sym(const Matrix &A, int n) {
  if (A.size() == 0) return Matrix::Zero(n, n);
  return 0.5 * (A + A.transpose());
}

using Gathered = fem::ElementGather;

/// Zeroes the owned global DOFs `dofs` of v.
void zero_dofs(Vec v, const std::vector<PetscInt> &dofs) {
  PetscInt lo;
  FX_PETSC(VecGetOwnershipRange(v, &lo, nullptr));
  PetscScalar *a;
  FX_PETSC(VecGetArray(v, &a));
  for (PetscInt d : dofs) a[d - lo] = 0.0;
  FX_PETSC(VecRestoreArray(v, &a));
}

Vec duplicate_zero(Vec proto) {
  Vec v;
  FX_PETSC(VecDuplicate(proto, &v));
  FX_PETSC(VecZeroEntries(v));
  return v;
}

void destroy_all(std::vector<Vec> &v) {
  for (Vec &x : v) VecDestroy(&x);
  v.clear();
}

/// y += sum_l c(l) x_l.
void add_combination(Vec y, const std::vector<Vec> &x, const Eigen::VectorXd &c) {
  if (x.empty()) return;
  FX_PETSC(VecMAXPY(y, static_cast<PetscInt>(x.size()), c.data(), const_cast<Vec *>(x.data())));
}

/// Solves (K_ii - lambda_j M_ii) a_j = b_j on range Q = {x: Phi^T M x = 0} for every column
/// (docs/theory.md section 10, step 6): conjugate gradients preconditioned by Q K_ii^-1, all
/// columns' preconditioner solves as one block. b_j must lie in range P (zero on the interfaces,
/// Phi^T b_j = 0). Returns the largest iteration count.
int fixed_mode_solves(const ReductionAdjointData &d, const std::vector<Vec> &Phi,
                      const std::vector<Vec> &MPhi, const std::vector<double> &lambda,
                      const std::vector<Vec> &b, const std::vector<Vec> &unprojected,
                      const std::vector<Vec> &x) {
  const std::size_t nc = b.size();
  if (nc == 0) return 0;
  const auto N = static_cast<PetscInt>(Phi.size());
  std::vector<Vec> r(nc), z(nc), p(nc), Ap(nc), w(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    FX_PETSC(VecZeroEntries(x[c]));
    FX_PETSC(VecDuplicate(b[c], &r[c]));
    FX_PETSC(VecCopy(b[c], r[c]));
    FX_PETSC(VecDuplicate(b[c], &z[c]));
    FX_PETSC(VecDuplicate(b[c], &p[c]));
    FX_PETSC(VecDuplicate(b[c], &Ap[c]));
    FX_PETSC(VecDuplicate(b[c], &w[c]));
  }
  auto cleanup = [&] {
    destroy_all(r);
    destroy_all(z);
    destroy_all(p);
    destroy_all(Ap);
    destroy_all(w);
  };
  std::vector<PetscScalar> dots(static_cast<std::size_t>(N));
  // z = Q K_ii^-1 r for the active columns.
  auto precondition = [&](const std::vector<std::size_t> &active) {
    std::vector<Vec> rhs, out;
    for (std::size_t c : active) {
      rhs.push_back(r[c]);
      out.push_back(z[c]);
    }
    d.interior->solve(rhs, out, "FFRF reduction adjoint: the preconditioner solve");
    for (std::size_t c : active) {
      if (N == 0) continue;
      FX_PETSC(VecMDot(z[c], N, const_cast<Vec *>(MPhi.data()), dots.data()));
      for (auto &v : dots) v = -v;
      FX_PETSC(VecMAXPY(z[c], N, dots.data(), const_cast<Vec *>(Phi.data())));
    }
  };
  std::vector<double> rz(nc, 0.0), rz0(nc, 0.0);
  std::vector<std::size_t> active;
  for (std::size_t c = 0; c < nc; ++c) active.push_back(c);
  precondition(active);
  std::vector<std::size_t> next;
  for (std::size_t c : active) {
    FX_PETSC(VecDot(r[c], z[c], &rz[c]));
    rz0[c] = rz[c];
    FX_PETSC(VecCopy(z[c], p[c]));
  }
  // Each column stops at 1e-12 of the largest cotangent of its response before the projection
  // P (in the K^-1 norm; a response's columns are consecutive, one per mode): a right-hand side
  // that P reduces to round-off (a cotangent nearly inside the span, as K Psi K-bar is) cannot
  // lose 12 more orders.
  const std::size_t per = lambda.size();
  std::vector<double> ref(nc, 0.0), rz_scale(nc, 0.0);
  {
    std::vector<Vec> y(nc);
    for (std::size_t c = 0; c < nc; ++c) FX_PETSC(VecDuplicate(b[c], &y[c]));
    d.interior->solve(unprojected, y, "FFRF reduction adjoint: the preconditioner solve");
    for (std::size_t c = 0; c < nc; ++c) FX_PETSC(VecDot(unprojected[c], y[c], &ref[c]));
    destroy_all(y);
  }
  for (std::size_t c = 0; c < nc; ++c)
    rz_scale[c] = std::max(
        rz0[c], *std::max_element(ref.begin() + static_cast<std::ptrdiff_t>(c - c % per),
                                  ref.begin() + static_cast<std::ptrdiff_t>(c - c % per + per)));
  constexpr double kTol = 1e-12;
  for (std::size_t c : active)
    if (rz[c] > kTol * kTol * rz_scale[c]) next.push_back(c);
  active = next;
  constexpr int kMaxIterations = 2000;
  int it = 0;
  for (; !active.empty() && it < kMaxIterations; ++it) {
    for (std::size_t c : active) {
      const double lam = lambda[c % lambda.size()];
      FX_PETSC(MatMult(d.K, p[c], Ap[c]));
      FX_PETSC(MatMult(d.M, p[c], w[c]));
      FX_PETSC(VecAXPY(Ap[c], -lam, w[c]));
      zero_dofs(Ap[c], d.interface_dofs);
      PetscScalar pAp;
      FX_PETSC(VecDot(p[c], Ap[c], &pAp));
      if (!(pAp > 0) && rz[c] <= kTol * kTol * rz_scale[c]) continue; // round-off: done
      if (!(pAp > 0)) {
        cleanup();
        throw Error("FFRF reduction adjoint: K - lambda M is not positive definite on the "
                    "complement of the kept fixed-interface modes (lambda " +
                        std::to_string(lam) + "): are the modes the lowest?",
                    true);
      }
      const double alpha = rz[c] / pAp;
      FX_PETSC(VecAXPY(x[c], alpha, p[c]));
      FX_PETSC(VecAXPY(r[c], -alpha, Ap[c]));
    }
    precondition(active);
    next.clear();
    for (std::size_t c : active) {
      PetscScalar rzn;
      FX_PETSC(VecDot(r[c], z[c], &rzn));
      const double beta = rzn / rz[c];
      rz[c] = rzn;
      if (std::abs(rzn) <= kTol * kTol * rz_scale[c]) continue;
      FX_PETSC(VecAYPX(p[c], beta, z[c]));
      next.push_back(c);
    }
    active = next;
  }
  cleanup();
  if (!active.empty())
    throw Error("FFRF reduction adjoint: the conjugate gradients of the fixed-interface modes "
                "did not converge in " +
                    std::to_string(kMaxIterations) +
                    " iterations (the last kept eigenvalue and the next are too close; change "
                    "reduction.modes)",
                true);
  return it;
}

/// What the stages of one reduction_adjoint call share (docs/theory.md section 10): the
/// reduction, the cotangents, and the vectors the stages hand on, in the reverse order of the
/// reduction (Psi-bar, then V-bar, then the solves' a_j).
struct AdjointWork {
  const mesh::DistributedMesh &mesh;
  const FlexibleReduction &r;
  const ReductionAdjointData &d;
  const std::vector<ReductionCotangent> &bars;
  const std::vector<Vec> &Psi;
  int n, ns, nf;
  std::size_t nr;
  PetscInt ne;
  int npe;
  bool exact;
  Vec proto = nullptr;
  std::vector<Vec> KPsi, MPsi;        ///< K Psi and M Psi (exact only)
  std::vector<std::vector<Vec>> pbar; ///< Psi-bar per response (exact only)
  std::vector<Matrix> Khat, Mhat;     ///< sym K-bar, sym M-bar per response
  bool geometric = false;             ///< step 1 runs
  std::vector<Matrix> Ghat;           ///< sym G-bar_c, response-major: [i * 6 + c]
  std::vector<Vec> uc_adjoint;        ///< a_c, response-major: [i * 6 + c]
  std::vector<Vec> vbar;              ///< V-bar', response-major: [i * n + j]
  std::vector<Vec> abar;              ///< a_j of steps 5 and 6, response-major: [i * n + j]

  AdjointWork(const mesh::DistributedMesh &mesh_, const FlexibleReduction &r_,
              const std::vector<ReductionCotangent> &bars_, BasisDerivative mode)
      : mesh(mesh_), r(r_), d(*r_.adjoint), bars(bars_), Psi(r_.basis), n(r_.size()),
        ns(d.static_modes), nf(n - ns), nr(bars_.size()), ne(mesh_.local_elements()),
        npe(mesh_.nodes_per_element()), exact(mode == BasisDerivative::Exact) {}
};

/// K Psi and M Psi, shared by all responses (only the exact basis derivative forms Psi-bar).
void basis_products(AdjointWork &w) {
  for (int k = 0; w.exact && k < w.n; ++k) {
    w.KPsi.push_back(duplicate_zero(w.proto));
    w.MPsi.push_back(duplicate_zero(w.proto));
    FX_PETSC(MatMult(w.d.K, w.Psi[static_cast<std::size_t>(k)], w.KPsi.back()));
    FX_PETSC(MatMult(w.d.M, w.Psi[static_cast<std::size_t>(k)], w.MPsi.back()));
  }
}

/// K-hat, M-hat and the reduced matrices' part of Psi-bar, 2 K Psi K-hat + 2 M Psi M-hat, on
/// top of the given full cotangent (docs/theory.md section 10, step 2).
void reduced_matrix_cotangents(AdjointWork &w) {
  // The cotangent of the basis vectors (exact only), per response.
  w.pbar.resize(w.nr);
  w.Khat.resize(w.nr);
  w.Mhat.resize(w.nr);
  for (std::size_t i = 0; i < w.nr; ++i) {
    w.Khat[i] = sym(w.bars[i].K, w.n);
    w.Mhat[i] = sym(w.bars[i].M, w.n);
    if (!w.exact) continue;
    for (int k = 0; k < w.n; ++k) {
      Vec v = duplicate_zero(w.proto);
      if (!w.bars[i].basis.empty())
        FX_PETSC(VecCopy(w.bars[i].basis[static_cast<std::size_t>(k)], v));
      // Step 2: 2 K Psi Khat + 2 M Psi Mhat.
      add_combination(v, w.KPsi, 2.0 * w.Khat[i].col(k));
      add_combination(v, w.MPsi, 2.0 * w.Mhat[i].col(k));
      w.pbar[i].push_back(v);
    }
  }
}

/// Ghosted vectors summed element by element (sharing one scatter), held open at their local
/// forms' arrays until finish().
struct GhostedSums {
  std::vector<Vec> global, local;
  std::vector<PetscScalar *> values;

  /// `count` zeroed ghosted vectors of the mesh's layout, opened for adding.
  GhostedSums(const mesh::DistributedMesh &mesh, std::size_t count) {
    for (std::size_t k = 0; k < count; ++k) {
      {
        Vec g;
        if (global.empty())
          g = fem::create_ghosted_vector(mesh);
        else
          FX_PETSC(VecDuplicate(global.front(), &g)); // shares the scatter
        global.push_back(g);
      }
      local.emplace_back();
      values.emplace_back();
      FX_PETSC(VecZeroEntries(global.back()));
      FX_PETSC(VecGhostGetLocalForm(global.back(), &local.back()));
      FX_PETSC(VecGetArray(local.back(), &values.back()));
    }
  }

  /// Closes vector k and adds its ghost entries to their owners (collective).
  void finish(std::size_t k) {
    FX_PETSC(VecRestoreArray(local[k], &values[k]));
    FX_PETSC(VecGhostRestoreLocalForm(global[k], &local[k]));
    FX_PETSC(VecGhostUpdateBegin(global[k], ADD_VALUES, SCATTER_REVERSE));
    FX_PETSC(VecGhostUpdateEnd(global[k], ADD_VALUES, SCATTER_REVERSE));
  }

  /// a[3 node + j] += factor f[3 b + j] over the nodes b of local element e.
  static void add_element(const AdjointWork &w, PetscInt e, PetscScalar *a, const double *f,
                          double factor) {
    for (int b = 0; b < w.npe; ++b) {
      const PetscInt node = w.mesh.connectivity[static_cast<std::size_t>(e * w.npe + b)];
      for (int j = 0; j < 3; ++j) a[3 * node + j] += factor * f[3 * b + j];
    }
  }
};

/// Ghat_c = sym(G-bar_c) per response and load case (zero where a response has no G-bar).
void geometric_cotangents(AdjointWork &w) {
  w.Ghat.resize(w.nr * 6);
  for (std::size_t i = 0; i < w.nr; ++i)
    for (int c = 0; c < 6; ++c)
      w.Ghat[i * 6 + static_cast<std::size_t>(c)] =
          w.bars[i].geometric.empty() ? Matrix::Zero(w.n, w.n)
                                      : sym(w.bars[i].geometric[static_cast<std::size_t>(c)], w.n);
}

/// Step 1's element terms (docs/theory.md section 10, step 1): s_hat += <Ghat_c, Psi_e^T
/// K_sigma,e(u_c) Psi_e>, the pseudo-loads u-bar_c (into `ubar`) and, exact only, Psi-bar += 2
/// K_sigma(u_c) Psi Ghat_c (into `kbar`).
void geometric_element_terms(const AdjointWork &w, GhostedSums &ubar, GhostedSums &kbar,
                             std::vector<std::vector<double>> &s_hat) {
  const std::size_t n = static_cast<std::size_t>(w.n);
  const Gathered psi(w.mesh, w.Psi), uc(w.mesh, w.d.loads.u);
  Matrix Pe, Ue, KP, Be;
  for (PetscInt e = 0; e < w.ne; ++e) {
    const fem::ElementCoords X = w.mesh.element_coordinates(e);
    psi.element(e, Pe);
    uc.element(e, Ue);
    const double se =
        w.d.factors.stiffness.empty() ? 1.0 : w.d.factors.stiffness[static_cast<std::size_t>(e)];
    for (int c = 0; c < 6; ++c) {
      const fem::ElementVector u_e = Ue.col(c);
      const fem::ElementMatrix Ks =
          fem::element_geometric_stiffness(w.mesh.type, X, w.d.material, u_e);
      KP.noalias() = Ks * Pe;
      const Matrix PKP = Pe.transpose() * KP;
      for (std::size_t i = 0; i < w.nr; ++i) {
        const Matrix &G = w.Ghat[i * 6 + static_cast<std::size_t>(c)];
        s_hat[i][static_cast<std::size_t>(e)] += G.cwiseProduct(PKP).sum();
        if (w.exact) {
          Be.noalias() = (2.0 * se) * (KP * G);
          for (int k = 0; k < w.n; ++k)
            GhostedSums::add_element(w, e, kbar.values[i * n + static_cast<std::size_t>(k)],
                                     Be.col(k).data(), 1.0);
        }
        const fem::ElementVector f =
            fem::element_geometric_stiffness_load(w.mesh.type, X, w.d.material, Pe, G);
        GhostedSums::add_element(w, e, ubar.values[i * 6 + static_cast<std::size_t>(c)], f.data(),
                                 se);
      }
    }
  }
}

/// Step 1's load solve K_ff a_c = P_f u-bar_c, all responses and load cases as one block
/// (docs/theory.md section 10, step 1); destroys the u-bar_c.
void geometric_load_solve(AdjointWork &w, GhostedSums &ubar) {
  std::vector<Vec> rhs;
  for (std::size_t k = 0; k < w.nr * 6; ++k) {
    ubar.finish(k);
    Vec b = duplicate_zero(w.proto);
    FX_PETSC(VecCopy(ubar.global[k], b));
    FX_PETSC(VecDestroy(&ubar.global[k]));
    zero_dofs(b, w.d.loads.frame_dofs);
    rhs.push_back(b);
    w.uc_adjoint.push_back(duplicate_zero(w.proto));
  }
  ClampedProblem &frame = w.d.loads.frame ? *w.d.loads.frame : *w.d.interior;
  try {
    frame.solve(rhs, w.uc_adjoint, "FFRF reduction adjoint: the geometric stiffness' load solve");
  } catch (const Error &) {
    destroy_all(rhs);
    throw;
  }
  destroy_all(rhs);
}

/// The adjoint of the geometric stiffness G_c = sym(Psi^T K_sigma(u_c) Psi) (docs/theory.md
/// section 10, step 1): Ghat, the element terms <Ghat_c, Psi_e^T K_sigma,e(u_c) Psi_e>, the
/// load solve's a_c and, exact only, Psi-bar += 2 K_sigma(u_c) Psi Ghat_c.
void geometric_stiffness_adjoint(AdjointWork &w, std::vector<std::vector<double>> &s_hat) {
  geometric_cotangents(w);
  // Element terms <Ghat, Psi_e^T K_sigma,e(u_c) Psi_e> and the pseudo-loads.
  GhostedSums ubar(w.mesh, w.nr * 6);
  // Psi-bar += 2 K_sigma(u_c) Psi Ghat_c, element by element into ghosted vectors (exact only).
  GhostedSums kbar(w.mesh, w.exact ? w.nr * static_cast<std::size_t>(w.n) : 0);
  geometric_element_terms(w, ubar, kbar, s_hat);
  geometric_load_solve(w, ubar);
  const auto n = static_cast<std::size_t>(w.n);
  for (std::size_t k = 0; k < kbar.global.size(); ++k) {
    kbar.finish(k);
    // The owned part (a ghosted vector's global form has the layout of pbar's).
    FX_PETSC(VecAXPY(w.pbar[k / n][k % n], 1.0, kbar.global[k]));
    FX_PETSC(VecDestroy(&kbar.global[k]));
  }
}

/// h_k at the owned nodes (docs/theory.md section 10, step 3): h_k,a = D-bar_k + S1-bar_k^T X_a
/// + sum_l (S2-bar_kl + S2-bar_lk^T) Psi_al, with pa the basis vectors' arrays.
void invariant_load(const AdjointWork &w, const FfrfInvariants &b, int k,
                    const std::vector<const PetscScalar *> &pa, Vec h) {
  PetscScalar *ha;
  FX_PETSC(VecGetArray(h, &ha));
  for (PetscInt a = 0; a < w.mesh.owned_nodes; ++a) {
    const Eigen::Vector3d X =
        Eigen::Map<const Eigen::Vector3d>(&w.mesh.coordinates[3 * static_cast<std::size_t>(a)]) -
        w.r.origin;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    if (b.D.size() > 0) v += b.D.col(k);
    if (!b.S1.empty()) v += b.S1[static_cast<std::size_t>(k)].transpose() * X;
    if (!b.S2.empty())
      for (int l = 0; l < w.n; ++l) {
        const Eigen::Vector3d psi(&pa[static_cast<std::size_t>(l)][3 * a]);
        v += (b.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] +
              b.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)].transpose()) *
             psi;
      }
    for (int j = 0; j < 3; ++j) ha[3 * a + j] = v(j);
  }
  FX_PETSC(VecRestoreArray(h, &ha));
}

/// Step 3: the invariants' Psi-bar, Psi-bar_k += M h_k (docs/theory.md section 10, step 3).
void invariants_basis_cotangent(AdjointWork &w) {
  const auto n = static_cast<std::size_t>(w.n);
  Vec h = duplicate_zero(w.proto), Mh = duplicate_zero(w.proto);
  for (std::size_t i = 0; i < w.nr; ++i) {
    const FfrfInvariants &b = w.bars[i].invariants;
    if (b.D.size() == 0 && b.S1.empty() && b.S2.empty()) continue;
    std::vector<const PetscScalar *> pa(n);
    for (std::size_t k = 0; k < n; ++k) FX_PETSC(VecGetArrayRead(w.Psi[k], &pa[k]));
    for (int k = 0; k < w.n; ++k) {
      invariant_load(w, b, k, pa, h);
      FX_PETSC(MatMult(w.d.M, h, Mh));
      FX_PETSC(VecAXPY(w.pbar[i][static_cast<std::size_t>(k)], 1.0, Mh));
    }
    for (std::size_t k = 0; k < n; ++k) FX_PETSC(VecRestoreArrayRead(w.Psi[k], &pa[k]));
  }
  FX_PETSC(VecDestroy(&h));
  FX_PETSC(VecDestroy(&Mh));
}

/// V-bar'_j = sum_k Psi-bar_k Y_jk for response i (appended to vbar).
void append_vbar(AdjointWork &w, std::size_t i) {
  for (int j = 0; j < w.n; ++j) {
    Vec v = duplicate_zero(w.proto);
    add_combination(v, w.pbar[i], w.d.Y.row(j).transpose());
    w.vbar.push_back(v);
  }
}

/// The M-Procrustes gauge's orthonormalization and maps for response i (docs/theory.md section
/// 10, step 4): C = B + Psi^T Psi-bar with B = Y^T Y-bar, M-hat -= 1/2 sym C (the element term
/// -1/2 <S, Psi_e^T M_e Psi_e>) and Psi-bar -= M Psi C.
void orthonormal_gauge_adjoint(AdjointWork &w, std::size_t i) {
  const int n = w.n;
  const ReductionAdjointData &d = w.d;
  std::vector<PetscScalar> dots(static_cast<std::size_t>(n));
  Matrix Ybar = Matrix::Zero(n, n);
  for (std::size_t k = 0; k < d.T.size(); ++k) {
    if (k < w.bars[i].translation.size() && w.bars[i].translation[k].size() > 0)
      Ybar += d.T[k].transpose() * w.bars[i].translation[k];
    if (k < w.bars[i].rotation.size() && w.bars[i].rotation[k].size() > 0)
      Ybar += d.R[k].transpose() * w.bars[i].rotation[k];
  }
  Matrix C = d.Y.transpose() * Ybar; // B, then + Psi^T Psi-bar
  for (int k = 0; k < n; ++k) {
    FX_PETSC(VecMDot(w.pbar[i][static_cast<std::size_t>(k)], n, w.Psi.data(), dots.data()));
    for (int m = 0; m < n; ++m) C(m, k) += dots[static_cast<std::size_t>(m)];
  }
  w.Mhat[i] -= 0.25 * (C + C.transpose());
  for (int k = 0; k < n; ++k)
    add_combination(w.pbar[i][static_cast<std::size_t>(k)], w.MPsi, -C.col(k));
}

/// Step 4: the orthonormalization and the maps (docs/theory.md section 10, step 4), forming
/// V-bar' and destroying Psi-bar.
void orthonormalization_adjoint(AdjointWork &w, BasisGauge gauge) {
  // Step 4: the orthonormalization and the maps: V-bar = (Psi-bar - M Psi (Psi^T Psi-bar + B))
  // Y^T, and the element term -1/2 <S, Psi_e^T M_e Psi_e> (into Mhat). Frozen coordinates:
  // Psi = V' Y_0, so V-bar = Psi-bar Y_0^T.
  if (w.exact && w.n > 0 && gauge == BasisGauge::FrozenCoordinates) {
    for (std::size_t i = 0; i < w.nr; ++i) append_vbar(w, i);
  } else if (w.exact && w.n > 0) {
    for (std::size_t i = 0; i < w.nr; ++i) {
      orthonormal_gauge_adjoint(w, i);
      append_vbar(w, i);
    }
  }
  for (auto &p : w.pbar) destroy_all(p);
}

/// Step 5: the static modes, K_ii a_j = (V-bar'_j)_i, one block solve (docs/theory.md section
/// 10, step 5).
void static_mode_adjoint(AdjointWork &w) {
  const auto n = static_cast<std::size_t>(w.n);
  std::vector<Vec> rhs, out;
  for (std::size_t i = 0; i < w.nr; ++i)
    for (int j = 0; j < w.ns; ++j) {
      rhs.push_back(w.vbar[i * n + static_cast<std::size_t>(j)]);
      out.push_back(w.abar[i * n + static_cast<std::size_t>(j)]);
    }
  if (!rhs.empty()) w.d.interior->solve(rhs, out, "FFRF reduction adjoint: the static-mode solve");
}

/// Step 6: the fixed-interface modes, (K_ii - lambda_j M_ii) a_j = P V-bar'_j on range Q
/// (docs/theory.md section 10, step 6). Returns the conjugate gradients' iteration count.
int fixed_mode_adjoint(AdjointWork &w) {
  const auto n = static_cast<std::size_t>(w.n);
  const ReductionAdjointData &d = w.d;
  std::vector<Vec> Phi(d.vectors.begin() + w.ns, d.vectors.end()), MPhi;
  for (Vec phi : Phi) {
    MPhi.push_back(duplicate_zero(w.proto));
    FX_PETSC(MatMult(d.M, phi, MPhi.back()));
    zero_dofs(MPhi.back(), d.interface_dofs);
  }
  std::vector<double> lambda(d.fixed_eigenvalues.begin(), d.fixed_eigenvalues.end());
  std::vector<PetscScalar> dots(static_cast<std::size_t>(w.nf));
  std::vector<Vec> rhs, out, unprojected;
  for (std::size_t i = 0; i < w.nr; ++i)
    for (int j = w.ns; j < w.n; ++j) {
      Vec b = w.vbar[i * n + static_cast<std::size_t>(j)];
      unprojected.push_back(duplicate_zero(w.proto));
      FX_PETSC(VecCopy(b, unprojected.back()));
      // P b = b - M Phi (Phi^T b).
      FX_PETSC(VecMDot(b, w.nf, Phi.data(), dots.data()));
      for (auto &v : dots) v = -v;
      FX_PETSC(VecMAXPY(b, w.nf, dots.data(), MPhi.data()));
      rhs.push_back(b);
      out.push_back(w.abar[i * n + static_cast<std::size_t>(j)]);
    }
  int iterations = 0;
  try {
    iterations = fixed_mode_solves(d, Phi, MPhi, lambda, rhs, unprojected, out);
  } catch (const Error &) {
    destroy_all(unprojected);
    destroy_all(MPhi);
    destroy_all(w.vbar);
    destroy_all(w.abar);
    throw;
  }
  destroy_all(unprojected);
  destroy_all(MPhi);
  return iterations;
}

/// One element's data for the element terms: K_e, M_e (unit factors), the gathered vectors and
/// the node positions in the frame with the load cases' w_c = B_c X.
struct ElementTerms {
  fem::ElementMatrix Ke, Me;
  Matrix Pe, Ve, Ae, Ue, Ace;
  Matrix PKP, PMP;
  Matrix Xe, We;
};

/// The invariants' element term for response i: wh += sum_ab m_ab phi(a, b) (docs/theory.md
/// section 10, step 3).
void invariant_element_term(const AdjointWork &w, const ElementTerms &t, std::size_t i,
                            double &wh) {
  const int n = w.n, npe = w.npe;
  const Matrix &Pe = t.Pe, &Xe = t.Xe;
  // The invariants: sum_ab m_ab phi(a, b) (docs/theory.md section 10, step 3).
  const FfrfInvariants &b = w.bars[i].invariants;
  Matrix g = Matrix::Zero(3 * npe, std::max(n, 1)); // g_a,k per node a
  const bool modal = b.D.size() > 0 || !b.S1.empty() || !b.S2.empty();
  if (modal)
    for (int a = 0; a < npe; ++a)
      for (int k = 0; k < n; ++k) {
        Eigen::Vector3d v = Eigen::Vector3d::Zero();
        if (b.D.size() > 0) v += b.D.col(k);
        if (!b.S1.empty()) v += b.S1[static_cast<std::size_t>(k)].transpose() * Xe.col(a);
        if (!b.S2.empty())
          for (int l = 0; l < n; ++l)
            v += b.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)].transpose() *
                 Pe.block<3, 1>(3 * a, l);
        g.block<3, 1>(3 * a, k) = v;
      }
  for (int a = 0; a < npe; ++a)
    for (int bb = 0; bb < npe; ++bb) {
      const double m = t.Me(3 * a, 3 * bb);
      if (m == 0.0) continue;
      double phi = b.mass + b.d0.dot(Xe.col(bb)) + Xe.col(a).dot(b.S0 * Xe.col(bb));
      if (modal)
        for (int k = 0; k < n; ++k) phi += Pe.block<3, 1>(3 * bb, k).dot(g.block<3, 1>(3 * a, k));
      wh += m * phi;
    }
}

/// The element's s_hat and w_hat terms of response i (docs/theory.md section 10): K_r and M_r
/// (with step 4's S), steps 5 and 6, step 1's load solve, then the invariants of step 3.
void response_element_terms(const AdjointWork &w, const ElementTerms &t, std::size_t i, double &sh,
                            double &wh) {
  const int n = w.n;
  sh = w.Khat[i].cwiseProduct(t.PKP).sum();
  wh = w.Mhat[i].cwiseProduct(t.PMP).sum();
  if (w.exact)
    for (int j = 0; j < n; ++j) {
      const auto col =
          static_cast<Eigen::Index>(i * static_cast<std::size_t>(n) + static_cast<std::size_t>(j));
      sh -= t.Ae.col(col).dot(t.Ke * t.Ve.col(j));
      if (j >= w.ns)
        wh += w.d.fixed_eigenvalues[static_cast<std::size_t>(j - w.ns)] *
              t.Ae.col(col).dot(t.Me * t.Ve.col(j));
    }
  if (w.geometric)
    for (int c = 0; c < 6; ++c) {
      const auto col = static_cast<Eigen::Index>(i * 6 + static_cast<std::size_t>(c));
      sh -= t.Ace.col(col).dot(t.Ke * t.Ue.col(c));
      wh += t.Ace.col(col).dot(t.Me * t.We.col(c));
    }
  invariant_element_term(w, t, i, wh);
}

/// The element terms of every stage (docs/theory.md section 10): K_r and M_r (with step 4's S),
/// the invariants, steps 1, 5 and 6, into s_hat and w_hat.
void element_terms(const AdjointWork &w, std::vector<std::vector<double>> &s_hat,
                   std::vector<std::vector<double>> &w_hat) {
  const ReductionAdjointData &d = w.d;
  const int npe = w.npe;
  const Gathered psi(w.mesh, w.Psi), vectors(w.mesh, w.exact ? d.vectors : std::vector<Vec>{}),
      adj(w.mesh, w.abar), uc(w.mesh, w.geometric ? d.loads.u : std::vector<Vec>{}),
      ac(w.mesh, w.uc_adjoint);
  ElementTerms t;
  for (PetscInt e = 0; e < w.ne; ++e) {
    const fem::ElementCoords X = w.mesh.element_coordinates(e);
    t.Ke = fem::element_stiffness(w.mesh.type, X, d.material, 1.0);
    t.Me = fem::element_mass(w.mesh.type, X, d.material.density);
    psi.element(e, t.Pe);
    const Matrix KP = t.Ke * t.Pe, MP = t.Me * t.Pe;
    t.PKP = t.Pe.transpose() * KP;
    t.PMP = t.Pe.transpose() * MP;
    if (w.exact) {
      vectors.element(e, t.Ve);
      adj.element(e, t.Ae);
    }
    if (w.geometric) {
      uc.element(e, t.Ue);
      ac.element(e, t.Ace);
    }
    // Node positions in the frame, and the load cases' w_c = B_c X.
    t.Xe.resize(3, npe);
    t.We.resize(3 * npe, 6);
    for (int a = 0; a < npe; ++a) t.Xe.col(a) = X.row(a).transpose() - w.r.origin;
    if (w.geometric)
      for (int c = 0; c < 6; ++c) {
        const Eigen::Matrix3d B = centrifugal_load_matrix(c);
        for (int a = 0; a < npe; ++a) t.We.block<3, 1>(3 * a, c) = B * t.Xe.col(a);
      }
    const auto ee = static_cast<std::size_t>(e);
    for (std::size_t i = 0; i < w.nr; ++i) {
      double sh = 0, wh = 0;
      response_element_terms(w, t, i, sh, wh);
      s_hat[i][ee] += sh;
      w_hat[i][ee] += wh;
    }
  }
}

} // namespace

ReductionAdjointStats reduction_adjoint(const mesh::DistributedMesh &mesh,
                                        const FlexibleReduction &r,
                                        const std::vector<ReductionCotangent> &bars,
                                        BasisDerivative mode,
                                        std::vector<std::vector<double>> &s_hat,
                                        std::vector<std::vector<double>> &w_hat, BasisGauge gauge) {
  LogScope log("FxReductionAdjoint");
  const double t0 = wall_time();
  if (!r.adjoint)
    throw Error("FFRF reduction adjoint: the reduction kept no adjoint data (not a design body)",
                true);
  AdjointWork w(mesh, r, bars, mode);
  const ReductionAdjointData &d = w.d;
  const int n = w.n;
  s_hat.assign(w.nr, std::vector<double>(static_cast<std::size_t>(w.ne), 0.0));
  w_hat.assign(w.nr, std::vector<double>(static_cast<std::size_t>(w.ne), 0.0));
  ReductionAdjointStats stats;
  if (w.nr == 0) return stats;
  FX_PETSC(MatCreateVecs(d.K, &w.proto, nullptr));

  basis_products(w);
  reduced_matrix_cotangents(w); // step 2's Psi-bar
  // Step 1: the geometric stiffness. Ghat per response and load case.
  w.geometric =
      !r.geometric.empty() && !d.loads.u.empty() && n > 0 &&
      std::any_of(bars.begin(), bars.end(), [](const auto &b) { return !b.geometric.empty(); });
  if (w.geometric) geometric_stiffness_adjoint(w, s_hat);
  if (w.exact && n > 0) invariants_basis_cotangent(w); // step 3
  orthonormalization_adjoint(w, gauge);                // step 4

  // Steps 5 and 6: the static modes and the fixed-interface modes.
  if (!w.vbar.empty()) {
    for (Vec v : w.vbar) zero_dofs(v, d.interface_dofs);
    for (std::size_t i = 0; i < w.nr; ++i)
      for (int j = 0; j < n; ++j) w.abar.push_back(duplicate_zero(w.proto));
    static_mode_adjoint(w);
    if (w.nf > 0) stats.cg_iterations = fixed_mode_adjoint(w);
  }
  destroy_all(w.vbar);

  // The element terms: K_r and M_r (with step 4's S), the invariants, steps 1, 5 and 6.
  element_terms(w, s_hat, w_hat);
  destroy_all(w.abar);
  destroy_all(w.uc_adjoint);
  destroy_all(w.KPsi);
  destroy_all(w.MPsi);
  FX_PETSC(VecDestroy(&w.proto));
  stats.seconds = wall_time() - t0;
  return stats;
}

} // namespace flexopt::reduce
