/// \file Face kernels: consistent traction loads and face areas (docs/theory.md section 3,
/// "Mass, volume, loads": the face traction).
#include "element_internal.hpp"
#include "flexopt/fem/element.hpp"

#include <algorithm>
#include <sstream>
#include <string>

namespace flexopt::fem {

using namespace detail;

namespace {

// Faces. Curved Tri6 and warped Quad4 have non-polynomial dA, so use generous rules: face loads are
// computed once per solve, on boundary faces only.
constexpr int kTri3Degree = 1;
constexpr int kTri6Degree = 10;
constexpr int kQuad4Degree = 7;
/// Edges: N_a |dx/dxi| is polynomial of degree 4 on a straight Line3 (|dx/dxi| linear in xi
/// only if curved; 5 Gauss points, degree 9, integrate curved Gmsh edges to round-off level).
constexpr int kLineDegree = 9;

void check_face_coords(FaceType type, const FaceCoords &Xf, const char *where) {
  if (Xf.rows() != nodes_per_face(type)) {
    std::ostringstream msg;
    msg << where << ": " << face_name(type) << " needs " << nodes_per_face(type)
        << " node coordinates, got " << Xf.rows();
    throw Error(msg.str());
  }
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

/// Calls visit(wda, N, x) at each point of the face rule of degree `degree`: the weight times
/// the surface (or curve) element, the shape functions and the physical point.
template <class Visit>
void for_face_points(FaceType type, const FaceCoords &Xf, int degree, Visit &&visit) {
  const ShapeTable &tab = face_table(type, degree);
  const int n = tab.num_nodes;
  const bool curve = type == FaceType::Line2 || type == FaceType::Line3;
  for (int q = 0; q < tab.num_points; ++q) {
    const double *dN = &tab.dN[static_cast<std::size_t>(q * n * 2)];
    const double wda = tab.weights[static_cast<std::size_t>(q)] *
                       (curve ? curve_jacobian(Xf, dN) : surface_jacobian(Xf, dN));
    const double *N = &tab.N[static_cast<std::size_t>(q * n)];
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int a = 0; a < n; ++a) x += N[a] * Xf.row(a).transpose();
    visit(wda, N, x);
  }
}

/// Returns sum_q w_q dA_q and fills nodal[a] = sum_q w_q dA_q N_a(q) if nodal is non-null.
double integrate_face(FaceType type, const FaceCoords &Xf, double *nodal) {
  const int n = nodes_per_face(type);
  if (nodal) std::fill(nodal, nodal + n, 0.0);
  double area = 0.0;
  for_face_points(type, Xf, face_degree(type), [&](double wda, const double *N, const auto &) {
    area += wda;
    if (nodal)
      for (int a = 0; a < n; ++a) nodal[a] += wda * N[a];
  });
  return area;
}

/// The rule for a linear field times N_a: exact on flat straight-sided faces (at least degree 2).
int linear_field_degree(FaceType type) {
  return std::max(face_degree(type), 2);
}

} // namespace

ElementVector face_linear_traction_load(FaceType type, const FaceCoords &Xf,
                                        const Eigen::Vector3d &t0, const Eigen::Matrix3d &T,
                                        const Eigen::Vector3d &c) {
  check_face_coords(type, Xf, "face_linear_traction_load");
  const int n = nodes_per_face(type);
  ElementVector f = ElementVector::Zero(3 * n);
  for_face_points(type, Xf, linear_field_degree(type),
                  [&](double wda, const double *N, const Eigen::Vector3d &x) {
                    const Eigen::Vector3d t = t0 + T * (x - c);
                    for (int a = 0; a < n; ++a)
                      for (int i = 0; i < 3; ++i) f[3 * a + i] += wda * N[a] * t[i];
                  });
  return f;
}

Eigen::Matrix3d face_second_moment(FaceType type, const FaceCoords &Xf, const Eigen::Vector3d &c) {
  check_face_coords(type, Xf, "face_second_moment");
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for_face_points(type, Xf, linear_field_degree(type),
                  [&](double wda, const double *, const Eigen::Vector3d &x) {
                    const Eigen::Vector3d r = x - c;
                    J += wda * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
                  });
  return J;
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

} // namespace flexopt::fem
