#include "flexopt/core/dense_blas.hpp"

#include "flexopt/core/error.hpp"

#include <petscblaslapack.h>

namespace flexopt {

void gemm(bool transpose_a, bool transpose_b, double alpha,
          const Eigen::Ref<const Eigen::MatrixXd> &A, const Eigen::Ref<const Eigen::MatrixXd> &B,
          double beta, Eigen::Ref<Eigen::MatrixXd> C) {
  const Eigen::Index m = C.rows(), n = C.cols(), k = transpose_a ? A.rows() : A.cols();
  if ((transpose_a ? A.cols() : A.rows()) != m || (transpose_b ? B.rows() : B.cols()) != n ||
      (transpose_b ? B.cols() : B.rows()) != k)
    throw Error("gemm: the sizes of A, B and C do not agree");
  if (m == 0 || n == 0) return;
  if (k == 0) {
    C *= beta;
    return;
  }
  const PetscBLASInt bm = static_cast<PetscBLASInt>(m), bn = static_cast<PetscBLASInt>(n),
                     bk = static_cast<PetscBLASInt>(k);
  const PetscBLASInt lda = static_cast<PetscBLASInt>(A.outerStride()),
                     ldb = static_cast<PetscBLASInt>(B.outerStride()),
                     ldc = static_cast<PetscBLASInt>(C.outerStride());
  BLASgemm_(transpose_a ? "T" : "N", transpose_b ? "T" : "N", &bm, &bn, &bk, &alpha, A.data(), &lda,
            B.data(), &ldb, &beta, C.data(), &ldc);
}

} // namespace flexopt
