/// \file Quadrature rules and their tabulated shape functions (docs/theory.md section 3,
/// "Quadrature rules").
#include "element_internal.hpp"
#include "flexopt/fem/element.hpp"

#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace flexopt::fem {

using namespace detail;

namespace {

/// Rules up to this degree are tabulated once (points, weights, N, dN) in function-local statics.
constexpr int kMaxCachedDegree = 10;
/// Highest degree accepted by the public quadrature functions (21 Gauss points per direction).
constexpr int kMaxDegree = 40;

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

} // namespace

namespace detail {

// ---------------------------------------------------------------------------------------------
// Tabulated rules: weights and shape-function values at the points, built once per
// (type, degree) in thread-safe function-local statics so that the kernels never allocate.

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

} // namespace detail

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

} // namespace flexopt::fem
