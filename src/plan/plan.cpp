#include "flexopt/plan/plan.hpp"

#include "flexopt/bodies/quaternion.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/dynamics/integrator.hpp"
#include "flexopt/dynamics/scene.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/mesh/load.hpp"
#include "flexopt/plan/ked.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <optional>
#include <unsupported/Eigen/FFT>

namespace flexopt::plan {

namespace {

constexpr double kPi = 3.14159265358979323846;
/// ACF cost model (docs/theory.md section 12.4): rank-seconds per DOF and Newton iteration, and
/// Newton iterations per step: the median of the quiet ACF runs at rho_inf < 1 of the
/// speed-accuracy map (docs/benchmarks.md "Speed against accuracy": 1.5-2.7 us, median 2.2, on
/// 837-13,257 DOFs with no visible trend; 3.7-4.5 iterations per step).
constexpr double kAcfSecondsPerDofIteration = 2.2e-6;
constexpr double kAcfIterationsPerStep = 4.2;
/// The largest Tet4 mesh (nodes) that the plan meshes again at order 2 to check for locking
/// (section 12.5): about 8 times the nodes at order 2.
constexpr PetscInt kLockingCheckNodes = 5000;
/// The most steps of the rigid pre-run (section 12.1).
constexpr long long kPrerunSteps = 2000;

std::string fmt(const char *format, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char *format, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, format);
  std::vsnprintf(buf, sizeof buf, format, ap);
  va_end(ap);
  return buf;
}

/// A place where a body's elastic deflection is measured (section 12.2): a 3 x n map from the
/// elastic coordinates and the scale its error is relative to.
struct Measure {
  std::string name;
  Eigen::Matrix3Xd S;
  double scale = 0;
  double deflection = 0;       ///< max over time of |S zeta| (the full model's KED)
  bool elastic_sensor = false; ///< an elastic_displacement sensor: a rigid model misses all of it
};

/// One estimated body during the pre-run.
struct Candidate {
  std::size_t body = 0;    ///< case body
  int mech = -1;           ///< mechanism body
  int n = 0;               ///< elastic coordinates of the plan's reduction
  std::vector<int> lambda; ///< the hold rows' entries in lambda
  Eigen::MatrixXd Q;       ///< (steps + 1) x n: the hold rows' multipliers
  Eigen::MatrixXd omega;   ///< (steps + 1) x 3: the body-frame angular velocity
  double spin = 0;
};

double body_extent(const mesh::DistributedMesh &m) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (PetscInt i = 0; i < m.owned_nodes; ++i)
    for (int k = 0; k < 3; ++k) {
      lo(k) = std::min(lo(k), m.coordinates[static_cast<std::size_t>(3 * i + k)]);
      hi(k) = std::max(hi(k), m.coordinates[static_cast<std::size_t>(3 * i + k)]);
    }
  MPI_Allreduce(MPI_IN_PLACE, lo.data(), 3, MPI_DOUBLE, MPI_MIN, m.comm);
  MPI_Allreduce(MPI_IN_PLACE, hi.data(), 3, MPI_DOUBLE, MPI_MAX, m.comm);
  return (hi - lo).maxCoeff();
}

/// The frequency [Hz] below which all but a fraction `tail` of the energy of the columns of Y
/// (samples every h) lies: one-sided spectra of the mean-free columns plus the mean at f = 0.
double energy_frequency(const Eigen::MatrixXd &Y, double h, double tail) {
  const Eigen::Index N = Y.rows();
  if (N < 4) return 0;
  Eigen::FFT<double> fft;
  std::vector<double> energy(static_cast<std::size_t>(N / 2 + 1), 0.0);
  std::vector<double> column(static_cast<std::size_t>(N));
  std::vector<std::complex<double>> spectrum;
  for (Eigen::Index k = 0; k < Y.cols(); ++k) {
    for (Eigen::Index i = 0; i < N; ++i) column[static_cast<std::size_t>(i)] = Y(i, k);
    fft.fwd(spectrum, column);
    for (std::size_t f = 0; f < energy.size(); ++f)
      energy[f] +=
          std::norm(spectrum[f]) * (f == 0 || 2 * f == static_cast<std::size_t>(N) ? 1 : 2);
  }
  double total = 0;
  for (double e : energy) total += e;
  if (!(total > 0)) return 0;
  double below = 0;
  for (std::size_t f = 0; f < energy.size(); ++f) {
    below += energy[f];
    if (below >= (1 - tail) * total) return static_cast<double>(f) / (static_cast<double>(N) * h);
  }
  return 0.5 / h;
}

/// max over the samples (rows of Z) of |S z|.
double max_norm(const Eigen::Matrix3Xd &S, const Eigen::MatrixXd &Z) {
  return (Z * S.transpose()).rowwise().norm().maxCoeff();
}

/// An upper bound of the mesh's highest angular frequency [rad/s]: the largest over the
/// elements of the largest eigenvalue of K_e x = w^2 M_e x (the assembled spectrum lies below
/// the elements' largest, Irons & Treharne 1971). Collective.
double highest_frequency(const mesh::DistributedMesh &mesh, const fem::IsotropicMaterial &mat) {
  const fem::IsotropicMaterial material{mat.E, mat.nu, mat.density};
  double w2 = 0;
  for (PetscInt e = 0; e < mesh.local_elements(); ++e) {
    const fem::ElementCoords X = mesh.element_coordinates(e);
    try {
      const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> eig(
          fem::element_stiffness(mesh.type, X, material),
          fem::element_mass(mesh.type, X, mat.density), Eigen::EigenvaluesOnly);
      w2 = std::max(w2, eig.eigenvalues().maxCoeff());
    } catch (const std::exception &err) {
      abort_local(std::string("plan: highest frequency: element ") +
                  std::to_string(mesh.element_tags[static_cast<std::size_t>(e)]) + ": " +
                  err.what());
    }
  }
  MPI_Allreduce(MPI_IN_PLACE, &w2, 1, MPI_DOUBLE, MPI_MAX, mesh.comm);
  return std::sqrt(w2);
}

/// The largest nodal |U z| over all ranks (U: the basis at the owned nodes, node-major).
double max_nodal_norm(const Eigen::MatrixXd &U, const Eigen::VectorXd &z, MPI_Comm comm) {
  double m = U.rows() ? (U * z).reshaped(3, U.rows() / 3).colwise().norm().maxCoeff() : 0;
  MPI_Allreduce(MPI_IN_PLACE, &m, 1, MPI_DOUBLE, MPI_MAX, comm);
  return m;
}

} // namespace

Plan make_plan(MPI_Comm comm, const PlanSettings &c, const PlanOptions &o) {
  using dynamics::BodyModel;
  const double t_plan = wall_time();
  Plan plan;
  plan.accuracy = c.accuracy;
  const double eps = c.accuracy;

  // The pre-run's scene: every body that is not rigid by the user's choice is an FFRF body with
  // the plan's reduction and no initial elastic state.
  dynamics::SceneDescription pre = c.scene;
  std::vector<std::size_t> estimated;
  for (std::size_t b = 0; b < pre.bodies.size(); ++b) {
    dynamics::BodyDescription &body = pre.bodies[b];
    BodyPlan bp;
    bp.body = body.name;
    bp.given = c.scene.bodies[b].model;
    bp.model = bp.given;
    if (body.model == BodyModel::Rigid || body.interfaces.empty()) {
      bp.recommended = BodyModel::Rigid;
      if (body.model != BodyModel::Rigid) {
        bp.model = bp.given == BodyModel::Auto ? BodyModel::Rigid : bp.given;
        bp.reasons.push_back("no interfaces: a flexible model needs one as its frame; estimated "
                             "as rigid");
      }
      body.model = BodyModel::Rigid;
      plan.bodies.push_back(bp);
      continue;
    }
    const int interfaces = static_cast<int>(body.interfaces.size());
    body.model = BodyModel::Ffrf;
    body.reduction.modes =
        std::min(o.max_modes, bodies::kMaxBodyCoordinates - 7 - 6 * (interfaces - 1));
    body.reduction.geometric_stiffening = false;
    body.initial.elastic_displacement = {};
    body.initial.elastic_velocity = {};
    body.rayleigh = {0, 0};
    bp.estimated = true;
    estimated.push_back(b);
    plan.bodies.push_back(bp);
  }
  if (estimated.empty()) {
    plan.seconds = wall_time() - t_plan;
    return plan;
  }
  if (o.report)
    print0(comm,
           "plan: the rigid pre-run: every body that is not rigid reduced with up to %d "
           "fixed-interface modes and held rigid\n",
           o.max_modes);
  dynamics::Scene scene = dynamics::build_scene(comm, pre);

  // Hold every elastic coordinate of the estimated bodies at zero: rows right after the
  // Euler-parameter normalizations, so that the joint rows they make redundant are dropped.
  dynamics::Mechanism &mech = scene.mechanism;
  std::vector<Candidate> cand;
  std::vector<joints::Equation> holds;
  for (std::size_t b : estimated) {
    Candidate cd;
    cd.body = b;
    cd.mech = scene.bodies[b].mechanism;
    cd.n = mech.size(cd.mech) - 7;
    for (int k = 0; k < cd.n; ++k) {
      joints::Equation e;
      e.kind = joints::Equation::Kind::ElasticCoordinate;
      e.a = cd.mech;
      e.coordinate = k;
      e.owner = c.scene.bodies[b].name + " (held rigid)";
      e.row_in_owner = k;
      holds.push_back(e);
    }
    cand.push_back(std::move(cd));
  }
  std::size_t first_joint = 0;
  while (first_joint < mech.equations.size() &&
         mech.equations[first_joint].kind == joints::Equation::Kind::Normalize)
    ++first_joint;
  mech.equations.insert(mech.equations.begin() + static_cast<std::ptrdiff_t>(first_joint),
                        holds.begin(), holds.end());
  mech.finalize();
  mech.drop_redundant_rows(scene.q0, 0.0);
  {
    std::size_t e = first_joint;
    for (Candidate &cd : cand)
      for (int k = 0; k < cd.n; ++k, ++e) {
        const int row = mech.enforced_index(mech.first_row(static_cast<int>(e)));
        if (row < 0)
          throw Error("plan: body " + c.scene.bodies[cd.body].name +
                          ": a hold row was found redundant (an internal error)",
                      true);
        cd.lambda.push_back(row);
      }
  }

  // Sensors: the scale of each position or displacement sensor is its largest displacement
  // over the pre-run.
  std::vector<dynamics::BoundSensor> track;
  std::vector<std::size_t> track_of;
  for (std::size_t i = 0; i < scene.sensors.size(); ++i) {
    const dynamics::BoundSensor &s = scene.sensors[i];
    if (s.quantity == dynamics::SensorQuantity::Position ||
        s.quantity == dynamics::SensorQuantity::Displacement) {
      dynamics::BoundSensor p = s;
      p.quantity = dynamics::SensorQuantity::Position;
      track.push_back(p);
      track_of.push_back(i);
    }
  }
  std::vector<bodies::Vec3> start(track.size());
  std::vector<double> scale(track.size(), 0.0);

  // The pre-run's grid: the case's, or at most kPrerunSteps steps over the same time (a rigid
  // motion needs no more; the KED integration is exact for the sampled forcing, and the
  // index-3 multipliers carry less round-off at larger steps, section 6.4).
  const long long case_steps = std::max(1LL, std::llround(c.time.end / c.time.step));
  const long long steps = std::min(case_steps, kPrerunSteps);
  const double h = c.time.end / static_cast<double>(steps);
  plan.steps = steps;
  for (Candidate &cd : cand) {
    cd.Q.resize(steps + 1, cd.n);
    cd.omega.resize(steps + 1, 3);
  }
  // rho_inf at most 0.5: the multipliers' start-up oscillation of the index-3 scheme decays as
  // rho_inf^n (section 6.4), and the forcing is the multipliers; the rigid motion is second-order
  // accurate for any rho_inf.
  dynamics::IntegratorSettings settings = dynamics::IntegratorSettings::from(c.time);
  settings.alpha = dynamics::AlphaParameters::from_rho_inf(std::min(c.time.rho_inf, 0.5));
  settings.step = h;
  settings.steps = steps;
  dynamics::Integrator integrator(scene, settings);
  const double t0 = wall_time();
  integrator.start();
  const dynamics::State *state = nullptr;
  auto record = [&](long long n) {
    for (Candidate &cd : cand) {
      for (int k = 0; k < cd.n; ++k)
        cd.Q(n, k) = state->lambda(cd.lambda[static_cast<std::size_t>(k)]);
      const int rigid = mech.offset(cd.mech);
      const bodies::Vec4 p = state->q.segment<4>(rigid + 3), pd = state->v.segment<4>(rigid + 3);
      cd.omega.row(n) = (2.0 * bodies::gbar_matrix(p) * pd).transpose();
      cd.spin = std::max(cd.spin, cd.omega.row(n).norm());
    }
    for (std::size_t i = 0; i < track.size(); ++i) {
      const bodies::Vec3 x = dynamics::sensor_value(scene, track[i], state->q);
      if (n == 0) start[i] = x;
      scale[i] = std::max(scale[i], (x - start[i]).norm());
    }
  };
  try {
    integrator.run([&](const dynamics::StepView &v) {
      state = v.dense;
      record(v.step);
    });
  } catch (const Error &e) {
    throw Error(std::string("plan: the rigid pre-run: ") + e.what(), true);
  }
  plan.prerun_s = wall_time() - t0;
  if (o.report)
    print0(comm, "plan: pre-run: %lld steps of %g s in %.2f s\n", steps, h, plan.prerun_s);

  // The smallest position scale among the scene's sensors (the propagation of a body's
  // interface motion to the other bodies' sensors).
  int size = 1;
  MPI_Comm_size(comm, &size);
  for (Candidate &cd : cand) {
    BodyPlan &bp = plan.bodies[cd.body];
    Estimates &est = bp.est;
    const dynamics::SceneBody &sb = scene.bodies[cd.body];
    const reduce::FlexibleReduction &red = *sb.reduction;
    const mesh::DistributedMesh &mesh = scene.meshes[cd.body];
    est.dofs = static_cast<int>(3 * mesh.global_nodes);
    est.length = body_extent(mesh);
    est.reduction_s = scene.reduction_seconds[cd.body];
    est.spin = cd.spin;
    const double w1 = std::sqrt(red.eigenvalues(0));
    est.f1 = w1 / (2 * kPi);

    // The KED response of the full plan model and of the sub-models.
    const ModalModel full = modal_model(red.K, red.M, Eigen::MatrixXd::Identity(cd.n, cd.n), cd.n);
    const Eigen::MatrixXd Z = ked_response(full, cd.Q, h);
    // Excitation: the spectrum of the quasi-static modal response Q_k / w_k^2.
    {
      const Eigen::MatrixXd Y = (cd.Q * full.E) * full.w2.cwiseInverse().asDiagonal();
      est.f_excitation = energy_frequency(Y, h, eps * eps);
    }

    // Where the deflection is measured.
    // A sensor that moves by less than 1e-9 of the body's extent over the pre-run (a scene at
    // rest) has no scale to measure against.
    const double tiny = 1e-9 * est.length;
    double other_scale = 0;
    bool other_sensors = false;
    for (std::size_t i = 0; i < track.size(); ++i)
      if (scene.sensors[track_of[i]].body != cd.mech && scale[i] > tiny) {
        other_scale = other_sensors ? std::min(other_scale, scale[i]) : scale[i];
        other_sensors = true;
      }
    std::vector<Measure> measures;
    for (std::size_t i = 0; i < scene.sensors.size(); ++i) {
      const dynamics::BoundSensor &s = scene.sensors[i];
      if (s.body != cd.mech || s.S.cols() != cd.n) continue;
      Measure m;
      m.name = "sensor " + s.name;
      m.S = s.S;
      m.deflection = max_norm(s.S, Z);
      if (s.quantity == dynamics::SensorQuantity::ElasticDisplacement) {
        m.elastic_sensor = true;
        m.scale = m.deflection;
      } else if (s.quantity == dynamics::SensorQuantity::Position ||
                 s.quantity == dynamics::SensorQuantity::Displacement) {
        for (std::size_t j = 0; j < track.size(); ++j)
          if (track_of[j] == i) m.scale = scale[j];
      } else {
        continue;
      }
      est.sensor_deflection.emplace_back(s.name, m.deflection);
      if (m.scale > tiny) measures.push_back(m);
    }
    // Each interface's elastic displacement relative to the rigid motion of interface 0 (which
    // turns elastically in a chord frame): T_I + [c_I - c_0]x Theta_0, what the joints pass on.
    if (other_sensors)
      for (std::size_t I = 1; I < red.translation.size(); ++I) {
        const Eigen::Vector3d d = red.centroids[I] - red.centroids[0];
        const Eigen::Matrix3Xd S = red.translation[I] + bodies::skew(d) * red.rotation[0];
        if (S.cwiseAbs().maxCoeff() > 0)
          measures.push_back({"interface " + c.scene.bodies[cd.body].interfaces[I], S, other_scale,
                              max_norm(S, Z), false});
      }

    // The worst instant: the largest strain energy; the nodes and elements there.
    Eigen::Index worst = 0;
    {
      const Eigen::VectorXd energy = ((Z * red.K).cwiseProduct(Z)).rowwise().sum();
      energy.maxCoeff(&worst);
    }
    const Eigen::VectorXd zeta = Z.row(worst).transpose();
    {
      const Eigen::MatrixXd &U = scene.owned_modes[cd.body];
      est.deflection = max_nodal_norm(U, zeta, comm);
      Vec u = fem::create_ghosted_vector(mesh);
      FX_PETSC(VecZeroEntries(u));
      std::vector<Vec> basis = red.basis;
      FX_PETSC(VecMAXPY(u, cd.n, zeta.data(), basis.data()));
      FX_PETSC(VecGhostUpdateBegin(u, INSERT_VALUES, SCATTER_FORWARD));
      FX_PETSC(VecGhostUpdateEnd(u, INSERT_VALUES, SCATTER_FORWARD));
      const std::vector<double> theta = fem::element_rotations(mesh, u);
      double tmax = theta.empty() ? 0 : *std::max_element(theta.begin(), theta.end());
      MPI_Allreduce(MPI_IN_PLACE, &tmax, 1, MPI_DOUBLE, MPI_MAX, comm);
      est.rotation = tmax;
      FX_PETSC(VecDestroy(&u));
    }
    const bool nodes_only = measures.empty();

    // Rigid: the whole KED deflection is the rigid model's error.
    est.rigid_error = 0;
    if (!measures.empty()) est.rigid_error_at = measures.front().name;
    bool elastic_sensor = false;
    for (const Measure &m : measures) {
      const double e = m.elastic_sensor ? 1.0 : m.deflection / m.scale;
      elastic_sensor = elastic_sensor || m.elastic_sensor;
      if (e > est.rigid_error) est.rigid_error = e, est.rigid_error_at = m.name;
    }
    if (nodes_only) {
      est.rigid_error = est.deflection / est.length;
      est.rigid_error_at = "largest nodal deflection / body size";
    }

    // The estimates of what a model changes in the motion (the loads' stress, ACF's mesh) start
    // as the case does: at rest and undeformed unless the case gives the body an initial elastic
    // state (then in its quasi-static state, as the modes' test): the ringing of a body released
    // undeformed under load is physical, and its phase is what a stiffness change shifts.
    const Start start = [&]() {
      const dynamics::InitialPlacement &init = c.scene.bodies[cd.body].initial;
      auto none = [](const std::array<std::string, 3> &f) {
        return f[0].empty() && f[1].empty() && f[2].empty();
      };
      return none(init.elastic_displacement) && none(init.elastic_velocity) ? Start::Rest
                                                                            : Start::QuasiStatic;
    }();
    // The relative error of the measures that a change D of the KED response (rows: samples)
    // makes: the largest over the measures, or the nodes at the worst instant.
    auto measures_error = [&](const Eigen::MatrixXd &D, std::string *at) {
      if (measures.empty())
        return max_nodal_norm(scene.owned_modes[cd.body], D.row(worst).transpose(), comm) /
               est.length;
      double e = 0;
      for (const Measure &m : measures) {
        const double em = max_norm(m.S, D) / m.scale;
        if (em > e) {
          e = em;
          if (at) *at = m.name;
        }
      }
      return e;
    };

    // FFRF with j fixed-interface modes against the plan's model.
    const int s0 = red.static_modes, fixed = red.fixed_modes;
    int chosen = -1;
    for (int j = 0; j <= fixed; ++j) {
      if (s0 + j == 0) {
        est.mode_errors.push_back(est.rigid_error);
        continue;
      }
      double e = 0;
      if (j < fixed) {
        const ModalModel sub = modal_model(red.K, red.M, red.craig_bampton, s0 + j);
        e = measures_error(ked_response(sub, cd.Q, h) - Z, nullptr);
      }
      est.mode_errors.push_back(e);
      if (chosen < 0 && e <= 0.5 * eps) chosen = j;
    }
    if (chosen < 0) chosen = fixed;

    // Geometric stiffening (rule 4) decides which part of the loads' stress FFRF takes in.
    const double spin_ratio = w1 > 0 ? est.spin / w1 : 0;
    bp.geometric_stiffening = spin_ratio * spin_ratio > eps;

    // The loads' stress stiffening (section 12.2): the stress of the quasi-static deformation
    // zeta_sigma = K_r^-1 (Q - F_c) that FFRF leaves out (F_c: the centrifugal load about the frame
    // origin, taken in by stiffened FFRF), compressed to its leading directions d_i, its reduced
    // geometric stiffness G_sigma(t) = sum_i c_i(t) G(d_i), the largest relative stiffness change
    // mu_sigma, and what it changes in the measures: the KED response with K_r + G_sigma(t)
    // against K_r's.
    {
      const Eigen::VectorXd w2 = red.eigenvalues.head(cd.n), root = w2.cwiseSqrt();
      Eigen::MatrixXd F = cd.Q;
      if (bp.geometric_stiffening)
        for (Eigen::Index t = 0; t < F.rows(); ++t) {
          const Eigen::Vector3d w = cd.omega.row(t).transpose();
          const Eigen::Matrix3d A =
              w.squaredNorm() * Eigen::Matrix3d::Identity() - w * w.transpose();
          for (int k = 0; k < cd.n; ++k)
            F(t, k) -= A.cwiseProduct(red.invariants.S1[static_cast<std::size_t>(k)]).sum();
        }
      // zeta_sigma K_r^1/2 = F K_r^-1/2 (rows: samples), in the energy norm.
      const Eigen::BDCSVD<Eigen::MatrixXd> svd(F * root.cwiseInverse().asDiagonal(),
                                               Eigen::ComputeThinU | Eigen::ComputeThinV);
      const Eigen::VectorXd &sv = svd.singularValues();
      int r = 0;
      while (r < std::min<Eigen::Index>(6, sv.size()) && sv(r) > 0 && sv(r) >= 1e-3 * sv(0)) ++r;
      Eigen::MatrixXd coef(F.rows(), r);
      std::vector<Vec> dirs;
      for (int i = 0; i < r; ++i) {
        coef.col(i) = sv(i) * svd.matrixU().col(i);
        dirs.push_back(
            reduce::basis_combination(red.basis, svd.matrixV().col(i).cwiseQuotient(root)));
      }
      const fem::IsotropicMaterial &mat = c.scene.bodies[cd.body].material;
      const std::vector<Eigen::MatrixXd> G =
          r ? reduce::reduced_geometric_stiffness(
                  mesh, fem::IsotropicMaterial{mat.E, mat.nu, mat.density}, red.basis, dirs, {},
                  "plan: the loads' stress stiffening")
            : std::vector<Eigen::MatrixXd>{};
      for (Vec &v : dirs) FX_PETSC(VecDestroy(&v));
      // mu_sigma (reported): at most ~250 samples, evenly spaced, and the one of the largest
      // coefficients.
      const Eigen::VectorXd W = root.cwiseInverse();
      const Eigen::Index samples = coef.rows(), stride = std::max<Eigen::Index>(1, samples / 250);
      Eigen::Index peak = 0;
      if (r > 0) coef.rowwise().norm().maxCoeff(&peak);
      for (Eigen::Index t = 0; t < samples && r > 0; ++t) {
        if (t % stride != 0 && t != peak) continue;
        Eigen::MatrixXd Gt = Eigen::MatrixXd::Zero(cd.n, cd.n);
        for (int i = 0; i < r; ++i) Gt += coef(t, i) * G[static_cast<std::size_t>(i)];
        const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(
            W.asDiagonal() * Gt * W.asDiagonal(), Eigen::EigenvaluesOnly);
        est.stress_stiffening =
            std::max(est.stress_stiffening, eig.eigenvalues().cwiseAbs().maxCoeff());
      }
      // e_sigma on the FFRF model rule 4 picks (the static modes and the chosen fixed-interface
      // modes, at least one coordinate): its stiffness with and without G_sigma.
      const ModalModel sub =
          modal_model(red.K, red.M, red.craig_bampton, std::min(cd.n, std::max(1, s0 + chosen)));
      std::vector<Eigen::MatrixXd> Gs;
      for (const Eigen::MatrixXd &Gi : G) Gs.push_back(sub.E.transpose() * Gi * sub.E);
      const Eigen::MatrixXd Qs = cd.Q * sub.E;
      double lowest = 0;
      const Eigen::MatrixXd D = (ked_response_varying(Eigen::MatrixXd(sub.w2.asDiagonal()), Gs,
                                                      coef, Qs, h, start, &lowest) -
                                 modal_response(sub.w2, Qs, h, start)) *
                                sub.E.transpose();
      est.stress_error_at = est.rigid_error_at;
      est.stress_error = lowest > 0 ? measures_error(D, &est.stress_error_at)
                                    : std::numeric_limits<double>::infinity();
    }

    // The rules (section 12.3).
    const bool flexible_design = !c.design_body.empty() && c.design_body == bp.body;
    // Why ACF (the first reason that holds), and what keeps a body from it: a response of the
    // case (objective, constraint) on an elastic_displacement sensor of the body.
    // The loads' stress, which FFRF leaves out, changes what the measures see by e_sigma; half
    // the budget (the other half: the modes' truncation).
    const bool stressed = est.stress_error > 0.5 * eps;
    auto acf_reason = [&]() {
      if (est.rotation * est.rotation > eps)
        return fmt("acf: the elastic rotation reaches %.3g rad; FFRF's linear strain in a "
                   "floating frame leaves out terms of order rotation^2 = %.2g > %g",
                   est.rotation, est.rotation * est.rotation, eps);
      if (!std::isfinite(est.stress_error))
        return std::string("acf: the loads' stress takes the body's stiffness to zero (it "
                           "buckles under the rigid motion's loads), which FFRF's linear "
                           "elasticity leaves out");
      return fmt("acf: the loads' stress (inertia, gravity, joints%s) changes the body's "
                 "stiffness by up to %.2g and %s by %.2g of its scale (> %g / 2), which FFRF's "
                 "linear elasticity leaves out",
                 bp.geometric_stiffening ? "; less the centrifugal part stiffened FFRF takes in"
                                         : "",
                 est.stress_stiffening, est.stress_error_at.c_str(), est.stress_error, eps);
    };
    std::string acf_blocker;
    for (const auto &[type, name] : c.sensor_responses)
      for (const dynamics::SensorDescription &sensor : c.scene.sensors)
        if (sensor.name == name && sensor.body == bp.body &&
            sensor.quantity == dynamics::SensorQuantity::ElasticDisplacement && acf_blocker.empty())
          acf_blocker = "the " + type + " response uses sensor '" + sensor.name +
                        "', this body's elastic displacement";
    bp.modes = chosen;
    if (!elastic_sensor && !flexible_design && est.rigid_error <= eps) {
      bp.recommended = BodyModel::Rigid;
      bp.reasons.push_back(fmt("rigid: the elastic deflection changes %s by %.2g of its scale, "
                               "within the accuracy %g",
                               est.rigid_error_at.c_str(), est.rigid_error, eps));
    } else if ((est.rotation * est.rotation > eps || stressed) && acf_blocker.empty()) {
      bp.recommended = BodyModel::Acf;
      bp.reasons.push_back(acf_reason());
    } else {
      if (!acf_blocker.empty() && (est.rotation * est.rotation > eps || stressed))
        bp.warnings.push_back(acf_reason() + "; but " + acf_blocker +
                              ", which a response of an ACF body cannot use yet: FFRF, with "
                              "that error");
      bp.recommended = BodyModel::Ffrf;
      if (elastic_sensor)
        bp.reasons.push_back("flexible: a sensor measures this body's elastic displacement");
      else if (flexible_design)
        bp.reasons.push_back("flexible: the design body of the optimization");
      else
        bp.reasons.push_back(fmt("flexible: a rigid model misses %.2g of %s's scale (> %g)",
                                 est.rigid_error, est.rigid_error_at.c_str(), eps));
      bp.reasons.push_back(fmt("ffrf: elastic rotation %.3g rad (rotation^2 = %.2g %s %g), the "
                               "loads' stress stiffening %.2g, %.2g of the measures (%s %g / 2)",
                               est.rotation, est.rotation * est.rotation,
                               est.rotation * est.rotation > eps ? ">" : "<=", eps,
                               est.stress_stiffening, est.stress_error,
                               stressed ? ">" : "<=", eps));
      std::string errs;
      for (std::size_t j = 0;
           j < est.mode_errors.size() && j <= static_cast<std::size_t>(chosen) + 2; ++j)
        errs += fmt("%s%zu: %.2g", errs.empty() ? "" : ", ", j, est.mode_errors[j]);
      bp.reasons.push_back(fmt("modes: %d (relative error against %d modes, KED: %s; <= %g)",
                               chosen, fixed, errs.c_str(), 0.5 * eps));
      if (bp.geometric_stiffening)
        bp.reasons.push_back(fmt("geometric stiffening: spin %.3g rad/s is %.3g times the first "
                                 "frequency %.4g rad/s; (spin/w1)^2 = %.2g > %g",
                                 est.spin, spin_ratio, w1, spin_ratio * spin_ratio, eps));
      else
        bp.reasons.push_back(
            fmt("no geometric stiffening: (spin/w1)^2 = %.2g <= %g", spin_ratio * spin_ratio, eps));
    }
    bp.reasons.push_back(fmt("estimates: first frequency %.4g Hz, excitation below %.3g Hz, spin "
                             "%.3g rad/s, KED deflection %.3g m, rotation %.3g rad, the loads' "
                             "stress stiffening %.3g (%.2g of the measures)",
                             est.f1, est.f_excitation, est.spin, est.deflection, est.rotation,
                             est.stress_stiffening, est.stress_error));

    // ACF's mesh (section 12.3): for an auto body that the rules make ACF, meshed from a .geo at a
    // given size and not a design body, the coarsest of 4, 3, 2 and 1.5 times the case's size
    // whose frequencies, put into the KED response in place of the case mesh's, change the
    // measures by at most eps / 4.
    std::optional<mesh::DistributedMesh> acf_mesh;
    const dynamics::BodyDescription &spec = pre.bodies[cd.body];
    if (bp.recommended == BodyModel::Acf && bp.given == BodyModel::Auto && !flexible_design &&
        spec.mesh.size > 0 && mesh::meshed_from_geo(spec.mesh)) {
      const fem::IsotropicMaterial &mat = spec.material;
      const Eigen::MatrixXd F = cd.Q * full.E;
      const Eigen::MatrixXd Zf = modal_response(full.w2, F, h, start) * full.E.transpose();
      std::string trials;
      for (double factor : {4.0, 3.0, 2.0, 1.5}) {
        dynamics::BodyDescription trial = spec;
        trial.mesh.size = factor * spec.mesh.size;
        std::optional<mesh::DistributedMesh> tm;
        std::shared_ptr<reduce::FlexibleReduction> tr;
        try {
          tm.emplace(mesh::load_body_mesh(comm, trial.mesh));
          tr = dynamics::reduce_ffrf_body(*tm, trial, mat, nullptr);
        } catch (const Error &err) { // collective: every rank skips the size
          trials +=
              fmt("%s%g m: failed (%s)", trials.empty() ? "" : ", ", trial.mesh.size, err.what());
          continue;
        }
        // The case mesh's modes with the trial mesh's frequencies, mode by mode.
        Eigen::VectorXd w2 = full.w2;
        const Eigen::Index m = std::min(w2.size(), tr->eigenvalues.size());
        for (Eigen::Index k = 0; k < m; ++k) w2(k) *= tr->eigenvalues(k) / red.eigenvalues(k);
        const double e =
            measures_error(modal_response(w2, F, h, start) * full.E.transpose() - Zf, nullptr);
        trials += fmt("%s%g m: %.2g (%lld DOFs)", trials.empty() ? "" : ", ", trial.mesh.size, e,
                      3LL * static_cast<long long>(tm->global_nodes));
        if (e <= 0.25 * eps) {
          bp.mesh_size = trial.mesh.size;
          est.acf_dofs = static_cast<int>(3 * tm->global_nodes);
          acf_mesh.emplace(std::move(*tm));
          break;
        }
      }
      if (bp.mesh_size > 0)
        bp.reasons.push_back(fmt("acf mesh: size %g m (the case's %g m): its frequencies change "
                                 "the measures by at most %g / 4 (%s)",
                                 bp.mesh_size, spec.mesh.size, eps, trials.c_str()));
      else
        bp.reasons.push_back(fmt("acf mesh: the case's (%g m): a coarser one changes the measures "
                                 "by more than %g / 4 (%s)",
                                 spec.mesh.size, eps, trials.c_str()));
    }

    // Linear tetrahedra lock in bending (section 12.5): a flexible body meshed from a .geo with
    // Tet4 (up to kLockingCheckNodes nodes) is reduced again on the same mesh at order 2, and a
    // first frequency more than eps above that one is reported.
    if (bp.recommended != BodyModel::Rigid && mesh.type == fem::ElementType::Tet4 &&
        mesh::meshed_from_geo(spec.mesh) && mesh.global_nodes <= kLockingCheckNodes) {
      dynamics::BodyDescription quadratic = spec;
      quadratic.mesh.order = 2;
      try {
        const mesh::DistributedMesh qm = mesh::load_body_mesh(comm, quadratic.mesh);
        const auto qr = dynamics::reduce_ffrf_body(qm, quadratic, spec.material, nullptr);
        const double stiff = std::sqrt(red.eigenvalues(0) / qr->eigenvalues(0)) - 1;
        if (stiff > eps)
          bp.warnings.push_back(fmt(
              "the mesh is too stiff: linear tetrahedra (Tet4) lock in bending; its first "
              "frequency, %.4g Hz, is %.1f %% above the same mesh at order 2 (%.4g Hz), and the "
              "estimates take the mesh as exact: give mesh: {order: 2} (or a finer size)",
              est.f1, 100 * stiff, std::sqrt(qr->eigenvalues(0)) / (2 * kPi)));
      } catch (const Error &err) { // collective
        bp.warnings.push_back(std::string("the order-2 check of the Tet4 mesh failed: ") +
                              err.what());
      }
    }

    // What runs, and where a given model disagrees.
    if (bp.given == BodyModel::Auto) {
      bp.model = bp.recommended;
    } else {
      bp.model = bp.given;
      const dynamics::ReductionSettings &r = c.scene.bodies[cd.body].reduction;
      if (bp.given == BodyModel::Ffrf && !r.geometric_stiffening && spin_ratio >= 1)
        bp.warnings.push_back(fmt("linear FFRF will diverge at this spin rate: %.3g rad/s is "
                                  "%.3g times the first frequency %.4g rad/s (give reduction: "
                                  "{geometric_stiffening: true})",
                                  est.spin, spin_ratio, w1));
      else if (bp.given == BodyModel::Ffrf && !r.geometric_stiffening && bp.geometric_stiffening)
        bp.warnings.push_back(fmt("the spin changes the first frequency by about (spin/w1)^2 = "
                                  "%.2g > %g; reduction: {geometric_stiffening: true} takes it in",
                                  spin_ratio * spin_ratio, eps));
      if (bp.given == BodyModel::Ffrf && bp.recommended == BodyModel::Acf)
        bp.warnings.push_back(
            est.rotation * est.rotation > eps
                ? fmt("FFRF's small-deformation assumption: the elastic rotation reaches %.3g "
                      "rad (rotation^2 = %.2g > %g); model: acf",
                      est.rotation, est.rotation * est.rotation, eps)
                : fmt("FFRF's linear elasticity: the loads' stress changes the stiffness by "
                      "%.2g and the measures by %.2g (> %g / 2); model: acf",
                      est.stress_stiffening, est.stress_error, eps));
      if (bp.given == BodyModel::Ffrf && bp.recommended == BodyModel::Ffrf && r.modes < chosen)
        bp.warnings.push_back(
            fmt("%d modes leave %.2g of the sensors' scale (the estimates "
                "need %d for %g)",
                r.modes, est.mode_errors[static_cast<std::size_t>(std::min(r.modes, fixed))],
                chosen, eps));
      if (bp.given == BodyModel::Rigid && bp.recommended != BodyModel::Rigid)
        bp.warnings.push_back(fmt("a rigid model misses %.2g of %s's scale (> %g)", est.rigid_error,
                                  est.rigid_error_at.c_str(), eps));
      if (bp.given == BodyModel::Acf && bp.recommended != BodyModel::Acf)
        bp.warnings.push_back(std::string("the estimates find ") +
                              dynamics::model_name(bp.recommended) +
                              " enough for the accuracy, at a fraction of ACF's cost");
    }
    // ACF at rho_inf = 1: nothing damps the mesh's highest frequencies, which the step does
    // not resolve (h w_max >> 1); on the co-rotated elements they can stall Newton
    // (docs/benchmarks.md "Where each method fails").
    if (bp.model == BodyModel::Acf) {
      const double w_max =
          highest_frequency(acf_mesh ? *acf_mesh : mesh, c.scene.bodies[cd.body].material);
      est.highest_frequency = w_max / (2 * kPi);
      if (c.time.rho_inf > 0.99 && c.time.step * w_max > 2)
        bp.warnings.push_back(fmt(
            "ACF at rho_inf = %g: the mesh's highest frequency, %.3g Hz, is not resolved by the "
            "step (h w_max = %.3g > 2) and not damped; Newton may stall on it: rho_inf <= 0.9 "
            "damps it",
            c.time.rho_inf, est.highest_frequency, c.time.step * w_max));
    }
    // Predicted cost of the body in the run.
    if (bp.model == BodyModel::Ffrf)
      bp.predicted_cost_s = est.reduction_s + plan.prerun_s * static_cast<double>(case_steps) /
                                                  static_cast<double>(steps);
    else if (bp.model == BodyModel::Acf)
      bp.predicted_cost_s = static_cast<double>(case_steps) * kAcfIterationsPerStep *
                            (est.acf_dofs ? est.acf_dofs : est.dofs) * kAcfSecondsPerDofIteration /
                            size;
    else
      bp.predicted_cost_s = 0;
  }
  plan.seconds = wall_time() - t_plan;
  return plan;
}

void print_plan(MPI_Comm comm, const Plan &plan) {
  print0(comm, "plan: accuracy %g (relative error of the sensors)\n", plan.accuracy);
  for (const BodyPlan &bp : plan.bodies) {
    std::string what = dynamics::model_name(bp.model);
    if (bp.model == dynamics::BodyModel::Ffrf)
      what +=
          fmt(", %d modes%s", bp.modes, bp.geometric_stiffening ? ", geometric stiffening" : "");
    if (bp.model == dynamics::BodyModel::Acf && bp.mesh_size > 0)
      what += fmt(", mesh size %g m", bp.mesh_size);
    if (bp.given != dynamics::BodyModel::Auto) what += " (given)";
    print0(comm, "plan: body %s (%s): %s; predicted cost %.3g s\n", bp.body.c_str(),
           dynamics::model_name(bp.given), what.c_str(), bp.predicted_cost_s);
    if (bp.given != dynamics::BodyModel::Auto && bp.estimated && bp.recommended != bp.model)
      print0(comm, "      the estimates recommend %s\n", dynamics::model_name(bp.recommended));
    for (const std::string &r : bp.reasons) print0(comm, "      %s\n", r.c_str());
    for (const std::string &w : bp.warnings) print0(comm, "      warning: %s\n", w.c_str());
  }
}

io::Json plan_json(const Plan &plan) {
  io::Json a = io::Json::array();
  for (const BodyPlan &bp : plan.bodies) {
    io::Json j = io::Json::object();
    j["body"] = bp.body;
    j["model"] = dynamics::model_name(bp.model);
    j["given"] = dynamics::model_name(bp.given);
    j["recommended"] = dynamics::model_name(bp.recommended);
    j["modes"] = bp.modes;
    j["geometric_stiffening"] = bp.geometric_stiffening;
    if (bp.mesh_size > 0) j["mesh_size"] = bp.mesh_size;
    io::Json r = io::Json::array();
    for (const auto &s : bp.reasons) r.push_back(s);
    j["reasons"] = r;
    io::Json w = io::Json::array();
    for (const auto &s : bp.warnings) w.push_back(s);
    j["warnings"] = w;
    j["predicted_cost_s"] = bp.predicted_cost_s;
    if (bp.estimated) {
      io::Json e = io::Json::object();
      e["dofs"] = bp.est.dofs;
      if (bp.est.acf_dofs) e["acf_dofs"] = bp.est.acf_dofs;
      e["length_m"] = bp.est.length;
      e["first_frequency_hz"] = bp.est.f1;
      e["spin_rad_s"] = bp.est.spin;
      e["excitation_hz"] = bp.est.f_excitation;
      e["deflection_m"] = bp.est.deflection;
      e["rotation_rad"] = bp.est.rotation;
      e["stress_stiffening"] = bp.est.stress_stiffening;
      e["stress_error"] =
          std::isfinite(bp.est.stress_error) ? io::Json(bp.est.stress_error) : io::Json("infinite");
      e["stress_error_at"] = bp.est.stress_error_at;
      if (bp.est.highest_frequency > 0) e["highest_frequency_hz"] = bp.est.highest_frequency;
      e["rigid_error"] = bp.est.rigid_error;
      e["rigid_error_at"] = bp.est.rigid_error_at;
      e["mode_errors"] = io::Json(bp.est.mode_errors);
      e["reduction_s"] = bp.est.reduction_s;
      io::Json sd = io::Json::object();
      for (const auto &[name, value] : bp.est.sensor_deflection) sd[name] = value;
      e["sensor_deflection_m"] = sd;
      j["estimates"] = e;
    }
    a.push_back(j);
  }
  return a;
}

void apply_plan(dynamics::SceneDescription &scene, const Plan &plan) {
  using dynamics::BodyModel;
  for (std::size_t b = 0; b < scene.bodies.size(); ++b) {
    dynamics::BodyDescription &body = scene.bodies[b];
    if (body.model != BodyModel::Auto) continue;
    const BodyPlan &bp = plan.bodies.at(b);
    body.model = bp.model;
    if (bp.model == BodyModel::Acf && bp.mesh_size > 0) body.mesh.size = bp.mesh_size;
    if (bp.model == BodyModel::Ffrf) {
      body.reduction.modes = bp.modes;
      body.reduction.geometric_stiffening = bp.geometric_stiffening;
      // The chord frame does not take geometric stiffening (case-format "reduction").
      if (!body.reduction.frame_given)
        body.reduction.frame = body.interfaces.size() >= 2 && !bp.geometric_stiffening
                                   ? reduce::FrameCondition::Chord
                                   : reduce::FrameCondition::Clamped;
    }
  }
}

} // namespace flexopt::plan
