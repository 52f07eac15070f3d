// FFRF bodies (docs/theory.md section 7.3): the equations of motion of a reduced flexible body
// against an independent computation on a cloud of particles carrying the same modes, the
// exact Jacobians against central differences, the kinetic energy, and the reduction to the
// rigid body when the body has no modes.
//
// The particle model: masses m_i at frame positions X_i with mode shapes Psi_ik, so that the
// invariants are plain sums (a lumped mass matrix is a special case of the consistent one the
// reduction uses). Point i moves as x_i = r + A(p) (X_i + Psi_i zeta), and d'Alembert gives the
// generalized inertial force sum_i m_i (dx_i/dq)^T x_i''. Its r and zeta rows are exact; its p
// rows differ from the FFRF form 2 Gbar^T F_w by a multiple of p (the direction the
// normalization multiplier absorbs), so they are compared after projecting p out.
#include "dynamics_checks.hpp"
#include "flexopt/bodies/ffrf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/dynamics/generalized_alpha.hpp"
#include "flexopt/dynamics/mechanism.hpp"

#include <cstdlib>
#include <gtest/gtest.h>
#include <random>

using namespace flexopt;
using bodies::Mat3;
using bodies::Matrix;
using bodies::Vec3;
using bodies::Vec4;
using bodies::Vector;

namespace {

std::mt19937 &rng() {
  static std::mt19937 g(7311);
  return g;
}
double uniform(double lo = -1, double hi = 1) {
  return std::uniform_real_distribution<double>(lo, hi)(rng());
}
Vec3 random3() {
  return Vec3(uniform(), uniform(), uniform());
}

struct Particles {
  std::vector<double> m;
  std::vector<Vec3> X;
  std::vector<Eigen::Matrix3Xd> Psi; ///< per particle, 3 x n
  int n = 0;
};

Particles random_particles(int count, int n) {
  Particles p;
  p.n = n;
  for (int i = 0; i < count; ++i) {
    p.m.push_back(uniform(0.5, 2.0));
    p.X.push_back(random3() + Vec3(1.0, 0, 0));
    p.Psi.push_back(0.3 * Eigen::Matrix3Xd::Random(3, n));
  }
  return p;
}

reduce::FfrfInvariants invariants_of(const Particles &p) {
  reduce::FfrfInvariants inv;
  const int n = p.n;
  inv.D = Eigen::Matrix3Xd::Zero(3, n);
  inv.S1.assign(static_cast<std::size_t>(n), Mat3::Zero());
  inv.S2.assign(static_cast<std::size_t>(n),
                std::vector<Mat3>(static_cast<std::size_t>(n), Mat3::Zero()));
  for (std::size_t i = 0; i < p.m.size(); ++i) {
    const double m = p.m[i];
    inv.mass += m;
    inv.d0 += m * p.X[i];
    inv.D += m * p.Psi[i];
    inv.S0 += m * p.X[i] * p.X[i].transpose();
    for (int k = 0; k < n; ++k) {
      inv.S1[static_cast<std::size_t>(k)] += m * p.X[i] * p.Psi[i].col(k).transpose();
      for (int l = 0; l < n; ++l)
        inv.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] +=
            m * p.Psi[i].col(k) * p.Psi[i].col(l).transpose();
    }
  }
  return inv;
}

Matrix random_spd(int n, double scale) {
  const Matrix B = Matrix::Random(n, n);
  return scale * (B * B.transpose() + n * Matrix::Identity(n, n));
}

bodies::FfrfModel model_of(const Particles &p, bool stiffening) {
  bodies::FfrfModel m;
  m.invariants = invariants_of(p);
  m.stiffness = random_spd(p.n, 10.0);
  m.damping = random_spd(p.n, 0.1);
  if (stiffening)
    for (int c = 0; c < 6; ++c) {
      const Matrix B = Matrix::Random(p.n, p.n);
      m.geometric.push_back(B + B.transpose());
    }
  return m;
}

/// World position of particle i at coordinates q.
Vec3 position(const Particles &p, std::size_t i, const Vector &q) {
  const Vec3 u = p.X[i] + p.Psi[i] * q.tail(p.n);
  return q.head<3>() + bodies::rotation(q.segment<4>(3)) * u;
}

/// dx_i/dq by central differences (x is a polynomial of degree 3 in q: error ~h^2).
Eigen::Matrix3Xd position_jacobian(const Particles &p, std::size_t i, const Vector &q) {
  Eigen::Matrix3Xd J(3, q.size());
  const double h = 1e-5;
  for (int j = 0; j < q.size(); ++j) {
    Vector a = q, b = q;
    a(j) += h, b(j) -= h;
    J.col(j) = (position(p, i, a) - position(p, i, b)) / (2 * h);
  }
  return J;
}

/// x_i'' along q(t) = q + t v + t^2 a / 2, by a fourth-order central difference in t.
Vec3 acceleration(const Particles &p, std::size_t i, const Vector &q, const Vector &v,
                  const Vector &a) {
  const double h = 1e-3;
  auto x = [&](double t) { return position(p, i, q + t * v + 0.5 * t * t * a); };
  return (-x(2 * h) + 16 * x(h) - 30 * x(0) + 16 * x(-h) - x(-2 * h)) / (12 * h * h);
}

/// A consistent unit-quaternion state: |p| = 1, p.p' = 0, p.p'' = -|p'|^2.
void random_state(int n, Vector &q, Vector &v, Vector &a) {
  const int N = 7 + n;
  q = Vector::Random(N), v = Vector::Random(N), a = Vector::Random(N);
  Vec4 p = q.segment<4>(3).normalized();
  Vec4 pd = v.segment<4>(3);
  pd -= p.dot(pd) * p;
  Vec4 pdd = a.segment<4>(3);
  pdd -= (p.dot(pdd) + pd.squaredNorm()) * p;
  q.segment<4>(3) = p, v.segment<4>(3) = pd, a.segment<4>(3) = pdd;
  q.tail(n) *= 0.2;
}

template <class F> Matrix fd_jacobian(F f, const Vector &x, double step = 1e-6) {
  const Vector f0 = f(x);
  Matrix J(f0.size(), x.size());
  for (int j = 0; j < x.size(); ++j) {
    Vector a = x, b = x;
    a(j) += step, b(j) -= step;
    J.col(j) = (f(a) - f(b)) / (2 * step);
  }
  return J;
}

double rel_error(const Matrix &a, const Matrix &b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(1.0, b.cwiseAbs().maxCoeff());
}

} // namespace

// Central differences with step 1e-6 on a residual of order 10-100: truncation ~1e-10,
// round-off ~1e-9 relative; 1e-7 leaves a margin of two orders.
TEST(FfrfBody, ExactJacobians) {
  for (bool stiffening : {false, true}) {
    const int n = 3;
    const Particles parts = random_particles(7, n);
    const bodies::FfrfBody body("flex", model_of(parts, stiffening));
    Vector q = Vector::Random(7 + n), v = Vector::Random(7 + n), a = Vector::Random(7 + n);
    const Vec3 g(0.3, -9.81, 0.2);
    Vector r(7 + n);
    Matrix K, C, M;
    body.residual(q, v, a, g, r, &K, &C, &M);
    auto res = [&](const Vector &qq, const Vector &vv, const Vector &aa) {
      Vector out(7 + n);
      body.residual(qq, vv, aa, g, out, nullptr, nullptr, nullptr);
      return out;
    };
    EXPECT_LT(rel_error(K, fd_jacobian([&](const Vector &x) { return res(x, v, a); }, q)), 1e-7)
        << "dr/dq, stiffening " << stiffening;
    EXPECT_LT(rel_error(C, fd_jacobian([&](const Vector &x) { return res(q, x, a); }, v)), 1e-7)
        << "dr/dv, stiffening " << stiffening;
    EXPECT_LT(rel_error(M, fd_jacobian([&](const Vector &x) { return res(q, v, x); }, a)), 1e-7)
        << "dr/da";
    EXPECT_LT((M - M.transpose()).cwiseAbs().maxCoeff(), 1e-12 * M.cwiseAbs().maxCoeff());
  }
}

// The residual is linear in every field of the model, so (d res/d model)^T mu paired with a
// model direction delta is exactly mu^T res evaluated with the model delta: the identity the
// dynamic adjoint of an FFRF design body uses (docs/theory.md section 10.1). Random directions
// (every entry, asymmetric S1, S2, K, C, G included) at random states; only round-off differs.
TEST(FfrfBody, ModelCotangentIsTheTransposeOfTheResidual) {
  const int n = 3;
  for (bool stiffening : {false, true}) {
    const bodies::FfrfBody body("flex", model_of(random_particles(7, n), stiffening));
    bodies::FfrfModel delta;
    delta.invariants.mass = 1.7;
    delta.invariants.d0 = Vec3::Random();
    delta.invariants.D = Matrix::Random(3, n);
    delta.invariants.S0 = Mat3::Random();
    for (int k = 0; k < n; ++k) {
      delta.invariants.S1.push_back(Mat3::Random());
      delta.invariants.S2.emplace_back();
      for (int l = 0; l < n; ++l) delta.invariants.S2.back().push_back(Mat3::Random());
    }
    delta.stiffness = Matrix::Random(n, n);
    delta.damping = Matrix::Random(n, n);
    if (stiffening)
      for (int c = 0; c < 6; ++c) delta.geometric.push_back(Matrix::Random(n, n));
    const bodies::FfrfBody direction("delta", delta);
    for (int trial = 0; trial < 3; ++trial) {
      Vector q, v, a;
      random_state(n, q, v, a);
      const Vec3 g(0.3, -9.81, 0.2);
      const Vector mu = Vector::Random(7 + n);
      bodies::FfrfModel bar;
      body.model_cotangent(q, v, a, g, mu, bar);
      Vector r(7 + n);
      direction.residual(q, v, a, g, r, nullptr, nullptr, nullptr);
      const auto &b = bar.invariants;
      const auto &d = delta.invariants;
      double pairing = b.mass * d.mass + b.d0.dot(d.d0) + b.D.cwiseProduct(d.D).sum() +
                       b.S0.cwiseProduct(d.S0).sum() +
                       bar.stiffness.cwiseProduct(delta.stiffness).sum() +
                       bar.damping.cwiseProduct(delta.damping).sum();
      for (int k = 0; k < n; ++k) {
        pairing +=
            b.S1[static_cast<std::size_t>(k)].cwiseProduct(d.S1[static_cast<std::size_t>(k)]).sum();
        for (int l = 0; l < n; ++l)
          pairing +=
              b.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)]
                  .cwiseProduct(d.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)])
                  .sum();
      }
      for (std::size_t c = 0; c < bar.geometric.size(); ++c)
        pairing += bar.geometric[c].cwiseProduct(delta.geometric[c]).sum();
      const double expected = mu.dot(r);
      EXPECT_NEAR(pairing, expected, 1e-12 * mu.cwiseAbs().dot(r.cwiseAbs()) + 1e-12)
          << "stiffening " << stiffening;
    }
  }
}

// The FFRF equations of motion equal d'Alembert's sum over the particles. The particle
// accelerations come from a fourth-order difference in time (h = 1e-3: error ~1e-10 x the
// sixth derivative, ~1e-8 here), so the check is 1e-6 relative.
TEST(FfrfBody, EqualsDAlembertOnParticles) {
  const int n = 4;
  const Particles parts = random_particles(9, n);
  bodies::FfrfModel model = model_of(parts, false);
  model.stiffness.setZero(n, n); // inertia only
  model.damping.setZero(n, n);
  const bodies::FfrfBody body("flex", model);
  for (int trial = 0; trial < 3; ++trial) {
    Vector q, v, a;
    random_state(n, q, v, a);
    const Vec3 g(0, -9.81, 1.0);
    Vector r(7 + n);
    body.residual(q, v, a, g, r, nullptr, nullptr, nullptr);
    Vector f = Vector::Zero(7 + n);
    for (std::size_t i = 0; i < parts.m.size(); ++i)
      f += parts.m[i] * position_jacobian(parts, i, q).transpose() *
           (acceleration(parts, i, q, v, a) - g);
    const Vec4 p = q.segment<4>(3);
    const Eigen::Matrix4d project = Eigen::Matrix4d::Identity() - p * p.transpose();
    f.segment<4>(3) = project * f.segment<4>(3);
    r.segment<4>(3) = project * r.segment<4>(3);
    EXPECT_LT(rel_error(r, f), 1e-6) << "FFRF\n"
                                     << r.transpose() << "\nparticles\n"
                                     << f.transpose();
    // Kinetic energy 1/2 sum m |x'|^2 (x' = dx/dq v) plus the potential of gravity.
    double T = 0, V = 0;
    for (std::size_t i = 0; i < parts.m.size(); ++i) {
      const Vec3 xd = position_jacobian(parts, i, q) * v;
      T += 0.5 * parts.m[i] * xd.squaredNorm();
      V -= parts.m[i] * g.dot(position(parts, i, q));
    }
    EXPECT_NEAR(body.energy(q, v, g), T + V, 1e-8 * (std::abs(T) + std::abs(V)));
  }
}

// Without modes, with the frame at the centre of mass, the FFRF body is the rigid body: same
// residual (rotational rows up to the p direction), same mass matrix on p-orthogonal
// directions, same energy.
TEST(FfrfBody, WithoutModesIsTheRigidBody) {
  Particles parts = random_particles(8, 0);
  const reduce::FfrfInvariants inv0 = invariants_of(parts);
  const Vec3 c = inv0.d0 / inv0.mass;
  for (Vec3 &X : parts.X) X -= c; // frame origin at the centre of mass
  bodies::FfrfModel model;
  model.invariants = invariants_of(parts);
  model.stiffness.resize(0, 0);
  const bodies::FfrfBody flex("flex", model);
  bodies::MassProperties props;
  props.mass = model.invariants.mass;
  props.center = Vec3::Zero();
  props.inertia = model.invariants.inertia(Vector());
  const bodies::RigidBody rigid("rigid", props);
  Vector q, v, a;
  random_state(0, q, v, a);
  const Vec3 g(0.1, -9.81, 0);
  Vector rf(7), rr(7);
  Matrix Mf, Mr;
  flex.residual(q, v, a, g, rf, nullptr, nullptr, &Mf);
  rigid.residual(q, v, a, g, rr, nullptr, nullptr, &Mr);
  const Vec4 p = q.segment<4>(3);
  const Eigen::Matrix4d P = Eigen::Matrix4d::Identity() - p * p.transpose();
  EXPECT_LT((rf.head<3>() - rr.head<3>()).norm(), 1e-13 * rr.norm());
  EXPECT_LT((P * (rf.tail<4>() - rr.tail<4>())).norm(), 1e-12 * rr.norm());
  EXPECT_LT((P * (Mf.bottomRightCorner<4, 4>() - Mr.bottomRightCorner<4, 4>()) * P).norm(),
            1e-12 * Mr.norm());
  EXPECT_NEAR(flex.energy(q, v, g), rigid.energy(q, v, g), 1e-12 * std::abs(rigid.energy(q, v, g)));
}

namespace {

/// A mechanism of an FFRF body (0, n elastic coordinates) and a rigid body (1), with one
/// equation of every kind between them and to the ground whose points and vectors on the
/// flexible body have random elastic parts, normalizations, gravity and a point force on the
/// flexible body: every flexible term of the constraints and of the dynamics residual.
dynamics::Mechanism flexible_mechanism(int n) {
  using K = joints::Equation::Kind;
  dynamics::Mechanism m;
  m.bodies.push_back(
      std::make_shared<bodies::FfrfBody>("flex", model_of(random_particles(6, n), true)));
  bodies::MassProperties rp;
  rp.mass = 1.7;
  rp.inertia = Mat3::Identity() * 0.3;
  rp.inertia(0, 1) = rp.inertia(1, 0) = 0.02;
  m.bodies.push_back(std::make_shared<bodies::RigidBody>("rigid", rp));
  for (int b = 0; b < 2; ++b) {
    joints::Equation e;
    e.kind = K::Normalize;
    e.a = b;
    e.owner = "normalize";
    m.equations.push_back(e);
  }
  auto driver = std::make_shared<const Expression>("0.3 + 2*t + 0.5*sin(3*t)");
  // (a, b) = (flex, rigid), (rigid, flex), (ground, flex), (flex, ground).
  for (auto [a, b] : {std::pair{0, 1}, std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, -1}})
    for (K k : {K::Coincide, K::Perpendicular, K::PointOnPlane, K::RotationDriver,
                K::TranslationDriver}) {
      joints::Equation e;
      e.kind = k, e.a = a, e.b = b, e.c = 0.1, e.driver = driver, e.owner = "test";
      e.sa = random3(), e.sb = random3(), e.ua = random3(), e.vb = random3(), e.ua2 = random3();
      if (a == 0)
        e.Sa = 0.5 * joints::Elastic::Random(3, n), e.Ua = 0.5 * joints::Elastic::Random(3, n),
        e.Ua2 = 0.5 * joints::Elastic::Random(3, n);
      if (b == 0)
        e.Sb = 0.5 * joints::Elastic::Random(3, n), e.Vb = 0.5 * joints::Elastic::Random(3, n);
      m.equations.push_back(e);
    }
  dynamics::PointForce f;
  f.body = 0;
  f.s = random3();
  f.S = joints::Elastic::Random(3, n);
  f.value = {Expression("3*sin(t)"), Expression("1 + t"), Expression("-2")};
  m.forces.push_back(f);
  m.gravity = Vec3(0.2, -9.81, 0);
  m.finalize();
  return m;
}

Vector random_coordinates(const dynamics::Mechanism &m) {
  Vector q = Vector::Random(m.coordinates());
  for (int b = 0; b < 2; ++b) {
    const int o = m.offset(b);
    q.segment<4>(o + 3) = q.segment<4>(o + 3).normalized() * (1 + 0.05 * uniform());
  }
  return q;
}

} // namespace

// Constraint gradients, Hessian contractions and time derivatives with flexible attachments,
// the dynamics residual's derivatives with a flexible body and a point load on it, and the
// generalized-alpha step residual's Jacobians, all against central differences (1e-7).
TEST(FfrfMechanism, EveryDerivative) {
  const int n = 3;
  const auto m = flexible_mechanism(n);
  const int N = m.coordinates(), rows = m.constraints();
  ASSERT_EQ(N, 7 + n + 7);
  const Vector q = random_coordinates(m), v = Vector::Random(N), a = Vector::Random(N);
  const double t = 0.37;
  Vector phi;
  Matrix J;
  m.constraint(q, t, phi, &J);
  auto phi_of = [&](const Vector &x) {
    Vector out;
    m.constraint(x, t, out, nullptr);
    return out;
  };
  EXPECT_LT(rel_error(J, fd_jacobian(phi_of, q)), 1e-7) << "Phi_q";
  const Vector lambda = Vector::Random(rows);
  Matrix H = Matrix::Zero(N, N);
  m.add_constraint_hessian(q, t, lambda, H);
  auto jtl = [&](const Vector &x) {
    Vector out;
    Matrix Jx;
    m.constraint(x, t, out, &Jx);
    return Vector(Jx.transpose() * lambda);
  };
  EXPECT_LT(rel_error(H, fd_jacobian(jtl, q)), 1e-7) << "Hessian";
  Vector pt, ptt, pqtv;
  m.constraint_time_terms(q, v, t, pt, ptt, pqtv);
  Vector tt(1);
  tt(0) = t;
  auto phi_t = [&](const Vector &x) {
    Vector out;
    m.constraint(q, x(0), out, nullptr);
    return out;
  };
  auto phit_t = [&](const Vector &x) {
    Vector a1, b1, c1;
    m.constraint_time_terms(q, v, x(0), a1, b1, c1);
    return a1;
  };
  auto jv_t = [&](const Vector &x) {
    Vector out;
    Matrix Jx;
    m.constraint(q, x(0), out, &Jx);
    return Vector(Jx * v);
  };
  EXPECT_LT(rel_error(pt, fd_jacobian(phi_t, tt)), 1e-7) << "phi_t";
  EXPECT_LT(rel_error(ptt, fd_jacobian(phit_t, tt)), 1e-7) << "phi_tt";
  EXPECT_LT(rel_error(pqtv, fd_jacobian(jv_t, tt)), 1e-7) << "phi_qt v";
  // Convective term (Phi_q v)_q v.
  auto jv_q = [&](const Vector &x) {
    Vector out;
    Matrix Jx;
    m.constraint(x, t, out, &Jx);
    return Vector(Jx * v);
  };
  EXPECT_LT(rel_error(m.constraint_convective(q, v, t), fd_jacobian(jv_q, q) * v), 1e-7);

  const auto dd = test_support::dynamics_derivatives(m, q, v, a, t);
  EXPECT_LT(rel_error(dd[0].analytic, dd[0].differences), 1e-7) << "dr/dq";
  EXPECT_LT(rel_error(dd[1].analytic, dd[1].differences), 1e-7) << "dr/dv";
  EXPECT_LT(rel_error(dd[2].analytic, dd[2].differences), 1e-7) << "dr/da";

  dynamics::GeneralizedAlpha ga(m, dynamics::AlphaParameters::from_rho_inf(0.7));
  dynamics::State s0, s1;
  auto fill = [&](dynamics::State &s, double time) {
    s.t = time;
    s.q = random_coordinates(m);
    s.v = Vector::Random(N);
    s.a = Vector::Random(N);
    s.acc = Vector::Random(N);
    s.lambda = Vector::Random(rows);
  };
  fill(s0, 0.2);
  fill(s1, 0.25);
  const auto sd = test_support::step_derivatives(ga, s1, s0, 0.05);
  EXPECT_LT(rel_error(sd[0].analytic, sd[0].differences), 1e-7) << "dR/ds_{n+1}";
  EXPECT_LT(rel_error(sd[1].analytic, sd[1].differences), 1e-7) << "dR/ds_n";
}

namespace {

/// A flexible pendulum of the synthetic body (n = 4 elastic coordinates) on a spherical joint,
/// released from rest in the undeformed state q0.
dynamics::Mechanism flexible_pendulum(int n, Vector &q0) {
  rng().seed(7311); // the same body whichever tests ran before (Eigen's Random: std::rand)
  std::srand(7311);
  using K = joints::Equation::Kind;
  dynamics::Mechanism m;
  bodies::FfrfModel model = model_of(random_particles(8, n), false);
  model.stiffness = 200.0 * Matrix::Identity(n, n);
  m.bodies.push_back(std::make_shared<bodies::FfrfBody>("flex", model));
  joints::Equation norm;
  norm.kind = K::Normalize, norm.a = 0, norm.owner = "normalize";
  m.equations.push_back(norm);
  joints::Equation pin;
  pin.kind = K::Coincide, pin.a = -1, pin.b = 0, pin.owner = "pin";
  pin.sb = Vec3::Zero();
  pin.sa = Vec3::Zero();
  m.equations.push_back(pin);
  m.gravity = Vec3(0, -9.81, 0);
  m.finalize();
  q0 = Vector::Zero(m.coordinates());
  q0(3) = 1;
  return m;
}

} // namespace

// A flexible pendulum of the synthetic body on a spherical joint: the sparse Newton path (block
// pattern with a 7 + n block) and the dense one take the same iterations and agree to
// round-off over 40 steps.
TEST(FfrfMechanism, SparseAndDensePathsAgree) {
  const int n = 4;
  Vector q0;
  const auto m = flexible_pendulum(n, q0);
  const auto r = test_support::run_dense_sparse_paths(m, q0, 0.01, 40, 0);
  const auto &sd = r.a, &ss = r.b;
  EXPECT_EQ(r.a_iterations, r.b_iterations);
  EXPECT_LT((sd.q - ss.q).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_GT((sd.q - q0).cwiseAbs().maxCoeff(), 0.05); // it has moved and deformed
  EXPECT_GT(sd.q.tail(n).cwiseAbs().maxCoeff(), 1e-4);
}

// The kept iteration matrix (docs/theory.md section 6.4) reaches Newton's solution of every
// step with the FFRF body's gyroscopic and centrifugal coupling too (the bound as for the rigid
// chain's GeneralizedAlpha.KeptMatrixReachesNewtonsSolution).
TEST(FfrfMechanism, KeptMatrixReachesNewtonsSolution) {
  const int n = 4;
  Vector q0;
  const auto m = flexible_pendulum(n, q0);
  test_support::expect_kept_matrix_reaches_newton(m, q0, 2e-3, 200, "flexible pendulum");
}
