/// \file The volume element kernels: material, stiffness, mass, volume, body force, stress
/// (docs/theory.md section 3, "Constitutive law and B-matrix" to "Stress and von Mises").
#include "flexopt/fem/element.hpp"

#include "element_internal.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace flexopt::fem {

using namespace detail;

namespace {

/// A Tet10 whose mid-edge nodes deviate from the edge midpoints by more than this fraction of h is
/// treated as curved (non-affine) and integrated with the higher-degree rules.
constexpr double kCurvedTol = 1e-10;

// Quadrature degrees per kernel; see docs/theory.md section 3 for the derivation of each.
// Tet4 (affine, constant B and det J).
constexpr int kTet4StiffnessDegree = 0;
constexpr int kTet4MassDegree = 2;
constexpr int kTet4VolumeDegree = 0;
constexpr int kTet4LoadDegree = 1;
// Straight-edged (affine) Tet10: B linear, det J constant.
constexpr int kTet10StiffnessDegree = 2;
constexpr int kTet10MassDegree = 4;
constexpr int kTet10VolumeDegree = 0;
constexpr int kTet10LoadDegree = 2;
// Curved Tet10: det J cubic, det J * grad N cubic.
constexpr int kCurvedTet10StiffnessDegree = 3;
constexpr int kCurvedTet10MassDegree = 7;
constexpr int kCurvedTet10VolumeDegree = 3;
constexpr int kCurvedTet10LoadDegree = 5;
// Trilinear Hex8 (degrees per direction): det J and det J * grad N have degree <= 2 per direction.
constexpr int kHex8StiffnessDegree = 3;
constexpr int kHex8MassDegree = 4;
constexpr int kHex8VolumeDegree = 2;
constexpr int kHex8LoadDegree = 3;

bool tet10_is_curved(const ElementCoords &X, double h) {
  for (int e = 0; e < 6; ++e) {
    const auto mid = 0.5 * (X.row(kTet10Edges[e][0]) + X.row(kTet10Edges[e][1]));
    if ((X.row(4 + e) - mid).norm() > kCurvedTol * h) return true;
  }
  return false;
}

} // namespace

namespace detail {

/// Quadrature degree for an integrand on a given element (see the constants above).
int kernel_degree(ElementType type, const ElementCoords &X, double h, Integrand what) {
  switch (type) {
  case ElementType::Tet4:
    switch (what) {
    case Integrand::Stiffness:
      return kTet4StiffnessDegree;
    case Integrand::Mass:
      return kTet4MassDegree;
    case Integrand::Volume:
      return kTet4VolumeDegree;
    case Integrand::Load:
      return kTet4LoadDegree;
    }
    break;
  case ElementType::Tet10: {
    const bool curved = tet10_is_curved(X, h);
    switch (what) {
    case Integrand::Stiffness:
      return curved ? kCurvedTet10StiffnessDegree : kTet10StiffnessDegree;
    case Integrand::Mass:
      return curved ? kCurvedTet10MassDegree : kTet10MassDegree;
    case Integrand::Volume:
      return curved ? kCurvedTet10VolumeDegree : kTet10VolumeDegree;
    case Integrand::Load:
      return curved ? kCurvedTet10LoadDegree : kTet10LoadDegree;
    }
    break;
  }
  case ElementType::Hex8:
    switch (what) {
    case Integrand::Stiffness:
      return kHex8StiffnessDegree;
    case Integrand::Mass:
      return kHex8MassDegree;
    case Integrand::Volume:
      return kHex8VolumeDegree;
    case Integrand::Load:
      return kHex8LoadDegree;
    }
    break;
  }
  throw Error("flexopt::fem: invalid element type or integrand");
}

} // namespace detail

namespace {

/// Stiffness for a fixed node count NN. With G = dN/dx (NN x 3) at a point, the isotropic form of
/// B^T D B between node a, component i and node b, component j is
///   lambda G(a,i) G(b,j) + mu G(a,j) G(b,i) + mu delta_ij (G_a . G_b).
/// All three terms are permutations of entries of A = sum_q w_q detJ_q g_q g_q^T with
/// g = vec(G) (node-major), so A is accumulated with one rank-1 update per point and K is read off.
template <int NN>
void stiffness_impl(ElementType type, const ShapeTable &tab, const ElementCoords &X, double lambda,
                    double mu, double det_min, ElementMatrix &K) {
  constexpr int kNd = 3 * NN;
  const Eigen::Matrix<double, NN, 3> Xn = X.rowwise() - X.row(0); // see jacobian()
  Eigen::Matrix<double, kNd, kNd> A = Eigen::Matrix<double, kNd, kNd>::Zero();
  Eigen::Matrix<double, NN, 3, Eigen::RowMajor> G;
  for (int q = 0; q < tab.num_points; ++q) {
    const Eigen::Map<const Eigen::Matrix<double, NN, 3, Eigen::RowMajor>> dN(&tab.dN[q * NN * 3]);
    const Eigen::Matrix3d J = Xn.transpose() * dN;
    const double det = J.determinant();
    if (!(det > det_min)) throw_degenerate("element_stiffness", type, X, det, det_min);
    G.noalias() = dN * J.inverse();
    const Eigen::Map<const Eigen::Matrix<double, kNd, 1>> g(G.data());
    A.noalias() += (tab.weights[q] * det) * g * g.transpose();
  }
  K.resize(kNd, kNd);
  for (int a = 0; a < NN; ++a)
    for (int b = 0; b < NN; ++b) {
      const double dot = A(3 * a, 3 * b) + A(3 * a + 1, 3 * b + 1) + A(3 * a + 2, 3 * b + 2);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
          K(3 * a + i, 3 * b + j) = lambda * A(3 * a + i, 3 * b + j) +
                                    mu * A(3 * a + j, 3 * b + i) + (i == j ? mu * dot : 0.0);
    }
}

/// Signed sum_q w_q det J_q N_a(q) (into nodal weights) and sum_q w_q det J_q (returned), with the
/// degenerate check if `where` is non-null.
double integrate_shape(ElementType type, const ShapeTable &tab, const ElementCoords &X,
                       double det_min, const char *where, double *nodal) {
  const int n = tab.num_nodes;
  if (nodal) std::fill(nodal, nodal + n, 0.0);
  double volume = 0.0;
  for (int q = 0; q < tab.num_points; ++q) {
    const double det = jacobian(X, &tab.dN[q * n * 3]).determinant();
    if (where && !(det > det_min)) throw_degenerate(where, type, X, det, det_min);
    const double wdet = tab.weights[q] * det;
    volume += wdet;
    if (nodal)
      for (int a = 0; a < n; ++a) nodal[a] += wdet * tab.N[q * n + a];
  }
  return volume;
}

} // namespace

// -----------------------------------------------------------------------------------------------
// Element catalogue

// -----------------------------------------------------------------------------------------------
// Material

double IsotropicMaterial::lambda() const {
  return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
}

double IsotropicMaterial::mu() const {
  return E / (2.0 * (1.0 + nu));
}

Eigen::Matrix<double, 6, 6> IsotropicMaterial::elasticity() const {
  const double l = lambda(), m = mu();
  Eigen::Matrix<double, 6, 6> D = Eigen::Matrix<double, 6, 6>::Zero();
  D.topLeftCorner<3, 3>().setConstant(l);
  for (int i = 0; i < 3; ++i) D(i, i) += 2.0 * m;
  for (int i = 3; i < 6; ++i) D(i, i) = m;
  return D;
}

void IsotropicMaterial::validate() const {
  // Negated comparisons so that NaN fails too.
  if (!(E > 0.0) || !std::isfinite(E) || !(nu > -1.0) || !(nu < 0.5) || !(density >= 0.0) ||
      !std::isfinite(density)) {
    std::ostringstream msg;
    msg << "invalid isotropic material: E = " << E << " (must be > 0), nu = " << nu
        << " (must be in (-1, 0.5)), density = " << density << " (must be >= 0)";
    throw Error(msg.str());
  }
}

// -----------------------------------------------------------------------------------------------
// Kernels

ElementMatrix element_stiffness(ElementType type, const ElementCoords &X,
                                const IsotropicMaterial &mat, double modulus_factor) {
  check_coords(type, X, "element_stiffness");
  mat.validate();
  const double h = size_scale(X);
  const double det_min = kDegenerateTol * h * h * h;
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Stiffness));
  const double lambda = modulus_factor * mat.lambda();
  const double mu = modulus_factor * mat.mu();
  ElementMatrix K;
  switch (type) {
  case ElementType::Tet4:
    stiffness_impl<4>(type, tab, X, lambda, mu, det_min, K);
    break;
  case ElementType::Tet10:
    stiffness_impl<10>(type, tab, X, lambda, mu, det_min, K);
    break;
  case ElementType::Hex8:
    stiffness_impl<8>(type, tab, X, lambda, mu, det_min, K);
    break;
  }
  return K;
}

ElementMatrix element_mass(ElementType type, const ElementCoords &X, double density) {
  check_coords(type, X, "element_mass");
  const double h = size_scale(X);
  const double det_min = kDegenerateTol * h * h * h;
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Mass));
  const int n = tab.num_nodes;
  // Scalar mass m_ab = sum_q w_q detJ_q N_a N_b, symmetric.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxNodes, kMaxNodes> m =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxNodes, kMaxNodes>::Zero(n, n);
  for (int q = 0; q < tab.num_points; ++q) {
    const double det = jacobian(X, &tab.dN[q * n * 3]).determinant();
    if (!(det > det_min)) throw_degenerate("element_mass", type, X, det, det_min);
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxNodes, 1>> Nq(
        &tab.N[q * n], n);
    m.noalias() += (tab.weights[q] * det) * Nq * Nq.transpose();
  }
  ElementMatrix M = ElementMatrix::Zero(3 * n, 3 * n);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      for (int i = 0; i < 3; ++i) M(3 * a + i, 3 * b + i) = density * m(a, b);
  return M;
}

double element_volume(ElementType type, const ElementCoords &X) {
  check_coords(type, X, "element_volume");
  const double h = size_scale(X);
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Volume));
  return integrate_shape(type, tab, X, 0.0, nullptr, nullptr);
}

ElementVector element_body_force(ElementType type, const ElementCoords &X,
                                 const Eigen::Vector3d &b) {
  check_coords(type, X, "element_body_force");
  const double h = size_scale(X);
  const double det_min = kDegenerateTol * h * h * h;
  const ShapeTable &tab = volume_table(type, kernel_degree(type, X, h, Integrand::Load));
  double nodal[kMaxNodes];
  integrate_shape(type, tab, X, det_min, "element_body_force", nodal);
  const int n = tab.num_nodes;
  ElementVector f(3 * n);
  for (int a = 0; a < n; ++a)
    for (int i = 0; i < 3; ++i) f[3 * a + i] = nodal[a] * b[i];
  return f;
}

namespace {
/// dN_a/dx at reference point xi, one row per node; throws naming `who` if det J <= 0 there.
ElementCoords physical_gradients(ElementType type, const ElementCoords &X,
                                 const Eigen::Vector3d &xi, const char *who) {
  const int n = nodes_per_element(type);
  double dN[kMaxNodes * 3];
  shape_functions(type, xi, nullptr, dN);
  const Eigen::Matrix3d J = jacobian(X, dN);
  const double det = J.determinant();
  if (!(det > 0.0)) throw_degenerate(who, type, X, det, 0.0);
  const Eigen::Matrix3d Jinv = J.inverse();
  ElementCoords g(n, 3);
  for (int a = 0; a < n; ++a) g.row(a) = Eigen::Map<const Eigen::RowVector3d>(&dN[a * 3]) * Jinv;
  return g;
}
} // namespace

Eigen::Matrix3d displacement_gradient(ElementType type, const ElementCoords &X,
                                      const ElementVector &u_e, const Eigen::Vector3d &xi,
                                      const char *who) {
  check_coords(type, X, who);
  const int n = nodes_per_element(type);
  if (u_e.size() != 3 * n)
    throw Error(std::string(who) + ": " + element_name(type) + " needs " + std::to_string(3 * n) +
                " displacement entries, got " + std::to_string(u_e.size()));
  const ElementCoords g = physical_gradients(type, X, xi, who);
  // H(i,j) = du_i/dx_j = sum_a u_(a,i) dN_a/dx_j.
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int a = 0; a < n; ++a) H += u_e.segment<3>(3 * a) * g.row(a);
  return H;
}

Voigt element_stress(ElementType type, const ElementCoords &X, const IsotropicMaterial &mat,
                     double modulus_factor, const ElementVector &u_e, const Eigen::Vector3d &xi) {
  mat.validate();
  const Eigen::Matrix3d H = displacement_gradient(type, X, u_e, xi, "element_stress");
  const double lambda = modulus_factor * mat.lambda();
  const double mu = modulus_factor * mat.mu();
  const double trace = H.trace();
  Voigt sigma;
  for (int i = 0; i < 3; ++i) sigma[i] = lambda * trace + 2.0 * mu * H(i, i);
  sigma[3] = mu * (H(1, 2) + H(2, 1));
  sigma[4] = mu * (H(0, 2) + H(2, 0));
  sigma[5] = mu * (H(0, 1) + H(1, 0));
  return sigma;
}

StressMatrix element_stress_matrix(ElementType type, const ElementCoords &X,
                                   const IsotropicMaterial &mat, const Eigen::Vector3d &xi) {
  const char *who = "element_stress_matrix";
  check_coords(type, X, who);
  mat.validate();
  const int n = nodes_per_element(type);
  const ElementCoords grad = physical_gradients(type, X, xi, who);
  const double lambda = mat.lambda(), mu = mat.mu();
  StressMatrix S = StressMatrix::Zero(6, 3 * n);
  for (int a = 0; a < n; ++a) {
    const Eigen::RowVector3d g = grad.row(a);
    // Normal rows: sigma_ii = lambda tr(H) + 2 mu H_ii; shear rows mu (H_ij + H_ji), Voigt
    // order yz, xz, xy (section 3).
    for (int k = 0; k < 3; ++k) {
      for (int i = 0; i < 3; ++i)
        S(i, 3 * a + k) = lambda * g(k) + (i == k ? 2.0 * mu * g(k) : 0.0);
    }
    S(3, 3 * a + 1) = mu * g(2);
    S(3, 3 * a + 2) = mu * g(1);
    S(4, 3 * a + 0) = mu * g(2);
    S(4, 3 * a + 2) = mu * g(0);
    S(5, 3 * a + 0) = mu * g(1);
    S(5, 3 * a + 1) = mu * g(0);
  }
  return S;
}

Voigt von_mises_gradient(const Voigt &s) {
  const double v = von_mises(s);
  if (v == 0.0) return Voigt::Zero();
  Voigt g;
  g << 2 * s[0] - s[1] - s[2], 2 * s[1] - s[2] - s[0], 2 * s[2] - s[0] - s[1], 6 * s[3], 6 * s[4],
      6 * s[5];
  return g / (2.0 * v);
}

double von_mises(const Voigt &s) {
  const double d01 = s[0] - s[1], d12 = s[1] - s[2], d20 = s[2] - s[0];
  return std::sqrt(0.5 * (d01 * d01 + d12 * d12 + d20 * d20) +
                   3.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
}

} // namespace flexopt::fem
