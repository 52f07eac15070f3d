/// \file Shape functions, the isoparametric map and its inverse (docs/theory.md section 3,
/// "Shape functions", "Geometry", "Inverse map").
#include "element_internal.hpp"
#include "flexopt/fem/element.hpp"

#include <cmath>
#include <sstream>
#include <string>

namespace flexopt::fem {

using namespace detail;

namespace detail {

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

/// Size scale h of an element: diagonal of the bounding box of its nodes.
double size_scale(const ElementCoords &X) {
  return (X.colwise().maxCoeff() - X.colwise().minCoeff()).norm();
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

} // namespace detail

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
