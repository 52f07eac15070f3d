/// \file The geometric (initial-stress) stiffness kernel and its adjoint pseudo-load
/// (docs/theory.md section 7.5, "Element kernel"; section 10, step 1).
#include "element_internal.hpp"
#include "flexopt/fem/element.hpp"

#include <string>
#include <vector>

namespace flexopt::fem {

using namespace detail;

namespace {

/// Geometric stiffness for a fixed node count NN. At each point, with G = dN/dx (NN x 3) and the
/// nodal displacements U (NN x 3), the displacement gradient is H = U^T G and the stress tensor
/// S = lambda tr(H) I + mu (H + H^T). The scalar matrix k = sum_q w_q detJ_q G S G^T couples the
/// same component of two nodes, K_sigma = k (x) I_3; k is symmetrized once at the end so that
/// K_sigma is exactly symmetric.
template <int NN>
void geometric_stiffness_impl(ElementType type, const ShapeTable &tab, const ElementCoords &X,
                              const ElementVector &u_e, double lambda, double mu, double det_min,
                              ElementMatrix &K) {
  const Eigen::Matrix<double, NN, 3> Xn = X.rowwise() - X.row(0); // see jacobian()
  const Eigen::Map<const Eigen::Matrix<double, NN, 3, Eigen::RowMajor>> U(u_e.data());
  Eigen::Matrix<double, NN, NN> k = Eigen::Matrix<double, NN, NN>::Zero();
  Eigen::Matrix<double, NN, 3, Eigen::RowMajor> G;
  for (int q = 0; q < tab.num_points; ++q) {
    const Eigen::Map<const Eigen::Matrix<double, NN, 3, Eigen::RowMajor>> dN(&tab.dN[q * NN * 3]);
    const Eigen::Matrix3d J = Xn.transpose() * dN;
    const double det = J.determinant();
    if (!(det > det_min)) throw_degenerate("element_geometric_stiffness", type, X, det, det_min);
    G.noalias() = dN * J.inverse();
    const Eigen::Matrix3d H = U.transpose() * G;
    const Eigen::Matrix3d S =
        lambda * H.trace() * Eigen::Matrix3d::Identity() + mu * (H + H.transpose());
    k.noalias() += (tab.weights[q] * det) * (G * S * G.transpose());
  }
  K = ElementMatrix::Zero(3 * NN, 3 * NN);
  for (int a = 0; a < NN; ++a)
    for (int b = 0; b < NN; ++b) {
      const double kab = 0.5 * (k(a, b) + k(b, a));
      for (int i = 0; i < 3; ++i) K(3 * a + i, 3 * b + i) = kab;
    }
}

template <int NN>
void geometric_stiffness_load_impl(ElementType type, const ShapeTable &tab, const ElementCoords &X,
                                   const Eigen::Ref<const Eigen::MatrixXd> &psi,
                                   const Eigen::Ref<const Eigen::MatrixXd> &Gbar, double lambda,
                                   double mu, double det_min, ElementVector &f) {
  const Eigen::Matrix<double, NN, 3> Xn = X.rowwise() - X.row(0); // see jacobian()
  const auto n = psi.cols();
  Eigen::Matrix<double, NN, 3> F = Eigen::Matrix<double, NN, 3>::Zero();
  Eigen::Matrix<double, NN, 3, Eigen::RowMajor> G;
  std::vector<Eigen::Matrix3d> H(static_cast<std::size_t>(n));
  for (int q = 0; q < tab.num_points; ++q) {
    const Eigen::Map<const Eigen::Matrix<double, NN, 3, Eigen::RowMajor>> dN(&tab.dN[q * NN * 3]);
    const Eigen::Matrix3d J = Xn.transpose() * dN;
    const double det = J.determinant();
    if (!(det > det_min))
      throw_degenerate("element_geometric_stiffness_load", type, X, det, det_min);
    G.noalias() = dN * J.inverse();
    // H_k(i, j) = d psi_k,i / dx_j.
    for (Eigen::Index k = 0; k < n; ++k) {
      const Eigen::Map<const Eigen::Matrix<double, NN, 3, Eigen::RowMajor>> P(psi.col(k).data());
      H[static_cast<std::size_t>(k)].noalias() = P.transpose() * G;
    }
    Eigen::Matrix3d T = Eigen::Matrix3d::Zero();
    for (Eigen::Index k = 0; k < n; ++k) {
      Eigen::Matrix3d W = Eigen::Matrix3d::Zero();
      for (Eigen::Index l = 0; l < n; ++l) W += Gbar(k, l) * H[static_cast<std::size_t>(l)];
      T.noalias() += H[static_cast<std::size_t>(k)].transpose() * W;
    }
    T = 0.5 * (T + T.transpose()).eval();
    const Eigen::Matrix3d Z = lambda * T.trace() * Eigen::Matrix3d::Identity() + 2.0 * mu * T;
    F.noalias() += (tab.weights[q] * det) * (G * Z);
  }
  f.resize(3 * NN);
  for (int a = 0; a < NN; ++a)
    for (int i = 0; i < 3; ++i) f[3 * a + i] = F(a, i);
}

} // namespace

ElementMatrix element_geometric_stiffness(ElementType type, const ElementCoords &X,
                                          const IsotropicMaterial &mat, const ElementVector &u_e) {
  check_coords(type, X, "element_geometric_stiffness");
  const int n = nodes_per_element(type);
  if (u_e.size() != 3 * n)
    throw Error(std::string("element_geometric_stiffness: ") + element_name(type) + " needs " +
                std::to_string(3 * n) + " displacement entries, got " + std::to_string(u_e.size()));
  mat.validate();
  const double h = size_scale(X);
  const double det_min = kDegenerateTol * h * h * h;
  // The stress is sampled at the stiffness rule's points: the pairing of K_sigma with K in the
  // stiffened operator K + K_sigma sees the same quadrature.
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Stiffness));
  ElementMatrix K;
  switch (type) {
  case ElementType::Tet4:
    geometric_stiffness_impl<4>(type, tab, X, u_e, mat.lambda(), mat.mu(), det_min, K);
    break;
  case ElementType::Tet10:
    geometric_stiffness_impl<10>(type, tab, X, u_e, mat.lambda(), mat.mu(), det_min, K);
    break;
  case ElementType::Hex8:
    geometric_stiffness_impl<8>(type, tab, X, u_e, mat.lambda(), mat.mu(), det_min, K);
    break;
  }
  return K;
}

ElementVector element_geometric_stiffness_load(ElementType type, const ElementCoords &X,
                                               const IsotropicMaterial &mat,
                                               const Eigen::Ref<const Eigen::MatrixXd> &psi,
                                               const Eigen::Ref<const Eigen::MatrixXd> &Gbar) {
  check_coords(type, X, "element_geometric_stiffness_load");
  const int n = nodes_per_element(type);
  if (psi.rows() != 3 * n || Gbar.rows() != psi.cols() || Gbar.cols() != psi.cols())
    throw Error(std::string("element_geometric_stiffness_load: ") + element_name(type) + " needs " +
                std::to_string(3 * n) +
                " rows per vector and a square Gbar of their "
                "count");
  mat.validate();
  const double h = size_scale(X);
  const double det_min = kDegenerateTol * h * h * h;
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Stiffness));
  ElementVector f;
  switch (type) {
  case ElementType::Tet4:
    geometric_stiffness_load_impl<4>(type, tab, X, psi, Gbar, mat.lambda(), mat.mu(), det_min, f);
    break;
  case ElementType::Tet10:
    geometric_stiffness_load_impl<10>(type, tab, X, psi, Gbar, mat.lambda(), mat.mu(), det_min, f);
    break;
  case ElementType::Hex8:
    geometric_stiffness_load_impl<8>(type, tab, X, psi, Gbar, mat.lambda(), mat.mu(), det_min, f);
    break;
  }
  return f;
}

} // namespace flexopt::fem
