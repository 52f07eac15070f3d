#include "flexopt/fem/element.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <string>

namespace flexopt::fem {

namespace {

/// det J below this fraction of h^3 (h: bounding-box diagonal of the nodes) counts as degenerate.
/// A well-shaped element has det J / h^3 of order 1e-2 to 1 (tet: det J = 6 V; hex: det J = V / 8),
/// so only elements that are flat to ~10 digits are rejected.
constexpr double kDegenerateTol = 1e-12;
/// A Tet10 whose mid-edge nodes deviate from the edge midpoints by more than this fraction of h is
/// treated as curved (non-affine) and integrated with the higher-degree rules.
constexpr double kCurvedTol = 1e-10;
/// Rules up to this degree are tabulated once (points, weights, N, dN) in function-local statics.
constexpr int kMaxCachedDegree = 10;
/// Highest degree accepted by the public quadrature functions (21 Gauss points per direction).
constexpr int kMaxDegree = 40;

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
// Faces. Curved Tri6 and warped Quad4 have non-polynomial dA, so use generous rules: face loads are
// computed once per solve, on boundary faces only.
constexpr int kTri3Degree = 1;
constexpr int kTri6Degree = 10;
constexpr int kQuad4Degree = 7;
/// Edges: N_a |dx/dxi| is polynomial of degree 4 on a straight Line3 (|dx/dxi| linear in xi
/// only if curved; 5 Gauss points, degree 9, integrate curved Gmsh edges to round-off level).
constexpr int kLineDegree = 9;

// ---------------------------------------------------------------------------------------------
// 1D Gauss-Legendre rules

/// n-point Gauss-Legendre rule on [-1, 1] (exact for degree 2n - 1). Nodes are roots of P_n found
/// by Newton's method from the asymptotic guess cos(pi (i + 3/4) / (n + 1/2)), which lies in the
/// basin of the i-th root; the rule is symmetrised explicitly so that odd monomials integrate to
/// zero up to roundoff in the sum only.
void gauss_legendre(int n, std::vector<double> &x, std::vector<double> &w) {
  x.assign(n, 0.0);
  w.assign(n, 0.0);
  // P_n(z) and P_n'(z) by the three-term recurrence.
  auto legendre = [n](double z, double &p, double &dp) {
    double p0 = 1.0, p1 = z;
    for (int k = 2; k <= n; ++k) {
      const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
      p0 = p1;
      p1 = p2;
    }
    p = p1;
    dp = n * (z * p1 - p0) / (z * z - 1.0);
  };
  for (int i = 0; i < (n + 1) / 2; ++i) {
    double z = std::cos(std::numbers::pi * (i + 0.75) / (n + 0.5));
    double p = 0.0, dp = 1.0;
    if (n % 2 == 1 && i == n / 2) {
      z = 0.0; // the middle root of an odd-order polynomial is exactly zero
    } else {
      for (int it = 0; it < 100; ++it) {
        legendre(z, p, dp);
        const double dz = p / dp;
        z -= dz;
        if (std::abs(dz) <= 1e-16) break;
      }
    }
    legendre(z, p, dp);
    const double weight = 2.0 / ((1.0 - z * z) * dp * dp);
    // The guess for index i approximates the i-th largest root.
    x[n - 1 - i] = z;
    x[i] = -z;
    w[i] = w[n - 1 - i] = weight;
  }
}

/// n-point Gauss-Legendre rule mapped to [0, 1].
void gauss_legendre_01(int n, std::vector<double> &x, std::vector<double> &w) {
  gauss_legendre(n, x, w);
  for (int i = 0; i < n; ++i) {
    x[i] = 0.5 * (x[i] + 1.0);
    w[i] *= 0.5;
  }
}

void check_degree(int degree, const char *where) {
  if (degree < 0 || degree > kMaxDegree)
    throw Error(std::string(where) + ": quadrature degree " + std::to_string(degree) +
                " out of range [0, " + std::to_string(kMaxDegree) + "]");
}

/// Points per direction for a tensor Gauss rule of degree `degree` per direction.
int gauss_points_for_degree(int degree) {
  return degree / 2 + 1;
}

QuadratureRule tet_rule(int degree) {
  QuadratureRule rule;
  if (degree <= 1) {
    rule.points.emplace_back(0.25, 0.25, 0.25);
    rule.weights.push_back(1.0 / 6.0);
    return rule;
  }
  if (degree == 2) {
    // Symmetric 4-point rule: points a + (b - a) e_k on the lines from the centroid to the
    // vertices; a = (5 - sqrt 5) / 20 and b = 1 - 3a make the second moments exact.
    const double a = (5.0 - std::sqrt(5.0)) / 20.0;
    const double b = 1.0 - 3.0 * a;
    rule.points = {{a, a, a}, {b, a, a}, {a, b, a}, {a, a, b}};
    rule.weights.assign(4, 1.0 / 24.0);
    return rule;
  }
  // Collapsed (Duffy) rule: x = u, y = (1-u) v, z = (1-u)(1-v) w maps [0,1]^3 onto the tet with
  // Jacobian (1-u)^2 (1-v). A monomial of total degree d becomes a polynomial of degree d+2 in u,
  // d+1 in v and d in w, so Gauss-Legendre with ceil((d+3)/2), ceil((d+2)/2), ceil((d+1)/2) points.
  std::vector<double> xu, wu, xv, wv, xw, ww;
  gauss_legendre_01((degree + 4) / 2, xu, wu);
  gauss_legendre_01((degree + 3) / 2, xv, wv);
  gauss_legendre_01((degree + 2) / 2, xw, ww);
  for (std::size_t i = 0; i < xu.size(); ++i)
    for (std::size_t j = 0; j < xv.size(); ++j)
      for (std::size_t k = 0; k < xw.size(); ++k) {
        const double u = xu[i], v = xv[j], s = xw[k];
        rule.points.emplace_back(u, (1.0 - u) * v, (1.0 - u) * (1.0 - v) * s);
        rule.weights.push_back(wu[i] * wv[j] * ww[k] * (1.0 - u) * (1.0 - u) * (1.0 - v));
      }
  return rule;
}

QuadratureRule hex_rule(int degree) {
  std::vector<double> x, w;
  gauss_legendre(gauss_points_for_degree(degree), x, w);
  QuadratureRule rule;
  // Node-major order with xi varying fastest is arbitrary; any order is a valid rule.
  for (std::size_t k = 0; k < x.size(); ++k)
    for (std::size_t j = 0; j < x.size(); ++j)
      for (std::size_t i = 0; i < x.size(); ++i) {
        rule.points.emplace_back(x[i], x[j], x[k]);
        rule.weights.push_back(w[i] * w[j] * w[k]);
      }
  return rule;
}

QuadratureRule tri_rule(int degree) {
  QuadratureRule rule;
  if (degree <= 1) {
    rule.points.emplace_back(1.0 / 3.0, 1.0 / 3.0, 0.0);
    rule.weights.push_back(0.5);
    return rule;
  }
  if (degree == 2) {
    rule.points = {
        {1.0 / 6.0, 1.0 / 6.0, 0.0}, {2.0 / 3.0, 1.0 / 6.0, 0.0}, {1.0 / 6.0, 2.0 / 3.0, 0.0}};
    rule.weights.assign(3, 1.0 / 6.0);
    return rule;
  }
  // Collapsed rule: x = u, y = (1-u) v, Jacobian (1-u): degree d+1 in u, d in v.
  std::vector<double> xu, wu, xv, wv;
  gauss_legendre_01((degree + 3) / 2, xu, wu);
  gauss_legendre_01((degree + 2) / 2, xv, wv);
  for (std::size_t i = 0; i < xu.size(); ++i)
    for (std::size_t j = 0; j < xv.size(); ++j) {
      rule.points.emplace_back(xu[i], (1.0 - xu[i]) * xv[j], 0.0);
      rule.weights.push_back(wu[i] * wv[j] * (1.0 - xu[i]));
    }
  return rule;
}

QuadratureRule quad_rule(int degree) {
  std::vector<double> x, w;
  gauss_legendre(gauss_points_for_degree(degree), x, w);
  QuadratureRule rule;
  for (std::size_t j = 0; j < x.size(); ++j)
    for (std::size_t i = 0; i < x.size(); ++i) {
      rule.points.emplace_back(x[i], x[j], 0.0);
      rule.weights.push_back(w[i] * w[j]);
    }
  return rule;
}

// ---------------------------------------------------------------------------------------------
// Tabulated rules: weights and shape-function values at the points, built once per
// (type, degree) in thread-safe function-local statics so that the kernels never allocate.

struct ShapeTable {
  int num_points = 0;
  int num_nodes = 0;
  std::vector<double> weights; // num_points
  std::vector<double> N;       // num_points x num_nodes
  std::vector<double> dN;      // num_points x num_nodes x dim (dim 3 for volumes, 2 for faces)
};

const ShapeTable &volume_table(ElementType type, int degree) {
  static const auto tables = [] {
    std::array<std::array<ShapeTable, kMaxCachedDegree + 1>, 3> all;
    for (ElementType t : {ElementType::Tet4, ElementType::Tet10, ElementType::Hex8})
      for (int d = 0; d <= kMaxCachedDegree; ++d) {
        const QuadratureRule rule = volume_quadrature(t, d);
        ShapeTable &tab = all[mesh::type_index(t)][d];
        tab.num_points = static_cast<int>(rule.points.size());
        tab.num_nodes = nodes_per_element(t);
        tab.weights = rule.weights;
        tab.N.resize(tab.num_points * tab.num_nodes);
        tab.dN.resize(tab.num_points * tab.num_nodes * 3);
        for (int q = 0; q < tab.num_points; ++q)
          shape_functions(t, rule.points[q], &tab.N[q * tab.num_nodes],
                          &tab.dN[q * tab.num_nodes * 3]);
      }
    return all;
  }();
  return tables[mesh::type_index(type)][degree];
}

const ShapeTable &face_table(FaceType type, int degree) {
  static const auto tables = [] {
    std::array<std::array<ShapeTable, kMaxCachedDegree + 1>, 5> all;
    for (FaceType t :
         {FaceType::Tri3, FaceType::Tri6, FaceType::Quad4, FaceType::Line2, FaceType::Line3})
      for (int d = 0; d <= kMaxCachedDegree; ++d) {
        const QuadratureRule rule = face_quadrature(t, d);
        ShapeTable &tab = all[mesh::face_index(t)][d];
        tab.num_points = static_cast<int>(rule.points.size());
        tab.num_nodes = nodes_per_face(t);
        tab.weights = rule.weights;
        tab.N.resize(tab.num_points * tab.num_nodes);
        tab.dN.resize(tab.num_points * tab.num_nodes * 2);
        for (int q = 0; q < tab.num_points; ++q)
          face_shape_functions(t, rule.points[q].head<2>(), &tab.N[q * tab.num_nodes],
                               &tab.dN[q * tab.num_nodes * 2]);
      }
    return all;
  }();
  return tables[mesh::face_index(type)][degree];
}

// ---------------------------------------------------------------------------------------------
// Element geometry helpers

void check_coords(ElementType type, const ElementCoords &X, const char *where) {
  if (X.rows() != nodes_per_element(type)) {
    std::ostringstream msg;
    msg << where << ": " << element_name(type) << " needs " << nodes_per_element(type)
        << " node coordinates, got " << X.rows();
    throw Error(msg.str());
  }
}

void check_face_coords(FaceType type, const FaceCoords &Xf, const char *where) {
  if (Xf.rows() != nodes_per_face(type)) {
    std::ostringstream msg;
    msg << where << ": " << face_name(type) << " needs " << nodes_per_face(type)
        << " node coordinates, got " << Xf.rows();
    throw Error(msg.str());
  }
}

/// Size scale h of an element: diagonal of the bounding box of its nodes.
double size_scale(const ElementCoords &X) {
  return (X.colwise().maxCoeff() - X.colwise().minCoeff()).norm();
}

/// Gmsh Tet10 edges of the mid-edge nodes 4..9.
constexpr int kTet10Edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 0}, {3, 2}, {3, 1}};

bool tet10_is_curved(const ElementCoords &X, double h) {
  for (int e = 0; e < 6; ++e) {
    const auto mid = 0.5 * (X.row(kTet10Edges[e][0]) + X.row(kTet10Edges[e][1]));
    if ((X.row(4 + e) - mid).norm() > kCurvedTol * h) return true;
  }
  return false;
}

enum class Integrand { Stiffness, Mass, Volume, Load };

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

/// Jacobian J(i,k) = dx_i / dxi_k = sum_a (X(a,i) - X(0,i)) dN(a,k) for a generic node count.
/// Since sum_a dN_a = 0, subtracting node 0 changes nothing mathematically, but the differences of
/// nearby coordinates are exact (Sterbenz), so an element far from the origin relative to its size
/// keeps full relative accuracy in J instead of losing |x| / h digits to cancellation.
Eigen::Matrix3d jacobian(const ElementCoords &X, const double *dN) {
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (int a = 1; a < X.rows(); ++a)
    for (int i = 0; i < 3; ++i) {
      const double xa = X(a, i) - X(0, i);
      for (int k = 0; k < 3; ++k) J(i, k) += xa * dN[a * 3 + k];
    }
  return J;
}

[[noreturn]] void throw_degenerate(const char *where, ElementType type, const ElementCoords &X,
                                   double det, double threshold) {
  std::ostringstream msg;
  msg.precision(6);
  msg << where << ": degenerate or inverted " << element_name(type) << " element (det J = " << det
      << " <= " << threshold << " at a quadrature point; first node at (" << X(0, 0) << ", "
      << X(0, 1) << ", " << X(0, 2) << "))";
  throw Error(msg.str());
}

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

/// Surface element |dx/dxi x dx/deta| at a face quadrature point.
double surface_jacobian(const FaceCoords &Xf, const double *dN) {
  // Coordinates relative to node 0 for accuracy, as in jacobian().
  Eigen::Vector3d t1 = Eigen::Vector3d::Zero(), t2 = Eigen::Vector3d::Zero();
  for (int a = 1; a < Xf.rows(); ++a) {
    const Eigen::Vector3d xa = (Xf.row(a) - Xf.row(0)).transpose();
    t1 += dN[a * 2] * xa;
    t2 += dN[a * 2 + 1] * xa;
  }
  return t1.cross(t2).norm();
}

/// |dx/dxi| of a curve edge at a point with reference derivatives dN (2 per node, the first used).
double curve_jacobian(const FaceCoords &Xf, const double *dN) {
  Eigen::Vector3d t1 = Eigen::Vector3d::Zero();
  for (int a = 1; a < Xf.rows(); ++a) t1 += dN[a * 2] * (Xf.row(a) - Xf.row(0)).transpose();
  return t1.norm();
}

int face_degree(FaceType type) {
  switch (type) {
  case FaceType::Tri3:
    return kTri3Degree;
  case FaceType::Tri6:
    return kTri6Degree;
  case FaceType::Quad4:
    return kQuad4Degree;
  case FaceType::Line2:
  case FaceType::Line3:
    return kLineDegree;
  }
  throw Error("flexopt::fem: invalid FaceType value");
}

/// Returns sum_q w_q dA_q and fills nodal[a] = sum_q w_q dA_q N_a(q) if nodal is non-null.
double integrate_face(FaceType type, const FaceCoords &Xf, double *nodal) {
  const ShapeTable &tab = face_table(type, face_degree(type));
  const int n = tab.num_nodes;
  if (nodal) std::fill(nodal, nodal + n, 0.0);
  double area = 0.0;
  for (int q = 0; q < tab.num_points; ++q) {
    const double wda = tab.weights[q] * (type == FaceType::Line2 || type == FaceType::Line3
                                             ? curve_jacobian(Xf, &tab.dN[q * n * 2])
                                             : surface_jacobian(Xf, &tab.dN[q * n * 2]));
    area += wda;
    if (nodal)
      for (int a = 0; a < n; ++a) nodal[a] += wda * tab.N[q * n + a];
  }
  return area;
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
// Quadrature

QuadratureRule volume_quadrature(ElementType type, int degree) {
  check_degree(degree, "volume_quadrature");
  switch (type) {
  case ElementType::Tet4:
  case ElementType::Tet10:
    return tet_rule(degree);
  case ElementType::Hex8:
    return hex_rule(degree);
  }
  throw Error("volume_quadrature: invalid ElementType");
}

QuadratureRule face_quadrature(FaceType type, int degree) {
  check_degree(degree, "face_quadrature");
  switch (type) {
  case FaceType::Tri3:
  case FaceType::Tri6:
    return tri_rule(degree);
  case FaceType::Quad4:
    return quad_rule(degree);
  case FaceType::Line2:
  case FaceType::Line3: {
    std::vector<double> x, w;
    gauss_legendre(degree / 2 + 1, x, w);
    QuadratureRule rule;
    for (std::size_t k = 0; k < x.size(); ++k) {
      rule.points.emplace_back(x[k], 0.0, 0.0);
      rule.weights.push_back(w[k]);
    }
    return rule;
  }
  }
  throw Error("face_quadrature: invalid FaceType");
}

// -----------------------------------------------------------------------------------------------
// Shape functions

namespace {

/// Lagrange shape functions on a D-simplex in barycentric coordinates L (D + 1 of them, with
/// constant reference gradients dL): linear N_a = L_a, or quadratic with corner functions
/// L_a (2 L_a - 1) and, for edge e = (p, r) in Gmsh's edge order, 4 L_p L_r.
template <int D>
void simplex_lagrange(bool quadratic, const double *L, const double (*dL)[D], const int (*edges)[2],
                      double *N, double *dN) {
  constexpr int kCorners = D + 1, kEdges = D * (D + 1) / 2;
  for (int a = 0; a < kCorners; ++a) {
    const double f = quadratic ? L[a] * (2.0 * L[a] - 1.0) : L[a];
    const double g = quadratic ? 4.0 * L[a] - 1.0 : 1.0;
    if (N) N[a] = f;
    if (dN)
      for (int k = 0; k < D; ++k) dN[a * D + k] = g * dL[a][k];
  }
  if (!quadratic) return;
  for (int e = 0; e < kEdges; ++e) {
    const int p = edges[e][0], r = edges[e][1], n = kCorners + e;
    if (N) N[n] = 4.0 * L[p] * L[r];
    if (dN)
      for (int k = 0; k < D; ++k) dN[n * D + k] = 4.0 * (L[r] * dL[p][k] + L[p] * dL[r][k]);
  }
}

} // namespace

void shape_functions(ElementType type, const Eigen::Vector3d &xi, double *N, double *dN) {
  switch (type) {
  case ElementType::Tet4:
  case ElementType::Tet10: {
    const double L[4] = {1.0 - xi[0] - xi[1] - xi[2], xi[0], xi[1], xi[2]};
    static constexpr double kDL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    simplex_lagrange<3>(type == ElementType::Tet10, L, kDL, kTet10Edges, N, dN);
    return;
  }
  case ElementType::Hex8: {
    static constexpr double kS[8][3] = {{-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1},
                                        {-1, -1, 1},  {1, -1, 1},  {1, 1, 1},  {-1, 1, 1}};
    for (int a = 0; a < 8; ++a) {
      const double fx = 1.0 + kS[a][0] * xi[0];
      const double fy = 1.0 + kS[a][1] * xi[1];
      const double fz = 1.0 + kS[a][2] * xi[2];
      if (N) N[a] = 0.125 * fx * fy * fz;
      if (dN) {
        dN[a * 3 + 0] = 0.125 * kS[a][0] * fy * fz;
        dN[a * 3 + 1] = 0.125 * fx * kS[a][1] * fz;
        dN[a * 3 + 2] = 0.125 * fx * fy * kS[a][2];
      }
    }
    return;
  }
  }
  throw Error("shape_functions: invalid ElementType");
}

void face_shape_functions(FaceType type, const Eigen::Vector2d &xi, double *N, double *dN) {
  switch (type) {
  case FaceType::Tri3:
  case FaceType::Tri6: {
    const double L[3] = {1.0 - xi[0] - xi[1], xi[0], xi[1]};
    static constexpr double kDL[3][2] = {{-1, -1}, {1, 0}, {0, 1}};
    static constexpr int kTri6Edges[3][2] = {{0, 1}, {1, 2}, {2, 0}};
    simplex_lagrange<2>(type == FaceType::Tri6, L, kDL, kTri6Edges, N, dN);
    return;
  }
  case FaceType::Quad4: {
    static constexpr double kS[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (int a = 0; a < 4; ++a) {
      const double fx = 1.0 + kS[a][0] * xi[0];
      const double fy = 1.0 + kS[a][1] * xi[1];
      if (N) N[a] = 0.25 * fx * fy;
      if (dN) {
        dN[a * 2 + 0] = 0.25 * kS[a][0] * fy;
        dN[a * 2 + 1] = 0.25 * fx * kS[a][1];
      }
    }
    return;
  }
  case FaceType::Line2:
  case FaceType::Line3: {
    const double t = xi[0];
    if (type == FaceType::Line2) {
      if (N) {
        N[0] = 0.5 * (1.0 - t);
        N[1] = 0.5 * (1.0 + t);
      }
      if (dN) {
        dN[0] = -0.5, dN[1] = 0.0;
        dN[2] = 0.5, dN[3] = 0.0;
      }
    } else {
      if (N) {
        N[0] = 0.5 * t * (t - 1.0);
        N[1] = 0.5 * t * (t + 1.0);
        N[2] = 1.0 - t * t;
      }
      if (dN) {
        dN[0] = t - 0.5, dN[1] = 0.0;
        dN[2] = t + 0.5, dN[3] = 0.0;
        dN[4] = -2.0 * t, dN[5] = 0.0;
      }
    }
    return;
  }
  }
  throw Error("face_shape_functions: invalid FaceType");
}

Eigen::Vector3d reference_centroid(ElementType type) {
  switch (type) {
  case ElementType::Tet4:
  case ElementType::Tet10:
    return Eigen::Vector3d::Constant(0.25);
  case ElementType::Hex8:
    return Eigen::Vector3d::Zero();
  }
  throw Error("reference_centroid: invalid ElementType");
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

Eigen::Matrix3d displacement_gradient(ElementType type, const ElementCoords &X,
                                      const ElementVector &u_e, const Eigen::Vector3d &xi,
                                      const char *who) {
  check_coords(type, X, who);
  const int n = nodes_per_element(type);
  if (u_e.size() != 3 * n)
    throw Error(std::string(who) + ": " + element_name(type) + " needs " + std::to_string(3 * n) +
                " displacement entries, got " + std::to_string(u_e.size()));
  double dN[kMaxNodes * 3];
  shape_functions(type, xi, nullptr, dN);
  const Eigen::Matrix3d J = jacobian(X, dN);
  const double det = J.determinant();
  if (!(det > 0.0)) throw_degenerate(who, type, X, det, 0.0);
  const Eigen::Matrix3d Jinv = J.inverse();
  // H(i,j) = du_i/dx_j = sum_a u_(a,i) dN_a/dx_j.
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (int a = 0; a < n; ++a) {
    const Eigen::RowVector3d g = Eigen::Map<const Eigen::RowVector3d>(&dN[a * 3]) * Jinv; // dN_a/dx
    H += u_e.segment<3>(3 * a) * g;
  }
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

double von_mises(const Voigt &s) {
  const double d01 = s[0] - s[1], d12 = s[1] - s[2], d20 = s[2] - s[0];
  return std::sqrt(0.5 * (d01 * d01 + d12 * d12 + d20 * d20) +
                   3.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5]));
}

ElementVector face_traction_load(FaceType type, const FaceCoords &Xf, const Eigen::Vector3d &t) {
  check_face_coords(type, Xf, "face_traction_load");
  double nodal[kMaxFaceNodes];
  integrate_face(type, Xf, nodal);
  const int n = nodes_per_face(type);
  ElementVector f(3 * n);
  for (int a = 0; a < n; ++a)
    for (int i = 0; i < 3; ++i) f[3 * a + i] = nodal[a] * t[i];
  return f;
}

double face_area(FaceType type, const FaceCoords &Xf) {
  check_face_coords(type, Xf, "face_area");
  return integrate_face(type, Xf, nullptr);
}

bool locate_point(ElementType type, const ElementCoords &X, const Eigen::Vector3d &p,
                  Eigen::Vector3d &xi, double tol) {
  check_coords(type, X, "locate_point");
  const int n = nodes_per_element(type);
  // Newton on r(xi) = x(xi) - p. The map is affine for Tet4 and straight Tet10 (one step), and
  // mildly nonlinear otherwise; 50 iterations is far more than a converging Newton needs.
  constexpr int kMaxIterations = 50;
  // Reference coordinates are O(1); once the step is below 1e-12 the quadratic convergence has
  // put the iterate at roundoff level, and the step has already been applied.
  constexpr double kStepTol = 1e-12;
  // Beyond this the iterate has left any sensible neighbourhood of the element.
  constexpr double kDivergence = 1e3;
  xi = reference_centroid(type);
  const Eigen::Vector3d p_rel = p - X.row(0).transpose();
  double N[kMaxNodes], dN[kMaxNodes * 3];
  bool converged = false;
  for (int it = 0; it < kMaxIterations && !converged; ++it) {
    shape_functions(type, xi, N, dN);
    // x(xi) - p evaluated relative to node 0 (sum_a N_a = 1), as in jacobian().
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int a = 1; a < n; ++a) x += N[a] * (X.row(a) - X.row(0)).transpose();
    const Eigen::Matrix3d J = jacobian(X, dN);
    if (!(std::abs(J.determinant()) > 0.0)) return false;
    const Eigen::Vector3d step = J.partialPivLu().solve(p_rel - x);
    if (!step.allFinite()) return false;
    xi += step;
    converged = step.lpNorm<Eigen::Infinity>() <= kStepTol;
    if (xi.lpNorm<Eigen::Infinity>() > kDivergence) return false;
  }
  if (!converged) return false;
  switch (type) {
  case ElementType::Tet4:
  case ElementType::Tet10:
    return xi.minCoeff() >= -tol && xi.sum() <= 1.0 + tol;
  case ElementType::Hex8:
    return xi.cwiseAbs().maxCoeff() <= 1.0 + tol;
  }
  return false;
}

} // namespace flexopt::fem
