// The small part of the distributed backend and the ties (dynamics::add_newton_system,
// dynamics::add_ties; docs/theory.md
// sections 6.4 and 8.2): the scaled Newton matrix of a rigid chain of 4 links added by rank 0
// into a PETSc matrix over all ranks, at offsets, is the derivative of -rhs along a Newton update
// x = [dq; dlambda^] (q += dq, v += gamma' dq, acc += beta' dq, lambda += beta' dlambda^):
//   A x = -(rhs(s + eps x) - rhs(s - eps x)) / (2 eps)
// (central differences, step 1e-6; tolerance 1e-6 of |A x|). On 1 and 2 ranks.
#include "../unit/dynamics_checks.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/ties.hpp"
#include "test_meshes.hpp"

#include <gtest/gtest.h>
#include <petscmat.h>

using namespace flexopt;
using dynamics::Vector;

TEST(SmallSystem, PetscNewtonMatrixIsTheDerivativeOfTheResidual) {
  Vector q0;
  const dynamics::Mechanism mech = ::test_support::chain(4, q0);
  const int n = mech.coordinates(), m = mech.constraints();
  // A moving, not converged state (every term of the matrix matters).
  dynamics::State s;
  s.t = 0.3;
  s.q = q0 + 0.05 * Vector::Random(n);
  for (std::size_t b = 0; b < mech.bodies.size(); ++b)
    s.q.segment<4>(7 * static_cast<int>(b) + 3).normalize();
  s.v = Vector::Random(n);
  s.acc = Vector::Random(n);
  s.a = Vector::Random(n);
  s.lambda = 10 * Vector::Random(m);
  const double bp = 3.2e5, gp = 1.7e3; // h ~ 2 ms
  // The system at offsets 5 (coordinates) and 5 + n + 3 (rows) of a matrix of size N.
  const PetscInt c0 = 5, r0 = 5 + n + 3, N = r0 + m + 4;
  Mat A;
  MatCreateAIJ(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, N, N, n + m, nullptr, n + m, nullptr,
               &A);
  Vector rhs;
  const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
  if (root) dynamics::add_newton_system(mech, s, bp, gp, A, c0, r0, rhs);
  MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY);
  MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY);
  // A x for a random x, gathered on every rank.
  const Vector x = Vector::Random(n + m);
  Vec X, AX;
  MatCreateVecs(A, &X, &AX);
  VecSet(X, 0.0);
  if (root)
    for (int k = 0; k < n + m; ++k)
      VecSetValue(X, k < n ? c0 + k : r0 + (k - n), x(k), INSERT_VALUES);
  VecAssemblyBegin(X);
  VecAssemblyEnd(X);
  MatMult(A, X, AX);
  const Vector ax = flexopt::test_support::gather_all(AX);
  Vector Ax(n + m);
  for (int k = 0; k < n + m; ++k) Ax(k) = ax(k < n ? c0 + k : r0 + (k - n));
  double outside = 0; // nothing outside the two ranges
  for (PetscInt k = 0; k < N; ++k)
    if (!((k >= c0 && k < c0 + n) || (k >= r0 && k < r0 + m))) outside += std::abs(ax(k));

  if (root) {
    const double eps = 1e-6;
    auto rhs_at = [&](double sign) {
      dynamics::State t = s;
      const Vector dq = sign * eps * x.head(n);
      t.q += dq;
      t.v += gp * dq;
      t.acc += bp * dq;
      t.lambda += sign * eps * bp * x.tail(m);
      Vector r;
      dynamics::newton_system_rhs(mech, t, bp, r);
      return r;
    };
    const Vector fd = -(rhs_at(1) - rhs_at(-1)) / (2 * eps);
    // The right-hand side alone (kept-matrix iterations) is the same.
    Vector rhs_only;
    dynamics::newton_system_rhs(mech, s, bp, rhs_only);
    EXPECT_LT((rhs_only - rhs).cwiseAbs().maxCoeff(), 1e-14 * rhs.cwiseAbs().maxCoeff());
    const double scale = Ax.cwiseAbs().maxCoeff();
    EXPECT_LT((Ax - fd).cwiseAbs().maxCoeff(), 1e-6 * scale);
    EXPECT_GT(scale, 1.0);
  }
  EXPECT_EQ(outside, 0.0);
  VecDestroy(&X);
  VecDestroy(&AX);
  MatDestroy(&A);
}

// The RBE2 ties of surface nodes to an interface node (dynamics::add_ties, docs/theory.md
// section 8.2), added by rank 0 into a matrix over all ranks: again A d = the central difference
// of -rhs along d = [dx; dr; dp; dlambda^] (lambda += beta' dlambda^), and -rhs on the tie rows
// is Phi_j = x_j - r - A(p) s_j.
TEST(SmallSystem, TieRowsAreTheDerivativeOfTheResidual) {
  const int nt = 5;
  const double bp = 2.5e5;
  dynamics::TieSet ties;
  for (int j = 0; j < nt; ++j) {
    ties.x_dof.push_back(3 * j);
    ties.s.push_back(bodies::Vec3::Random());
  }
  ties.coord0 = 3 * nt;
  ties.row0 = 3 * nt + 7;
  const PetscInt N = 6 * nt + 7;
  Vector z = Vector::Random(N); // [x; r; p; lambda]
  z.segment<4>(3 * nt + 3).normalize();
  // The ties' right-hand side alone (no matrix) at [x; r; p; lambda] on this rank.
  auto tie_rhs = [&](const Vector &zz) {
    Vec rv;
    VecCreateSeq(PETSC_COMM_SELF, N, &rv);
    VecSet(rv, 0.0);
    dynamics::add_ties(ties, zz.data(), zz.segment<3>(3 * nt),
                       bodies::Vec4(zz.segment<4>(3 * nt + 3)), zz.data() + 3 * nt + 7, bp, nullptr,
                       rv);
    VecAssemblyBegin(rv);
    VecAssemblyEnd(rv);
    const Vector out = flexopt::test_support::gather_all(rv);
    VecDestroy(&rv);
    return out;
  };
  const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
  Mat A;
  MatCreateAIJ(PETSC_COMM_WORLD, PETSC_DECIDE, PETSC_DECIDE, N, N, N, nullptr, N, nullptr, &A);
  Vec rhs, D, AD;
  MatCreateVecs(A, &D, &rhs);
  VecDuplicate(rhs, &AD);
  VecSet(rhs, 0.0);
  const double *lam = z.data() + 3 * nt + 7;
  double violation = 0;
  if (root)
    violation = dynamics::add_ties(ties, z.data(), z.segment<3>(3 * nt),
                                   bodies::Vec4(z.segment<4>(3 * nt + 3)), lam, bp, A, rhs);
  MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY);
  MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY);
  VecAssemblyBegin(rhs);
  VecAssemblyEnd(rhs);
  const Vector d = Vector::Random(N);
  VecSet(D, 0.0);
  if (root)
    for (PetscInt k = 0; k < N; ++k) VecSetValue(D, k, d(k), INSERT_VALUES);
  VecAssemblyBegin(D);
  VecAssemblyEnd(D);
  MatMult(A, D, AD);
  const Vector Ad = flexopt::test_support::gather_all(AD),
               r0 = flexopt::test_support::gather_all(rhs);
  if (root) {
    // The tie rows of -rhs are Phi_j.
    for (int j = 0; j < nt; ++j) {
      const bodies::Vec3 phi = z.segment<3>(3 * j) - z.segment<3>(3 * nt) -
                               bodies::rotation(bodies::Vec4(z.segment<4>(3 * nt + 3))) *
                                   ties.s[static_cast<std::size_t>(j)];
      EXPECT_LT((-r0.segment<3>(ties.row0 + 3 * j) - phi).cwiseAbs().maxCoeff(), 1e-15);
    }
    EXPECT_GT(violation, 0.1);
    const double eps = 1e-6;
    auto rhs_at = [&](double sign) {
      Vector zz = z;
      zz.head(3 * nt + 7) += sign * eps * d.head(3 * nt + 7);
      zz.tail(3 * nt) += sign * eps * bp * d.tail(3 * nt);
      return tie_rhs(zz);
    };
    const Vector fd = -(rhs_at(1) - rhs_at(-1)) / (2 * eps);
    EXPECT_LT((Ad - fd).cwiseAbs().maxCoeff(), 1e-6 * Ad.cwiseAbs().maxCoeff());
    // Without a matrix: the same right-hand side.
    EXPECT_LT((tie_rhs(z) - r0).cwiseAbs().maxCoeff(), 1e-14 * r0.cwiseAbs().maxCoeff());
  }
  VecDestroy(&D);
  VecDestroy(&AD);
  VecDestroy(&rhs);
  MatDestroy(&A);
}

// The ties' velocity term: along q(t) = q0 + v t + a t^2 / 2 (x, r, p), the second central
// difference of Phi_j(q(t)) at t = 0 equals Phi_j,q a - gamma_j (step 1e-4: truncation ~1e-8 of
// the terms, round-off 1e-16 / 1e-8).
TEST(SmallSystem, TieAccelerationTerm) {
  dynamics::TieSet ties;
  ties.x_dof = {0};
  ties.s = {bodies::Vec3(0.3, -0.2, 0.5)};
  const Vector q0 = Vector::Random(10), v = Vector::Random(10), a = Vector::Random(10);
  auto phi = [&](double t) {
    const Vector q = q0 + v * t + 0.5 * a * t * t;
    return bodies::Vec3(q.head<3>() - q.segment<3>(3) -
                        bodies::rotation(bodies::Vec4(q.segment<4>(6))) * ties.s[0]);
  };
  const double h = 1e-4;
  const bodies::Vec3 second = (phi(h) - 2 * phi(0) + phi(-h)) / (h * h);
  bodies::Vec3 gamma;
  dynamics::tie_accelerations(ties, bodies::Vec4(v.segment<4>(6)), gamma.data());
  const bodies::Vec3 phiq_a = a.head<3>() - a.segment<3>(3) -
                              bodies::rotate_jacobian(bodies::Vec4(q0.segment<4>(6)), ties.s[0]) *
                                  bodies::Vec4(a.segment<4>(6));
  EXPECT_LT((second - (phiq_a - gamma)).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_GT(gamma.norm(), 0.1); // the term matters
}
