#pragma once
/// \file Internals shared by the element kernels' files (src/fem/element*.cpp; private to
/// src/fem/): the degeneracy tolerance, the tabulated rules, the geometry helpers and the
/// quadrature degree of each kernel (docs/theory.md section 3).
#include "flexopt/fem/element.hpp"

#include <vector>

namespace flexopt::fem::detail {

/// det J below this fraction of h^3 (h: bounding-box diagonal of the nodes) counts as degenerate.
/// A well-shaped element has det J / h^3 of order 1e-2 to 1 (tet: det J = 6 V; hex: det J = V / 8),
/// so only elements that are flat to ~10 digits are rejected.
constexpr double kDegenerateTol = 1e-12;

/// A tabulated rule: weights and shape-function values at the points, built once per
/// (type, degree) in thread-safe function-local statics so that the kernels never allocate.
struct ShapeTable {
  int num_points = 0;
  int num_nodes = 0;
  std::vector<double> weights; // num_points
  std::vector<double> N;       // num_points x num_nodes
  std::vector<double> dN;      // num_points x num_nodes x dim (dim 3 for volumes, 2 for faces)
};

/// The tabulated rule of degree `degree` (<= kMaxCachedDegree) on the reference volume of `type`.
const ShapeTable &volume_table(ElementType type, int degree);
/// The tabulated rule of degree `degree` (<= kMaxCachedDegree) on the reference face of `type`.
const ShapeTable &face_table(FaceType type, int degree);

/// Throws flexopt::Error naming `where` unless X has nodes_per_element(type) rows.
void check_coords(ElementType type, const ElementCoords &X, const char *where);
/// Size scale h of an element: diagonal of the bounding box of its nodes.
double size_scale(const ElementCoords &X);

/// Gmsh Tet10 edges of the mid-edge nodes 4..9.
inline constexpr int kTet10Edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 0}, {3, 2}, {3, 1}};

/// What a kernel integrates (it sets the quadrature degree).
enum class Integrand { Stiffness, Mass, Volume, Load };

/// Quadrature degree for an integrand on a given element (docs/theory.md section 3).
int kernel_degree(ElementType type, const ElementCoords &X, double h, Integrand what);

/// Jacobian J(i,k) = dx_i / dxi_k = sum_a (X(a,i) - X(0,i)) dN(a,k), relative to node 0
/// (docs/theory.md section 3, "Geometry").
Eigen::Matrix3d jacobian(const ElementCoords &X, const double *dN);
/// Throws the "degenerate or inverted element" flexopt::Error of `where`.
[[noreturn]] void throw_degenerate(const char *where, ElementType type, const ElementCoords &X,
                                   double det, double threshold);

} // namespace flexopt::fem::detail
