/// \file The estimates of make_plan (docs/theory.md section 12.2): the KED response of each
/// candidate body, its measures, the worst instant, the rigid model's error, the modes' errors and
/// the loads' stress stiffening.
#include "flexopt/bodies/quaternion.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/assembly.hpp"
#include "flexopt/reduce/flexible_reduction.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"
#include "plan_detail.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unsupported/Eigen/FFT>

namespace flexopt::plan::detail {

namespace {

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

/// The largest nodal |U z| over all ranks (U: the basis at the owned nodes, node-major).
double max_nodal_norm(const Eigen::MatrixXd &U, const Eigen::VectorXd &z, MPI_Comm comm) {
  double m = U.rows() ? (U * z).reshaped(3, U.rows() / 3).colwise().norm().maxCoeff() : 0;
  MPI_Allreduce(MPI_IN_PLACE, &m, 1, MPI_DOUBLE, MPI_MAX, comm);
  return m;
}

/// Where the deflection of a body is measured (section 12.2, "Scales"): its sensors, and its
/// interfaces against the smallest scale of the other bodies' sensors; each sensor's KED
/// deflection into est.sensor_deflection.
std::vector<Measure> measure_points(const PlanSettings &c, const dynamics::Scene &scene,
                                    const PreRun &run, const Candidate &cd,
                                    const Eigen::MatrixXd &Z, Estimates &est) {
  const reduce::FlexibleReduction &red = *scene.bodies[cd.body].reduction;
  // Where the deflection is measured.
  // A sensor that moves by less than 1e-9 of the body's extent over the pre-run (a scene at
  // rest) has no scale to measure against.
  const double tiny = 1e-9 * est.length;
  // The smallest position scale among the scene's sensors (the propagation of a body's
  // interface motion to the other bodies' sensors).
  double other_scale = 0;
  bool other_sensors = false;
  for (std::size_t i = 0; i < run.track_of.size(); ++i)
    if (scene.sensors[run.track_of[i]].body != cd.mech && run.scale[i] > tiny) {
      other_scale = other_sensors ? std::min(other_scale, run.scale[i]) : run.scale[i];
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
      for (std::size_t j = 0; j < run.track_of.size(); ++j)
        if (run.track_of[j] == i) m.scale = run.scale[j];
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
  return measures;
}

/// The worst instant (section 12.2): the sample of the largest strain energy; the largest nodal
/// deflection and elastic rotation there into est. Collective.
Eigen::Index worst_instant(MPI_Comm comm, const dynamics::Scene &scene, const Candidate &cd,
                           const Eigen::MatrixXd &Z, Estimates &est) {
  const reduce::FlexibleReduction &red = *scene.bodies[cd.body].reduction;
  const mesh::DistributedMesh &mesh = scene.meshes[cd.body];
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
  return worst;
}

/// The rigid model's error (section 12.2, rule 1 of section 12.3): the whole KED deflection,
/// relative to the measures' scales (or the largest nodal deflection to the body's size); true if
/// an elastic_displacement sensor measures the body.
bool rigid_error(const std::vector<Measure> &measures, Estimates &est) {
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
  return elastic_sensor;
}

/// How the case starts the body (section 12.2, the stress estimate; section 12.3, ACF's mesh).
Start case_start(const dynamics::InitialPlacement &init) {
  // The estimates of what a model changes in the motion (the loads' stress, ACF's mesh) start
  // as the case does: at rest and undeformed unless the case gives the body an initial elastic
  // state (then in its quasi-static state, as the modes' test): the ringing of a body released
  // undeformed under load is physical, and its phase is what a stiffness change shifts.
  auto none = [](const std::array<std::string, 3> &f) {
    return f[0].empty() && f[1].empty() && f[2].empty();
  };
  return none(init.elastic_displacement) && none(init.elastic_velocity) ? Start::Rest
                                                                        : Start::QuasiStatic;
}

/// FFRF with j fixed-interface modes against the plan's model (section 12.3, rule 4): the
/// relative errors into est.mode_errors; returns the fewest modes within eps / 2.
int mode_errors(const BodyKed &ked, double eps, Estimates &est) {
  const reduce::FlexibleReduction &red = *ked.red;
  const Candidate &cd = *ked.cd;
  // FFRF with j fixed-interface modes against the plan's model.
  const int s0 = ked.s0, fixed = ked.fixed;
  int chosen = -1;
  for (int j = 0; j <= fixed; ++j) {
    if (s0 + j == 0) {
      est.mode_errors.push_back(est.rigid_error);
      continue;
    }
    double e = 0;
    if (j < fixed) {
      const ModalModel sub = modal_model(red.K, red.M, red.craig_bampton, s0 + j);
      e = ked.measures.error(ked_response(sub, cd.Q, ked.h) - ked.Z, nullptr);
    }
    est.mode_errors.push_back(e);
    if (chosen < 0 && e <= 0.5 * eps) chosen = j;
  }
  if (chosen < 0) chosen = fixed;
  return chosen;
}

/// The loads' stress of one body compressed to its leading directions (section 12.2): the
/// coefficients c_i(t) (rows: samples) and the reduced geometric stiffness G(d_i) of each.
struct StressHistory {
  Eigen::VectorXd root;           ///< the reduction's frequencies w_k [rad/s]
  Eigen::MatrixXd coef;           ///< c_i(t_n)
  std::vector<Eigen::MatrixXd> G; ///< G(d_i)
  int r = 0;                      ///< the directions kept
};

/// The history of the stress FFRF leaves out (section 12.2): zeta_sigma = K_r^-1 (Q - F_c),
/// F_c the centrifugal load stiffened FFRF takes in, its leading directions (SVD in the energy
/// norm) and their reduced geometric stiffness. Collective.
StressHistory stress_history(const PlanSettings &c, const BodyKed &ked, const BodyPlan &bp) {
  const reduce::FlexibleReduction &red = *ked.red;
  const Candidate &cd = *ked.cd;
  const mesh::DistributedMesh &mesh = *ked.mesh;
  StressHistory s;
  const Eigen::VectorXd w2 = red.eigenvalues.head(cd.n);
  s.root = w2.cwiseSqrt();
  const Eigen::VectorXd &root = s.root;
  Eigen::MatrixXd F = cd.Q;
  if (bp.geometric_stiffening)
    for (Eigen::Index t = 0; t < F.rows(); ++t) {
      const Eigen::Vector3d w = cd.omega.row(t).transpose();
      const Eigen::Matrix3d A = w.squaredNorm() * Eigen::Matrix3d::Identity() - w * w.transpose();
      for (int k = 0; k < cd.n; ++k)
        F(t, k) -= A.cwiseProduct(red.invariants.S1[static_cast<std::size_t>(k)]).sum();
    }
  // zeta_sigma K_r^1/2 = F K_r^-1/2 (rows: samples), in the energy norm.
  const Eigen::BDCSVD<Eigen::MatrixXd> svd(F * root.cwiseInverse().asDiagonal(),
                                           Eigen::ComputeThinU | Eigen::ComputeThinV);
  const Eigen::VectorXd &sv = svd.singularValues();
  int &r = s.r;
  while (r < std::min<Eigen::Index>(6, sv.size()) && sv(r) > 0 && sv(r) >= 1e-3 * sv(0)) ++r;
  Eigen::MatrixXd &coef = s.coef;
  coef.resize(F.rows(), r);
  std::vector<Vec> dirs;
  for (int i = 0; i < r; ++i) {
    coef.col(i) = sv(i) * svd.matrixU().col(i);
    dirs.push_back(reduce::basis_combination(red.basis, svd.matrixV().col(i).cwiseQuotient(root)));
  }
  const fem::IsotropicMaterial &mat = c.scene.bodies[cd.body].material;
  s.G = r ? reduce::reduced_geometric_stiffness(
                mesh, fem::IsotropicMaterial{mat.E, mat.nu, mat.density}, red.basis, dirs, {},
                "plan: the loads' stress stiffening")
          : std::vector<Eigen::MatrixXd>{};
  for (Vec &v : dirs) FX_PETSC(VecDestroy(&v));
  return s;
}

/// mu_sigma (section 12.2, reported) into est: the largest relative stiffness change the loads'
/// stress makes, over at most ~250 evenly spaced samples and the one of the largest coefficients.
void stress_stiffening(const StressHistory &s, int n, Estimates &est) {
  const Eigen::MatrixXd &coef = s.coef;
  const std::vector<Eigen::MatrixXd> &G = s.G;
  const int r = s.r;
  // mu_sigma (reported): at most ~250 samples, evenly spaced, and the one of the largest
  // coefficients.
  const Eigen::VectorXd W = s.root.cwiseInverse();
  const Eigen::Index samples = coef.rows(), stride = std::max<Eigen::Index>(1, samples / 250);
  Eigen::Index peak = 0;
  if (r > 0) coef.rowwise().norm().maxCoeff(&peak);
  for (Eigen::Index t = 0; t < samples && r > 0; ++t) {
    if (t % stride != 0 && t != peak) continue;
    Eigen::MatrixXd Gt = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i < r; ++i) Gt += coef(t, i) * G[static_cast<std::size_t>(i)];
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(W.asDiagonal() * Gt * W.asDiagonal(),
                                                             Eigen::EigenvaluesOnly);
    est.stress_stiffening =
        std::max(est.stress_stiffening, eig.eigenvalues().cwiseAbs().maxCoeff());
  }
}

/// e_sigma (section 12.2) on the FFRF model rule 4 picks: what G_sigma(t) changes in the
/// measures' KED response; infinite where the stiffness drops to zero or below.
void stress_error(const BodyKed &ked, const StressHistory &s, Estimates &est) {
  const reduce::FlexibleReduction &red = *ked.red;
  const Candidate &cd = *ked.cd;
  // e_sigma on the FFRF model rule 4 picks (the static modes and the chosen fixed-interface
  // modes, at least one coordinate): its stiffness with and without G_sigma.
  const ModalModel sub = modal_model(red.K, red.M, red.craig_bampton,
                                     std::min(cd.n, std::max(1, ked.s0 + ked.chosen)));
  std::vector<Eigen::MatrixXd> Gs;
  for (const Eigen::MatrixXd &Gi : s.G) Gs.push_back(sub.E.transpose() * Gi * sub.E);
  const Eigen::MatrixXd Qs = cd.Q * sub.E;
  double lowest = 0;
  const Eigen::MatrixXd D = (ked_response_varying(Eigen::MatrixXd(sub.w2.asDiagonal()), Gs, s.coef,
                                                  Qs, ked.h, ked.start, &lowest) -
                             modal_response(sub.w2, Qs, ked.h, ked.start)) *
                            sub.E.transpose();
  est.stress_error_at = est.rigid_error_at;
  est.stress_error = lowest > 0 ? ked.measures.error(D, &est.stress_error_at)
                                : std::numeric_limits<double>::infinity();
}

} // namespace

// The relative error of the measures that a change D of the KED response (rows: samples)
// makes: the largest over the measures, or the nodes at the worst instant.
double Measures::error(const Eigen::MatrixXd &D, std::string *at) const {
  if (list.empty()) return max_nodal_norm(*owned_modes, D.row(worst).transpose(), comm) / length;
  double e = 0;
  for (const Measure &m : list) {
    const double em = max_norm(m.S, D) / m.scale;
    if (em > e) {
      e = em;
      if (at) *at = m.name;
    }
  }
  return e;
}

BodyKed estimate_body(MPI_Comm comm, const PlanSettings &c, const dynamics::Scene &scene,
                      const PreRun &run, const Candidate &cd, BodyPlan &bp) {
  const double eps = c.accuracy;
  const double h = run.h;
  Estimates &est = bp.est;
  const dynamics::SceneBody &sb = scene.bodies[cd.body];
  const reduce::FlexibleReduction &red = *sb.reduction;
  const mesh::DistributedMesh &mesh = scene.meshes[cd.body];
  BodyKed ked;
  ked.cd = &cd;
  ked.red = &red;
  ked.mesh = &mesh;
  ked.h = h;
  est.dofs = static_cast<int>(3 * mesh.global_nodes);
  est.length = body_extent(mesh);
  est.reduction_s = scene.reduction_seconds[cd.body];
  est.spin = cd.spin;
  ked.w1 = std::sqrt(red.eigenvalues(0));
  est.f1 = ked.w1 / (2 * kPi);

  // The KED response of the full plan model and of the sub-models.
  ked.full = modal_model(red.K, red.M, Eigen::MatrixXd::Identity(cd.n, cd.n), cd.n);
  ked.Z = ked_response(ked.full, cd.Q, h);
  // Excitation: the spectrum of the quasi-static modal response Q_k / w_k^2.
  {
    const Eigen::MatrixXd Y = (cd.Q * ked.full.E) * ked.full.w2.cwiseInverse().asDiagonal();
    est.f_excitation = energy_frequency(Y, h, eps * eps);
    est.quasi_static_error = quasi_static_error(ked.full, red.M, ked.Z, cd.Q);
  }

  ked.measures.list = measure_points(c, scene, run, cd, ked.Z, est);
  ked.measures.owned_modes = &scene.owned_modes[cd.body];
  ked.measures.length = est.length;
  ked.measures.comm = comm;
  ked.measures.worst = worst_instant(comm, scene, cd, ked.Z, est);
  ked.elastic_sensor = rigid_error(ked.measures.list, est);
  ked.start = case_start(c.scene.bodies[cd.body].initial);

  ked.s0 = red.static_modes;
  ked.fixed = red.fixed_modes;
  ked.chosen = mode_errors(ked, eps, est);

  // Geometric stiffening (rule 4) decides which part of the loads' stress FFRF takes in.
  ked.spin_ratio = ked.w1 > 0 ? est.spin / ked.w1 : 0;
  bp.geometric_stiffening = ked.spin_ratio * ked.spin_ratio > eps;

  // The loads' stress stiffening (section 12.2): the stress of the quasi-static deformation
  // zeta_sigma = K_r^-1 (Q - F_c) that FFRF leaves out (F_c: the centrifugal load about the frame
  // origin, taken in by stiffened FFRF), compressed to its leading directions d_i, its reduced
  // geometric stiffness G_sigma(t) = sum_i c_i(t) G(d_i), the largest relative stiffness change
  // mu_sigma, and what it changes in the measures: the KED response with K_r + G_sigma(t)
  // against K_r's.
  const StressHistory stress = stress_history(c, ked, bp);
  stress_stiffening(stress, cd.n, est);
  stress_error(ked, stress, est);
  return ked;
}

} // namespace flexopt::plan::detail
