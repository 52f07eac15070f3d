// A stress response on an FFRF body (docs/theory.md section 10.3).
#include "flexopt/adjoint/ffrf_stress.hpp"

#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/dense_blas.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/optimize/static_stress.hpp"
#include "flexopt/reduce/stress_shapes.hpp"

#include <algorithm>
#include <numeric>

namespace flexopt::adjoint {

namespace {
/// The samples come in tiles of kTileElements elements by kTileSteps steps, S = T_rows Z_steps
/// (6 kTileElements x kTileSteps doubles, 1.5 MB: it stays in cache while its samples are
/// aggregated, and the products read T and Z once per tile instead of writing and reading every
/// stress through memory; measured on cases/slider_crank_stress, docs/benchmarks.md).
constexpr Eigen::Index kTileElements = 128, kTileSteps = 256;

/// Calls f(i0, ni, n0, nb, S) for every tile: elements i0 ... i0 + ni - 1 (of T's blocks), steps
/// n0 ... n0 + nb - 1, S = T(6 i0 : 6 (i0 + ni), :) Z(:, n0 : n0 + nb) (6 ni x nb).
template <class F> void for_each_tile(const Eigen::MatrixXd &T, const Eigen::MatrixXd &Z, F &&f) {
  const Eigen::Index ne = T.rows() / 6, steps = Z.cols();
  Eigen::MatrixXd S(6 * kTileElements, kTileSteps);
  for (Eigen::Index n0 = 0; n0 < steps; n0 += kTileSteps) {
    const Eigen::Index nb = std::min(kTileSteps, steps - n0);
    for (Eigen::Index i0 = 0; i0 < ne; i0 += kTileElements) {
      const Eigen::Index ni = std::min(kTileElements, ne - i0);
      auto tile = S.topLeftCorner(6 * ni, nb);
      gemm(false, false, 1.0, T.middleRows(6 * i0, 6 * ni), Z.middleCols(n0, nb), 0.0, tile);
      f(i0, ni, n0, nb, tile);
    }
  }
}
} // namespace

FfrfStress::FfrfStress(const optimize::ResponseSettings &r, const mesh::DistributedMesh &mesh,
                       const fem::IsotropicMaterial &material)
    : BodyStress(r, mesh, material) {}

void FfrfStress::set_basis(const std::vector<Vec> &basis) {
  shapes_ = reduce::stress_shapes(mesh_, material_, basis, elements_);
}

double FfrfStress::finish(double h, const std::vector<double> &eta, const std::vector<double> &deta,
                          bool gradients) {
  aggregate_.clear();
  const auto steps = static_cast<Eigen::Index>(zeta_.size());
  const std::size_t N = zeta_.empty() ? 0 : zeta_.size() - 1;
  Eigen::MatrixXd Z(shapes_.cols(), steps);
  for (Eigen::Index n = 0; n < steps; ++n) Z.col(n) = zeta_[static_cast<std::size_t>(n)];
  for_each_tile(
      shapes_, Z,
      [&](Eigen::Index i0, Eigen::Index ni, Eigen::Index n0, Eigen::Index nb, const auto &S) {
        for (Eigen::Index b = 0; b < nb; ++b) {
          const double w = trapezoid_weight(static_cast<std::size_t>(n0 + b), N);
          const double t = static_cast<double>(n0 + b) * h;
          for (Eigen::Index k = 0; k < ni; ++k) {
            const fem::Voigt s = S.template block<6, 1>(6 * k, b);
            const auto i = static_cast<std::size_t>(i0 + k);
            aggregate_.add(eta_of(eta, i) * fem::von_mises(s), w, tag_of(i), t);
          }
        }
      });
  aggregate_.reduce(mesh_.comm);
  if (gradients) adjoint_pieces(Z, eta, deta);
  return scale_ * aggregate_.value();
}

void FfrfStress::adjoint_pieces(const Eigen::MatrixXd &Z, const std::vector<double> &eta,
                                const std::vector<double> &deta) {
  // The same tiles: A = [g eta dv/dsigma] (6 ni x nb), dR/dZ += T^T A, Tbar += A Z^T, and the
  // explicit sum_n g eta' v (docs/theory.md 10.3).
  const std::size_t N = zeta_.empty() ? 0 : zeta_.size() - 1;
  dzeta_.setZero(shapes_.cols(), Z.cols());
  shape_cotangent_.setZero(shapes_.rows(), shapes_.cols());
  explicit_.assign(static_cast<std::size_t>(mesh_.local_elements()), 0.0);
  Eigen::MatrixXd A(6 * kTileElements, kTileSteps);
  for_each_tile(
      shapes_, Z,
      [&](Eigen::Index i0, Eigen::Index ni, Eigen::Index n0, Eigen::Index nb, const auto &S) {
        auto a = A.topLeftCorner(6 * ni, nb); // every entry written below
        for (Eigen::Index b = 0; b < nb; ++b) {
          const double w = trapezoid_weight(static_cast<std::size_t>(n0 + b), N);
          for (Eigen::Index k = 0; k < ni; ++k) {
            const auto e = static_cast<std::size_t>(elements_[static_cast<std::size_t>(i0 + k)]);
            const fem::Voigt s = S.template block<6, 1>(6 * k, b);
            const double v = fem::von_mises(s), et = eta.empty() ? 1.0 : eta[e];
            const double g = scale_ * aggregate_.derivative(et * v, w);
            if (g == 0.0 || v == 0.0) {
              a.template block<6, 1>(6 * k, b).setZero();
              continue;
            }
            a.template block<6, 1>(6 * k, b) = (g * et) * fem::von_mises_gradient(s); // (5.1)
            if (!deta.empty()) explicit_[e] += g * deta[e] * v;
          }
        }
        gemm(true, false, 1.0, shapes_.middleRows(6 * i0, 6 * ni), a, 1.0,
             dzeta_.middleCols(n0, nb));
        gemm(false, true, 1.0, a, Z.middleCols(n0, nb), 1.0,
             shape_cotangent_.middleRows(6 * i0, 6 * ni));
      });
  MPI_Allreduce(MPI_IN_PLACE, dzeta_.data(), static_cast<int>(dzeta_.size()), MPI_DOUBLE, MPI_SUM,
                mesh_.comm);
}

void FfrfStress::add_basis_cotangent(const std::vector<Vec> &out) const {
  reduce::add_stress_shape_cotangent(mesh_, material_, elements_, shape_cotangent_, out);
}

} // namespace flexopt::adjoint
