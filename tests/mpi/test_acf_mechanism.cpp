// ACF bodies in a mechanism (dynamics::DistributedAlpha with a small part and ties, docs/theory.md
// section 8.2): the steel beam (meshes/beam.geo, 1 m x 50 x 100 mm) hinged at its `clamp` face
// to the ground by a revolute joint about z, swinging under gravity -y with a 2 kg rigid block
// on a spherical joint at its `tip` face. The interface nodes are massless rigid bodies tied to
// the surface nodes. On 1 and 2 ranks:
//  - the scaled Newton matrix is the derivative of [R_d / beta'; Phi] along a Newton update
//    (central differences, step 1e-6: truncation ~1e-12 relative; tolerance 1e-6);
//  - with rho_inf = 1 (no numerical dissipation) and ideal joints the energy is conserved to the
//    accuracy of the scheme: over 0.15 s the drift is 1.9e-6 of the kinetic energy (bound 1e-5);
//  - a stiff beam swings as the rigid pendulum of the dense backend: the block positions after
//    0.2 s differ by less than the static sag of the beam under its own weight and the block
//    (the elastic deflection's scale; measured 5.1e-6 m against 2.5e-4 m);
//  - the run on 2 ranks equals the run on rank 0 alone (another partition) to 1e-9.
#include "flexopt/adjoint/dist_sweep.hpp"
#include "flexopt/bodies/acf_body.hpp"
#include "flexopt/bodies/rigid_body.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/dynamics/distributed_alpha.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/mesh/distributed_mesh.hpp"
#include "test_meshes.hpp"

#include <cmath>
#include <cstdio>
#include <gtest/gtest.h>
#include <memory>
#include <random>
#include <vector>

using namespace flexopt;
using dynamics::Vec3;
using dynamics::Vector;

namespace {

const Vec3 kClamp(0, 0.025, 0.05), kTip(1, 0.025, 0.05), kGravity(0, -9.81, 0);
constexpr double kBlockMass = 2;

bodies::MassProperties block() {
  bodies::MassProperties p;
  p.mass = kBlockMass;
  p.center = kTip;
  p.inertia = 0.01 * bodies::Mat3::Identity();
  return p;
}

/// The normalizations and the joints of the pendulum: the revolute joint about z between the
/// ground and body `at_clamp` at the clamp centroid, the spherical joint between body `at_tip`
/// and the block `block_body` at the tip centroid (every body placed unrotated).
void add_joints(dynamics::Mechanism &mech, int at_clamp, int at_tip, int block_body) {
  for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b) {
    joints::Equation e;
    e.kind = joints::Equation::Kind::Normalize;
    e.a = b;
    e.owner = "normalize";
    mech.equations.push_back(e);
  }
  auto attach = [&](int body, const Vec3 &world) {
    dynamics::Attachment a;
    a.body = body;
    a.world = world;
    a.s = body < 0 ? world : Vec3(world - mech.body(body).origin());
    return a;
  };
  for (auto &e : dynamics::joint_equations(dynamics::JointType::Revolute, attach(-1, kClamp),
                                           attach(at_clamp, kClamp), Vec3::UnitZ(), "hinge"))
    mech.equations.push_back(e);
  for (auto &e : dynamics::joint_equations(dynamics::JointType::Spherical, attach(at_tip, kTip),
                                           attach(block_body, kTip), Vec3::UnitZ(), "tip"))
    mech.equations.push_back(e);
  mech.gravity = kGravity;
  mech.finalize();
}

/// The ACF pendulum on the mesh m with Young's modulus E.
struct AcfPendulum {
  bodies::AcfBody beam;
  dynamics::Mechanism mech;
  std::unique_ptr<dynamics::DistributedAlpha> da;
  AcfPendulum(const mesh::DistributedMesh &m, double E, double rho_inf, double damping = 0,
              dynamics::NewtonSettings newton = {})
      : beam("beam", m, fem::IsotropicMaterial{E, 0.3, 7850}, std::vector<double>{}, damping) {
    mech.bodies.push_back(std::make_shared<bodies::InterfaceNode>("beam:clamp", kClamp));
    mech.bodies.push_back(std::make_shared<bodies::InterfaceNode>("beam:tip", kTip));
    mech.bodies.push_back(std::make_shared<bodies::RigidBody>("block", block()));
    add_joints(mech, 0, 1, 2);
    std::vector<dynamics::AcfInterface> faces{{0, "clamp", 0, kClamp, "test"},
                                              {0, "tip", 1, kTip, "test"}};
    da = std::make_unique<dynamics::DistributedAlpha>(
        std::vector<const bodies::AcfBody *>{&beam}, &mech, faces, kGravity,
        dynamics::AlphaParameters::from_rho_inf(rho_inf), newton);
  }
  dynamics::DistState initial() const {
    Vec x0 = da->create_vector(), v0 = da->create_vector();
    da->set_nodal(x0, 0, [](const Eigen::Vector3d &X) { return X; });
    Vector q(mech.coordinates());
    for (int b = 0; b < 3; ++b)
      q.segment(mech.offset(b), 7) = mech.body(b).placement(Vec3::Zero(), bodies::Mat3::Identity());
    da->set_small(x0, q);
    dynamics::DistState s = da->initial_state(x0, v0, 0.0);
    VecDestroy(&x0);
    VecDestroy(&v0);
    return s;
  }
  /// `steps` steps of h from s0; adds the factorizations and Newton iterations to the counts.
  dynamics::DistState run(const dynamics::DistState &s0, double h, int steps,
                          long *factorizations = nullptr, long *iterations = nullptr) const {
    dynamics::DistState s = s0, next;
    for (int n = 0; n < steps; ++n) {
      dynamics::StepInfo info;
      if (!da->advance(s, h, next, info)) throw std::runtime_error("step failed");
      if (factorizations) *factorizations += info.factorizations;
      if (iterations) *iterations += info.iterations;
      s = next;
    }
    return s;
  }
  /// The block's position (the tip of the pendulum).
  Vec3 tip(const dynamics::DistState &s) const {
    return da->small_state(s).q.segment<3>(mech.offset(2));
  }
};

} // namespace

/// Checks the Newton matrix of the pendulum with stiffness-proportional damping b.
void check_newton_matrix(double damping) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  // A soft beam (E / 100) so that the elastic forces and the tie multipliers are not small.
  const AcfPendulum p(m, 2.1e9, 0.8, damping);
  const double h = 1e-3;
  const dynamics::DistState s = p.run(p.initial(), h, 5);
  const auto k = dynamics::AlphaParameters::from_rho_inf(0.8).newton_scaling(h);
  Mat A = p.da->newton_matrix(s, h);
  // A random direction z = [dq; dlambda^] (entries in [-1, 1]; the same global vector on every
  // rank count: drawn from one seeded sequence by global index).
  Vec z = p.da->create_vector(), Az = p.da->create_vector(), Rp = p.da->create_vector(),
      Rm = p.da->create_vector(), cmask = p.da->create_vector();
  PetscInt lo, hi;
  VecGetOwnershipRange(z, &lo, &hi);
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (PetscInt i = 0; i < p.da->global_size(); ++i) {
    const double value = u(gen);
    if (i >= lo && i < hi) VecSetValue(z, i, value, INSERT_VALUES);
  }
  VecAssemblyBegin(z);
  VecAssemblyEnd(z);
  MatMult(A, z, Az);
  // s +- eps z along the Newton update.
  p.da->coordinate_mask(cmask);
  const double eps = 1e-6;
  auto moved = [&](double e) {
    dynamics::DistState t = s;
    Vec dq, dl;
    VecDuplicate(z, &dq);
    VecDuplicate(z, &dl);
    VecPointwiseMult(dq, z, cmask);
    VecWAXPY(dl, -1.0, dq, z);
    VecAXPY(t.q, e, dq);
    VecAXPY(t.v, e * k.gp, dq);
    VecAXPY(t.a, e * k.ap, dq);
    VecAXPY(t.acc, e * k.bp, dq);
    VecAXPY(t.lambda, e * k.bp, dl);
    VecDestroy(&dq);
    VecDestroy(&dl);
    return t;
  };
  p.da->equations(moved(eps), Rp);
  p.da->equations(moved(-eps), Rm);
  const Vector az = test_support::gather_all(Az), rp = test_support::gather_all(Rp),
               rm = test_support::gather_all(Rm), c = test_support::gather_all(cmask);
  Vector fd = (rp - rm) / (2 * eps);
  for (Eigen::Index i = 0; i < fd.size(); ++i)
    if (c(i) != 0) fd(i) /= k.bp; // the coordinate rows are R_d / beta'
  const double err = (az - fd).cwiseAbs().maxCoeff(), ref = az.cwiseAbs().maxCoeff();
  if (comm_rank(m.comm) == 0)
    std::printf("ACF pendulum Newton matrix (%lld unknowns, damping %g s): |A z - FD| / |A z| = "
                "%.2e\n",
                static_cast<long long>(fd.size()), damping, err / ref);
  EXPECT_LT(err, 1e-6 * ref);
  for (Vec *v : {&z, &Az, &Rp, &Rm, &cmask}) VecDestroy(v);
}

TEST(AcfMechanism, NewtonMatrixIsTheDerivativeOfTheEquations) {
  check_newton_matrix(0);
}

// With damping b = 1e-3 s (the first bending mode of the soft beam, ~100 rad/s, 5 % of
// critical; the element rates after 5 steps make f_d comparable to the elastic force's change):
// the matrix adds (df_d/dx + gamma' df_d/dv) / beta'.
TEST(AcfMechanism, NewtonMatrixWithDampingIsTheDerivativeOfTheEquations) {
  check_newton_matrix(1e-3);
}

/// The distributed backward sweep (docs/theory.md section 9.7) against central differences of
/// whole forward runs: Psi = the block's x after 8 steps of 1 ms from a state s0 of the swinging
/// ACF pendulum; dPsi/ds0 = -mu_0 (treating s0 as free: R_1 uses its q, v, a, acc linearly) in a
/// random direction of all four blocks, against (Psi(s0 + e d) - Psi(s0 - e d)) / 2e. Newton's
/// method proper (responses smooth to round-off, docs/theory.md section 9.5).
void check_backward_sweep(double damping) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  dynamics::NewtonSettings newton;
  newton.reuse_contraction = 0;
  const AcfPendulum p(m, 2.1e9, 0.8, damping, newton);
  const double h = 1e-3;
  const int steps = 8;
  const dynamics::DistState s0 = p.run(p.initial(), h, 3);
  const int block_x = p.mech.offset(2);
  auto psi = [&](const dynamics::DistState &start, std::vector<dynamics::DistState> *states) {
    dynamics::DistState s = start, next;
    if (states) states->assign(1, start);
    for (int n = 0; n < steps; ++n) {
      dynamics::StepInfo info;
      if (!p.da->advance(s, h, next, info) || info.halvings > 0)
        throw std::runtime_error("step failed or halved");
      s = next;
      if (states) states->push_back(s);
    }
    return p.tip(s).x();
  };
  std::vector<dynamics::DistState> states;
  const double psi0 = psi(s0, &states);
  // dPsi/ds_N: 1 at the block's x.
  dynamics::DistState dN = s0;
  for (Vec v : {dN.q, dN.v, dN.a, dN.acc, dN.lambda}) VecZeroEntries(v);
  Vector e = Vector::Zero(p.mech.coordinates());
  e(block_x) = 1;
  p.da->set_small(dN.q, e);
  VecAssemblyBegin(dN.q);
  VecAssemblyEnd(dN.q);
  adjoint::DistBackwardSweep sweep(*p.da, 1);
  for (int k = steps; k >= 1; --k)
    sweep.step(states[static_cast<std::size_t>(k)], h, {k == steps ? &dN : nullptr});
  const dynamics::DistState mu0 = sweep.finish({nullptr})[0];
  // A random direction d (the same global vector on every rank count), on the coordinates.
  Vec cmask = p.da->create_vector();
  p.da->coordinate_mask(cmask);
  PetscInt lo, hi;
  VecGetOwnershipRange(cmask, &lo, &hi);
  auto random = [&](unsigned seed, double scale) {
    Vec v = p.da->create_vector();
    std::mt19937 gen(seed);
    std::uniform_real_distribution<double> u(-scale, scale);
    for (PetscInt i = 0; i < p.da->global_size(); ++i) {
      const double value = u(gen);
      if (i >= lo && i < hi) VecSetValue(v, i, value, INSERT_VALUES);
    }
    VecAssemblyBegin(v);
    VecAssemblyEnd(v);
    VecPointwiseMult(v, v, cmask);
    return v;
  };
  Vec dq = random(11, 1e-3), dv = random(12, 1e-1), da = random(13, 1.0), dacc = random(14, 1.0);
  auto dot = [](Vec a, Vec b) {
    PetscScalar d;
    VecDot(a, b, &d);
    return d;
  };
  const double adjoint = -(dot(mu0.q, dq) + dot(mu0.v, dv) + dot(mu0.a, da) + dot(mu0.acc, dacc));
  auto moved = [&](double eps) {
    dynamics::DistState t = s0;
    VecAXPY(t.q, eps, dq);
    VecAXPY(t.v, eps, dv);
    VecAXPY(t.a, eps, da);
    VecAXPY(t.acc, eps, dacc);
    return psi(t, nullptr);
  };
  const double eps = 1e-3;
  // Fourth order: (4 D(e/2) - D(e)) / 3.
  const double d1 = (moved(eps) - moved(-eps)) / (2 * eps),
               d2 = (moved(eps / 2) - moved(-eps / 2)) / eps;
  const double fd = (4 * d2 - d1) / 3;
  if (comm_rank(m.comm) == 0)
    std::printf("ACF pendulum backward sweep (damping %g s, %d steps, Psi = %.9f): adjoint "
                "% .12e, central differences % .12e, relative difference %.2e\n",
                damping, steps, psi0, adjoint, fd, std::abs(adjoint - fd) / std::abs(fd));
  EXPECT_LT(std::abs(adjoint - fd), 1e-7 * std::abs(fd));
  for (Vec *v : {&cmask, &dq, &dv, &da, &dacc}) VecDestroy(v);
}

TEST(AcfMechanism, DistributedBackwardSweepGivesTheDerivativeOfAResponse) {
  check_backward_sweep(0);
}

// With damping the velocity block C = df_d/dv is non-zero; the sweep separates it from the
// matrix by a second assembly without it.
TEST(AcfMechanism, DistributedBackwardSweepWithDamping) {
  check_backward_sweep(1e-3);
}

TEST(AcfMechanism, SwingingPendulumKeepsItsEnergy) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  const AcfPendulum p(m, 2.1e11, 1.0);
  const dynamics::DistState s0 = p.initial();
  const double E0 = p.da->energy(s0);
  const dynamics::DistState s = p.run(s0, 1e-3, 150);
  const double E = p.da->energy(s);
  // The scale of the energy exchanged: the block and the beam fall by about 0.1 m.
  double k, e, pot;
  p.da->energies(s, k, e, pot);
  const double drift = std::abs(E - E0) / k;
  const double ties = p.da->tie_violation(s);
  const Vec3 tip = p.tip(s);
  if (comm_rank(m.comm) == 0)
    std::printf("ACF pendulum, 150 steps of 1 ms, rho_inf = 1: |E - E0| / T = %.2e, tie residual "
                "%.2e, block at (%.6f, %.6f, %.6f)\n",
                drift, ties, tip.x(), tip.y(), tip.z());
  EXPECT_LT(drift, 1e-5); // 5 times the measured 1.9e-6
  EXPECT_LT(ties, 1e-12);
}

// The co-rotated kept matrix (docs/theory.md section 8.2) changes the iteration, not the equations:
// the swinging pendulum ends where Newton's method (a new matrix every iteration) puts it, to the
// drift that the kept-matrix tolerance allows (section 6.4: about N (gamma/beta)(T/h) 1e-15 (1 +
// max|q|) ~ 1e-10 m here), with the kept matrix applied turned or as assembled; turned, it is
// replaced far less often (the beam turns by up to 5 mrad per step).
TEST(AcfMechanism, CoRotatedKeptMatrixReachesNewtonsSolution) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  const double h = 1e-3;
  const int steps = 150;
  dynamics::NewtonSettings newton, plain, turned;
  newton.reuse_contraction = 0;
  plain.corotate_kept = false;
  long f_newton = 0, f_plain = 0, f_turned = 0, it_plain = 0, it_turned = 0;
  const AcfPendulum a(m, 2.1e11, 1.0, 0, newton), b(m, 2.1e11, 1.0, 0, plain),
      c(m, 2.1e11, 1.0, 0, turned);
  const Vec3 tip_newton = a.tip(a.run(a.initial(), h, steps, &f_newton));
  const Vec3 tip_plain = b.tip(b.run(b.initial(), h, steps, &f_plain, &it_plain));
  const Vec3 tip_turned = c.tip(c.run(c.initial(), h, steps, &f_turned, &it_turned));
  if (comm_rank(m.comm) == 0)
    std::printf("ACF pendulum, %d steps: tip vs Newton's %.2e m (kept as assembled, %ld "
                "factorizations, %ld iterations), %.2e m (kept turned, %ld factorizations, %ld "
                "iterations); Newton %ld factorizations; swung %.3f m\n",
                steps, (tip_plain - tip_newton).norm(), f_plain, it_plain,
                (tip_turned - tip_newton).norm(), f_turned, it_turned, f_newton,
                (tip_newton - kTip).norm());
  EXPECT_GT((tip_newton - kTip).norm(), 0.1);
  EXPECT_LT((tip_plain - tip_newton).norm(), 1e-9);
  EXPECT_LT((tip_turned - tip_newton).norm(), 1e-9);
  EXPECT_LT(10 * f_turned, f_plain); // measured 1 against 99
}

TEST(AcfMechanism, StiffBeamSwingsAsTheRigidPendulum) {
  mesh::MeshData data;
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2, &data);
  const double h = 1e-3;
  const int steps = 200;
  const AcfPendulum p(m, 2.1e11, 0.8);
  const Vec3 acf = p.tip(p.run(p.initial(), h, steps));
  // The rigid pendulum (dense backend): the beam's mass properties from the same mesh.
  std::vector<double> buf(13);
  if (comm_rank(m.comm) == 0) {
    const bodies::MassProperties mp = bodies::mass_properties(data, 7850);
    buf[0] = mp.mass;
    for (int k = 0; k < 3; ++k) buf[static_cast<std::size_t>(1 + k)] = mp.center(k);
    for (int k = 0; k < 9; ++k) buf[static_cast<std::size_t>(4 + k)] = mp.inertia(k / 3, k % 3);
  }
  MPI_Bcast(buf.data(), 13, MPI_DOUBLE, 0, m.comm);
  bodies::MassProperties mp;
  mp.mass = buf[0];
  mp.center = Vec3(buf[1], buf[2], buf[3]);
  for (int k = 0; k < 9; ++k) mp.inertia(k / 3, k % 3) = buf[static_cast<std::size_t>(4 + k)];
  dynamics::Mechanism rigid;
  rigid.bodies.push_back(std::make_shared<bodies::RigidBody>("beam", mp));
  rigid.bodies.push_back(std::make_shared<bodies::RigidBody>("block", block()));
  add_joints(rigid, 0, 0, 1);
  Vector q0(rigid.coordinates());
  for (int b = 0; b < 2; ++b)
    q0.segment(rigid.offset(b), 7) =
        rigid.body(b).placement(Vec3::Zero(), bodies::Mat3::Identity());
  const dynamics::GeneralizedAlpha ga(rigid, dynamics::AlphaParameters::from_rho_inf(0.8));
  dynamics::State s = ga.initial_state(q0, Vector::Zero(q0.size()), 0.0), next;
  for (int n = 0; n < steps; ++n) {
    dynamics::StepInfo info;
    ASSERT_TRUE(ga.advance(s, h, next, info));
    s = next;
  }
  const Vec3 rig = s.q.segment<3>(rigid.offset(1));
  // Static sag of the pinned beam, bounded by the cantilever under its weight q = rho A g and the
  // block's weight P: q L^4 / (8 EI) + P L^3 / (3 EI), I = b h^3 / 12 (h = 0.05 m in y).
  const double EI = 2.1e11 * 0.1 * std::pow(0.05, 3) / 12, q = 7850 * 0.005 * 9.81;
  const double sag = q / (8 * EI) + kBlockMass * 9.81 / (3 * EI);
  if (comm_rank(m.comm) == 0)
    std::printf("stiff ACF vs rigid pendulum after %d steps: block at (%.6f, %.6f) vs (%.6f, "
                "%.6f), |difference| %.3e m, sag scale %.3e m\n",
                steps, acf.x(), acf.y(), rig.x(), rig.y(), (acf - rig).norm(), sag);
  EXPECT_GT((rig - kTip).norm(), 0.1); // it has swung
  EXPECT_LT((acf - rig).norm(), sag);  // measured 5.1e-6 m against 2.5e-4 m
}

TEST(AcfMechanism, SameOnOneAndTwoRanks) {
  mesh::MeshData data;
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2, &data);
  const bool root = comm_rank(PETSC_COMM_WORLD) == 0;
  const AcfPendulum all(m, 2.1e10, 0.8);
  const dynamics::DistState sa = all.run(all.initial(), 1e-3, 50);
  const Vec3 tip_all = all.tip(sa);
  const double E_all = all.da->energy(sa);
  if (root) {
    auto alone = mesh::distribute_mesh(PETSC_COMM_SELF, &data);
    const AcfPendulum one(alone, 2.1e10, 0.8);
    const dynamics::DistState so = one.run(one.initial(), 1e-3, 50);
    EXPECT_LT((tip_all - one.tip(so)).norm(), 1e-9);
    EXPECT_NEAR(E_all, one.da->energy(so), 1e-9 * std::abs(E_all));
  }
}

namespace {

/// Placed positions x0 and given velocities v0 of the pendulum p (the caller destroys them):
/// unrotated, spinning at omega about the world origin, the beam with an elastic bending rate
/// 0.1 x (1 - x) along z that vanishes on both interface faces.
void spinning_start(const AcfPendulum &p, const Vec3 &omega, Vec &x0, Vec &v0) {
  x0 = p.da->create_vector();
  v0 = p.da->create_vector();
  p.da->set_nodal(x0, 0, [](const Eigen::Vector3d &X) { return X; });
  p.da->set_nodal(v0, 0, [&](const Eigen::Vector3d &X) {
    return Eigen::Vector3d(omega.cross(X) + Eigen::Vector3d(0, 0, 0.1 * X.x() * (1 - X.x())));
  });
  Vector q(p.mech.coordinates()), v(p.mech.coordinates());
  for (int b = 0; b < 3; ++b) {
    const Vector qb = p.mech.body(b).placement(Vec3::Zero(), bodies::Mat3::Identity());
    q.segment(p.mech.offset(b), 7) = qb;
    v.segment(p.mech.offset(b), 7) = p.mech.body(b).placement_velocity(qb, Vec3::Zero(), omega);
  }
  p.da->set_small(x0, q);
  p.da->set_small(v0, v);
}

} // namespace

// The consistent start keeps the given elastic velocities of an ACF body (docs/theory.md section
// 6.4): the pendulum is given a spin about an axis through the world origin with a component
// about x (the hinge at the clamp allows neither) and an elastic bending velocity that vanishes
// on both interface faces. The start may change only the six rigid velocity fields: the change
// at the owned nodes of every rank is one rigid field (fitted per rank; the same on every rank),
// the joints then hold, and no elastic velocity had to be corrected.
TEST(AcfMechanism, StartKeepsElasticVelocities) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  const AcfPendulum p(m, 2.1e11, 0.8);
  const Vec3 omega(0.3, 0, 2);
  Vec x0, v0;
  spinning_start(p, omega, x0, v0);
  dynamics::StartReport report;
  const dynamics::DistState s = p.da->initial_state(x0, v0, 0.0, &report);
  const std::vector<double> given = p.da->owned_values(v0, 0), now = p.da->owned_values(s.v, 0),
                            x = p.da->owned_values(s.q, 0);
  VecDestroy(&x0);
  VecDestroy(&v0);
  EXPECT_FALSE(report.elastic_corrected);
  EXPECT_LT(report.rigid_residual, 1e-12);
  // The change on this rank's nodes: dv_j = du + dw x x_j, least squares over the nodes.
  const auto nodes = static_cast<Eigen::Index>(x.size() / 3);
  ASSERT_GT(nodes, 3);
  Eigen::MatrixXd A(3 * nodes, 6);
  Eigen::VectorXd dv(3 * nodes);
  for (Eigen::Index j = 0; j < nodes; ++j) {
    A.block<3, 3>(3 * j, 0).setIdentity();
    A.block<3, 3>(3 * j, 3) = -bodies::skew(Vec3(&x[static_cast<std::size_t>(3 * j)]));
    for (int k = 0; k < 3; ++k)
      dv(3 * j + k) =
          now[static_cast<std::size_t>(3 * j + k)] - given[static_cast<std::size_t>(3 * j + k)];
  }
  const Eigen::VectorXd y = A.colPivHouseholderQr().solve(dv);
  const double change = dv.cwiseAbs().maxCoeff();
  EXPECT_GT(change, 0.01); // the given spin violated the hinge
  EXPECT_LT((A * y - dv).cwiseAbs().maxCoeff(), 1e-12 * change);
  // The same field on every rank, and the spin about x is gone: dw_x = -0.3.
  double lo[6], hi[6];
  MPI_Allreduce(y.data(), lo, 6, MPI_DOUBLE, MPI_MIN, PETSC_COMM_WORLD);
  MPI_Allreduce(y.data(), hi, 6, MPI_DOUBLE, MPI_MAX, PETSC_COMM_WORLD);
  for (int k = 0; k < 6; ++k) EXPECT_LT(hi[k] - lo[k], 1e-12 * change) << k;
  EXPECT_NEAR(y(3), -omega.x(), 1e-12);
  // The kinetic energy reported is that of the corrected velocities.
  EXPECT_NEAR(report.kinetic, p.da->kinetic_energy(s), 1e-12 * report.kinetic);
  EXPECT_LT(report.kinetic, report.kinetic_given); // the spin about x and the slip were removed
}

// The adjoint of the start's velocity dependence (docs/theory.md section 9.2, stage 2):
// start_velocity_transpose adds (d[Q; gamma]/dv)^T nu, with [Q; gamma] = start_rhs. Every part of
// [Q; gamma] is at most quadratic in v (the damping force linear, the rigid block's inertia
// terms, the joints' and the ties' convective terms quadratic), so a central difference along
// any dv is exact up to round-off: nu . (r(v + e dv) - r(v - e dv)) / (2 e) = dv . (gv - 0).
// The damped pendulum spinning about z (0.3 rad/s about x too, an elastic bending rate), random
// nu and dv, the parts of nu on the coordinates and on the constraints apart (leaving out the
// ties' terms changes the second by 7 %).
TEST(AcfMechanism, StartVelocityTransposeIsTheDerivativeOfTheRightHandSide) {
  auto m = test_support::load_test_mesh("beam.geo", 0.05, 2);
  const AcfPendulum p(m, 2.1e11, 0.8, 1e-3);
  Vec x0, v0;
  spinning_start(p, Vec3(0.3, 0, 2), x0, v0);
  dynamics::DistState s = p.da->initial_state(x0, v0, 0.0);
  VecDestroy(&x0);
  VecDestroy(&v0);
  // Random nu (all entries) and dv (the coordinates), the same on any number of ranks up to the
  // layout: each entry from its global number.
  Vec nu = p.da->create_vector(), dv = p.da->create_vector(), cmask = p.da->create_vector(),
      gv = p.da->create_vector(), rp = p.da->create_vector(), rm = p.da->create_vector();
  p.da->coordinate_mask(cmask);
  PetscInt lo, hi;
  VecGetOwnershipRange(nu, &lo, &hi);
  for (PetscInt i = lo; i < hi; ++i) {
    std::mt19937 gen(static_cast<unsigned>(1000 + i));
    std::uniform_real_distribution<double> u(-1, 1);
    VecSetValue(nu, i, u(gen), INSERT_VALUES);
    VecSetValue(dv, i, u(gen), INSERT_VALUES);
  }
  for (Vec x : {nu, dv}) {
    VecAssemblyBegin(x);
    VecAssemblyEnd(x);
  }
  VecPointwiseMult(dv, dv, cmask);
  const double e = 1e-2;
  dynamics::DistState sp = s, sm = s;
  VecAXPY(sp.v, e, dv);
  VecAXPY(sm.v, -e, dv);
  p.da->start_rhs(sp, rp);
  p.da->start_rhs(sm, rm);
  VecAXPY(rp, -1.0, rm);
  // nu on the coordinate entries (Q: the damping and the block's inertia terms), then on the
  // constraint entries (gamma: the ties' and the joints' convective terms), each on its own so
  // that neither hides the other.
  Vec part = p.da->create_vector(), mask = p.da->create_vector();
  for (const bool coordinates : {true, false}) {
    VecCopy(cmask, mask);
    if (!coordinates) {
      VecScale(mask, -1.0);
      VecShift(mask, 1.0);
    }
    VecPointwiseMult(part, nu, mask);
    VecZeroEntries(gv);
    p.da->start_velocity_transpose(s, part, gv);
    PetscScalar analytic, fd;
    VecDot(dv, gv, &analytic);
    VecDot(part, rp, &fd);
    fd /= 2 * e;
    if (comm_rank(m.comm) == 0)
      std::printf("start velocity transpose, nu on the %s: dv . gv = %.12e, central difference "
                  "%.12e\n",
                  coordinates ? "coordinates" : "constraints", static_cast<double>(analytic),
                  static_cast<double>(fd));
    EXPECT_NEAR(analytic, fd, 1e-9 * std::abs(fd)) << (coordinates ? "Q" : "gamma");
  }
  for (Vec *x : {&nu, &dv, &cmask, &gv, &rp, &rm, &part, &mask}) VecDestroy(x);
}
