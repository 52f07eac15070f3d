#include "flexopt/dynamics/integrator.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/fem/corotated.hpp"
#include "flexopt/reduce/stress_shapes.hpp"

#include <cmath>
#include <petscsys.h>

namespace flexopt::dynamics {

namespace {

/// Current world coordinates of the owned nodes of case body b (a rigid or FFRF body of the
/// mechanism) and, for a flexible body, their elastic displacement Psi zeta (frame axes) into
/// `elastic`.
std::vector<double> body_positions(const Scene &scene, std::size_t b, const Vector &q,
                                   std::vector<double> &elastic) {
  const mesh::DistributedMesh &m = scene.meshes[b];
  const Mechanism &mech = scene.mechanism;
  const int mb = scene.bodies[b].mechanism;
  const int o = mech.offset(mb), ne = mech.size(mb) - 7;
  const bodies::Vec3 r = q.segment<3>(o),
                     origin = mech.bodies[static_cast<std::size_t>(mb)]->origin();
  const bodies::Mat3 A = bodies::rotation(q.segment<4>(o + 3));
  const auto nodes = static_cast<std::size_t>(m.owned_nodes);
  std::vector<double> x(3 * nodes);
  elastic.assign(ne > 0 ? 3 * nodes : 0, 0.0);
  if (ne > 0)
    Eigen::Map<Eigen::VectorXd>(elastic.data(), static_cast<Eigen::Index>(3 * nodes)) =
        scene.owned_modes[b] * q.segment(o + 7, ne);
  for (std::size_t i = 0; i < nodes; ++i) {
    bodies::Vec3 X(m.coordinates[3 * i], m.coordinates[3 * i + 1], m.coordinates[3 * i + 2]);
    X -= origin;
    if (ne > 0) X += bodies::Vec3(elastic[3 * i], elastic[3 * i + 1], elastic[3 * i + 2]);
    const bodies::Vec3 p = r + A * X;
    for (std::size_t k = 0; k < 3; ++k) x[3 * i + k] = p(static_cast<Eigen::Index>(k));
  }
  return x;
}

} // namespace

IntegratorSettings IntegratorSettings::from(const TimeSettings &time) {
  IntegratorSettings s;
  s.alpha = AlphaParameters::from_rho_inf(time.rho_inf);
  s.newton.reuse_contraction = time.newton_reuse;
  PetscBool turned = PETSC_TRUE;
  FX_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fx_kept_turned", &turned, nullptr));
  s.newton.corotate_kept = turned == PETSC_TRUE;
  s.step = time.step;
  s.steps = std::llround(time.end / time.step);
  return s;
}

Integrator::Integrator(const Scene &scene, const IntegratorSettings &settings)
    : scene_(scene), settings_(settings) {
  if (scene.acf.empty())
    dense_ = std::make_unique<GeneralizedAlpha>(scene.mechanism, settings.alpha, settings.newton);
  else
    dist_ = std::make_unique<DistributedAlpha>(acf_body_list(scene), &scene.mechanism,
                                               scene.acf_interfaces, scene.mechanism.gravity,
                                               settings.alpha, settings.newton);
}

Integrator::~Integrator() = default;

const GeneralizedAlpha &Integrator::dense() const {
  if (!dense_) throw Error("Integrator: the scene runs on the distributed backend", true);
  return *dense_;
}

const DistributedAlpha &Integrator::dist() const {
  if (!dist_) throw Error("Integrator: the scene runs on the dense backend", true);
  return *dist_;
}

void Integrator::start(StartReport *report) {
  if (dense_) {
    state_.state = dense_->initial_state(scene_.q0, scene_.v0, 0.0, report);
    small_ = state_.state;
  } else {
    dist_state_.state = acf_initial_state(scene_, *dist_, report);
    small_ = dist_->small_state(dist_state_.state);
  }
}

void Integrator::run(const StepObserver &observer) {
  const StepInfo none;
  observer(StepView{0, 0.0, none, dense_ ? &state_.state : nullptr,
                    dist_ ? &dist_state_.state : nullptr});
  const double h = settings_.step;
  if (dense_) {
    run_steps(*dense_, settings_.steps, h, state_, nullptr, [&](long long j, const StepInfo &info) {
      small_ = state_.state;
      observer(StepView{j, state_.state.t, info, &state_.state, nullptr});
    });
  } else {
    run_steps(*dist_, settings_.steps, h, dist_state_, nullptr,
              [&](long long j, const StepInfo &info) {
                small_ = dist_->small_state(dist_state_.state);
                observer(StepView{j, dist_state_.state.t, info, nullptr, &dist_state_.state});
              });
  }
}

void Integrator::set_state(const State *dense, const DistState *dist, double t) {
  if (dense_) {
    state_.state = *dense;
    state_.state.t = t;
    small_ = state_.state;
  } else {
    dist_state_.state = *dist;
    dist_state_.state.t = t;
    small_ = dist_->small_state(dist_state_.state);
  }
}

double Integrator::tie_violation() const {
  return dist_ ? dist_->tie_violation(dist_state_.state) : 0.0;
}

double Integrator::energy() const {
  return dist_ ? dist_->energy(dist_state_.state)
               : scene_.mechanism.energy(state_.state.q, state_.state.v);
}

Vec3 Integrator::sensor(const BoundSensor &s) const {
  if (dist_ && s.acf_body >= 0)
    return acf_sensor_value(scene_, *dist_, s, dist_state_.state, small_);
  return sensor_value(scene_, s, small_);
}

std::vector<double> Integrator::positions(std::size_t b, std::vector<double> &elastic) const {
  const SceneBody &sb = scene_.bodies[b];
  if (sb.acf < 0) return body_positions(scene_, b, small_.q, elastic);
  std::vector<double> x =
      dist_->owned_positions(dist_state_.state, static_cast<std::size_t>(sb.acf));
  elastic.clear();
  if (sb.nodes.empty()) return x;
  // The elastic displacement in the body's frame (docs/theory.md section 8.4).
  const InterfaceFrame frame = acf_frame(scene_, sb, small_);
  const mesh::DistributedMesh &m = scene_.meshes[b];
  elastic.resize(x.size());
  for (std::size_t i = 0; i < x.size() / 3; ++i) {
    const Vec3 e = frame.elastic(Vec3(&x[3 * i]), Vec3(&m.coordinates[3 * i]));
    for (int k = 0; k < 3; ++k) elastic[3 * i + static_cast<std::size_t>(k)] = e(k);
  }
  return x;
}

std::vector<double> Integrator::von_mises(std::size_t b,
                                          const fem::IsotropicMaterial &material) const {
  const SceneBody &sb = scene_.bodies[b];
  const mesh::DistributedMesh &m = scene_.meshes[b];
  const auto ne = static_cast<std::size_t>(m.local_elements());
  std::vector<double> v;
  if (sb.acf >= 0) { // the co-rotated stress (docs/theory.md 8.3)
    const auto a = static_cast<std::size_t>(sb.acf);
    const bodies::AcfBody &body = *scene_.acf[a];
    std::vector<double> u;
    dist_->local_values(dist_state_.state.q, a, u);
    for (std::size_t k = 0; k < u.size(); ++k) u[k] -= m.coordinates[k];
    const Eigen::Vector3d xi = fem::reference_centroid(m.type);
    v.resize(ne);
    for (std::size_t e = 0; e < ne; ++e) {
      const auto pe = static_cast<PetscInt>(e);
      const fem::StressMatrix S =
          fem::element_stress_matrix(m.type, m.element_coordinates(pe), body.material(), xi);
      v[e] = fem::corotated_von_mises(body.elements()[e], S, body.positions(pe, u.data()), nullptr);
    }
    return v;
  }
  if (!sb.reduction) return v;
  // An FFRF body: sigma_e = T_e zeta (docs/theory.md 10.3), T made again when the body's
  // reduction changed (a new design).
  shapes_.resize(scene_.bodies.size());
  StressShapes &sh = shapes_[b];
  if (sh.reduction.lock() != sb.reduction) {
    std::vector<PetscInt> all(ne);
    for (std::size_t e = 0; e < ne; ++e) all[e] = static_cast<PetscInt>(e);
    sh.T = reduce::stress_shapes(m, material, sb.reduction->basis, all);
    sh.reduction = sb.reduction;
  }
  const Mechanism &mech = scene_.mechanism;
  const int mb = sb.mechanism, o = mech.offset(mb) + 7, nz = mech.size(mb) - 7;
  const Eigen::VectorXd sigma = sh.T * small_.q.segment(o, nz);
  v.resize(ne);
  for (std::size_t e = 0; e < ne; ++e)
    v[e] = fem::von_mises(sigma.segment<6>(6 * static_cast<Eigen::Index>(e)));
  return v;
}

} // namespace flexopt::dynamics
