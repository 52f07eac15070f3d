// The frame of an ACF body's elastic displacement (dynamics/interface_frame.hpp, docs/theory.md
// section 8.4), clamped and chord:
//  - a rigid motion of the body (nodes, interface nodes and the first interface's rotation moved
//    by one random rotation and translation) gives e = 0 to round-off, at any point;
//  - chord: the second interface's centroid moves along the frame's axis only, the frame does not
//    roll about its axis relative to the first interface, and, linearized, the frame rotation is
//    section 7.1's (theta0 . d^) d^ + d^ x (t1 - t0) / |d0|;
//  - the cotangent of w . e against central differences in x, r0, p0 (unnormalized) and r1;
//  - a chord turned by more than 90 degrees from the first interface's axis is refused.
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/interface_frame.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <random>

namespace {

using flexopt::dynamics::elastic_cotangent;
using flexopt::dynamics::FrameNodes;
using flexopt::dynamics::interface_frame;
using flexopt::reduce::FrameCondition;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Mat3 = Eigen::Matrix3d;

constexpr FrameCondition kFrames[] = {FrameCondition::Clamped, FrameCondition::Chord};

Vec3 random_vector(std::mt19937 &rng, double scale) {
  std::uniform_real_distribution<double> u(-1, 1);
  return scale * Vec3(u(rng), u(rng), u(rng));
}

/// Euler parameters (e0, e) of a random rotation by up to `angle`.
Vec4 random_rotation(std::mt19937 &rng, double angle) {
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Quaterniond q(Eigen::AngleAxisd(angle * u(rng), random_vector(rng, 1).normalized()));
  return Vec4(q.w(), q.x(), q.y(), q.z());
}

/// A link 0.6 m long between its interface centroids, away from the origin.
FrameNodes reference_link(FrameCondition condition) {
  FrameNodes n;
  n.condition = condition;
  n.c0 = Vec3(0.3, -0.1, 0.05);
  n.c1 = n.c0 + Vec3(0.55, 0.2, -0.1);
  n.r0 = n.c0;
  n.r1 = n.c1;
  return n;
}

/// The link moved rigidly by a random rotation R (Euler parameters p, up to 3 rad) and
/// translation t (up to `shift`), its interface nodes then displaced by up to `jitter`; the
/// first interface node turned by R.
struct Moved {
  FrameNodes n;
  Vec4 p;
  Mat3 R;
  Vec3 t;
};
Moved moved_link(FrameCondition condition, std::mt19937 &rng, double shift, double jitter) {
  Moved m{reference_link(condition), random_rotation(rng, 3.0), Mat3::Identity(), Vec3::Zero()};
  m.R = flexopt::bodies::rotation(m.p);
  m.t = random_vector(rng, shift);
  m.n.r0 = m.t + m.R * m.n.c0 + random_vector(rng, jitter);
  m.n.r1 = m.t + m.R * m.n.c1 + random_vector(rng, jitter);
  m.n.p0 = m.p;
  return m;
}

TEST(InterfaceFrame, RigidMotionHasNoElasticDisplacement) {
  std::mt19937 rng(7);
  for (const FrameCondition condition : kFrames)
    for (int trial = 0; trial < 20; ++trial) {
      const Moved m = moved_link(condition, rng, 2.0, 0.0);
      const FrameNodes &n = m.n;
      const Mat3 &R = m.R;
      const Vec3 &t = m.t;
      const auto f = interface_frame(n, "test", 0.0);
      for (int k = 0; k < 10; ++k) {
        const Vec3 X = n.c0 + random_vector(rng, 0.5);
        EXPECT_LT(f.elastic(t + R * X, X).norm(), 1e-15 * 8) << "trial " << trial;
      }
    }
}

TEST(InterfaceFrame, ChordHoldsTheSecondInterfaceOnItsAxisWithoutRoll) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    // A deformed state: the body moved rigidly, then its interfaces moved and turned elastically.
    Moved m = moved_link(FrameCondition::Chord, rng, 2.0, 0.01);
    FrameNodes &n = m.n;
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(m.p(0), m.p(1), m.p(2), m.p(3)) *
        Eigen::Quaterniond(
            Eigen::AngleAxisd(0.05 * (trial + 1) / 20.0, random_vector(rng, 1).normalized()));
    n.p0 = Vec4(q.w(), q.x(), q.y(), q.z());
    const auto f = interface_frame(n, "test", 0.0);
    const Vec3 d = n.c1 - n.c0, d_hat = d.normalized();
    // e(c1) at r1 lies along the axis, by the chord's stretch.
    const Vec3 e1 = f.elastic(n.r1, n.c1);
    EXPECT_LT((e1 - d_hat * d_hat.dot(e1)).norm(), 1e-15 * 8);
    EXPECT_NEAR(d_hat.dot(e1), (n.r1 - n.r0).norm() - d.norm(), 1e-15 * 8);
    // No roll about the axis relative to the first interface: A(p0)^T A_F turns about an axis
    // normal to d^.
    const Mat3 B = flexopt::bodies::rotation(n.p0).transpose() * f.A;
    const Eigen::AngleAxisd aa(B);
    EXPECT_LT(std::abs(aa.angle() * aa.axis().dot(d_hat)), 1e-14);
    EXPECT_LT((f.A.transpose() * f.A - Mat3::Identity()).norm(), 1e-14);
  }
}

TEST(InterfaceFrame, ChordLinearizesToTheReductionsFrame) {
  // Small interface motions t0, t1, theta0 of size eps about the reference: the frame's rotation
  // vector is (theta0 . d^) d^ + d^ x (t1 - t0) / |d0| + O(eps^2).
  std::mt19937 rng(3);
  FrameNodes n = reference_link(FrameCondition::Chord);
  const Vec3 d = n.c1 - n.c0, d_hat = d.normalized();
  for (const double eps : {1e-3, 1e-4}) {
    const Vec3 t0 = random_vector(rng, eps), t1 = random_vector(rng, eps);
    const Vec3 theta0 = random_vector(rng, eps);
    const Eigen::Quaterniond q(Eigen::AngleAxisd(theta0.norm(), theta0.normalized()));
    n.p0 = Vec4(q.w(), q.x(), q.y(), q.z());
    n.r0 = n.c0 + t0;
    n.r1 = n.c1 + t1;
    const Eigen::AngleAxisd aa(interface_frame(n, "test", 0.0).A);
    const Vec3 expected = theta0.dot(d_hat) * d_hat + d_hat.cross(t1 - t0) / d.norm();
    EXPECT_LT((aa.angle() * aa.axis() - expected).norm(), 10 * eps * eps) << "eps " << eps;
  }
}

TEST(InterfaceFrame, CotangentMatchesCentralDifferences) {
  std::mt19937 rng(5);
  for (const FrameCondition condition : kFrames)
    for (int trial = 0; trial < 5; ++trial) {
      Moved m = moved_link(condition, rng, 1.0, 0.02);
      FrameNodes &n = m.n;
      const Mat3 &R = m.R;
      const Vec3 &t = m.t;
      // Not unit: the frame differentiates the polynomial A(p), as the joints do.
      n.p0 = (m.p + 0.03 * Vec4::Random()) * 1.01;
      const Vec3 X = n.c0 + random_vector(rng, 0.4);
      const Vec3 x = t + R * X + random_vector(rng, 0.02);
      const Vec3 w = random_vector(rng, 1.0);
      auto value = [&](const FrameNodes &m, const Vec3 &y) {
        return w.dot(interface_frame(m, "test", 0.0).elastic(y, X));
      };
      const auto ct = elastic_cotangent(n, x, w, "test", 0.0);
      const double h = 1e-6, tol = 1e-8;
      for (int i = 0; i < 3; ++i) {
        Vec3 dx = Vec3::Zero();
        dx(i) = h;
        EXPECT_NEAR(ct.x(i), (value(n, x + dx) - value(n, x - dx)) / (2 * h), tol);
        FrameNodes a = n, b = n;
        a.r0(i) += h, b.r0(i) -= h;
        EXPECT_NEAR(ct.r0(i), (value(a, x) - value(b, x)) / (2 * h), tol) << "r0 " << i;
        a = n, b = n;
        a.r1(i) += h, b.r1(i) -= h;
        EXPECT_NEAR(ct.r1(i), (value(a, x) - value(b, x)) / (2 * h), tol) << "r1 " << i;
      }
      for (int i = 0; i < 4; ++i) {
        FrameNodes a = n, b = n;
        a.p0(i) += h, b.p0(i) -= h;
        EXPECT_NEAR(ct.p0(i), (value(a, x) - value(b, x)) / (2 * h), tol) << "p0 " << i;
      }
      if (condition == FrameCondition::Clamped) EXPECT_EQ(ct.r1.norm(), 0.0);
    }
}

TEST(InterfaceFrame, ChordTurnedBeyondAQuarterTurnIsRefused) {
  FrameNodes n = reference_link(FrameCondition::Chord);
  n.r1 = n.r0 - (n.c1 - n.c0); // the chord reversed
  EXPECT_THROW(interface_frame(n, "rod", 0.1), flexopt::Error);
  n.r1 = n.r0;
  EXPECT_THROW(interface_frame(n, "rod", 0.1), flexopt::Error);
}

} // namespace
