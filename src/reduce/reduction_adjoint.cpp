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
  const ReductionAdjointData &d = *r.adjoint;
  const int n = r.size();
  const int ns = d.static_modes, nf = n - ns;
  const std::size_t nr = bars.size();
  const PetscInt ne = mesh.local_elements();
  const int npe = mesh.nodes_per_element();
  const bool exact = mode == BasisDerivative::Exact;
  s_hat.assign(nr, std::vector<double>(static_cast<std::size_t>(ne), 0.0));
  w_hat.assign(nr, std::vector<double>(static_cast<std::size_t>(ne), 0.0));
  ReductionAdjointStats stats;
  if (nr == 0) return stats;
  const std::vector<Vec> &Psi = r.basis;
  Vec proto;
  FX_PETSC(MatCreateVecs(d.K, &proto, nullptr));

  // K Psi and M Psi, shared by all responses (only the exact basis derivative forms Psi-bar).
  std::vector<Vec> KPsi, MPsi;
  for (int k = 0; exact && k < n; ++k) {
    KPsi.push_back(duplicate_zero(proto));
    MPsi.push_back(duplicate_zero(proto));
    FX_PETSC(MatMult(d.K, Psi[static_cast<std::size_t>(k)], KPsi.back()));
    FX_PETSC(MatMult(d.M, Psi[static_cast<std::size_t>(k)], MPsi.back()));
  }
  // The cotangent of the basis vectors (exact only), per response.
  std::vector<std::vector<Vec>> pbar(nr);
  std::vector<Matrix> Khat(nr), Mhat(nr);
  for (std::size_t i = 0; i < nr; ++i) {
    Khat[i] = sym(bars[i].K, n);
    Mhat[i] = sym(bars[i].M, n);
    if (!exact) continue;
    for (int k = 0; k < n; ++k) {
      Vec v = duplicate_zero(proto);
      if (!bars[i].basis.empty()) FX_PETSC(VecCopy(bars[i].basis[static_cast<std::size_t>(k)], v));
      // Step 2: 2 K Psi Khat + 2 M Psi Mhat.
      add_combination(v, KPsi, 2.0 * Khat[i].col(k));
      add_combination(v, MPsi, 2.0 * Mhat[i].col(k));
      pbar[i].push_back(v);
    }
  }

  // Step 1: the geometric stiffness. Ghat per response and load case.
  const bool geometric =
      !r.geometric.empty() && !d.loads.u.empty() && n > 0 &&
      std::any_of(bars.begin(), bars.end(), [](const auto &b) { return !b.geometric.empty(); });
  std::vector<Vec> uc_adjoint; // a_c, response-major: [i * 6 + c]
  std::vector<Matrix> Ghat(nr * 6);
  if (geometric) {
    for (std::size_t i = 0; i < nr; ++i)
      for (int c = 0; c < 6; ++c)
        Ghat[i * 6 + static_cast<std::size_t>(c)] =
            bars[i].geometric.empty() ? Matrix::Zero(n, n)
                                      : sym(bars[i].geometric[static_cast<std::size_t>(c)], n);
    // Element terms <Ghat, Psi_e^T K_sigma,e(u_c) Psi_e> and the pseudo-loads.
    std::vector<Vec> ubar(nr * 6), ubar_local(nr * 6);
    std::vector<PetscScalar *> ua(nr * 6);
    for (std::size_t k = 0; k < nr * 6; ++k) {
      if (k == 0)
        ubar[k] = fem::create_ghosted_vector(mesh);
      else
        FX_PETSC(VecDuplicate(ubar[0], &ubar[k])); // shares the scatter
      FX_PETSC(VecZeroEntries(ubar[k]));
      FX_PETSC(VecGhostGetLocalForm(ubar[k], &ubar_local[k]));
      FX_PETSC(VecGetArray(ubar_local[k], &ua[k]));
    }
    // Psi-bar += 2 K_sigma(u_c) Psi Ghat_c, element by element into ghosted vectors (exact only).
    std::vector<Vec> kbar, kbar_local;
    std::vector<PetscScalar *> ka;
    if (exact)
      for (std::size_t k = 0; k < nr * static_cast<std::size_t>(n); ++k) {
        {
          Vec g;
          if (kbar.empty())
            g = fem::create_ghosted_vector(mesh);
          else
            FX_PETSC(VecDuplicate(kbar.front(), &g)); // shares the scatter
          kbar.push_back(g);
        }
        kbar_local.emplace_back();
        ka.emplace_back();
        FX_PETSC(VecZeroEntries(kbar.back()));
        FX_PETSC(VecGhostGetLocalForm(kbar.back(), &kbar_local.back()));
        FX_PETSC(VecGetArray(kbar_local.back(), &ka.back()));
      }
    {
      const Gathered psi(mesh, Psi), uc(mesh, d.loads.u);
      Matrix Pe, Ue, KP, Be;
      for (PetscInt e = 0; e < ne; ++e) {
        const fem::ElementCoords X = mesh.element_coordinates(e);
        psi.element(e, Pe);
        uc.element(e, Ue);
        const double se =
            d.factors.stiffness.empty() ? 1.0 : d.factors.stiffness[static_cast<std::size_t>(e)];
        for (int c = 0; c < 6; ++c) {
          const fem::ElementVector u_e = Ue.col(c);
          const fem::ElementMatrix Ks =
              fem::element_geometric_stiffness(mesh.type, X, d.material, u_e);
          KP.noalias() = Ks * Pe;
          const Matrix PKP = Pe.transpose() * KP;
          for (std::size_t i = 0; i < nr; ++i) {
            const Matrix &G = Ghat[i * 6 + static_cast<std::size_t>(c)];
            s_hat[i][static_cast<std::size_t>(e)] += G.cwiseProduct(PKP).sum();
            if (exact) {
              Be.noalias() = (2.0 * se) * (KP * G);
              for (int k = 0; k < n; ++k) {
                PetscScalar *a = ka[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(k)];
                for (int b = 0; b < npe; ++b) {
                  const PetscInt node = mesh.connectivity[static_cast<std::size_t>(e * npe + b)];
                  for (int j = 0; j < 3; ++j) a[3 * node + j] += Be(3 * b + j, k);
                }
              }
            }
            const fem::ElementVector f =
                fem::element_geometric_stiffness_load(mesh.type, X, d.material, Pe, G);
            PetscScalar *a = ua[i * 6 + static_cast<std::size_t>(c)];
            for (int b = 0; b < npe; ++b) {
              const PetscInt node = mesh.connectivity[static_cast<std::size_t>(e * npe + b)];
              for (int j = 0; j < 3; ++j) a[3 * node + j] += se * f[3 * b + j];
            }
          }
        }
      }
    }
    std::vector<Vec> rhs;
    for (std::size_t k = 0; k < nr * 6; ++k) {
      FX_PETSC(VecRestoreArray(ubar_local[k], &ua[k]));
      FX_PETSC(VecGhostRestoreLocalForm(ubar[k], &ubar_local[k]));
      FX_PETSC(VecGhostUpdateBegin(ubar[k], ADD_VALUES, SCATTER_REVERSE));
      FX_PETSC(VecGhostUpdateEnd(ubar[k], ADD_VALUES, SCATTER_REVERSE));
      Vec b = duplicate_zero(proto);
      FX_PETSC(VecCopy(ubar[k], b));
      FX_PETSC(VecDestroy(&ubar[k]));
      zero_dofs(b, d.loads.frame_dofs);
      rhs.push_back(b);
      uc_adjoint.push_back(duplicate_zero(proto));
    }
    ClampedProblem &frame = d.loads.frame ? *d.loads.frame : *d.interior;
    try {
      frame.solve(rhs, uc_adjoint, "FFRF reduction adjoint: the geometric stiffness' load solve");
    } catch (const Error &) {
      destroy_all(rhs);
      throw;
    }
    destroy_all(rhs);
    for (std::size_t k = 0; k < kbar.size(); ++k) {
      FX_PETSC(VecRestoreArray(kbar_local[k], &ka[k]));
      FX_PETSC(VecGhostRestoreLocalForm(kbar[k], &kbar_local[k]));
      FX_PETSC(VecGhostUpdateBegin(kbar[k], ADD_VALUES, SCATTER_REVERSE));
      FX_PETSC(VecGhostUpdateEnd(kbar[k], ADD_VALUES, SCATTER_REVERSE));
      // The owned part (a ghosted vector's global form has the layout of pbar's).
      FX_PETSC(VecAXPY(pbar[k / static_cast<std::size_t>(n)][k % static_cast<std::size_t>(n)], 1.0,
                       kbar[k]));
      FX_PETSC(VecDestroy(&kbar[k]));
    }
  }

  // Step 3: the invariants' Psi-bar: M h_k.
  if (exact && n > 0) {
    Vec h = duplicate_zero(proto), Mh = duplicate_zero(proto);
    for (std::size_t i = 0; i < nr; ++i) {
      const FfrfInvariants &b = bars[i].invariants;
      if (b.D.size() == 0 && b.S1.empty() && b.S2.empty()) continue;
      std::vector<const PetscScalar *> pa(static_cast<std::size_t>(n));
      for (int k = 0; k < n; ++k)
        FX_PETSC(
            VecGetArrayRead(Psi[static_cast<std::size_t>(k)], &pa[static_cast<std::size_t>(k)]));
      for (int k = 0; k < n; ++k) {
        PetscScalar *ha;
        FX_PETSC(VecGetArray(h, &ha));
        for (PetscInt a = 0; a < mesh.owned_nodes; ++a) {
          const Eigen::Vector3d X = Eigen::Map<const Eigen::Vector3d>(
                                        &mesh.coordinates[3 * static_cast<std::size_t>(a)]) -
                                    r.origin;
          Eigen::Vector3d v = Eigen::Vector3d::Zero();
          if (b.D.size() > 0) v += b.D.col(k);
          if (!b.S1.empty()) v += b.S1[static_cast<std::size_t>(k)].transpose() * X;
          if (!b.S2.empty())
            for (int l = 0; l < n; ++l) {
              const Eigen::Vector3d psi(&pa[static_cast<std::size_t>(l)][3 * a]);
              v += (b.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] +
                    b.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)].transpose()) *
                   psi;
            }
          for (int j = 0; j < 3; ++j) ha[3 * a + j] = v(j);
        }
        FX_PETSC(VecRestoreArray(h, &ha));
        FX_PETSC(MatMult(d.M, h, Mh));
        FX_PETSC(VecAXPY(pbar[i][static_cast<std::size_t>(k)], 1.0, Mh));
      }
      for (int k = 0; k < n; ++k)
        FX_PETSC(VecRestoreArrayRead(Psi[static_cast<std::size_t>(k)],
                                     &pa[static_cast<std::size_t>(k)]));
    }
    FX_PETSC(VecDestroy(&h));
    FX_PETSC(VecDestroy(&Mh));
  }

  // Step 4: the orthonormalization and the maps: V-bar = (Psi-bar - M Psi (Psi^T Psi-bar + B))
  // Y^T, and the element term -1/2 <S, Psi_e^T M_e Psi_e> (into Mhat). Frozen coordinates:
  // Psi = V' Y_0, so V-bar = Psi-bar Y_0^T.
  std::vector<Vec> vbar; // response-major: [i * n + j]
  if (exact && n > 0 && gauge == BasisGauge::FrozenCoordinates) {
    for (std::size_t i = 0; i < nr; ++i)
      for (int j = 0; j < n; ++j) {
        Vec v = duplicate_zero(proto);
        add_combination(v, pbar[i], d.Y.row(j).transpose());
        vbar.push_back(v);
      }
  } else if (exact && n > 0) {
    std::vector<PetscScalar> dots(static_cast<std::size_t>(n));
    for (std::size_t i = 0; i < nr; ++i) {
      Matrix Ybar = Matrix::Zero(n, n);
      for (std::size_t k = 0; k < d.T.size(); ++k) {
        if (k < bars[i].translation.size() && bars[i].translation[k].size() > 0)
          Ybar += d.T[k].transpose() * bars[i].translation[k];
        if (k < bars[i].rotation.size() && bars[i].rotation[k].size() > 0)
          Ybar += d.R[k].transpose() * bars[i].rotation[k];
      }
      Matrix C = d.Y.transpose() * Ybar; // B, then + Psi^T Psi-bar
      for (int k = 0; k < n; ++k) {
        FX_PETSC(VecMDot(pbar[i][static_cast<std::size_t>(k)], n, Psi.data(), dots.data()));
        for (int m = 0; m < n; ++m) C(m, k) += dots[static_cast<std::size_t>(m)];
      }
      Mhat[i] -= 0.25 * (C + C.transpose());
      for (int k = 0; k < n; ++k)
        add_combination(pbar[i][static_cast<std::size_t>(k)], MPsi, -C.col(k));
      for (int j = 0; j < n; ++j) {
        Vec v = duplicate_zero(proto);
        add_combination(v, pbar[i], d.Y.row(j).transpose());
        vbar.push_back(v);
      }
    }
  }
  for (auto &p : pbar) destroy_all(p);

  // Steps 5 and 6: the static modes and the fixed-interface modes.
  std::vector<Vec> abar; // response-major: [i * n + j]
  if (!vbar.empty()) {
    for (Vec v : vbar) zero_dofs(v, d.interface_dofs);
    std::vector<Vec> rhs, out;
    for (std::size_t i = 0; i < nr; ++i)
      for (int j = 0; j < n; ++j) abar.push_back(duplicate_zero(proto));
    for (std::size_t i = 0; i < nr; ++i)
      for (int j = 0; j < ns; ++j) {
        rhs.push_back(vbar[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)]);
        out.push_back(abar[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)]);
      }
    if (!rhs.empty()) d.interior->solve(rhs, out, "FFRF reduction adjoint: the static-mode solve");
    if (nf > 0) {
      std::vector<Vec> Phi(d.vectors.begin() + ns, d.vectors.end()), MPhi;
      for (Vec phi : Phi) {
        MPhi.push_back(duplicate_zero(proto));
        FX_PETSC(MatMult(d.M, phi, MPhi.back()));
        zero_dofs(MPhi.back(), d.interface_dofs);
      }
      std::vector<double> lambda(d.fixed_eigenvalues.begin(), d.fixed_eigenvalues.end());
      std::vector<PetscScalar> dots(static_cast<std::size_t>(nf));
      rhs.clear();
      out.clear();
      std::vector<Vec> unprojected;
      for (std::size_t i = 0; i < nr; ++i)
        for (int j = ns; j < n; ++j) {
          Vec b = vbar[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)];
          unprojected.push_back(duplicate_zero(proto));
          FX_PETSC(VecCopy(b, unprojected.back()));
          // P b = b - M Phi (Phi^T b).
          FX_PETSC(VecMDot(b, nf, Phi.data(), dots.data()));
          for (auto &v : dots) v = -v;
          FX_PETSC(VecMAXPY(b, nf, dots.data(), MPhi.data()));
          rhs.push_back(b);
          out.push_back(abar[i * static_cast<std::size_t>(n) + static_cast<std::size_t>(j)]);
        }
      try {
        stats.cg_iterations = fixed_mode_solves(d, Phi, MPhi, lambda, rhs, unprojected, out);
      } catch (const Error &) {
        destroy_all(unprojected);
        destroy_all(MPhi);
        destroy_all(vbar);
        destroy_all(abar);
        throw;
      }
      destroy_all(unprojected);
      destroy_all(MPhi);
    }
  }
  destroy_all(vbar);

  // The element terms: K_r and M_r (with step 4's S), the invariants, steps 1, 5 and 6.
  {
    const Gathered psi(mesh, Psi), vectors(mesh, exact ? d.vectors : std::vector<Vec>{}),
        adj(mesh, abar), uc(mesh, geometric ? d.loads.u : std::vector<Vec>{}), ac(mesh, uc_adjoint);
    Matrix Pe, Ve, Ae, Ue, Ace;
    for (PetscInt e = 0; e < ne; ++e) {
      const fem::ElementCoords X = mesh.element_coordinates(e);
      const fem::ElementMatrix Ke = fem::element_stiffness(mesh.type, X, d.material, 1.0);
      const fem::ElementMatrix Me = fem::element_mass(mesh.type, X, d.material.density);
      psi.element(e, Pe);
      const Matrix KP = Ke * Pe, MP = Me * Pe;
      const Matrix PKP = Pe.transpose() * KP, PMP = Pe.transpose() * MP;
      if (exact) {
        vectors.element(e, Ve);
        adj.element(e, Ae);
      }
      if (geometric) {
        uc.element(e, Ue);
        ac.element(e, Ace);
      }
      // Node positions in the frame, and the load cases' w_c = B_c X.
      Matrix Xe(3, npe), We(3 * npe, 6);
      for (int a = 0; a < npe; ++a) Xe.col(a) = X.row(a).transpose() - r.origin;
      if (geometric)
        for (int c = 0; c < 6; ++c) {
          const Eigen::Matrix3d B = centrifugal_load_matrix(c);
          for (int a = 0; a < npe; ++a) We.block<3, 1>(3 * a, c) = B * Xe.col(a);
        }
      const auto ee = static_cast<std::size_t>(e);
      for (std::size_t i = 0; i < nr; ++i) {
        double sh = Khat[i].cwiseProduct(PKP).sum();
        double wh = Mhat[i].cwiseProduct(PMP).sum();
        if (exact)
          for (int j = 0; j < n; ++j) {
            const auto col = static_cast<Eigen::Index>(i * static_cast<std::size_t>(n) +
                                                       static_cast<std::size_t>(j));
            sh -= Ae.col(col).dot(Ke * Ve.col(j));
            if (j >= ns)
              wh += d.fixed_eigenvalues[static_cast<std::size_t>(j - ns)] *
                    Ae.col(col).dot(Me * Ve.col(j));
          }
        if (geometric)
          for (int c = 0; c < 6; ++c) {
            const auto col = static_cast<Eigen::Index>(i * 6 + static_cast<std::size_t>(c));
            sh -= Ace.col(col).dot(Ke * Ue.col(c));
            wh += Ace.col(col).dot(Me * We.col(c));
          }
        // The invariants: sum_ab m_ab phi(a, b) (docs/theory.md section 10, step 3).
        const FfrfInvariants &b = bars[i].invariants;
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
            const double m = Me(3 * a, 3 * bb);
            if (m == 0.0) continue;
            double phi = b.mass + b.d0.dot(Xe.col(bb)) + Xe.col(a).dot(b.S0 * Xe.col(bb));
            if (modal)
              for (int k = 0; k < n; ++k)
                phi += Pe.block<3, 1>(3 * bb, k).dot(g.block<3, 1>(3 * a, k));
            wh += m * phi;
          }
        s_hat[i][ee] += sh;
        w_hat[i][ee] += wh;
      }
    }
  }
  destroy_all(abar);
  destroy_all(uc_adjoint);
  destroy_all(KPsi);
  destroy_all(MPsi);
  FX_PETSC(VecDestroy(&proto));
  stats.seconds = wall_time() - t0;
  return stats;
}

} // namespace flexopt::reduce
