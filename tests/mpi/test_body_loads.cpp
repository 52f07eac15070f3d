// The loads a body carries at a state of its mechanism (docs/theory.md section 14.2, the
// equivalent static loads of issue 47), on the flexible slider-crank of
// tests/gradient/ffrf_slider_crank (a rigid crank driven at 150 rad/s, an FFRF rod in the chord
// frame, a rigid slider on a prismatic guide) with gravity added, at the consistent start and at
// steps 20, 40, 60 of the run:
// - the loads are an exact decomposition of each body's equations of motion: their imbalance
//   (force and moment about the body's origin, body axes) equals minus the residual of the
//   body's rows, r = M acc + Q_v - Q + Phi_q^T lambda (force rows; moment 1/2 Gbar(p) r_p), to
//   1e-11 of the largest term (rounding: up to 340 nodal terms, each up to the scale, cancel;
//   measured 3.4e-13). This fails if a joint's
//   force or moment, the nodal inertia (with the FFRF rod's elastic terms 2 omega x Psi zeta' +
//   Psi zeta'') or gravity is missing or wrong;
// - so they balance to the Newton tolerance: 1e-9 of the largest term (measured 1.8e-10; the
//   iterations stop at 1e-12 on the coordinates, relative to 1 + max|q|, which leaves the
//   acceleration-level residual some thousand times larger, relative to the forces);
// - a joint's loads on its two bodies are opposite in world axes (Newton's third law), to 1e-12
//   of the force, and each sits at the interface the joint attaches to.
#include "flexopt/dynamics/body_loads.hpp"
#include "flexopt/dynamics/integrator.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/io/case.hpp"

#include <cstdio>
#include <gtest/gtest.h>
#include <stdexcept>
#include <tuple>

using namespace flexopt;

namespace {

struct MassMatrices {
  std::vector<Mat> mass;
  ~MassMatrices() {
    for (Mat &m : mass) MatDestroy(&m);
  }
};

const dynamics::PointLoad &find_load(const dynamics::BodyLoads &l, const std::string &owner) {
  for (const auto &p : l.points)
    if (p.owner == owner) return p;
  throw std::runtime_error("no load of " + owner);
}

/// Minus the residual of body mb's rows, as the force (body axes) and moment of section 14.2.
std::pair<Eigen::Vector3d, Eigen::Vector3d> equations_residual(const dynamics::Mechanism &mech,
                                                               int mb, const dynamics::State &s) {
  Eigen::VectorXd r, phi;
  mech.dynamics(s.q, s.v, s.acc, s.t, r, nullptr, nullptr, nullptr);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(mech.constraints(), mech.coordinates());
  joints::DenseSink sink(&J, nullptr);
  mech.constraint(s.q, s.t, phi, sink);
  r += J.transpose() * s.lambda;
  const int o = mech.offset(mb);
  const Eigen::Vector4d p = s.q.segment<4>(o + 3);
  return {-(bodies::rotation(p).transpose() * r.segment<3>(o)),
          -(0.5 * bodies::gbar_matrix(p) * r.segment<4>(o + 3))};
}

TEST(BodyLoads, BalanceAndThirdLawOnTheFlexibleSliderCrank) {
  io::Case c = io::load_case(FLEXOPT_SOURCE_DIR "/tests/gradient/ffrf_slider_crank");
  c.scene.gravity = std::array<double, 3>{0, -9.81, 3.0};
  const dynamics::Scene scene = dynamics::build_scene(PETSC_COMM_WORLD, c.scene);
  MassMatrices mats;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    Mat M = fem::create_matrix(scene.meshes[b]);
    fem::assemble_mass(scene.meshes[b], c.scene.bodies[b].material.density, {}, M);
    mats.mass.push_back(M);
  }
  const dynamics::Mechanism &mech = scene.mechanism;
  const dynamics::GeneralizedAlpha ga(mech, dynamics::AlphaParameters::from_rho_inf(0.8));
  dynamics::Record<dynamics::State> record;
  record.state = ga.initial_state(scene.q0, scene.v0, 0.0);

  double worst_exact = 0, worst_balance = 0, worst_third = 0;
  auto check = [&](long long j) {
    std::vector<dynamics::BodyLoads> loads;
    for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
      loads.push_back(dynamics::body_loads(scene, b, record.state, mats.mass[b]));
      const dynamics::BodyLoads &l = loads.back();
      const std::string where = c.scene.bodies[b].name + ", step " + std::to_string(j);
      const auto [force, moment] =
          equations_residual(mech, scene.bodies[b].mechanism, record.state);
      const double ef = (l.force_residual - force).norm() / l.force_scale;
      const double em = (l.moment_residual - moment).norm() / l.moment_scale;
      EXPECT_LE(ef, 1e-11) << where;
      EXPECT_LE(em, 1e-11) << where;
      const double bf = l.force_residual.norm() / l.force_scale;
      const double bm = l.moment_residual.norm() / l.moment_scale;
      EXPECT_LE(bf, 1e-9) << where;
      EXPECT_LE(bm, 1e-9) << where;
      worst_exact = std::max({worst_exact, ef, em});
      worst_balance = std::max({worst_balance, bf, bm});
    }
    // Each joint's load sits at the interface it attaches to.
    const std::vector<std::vector<std::pair<std::string, std::string>>> at = {
        {{"joint main", "end_a"}, {"joint crank_pin", "end_b"}},
        {{"joint crank_pin", "end_a"}, {"joint wrist_pin", "end_b"}},
        {{"joint wrist_pin", "pin"}, {"joint guide", "pin"}}};
    for (std::size_t b = 0; b < at.size(); ++b)
      for (const auto &[owner, interface] : at[b])
        EXPECT_EQ(find_load(loads[b], owner).interface, interface)
            << c.scene.bodies[b].name << ": " << owner;
    const auto world = [&](std::size_t b, const dynamics::PointLoad &p) -> Eigen::Vector3d {
      const int o = mech.offset(scene.bodies[b].mechanism);
      return bodies::rotation(record.state.q.segment<4>(o + 3)) * p.force;
    };
    for (const auto &[joint, a, b] :
         {std::tuple{"joint crank_pin", 0, 1}, std::tuple{"joint wrist_pin", 1, 2}}) {
      const auto ia = static_cast<std::size_t>(a), ib = static_cast<std::size_t>(b);
      const Eigen::Vector3d fa = world(ia, find_load(loads[ia], joint));
      const Eigen::Vector3d fb = world(ib, find_load(loads[ib], joint));
      const double rel = (fa + fb).norm() / fa.norm();
      EXPECT_LE(rel, 1e-12) << joint << ", step " << j;
      worst_third = std::max(worst_third, rel);
    }
  };
  check(0);
  dynamics::run_steps(ga, 60, 1e-4, record, nullptr, [&](long long j, const dynamics::StepInfo &) {
    if (j % 20 == 0) check(j);
  });
  int rank = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &rank);
  if (rank == 0)
    std::printf("[   info   ] loads against the equations %.2e, balance %.2e (of the largest "
                "term); third law %.2e\n",
                worst_exact, worst_balance, worst_third);
}

} // namespace
