// The co-rotated element of ACF bodies (fem/corotated.hpp, docs/theory.md section 8.1), for
// Tet4, Tet10 and Hex8 of a distorted reference shape (steel, element size 0.1 m), deformed by
// a random displacement of 2 % of the size and moved by a random large rotation:
//  - rigid motions: zero energy and force; E(Qx + t) = E(x), f(Qx + t) = Q f(x);
//  - no net force and no net moment (momentum conservation);
//  - f is the gradient of E and T the Hessian (central differences; symmetric);
//  - T = K at the reference configuration, and for Tet4 f = R K u~ (the textbook force);
//  - damping (corotated_damping): zero for rigid velocity fields, moment-free, f = dD/dv, Cv and
//    Cx against central differences, Cv = beta K at the reference.
#include "flexopt/fem/corotated.hpp"
#include "reference_elements.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <random>

namespace {

using namespace flexopt::fem;
using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr ElementType kTypes[] = {ElementType::Tet4, ElementType::Tet10, ElementType::Hex8};
const IsotropicMaterial kSteel{2.1e11, 0.3, 7850};

/// A distorted element of size ~0.1 m away from the origin, in Gmsh ordering (Tet10 mid-edge
/// nodes moved off the edge midpoints: a curved element; Hex8 of side 0.1 m).
ElementCoords reference_shape(ElementType type, std::mt19937 &rng) {
  std::uniform_real_distribution<double> jitter(-0.01, 0.01);
  ElementCoords X = test_support::reference_nodes(type);
  X *= type == ElementType::Hex8 ? 0.05 : 0.1;
  for (int a = 0; a < X.rows(); ++a)
    for (int i = 0; i < 3; ++i) X(a, i) += jitter(rng) + (i == 0 ? 3.0 : 1.0);
  return X;
}

Matrix3d random_rotation(std::mt19937 &rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  const Vector3d axis = Vector3d(u(rng), u(rng), u(rng)).normalized();
  return Eigen::AngleAxisd(3.0 * u(rng), axis).toRotationMatrix();
}

ElementCoords moved(const ElementCoords &x, const Matrix3d &Q, const Vector3d &t) {
  ElementCoords y = x;
  for (int a = 0; a < x.rows(); ++a) y.row(a) = (Q * x.row(a).transpose() + t).transpose();
  return y;
}

/// The reference deformed by 2 % of the element size at random, then rotated and moved.
ElementCoords deformed(const ElementCoords &X, std::mt19937 &rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  ElementCoords x = X;
  for (int a = 0; a < X.rows(); ++a)
    for (int i = 0; i < 3; ++i) x(a, i) += 0.002 * u(rng);
  return moved(x, random_rotation(rng), Vector3d(0.3, -0.2, 0.5));
}

/// A reference element, its co-rotated data and a deformed, moved configuration.
struct Sample {
  ElementCoords X, x;
  CorotatedElement e;
  Sample(ElementType type, std::mt19937 &rng)
      : X(reference_shape(type, rng)), e(corotated_element(type, X, kSteel)) {
    x = deformed(X, rng);
  }
};

/// check(type, sample) for every element type, the samples drawn from a generator seeded
/// with `seed`.
template <class Check> void for_each_sample(unsigned seed, Check &&check) {
  std::mt19937 rng(seed);
  for (ElementType type : kTypes) check(type, Sample(type, rng), rng);
}

double max_abs(const ElementVector &v) {
  return v.cwiseAbs().maxCoeff();
}

} // namespace

TEST(CorotatedElement, RigidMotionsAreFreeOfEnergyAndForce) {
  std::mt19937 rng(11);
  for (ElementType type : kTypes) {
    const ElementCoords X = reference_shape(type, rng);
    const CorotatedElement e = corotated_element(type, X, kSteel);
    const ElementCoords x = moved(X, random_rotation(rng), Vector3d(1, 2, -3));
    ElementVector f;
    const double E = corotated_state(e, x, &f, nullptr);
    // Scale: the force of a 1e-3 strain, |K| * 1e-4 m.
    const double fscale = e.K.cwiseAbs().maxCoeff() * 1e-4;
    EXPECT_LT(std::abs(E), 1e-20 * fscale) << element_name(type);
    EXPECT_LT(max_abs(f), 1e-9 * fscale) << element_name(type);
  }
}

TEST(CorotatedElement, InvariantUnderRigidMotionsWithoutNetForceOrMoment) {
  for_each_sample(12, [](ElementType type, const Sample &sm, std::mt19937 &rng) {
    (void)rng;
    const ElementCoords &X = sm.X, &x = sm.x;
    const CorotatedElement &e = sm.e;
    ElementVector f, fq;
    ElementMatrix T, Tq;
    const double E = corotated_state(e, x, &f, &T);
    const Matrix3d Q = random_rotation(rng);
    const double Eq = corotated_state(e, moved(x, Q, Vector3d(-1, 0.5, 2)), &fq, &Tq);
    EXPECT_GT(E, 0) << element_name(type);
    EXPECT_NEAR(Eq, E, 1e-12 * E) << element_name(type);
    const double fs = max_abs(f), ts = T.cwiseAbs().maxCoeff();
    Vector3d net = Vector3d::Zero(), moment = Vector3d::Zero();
    for (int a = 0; a < X.rows(); ++a) {
      const Vector3d fa = f.segment<3>(3 * a);
      EXPECT_LT((fq.segment<3>(3 * a) - Q * fa).cwiseAbs().maxCoeff(), 1e-10 * fs);
      for (int b = 0; b < X.rows(); ++b)
        EXPECT_LT((Tq.block<3, 3>(3 * a, 3 * b) - Q * T.block<3, 3>(3 * a, 3 * b) * Q.transpose())
                      .cwiseAbs()
                      .maxCoeff(),
                  1e-10 * ts);
      net += fa;
      moment += x.row(a).transpose().cross(fa);
    }
    // Relative to the largest nodal force times the element's distance from the origin (~3 m).
    EXPECT_LT(net.cwiseAbs().maxCoeff(), 1e-11 * fs) << element_name(type);
    EXPECT_LT(moment.cwiseAbs().maxCoeff(), 1e-11 * fs * 4) << element_name(type);
  });
}

TEST(CorotatedElement, ForceIsTheGradientAndTangentTheHessian) {
  for_each_sample(13, [](ElementType type, const Sample &sm, std::mt19937 &rng) {
    (void)rng;
    const ElementCoords &X = sm.X, &x = sm.x;
    const CorotatedElement &e = sm.e;
    ElementVector f;
    ElementMatrix T;
    corotated_state(e, x, &f, &T);
    const int nd = 3 * static_cast<int>(X.rows());
    // Central differences with a step of 1e-7 m (strain 1e-6 against the 2e-2 deformation):
    // truncation ~1e-12 relative, round-off ~1e-16 / 1e-7 * |E| / |f| ~ 1e-9 of f.
    const double step = 1e-7;
    ElementMatrix Tfd(nd, nd);
    ElementVector ffd(nd);
    for (int j = 0; j < nd; ++j) {
      ElementCoords xp = x, xm = x;
      xp(j / 3, j % 3) += step;
      xm(j / 3, j % 3) -= step;
      ElementVector fp, fm;
      const double Ep = corotated_state(e, xp, &fp, nullptr);
      const double Em = corotated_state(e, xm, &fm, nullptr);
      ffd(j) = (Ep - Em) / (2 * step);
      Tfd.col(j) = (fp - fm) / (2 * step);
    }
    const double fs = max_abs(f), ts = T.cwiseAbs().maxCoeff();
    EXPECT_LT(max_abs(f - ffd), 1e-6 * fs) << element_name(type);
    EXPECT_LT((T - Tfd).cwiseAbs().maxCoeff(), 1e-6 * ts) << element_name(type);
    // The Hessian is symmetric: the differences of f, which are not symmetrized, show it.
    EXPECT_LT((Tfd - Tfd.transpose()).cwiseAbs().maxCoeff(), 1e-6 * ts) << element_name(type);
  });
}

TEST(CorotatedElement, LinearLimitAndTheTet4Force) {
  std::mt19937 rng(14);
  for (ElementType type : kTypes) {
    const ElementCoords X = reference_shape(type, rng);
    const CorotatedElement e = corotated_element(type, X, kSteel);
    ElementVector f;
    ElementMatrix T;
    corotated_state(e, X, &f, &T);
    const double ks = e.K.cwiseAbs().maxCoeff();
    EXPECT_LT((T - e.K).cwiseAbs().maxCoeff(), 1e-12 * ks) << element_name(type);
  }
  // Tet4: F is constant, so for an isotropic material the local stress commutes with U and the
  // rotation's variation adds nothing: f = R_blk K u~.
  const ElementCoords X = reference_shape(ElementType::Tet4, rng);
  const CorotatedElement e = corotated_element(ElementType::Tet4, X, kSteel);
  const ElementCoords x = deformed(X, rng);
  ElementVector f;
  corotated_state(e, x, &f, nullptr);
  Matrix3d F = Matrix3d::Zero();
  for (int a = 1; a < 4; ++a) F += (x.row(a) - x.row(0)).transpose() * e.h.row(a); // sum_a h_a = 0
  const Matrix3d R = polar_rotation(F);
  Vector3d xc = Vector3d::Zero(), Xc = Vector3d::Zero();
  for (int a = 0; a < 4; ++a) {
    xc += 0.25 * x.row(a).transpose();
    Xc += 0.25 * X.row(a).transpose();
  }
  ElementVector u(12), Ru(12);
  for (int a = 0; a < 4; ++a)
    u.segment<3>(3 * a) = R.transpose() * (x.row(a).transpose() - xc) - (X.row(a).transpose() - Xc);
  const ElementVector g = e.K * u;
  for (int a = 0; a < 4; ++a) Ru.segment<3>(3 * a) = R * g.segment<3>(3 * a);
  EXPECT_LT(max_abs(f - Ru), 1e-10 * max_abs(f));
}

TEST(CorotatedElement, PolarRotationAndInvertedElements) {
  std::mt19937 rng(15);
  // F = Q S with S symmetric positive definite: the rotation is Q, for stretches from 1e-3 to 2.
  for (double stretch : {1e-3, 0.1, 1.0}) {
    const Matrix3d Q = random_rotation(rng);
    Matrix3d A = Matrix3d::Random();
    const Matrix3d S = Matrix3d::Identity() + stretch * (A * A.transpose()) / A.squaredNorm();
    EXPECT_LT((polar_rotation(Q * S) - Q).cwiseAbs().maxCoeff(), 1e-14) << stretch;
  }
  const ElementCoords X = reference_shape(ElementType::Tet4, rng);
  const CorotatedElement e = corotated_element(ElementType::Tet4, X, kSteel);
  ElementCoords x = X;
  x.row(3) = X.row(0) - (X.row(3) - X.row(0)); // node 3 mirrored through node 0: inverted
  try {
    corotated_state(e, x, nullptr, nullptr);
    FAIL() << "no error for an inverted element";
  } catch (const flexopt::Error &err) {
    EXPECT_NE(std::string(err.what()).find("inverted"), std::string::npos) << err.what();
  }
}

namespace {

/// A velocity of 1 m/s scale at every node: a rigid field (v0 + omega x x) plus a random part.
ElementVector velocities(const ElementCoords &x, std::mt19937 &rng, double random_part) {
  std::uniform_real_distribution<double> u(-1, 1);
  const Vector3d v0(u(rng), u(rng), u(rng)), omega(u(rng), u(rng), u(rng));
  ElementVector v(3 * x.rows());
  for (int a = 0; a < x.rows(); ++a)
    v.segment<3>(3 * a) =
        v0 + omega.cross(x.row(a).transpose()) + random_part * Vector3d(u(rng), u(rng), u(rng));
  return v;
}

} // namespace

// Damping (corotated_damping): a rigid velocity field dissipates nothing and gives no force at
// a deformed, rotated configuration (u~' = 0 exactly); the force has no net force or moment;
// the force is the gradient of D = P / 2 in v; Cv and Cx against central differences of f.
TEST(CorotatedDamping, RigidVelocitiesAreFreeAndTheForceIsMomentFree) {
  const double beta = 1e-3;
  for_each_sample(21, [&](ElementType type, const Sample &sm, std::mt19937 &rng) {
    const CorotatedElement &e = sm.e;
    const ElementCoords &x = sm.x;
    ElementVector f;
    const ElementVector rigid = velocities(x, rng, 0.0);
    const double P0 = corotated_damping(e, x, rigid, beta, &f, nullptr, nullptr);
    // Scale: the force of a 1 1/s strain rate, beta |K| * 0.1 m/s.
    const double fscale = beta * e.K.cwiseAbs().maxCoeff() * 0.1;
    EXPECT_LT(std::abs(P0), 1e-20 * fscale) << element_name(type);
    EXPECT_LT(max_abs(f), 1e-11 * fscale) << element_name(type);
    const ElementVector v = velocities(x, rng, 0.1);
    const double P = corotated_damping(e, x, v, beta, &f, nullptr, nullptr);
    EXPECT_GT(P, 0) << element_name(type);
    Vector3d net = Vector3d::Zero(), moment = Vector3d::Zero();
    for (int a = 0; a < x.rows(); ++a) {
      net += f.segment<3>(3 * a);
      moment += x.row(a).transpose().cross(f.segment<3>(3 * a));
    }
    const double fs = max_abs(f);
    EXPECT_LT(net.cwiseAbs().maxCoeff(), 1e-11 * fs) << element_name(type);
    EXPECT_LT(moment.cwiseAbs().maxCoeff(), 1e-11 * fs * 4) << element_name(type);
    // The power is f . v (D is quadratic in v).
    EXPECT_NEAR(f.dot(v), P, 1e-12 * P) << element_name(type);
  });
}

TEST(CorotatedDamping, ForceIsTheGradientAndBothTangentsTheDerivatives) {
  const double beta = 1e-3;
  for_each_sample(22, [&](ElementType type, const Sample &sm, std::mt19937 &rng) {
    const CorotatedElement &e = sm.e;
    const ElementCoords &x = sm.x;
    const ElementVector v = velocities(x, rng, 0.1);
    ElementVector f;
    ElementMatrix Cv, Cx;
    corotated_damping(e, x, v, beta, &f, &Cv, &Cx);
    const int nd = 3 * static_cast<int>(x.rows());
    // Central differences: in v with a step of 1e-4 m/s (D is quadratic in v: exact up to
    // round-off), in x with 1e-7 m (as for the elastic tangent).
    const double dv = 1e-4, dx = 1e-7;
    ElementVector ffd(nd);
    ElementMatrix Cvfd(nd, nd), Cxfd(nd, nd);
    for (int j = 0; j < nd; ++j) {
      ElementVector vp = v, vm = v, fp, fm;
      vp(j) += dv;
      vm(j) -= dv;
      const double Pp = corotated_damping(e, x, vp, beta, &fp, nullptr, nullptr);
      const double Pm = corotated_damping(e, x, vm, beta, &fm, nullptr, nullptr);
      ffd(j) = (Pp - Pm) / 2 / (2 * dv);
      Cvfd.col(j) = (fp - fm) / (2 * dv);
      ElementCoords xp = x, xm = x;
      xp(j / 3, j % 3) += dx;
      xm(j / 3, j % 3) -= dx;
      corotated_damping(e, xp, v, beta, &fp, nullptr, nullptr);
      corotated_damping(e, xm, v, beta, &fm, nullptr, nullptr);
      Cxfd.col(j) = (fp - fm) / (2 * dx);
    }
    const double fs = max_abs(f), cvs = Cv.cwiseAbs().maxCoeff(), cxs = Cx.cwiseAbs().maxCoeff();
    EXPECT_LT(max_abs(f - ffd), 1e-8 * fs) << element_name(type);
    EXPECT_LT((Cv - Cvfd).cwiseAbs().maxCoeff(), 1e-8 * cvs) << element_name(type);
    EXPECT_LT((Cx - Cxfd).cwiseAbs().maxCoeff(), 1e-6 * cxs) << element_name(type);
    // At the reference configuration and rest: Cv = beta K (the linear Rayleigh term).
    ElementMatrix C0;
    corotated_damping(e, sm.X, ElementVector::Zero(nd), beta, nullptr, &C0, nullptr);
    EXPECT_LT((C0 - beta * e.K).cwiseAbs().maxCoeff(), 1e-12 * beta * e.K.cwiseAbs().maxCoeff())
        << element_name(type);
  });
}

// The co-rotated von Mises stress (docs/theory.md section 8.3): invariant under rigid motions,
// equal to the linear stress in the small-displacement limit (where R -> I to first order), and
// its gradient (through the variation of R) against central differences.
TEST(CorotatedStress, InvariantLinearInTheLimitAndItsGradient) {
  for_each_sample(16, [](ElementType type, const Sample &sm, std::mt19937 &rng) {
    const ElementCoords &X = sm.X, &x = sm.x;
    const CorotatedElement &e = sm.e;
    const StressMatrix S = element_stress_matrix(type, X, kSteel, reference_centroid(type));
    ElementVector grad;
    const double v = corotated_von_mises(e, S, x, &grad);
    EXPECT_GT(v, 0) << element_name(type);
    const Matrix3d Q = random_rotation(rng);
    EXPECT_NEAR(corotated_von_mises(e, S, moved(x, Q, Vector3d(2, -1, 0.5)), nullptr), v, 1e-12 * v)
        << element_name(type);
    // A displacement of 1e-6 of the element size: the co-rotated stress is the linear one but
    // for terms quadratic in it (a relative 1e-6 and below).
    std::uniform_real_distribution<double> u(-1, 1);
    ElementVector du(3 * X.rows());
    for (int j = 0; j < du.size(); ++j) du(j) = 1e-7 * u(rng);
    ElementCoords xs = X;
    for (int a = 0; a < X.rows(); ++a) xs.row(a) += du.segment<3>(3 * a).transpose();
    const double vs = corotated_von_mises(e, S, xs, nullptr), vl = von_mises(S * du);
    EXPECT_NEAR(vs, vl, 1e-5 * vl) << element_name(type);
    // Central differences, step 1e-7 m (strain 1e-6 against the 2e-2 deformation): truncation
    // ~1e-12 relative, round-off ~1e-16 |v| / 1e-7 ~ 1e-9 of |grad| * size.
    const double step = 1e-7;
    ElementVector gfd(grad.size());
    for (int j = 0; j < grad.size(); ++j) {
      ElementCoords xp = x, xm = x;
      xp(j / 3, j % 3) += step;
      xm(j / 3, j % 3) -= step;
      gfd(j) = (corotated_von_mises(e, S, xp, nullptr) - corotated_von_mises(e, S, xm, nullptr)) /
               (2 * step);
    }
    EXPECT_LT(max_abs(grad - gfd), 1e-6 * max_abs(grad)) << element_name(type);
  });
}
