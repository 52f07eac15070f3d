#pragma once
/// \file Dense matrix products through the BLAS that PETSc links (OpenBLAS on Debian: its
/// kernels are chosen for the CPU at run time, where Eigen's own follow the compiler's target).
/// For the large products of the dynamic stress responses (docs/theory.md 10.3).
#include <Eigen/Dense>

namespace flexopt {

/// C = alpha op(A) op(B) + beta C, op(X) = X or X^T (`transpose_a`, `transpose_b`); the sizes
/// must agree (C is not resized).
void gemm(bool transpose_a, bool transpose_b, double alpha,
          const Eigen::Ref<const Eigen::MatrixXd> &A, const Eigen::Ref<const Eigen::MatrixXd> &B,
          double beta, Eigen::Ref<Eigen::MatrixXd> C);

} // namespace flexopt
