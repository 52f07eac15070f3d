#pragma once
/// \file The stiffness operator of a Hex8 mesh applied element by element, without its matrix:
/// y = K x with K = sum_e factor_e K_e^0 (K_e^0 the unit-modulus element matrix, one per element
/// shape) and the rows and columns of the supported DOFs replaced by a scaled identity, the
/// operator StaticProblem assembles. On a structured lattice every element is a translate of
/// the first, so one 24 x 24 matrix serves all: the product reads x, the factors and the
/// connectivity instead of the matrix's 81 entries per row (a third of MatMult's time at 212k
/// DOFs, docs/solvers.md "Matrix-free finest level"). docs/theory.md section 1.
#include "flexopt/fem/element.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"

#include <Eigen/Dense>
#include <cstdint>
#include <memory>
#include <petscmat.h>
#include <vector>

namespace flexopt::fem {

class MatrixFreeStiffness {
public:
  /// The operator of a Hex8 mesh whose elements are, on every rank, translates of at most
  /// UnitStiffness::kMaxShapes shapes; else nullptr (on every rank). Collective.
  static std::unique_ptr<MatrixFreeStiffness> create(const mesh::DistributedMesh &mesh,
                                                     const IsotropicMaterial &material);
  ~MatrixFreeStiffness();
  MatrixFreeStiffness(const MatrixFreeStiffness &) = delete;
  MatrixFreeStiffness &operator=(const MatrixFreeStiffness &) = delete;

  /// K = sum_e factor_e K_e^0 (factor empty: all 1), then the rows and columns of `fixed`
  /// (owned global DOF numbers) replaced by `diagonal` times the identity. Increases the shell
  /// matrix's state (solvers see a new operator). Collective.
  void set(const std::vector<double> &factor, const std::vector<PetscInt> &fixed, double diagonal);
  /// y = K x (x and y in the layout of create_matrix(mesh)). Collective.
  void multiply(Vec x, Vec y) const;
  /// The operator as a PETSc shell matrix (MatMult, MatMultTranspose: K is symmetric), owned by
  /// this object.
  Mat matrix() const { return shell_; }

private:
  MatrixFreeStiffness() = default;
  using Matrix24 = Eigen::Matrix<double, 24, 24>;
  const mesh::DistributedMesh *mesh_ = nullptr;
  std::vector<Matrix24> shapes_;    ///< K^0 per shape
  std::vector<std::uint8_t> shape_; ///< shape of each local element
  std::vector<double> factor_;      ///< factor of each local element
  std::vector<PetscInt> fixed_;     ///< supported DOFs, owned (local) numbers
  double diagonal_ = 1.0;
  Vec xg_ = nullptr, yg_ = nullptr; ///< ghosted work vectors
  Mat shell_ = nullptr;
};

} // namespace flexopt::fem
