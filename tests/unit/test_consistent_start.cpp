// The velocity correction of the consistent start (docs/theory.md section 6.4,
// dynamics/consistent_start.hpp): only rigid-body velocities change, with the least change of
// kinetic energy, and the result satisfies Phi_q v + Phi_t = 0.
//
// Tolerances: the correction is one least-squares solve of a well-conditioned system of a few
// dozen unknowns (round-off ~1e-15 of the velocities); the checks allow 1e-11 of the velocity
// scale.
#include "dynamics_checks.hpp"
#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/dynamics/consistent_start.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"

#include <Eigen/QR>
#include <gtest/gtest.h>
#include <memory>

using namespace flexopt;
using bodies::Mat3;
using bodies::Vec3;
using dynamics::Matrix;
using dynamics::Vector;

namespace {

constexpr double kTol = 1e-11;

/// Velocities of every body of m from random translations and spins (p' = 1/2 G^T omega, so
/// that the normalizations hold), random elastic velocities.
Vector random_velocities(const dynamics::Mechanism &m, const Vector &q) {
  Vector v = Vector::Random(m.coordinates());
  for (int b = 0; b < static_cast<int>(m.bodies.size()); ++b) {
    const int o = m.offset(b);
    v.segment<4>(o + 3) =
        0.5 * bodies::g_matrix(q.segment<4>(o + 3)).transpose() * Vec3(Vec3::Random());
  }
  return v;
}

double violation(const dynamics::Mechanism &m, const Vector &q, const Vector &v, double t) {
  Vector phi, phi_t, phi_tt, phi_qt_v;
  Matrix J;
  m.constraint(q, t, phi, &J);
  m.constraint_time_terms(q, v, t, phi_t, phi_tt, phi_qt_v);
  return (J * v + phi_t).cwiseAbs().maxCoeff();
}

/// The mass-weighted correction of all velocities: [M J^T; J 0] [dv; mu] = [0; -(J v + Phi_t)].
Vector mass_weighted(const dynamics::Mechanism &m, const Vector &q, const Vector &v, double t) {
  const int n = m.coordinates(), k = m.constraints();
  Vector r, phi, phi_t, phi_tt, phi_qt_v;
  Matrix M, J;
  m.dynamics(q, v, Vector::Zero(n), t, r, nullptr, nullptr, &M);
  m.constraint(q, t, phi, &J);
  m.constraint_time_terms(q, v, t, phi_t, phi_tt, phi_qt_v);
  Matrix S = Matrix::Zero(n + k, n + k);
  S.topLeftCorner(n, n) = M;
  S.topRightCorner(n, k) = J.transpose();
  S.bottomLeftCorner(k, n) = J;
  Vector rhs = Vector::Zero(n + k);
  rhs.tail(k) = -(J * v + phi_t);
  return S.fullPivLu().solve(rhs).head(n);
}

/// A flexible pendulum: the synthetic FFRF body of n elastic coordinates (particles, as in
/// test_ffrf.cpp) on a spherical joint to the ground at a body point away from its frame
/// origin whose position depends on the elastic coordinates, and a rigid body hinged to it
/// by a revolute joint (coincidence + two perpendicularities) driven in rotation.
dynamics::Mechanism flexible_pendulum(int n, Vector &q0) {
  using K = joints::Equation::Kind;
  std::srand(5813);
  dynamics::Mechanism m;
  bodies::FfrfModel model;
  {
    // Particles at random positions with random basis vectors: the invariants of section 7.2.
    const int count = 8;
    Eigen::Matrix3Xd X = Eigen::Matrix3Xd::Random(3, count);
    std::vector<Eigen::Matrix3Xd> Psi(count, Eigen::Matrix3Xd::Random(3, n) * 0.1);
    Vector mass = (Vector::Random(count).array() + 1.5).matrix();
    auto &inv = model.invariants;
    inv.mass = mass.sum();
    inv.d0.setZero();
    inv.S0.setZero();
    inv.D = Matrix::Zero(3, n);
    inv.S1.assign(static_cast<std::size_t>(n), Mat3::Zero());
    inv.S2.assign(static_cast<std::size_t>(n),
                  std::vector<Mat3>(static_cast<std::size_t>(n), Mat3::Zero()));
    for (int i = 0; i < count; ++i) {
      const double mi = mass(i);
      const auto &P = Psi[static_cast<std::size_t>(i)];
      inv.d0 += mi * X.col(i);
      inv.S0 += mi * X.col(i) * X.col(i).transpose();
      inv.D += mi * P;
      for (int k = 0; k < n; ++k) {
        inv.S1[static_cast<std::size_t>(k)] += mi * X.col(i) * P.col(k).transpose();
        for (int l = 0; l < n; ++l)
          inv.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] +=
              mi * P.col(k) * P.col(l).transpose();
      }
    }
    model.stiffness = 100.0 * Matrix::Identity(n, n);
    model.damping = Matrix::Zero(n, n);
  }
  m.bodies.push_back(std::make_shared<bodies::FfrfBody>("flex", model));
  bodies::MassProperties rp;
  rp.mass = 1.7;
  rp.inertia = Mat3::Identity() * 0.3;
  rp.inertia(0, 1) = rp.inertia(1, 0) = 0.02;
  m.bodies.push_back(std::make_shared<bodies::RigidBody>("rigid", rp));
  for (int b = 0; b < 2; ++b) {
    joints::Equation e;
    e.kind = K::Normalize, e.a = b, e.owner = "normalize";
    m.equations.push_back(e);
  }
  // Spherical joint to the ground at the flexible body's point (0.3, 0, 0) + S zeta.
  joints::Equation pin;
  pin.kind = K::Coincide, pin.a = -1, pin.b = 0, pin.owner = "pin";
  pin.sa = Vec3(0.3, 0, 0), pin.sb = Vec3(0.3, 0, 0);
  pin.Sb = 0.5 * joints::Elastic::Random(3, n);
  m.equations.push_back(pin);
  // Revolute about z between the flexible body's point (-0.4, 0, 0) and the rigid body's
  // centre of mass, and a rotation driver on it.
  joints::Equation c;
  c.kind = K::Coincide, c.a = 0, c.b = 1, c.owner = "hinge";
  c.sa = Vec3(-0.4, 0, 0), c.sb = Vec3(0, 0, 0);
  c.Sa = 0.5 * joints::Elastic::Random(3, n);
  m.equations.push_back(c);
  for (const Vec3 &u : {Vec3::UnitX(), Vec3::UnitY()}) {
    joints::Equation p;
    p.kind = K::Perpendicular, p.a = 0, p.b = 1, p.owner = "hinge";
    p.ua = u, p.vb = Vec3::UnitZ();
    p.Ua = 0.5 * joints::Elastic::Random(3, n);
    m.equations.push_back(p);
  }
  joints::Equation d;
  d.kind = K::RotationDriver, d.a = 0, d.b = 1, d.owner = "driver";
  d.ua = Vec3::UnitX(), d.ua2 = Vec3::UnitY(), d.vb = Vec3::UnitX();
  d.driver = std::make_shared<const Expression>("3*t");
  m.equations.push_back(d);
  m.finalize();
  q0 = Vector::Zero(m.coordinates());
  q0(3) = 1;
  q0.segment<3>(7 + n) = Vec3(-0.4, 0, 0);
  q0(7 + n + 3) = 1;
  return m;
}

} // namespace

// For rigid bodies every coordinate is a rigid-body coordinate: the correction is the
// mass-weighted projection of all velocities, and the joints hold afterwards.
TEST(ConsistentStart, RigidChainEqualsTheMassWeightedProjection) {
  std::srand(4242);
  Vector q0;
  const auto m = test_support::chain(4, q0);
  const Vector v0 = random_velocities(m, q0);
  const auto c = dynamics::rigid_velocity_correction(m, q0, v0, 0.0);
  const Vector expected = mass_weighted(m, q0, v0, 0.0);
  const double scale = v0.cwiseAbs().maxCoeff();
  EXPECT_LT((c.dv - expected).cwiseAbs().maxCoeff(), kTol * scale);
  EXPECT_LT(c.residual, kTol * scale);
  EXPECT_LT(violation(m, q0, v0 + c.dv, 0.0), kTol * scale);
  EXPECT_GT(c.scale, 0.1); // the given velocities violated the joints
}

// A driven pendulum whose joints determine every speed: the result does not depend on the
// metric (it equals the Euclidean smallest correction, the rule before the rigid-body
// correction existed).
TEST(ConsistentStart, DeterminedSpeedsDoNotDependOnTheMetric) {
  Vector q0, dummy;
  auto chain = test_support::chain(1, q0);
  joints::Equation d;
  d.kind = joints::Equation::Kind::RotationDriver, d.a = -1, d.b = 0, d.owner = "driver";
  d.ua = Vec3::UnitX(), d.ua2 = Vec3::UnitY(), d.vb = Vec3::UnitX();
  d.driver = std::make_shared<const Expression>("2*t");
  chain.equations.push_back(d);
  chain.finalize();
  std::srand(99);
  const Vector v0 = random_velocities(chain, q0);
  const auto c = dynamics::rigid_velocity_correction(chain, q0, v0, 0.0);
  Vector phi, phi_t, phi_tt, phi_qt_v;
  Matrix J;
  chain.constraint(q0, 0.0, phi, &J);
  chain.constraint_time_terms(q0, v0, 0.0, phi_t, phi_tt, phi_qt_v);
  const Vector euclid = -J.completeOrthogonalDecomposition().solve(J * v0 + phi_t);
  EXPECT_LT((c.dv - euclid).cwiseAbs().maxCoeff(), kTol * v0.cwiseAbs().maxCoeff());
  // The link turns at the driver's 2 rad/s about z.
  const Vec3 omega = 2 * bodies::g_matrix(q0.segment<4>(3)) * (v0 + c.dv).segment<4>(3);
  EXPECT_NEAR(omega.z(), 2.0, 1e-12);
}

// With a flexible body: the elastic velocities are kept exactly, the joints hold, and the
// change is the least in kinetic energy among rigid-body changes: W y is orthogonal to every
// rigid-body change that keeps Phi_q v + Phi_t (the optimality condition of the weighted
// least-change problem).
TEST(ConsistentStart, ElasticVelocitiesAreKeptAndTheChangeIsLeast) {
  const int n = 3;
  Vector q0;
  const auto m = flexible_pendulum(n, q0);
  // Placed consistent in position: project as the integrator does.
  dynamics::GeneralizedAlpha ga(m, dynamics::AlphaParameters::from_rho_inf(0.8));
  dynamics::StartReport report;
  const Vector v0 = random_velocities(m, q0);
  const dynamics::State s = ga.initial_state(q0, v0, 0.0, &report);
  const Vector dv = s.v - v0;
  // Elastic velocities: exactly as given.
  EXPECT_EQ(dv.segment(7, n).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_FALSE(report.elastic_corrected);
  const double scale = v0.cwiseAbs().maxCoeff();
  EXPECT_LT(violation(m, s.q, s.v, 0.0), kTol * scale);
  // Optimality: with the rigid-body maps T_b (du, dw) -> (dr, dp) of both bodies and the
  // kinetic-energy metric W = T^T M T, dv = T y and W y lies in the range of (J T)^T.
  Matrix T = Matrix::Zero(m.coordinates(), 12);
  for (int b = 0; b < 2; ++b) {
    const int o = m.offset(b);
    T.block<3, 3>(o, 6 * b).setIdentity();
    T.block<4, 3>(o + 3, 6 * b + 3) = 0.5 * bodies::g_matrix(s.q.segment<4>(o + 3)).transpose();
  }
  Vector r, phi;
  Matrix M, J;
  m.dynamics(s.q, s.v, Vector::Zero(m.coordinates()), 0.0, r, nullptr, nullptr, &M);
  m.constraint(s.q, 0.0, phi, &J);
  const Matrix W = T.transpose() * M * T;
  const Vector y = T.completeOrthogonalDecomposition().solve(dv);
  EXPECT_LT((T * y - dv).cwiseAbs().maxCoeff(), kTol * scale); // dv is a rigid-body change
  const Matrix JT = J * T;
  const Eigen::FullPivLU<Matrix> lu(JT);
  const Matrix N = lu.kernel(); // rigid-body changes that keep the joints' rates
  ASSERT_GT(N.cols(), 0);       // the pin leaves the spin free: the metric matters
  EXPECT_LT((N.transpose() * W * y).cwiseAbs().maxCoeff(), kTol * (W * y).cwiseAbs().maxCoeff());
  // The reported kinetic energies are those of the given and the corrected velocities.
  EXPECT_NEAR(report.kinetic_given, 0.5 * v0.dot(M * v0), 1e-12 * report.kinetic_given);
  EXPECT_NEAR(report.kinetic, 0.5 * s.v.dot(M * s.v), 1e-12 * report.kinetic);
}

// Where the joints prescribe an elastic velocity (the flexible body held at a second point that
// the rigid-body velocities cannot satisfy), the mass-weighted correction of all velocities
// follows and the joints hold.
TEST(ConsistentStart, JointsThatNeedElasticVelocitiesFallBackToTheFullCorrection) {
  const int n = 3;
  Vector q0;
  auto m = flexible_pendulum(n, q0);
  // Fix the rigid body to the ground as well (a coincidence at its centre): with the pin, the
  // flexible body is held at two points whose distance only elastic coordinates can change,
  // and a driver moves the second point.
  joints::Equation g;
  g.kind = joints::Equation::Kind::TranslationDriver, g.a = -1, g.b = 1, g.owner = "push";
  g.ua = Vec3::UnitX(), g.sa = Vec3::Zero(), g.sb = Vec3::Zero(), g.c = -0.4;
  g.driver = std::make_shared<const Expression>("0.01*t");
  m.equations.push_back(g);
  for (const Vec3 &u : {Vec3::UnitY(), Vec3::UnitZ()}) {
    joints::Equation p;
    p.kind = joints::Equation::Kind::PointOnPlane, p.a = -1, p.b = 1, p.owner = "slot";
    p.ua = u, p.sa = Vec3::Zero(), p.sb = Vec3::Zero();
    m.equations.push_back(p);
  }
  m.finalize();
  dynamics::GeneralizedAlpha ga(m, dynamics::AlphaParameters::from_rho_inf(0.8));
  dynamics::StartReport report;
  const Vector v0 = Vector::Zero(m.coordinates());
  const dynamics::State s = ga.initial_state(q0, v0, 0.0, &report);
  EXPECT_TRUE(report.elastic_corrected);
  EXPECT_GT(report.rigid_residual, 1e-4);
  EXPECT_LT(violation(m, s.q, s.v, 0.0), 1e-13);
  EXPECT_GT(s.v.segment(7, n).cwiseAbs().maxCoeff(), 1e-6); // elastic velocities were needed
}
