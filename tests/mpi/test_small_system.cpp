// The small part of the distributed backend (dynamics::add_newton_system, docs/theory.md
// sections 6.4 and 8.2): the scaled Newton matrix of a rigid chain of 4 links added by rank 0
// into a PETSc matrix over all ranks, at offsets, is the derivative of -rhs along a Newton update
// x = [dq; dlambda^] (q += dq, v += gamma' dq, acc += beta' dq, lambda += beta' dlambda^):
//   A x = -(rhs(s + eps x) - rhs(s - eps x)) / (2 eps)
// (central differences, step 1e-6; tolerance 1e-6 of |A x|). On 1 and 2 ranks.
#include "../unit/dynamics_checks.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <gtest/gtest.h>
#include <petscmat.h>

using namespace flexopt;
using dynamics::Vector;

TEST(SmallSystem, PetscNewtonMatrixIsTheDerivativeOfTheResidual) {
  Vector q0;
  const dynamics::Mechanism mech = test_support::chain(4, q0);
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
  Vec all;
  VecScatter toall;
  VecScatterCreateToAll(AX, &toall, &all);
  VecScatterBegin(toall, AX, all, INSERT_VALUES, SCATTER_FORWARD);
  VecScatterEnd(toall, AX, all, INSERT_VALUES, SCATTER_FORWARD);
  const PetscScalar *ax;
  VecGetArrayRead(all, &ax);
  Vector Ax(n + m);
  for (int k = 0; k < n + m; ++k) Ax(k) = ax[k < n ? c0 + k : r0 + (k - n)];
  double outside = 0; // nothing outside the two ranges
  for (PetscInt k = 0; k < N; ++k)
    if (!((k >= c0 && k < c0 + n) || (k >= r0 && k < r0 + m))) outside += std::abs(ax[k]);
  VecRestoreArrayRead(all, &ax);

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
      Mat dummy;
      MatCreateSeqAIJ(PETSC_COMM_SELF, n + m, n + m, n + m, nullptr, &dummy);
      dynamics::add_newton_system(mech, t, bp, gp, dummy, 0, n, r);
      MatDestroy(&dummy);
      return r;
    };
    const Vector fd = -(rhs_at(1) - rhs_at(-1)) / (2 * eps);
    const double scale = Ax.cwiseAbs().maxCoeff();
    EXPECT_LT((Ax - fd).cwiseAbs().maxCoeff(), 1e-6 * scale);
    EXPECT_GT(scale, 1.0);
  }
  EXPECT_EQ(outside, 0.0);
  VecScatterDestroy(&toall);
  VecDestroy(&all);
  VecDestroy(&X);
  VecDestroy(&AX);
  MatDestroy(&A);
}
