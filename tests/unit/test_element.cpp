// Unit tests of the element kernels (src/fem/element*.cpp). Each test asserts a mathematical fact;
// tolerances are stated next to the assertion with the reason for their size. Roundoff in a sum of
// m terms of size s is bounded by about m * eps * s (eps = 2.2e-16), which is where the "1e-14" and
// "1e-13" relative tolerances of exact identities come from.
#include "flexopt/fem/element.hpp"
#include "reference_elements.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>
#include <random>
#include <string>
#include <vector>

namespace {

using namespace flexopt::fem;
using Eigen::Vector3d;
using test_support::reference_nodes;

constexpr ElementType kAllTypes[] = {ElementType::Tet4, ElementType::Tet10, ElementType::Hex8};
constexpr FaceType kAllFaces[] = {FaceType::Tri3, FaceType::Tri6, FaceType::Quad4};
constexpr int kTet10Edges[6][2] = {{0, 1}, {1, 2}, {2, 0}, {3, 0}, {3, 2}, {3, 1}};

double factorial(int n) {
  double f = 1.0;
  for (int i = 2; i <= n; ++i) f *= i;
  return f;
}

/// Integral over [-1, 1] of x^a.
double cube_moment_1d(int a) {
  return a % 2 == 1 ? 0.0 : 2.0 / (a + 1);
}

Eigen::MatrixXd reference_face_nodes(FaceType type) {
  Eigen::MatrixXd X(nodes_per_face(type), 2);
  switch (type) {
  case FaceType::Tri3:
    X << 0, 0, 1, 0, 0, 1;
    break;
  case FaceType::Tri6:
    X << 0, 0, 1, 0, 0, 1, 0.5, 0, 0.5, 0.5, 0, 0.5;
    break;
  case FaceType::Quad4:
    X << -1, -1, 1, -1, 1, 1, -1, 1;
    break;
  }
  return X;
}

/// Random reference point strictly inside the element (margin 0.02 from the boundary).
Vector3d random_inside(ElementType type, std::mt19937 &rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  if (type == ElementType::Hex8)
    return Vector3d(u(rng), u(rng), u(rng)) * 1.9 - Vector3d::Ones() * 0.95;
  while (true) {
    Vector3d xi(u(rng), u(rng), u(rng));
    if (xi.minCoeff() > 0.02 && xi.sum() < 0.98) return xi;
  }
}

/// Physical point x(xi) = sum_a N_a(xi) X_a.
Vector3d map_point(ElementType type, const ElementCoords &X, const Vector3d &xi) {
  double N[kMaxNodes];
  shape_functions(type, xi, N, nullptr);
  Vector3d x = Vector3d::Zero();
  for (int a = 0; a < X.rows(); ++a) x += N[a] * X.row(a).transpose();
  return x;
}

/// Jacobian dx/dxi at xi, computed independently of the library's internals. Coordinates are
/// taken relative to node 0 (exact differences), so that the small element far from the origin
/// does not lose |x|/h digits to cancellation.
Eigen::Matrix3d map_jacobian(ElementType type, const ElementCoords &X, const Vector3d &xi) {
  double dN[kMaxDofs];
  shape_functions(type, xi, nullptr, dN);
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (int a = 1; a < X.rows(); ++a)
    J += (X.row(a) - X.row(0)).transpose() * Eigen::Map<const Eigen::RowVector3d>(&dN[3 * a]);
  return J;
}

struct TestElement {
  std::string name;
  ElementType type;
  ElementCoords X;
};

/// Distorted test elements of every type: a general Tet4, a straight-edged Tet10 on the same
/// corners, a curved Tet10 (mid-edge nodes displaced by up to ~6% of the edge length), a
/// non-affine Hex8, and a small curved Tet10 far from the origin (checks scale-invariance of all
/// relative tolerances).
std::vector<TestElement> test_elements() {
  std::vector<TestElement> out;
  ElementCoords tet4(4, 3);
  tet4 << 0.1, 0.0, -0.05, 1.2, 0.1, 0.05, 0.2, 0.9, 0.1, 0.15, 0.2, 1.1;
  out.push_back({"Tet4", ElementType::Tet4, tet4});

  ElementCoords tet10(10, 3);
  tet10.topRows(4) = tet4;
  for (int e = 0; e < 6; ++e)
    tet10.row(4 + e) = 0.5 * (tet4.row(kTet10Edges[e][0]) + tet4.row(kTet10Edges[e][1]));
  out.push_back({"Tet10 straight", ElementType::Tet10, tet10});

  ElementCoords curved = tet10;
  const double offsets[6][3] = {{0.03, -0.05, 0.02}, {-0.04, 0.02, 0.05},  {0.02, 0.04, -0.03},
                                {-0.05, 0.01, 0.03}, {0.03, -0.02, -0.04}, {0.01, 0.05, 0.02}};
  for (int e = 0; e < 6; ++e) curved.row(4 + e) += Eigen::RowVector3d(offsets[e]);
  out.push_back({"Tet10 curved", ElementType::Tet10, curved});

  ElementCoords hex = reference_nodes(ElementType::Hex8);
  const double hex_offsets[8][3] = {{0.10, -0.05, 0.08},  {-0.12, 0.07, 0.00}, {0.05, 0.15, -0.10},
                                    {-0.08, -0.06, 0.12}, {0.00, 0.10, -0.07}, {0.14, -0.09, 0.05},
                                    {-0.10, 0.04, 0.15},  {0.07, -0.12, -0.05}};
  for (int a = 0; a < 8; ++a) {
    hex.row(a) = 0.5 * hex.row(a).cwiseProduct(Eigen::RowVector3d(1.0, 0.8, 1.3)) +
                 0.3 * Eigen::RowVector3d(hex_offsets[a]);
  }
  out.push_back({"Hex8 distorted", ElementType::Hex8, hex});

  ElementCoords far = curved * 1e-3;
  far.rowwise() += Eigen::RowVector3d(5.0, -3.0, 7.0);
  out.push_back({"Tet10 curved small far", ElementType::Tet10, far});
  return out;
}

/// Stiffness assembled from the textbook definition sum_q w_q det J_q B_q^T D B_q, with an
/// explicitly built 6 x 3n strain-displacement matrix (engineering shear), as an independent
/// reference for the library's isotropic shortcut.
Eigen::MatrixXd reference_stiffness(ElementType type, const ElementCoords &X,
                                    const IsotropicMaterial &mat, double factor, int degree) {
  const int n = X.rows();
  const QuadratureRule rule = volume_quadrature(type, degree);
  const Eigen::Matrix<double, 6, 6> D = factor * mat.elasticity();
  Eigen::MatrixXd K = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (std::size_t q = 0; q < rule.points.size(); ++q) {
    double dN[kMaxDofs];
    shape_functions(type, rule.points[q], nullptr, dN);
    const Eigen::Matrix3d J = map_jacobian(type, X, rule.points[q]);
    const Eigen::Matrix3d Jinv = J.inverse();
    Eigen::MatrixXd B = Eigen::MatrixXd::Zero(6, 3 * n);
    for (int a = 0; a < n; ++a) {
      const Eigen::RowVector3d g = Eigen::Map<const Eigen::RowVector3d>(&dN[3 * a]) * Jinv;
      B(0, 3 * a) = g[0];
      B(1, 3 * a + 1) = g[1];
      B(2, 3 * a + 2) = g[2];
      B(3, 3 * a + 1) = g[2];
      B(3, 3 * a + 2) = g[1];
      B(4, 3 * a) = g[2];
      B(4, 3 * a + 2) = g[0];
      B(5, 3 * a) = g[1];
      B(5, 3 * a + 1) = g[0];
    }
    K += rule.weights[q] * J.determinant() * B.transpose() * D * B;
  }
  return K;
}

/// Engineering strain (Voigt) of the linear field u = A x + c.
Voigt strain_of(const Eigen::Matrix3d &A) {
  Voigt e;
  e << A(0, 0), A(1, 1), A(2, 2), A(1, 2) + A(2, 1), A(0, 2) + A(2, 0), A(0, 1) + A(1, 0);
  return e;
}

/// Nodal values of the linear field u = A (x - x_0) + c, x_0 = node 0. Writing the field relative
/// to a node keeps the nodal values' variation across the element at full relative precision;
/// with u = A x + c' and |x| >> h the input rounding alone (eps |u| / (|A| h)) would exceed the
/// tolerances for the element far from the origin.
ElementVector nodal_values(const ElementCoords &X, const Eigen::Matrix3d &A, const Vector3d &c) {
  ElementVector u(3 * X.rows());
  for (int a = 0; a < X.rows(); ++a)
    u.segment<3>(3 * a) = A * (X.row(a) - X.row(0)).transpose() + c;
  return u;
}

const IsotropicMaterial kSteel{210e9, 0.3, 7850.0};

// -----------------------------------------------------------------------------------------------
// Quadrature

TEST(Quadrature, TetRulesIntegrateMonomialsExactly) {
  // int_T x^a y^b z^c = a! b! c! / (a+b+c+3)!. All terms are positive, so the rule's roundoff is
  // a few eps relative: 1e-14 leaves a factor ~50 of margin.
  for (int degree = 0; degree <= 12; ++degree) {
    const QuadratureRule rule = volume_quadrature(ElementType::Tet10, degree);
    for (double w : rule.weights) EXPECT_GT(w, 0.0);
    for (const Vector3d &p : rule.points) {
      EXPECT_GE(p.minCoeff(), 0.0);
      EXPECT_LE(p.sum(), 1.0);
    }
    for (int a = 0; a <= degree; ++a)
      for (int b = 0; a + b <= degree; ++b)
        for (int c = 0; a + b + c <= degree; ++c) {
          double sum = 0.0;
          for (std::size_t q = 0; q < rule.points.size(); ++q) {
            const Vector3d &p = rule.points[q];
            sum += rule.weights[q] * std::pow(p[0], a) * std::pow(p[1], b) * std::pow(p[2], c);
          }
          const double exact =
              factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 3);
          EXPECT_NEAR(sum, exact, 1e-14 * exact)
              << "degree " << degree << " monomial " << a << " " << b << " " << c;
        }
  }
  // Tet4 and Tet10 share the reference tet and hence the rules.
  EXPECT_EQ(volume_quadrature(ElementType::Tet4, 2).points.size(), 4u);
  EXPECT_EQ(volume_quadrature(ElementType::Tet4, 1).points.size(), 1u);
}

TEST(Quadrature, HexRulesIntegrateMonomialsExactly) {
  // Degree per direction; odd moments vanish, so compare against the integral of |monomial|
  // (the natural scale of the roundoff of a positive-weight rule).
  for (int degree = 0; degree <= 11; ++degree) {
    const QuadratureRule rule = volume_quadrature(ElementType::Hex8, degree);
    const int per_direction = degree / 2 + 1;
    EXPECT_EQ(static_cast<int>(rule.points.size()), per_direction * per_direction * per_direction);
    for (int a = 0; a <= degree; ++a)
      for (int b = 0; b <= degree; ++b)
        for (int c = 0; c <= degree; ++c) {
          double sum = 0.0;
          for (std::size_t q = 0; q < rule.points.size(); ++q) {
            const Vector3d &p = rule.points[q];
            sum += rule.weights[q] * std::pow(p[0], a) * std::pow(p[1], b) * std::pow(p[2], c);
          }
          const double exact = cube_moment_1d(a) * cube_moment_1d(b) * cube_moment_1d(c);
          const double scale = 8.0 / ((a + 1) * (b + 1) * (c + 1)); // int |x^a y^b z^c|
          EXPECT_NEAR(sum, exact, 1e-14 * scale)
              << "degree " << degree << " monomial " << a << " " << b << " " << c;
        }
  }
}

TEST(Quadrature, FaceRulesIntegrateMonomialsExactly) {
  for (int degree = 0; degree <= 12; ++degree) {
    // Triangle: int x^a y^b = a! b! / (a+b+2)!.
    const QuadratureRule tri = face_quadrature(FaceType::Tri6, degree);
    for (std::size_t q = 0; q < tri.points.size(); ++q) {
      EXPECT_GT(tri.weights[q], 0.0);
      EXPECT_EQ(tri.points[q][2], 0.0);
    }
    for (int a = 0; a <= degree; ++a)
      for (int b = 0; a + b <= degree; ++b) {
        double sum = 0.0;
        for (std::size_t q = 0; q < tri.points.size(); ++q)
          sum += tri.weights[q] * std::pow(tri.points[q][0], a) * std::pow(tri.points[q][1], b);
        const double exact = factorial(a) * factorial(b) / factorial(a + b + 2);
        EXPECT_NEAR(sum, exact, 1e-14 * exact) << "tri degree " << degree << " " << a << " " << b;
      }
    // Quad [-1,1]^2, degree per direction.
    const QuadratureRule quad = face_quadrature(FaceType::Quad4, degree);
    for (int a = 0; a <= degree; ++a)
      for (int b = 0; b <= degree; ++b) {
        double sum = 0.0;
        for (std::size_t q = 0; q < quad.points.size(); ++q)
          sum += quad.weights[q] * std::pow(quad.points[q][0], a) * std::pow(quad.points[q][1], b);
        const double exact = cube_moment_1d(a) * cube_moment_1d(b);
        EXPECT_NEAR(sum, exact, 1e-14 * 4.0 / ((a + 1) * (b + 1)))
            << "quad degree " << degree << " " << a << " " << b;
      }
  }
  EXPECT_EQ(face_quadrature(FaceType::Tri3, 2).points.size(), 3u);
}

TEST(Quadrature, RejectsInvalidDegree) {
  EXPECT_THROW(volume_quadrature(ElementType::Tet4, -1), flexopt::Error);
  EXPECT_THROW(volume_quadrature(ElementType::Hex8, 1000), flexopt::Error);
  EXPECT_THROW(face_quadrature(FaceType::Quad4, -2), flexopt::Error);
}

// -----------------------------------------------------------------------------------------------
// Catalogue and shape functions

TEST(Catalogue, CountsAndNames) {
  EXPECT_EQ(nodes_per_element(ElementType::Tet4), 4);
  EXPECT_EQ(nodes_per_element(ElementType::Tet10), 10);
  EXPECT_EQ(nodes_per_element(ElementType::Hex8), 8);
  EXPECT_EQ(corner_nodes(ElementType::Tet4), 4);
  EXPECT_EQ(corner_nodes(ElementType::Tet10), 4);
  EXPECT_EQ(corner_nodes(ElementType::Hex8), 8);
  EXPECT_EQ(nodes_per_face(FaceType::Tri3), 3);
  EXPECT_EQ(nodes_per_face(FaceType::Tri6), 6);
  EXPECT_EQ(nodes_per_face(FaceType::Quad4), 4);
  EXPECT_STREQ(element_name(ElementType::Tet10), "Tet10");
  EXPECT_STREQ(element_name(ElementType::Hex8), "Hex8");
  EXPECT_STREQ(face_name(FaceType::Quad4), "Quad4");
  EXPECT_TRUE(reference_centroid(ElementType::Tet4).isApprox(Vector3d::Constant(0.25)));
  EXPECT_TRUE(reference_centroid(ElementType::Hex8).isZero());
}

TEST(ShapeFunctions, PartitionOfUnityAndKroneckerDelta) {
  std::mt19937 rng(7);
  for (ElementType type : kAllTypes) {
    const int n = nodes_per_element(type);
    const ElementCoords nodes = reference_nodes(type);
    double N[kMaxNodes], dN[kMaxDofs];
    // N_a(x_b) = delta_ab: values are 0 or 1 computed from O(1) numbers, exact to a few eps.
    for (int b = 0; b < n; ++b) {
      shape_functions(type, nodes.row(b).transpose(), N, nullptr);
      for (int a = 0; a < n; ++a)
        EXPECT_NEAR(N[a], a == b ? 1.0 : 0.0, 1e-15) << element_name(type) << " " << a << " " << b;
    }
    for (int trial = 0; trial < 20; ++trial) {
      shape_functions(type, random_inside(type, rng), N, dN);
      double sum = 0.0;
      Vector3d dsum = Vector3d::Zero();
      for (int a = 0; a < n; ++a) {
        sum += N[a];
        dsum += Eigen::Map<const Vector3d>(&dN[3 * a]);
      }
      EXPECT_NEAR(sum, 1.0, 1e-14) << element_name(type);
      EXPECT_LT(dsum.norm(), 1e-13) << element_name(type);
    }
  }
  for (FaceType type : kAllFaces) {
    const int n = nodes_per_face(type);
    const Eigen::MatrixXd nodes = reference_face_nodes(type);
    double N[kMaxFaceNodes], dN[2 * kMaxFaceNodes];
    for (int b = 0; b < n; ++b) {
      face_shape_functions(type, nodes.row(b).transpose(), N, nullptr);
      for (int a = 0; a < n; ++a) EXPECT_NEAR(N[a], a == b ? 1.0 : 0.0, 1e-15) << face_name(type);
    }
    face_shape_functions(type, Eigen::Vector2d(0.2, 0.3), N, dN);
    double sum = 0.0, dx = 0.0, dy = 0.0;
    for (int a = 0; a < n; ++a) {
      sum += N[a];
      dx += dN[2 * a];
      dy += dN[2 * a + 1];
    }
    EXPECT_NEAR(sum, 1.0, 1e-14);
    EXPECT_NEAR(dx, 0.0, 1e-13);
    EXPECT_NEAR(dy, 0.0, 1e-13);
  }
}

TEST(ShapeFunctions, DerivativesMatchCentralDifferences) {
  // Central differences with step 1e-5: truncation h^2/6 |N'''| <= ~1e-10 (N is at most
  // quadratic for tets and trilinear for Hex8, so truncation is in fact zero) plus cancellation
  // eps/h ~ 2e-11; 1e-7 is the brief's bound and is very safe.
  constexpr double kStep = 1e-5;
  std::mt19937 rng(11);
  for (ElementType type : kAllTypes) {
    const int n = nodes_per_element(type);
    for (int trial = 0; trial < 10; ++trial) {
      const Vector3d xi = random_inside(type, rng);
      double dN[kMaxDofs];
      shape_functions(type, xi, nullptr, dN);
      for (int k = 0; k < 3; ++k) {
        double Np[kMaxNodes], Nm[kMaxNodes];
        shape_functions(type, xi + kStep * Vector3d::Unit(k), Np, nullptr);
        shape_functions(type, xi - kStep * Vector3d::Unit(k), Nm, nullptr);
        for (int a = 0; a < n; ++a)
          EXPECT_NEAR(dN[3 * a + k], (Np[a] - Nm[a]) / (2 * kStep), 1e-7)
              << element_name(type) << " node " << a << " direction " << k;
      }
    }
  }
  for (FaceType type : kAllFaces) {
    const int n = nodes_per_face(type);
    const Eigen::Vector2d xi(0.21, 0.33);
    double dN[2 * kMaxFaceNodes];
    face_shape_functions(type, xi, nullptr, dN);
    for (int k = 0; k < 2; ++k) {
      double Np[kMaxFaceNodes], Nm[kMaxFaceNodes];
      face_shape_functions(type, xi + kStep * Eigen::Vector2d::Unit(k), Np, nullptr);
      face_shape_functions(type, xi - kStep * Eigen::Vector2d::Unit(k), Nm, nullptr);
      for (int a = 0; a < n; ++a)
        EXPECT_NEAR(dN[2 * a + k], (Np[a] - Nm[a]) / (2 * kStep), 1e-7) << face_name(type);
    }
  }
}

// -----------------------------------------------------------------------------------------------
// Material and von Mises

TEST(Material, ElasticityMatrixInvertsHookesLaw) {
  const IsotropicMaterial mat{2.0, 0.25, 1.0};
  EXPECT_DOUBLE_EQ(mat.mu(), 0.8);
  EXPECT_DOUBLE_EQ(mat.lambda(), 0.8);
  const Eigen::Matrix<double, 6, 6> D = mat.elasticity();
  EXPECT_TRUE(D.isApprox(D.transpose(), 0.0));
  // Uniaxial stress sigma_xx = 1: eps = (1, -nu, -nu)/E; gamma_xy = 2 eps_xy and tau_xy = 1
  // gives gamma = 1/mu. Compliance relations are exact rationals here, so 1e-15.
  Voigt eps;
  eps << 1.0 / mat.E, -mat.nu / mat.E, -mat.nu / mat.E, 0, 0, 1.0 / mat.mu();
  Voigt expected;
  expected << 1, 0, 0, 0, 0, 1;
  EXPECT_LT((D * eps - expected).norm(), 1e-15);
  EXPECT_THROW((IsotropicMaterial{1.0, 0.5, 1.0}.validate()), flexopt::Error);
  EXPECT_THROW((IsotropicMaterial{-1.0, 0.3, 1.0}.validate()), flexopt::Error);
  EXPECT_THROW((IsotropicMaterial{1.0, 0.3, -1.0}.validate()), flexopt::Error);
  EXPECT_NO_THROW((IsotropicMaterial{1.0, -0.5, 0.0}.validate()));
}

TEST(VonMises, KnownStressStates) {
  Voigt s = Voigt::Zero();
  s[0] = 3.0; // uniaxial: sigma_vm = |sigma|
  EXPECT_NEAR(von_mises(s), 3.0, 1e-15);
  s.setZero();
  s[5] = 2.0; // pure shear: sqrt(3) tau
  EXPECT_NEAR(von_mises(s), 2.0 * std::sqrt(3.0), 1e-15);
  s << 5, 5, 5, 0, 0, 0; // hydrostatic: 0
  EXPECT_EQ(von_mises(s), 0.0);
  // Invariance: adding a hydrostatic part does not change the value.
  Voigt t;
  t << 1.0, -2.0, 0.5, 0.3, -0.7, 1.1;
  Voigt t_shifted = t;
  t_shifted.head<3>().array() += 10.0;
  EXPECT_NEAR(von_mises(t), von_mises(t_shifted), 1e-13);
}

// -----------------------------------------------------------------------------------------------
// Stiffness

TEST(Stiffness, MatchesExplicitBTransposeDB) {
  // Library uses the isotropic closed form of B^T D B; compare with the textbook product using the
  // same quadrature rule as documented (Tet4: 1 point; Tet10: degree 2, degree 3 if curved; Hex8:
  // 2x2x2). Entries are sums of ~n_q * 36 products: 1e-13 relative to max |K|.
  for (const TestElement &el : test_elements()) {
    int degree = 0;
    if (el.type == ElementType::Tet10) degree = el.name.find("curved") != std::string::npos ? 3 : 2;
    if (el.type == ElementType::Hex8) degree = 3;
    const ElementMatrix K = element_stiffness(el.type, el.X, kSteel, 0.37);
    const Eigen::MatrixXd Kref = reference_stiffness(el.type, el.X, kSteel, 0.37, degree);
    EXPECT_LT((K - Kref).cwiseAbs().maxCoeff(), 1e-13 * Kref.cwiseAbs().maxCoeff()) << el.name;
    EXPECT_LT((K - K.transpose()).cwiseAbs().maxCoeff(), 1e-14 * K.cwiseAbs().maxCoeff())
        << el.name;
  }
}

TEST(Stiffness, FreeElementHasExactlySixZeroEigenvalues) {
  // Zero eigenvalues of a computed PSD matrix come out at roundoff, ~n eps max(lambda) = 1e-14;
  // the smallest non-zero eigenvalue of a reasonably shaped element is > 1e-3 max(lambda).
  for (const TestElement &el : test_elements()) {
    const ElementMatrix K = element_stiffness(el.type, el.X, kSteel);
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Eigen::MatrixXd(K), Eigen::EigenvaluesOnly);
    const Eigen::VectorXd lambda = eig.eigenvalues(); // ascending
    const double max_lambda = lambda[lambda.size() - 1];
    for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(lambda[i]), 1e-12 * max_lambda) << el.name;
    EXPECT_GT(lambda[6], 1e-8 * max_lambda) << el.name;
  }
}

TEST(Stiffness, RigidBodyModesAreInTheNullSpace) {
  for (const TestElement &el : test_elements()) {
    const ElementMatrix K = element_stiffness(el.type, el.X, kSteel, 0.5);
    const int n = el.X.rows();
    const Vector3d centre = el.X.colwise().mean().transpose();
    for (int mode = 0; mode < 6; ++mode) {
      ElementVector r(3 * n);
      for (int a = 0; a < n; ++a) {
        // Translations e_k, and infinitesimal rotations e_k x (x - centre); measuring the
        // position from the centre keeps |r| at the element size, so the roundoff bound
        // eps * |K| |r| is meaningful for the element far from the origin too.
        const Vector3d x = el.X.row(a).transpose() - centre;
        r.segment<3>(3 * a) = mode < 3 ? Vector3d::Unit(mode) : Vector3d::Unit(mode - 3).cross(x);
      }
      const double scale = K.cwiseAbs().maxCoeff() * r.cwiseAbs().maxCoeff();
      EXPECT_LT((K * r).cwiseAbs().maxCoeff(), 1e-12 * scale) << el.name << " mode " << mode;
    }
  }
}

TEST(Stiffness, IsLinearInTheModulusFactor) {
  for (const TestElement &el : test_elements()) {
    const ElementMatrix K1 = element_stiffness(el.type, el.X, kSteel, 1.0);
    const ElementMatrix K2 = element_stiffness(el.type, el.X, kSteel, 1e-3);
    EXPECT_LT((K2 - 1e-3 * K1).cwiseAbs().maxCoeff(), 1e-15 * K1.cwiseAbs().maxCoeff());
  }
}

TEST(Stiffness, ThrowsOnDegenerateOrInvertedElements) {
  for (const TestElement &el : test_elements()) {
    ElementCoords inverted = el.X;
    // Mirroring the element in the plane x = const turns every det J negative.
    inverted.col(0) *= -1.0;
    EXPECT_THROW(element_stiffness(el.type, inverted, kSteel), flexopt::Error) << el.name;
    EXPECT_THROW(element_mass(el.type, inverted, 1.0), flexopt::Error) << el.name;
    EXPECT_THROW(element_body_force(el.type, inverted, Vector3d::UnitX()), flexopt::Error);
    EXPECT_LT(element_volume(el.type, inverted), 0.0) << el.name;
    // Flattening the element onto z = 0 makes det J vanish.
    ElementCoords flat = el.X;
    flat.col(2).setConstant(0.3);
    EXPECT_THROW(element_stiffness(el.type, flat, kSteel), flexopt::Error) << el.name;
  }
  try {
    ElementCoords X = reference_nodes(ElementType::Tet4);
    X.row(3) = X.row(2);
    element_stiffness(ElementType::Tet4, X, kSteel);
    FAIL() << "no exception";
  } catch (const flexopt::Error &e) {
    EXPECT_NE(std::string(e.what()).find("degenerate or inverted"), std::string::npos);
  }
  // Wrong node count and invalid material.
  EXPECT_THROW(element_stiffness(ElementType::Tet10, reference_nodes(ElementType::Tet4), kSteel),
               flexopt::Error);
  EXPECT_THROW(element_stiffness(ElementType::Tet4, reference_nodes(ElementType::Tet4),
                                 IsotropicMaterial{1.0, 0.6, 1.0}),
               flexopt::Error);
}

// -----------------------------------------------------------------------------------------------
// Stress

TEST(Stress, LinearDisplacementGivesExactConstantStress) {
  // Isoparametric elements reproduce u = A x + c exactly (sum_a N_a = 1, sum_a N_a x_a = x), so
  // B u_e = eps(A) at every point of every element, curved or distorted. The only error is the
  // roundoff of J^-1 and of the sums: 1e-12 relative.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const TestElement &el : test_elements()) {
    Eigen::Matrix3d A;
    for (int i = 0; i < 9; ++i) A.data()[i] = 1e-3 * u(rng);
    // Translation of the size of the field's variation over the element (see nodal_values).
    const double h = (el.X.colwise().maxCoeff() - el.X.colwise().minCoeff()).norm();
    const Vector3d c = 1e-3 * h * Vector3d(u(rng), u(rng), u(rng));
    const double factor = 0.42;
    const Voigt exact = factor * kSteel.elasticity() * strain_of(A);
    const ElementVector ue = nodal_values(el.X, A, c);
    std::vector<Vector3d> points = volume_quadrature(el.type, 3).points;
    for (int i = 0; i < 10; ++i) points.push_back(random_inside(el.type, rng));
    const ElementCoords corners = reference_nodes(el.type);
    for (int a = 0; a < corners.rows(); ++a) points.push_back(corners.row(a).transpose());
    for (const Vector3d &xi : points) {
      const Voigt s = element_stress(el.type, el.X, kSteel, factor, ue, xi);
      EXPECT_LT((s - exact).norm(), 1e-12 * exact.norm()) << el.name << " at " << xi.transpose();
    }
  }
}

TEST(Stress, StressMatrixIsTheLinearMapOfElementStress) {
  // S = D B(xi) applied to any element displacement (not only linear fields) must give
  // element_stress's sigma with modulus factor 1: the two build sigma by different routes (S
  // column by column, element_stress through H), so agreement to 1e-13 relative checks every
  // entry of S.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const TestElement &el : test_elements()) {
    ElementVector ue(3 * el.X.rows());
    for (int k = 0; k < ue.size(); ++k) ue(k) = 1e-3 * u(rng);
    for (int i = 0; i < 4; ++i) {
      const Vector3d xi = i == 0 ? reference_centroid(el.type) : random_inside(el.type, rng);
      const StressMatrix S = element_stress_matrix(el.type, el.X, kSteel, xi);
      const Voigt expected = element_stress(el.type, el.X, kSteel, 1.0, ue, xi);
      EXPECT_LT((S * ue - expected).norm(), 1e-13 * expected.norm()) << el.name;
    }
  }
}

TEST(VonMises, GradientMatchesCentralDifferences) {
  // Central differences with h = 1e-6 |sigma|: truncation O(h^2) relative 1e-12, round-off
  // 1e-16 / 1e-6 = 1e-10 of |g| (which is O(1)); 1e-8 absolute holds both with room.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Voigt s;
    for (int k = 0; k < 6; ++k) s[k] = 1e8 * u(rng);
    const Voigt g = von_mises_gradient(s);
    const double h = 1e-6 * s.norm();
    for (int k = 0; k < 6; ++k) {
      Voigt sp = s, sm = s;
      sp[k] += h;
      sm[k] -= h;
      const double fd = (von_mises(sp) - von_mises(sm)) / (2 * h);
      EXPECT_NEAR(g[k], fd, 1e-8) << "component " << k;
    }
    // Homogeneous of degree 1: sigma . dv/dsigma = v (Euler).
    EXPECT_NEAR(s.dot(g), von_mises(s), 1e-12 * von_mises(s));
  }
  EXPECT_EQ(von_mises_gradient(Voigt::Zero()).norm(), 0.0);
}

// -----------------------------------------------------------------------------------------------
// Geometric stiffness

/// Stress tensor (3x3) of a Voigt stress.
Eigen::Matrix3d stress_tensor(const Voigt &s) {
  Eigen::Matrix3d S;
  S << s[0], s[5], s[4], s[5], s[1], s[3], s[4], s[3], s[2];
  return S;
}

/// Quadrature degree of element_stiffness for a test element (as in the stiffness test).
int stiffness_degree(const TestElement &el) {
  if (el.type == ElementType::Tet10) return el.name.find("curved") != std::string::npos ? 3 : 2;
  return el.type == ElementType::Hex8 ? 3 : 0;
}

TEST(GeometricStiffness, UniformStressGivesVolumeTimesTraceOfH2SigmaH2T) {
  // For u = H1 x the stress sigma = D eps(H1) is uniform and exact at every point (see the stress
  // test); for w = H2 x, grad w = H2 exactly, so w^T K_sigma w = int tr(H2 sigma H2^T) dV =
  // V tr(H2 sigma H2^T). The stiffness rule integrates det J exactly on every element here
  // (Tet4, affine Tet10: constant; curved Tet10: cubic, degree-3 rule; Hex8: degree 2 per
  // direction, 2x2x2 Gauss), so only roundoff remains: ~1e-14 relative; the bound asked is 1e-10.
  // The translations c1, c2 exercise K_sigma's null space (sum_b grad N_b = 0).
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  double worst = 0.0;
  for (const TestElement &el : test_elements()) {
    const double h = (el.X.colwise().maxCoeff() - el.X.colwise().minCoeff()).norm();
    for (int trial = 0; trial < 5; ++trial) {
      Eigen::Matrix3d H1, H2;
      for (int i = 0; i < 9; ++i) {
        H1.data()[i] = 1e-3 * u(rng);
        H2.data()[i] = u(rng);
      }
      const ElementVector ue = nodal_values(el.X, H1, 1e-3 * h * Vector3d(u(rng), u(rng), u(rng)));
      const ElementVector we = nodal_values(el.X, H2, h * Vector3d(u(rng), u(rng), u(rng)));
      const Eigen::Matrix3d sigma = stress_tensor(kSteel.elasticity() * strain_of(H1));
      const ElementMatrix Ks = element_geometric_stiffness(el.type, el.X, kSteel, ue);
      const double exact = element_volume(el.type, el.X) * (H2 * sigma * H2.transpose()).trace();
      const double err = std::abs(we.dot(Ks * we) - exact) / std::abs(exact);
      worst = std::max(worst, err);
      EXPECT_LT(err, 1e-10) << el.name;
      EXPECT_EQ((Ks - Ks.transpose()).cwiseAbs().maxCoeff(), 0.0) << el.name;
    }
  }
  std::printf("geometric stiffness: max relative error of w^T K_sigma w = V tr(H2 sigma H2^T): "
              "%.2e\n",
              worst);
}

TEST(GeometricStiffness, LoadIsTheDerivativeOfTheReducedPairing) {
  // element_geometric_stiffness_load(psi, G) . u = sum_kl G_kl psi_k^T K_sigma(u) psi_l for any
  // u (K_sigma is linear in u), for random vectors psi and a symmetric G: the identity the
  // adjoint of the reduced geometric stiffness rests on (docs/theory.md section 10, step 1).
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const TestElement &el : test_elements()) {
    const int n = el.X.rows();
    Eigen::MatrixXd psi(3 * n, 3), G(3, 3);
    for (int i = 0; i < psi.size(); ++i) psi.data()[i] = u(rng);
    for (int i = 0; i < G.size(); ++i) G.data()[i] = u(rng);
    G = 0.5 * (G + G.transpose()).eval();
    const ElementVector f = element_geometric_stiffness_load(el.type, el.X, kSteel, psi, G);
    for (int trial = 0; trial < 3; ++trial) {
      ElementVector ue(3 * n);
      for (int i = 0; i < 3 * n; ++i) ue[i] = u(rng);
      const ElementMatrix Ks = element_geometric_stiffness(el.type, el.X, kSteel, ue);
      const double pairing = (G.cwiseProduct(psi.transpose() * Ks * psi)).sum();
      EXPECT_NEAR(f.dot(ue), pairing, 1e-12 * (Ks * psi).cwiseAbs().sum()) << el.name;
    }
  }
}

TEST(GeometricStiffness, MatchesTheQuadratureOfPointStresses) {
  // Independent reference for a non-uniform stress (random nodal displacements): the stress from
  // element_stress at each point of the documented stiffness rule, and the textbook sum
  // K_(a,k),(b,k) = sum_q w_q det J_q grad N_a^T S_q grad N_b. Entries are sums of ~n_q * 9
  // products: 1e-13 relative to max |K_sigma|.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const TestElement &el : test_elements()) {
    const int n = el.X.rows();
    const double h = (el.X.colwise().maxCoeff() - el.X.colwise().minCoeff()).norm();
    ElementVector ue(3 * n);
    for (int i = 0; i < 3 * n; ++i) ue[i] = 1e-3 * h * u(rng);
    const QuadratureRule rule = volume_quadrature(el.type, stiffness_degree(el));
    Eigen::MatrixXd k = Eigen::MatrixXd::Zero(n, n);
    for (std::size_t q = 0; q < rule.points.size(); ++q) {
      double dN[kMaxDofs];
      shape_functions(el.type, rule.points[q], nullptr, dN);
      const Eigen::Matrix3d J = map_jacobian(el.type, el.X, rule.points[q]);
      Eigen::MatrixXd G(n, 3);
      for (int a = 0; a < n; ++a)
        G.row(a) = Eigen::Map<const Eigen::RowVector3d>(&dN[3 * a]) * J.inverse();
      const Eigen::Matrix3d S =
          stress_tensor(element_stress(el.type, el.X, kSteel, 1.0, ue, rule.points[q]));
      k += rule.weights[q] * J.determinant() * G * S * G.transpose();
    }
    const ElementMatrix Ks = element_geometric_stiffness(el.type, el.X, kSteel, ue);
    const double scale = k.cwiseAbs().maxCoeff();
    double diff = 0.0;
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            diff = std::max(diff, std::abs(Ks(3 * a + i, 3 * b + j) - (i == j ? k(a, b) : 0.0)));
    EXPECT_LT(diff, 1e-13 * scale) << el.name;
  }
}

TEST(GeometricStiffness, LinearInTheDisplacementAndBlindToRigidTranslations) {
  // K_sigma(u) is linear in u; a rigid translation has no stress (K_sigma(t) = 0 to roundoff) and
  // lies in K_sigma's null space (sum_b grad N_b = 0).
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const TestElement &el : test_elements()) {
    const int n = el.X.rows();
    const double h = (el.X.colwise().maxCoeff() - el.X.colwise().minCoeff()).norm();
    ElementVector u1(3 * n), u2(3 * n), t(3 * n);
    for (int i = 0; i < 3 * n; ++i) {
      u1[i] = 1e-3 * h * u(rng);
      u2[i] = 1e-3 * h * u(rng);
    }
    const Vector3d shift(u(rng), u(rng), u(rng));
    for (int a = 0; a < n; ++a) t.segment<3>(3 * a) = 1e-3 * h * shift;
    const ElementMatrix K1 = element_geometric_stiffness(el.type, el.X, kSteel, u1);
    const ElementMatrix K2 = element_geometric_stiffness(el.type, el.X, kSteel, u2);
    const ElementMatrix K12 = element_geometric_stiffness(el.type, el.X, kSteel, u1 - 0.5 * u2);
    const double scale = K1.cwiseAbs().maxCoeff() + K2.cwiseAbs().maxCoeff();
    EXPECT_LT((K12 - (K1 - 0.5 * K2)).cwiseAbs().maxCoeff(), 1e-13 * scale) << el.name;
    EXPECT_LT(element_geometric_stiffness(el.type, el.X, kSteel, t).cwiseAbs().maxCoeff(),
              1e-12 * scale)
        << el.name;
    ElementVector ones(3 * n);
    for (int a = 0; a < n; ++a) ones.segment<3>(3 * a) = shift;
    EXPECT_LT((K1 * ones).cwiseAbs().maxCoeff(), 1e-12 * scale * shift.norm()) << el.name;
  }
}

TEST(GeometricStiffness, ThrowsLikeTheStiffness) {
  for (const TestElement &el : test_elements()) {
    const ElementVector ue = ElementVector::Constant(3 * el.X.rows(), 1e-4);
    ElementCoords inverted = el.X;
    inverted.col(0) *= -1.0;
    EXPECT_THROW(element_geometric_stiffness(el.type, inverted, kSteel, ue), flexopt::Error)
        << el.name;
    ElementCoords flat = el.X;
    flat.col(2).setConstant(0.3);
    EXPECT_THROW(element_geometric_stiffness(el.type, flat, kSteel, ue), flexopt::Error) << el.name;
    EXPECT_THROW(element_geometric_stiffness(el.type, el.X, kSteel, ue.head(3)), flexopt::Error)
        << el.name;
    EXPECT_THROW(element_geometric_stiffness(el.type, el.X, IsotropicMaterial{1.0, 0.6, 1.0}, ue),
                 flexopt::Error)
        << el.name;
  }
  try {
    ElementCoords X = reference_nodes(ElementType::Tet4);
    X.row(3) = X.row(2);
    element_geometric_stiffness(ElementType::Tet4, X, kSteel, ElementVector::Zero(12));
    FAIL() << "no exception";
  } catch (const flexopt::Error &e) {
    EXPECT_NE(std::string(e.what()).find("degenerate or inverted"), std::string::npos);
  }
}

// -----------------------------------------------------------------------------------------------
// Small structured meshes for the patch and convergence tests

struct Mesh {
  ElementType type;
  std::vector<Vector3d> nodes;
  std::vector<bool> on_boundary;                    // per node
  std::vector<std::array<int, kMaxNodes>> elements; // Gmsh node ordering
  std::vector<std::array<int, 2>> mid_edge;         // per node: edge end vertices, or {-1, -1}
};

/// Unit cube with n^3 cells: Hex8 cells, or each cell split into the 6 Kuhn tets along its main
/// diagonal (translation-invariant, hence conforming). Nodes live on a (2n+1)^3 "fine" lattice
/// so that Tet10 mid-edge nodes have lattice positions too; unused lattice points are dropped.
Mesh cube_mesh(ElementType type, int n) {
  const int m = 2 * n + 1;
  auto lattice = [m](int i, int j, int k) { return (k * m + j) * m + i; };
  std::vector<int> id(m * m * m, -1);
  Mesh mesh{type, {}, {}, {}, {}};
  auto node = [&](int i, int j, int k) {
    int &slot = id[lattice(i, j, k)];
    if (slot < 0) {
      slot = static_cast<int>(mesh.nodes.size());
      mesh.nodes.emplace_back(double(i) / (2 * n), double(j) / (2 * n), double(k) / (2 * n));
      mesh.on_boundary.push_back(i == 0 || j == 0 || k == 0 || i == m - 1 || j == m - 1 ||
                                 k == m - 1);
      mesh.mid_edge.push_back({-1, -1});
    }
    return slot;
  };
  using Lattice = std::array<int, 3>;
  for (int ck = 0; ck < n; ++ck)
    for (int cj = 0; cj < n; ++cj)
      for (int ci = 0; ci < n; ++ci) {
        const Lattice base{2 * ci, 2 * cj, 2 * ck};
        if (type == ElementType::Hex8) {
          static constexpr int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                                {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
          std::array<int, kMaxNodes> el{};
          for (int a = 0; a < 8; ++a)
            el[a] = node(base[0] + 2 * kCorner[a][0], base[1] + 2 * kCorner[a][1],
                         base[2] + 2 * kCorner[a][2]);
          mesh.elements.push_back(el);
          continue;
        }
        static constexpr int kPerm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                            {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
        for (const auto &perm : kPerm) {
          std::array<Lattice, 4> v;
          v[0] = base;
          for (int s = 0; s < 3; ++s) {
            v[s + 1] = v[s];
            v[s + 1][perm[s]] += 2;
          }
          // Orient positively: odd permutations give negative volume; swap vertices 1 and 2.
          const Eigen::Vector3i e1(v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]);
          const Eigen::Vector3i e2(v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]);
          const Eigen::Vector3i e3(v[3][0] - v[0][0], v[3][1] - v[0][1], v[3][2] - v[0][2]);
          if (e1.dot(e2.cross(e3)) < 0) std::swap(v[1], v[2]);
          std::array<int, kMaxNodes> el{};
          for (int a = 0; a < 4; ++a) el[a] = node(v[a][0], v[a][1], v[a][2]);
          if (type == ElementType::Tet10)
            for (int e = 0; e < 6; ++e) {
              const Lattice &p = v[kTet10Edges[e][0]], &r = v[kTet10Edges[e][1]];
              el[4 + e] = node((p[0] + r[0]) / 2, (p[1] + r[1]) / 2, (p[2] + r[2]) / 2);
              mesh.mid_edge[el[4 + e]] = {el[kTet10Edges[e][0]], el[kTet10Edges[e][1]]};
            }
          mesh.elements.push_back(el);
        }
      }
  return mesh;
}

ElementCoords element_coords(const Mesh &mesh, int e) {
  const int n = nodes_per_element(mesh.type);
  ElementCoords X(n, 3);
  for (int a = 0; a < n; ++a) X.row(a) = mesh.nodes[mesh.elements[e][a]].transpose();
  return X;
}

/// Moves vertex nodes randomly by up to `vertex_shift` per coordinate, re-centres the mid-edge
/// nodes on their (now moved) edges, then moves them by up to `mid_shift` (curving the edges).
void distort(Mesh &mesh, double vertex_shift, double mid_shift, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
    if (mesh.mid_edge[i][0] < 0) mesh.nodes[i] += vertex_shift * Vector3d(u(rng), u(rng), u(rng));
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
    if (mesh.mid_edge[i][0] >= 0)
      mesh.nodes[i] = 0.5 * (mesh.nodes[mesh.mid_edge[i][0]] + mesh.nodes[mesh.mid_edge[i][1]]) +
                      mid_shift * Vector3d(u(rng), u(rng), u(rng));
}

Eigen::SparseMatrix<double> assemble_stiffness(const Mesh &mesh, const IsotropicMaterial &mat) {
  const int n = nodes_per_element(mesh.type);
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(mesh.elements.size() * 9 * n * n);
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const ElementMatrix K = element_stiffness(mesh.type, element_coords(mesh, e), mat);
    for (int a = 0; a < n; ++a)
      for (int b = 0; b < n; ++b)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j)
            triplets.emplace_back(3 * mesh.elements[e][a] + i, 3 * mesh.elements[e][b] + j,
                                  K(3 * a + i, 3 * b + j));
  }
  const int ndof = 3 * static_cast<int>(mesh.nodes.size());
  Eigen::SparseMatrix<double> K(ndof, ndof);
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

/// Solves K u = f with u prescribed (from `u`) at all boundary nodes; returns the full u.
Eigen::VectorXd solve_dirichlet(const Mesh &mesh, const Eigen::SparseMatrix<double> &K,
                                const Eigen::VectorXd &f, Eigen::VectorXd u) {
  const int ndof = static_cast<int>(u.size());
  std::vector<int> free_index(ndof, -1);
  int nfree = 0;
  for (int d = 0; d < ndof; ++d)
    if (!mesh.on_boundary[d / 3]) free_index[d] = nfree++;
  Eigen::VectorXd rhs(nfree);
  for (int d = 0; d < ndof; ++d)
    if (free_index[d] >= 0) rhs[free_index[d]] = f[d];
  std::vector<Eigen::Triplet<double>> triplets;
  for (int col = 0; col < K.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(K, col); it; ++it) {
      const int fr = free_index[it.row()], fc = free_index[it.col()];
      if (fr < 0) continue;
      if (fc >= 0)
        triplets.emplace_back(fr, fc, it.value());
      else
        rhs[fr] -= it.value() * u[it.col()];
    }
  Eigen::SparseMatrix<double> Kff(nfree, nfree);
  Kff.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(Kff);
  EXPECT_EQ(solver.info(), Eigen::Success);
  const Eigen::VectorXd uf = solver.solve(rhs);
  for (int d = 0; d < ndof; ++d)
    if (free_index[d] >= 0) u[d] = uf[free_index[d]];
  return u;
}

// -----------------------------------------------------------------------------------------------
// Patch test

struct PatchCase {
  const char *name;
  ElementType type;
  double vertex_shift; // relative to the cell size 1/3
  double mid_shift;
};

TEST(PatchTest, LinearFieldIsReproducedOnDistortedPatches) {
  // A 3x3x3 patch (Hex8: 27 non-affine hexes, 8 free interior nodes; tets: 162 elements) with
  // randomly moved nodes. For u = A x + c every element's stress is exactly D eps(A), so the
  // assembled internal force at each interior node is sigma : sum_e int_e grad N_i dV, which is
  // zero because N_i vanishes on the patch boundary -- provided the quadrature integrates
  // det J grad N_i exactly (Hex8 2x2x2, Tet10 degree 2 if straight / 3 if curved). Hence
  // (1) K u has zero rows at interior DOFs and (2) solving with the linear field prescribed on
  // the boundary gives it back at the interior nodes.
  const PatchCase cases[] = {{"Hex8", ElementType::Hex8, 0.25, 0.0},
                             {"Tet4", ElementType::Tet4, 0.2, 0.0},
                             {"Tet10 straight", ElementType::Tet10, 0.2, 0.0},
                             {"Tet10 curved", ElementType::Tet10, 0.2, 0.08}};
  Eigen::Matrix3d A;
  A << 0.3, -0.2, 0.5, 0.1, 0.7, -0.4, -0.6, 0.25, 0.15;
  const Vector3d c(0.1, -0.2, 0.3);
  for (const PatchCase &pc : cases) {
    Mesh mesh = cube_mesh(pc.type, 3);
    distort(mesh, pc.vertex_shift / 3.0, pc.mid_shift / 3.0, 1234);
    const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, kSteel);
    Eigen::VectorXd u(3 * mesh.nodes.size());
    for (std::size_t i = 0; i < mesh.nodes.size(); ++i) u.segment<3>(3 * i) = A * mesh.nodes[i] + c;
    // (1) Interior residual: each entry of K u is a sum of ~100 terms bounded by |K|max |u|max.
    const Eigen::VectorXd r = K * u;
    const double scale = Eigen::MatrixXd(K).cwiseAbs().maxCoeff() * u.cwiseAbs().maxCoeff();
    double max_interior = 0.0;
    int interior = 0;
    for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
      if (!mesh.on_boundary[i]) {
        max_interior = std::max(max_interior, r.segment<3>(3 * i).cwiseAbs().maxCoeff());
        ++interior;
      }
    EXPECT_GT(interior, 0);
    EXPECT_LT(max_interior, 1e-12 * scale) << pc.name;
    // (2) Solve: the stiffness condition number of the patch (~1e3) amplifies the residual
    // roundoff; 1e-10 relative to |u| leaves a wide margin.
    Eigen::VectorXd u0 = u;
    for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
      if (!mesh.on_boundary[i]) u0.segment<3>(3 * i).setZero();
    const Eigen::VectorXd uh = solve_dirichlet(mesh, K, Eigen::VectorXd::Zero(u.size()), u0);
    EXPECT_LT((uh - u).cwiseAbs().maxCoeff(), 1e-10 * u.cwiseAbs().maxCoeff()) << pc.name;
  }
}

// -----------------------------------------------------------------------------------------------
// Mass, volume, body force

TEST(Mass, TotalMassVolumeAndPositiveDefiniteness) {
  const double rho = 7850.0;
  // Tet with known volume |det[x1-x0, x2-x0, x3-x0]| / 6.
  const ElementCoords tet4 = test_elements()[0].X;
  const Eigen::Matrix3d edges = (Eigen::Matrix3d() << tet4.row(1) - tet4.row(0),
                                 tet4.row(2) - tet4.row(0), tet4.row(3) - tet4.row(0))
                                    .finished();
  const double tet_volume = std::abs(edges.determinant()) / 6.0;
  // Parallelepiped hex x = x0 + sum_k (xi_k + 1)/2 a_k: volume |det[a1 a2 a3]|.
  Eigen::Matrix3d spans;
  spans << 1.1, 0.2, -0.1, 0.3, 0.9, 0.25, 0.1, -0.2, 1.3; // columns a_k
  ElementCoords para(8, 3);
  const ElementCoords ref = reference_nodes(ElementType::Hex8);
  for (int a = 0; a < 8; ++a)
    para.row(a) =
        (Vector3d(0.5, -1.0, 2.0) + spans * (0.5 * (ref.row(a).transpose() + Vector3d::Ones())))
            .transpose();
  const double para_volume = std::abs(spans.determinant());

  struct Case {
    std::string name;
    ElementType type;
    ElementCoords X;
    double volume;
  };
  std::vector<Case> cases = {
      {"Tet4", ElementType::Tet4, tet4, tet_volume},
      {"Tet10 straight", ElementType::Tet10, test_elements()[1].X, tet_volume},
      {"Hex8 parallelepiped", ElementType::Hex8, para, para_volume}};
  // Curved/non-affine elements: compare with an independent high-degree integration of det J
  // (det J is a polynomial of degree 3 (curved Tet10) or 2 per direction (Hex8), so degree 8
  // rules are exact).
  for (const TestElement &el : test_elements()) {
    if (el.name.find("curved") == std::string::npos && el.type != ElementType::Hex8) continue;
    const QuadratureRule rule = volume_quadrature(el.type, 8);
    double v = 0.0;
    for (std::size_t q = 0; q < rule.points.size(); ++q)
      v += rule.weights[q] * map_jacobian(el.type, el.X, rule.points[q]).determinant();
    cases.push_back({el.name, el.type, el.X, v});
  }
  for (const Case &c : cases) {
    EXPECT_NEAR(element_volume(c.type, c.X), c.volume, 1e-13 * c.volume) << c.name;
    const ElementMatrix M = element_mass(c.type, c.X, rho);
    // sum_ab M = rho sum_ab int N_a N_b = rho int (sum N)^2 = rho V, per direction.
    EXPECT_NEAR(M.sum(), 3.0 * rho * c.volume, 1e-13 * 3.0 * rho * c.volume) << c.name;
    EXPECT_LT((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-15 * M.cwiseAbs().maxCoeff());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(Eigen::MatrixXd(M), Eigen::EigenvaluesOnly);
    EXPECT_GT(eig.eigenvalues()[0], 1e-6 * eig.eigenvalues().maxCoeff()) << c.name;
    // Different directions do not couple.
    EXPECT_EQ(M(0, 1), 0.0);
    EXPECT_EQ(M(0, 5), 0.0);
  }
  // Closed form for Tet4: M_ab = rho V (1 + delta_ab) / 20 (per direction).
  const ElementMatrix M = element_mass(ElementType::Tet4, tet4, rho);
  for (int a = 0; a < 4; ++a)
    for (int b = 0; b < 4; ++b)
      EXPECT_NEAR(M(3 * a + 1, 3 * b + 1), rho * tet_volume * (a == b ? 2.0 : 1.0) / 20.0,
                  1e-14 * rho * tet_volume);
}

TEST(Mass, ExactForCurvedAndNonAffineElements) {
  // The documented contract is exactness for every geometry of the type: N_a N_b det J is a
  // polynomial of degree 7 (curved Tet10) or 4 per direction (trilinear Hex8), and N_a det J of
  // degree 5 resp. 3. A degree-12 reference integration is therefore exact too, and both agree to
  // roundoff (1e-13 relative to the largest entry). The Tet4 and straight Tet10 are included to
  // cover the affine rules.
  const Vector3d b(0.3, -1.0, 2.0);
  for (const TestElement &el : test_elements()) {
    const int n = el.X.rows();
    const QuadratureRule rule = volume_quadrature(el.type, 12);
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd fn = Eigen::VectorXd::Zero(n);
    for (std::size_t q = 0; q < rule.points.size(); ++q) {
      Eigen::Matrix<double, kMaxNodes, 1> N;
      shape_functions(el.type, rule.points[q], N.data(), nullptr);
      const double wdet =
          rule.weights[q] * map_jacobian(el.type, el.X, rule.points[q]).determinant();
      m += wdet * N.head(n) * N.head(n).transpose();
      fn += wdet * N.head(n);
    }
    const ElementMatrix M = element_mass(el.type, el.X, 2.5);
    const ElementVector f = element_body_force(el.type, el.X, b);
    for (int a = 0; a < n; ++a) {
      for (int c = 0; c < n; ++c)
        EXPECT_NEAR(M(3 * a + 2, 3 * c + 2), 2.5 * m(a, c), 1e-13 * 2.5 * m.cwiseAbs().maxCoeff())
            << el.name << " " << a << " " << c;
      EXPECT_LT((f.segment<3>(3 * a) - fn[a] * b).norm(),
                1e-13 * b.norm() * fn.cwiseAbs().maxCoeff())
          << el.name << " " << a;
    }
  }
}

TEST(BodyForce, NodalLoadsSumToBTimesVolumeWithKnownSplit) {
  // Sum over nodes of f = b int sum_a N_a = b V; for affine elements the split is the classical
  // one: Tet4 V/4 each; Tet10 corners -V/20 and mid-edge nodes V/5; parallelepiped Hex8 V/8.
  const Vector3d b(1.5, -2.0, 9.81);
  for (const TestElement &el : test_elements()) {
    const ElementVector f = element_body_force(el.type, el.X, b);
    const double V = element_volume(el.type, el.X);
    Vector3d total = Vector3d::Zero();
    for (int a = 0; a < el.X.rows(); ++a) total += f.segment<3>(3 * a);
    EXPECT_LT((total - b * V).norm(), 1e-13 * b.norm() * V) << el.name;
    if (el.type == ElementType::Tet4)
      for (int a = 0; a < 4; ++a)
        EXPECT_LT((f.segment<3>(3 * a) - b * V / 4).norm(), 1e-14 * b.norm() * V);
    if (el.name == "Tet10 straight")
      for (int a = 0; a < 10; ++a)
        EXPECT_LT((f.segment<3>(3 * a) - b * V * (a < 4 ? -1.0 / 20 : 1.0 / 5)).norm(),
                  1e-14 * b.norm() * V)
            << a;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity() * 0.7;
  S(0, 1) = 0.2;
  S(2, 0) = -0.1;
  ElementCoords para = reference_nodes(ElementType::Hex8) * S.transpose();
  const ElementVector f = element_body_force(ElementType::Hex8, para, b);
  const double V = 8.0 * S.determinant();
  for (int a = 0; a < 8; ++a)
    EXPECT_LT((f.segment<3>(3 * a) - b * V / 8).norm(), 1e-14 * b.norm() * V);
}

// -----------------------------------------------------------------------------------------------
// Face loads

FaceCoords face_coords(std::initializer_list<Vector3d> rows) {
  FaceCoords X(static_cast<int>(rows.size()), 3);
  int i = 0;
  for (const Vector3d &r : rows) X.row(i++) = r.transpose();
  return X;
}

TEST(FaceLoad, FlatFacesHaveExactAreaAndLoads) {
  const Vector3d t(100.0, -50.0, 20.0);
  // A triangle in a tilted plane: area |(p1-p0) x (p2-p0)| / 2.
  const Vector3d p0(0.1, 0.2, 0.3), p1(1.4, 0.5, -0.2), p2(0.3, 1.1, 0.9);
  const double tri_area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
  const FaceCoords tri3 = face_coords({p0, p1, p2});
  const FaceCoords tri6 =
      face_coords({p0, p1, p2, 0.5 * (p0 + p1), 0.5 * (p1 + p2), 0.5 * (p2 + p0)});
  // A planar non-parallelogram quad (trapezoid in the plane spanned by e1, e2): shoelace area.
  const Vector3d o(1.0, 2.0, 3.0), e1 = Vector3d(1, 1, 0).normalized(),
                                   e2 = Vector3d(-1, 1, 2).normalized();
  const double q[4][2] = {{0, 0}, {2.0, 0.1}, {1.6, 1.2}, {0.3, 0.9}};
  double quad_area = 0.0;
  for (int i = 0; i < 4; ++i)
    quad_area += 0.5 * (q[i][0] * q[(i + 1) % 4][1] - q[(i + 1) % 4][0] * q[i][1]);
  FaceCoords quad(4, 3);
  for (int i = 0; i < 4; ++i) quad.row(i) = (o + q[i][0] * e1 + q[i][1] * e2).transpose();

  struct Case {
    FaceType type;
    FaceCoords X;
    double area;
  };
  for (const Case &c : {Case{FaceType::Tri3, tri3, tri_area}, Case{FaceType::Tri6, tri6, tri_area},
                        Case{FaceType::Quad4, quad, quad_area}}) {
    EXPECT_NEAR(face_area(c.type, c.X), c.area, 1e-14 * c.area) << face_name(c.type);
    const ElementVector f = face_traction_load(c.type, c.X, t);
    Vector3d total = Vector3d::Zero();
    for (int a = 0; a < c.X.rows(); ++a) total += f.segment<3>(3 * a);
    EXPECT_LT((total - t * c.area).norm(), 1e-14 * t.norm() * c.area) << face_name(c.type);
  }
  // Classical splits: Tri3 A/3 per node; straight Tri6: 0 at corners, A/3 at mid-edge nodes.
  const ElementVector f3 = face_traction_load(FaceType::Tri3, tri3, t);
  const ElementVector f6 = face_traction_load(FaceType::Tri6, tri6, t);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT((f3.segment<3>(3 * a) - t * tri_area / 3).norm(), 1e-14 * t.norm() * tri_area);
    EXPECT_LT(f6.segment<3>(3 * a).norm(), 1e-14 * t.norm() * tri_area);
    EXPECT_LT((f6.segment<3>(9 + 3 * a) - t * tri_area / 3).norm(), 1e-14 * t.norm() * tri_area);
  }
  EXPECT_THROW(face_area(FaceType::Tri6, tri3), flexopt::Error);
}

/// Tri6 on the graph of a quadratic z = g(x, y) over the triangle (0,0), (1,0), (0,1): quadratic
/// interpolation reproduces g exactly, so the face *is* that surface patch.
template <class G> FaceCoords quadratic_graph_tri6(G g) {
  const double xy[6][2] = {{0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0.5, 0.5}, {0, 0.5}};
  FaceCoords X(6, 3);
  for (int a = 0; a < 6; ++a) X.row(a) << xy[a][0], xy[a][1], g(xy[a][0], xy[a][1]);
  return X;
}

TEST(FaceLoad, CurvedTri6AreaMatchesIndependentValues) {
  // (1) Parabolic cylinder z = k x^2 / 2: area = int_0^1 (1 - x) sqrt(1 + k^2 x^2) dx
  //     = [sqrt(1+k^2) + asinh(k)/k] / 2 - [(1+k^2)^{3/2} - 1] / (3 k^2).
  // The integrand is analytic with singularities at x = +-i/k; a 6-point Gauss rule in x
  // (degree-10 collapsed rule) converges like rho^-12 with rho ~ 8.5 (k = 0.5), i.e. ~1e-11.
  const double k = 0.5;
  const FaceCoords cyl = quadratic_graph_tri6([k](double x, double) { return 0.5 * k * x * x; });
  const double exact = 0.5 * (std::sqrt(1 + k * k) + std::asinh(k) / k) -
                       (std::pow(1 + k * k, 1.5) - 1.0) / (3 * k * k);
  EXPECT_NEAR(face_area(FaceType::Tri6, cyl), exact, 1e-10 * exact);
  const Vector3d t(0.0, 0.0, -1e3);
  const ElementVector f = face_traction_load(FaceType::Tri6, cyl, t);
  Vector3d total = Vector3d::Zero();
  for (int a = 0; a < 6; ++a) total += f.segment<3>(3 * a);
  EXPECT_LT((total - t * face_area(FaceType::Tri6, cyl)).norm(), 1e-13 * t.norm() * exact);

  // (2) Doubly curved patch z = 0.3 x^2 + 0.2 x y - 0.25 y^2, compared with the area of the
  // inscribed polyhedron on a uniform m x m subdivision (error c2 h^2 + c4 h^4 + ...), Richardson-
  // extrapolated from m = 64 and 128: remaining error O(h^4) ~ 1e-9.
  auto g = [](double x, double y) { return 0.3 * x * x + 0.2 * x * y - 0.25 * y * y; };
  auto polyhedral_area = [&g](int m) {
    auto p = [&](int i, int j) {
      const double x = double(i) / m, y = double(j) / m;
      return Vector3d(x, y, g(x, y));
    };
    double area = 0.0;
    for (int j = 0; j < m; ++j)
      for (int i = 0; i + j < m; ++i) {
        area += 0.5 * (p(i + 1, j) - p(i, j)).cross(p(i, j + 1) - p(i, j)).norm();
        if (i + j + 1 < m)
          area += 0.5 * (p(i + 1, j + 1) - p(i + 1, j)).cross(p(i, j + 1) - p(i + 1, j)).norm();
      }
    return area;
  };
  const double reference = (4.0 * polyhedral_area(128) - polyhedral_area(64)) / 3.0;
  const FaceCoords patch = quadratic_graph_tri6(g);
  EXPECT_NEAR(face_area(FaceType::Tri6, patch), reference, 1e-8 * reference);
}

// -----------------------------------------------------------------------------------------------
// Inverse map

TEST(LocatePoint, RoundTripAndOutsidePoints) {
  // Newton converges quadratically to roundoff; the inverse map's conditioning (|J| |J^-1| ~ 10
  // for these elements) keeps the round-trip error near 1e-15, well inside 1e-10.
  std::mt19937 rng(5);
  for (const TestElement &el : test_elements()) {
    for (int trial = 0; trial < 25; ++trial) {
      const Vector3d xi = random_inside(el.type, rng);
      Vector3d found;
      ASSERT_TRUE(locate_point(el.type, el.X, map_point(el.type, el.X, xi), found)) << el.name;
      EXPECT_LT((found - xi).cwiseAbs().maxCoeff(), 1e-10) << el.name;
    }
    // Just outside (beyond the tolerance) and far outside.
    const Vector3d out_ref =
        el.type == ElementType::Hex8 ? Vector3d(1.05, 0.2, -0.3) : Vector3d(0.5, 0.3, 0.25);
    Vector3d found;
    EXPECT_FALSE(locate_point(el.type, el.X, map_point(el.type, el.X, out_ref), found)) << el.name;
    const double h = (el.X.colwise().maxCoeff() - el.X.colwise().minCoeff()).norm();
    const Vector3d far = el.X.colwise().mean().transpose() + Vector3d(3.0, -2.0, 1.0) * h;
    EXPECT_FALSE(locate_point(el.type, el.X, far, found)) << el.name;
    // A node is on the boundary: inside up to the tolerance.
    EXPECT_TRUE(locate_point(el.type, el.X, el.X.row(1).transpose(), found)) << el.name;
  }
}

// -----------------------------------------------------------------------------------------------
// Convergence

/// Manufactured solution: a sum of plane waves u = sum_m a_m sin(k_m . x + phi_m), for which
/// -div sigma(u) = sum_m [(lambda + mu)(a_m . k_m) k_m + mu |k_m|^2 a_m] sin(k_m . x + phi_m).
struct PlaneWaves {
  struct Wave {
    Vector3d k, a;
    double phi;
  };
  std::array<Wave, 3> waves{{{{1.2, 0.7, -0.9}, {1.0, 0.5, -0.3}, 0.3},
                             {{-0.5, 1.6, 1.1}, {-0.4, 1.0, 0.6}, 1.1},
                             {{0.8, -1.0, 1.5}, {0.2, -0.7, 1.0}, -0.4}}};
  Vector3d u(const Vector3d &x) const {
    Vector3d r = Vector3d::Zero();
    for (const Wave &w : waves) r += w.a * std::sin(w.k.dot(x) + w.phi);
    return r;
  }
  Vector3d body_force(const Vector3d &x, double lambda, double mu) const {
    Vector3d r = Vector3d::Zero();
    for (const Wave &w : waves)
      r += ((lambda + mu) * w.a.dot(w.k) * w.k + mu * w.k.squaredNorm() * w.a) *
           std::sin(w.k.dot(x) + w.phi);
    return r;
  }
};

struct ErrorNorms {
  double l2;
  double nodal_max;
};

ErrorNorms solve_manufactured(ElementType type, int n) {
  const IsotropicMaterial mat{1.0, 0.3, 1.0};
  const PlaneWaves exact;
  const Mesh mesh = cube_mesh(type, n);
  const int nn = nodes_per_element(type);
  const Eigen::SparseMatrix<double> K = assemble_stiffness(mesh, mat);
  // Load vector f_a = int N_a b(x) dV with a rule accurate far beyond the discretisation error
  // (degree 6 on tets, 4 points per direction on hexes).
  const QuadratureRule rule = volume_quadrature(type, type == ElementType::Hex8 ? 7 : 6);
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * mesh.nodes.size());
  double N[kMaxNodes];
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const ElementCoords X = element_coords(mesh, e);
    for (std::size_t q = 0; q < rule.points.size(); ++q) {
      shape_functions(type, rule.points[q], N, nullptr);
      const double wdet = rule.weights[q] * map_jacobian(type, X, rule.points[q]).determinant();
      const Vector3d b =
          exact.body_force(map_point(type, X, rule.points[q]), mat.lambda(), mat.mu());
      for (int a = 0; a < nn; ++a) f.segment<3>(3 * mesh.elements[e][a]) += wdet * N[a] * b;
    }
  }
  Eigen::VectorXd u0 = Eigen::VectorXd::Zero(f.size());
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
    if (mesh.on_boundary[i]) u0.segment<3>(3 * i) = exact.u(mesh.nodes[i]);
  const Eigen::VectorXd uh = solve_dirichlet(mesh, K, f, u0);

  ErrorNorms err{0.0, 0.0};
  for (std::size_t i = 0; i < mesh.nodes.size(); ++i)
    err.nodal_max = std::max(err.nodal_max, (uh.segment<3>(3 * i) - exact.u(mesh.nodes[i])).norm());
  for (std::size_t e = 0; e < mesh.elements.size(); ++e) {
    const ElementCoords X = element_coords(mesh, e);
    for (std::size_t q = 0; q < rule.points.size(); ++q) {
      shape_functions(type, rule.points[q], N, nullptr);
      Vector3d u_h = Vector3d::Zero();
      for (int a = 0; a < nn; ++a) u_h += N[a] * uh.segment<3>(3 * mesh.elements[e][a]);
      const double wdet = rule.weights[q] * map_jacobian(type, X, rule.points[q]).determinant();
      err.l2 += wdet * (u_h - exact.u(map_point(type, X, rule.points[q]))).squaredNorm();
    }
  }
  err.l2 = std::sqrt(err.l2);
  return err;
}

TEST(Convergence, ManufacturedSolutionOrders) {
  // Smooth solution, Dirichlet data interpolated on the whole boundary: a priori theory gives
  // ||u - u_h||_L2 = O(h^{p+1}): 2 for Hex8/Tet4, 3 for Tet10. The observed order between the
  // two finest meshes (n = 4 -> 8) must exceed 1.8 resp. 2.7.
  struct Case {
    ElementType type;
    double min_order;
  };
  for (const Case &c : {Case{ElementType::Hex8, 1.8}, Case{ElementType::Tet4, 1.8},
                        Case{ElementType::Tet10, 2.7}}) {
    const auto start = std::chrono::steady_clock::now();
    const int sizes[] = {2, 4, 8};
    ErrorNorms err[3];
    for (int i = 0; i < 3; ++i) err[i] = solve_manufactured(c.type, sizes[i]);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    for (int i = 0; i < 3; ++i) {
      std::printf("[convergence] %-5s n=%d  L2 error %.4e  nodal max error %.4e",
                  element_name(c.type), sizes[i], err[i].l2, err[i].nodal_max);
      if (i > 0)
        std::printf("  L2 order %.3f  nodal order %.3f", std::log2(err[i - 1].l2 / err[i].l2),
                    std::log2(err[i - 1].nodal_max / err[i].nodal_max));
      std::printf("\n");
    }
    std::printf("[convergence] %-5s total %.2f s\n", element_name(c.type), seconds);
    EXPECT_GT(std::log2(err[1].l2 / err[2].l2), c.min_order) << element_name(c.type);
    EXPECT_GT(std::log2(err[0].l2 / err[1].l2), c.min_order - 0.3) << element_name(c.type);
  }
}

} // namespace

// Edges (physical curves): consistent loads of a constant force per length.
TEST(EdgeLoad, LineElementsIntegrateForcePerLength) {
  using flexopt::fem::FaceCoords;
  using flexopt::fem::FaceType;
  const Eigen::Vector3d q(0.0, 0.0, -2.5);
  // Straight Line2 of length 3 in a skew direction: each end gets q L / 2.
  FaceCoords l2(2, 3);
  l2 << 1.0, 2.0, 3.0, 1.0 + 1.0, 2.0 + 2.0, 3.0 + 2.0; // direction (1, 2, 2), length 3
  EXPECT_NEAR(flexopt::fem::face_area(FaceType::Line2, l2), 3.0, 1e-14);
  auto f2 = flexopt::fem::face_traction_load(FaceType::Line2, l2, q);
  EXPECT_NEAR(f2[2], -2.5 * 1.5, 1e-14);
  EXPECT_NEAR(f2[5], -2.5 * 1.5, 1e-14);
  // Straight Line3 (mid node at the midpoint): L/6, L/6, 2L/3.
  FaceCoords l3(3, 3);
  l3 << 0, 0, 0, 2, 0, 0, 1, 0, 0;
  auto f3 = flexopt::fem::face_traction_load(FaceType::Line3, l3, q);
  EXPECT_NEAR(f3[2], -2.5 * 2.0 / 6.0, 1e-14);
  EXPECT_NEAR(f3[5], -2.5 * 2.0 / 6.0, 1e-14);
  EXPECT_NEAR(f3[8], -2.5 * 2.0 * 2.0 / 3.0, 1e-14);
  // Curved Line3: the parabola x = t, y = c (1 - t^2), t in [-1, 1] (nodes at t = -1, 1, 0).
  // Its length is 2 int_0^1 sqrt(1 + 4 c^2 t^2) dt, in closed form with asinh.
  const double c = 0.3;
  FaceCoords arc(3, 3);
  arc << -1, 0, 0, 1, 0, 0, 0, c, 0;
  const double a = 2.0 * c;
  const double exact = (std::sqrt(1 + a * a) + std::asinh(a) / a);
  EXPECT_NEAR(flexopt::fem::face_area(FaceType::Line3, arc), exact, 1e-6 * exact);
  auto fa = flexopt::fem::face_traction_load(FaceType::Line3, arc, q);
  EXPECT_NEAR(fa[2] + fa[5] + fa[8], -2.5 * flexopt::fem::face_area(FaceType::Line3, arc), 1e-13);
}
