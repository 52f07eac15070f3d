// Rigid-body dynamics: every derivative against central finite differences (rigid body inertial
// force, each constraint primitive's gradient, Hessian contraction and time derivatives, the
// loads, and the generalized-alpha step residual's Jacobians), and the quaternion helpers.
//
// Tolerances: central differences with step 1e-6 on functions of order 1 have truncation
// ~1e-12 and round-off ~1e-10; the checks use 1e-7 relative to the largest entry.
#include "dynamics_checks.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/mechanism.hpp"
#include "flexopt/dynamics/scene.hpp"

#include <gtest/gtest.h>
#include <memory>
#include <random>
#include <stdexcept>

using namespace flexopt;
using bodies::Mat3;
using bodies::Vec3;
using bodies::Vec4;
using dynamics::Matrix;
using dynamics::Vector;

namespace {

/// The joint type named as in case.yaml.
dynamics::JointType joint_type(const std::string &name) {
  using dynamics::JointType;
  for (JointType t :
       {JointType::Revolute, JointType::Spherical, JointType::Prismatic, JointType::Fixed})
    if (name == dynamics::joint_type_name(t)) return t;
  throw std::invalid_argument("no joint type " + name);
}

constexpr double kStep = 1e-6, kTol = 1e-7;

std::mt19937 &rng() {
  static std::mt19937 g(20261122);
  return g;
}
double uniform(double lo = -1, double hi = 1) {
  return std::uniform_real_distribution<double>(lo, hi)(rng());
}
Vec3 random3() {
  return Vec3(uniform(), uniform(), uniform());
}
/// Euler parameters near unit length (the derivatives hold for any p).
Vec4 random_p() {
  Vec4 p(uniform(), uniform(), uniform(), uniform());
  return p / p.norm() * (1 + 0.05 * uniform());
}

/// Central-difference Jacobian of f: R^n -> R^k at x.
template <class F> Matrix fd_jacobian(F f, const Vector &x, int k) {
  Matrix J(k, x.size());
  for (int j = 0; j < x.size(); ++j) {
    Vector xp = x, xm = x;
    xp(j) += kStep;
    xm(j) -= kStep;
    J.col(j) = (f(xp) - f(xm)) / (2 * kStep);
  }
  return J;
}

void expect_close(const Matrix &a, const Matrix &b, const char *what) {
  ASSERT_EQ(a.rows(), b.rows()) << what;
  ASSERT_EQ(a.cols(), b.cols()) << what;
  const double scale = std::max(1.0, b.cwiseAbs().maxCoeff());
  EXPECT_LE((a - b).cwiseAbs().maxCoeff(), kTol * scale) << what << "\nanalytic\n"
                                                         << a << "\nfinite differences\n"
                                                         << b;
}

bodies::MassProperties some_body() {
  bodies::MassProperties p;
  p.mass = 2.5;
  p.center = Vec3(0.1, -0.2, 0.05);
  Mat3 J;
  J << 0.3, 0.02, -0.01, 0.02, 0.5, 0.03, -0.01, 0.03, 0.4;
  p.inertia = J;
  return p;
}

/// Two free bodies, random state.
Vector random_q(int bodies) {
  Vector q(7 * bodies);
  for (int b = 0; b < bodies; ++b) {
    q.segment<3>(7 * b) = random3();
    q.segment<4>(7 * b + 3) = random_p();
  }
  return q;
}

} // namespace

TEST(Quaternion, RotationIsOrthogonalAndMatchesAxisAngle) {
  const Vec3 axis = random3().normalized();
  const double angle = 1.234;
  const Vec4 p = bodies::from_axis_angle(axis, angle);
  const Mat3 A = bodies::rotation(p);
  EXPECT_LT((A * A.transpose() - Mat3::Identity()).norm(), 1e-14);
  EXPECT_NEAR(A.determinant(), 1, 1e-14);
  // Rodrigues
  const Mat3 K = bodies::skew(axis);
  const Mat3 R = Mat3::Identity() + std::sin(angle) * K + (1 - std::cos(angle)) * K * K;
  EXPECT_LT((A - R).norm(), 1e-14);
  EXPECT_LT((bodies::from_matrix(A) - p).norm(), 1e-14);
  EXPECT_LT((bodies::rotation_vector(A) - angle * axis).norm(), 1e-13);
  // omega = 2 G p' for p' = d/dt p(axis, w t): omega = w axis.
  const double w = 0.7;
  const Vec4 pdot = 0.5 * w *
                    Vec4(-std::sin(0.5 * angle), std::cos(0.5 * angle) * axis.x(),
                         std::cos(0.5 * angle) * axis.y(), std::cos(0.5 * angle) * axis.z());
  EXPECT_LT((2 * bodies::g_matrix(p) * pdot - w * axis).norm(), 1e-14);
}

TEST(Quaternion, RotateJacobianAndHessian) {
  const Vec4 p = random_p();
  const Vec3 u = random3(), w = random3();
  auto f = [&](const Vector &x) -> Vector { return bodies::rotation(x) * u; };
  expect_close(bodies::rotate_jacobian(p, u), fd_jacobian(f, p, 3), "D(p, u)");
  auto g = [&](const Vector &x) -> Vector { return bodies::rotate_jacobian(x, u).transpose() * w; };
  expect_close(bodies::rotate_hessian(u, w), fd_jacobian(g, p, 4), "K(u, w)");
  auto t = [&](const Vector &x) -> Vector { return bodies::gbar_matrix(x).transpose() * w; };
  expect_close(bodies::gbar_transpose_matrix(w), fd_jacobian(t, p, 4), "T(w)");
}

TEST(RigidBody, InertialForceDerivatives) {
  bodies::RigidBody body("b", some_body());
  using V7 = bodies::RigidBody::Vec7;
  V7 q, v, a;
  q << random3(), random_p();
  v << random3(), 0.5 * Vec4(uniform(), uniform(), uniform(), uniform());
  a << random3(), Vec4(uniform(), uniform(), uniform(), uniform());
  bodies::RigidBody::Mat7 dq, dv, M;
  body.inertial_force(q, v, a, nullptr, &dq, &dv, &M);
  auto fq = [&](const Vector &x) -> Vector {
    V7 f;
    body.inertial_force(x, v, a, &f, nullptr, nullptr, nullptr);
    return f;
  };
  auto fv = [&](const Vector &x) -> Vector {
    V7 f;
    body.inertial_force(q, x, a, &f, nullptr, nullptr, nullptr);
    return f;
  };
  auto fa = [&](const Vector &x) -> Vector {
    V7 f;
    body.inertial_force(q, v, x, &f, nullptr, nullptr, nullptr);
    return f;
  };
  expect_close(dq, fd_jacobian(fq, q, 7), "df/dq");
  expect_close(dv, fd_jacobian(fv, v, 7), "df/dv");
  expect_close(M, fd_jacobian(fa, a, 7), "M");
}

// The rotational equation is Euler's: for unit p and p' _|_ p (so that w = 2 Gbar p' is the body
// angular velocity), Gbar f_p / 2 = J w' + w x J w with w' = 2 Gbar p''.
TEST(RigidBody, RotationalEquationIsEulers) {
  bodies::RigidBody body("b", some_body());
  using V7 = bodies::RigidBody::Vec7;
  const Vec4 p = random_p().normalized();
  const Vec3 w = random3(), wd = random3();
  const bodies::Mat34 G = bodies::gbar_matrix(p);
  const Vec4 pd = 0.5 * G.transpose() * w;
  // p'' from w' = 2 Gbar p'' and d/dt(p.p') = 0: p'' = 1/2 Gbar^T w' - |p'|^2 p.
  const Vec4 pdd = 0.5 * G.transpose() * wd - pd.squaredNorm() * p;
  V7 q, v, a, f;
  q << Vec3::Zero(), p;
  v << Vec3::Zero(), pd;
  a << Vec3::Zero(), pdd;
  body.inertial_force(q, v, a, &f, nullptr, nullptr, nullptr);
  const Mat3 &J = body.inertia();
  const Vec3 euler = J * wd + w.cross(J * w);
  EXPECT_LT((0.5 * G * f.tail<4>() - euler).norm(), 1e-12 * euler.norm());
}

namespace {

/// some_body() described about a reference point o away from its centre of mass (first moment
/// S = m (c - o), inertia J_o = J_c + m (|d|^2 I - d d^T), d = c - o).
bodies::MassProperties offset_body(const Vec3 &o) {
  const bodies::MassProperties c = some_body();
  const Vec3 d = c.center - o;
  bodies::MassProperties p;
  p.mass = c.mass;
  p.center = o;
  p.first = c.mass * d;
  p.inertia = c.inertia + c.mass * (d.squaredNorm() * Mat3::Identity() - d * d.transpose());
  return p;
}

} // namespace

// The terms of a first moment (docs/theory.md section 9.1) and the gravity potential they add:
// every derivative of the residual against central differences.
TEST(RigidBody, OffsetReferenceDerivatives) {
  const bodies::RigidBody body("b", offset_body(Vec3(0.3, 0.1, -0.2)));
  using V7 = bodies::RigidBody::Vec7;
  V7 q, v, a;
  q << random3(), random_p();
  v << random3(), 0.5 * Vec4(uniform(), uniform(), uniform(), uniform());
  a << random3(), Vec4(uniform(), uniform(), uniform(), uniform());
  const Vec3 g(0.3, -9.81, 1.2);
  Matrix K, C, M;
  V7 r;
  body.residual(q, v, a, g, r, &K, &C, &M);
  auto res = [&](const V7 &x, const V7 &y, const V7 &z) -> Vector {
    V7 out;
    body.residual(x, y, z, g, out, nullptr, nullptr, nullptr);
    return out;
  };
  expect_close(K, fd_jacobian([&](const Vector &x) { return res(x, v, a); }, q, 7), "K");
  expect_close(C, fd_jacobian([&](const Vector &x) { return res(q, x, a); }, v, 7), "C");
  expect_close(M, fd_jacobian([&](const Vector &x) { return res(q, v, x); }, a, 7), "M");
  EXPECT_LT((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-14 * M.cwiseAbs().maxCoeff());
  // Linear and homogeneous in the ten mass parameters.
  const Vector lin = body.parameter_jacobian(q, v, a, g) * bodies::to_parameters(body.properties());
  EXPECT_LT((lin - r).cwiseAbs().maxCoeff(), 1e-13 * r.cwiseAbs().maxCoeff());
}

// The same body described about its centre of mass and about another point o moves the same
// way: with r_c = r_o + A(p) d (d = c - o), the generalized forces in o's coordinates are the
// pull-back f_o = [f_c,r; D(p, d)^T f_c,r + f_c,p], on the Euler-parameter manifold (|p| = 1,
// p' _|_ p, p'' = 1/2 Gbar^T w' - |p'|^2 p), where only Gbar f_p is physical (the component
// along p goes to the normalization multiplier). Energies agree too.
TEST(RigidBody, OffsetReferenceDescribesTheSameMotion) {
  const bodies::MassProperties pc = some_body();
  const Vec3 o(0.3, 0.1, -0.2), d = pc.center - o;
  const bodies::RigidBody centroidal("c", pc), offset("o", offset_body(o));
  using V7 = bodies::RigidBody::Vec7;
  const Vec4 p = random_p().normalized();
  const bodies::Mat34 G = bodies::gbar_matrix(p);
  const Vec3 w = random3(), wd = random3();
  const Vec4 pd = 0.5 * G.transpose() * w;
  const Vec4 pdd = 0.5 * G.transpose() * wd - pd.squaredNorm() * p;
  const Vec3 rc = random3(), vc = random3(), ac = random3(), g(0.3, -9.81, 1.2);
  V7 qc, vcv, acv, qo, vo, ao;
  qc << rc, p;
  vcv << vc, pd;
  acv << ac, pdd;
  qo << rc - bodies::rotation(p) * d, p;
  vo << vc - bodies::rotate_jacobian(p, d) * pd, pd;
  ao << ac - bodies::rotate_jacobian(p, d) * pdd - bodies::rotate_jacobian(pd, d) * pd, pdd;
  V7 fc, fo;
  centroidal.residual(qc, vcv, acv, g, fc, nullptr, nullptr, nullptr);
  offset.residual(qo, vo, ao, g, fo, nullptr, nullptr, nullptr);
  const Vec3 fr = fc.head<3>();
  const Vec4 fp = bodies::rotate_jacobian(p, d).transpose() * fr + fc.tail<4>();
  const double scale = fc.cwiseAbs().maxCoeff();
  EXPECT_LT((fo.head<3>() - fr).norm(), 1e-13 * scale);
  EXPECT_LT((G * (fo.tail<4>() - fp)).norm(), 1e-13 * scale);
  const double ec = centroidal.energy(qc, vcv, g), eo = offset.energy(qo, vo, g);
  EXPECT_NEAR(eo, ec, 1e-13 * std::abs(ec));
  EXPECT_LT((offset.center_of_mass() - pc.center).norm(), 1e-15);
}

namespace {

/// The coordinate offsets of a mechanism of rigid bodies (7 per body), which
/// Mechanism::finalize() sets for equations used inside a mechanism.
joints::Equation rigid_layout(joints::Equation e) {
  e.oa = 7 * std::max(e.a, 0);
  e.ob = 7 * std::max(e.b, 0);
  return e;
}
std::vector<joints::Equation> rigid_layout(std::vector<joints::Equation> eqs) {
  for (auto &e : eqs) e = rigid_layout(e);
  return eqs;
}

/// One equation of each kind between body 0 and body 1 (and to the ground).
std::vector<joints::Equation> all_kinds() {
  using K = joints::Equation::Kind;
  auto driver = std::make_shared<const Expression>("0.3 + 2*t + 0.5*sin(3*t)");
  std::vector<joints::Equation> eqs;
  for (int ground = 0; ground < 2; ++ground) {
    const int a = ground ? -1 : 0, b = 1;
    joints::Equation e;
    e.a = a, e.b = b, e.sa = random3(), e.sb = random3(), e.ua = random3(), e.vb = random3(),
    e.ua2 = random3(), e.c = 0.1;
    for (K k : {K::Coincide, K::Perpendicular, K::PointOnPlane, K::RotationDriver,
                K::TranslationDriver}) {
      e.kind = k;
      e.driver = driver;
      e.owner = "test";
      eqs.push_back(rigid_layout(e));
    }
  }
  joints::Equation n;
  n.kind = K::Normalize;
  n.a = 1;
  eqs.push_back(rigid_layout(n));
  return eqs;
}

} // namespace

TEST(Constraints, GradientsHessiansAndTimeDerivatives) {
  const Vector q = random_q(2);
  Vector v(14);
  for (int i = 0; i < 14; ++i) v(i) = uniform();
  const double t = 0.37;
  for (const auto &e : all_kinds()) {
    const int k = e.rows();
    const std::string what =
        "kind " + std::to_string(static_cast<int>(e.kind)) + " a=" + std::to_string(e.a);
    auto phi = [&](const Vector &x) -> Vector {
      Vector out(k);
      e.value(x, t, out.data());
      return out;
    };
    Matrix J = Matrix::Zero(k, 14);
    e.gradient(q, t, J, 0);
    expect_close(J, fd_jacobian(phi, q, k), (what + ": gradient").c_str());
    Vector lambda(k);
    for (int i = 0; i < k; ++i) lambda(i) = uniform();
    Matrix H = Matrix::Zero(14, 14);
    e.add_hessian(q, t, lambda.data(), H);
    auto jtl = [&](const Vector &x) -> Vector {
      Matrix Jx = Matrix::Zero(k, 14);
      e.gradient(x, t, Jx, 0);
      return Jx.transpose() * lambda;
    };
    expect_close(H, fd_jacobian(jtl, q, 14), (what + ": Hessian").c_str());
    // Time derivatives (drivers) against differences in t.
    double pt[3], ptt[3], pqtv[3];
    e.time_derivatives(q, v, t, pt, ptt, pqtv);
    Vector tt(1);
    tt(0) = t;
    auto phi_t = [&](const Vector &x) -> Vector {
      Vector out(k);
      e.value(q, x(0), out.data());
      return out;
    };
    auto phit_t = [&](const Vector &x) -> Vector {
      double a1[3], b1[3], c1[3];
      e.time_derivatives(q, v, x(0), a1, b1, c1);
      return Eigen::Map<Vector>(a1, k);
    };
    auto jv_t = [&](const Vector &x) -> Vector {
      Matrix Jx = Matrix::Zero(k, 14);
      e.gradient(q, x(0), Jx, 0);
      return Jx * v;
    };
    expect_close(Eigen::Map<Vector>(pt, k), fd_jacobian(phi_t, tt, k), (what + ": phi_t").c_str());
    expect_close(Eigen::Map<Vector>(ptt, k), fd_jacobian(phit_t, tt, k),
                 (what + ": phi_tt").c_str());
    expect_close(Eigen::Map<Vector>(pqtv, k), fd_jacobian(jv_t, tt, k),
                 (what + ": phi_qt v").c_str());
  }
}

namespace {

/// Two bodies, a spherical joint between them, a revolute to the ground, a driver, gravity and
/// a time-dependent point force: every term of the dynamics residual.
dynamics::Mechanism two_body_mechanism() {
  dynamics::Mechanism m;
  m.bodies.push_back(std::make_shared<bodies::RigidBody>("a", some_body()));
  auto p2 = some_body();
  p2.mass = 1.3;
  m.bodies.push_back(std::make_shared<bodies::RigidBody>("b", p2));
  m.gravity = Vec3(0, -9.81, 0.5);
  for (int b = 0; b < 2; ++b) {
    joints::Equation n;
    n.kind = joints::Equation::Kind::Normalize;
    n.a = b;
    n.owner = "body";
    m.equations.push_back(n);
  }
  for (const auto &e : all_kinds())
    if (e.kind != joints::Equation::Kind::Normalize) m.equations.push_back(e);
  dynamics::PointForce f;
  f.body = 1;
  f.s = random3();
  f.value = {Expression("3*sin(t)"), Expression("1 + t"), Expression("-2")};
  m.forces.push_back(f);
  m.finalize();
  return m;
}

} // namespace

TEST(Mechanism, DynamicsDerivatives) {
  const auto m = two_body_mechanism();
  const Vector q = random_q(2);
  Vector v(14), a(14);
  for (int i = 0; i < 14; ++i) v(i) = uniform(), a(i) = uniform();
  const auto d = test_support::dynamics_derivatives(m, q, v, a, 0.6);
  expect_close(d[0].analytic, d[0].differences, "dr/dq");
  expect_close(d[1].analytic, d[1].differences, "dr/dv");
  expect_close(d[2].analytic, d[2].differences, "M");
}

TEST(GeneralizedAlpha, StepResidualJacobians) {
  const auto m = two_body_mechanism();
  const int n = m.coordinates(), mm = m.constraints();
  dynamics::GeneralizedAlpha ga(m, dynamics::AlphaParameters::from_rho_inf(0.7));
  dynamics::State s0, s1;
  auto fill = [&](dynamics::State &s, double t) {
    s.t = t;
    s.q = random_q(2);
    s.v = Vector::Random(n);
    s.a = Vector::Random(n);
    s.acc = Vector::Random(n);
    s.lambda = Vector::Random(mm);
  };
  fill(s0, 0.2);
  fill(s1, 0.25);
  const auto d = test_support::step_derivatives(ga, s1, s0, 0.05);
  expect_close(d[0].analytic, d[0].differences, "dR/ds_{n+1}");
  expect_close(d[1].analytic, d[1].differences, "dR/ds_n");
}

TEST(GeneralizedAlpha, ParametersOfChungHulbert) {
  const auto p = dynamics::AlphaParameters::from_rho_inf(1.0);
  EXPECT_DOUBLE_EQ(p.alpha_m, 0.5);
  EXPECT_DOUBLE_EQ(p.alpha_f, 0.5);
  EXPECT_DOUBLE_EQ(p.gamma, 0.5);
  EXPECT_DOUBLE_EQ(p.beta, 0.25);
}

namespace {

/// A chain of `links` rigid links hinged about z (revolute = point coincidence + two
/// perpendicularities), the first to the ground, released horizontally under gravity.

} // namespace

// The sparse Newton path (block assembly straight into a sparse LU) and the dense one solve the
// same equations: a chain of 8 links (104 unknowns) integrated 50 steps both ways agrees to
// round-off amplified by the motion (1e-10 of the chain's length), with the same Newton
// iteration counts.
TEST(GeneralizedAlpha, SparseAndDensePathsAgree) {
  Vector q0;
  const auto m = test_support::chain(8, q0);
  // A large step (20 ms), where the stiffness and constraint-Hessian terms of the iteration
  // matrix matter for Newton's convergence rate.
  const auto r = test_support::run_dense_sparse_paths(m, q0, 0.02, 50, 10);
  const auto &sd = r.a, &ss = r.b;
  // Both Jacobians are exact: Newton converges alike (a missing term would cost iterations).
  EXPECT_EQ(r.a_iterations, r.b_iterations);
  EXPECT_LT((sd.q - ss.q).cwiseAbs().maxCoeff(), 1e-10 * 8);
  EXPECT_LT((sd.lambda - ss.lambda).cwiseAbs().maxCoeff(), 1e-8 * sd.lambda.cwiseAbs().maxCoeff());
  // The chain has moved: the check is not comparing two resting states.
  EXPECT_GT((sd.q - q0).cwiseAbs().maxCoeff(), 0.1);
}

// The kept (simplified-Newton) iteration matrix changes the path to each step's solution and
// leaves a remainder controlled by NewtonSettings::kept_tolerance (docs/theory.md section 6.4).
// A position error d of one step carries a velocity error (gamma / (beta h)) d into the rest of
// the run, so over N steps of h the deviation from Newton's trajectory is estimated by
// N (gamma / beta) (T / h) kept_tolerance (1 + max|q|) = 300 * 1.9 * 300 * 1e-15 * 9 = 1.5e-9
// here; the test allows ten times that (measured 5.2e-11; Newton dense against Newton sparse,
// round-off only: 2e-15). The
// deviation must shrink with the tolerance (measured 8.5e-9 at 1e-13): the kept path converges
// to Newton's solution, and is not merely close to it.
TEST(GeneralizedAlpha, KeptMatrixReachesNewtonsSolution) {
  Vector q0;
  const auto m = test_support::chain(8, q0);
  test_support::expect_kept_matrix_reaches_newton(m, q0, 1e-3, 300, "chain of 8 links");
}

// The index-3 scheme as h -> 0 (docs/theory.md section 6.4; issue 22's stability map): the
// Newton matrix [beta' M + gamma' C + K, J^T; J, 0] of the step has a block of order h^-2
// beside constraint rows of order 1, so its eigenvalues spread as h^-2 and h^2 and its
// condition number grows as h^-4 (Bottasso, Bauchau & Cardona 2007); the scaled matrix the
// integrator factorizes, [M + (gamma'/beta') C + K/beta', J^T; J, 0], tends to [M, J^T; J, 0],
// which is regular (M is positive definite on the null space of J), so its condition number
// stays bounded. On a moving double pendulum (after 200 steps of 1 ms, multipliers loaded),
// for h = 1e-1 ... 1e-7: the unscaled condition number's log-log slope is -4 to 1 % between
// h = 1e-1 and 1e-3 (measured -3.997, -4.000), and it passes 1e16 by h = 1e-4 (numerically
// singular in double precision: below that even the SVD cannot resolve its smallest singular
// value, so the slope is not asserted there); the scaled one stays within a factor 1.1 of its
// value at h = 1e-1 (measured 57.7-59.7). The table is what scripts/study_stability.py draws
// (lines "index3 h= ...").
TEST(GeneralizedAlpha, ScaledNewtonMatrixStaysConditionedAsTheStepShrinks) {
  Vector q0;
  const auto m = test_support::chain(2, q0);
  const auto par = dynamics::AlphaParameters::from_rho_inf(0.8);
  const dynamics::GeneralizedAlpha ga(m, par);
  dynamics::State s = ga.initial_state(q0, Vector::Zero(q0.size()), 0), next;
  for (int k = 0; k < 200; ++k) {
    dynamics::StepInfo info;
    ASSERT_TRUE(ga.advance(s, 1e-3, next, info));
    s = next;
  }
  ASSERT_GT(s.lambda.cwiseAbs().maxCoeff(), 1.0); // the joints carry load
  Matrix K, C, M, J;
  ga.jacobian_blocks(s, K, C, M, J);
  const int n = static_cast<int>(M.rows()), c = static_cast<int>(J.rows());
  auto condition = [&](double h, bool scaled) {
    const auto k = par.newton_scaling(h);
    Matrix A = Matrix::Zero(n + c, n + c);
    A.topLeftCorner(n, n) =
        scaled ? Matrix(M + (k.gp / k.bp) * C + K / k.bp) : Matrix(k.bp * M + k.gp * C + K);
    A.topRightCorner(n, c) = J.transpose();
    A.bottomLeftCorner(c, n) = J;
    const Eigen::JacobiSVD<Matrix> svd(A);
    const auto &sv = svd.singularValues();
    return sv(0) / sv(sv.size() - 1);
  };
  std::vector<double> hs, scaled, unscaled;
  for (double h = 1e-1; h > 0.5e-7; h /= 10) {
    hs.push_back(h);
    scaled.push_back(condition(h, true));
    unscaled.push_back(condition(h, false));
    std::printf("index3 h= %.0e scaled= %.4e unscaled= %.4e\n", h, scaled.back(), unscaled.back());
  }
  for (std::size_t i = 0; i < hs.size(); ++i)
    EXPECT_LT(std::max(scaled[i], scaled[0]) / std::min(scaled[i], scaled[0]), 1.1) << hs[i];
  for (std::size_t i = 1; i < 3; ++i) {
    const double slope = std::log(unscaled[i] / unscaled[i - 1]) / std::log(hs[i] / hs[i - 1]);
    EXPECT_NEAR(slope, -4.0, 0.04) << "unscaled, between h = " << hs[i - 1] << " and " << hs[i];
  }
  EXPECT_GT(unscaled[3], 1e16) << "unscaled at h = 1e-4";
}

namespace {

/// Two bodies in random placements (coordinates q, rotations R) attached at world points xa
/// (body 0) and xb (body 1).
struct RandomPair {
  Vector q = Vector(14);
  Mat3 R[2];
  dynamics::Attachment A, B;
  RandomPair(const Vec3 &xa, const Vec3 &xb) {
    for (int b = 0; b < 2; ++b) {
      R[b] = Eigen::AngleAxisd(uniform(-3, 3), random3().normalized()).toRotationMatrix();
      q.segment<3>(7 * b) = random3();
      q.segment<4>(7 * b + 3) = bodies::from_matrix(R[b]);
    }
    A.body = 0, B.body = 1, A.R = R[0], B.R = R[1], A.world = xa, B.world = xb;
    A.s = R[0].transpose() * (xa - q.segment<3>(0));
    B.s = R[1].transpose() * (xb - q.segment<3>(7));
  }
};

} // namespace

// Every joint type as the scene builds it, between two bodies in a random initial placement:
// the row count, the equations satisfied at the initial placement, the gradient and the
// Hessian contraction of the whole joint against central differences, and the motion the joint
// allows (revolute: rotation about its axis through the joint point; prismatic: translation
// along its axis) keeps the equations satisfied while a forbidden motion violates them.
TEST(Joints, EveryTypeAsBuilt) {
  const Vec3 axis = random3().normalized();
  auto rigid_motion = [](Vector q, int b, const Mat3 &R, const Vec3 &about, const Vec3 &shift) {
    // x -> about + R (x - about) + shift for body b: r and p change accordingly.
    const Vec3 r = q.segment<3>(7 * b);
    q.segment<3>(7 * b) = about + R * (r - about) + shift;
    const Mat3 A = bodies::rotation(q.segment<4>(7 * b + 3));
    q.segment<4>(7 * b + 3) = bodies::from_matrix(R * A);
    return q;
  };
  for (const std::string type : {"spherical", "revolute", "prismatic", "fixed"}) {
    // The joint point in the world, the same for both bodies (prismatic: any two points).
    const Vec3 x = random3();
    const RandomPair pair(x, type == "prismatic" ? Vec3(x + 0.3 * random3()) : x);
    const Vector &q = pair.q;
    const auto eqs =
        rigid_layout(dynamics::joint_equations(joint_type(type), pair.A, pair.B, axis, "joint"));
    int rows = 0;
    for (const auto &e : eqs) rows += e.rows();
    const int expected = type == "spherical" ? 3 : type == "fixed" ? 6 : 5;
    EXPECT_EQ(rows, expected) << type;
    auto phi = [&](const Vector &x_) -> Vector {
      Vector out(rows);
      int r = 0;
      for (const auto &e : eqs) {
        e.value(x_, 0.0, out.data() + r);
        r += e.rows();
      }
      return out;
    };
    EXPECT_LT(phi(q).cwiseAbs().maxCoeff(), 1e-14) << type << ": not satisfied where built";
    Matrix J = Matrix::Zero(rows, 14), H = Matrix::Zero(14, 14);
    Vector lambda(rows);
    for (int i = 0; i < rows; ++i) lambda(i) = uniform();
    int r = 0;
    for (const auto &e : eqs) {
      e.gradient(q, 0.0, J, r);
      e.add_hessian(q, 0.0, lambda.data() + r, H);
      r += e.rows();
    }
    expect_close(J, fd_jacobian(phi, q, rows), (type + ": gradient").c_str());
    auto jtl = [&](const Vector &x_) -> Vector {
      Matrix Jx = Matrix::Zero(rows, 14);
      int rr = 0;
      for (const auto &e : eqs) {
        e.gradient(x_, 0.0, Jx, rr);
        rr += e.rows();
      }
      return Jx.transpose() * lambda;
    };
    expect_close(H, fd_jacobian(jtl, q, 14), (type + ": Hessian").c_str());
    // Allowed and forbidden motions of body b.
    const Mat3 spin = Eigen::AngleAxisd(0.7, axis).toRotationMatrix();
    const Mat3 tilt = Eigen::AngleAxisd(0.7, axis.unitOrthogonal()).toRotationMatrix();
    const double about_axis = phi(rigid_motion(q, 1, spin, x, Vec3::Zero())).cwiseAbs().maxCoeff();
    const double tilted = phi(rigid_motion(q, 1, tilt, x, Vec3::Zero())).cwiseAbs().maxCoeff();
    const double along =
        phi(rigid_motion(q, 1, Mat3::Identity(), x, 0.4 * axis)).cwiseAbs().maxCoeff();
    if (type == "spherical") {
      EXPECT_LT(std::max(about_axis, tilted), 1e-14) << type << " allows any rotation about x";
      EXPECT_GT(along, 0.1) << type;
    } else if (type == "revolute") {
      EXPECT_LT(about_axis, 1e-14) << type;
      EXPECT_GT(tilted, 0.1) << type;
      EXPECT_GT(along, 0.1) << type;
    } else if (type == "prismatic") {
      EXPECT_LT(along, 1e-14) << type;
      EXPECT_GT(about_axis, 0.1) << type;
    } else {
      EXPECT_GT(std::min({about_axis, tilted, along}), 0.1) << type << " allows nothing";
    }
  }
}

// Drivers on a revolute (angle) and a prismatic (displacement) joint: zero where built when
// f(0) = 0, and zero after rotating / translating body b by f(t) about / along the axis.
TEST(Joints, DriversPrescribeTheJointCoordinate) {
  const Vec3 axis = random3().normalized();
  auto f = std::make_shared<const Expression>("0.8*t + 0.3*t^2");
  const Vec3 x = random3();
  const RandomPair pair(x, x);
  const Vector &q = pair.q;
  const auto &A = pair.A, &B = pair.B;
  const Mat3 *R = pair.R;
  const double t = 0.9, value = 0.8 * t + 0.3 * t * t;
  for (const std::string type : {"revolute", "prismatic"}) {
    const auto e =
        rigid_layout(dynamics::driver_equation(joint_type(type), A, B, axis, f, "driver"));
    double phi0 = 1, phit = 1;
    e.value(q, 0.0, &phi0);
    EXPECT_LT(std::abs(phi0), 1e-14) << type;
    Vector moved = q;
    if (type == "revolute") {
      const Mat3 Rt = Eigen::AngleAxisd(value, axis).toRotationMatrix();
      moved.segment<3>(7) = x + Rt * (q.segment<3>(7) - x);
      moved.segment<4>(10) = bodies::from_matrix(Rt * R[1]);
    } else {
      moved.segment<3>(7) += value * axis;
    }
    e.value(moved, t, &phit);
    EXPECT_LT(std::abs(phit), 1e-13) << type << ": the joint coordinate is f(t)";
  }
}
