// The adjoint of the FFRF reduction (docs/theory.md section 10) against finite differences of
// the reduction itself, on 1 and 2 ranks. The steel beam (meshes/beam.geo, Tet10) carries a
// random density rho_e in [0.6, 1] per element (stiffness factor rho^3, mass factor rho), and
// the reduction is differentiated along a random direction delta of the densities. For each
// reduced quantity q (basis, K_r, M_r, every invariant, the interface maps, the geometric
// stiffness) and a random cotangent qbar, J = <qbar, q> is differenced with a fourth-order
// central stencil of four more reductions and compared with sum_e (s_hat_e ds_e + w_hat_e dw_e).
// The reduced quantities are defined up to an orthogonal change of the modal coordinates (the
// eigenvector gauge: signs, order, rotations in repeated eigenvalues); every perturbed reduction
// is aligned to the unperturbed one by the orthogonal polar factor U of Psi_0^T M_0 Psi_h
// (Psi -> Psi U^T, K_r -> U K_r U^T, D -> D U^T, ...), the gauge in which the adjoint is
// written. Relative agreement required: 1e-7 (the figure).
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "flexopt/reduce/field_projection.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/reduction_adjoint.hpp"
#include "test_meshes.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>
#include <random>
#include <string>

using namespace flexopt;

namespace {

using Matrix = Eigen::MatrixXd;

/// A number in [0, 1) from an element's Gmsh tag (the same on every rank count).
double hashed(std::size_t tag, double salt) {
  const double x = std::sin(static_cast<double>(tag) * 12.9898 + salt) * 43758.5453;
  return x - std::floor(x);
}

struct Scene {
  std::vector<std::string> interfaces;
  int modes = 3;
  bool stiffening = false;
  reduce::FrameCondition frame = reduce::FrameCondition::Clamped;
};

/// A density rho_e in [0.6, 1] and a direction delta_e in [-1, 1] per local element, from its
/// Gmsh tag (the same design on every rank count).
void random_densities(const mesh::DistributedMesh &m, std::vector<double> &rho,
                      std::vector<double> &delta) {
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const std::size_t tag = m.element_tags[static_cast<std::size_t>(e)];
    rho.push_back(0.6 + 0.4 * hashed(tag, 0.0));
    delta.push_back(2 * hashed(tag, 1.0) - 1);
  }
}

/// The reduction at densities rho + t delta.
std::unique_ptr<reduce::FlexibleReduction> reduce_at(const mesh::DistributedMesh &m, const Scene &s,
                                                     const std::vector<double> &rho,
                                                     const std::vector<double> &delta, double t) {
  reduce::ElementFactors f;
  for (std::size_t e = 0; e < rho.size(); ++e) {
    const double r = rho[e] + t * delta[e];
    f.stiffness.push_back(r * r * r);
    f.mass.push_back(r);
  }
  auto out = std::make_unique<reduce::FlexibleReduction>();
  reduce::reduce_flexible_body(m, fem::IsotropicMaterial{2.1e11, 0.3, 7850}, s.interfaces, s.modes,
                               s.stiffening, *out, s.frame, &f);
  return out;
}

/// The orthogonal polar factor of Psi_0^T M_0 Psi_h.
Matrix alignment(const reduce::FlexibleReduction &r0, const reduce::FlexibleReduction &rh) {
  const int n = r0.size();
  Matrix B(n, n);
  Vec w;
  VecDuplicate(r0.basis[0], &w);
  for (int l = 0; l < n; ++l) {
    MatMult(r0.adjoint->M, rh.basis[static_cast<std::size_t>(l)], w);
    for (int k = 0; k < n; ++k) VecDot(w, r0.basis[static_cast<std::size_t>(k)], &B(k, l));
  }
  VecDestroy(&w);
  Eigen::JacobiSVD<Matrix> svd(B, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

/// The frozen Craig-Bampton coordinates of r0 for rh: Psi_h G with G = Y_h^-1 diag(I, C) Y_0,
/// C = (Phi_0^T M_0 Phi_h)^-1 aligning the fixed-interface modes inside their span (the part
/// the adjoint leaves out as a change of coordinates). Returned as U = G^T, for pairing().
Matrix frozen_alignment(const reduce::FlexibleReduction &r0, const reduce::FlexibleReduction &rh) {
  const auto &d0 = *r0.adjoint, &dh = *rh.adjoint;
  const int n = r0.size(), ns = d0.static_modes, nf = n - ns;
  Matrix B(nf, nf);
  Vec w;
  VecDuplicate(r0.basis[0], &w);
  for (int l = 0; l < nf; ++l) {
    MatMult(d0.M, dh.vectors[static_cast<std::size_t>(ns + l)], w);
    for (int k = 0; k < nf; ++k) VecDot(w, d0.vectors[static_cast<std::size_t>(ns + k)], &B(k, l));
  }
  VecDestroy(&w);
  Matrix E = Matrix::Identity(n, n);
  E.bottomRightCorner(nf, nf) = B.inverse();
  const Matrix G = dh.Y.inverse() * E * d0.Y;
  return G.transpose();
}

/// <bar, q(rh)> with rh aligned to r0 by U (Psi -> Psi U^T).
double pairing(const reduce::ReductionCotangent &bar, const reduce::FlexibleReduction &rh,
               const Matrix &U) {
  const int n = rh.size();
  double J = 0;
  if (bar.K.size()) J += bar.K.cwiseProduct(U * rh.K * U.transpose()).sum();
  if (bar.M.size()) J += bar.M.cwiseProduct(U * rh.M * U.transpose()).sum();
  const reduce::FfrfInvariants &b = bar.invariants, &q = rh.invariants;
  J += b.mass * q.mass + b.d0.dot(q.d0) + b.S0.cwiseProduct(q.S0).sum();
  if (b.D.size()) J += b.D.cwiseProduct(q.D * U.transpose()).sum();
  for (int k = 0; k < static_cast<int>(b.S1.size()); ++k)
    for (int l = 0; l < n; ++l)
      J += U(k, l) *
           b.S1[static_cast<std::size_t>(k)].cwiseProduct(q.S1[static_cast<std::size_t>(l)]).sum();
  for (int k = 0; k < static_cast<int>(b.S2.size()); ++k)
    for (int l = 0; l < n; ++l)
      for (int a = 0; a < n; ++a)
        for (int c = 0; c < n; ++c)
          J += U(k, a) * U(l, c) *
               b.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)]
                   .cwiseProduct(q.S2[static_cast<std::size_t>(a)][static_cast<std::size_t>(c)])
                   .sum();
  for (std::size_t i = 0; i < bar.translation.size(); ++i)
    J += bar.translation[i].cwiseProduct(rh.translation[i] * U.transpose()).sum();
  for (std::size_t i = 0; i < bar.rotation.size(); ++i)
    J += bar.rotation[i].cwiseProduct(rh.rotation[i] * U.transpose()).sum();
  for (std::size_t c = 0; c < bar.geometric.size(); ++c)
    J += bar.geometric[c].cwiseProduct(U * rh.geometric[c] * U.transpose()).sum();
  for (std::size_t k = 0; k < bar.basis.size(); ++k)
    for (int l = 0; l < n; ++l) {
      PetscScalar dot;
      VecDot(bar.basis[k], rh.basis[static_cast<std::size_t>(l)], &dot);
      J += U(static_cast<Eigen::Index>(k), l) * dot;
    }
  return J;
}

/// One cotangent per reduced quantity, random (a fixed seed: the same on every rank).
std::vector<std::pair<std::string, reduce::ReductionCotangent>>
cotangents(const reduce::FlexibleReduction &r, std::mt19937 &gen) {
  const int n = r.size();
  std::uniform_real_distribution<double> u(-1, 1);
  auto random = [&](int rows, int cols) {
    Matrix A(rows, cols);
    for (int j = 0; j < cols; ++j)
      for (int i = 0; i < rows; ++i) A(i, j) = u(gen);
    return A;
  };
  std::vector<std::pair<std::string, reduce::ReductionCotangent>> out;
  auto add = [&](const std::string &name, auto &&set) {
    reduce::ReductionCotangent b;
    set(b);
    out.emplace_back(name, std::move(b));
  };
  const double kscale = 1.0 / r.K.cwiseAbs().maxCoeff();
  add("K_r", [&](auto &b) { b.K = kscale * random(n, n); });
  add("M_r", [&](auto &b) { b.M = random(n, n); });
  add("mass", [&](auto &b) { b.invariants.mass = 1.0; });
  add("d0", [&](auto &b) { b.invariants.d0 = random(3, 1); });
  add("S0", [&](auto &b) { b.invariants.S0 = random(3, 3); });
  add("D", [&](auto &b) { b.invariants.D = random(3, n); });
  add("S1", [&](auto &b) {
    for (int k = 0; k < n; ++k) b.invariants.S1.push_back(random(3, 3));
  });
  add("S2", [&](auto &b) {
    b.invariants.S2.assign(static_cast<std::size_t>(n), {});
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l)
        b.invariants.S2[static_cast<std::size_t>(k)].push_back(random(3, 3));
  });
  // A single clamped interface has zero maps at every design: nothing to differentiate.
  bool maps = false;
  for (const auto &T : r.translation) maps = maps || T.cwiseAbs().maxCoeff() > 0;
  for (const auto &R : r.rotation) maps = maps || R.cwiseAbs().maxCoeff() > 0;
  if (maps)
    add("translation", [&](auto &b) {
      for (std::size_t i = 0; i < r.translation.size(); ++i) b.translation.push_back(random(3, n));
    });
  if (maps)
    add("rotation", [&](auto &b) {
      for (std::size_t i = 0; i < r.rotation.size(); ++i) b.rotation.push_back(random(3, n));
    });
  if (!r.geometric.empty())
    add("geometric", [&](auto &b) {
      for (std::size_t c = 0; c < 6; ++c) b.geometric.push_back(kscale * random(n, n));
    });
  return out;
}

void check_reduction_adjoint(const Scene &s, double tolerance,
                             reduce::BasisGauge gauge = reduce::BasisGauge::Orthonormal) {
  const bool frozen = gauge == reduce::BasisGauge::FrozenCoordinates;
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const PetscInt ne = m.local_elements();
  std::vector<double> rho, delta;
  random_densities(m, rho, delta);
  const auto r0 = reduce_at(m, s, rho, delta, 0.0);
  const int n = r0->size();
  ASSERT_GT(n, 0);
  std::mt19937 gen(7);
  auto bars = cotangents(*r0, gen);
  // In frozen coordinates the interface maps are constant: nothing to compare.
  if (frozen)
    bars.erase(std::remove_if(
                   bars.begin(), bars.end(),
                   [](const auto &b) { return b.first == "translation" || b.first == "rotation"; }),
               bars.end());
  // A basis cotangent: smooth random fields (a function of the node position).
  std::vector<Vec> basis_bar;
  {
    reduce::ReductionCotangent b;
    for (int k = 0; k < n; ++k) {
      Vec v;
      VecDuplicate(r0->basis[0], &v);
      PetscScalar *a;
      VecGetArray(v, &a);
      for (PetscInt i = 0; i < m.owned_nodes; ++i)
        for (int c = 0; c < 3; ++c)
          a[3 * i + c] = std::sin(3.0 * m.coordinates[3 * static_cast<std::size_t>(i)] + k + c) *
                         std::cos(20.0 * m.coordinates[3 * static_cast<std::size_t>(i) + 1] - c);
      VecRestoreArray(v, &a);
      basis_bar.push_back(v);
    }
    b.basis = basis_bar;
    bars.emplace_back("basis", std::move(b));
  }
  std::vector<reduce::ReductionCotangent> list;
  for (const auto &b : bars) list.push_back(b.second);
  std::vector<std::vector<double>> s_hat, w_hat;
  const auto stats =
      reduce::reduction_adjoint(m, *r0, list, reduce::BasisDerivative::Exact, s_hat, w_hat, gauge);
  // Fourth-order central differences along delta.
  const double h = 1e-3;
  const double steps[4] = {-2 * h, -h, h, 2 * h};
  const double weights[4] = {1.0 / 12, -8.0 / 12, 8.0 / 12, -1.0 / 12};
  std::vector<double> fd(bars.size(), 0.0), J0(bars.size(), 0.0);
  const Matrix I = Matrix::Identity(n, n);
  for (std::size_t q = 0; q < bars.size(); ++q) J0[q] = pairing(bars[q].second, *r0, I);
  for (int k = 0; k < 4; ++k) {
    const auto rh = reduce_at(m, s, rho, delta, steps[k]);
    const Matrix U = frozen ? frozen_alignment(*r0, *rh) : alignment(*r0, *rh);
    for (std::size_t q = 0; q < bars.size(); ++q)
      fd[q] += weights[k] * pairing(bars[q].second, *rh, U) / h;
  }
  for (std::size_t q = 0; q < bars.size(); ++q) {
    double local = 0;
    for (PetscInt e = 0; e < ne; ++e) {
      const auto i = static_cast<std::size_t>(e);
      local += s_hat[q][i] * 3 * rho[i] * rho[i] * delta[i] + w_hat[q][i] * delta[i];
    }
    double adj = 0;
    MPI_Allreduce(&local, &adj, 1, MPI_DOUBLE, MPI_SUM, m.comm);
    const double scale = std::max(std::abs(adj), std::abs(J0[q]));
    const double err = std::abs(adj - fd[q]) / scale;
    if (comm_rank(m.comm) == 0)
      std::printf("%-12s adjoint %+.12e  FD %+.12e  |J| %.3e  rel. error %.2e\n",
                  bars[q].first.c_str(), adj, fd[q], std::abs(J0[q]), err);
    EXPECT_LT(err, tolerance) << bars[q].first;
  }
  if (comm_rank(m.comm) == 0)
    std::printf("fixed-interface modes' conjugate gradients: %d iterations\n", stats.cg_iterations);
  for (Vec &v : basis_bar) VecDestroy(&v);
}

/// The initial elastic coordinates of a design body (docs/theory.md section 10.2):
/// zeta = Psi^T M(w) u of a smooth field u, in frozen coordinates zeta_F = G^-1 zeta_h (Psi_h G
/// the frozen basis, U = G^T), paired with a random cotangent and differenced like the
/// quantities above against project_field_adjoint composed with reduction_adjoint.
void check_projection_adjoint(const Scene &s, double tolerance) {
  auto m = test_support::load_test_mesh("beam.geo", 0.025, 2);
  const PetscInt ne = m.local_elements();
  std::vector<double> rho, delta;
  random_densities(m, rho, delta);
  const double density = 7850;
  const reduce::Field u = [](const Eigen::Vector3d &x) {
    return Eigen::Vector3d(1e-4 * x.x() * x.x(), 2e-3 * std::sin(3 * x.x()) * (1 + x.y()),
                           -1e-3 * x.x() * x.z());
  };
  // Each reduction projects with its own mass matrix, M(rho + t delta).
  auto zeta_at = [&](const reduce::FlexibleReduction &r) {
    return reduce::project_field(m, density, r, u).coordinates;
  };
  const auto r0 = reduce_at(m, s, rho, delta, 0.0);
  const int n = r0->size();
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> uni(-1, 1);
  Eigen::VectorXd zbar(n);
  for (int k = 0; k < n; ++k) zbar(k) = uni(gen);
  const Eigen::VectorXd zeta0 = zeta_at(*r0);
  reduce::ReductionCotangent bar;
  for (int k = 0; k < n; ++k) {
    Vec v;
    VecDuplicate(r0->basis[0], &v);
    VecZeroEntries(v);
    bar.basis.push_back(v);
  }
  std::vector<double> w_projection;
  reduce::project_field_adjoint(m, density, *r0, u, zeta0, zbar, bar.basis, w_projection);
  std::vector<std::vector<double>> s_hat, w_hat;
  reduce::reduction_adjoint(m, *r0, {bar}, reduce::BasisDerivative::Exact, s_hat, w_hat,
                            reduce::BasisGauge::FrozenCoordinates);
  const double h = 1e-3;
  const double steps[4] = {-2 * h, -h, h, 2 * h};
  const double weights[4] = {1.0 / 12, -8.0 / 12, 8.0 / 12, -1.0 / 12};
  double fd = 0;
  for (int k = 0; k < 4; ++k) {
    const auto rh = reduce_at(m, s, rho, delta, steps[k]);
    const Matrix U = frozen_alignment(*r0, *rh);
    const Eigen::VectorXd zF = U.transpose().lu().solve(zeta_at(*rh));
    fd += weights[k] * zbar.dot(zF) / h;
  }
  double local = 0;
  for (PetscInt e = 0; e < ne; ++e) {
    const auto i = static_cast<std::size_t>(e);
    local +=
        s_hat[0][i] * 3 * rho[i] * rho[i] * delta[i] + (w_hat[0][i] + w_projection[i]) * delta[i];
  }
  double adj = 0;
  MPI_Allreduce(&local, &adj, 1, MPI_DOUBLE, MPI_SUM, m.comm);
  const double err = std::abs(adj - fd) / std::max(std::abs(adj), std::abs(zbar.dot(zeta0)));
  if (comm_rank(m.comm) == 0)
    std::printf("projection   adjoint %+.12e  FD %+.12e  |J| %.3e  rel. error %.2e\n", adj, fd,
                std::abs(zbar.dot(zeta0)), err);
  EXPECT_LT(err, tolerance);
  for (Vec &v : bar.basis) VecDestroy(&v);
}

} // namespace

// The frame clamped at the only interface, 4 modes, with the centrifugal geometric stiffness
// (which shares the interior factorization).
TEST(ReductionAdjoint, ClampedFrameWithGeometricStiffening) {
  check_reduction_adjoint(Scene{{"clamp"}, 4, true, reduce::FrameCondition::Clamped}, 1e-7);
}

// Two interfaces in the chord frame: 6 static modes and 3 fixed-interface modes.
TEST(ReductionAdjoint, ChordFrameWithStaticModes) {
  check_reduction_adjoint(Scene{{"clamp", "tip"}, 3, false, reduce::FrameCondition::Chord}, 1e-7);
}

// Two interfaces, the frame clamped at the first, with geometric stiffening (its own
// factorization of the frame-clamped stiffness).
TEST(ReductionAdjoint, TwoInterfacesWithGeometricStiffening) {
  check_reduction_adjoint(Scene{{"clamp", "tip"}, 2, true, reduce::FrameCondition::Clamped}, 1e-7);
}

// The same two scenes in frozen Craig-Bampton coordinates (Y held, the maps constant), the gauge
// of the dynamic adjoint: every perturbed reduction expressed in r0's coordinates, its
// fixed-interface modes aligned inside their span.
TEST(ReductionAdjoint, FrozenCoordinatesChordFrame) {
  check_reduction_adjoint(Scene{{"clamp", "tip"}, 3, false, reduce::FrameCondition::Chord}, 1e-7,
                          reduce::BasisGauge::FrozenCoordinates);
}

TEST(ReductionAdjoint, FrozenCoordinatesWithGeometricStiffening) {
  check_reduction_adjoint(Scene{{"clamp", "tip"}, 2, true, reduce::FrameCondition::Clamped}, 1e-7,
                          reduce::BasisGauge::FrozenCoordinates);
}

// The initial elastic coordinates' projection (section 10.2) in frozen coordinates, on the chord
// frame (as the slider-crank's rod) and with one clamped interface and stiffening.
TEST(ReductionAdjoint, ProjectionInFrozenCoordinatesChordFrame) {
  check_projection_adjoint(Scene{{"clamp", "tip"}, 3, false, reduce::FrameCondition::Chord}, 1e-7);
}

TEST(ReductionAdjoint, ProjectionInFrozenCoordinatesClamped) {
  check_projection_adjoint(Scene{{"clamp"}, 4, true, reduce::FrameCondition::Clamped}, 1e-7);
}

// The cut (docs/theory.md section 10): the square box clamped at one end (a y <-> z symmetric
// structured Hex8 mesh) has its two lowest bending modes at one eigenvalue. One mode splits the
// pair, where the reduced model is not differentiable: check_modal_cut refuses it with both
// frequencies; two modes keep the pair together and pass.
TEST(ReductionAdjoint, SplitPairAtTheCutIsRefused) {
  auto m = test_support::load_test_mesh("box_2x1x1_hex.geo");
  reduce::ElementFactors f;
  f.stiffness.assign(static_cast<std::size_t>(m.local_elements()), 0.5);
  f.mass.assign(static_cast<std::size_t>(m.local_elements()), 0.8);
  const fem::IsotropicMaterial steel{2.1e11, 0.3, 7850};
  reduce::FlexibleReduction one, two;
  reduce::reduce_flexible_body(m, steel, {"clamp"}, 1, false, one, reduce::FrameCondition::Clamped,
                               &f);
  try {
    reduce::check_modal_cut(one, "box", m.comm);
    ADD_FAILURE() << "a split pair was not refused";
  } catch (const Error &e) {
    EXPECT_NE(std::string(e.what()).find("repeated eigenvalue"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'box'"), std::string::npos) << e.what();
  }
  reduce::reduce_flexible_body(m, steel, {"clamp"}, 2, false, two, reduce::FrameCondition::Clamped,
                               &f);
  EXPECT_NO_THROW(reduce::check_modal_cut(two, "box", m.comm));
}

namespace {

/// Stiffness factors 1 - 0.6 (2 |c_k - 0.5|)^2 of the box's elements, c the centroid: the outer
/// fibres of direction k (1: y, 2: z) softened, so the box bends in that direction most easily.
reduce::ElementFactors softened_fibres(const mesh::DistributedMesh &m, int k) {
  reduce::ElementFactors f;
  for (PetscInt e = 0; e < m.local_elements(); ++e) {
    const fem::ElementCoords X = m.element_coordinates(e);
    const double c = X.col(k).mean(), r = 2 * std::abs(c - 0.5);
    f.stiffness.push_back(1 - 0.6 * r * r);
    f.mass.push_back(0.8);
  }
  return f;
}

/// |Psi_a^T M_a Psi_b| for one-mode reductions (1: the same mode, 0: M-orthogonal ones).
double mode_overlap(const reduce::FlexibleReduction &a, const reduce::FlexibleReduction &b) {
  Vec w;
  VecDuplicate(a.basis[0], &w);
  MatMult(a.adjoint->M, a.basis[0], w);
  PetscScalar d;
  VecDot(w, b.basis[0], &d);
  VecDestroy(&w);
  return std::abs(d);
}

} // namespace

// Reuse across designs (docs/theory.md section 10, "Reuse across designs"): the reduction at a
// design B made from design A's interior problem (its symbolic factorization kept, the
// eigensolver restarted from the same vector) equals a fresh reduction at B, across a crossing.
// The square box clamped at one end has a y- and a z-bending mode at one eigenvalue; softening
// the outer y fibres (A) puts the y mode lowest, softening the z fibres (B) the z mode. With one
// kept mode, the kept mode of A leaves the kept set at B: the reused problem must give B's own
// lowest mode (overlap 1 with the fresh one, far from A's), its eigenvalue, its reduced matrices
// and the same adjoint sensitivities, to the eigensolver's tolerance.
TEST(ReductionReuse, SameAsFreshAcrossACrossing) {
  auto m = test_support::load_test_mesh("box_2x1x1_hex.geo");
  const fem::IsotropicMaterial steel{2.1e11, 0.3, 7850};
  const reduce::ElementFactors a = softened_fibres(m, 1), b = softened_fibres(m, 2);
  reduce::FlexibleReduction ra, fresh, reused;
  const auto clamped = reduce::FrameCondition::Clamped;
  reduce::reduce_flexible_body(m, steel, {"clamp"}, 1, false, ra, clamped, &a);
  reduce::reduce_flexible_body(m, steel, {"clamp"}, 1, false, fresh, clamped, &b);
  reduce::reduce_flexible_body(m, steel, {"clamp"}, 1, false, reused, clamped, &b,
                               ra.adjoint->interior);
  ASSERT_EQ(reused.adjoint->interior, ra.adjoint->interior)
      << "the interior problem was not reused";
  const double la = ra.adjoint->fixed_eigenvalues[0], lb = fresh.adjoint->fixed_eigenvalues[0];
  const double lr = reused.adjoint->fixed_eigenvalues[0];
  // The crossing happened: A's mode is (nearly) M-orthogonal to B's.
  const double across = mode_overlap(fresh, ra);
  EXPECT_LT(across, 0.1);
  EXPECT_NEAR(lr, lb, 1e-10 * lb) << "A's eigenvalue " << la;
  EXPECT_NEAR(mode_overlap(fresh, reused), 1.0, 1e-9);
  EXPECT_NEAR(reused.K(0, 0), fresh.K(0, 0), 1e-9 * std::abs(fresh.K(0, 0)));
  EXPECT_NEAR(reused.M(0, 0), fresh.M(0, 0), 1e-9 * std::abs(fresh.M(0, 0)));
  // The same sensitivities of K_r + 0.5 M_r (sign-free for one mode).
  auto sensitivities = [&](const reduce::FlexibleReduction &r) {
    reduce::ReductionCotangent bar;
    bar.K = Matrix::Constant(1, 1, 1.0);
    bar.M = Matrix::Constant(1, 1, 0.5);
    std::vector<std::vector<double>> s_hat, w_hat;
    reduce::reduction_adjoint(m, r, {bar}, reduce::BasisDerivative::Exact, s_hat, w_hat);
    std::vector<double> all = s_hat[0];
    all.insert(all.end(), w_hat[0].begin(), w_hat[0].end());
    return all;
  };
  const std::vector<double> sf = sensitivities(fresh), sr = sensitivities(reused);
  double diff = 0, size = 0;
  for (std::size_t i = 0; i < sf.size(); ++i) {
    diff = std::max(diff, std::abs(sf[i] - sr[i]));
    size = std::max(size, std::abs(sf[i]));
  }
  MPI_Allreduce(MPI_IN_PLACE, &diff, 1, MPI_DOUBLE, MPI_MAX, m.comm);
  MPI_Allreduce(MPI_IN_PLACE, &size, 1, MPI_DOUBLE, MPI_MAX, m.comm);
  if (comm_rank(m.comm) == 0)
    std::printf("reuse across a crossing: lambda A %.10e, B fresh %.10e, B reused %.10e; "
                "overlap(A, B) %.2e; sensitivities differ by %.2e of %.3e\n",
                la, lb, lr, across, diff, size);
  EXPECT_LT(diff, 1e-8 * size);
}
