// The design partials of a dynamic design problem (docs/theory.md sections 9.1 and 10): the
// rigid design body's mass parameters, the FFRF design body's packed model cotangent and its
// pull-back through the reduction's adjoint, per element.
#include "flexopt/adjoint/dynamic_problem.hpp"
#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/fem/probe.hpp"
#include "flexopt/reduce/field_projection.hpp"

namespace flexopt::adjoint {

namespace {

/// The FfrfModel cotangent of an n-coordinate body packed into a vector (mass, d0, D, S0, S1,
/// S2, stiffness, damping, then the 6 geometric matrices if `stiffening`) and back.
int packed_size(int n, bool stiffening) {
  return 1 + 3 + 3 * n + 9 + 9 * n + 9 * n * n + 2 * n * n + (stiffening ? 6 * n * n : 0);
}

template <class F> void visit_packed(int n, bool stiffening, bodies::FfrfModel &m, F &&f) {
  auto &inv = m.invariants;
  f(&inv.mass, 1);
  f(inv.d0.data(), 3);
  f(inv.D.data(), 3 * n);
  f(inv.S0.data(), 9);
  for (auto &S : inv.S1) f(S.data(), 9);
  for (auto &row : inv.S2)
    for (auto &S : row) f(S.data(), 9);
  f(m.stiffness.data(), n * n);
  f(m.damping.data(), n * n);
  if (stiffening)
    for (auto &G : m.geometric) f(G.data(), n * n);
}

Vector pack(bodies::FfrfModel &m, int n, bool stiffening) {
  Vector out(packed_size(n, stiffening));
  Eigen::Index at = 0;
  visit_packed(n, stiffening, m, [&](double *x, int len) {
    out.segment(at, len) = Eigen::Map<const Vector>(x, len);
    at += len;
  });
  return out;
}

bodies::FfrfModel unpack(const Vector &v, int n, bool stiffening) {
  bodies::FfrfModel m;
  m.invariants.D.setZero(3, n);
  m.invariants.S1.assign(static_cast<std::size_t>(n), bodies::Mat3::Zero());
  m.invariants.S2.assign(
      static_cast<std::size_t>(n),
      std::vector<bodies::Mat3>(static_cast<std::size_t>(n), bodies::Mat3::Zero()));
  m.stiffness.setZero(n, n);
  m.damping.setZero(n, n);
  if (stiffening) m.geometric.assign(6, Matrix::Zero(n, n));
  Eigen::Index at = 0;
  visit_packed(n, stiffening, m, [&](double *x, int len) {
    Eigen::Map<Vector>(x, len) = v.segment(at, len);
    at += len;
  });
  return m;
}

/// c.basis as n zero vectors of the basis's layout (owned: destroyed by the caller), unless it
/// holds them already (a response with several basis cotangents adds them up).
void zero_basis_cotangent(const reduce::FlexibleReduction &r, int n, reduce::ReductionCotangent &c,
                          std::vector<Vec> &owned) {
  if (!c.basis.empty()) return;
  for (int k = 0; k < n; ++k) {
    Vec v;
    FX_PETSC(VecDuplicate(r.basis.front(), &v));
    FX_PETSC(VecZeroEntries(v));
    c.basis.push_back(v);
    owned.push_back(v);
  }
}

} // namespace

void DynamicProblem::record_design_frame(std::size_t i, const Vector &q) {
  if (sensor_design_[i] < 0) return;
  const DesignBody &db = designs_[static_cast<std::size_t>(sensor_design_[i])];
  const dynamics::Mechanism &mech = scene_.mechanism;
  const int od = mech.offset(db.mechanism), nd = mech.size(db.mechanism);
  const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
  ev_.sensor_frames[i].emplace_back(bs.quantity == dynamics::SensorQuantity::ElasticDisplacement
                                        ? bodies::Mat3::Identity()
                                        : bodies::rotation(q.segment<4>(od + 3)),
                                    q.segment(od + 7, nd - 7));
}

int DynamicProblem::design_parameters_of(const DesignBody &db) const {
  if (db.rigid()) return 10;
  const auto &body = dynamic_cast<const bodies::FfrfBody &>(scene_.mechanism.body(db.mechanism));
  return packed_size(body.coordinates() - 7, body.stiffening());
}

int DynamicProblem::design_parameters() const {
  int rows = 0;
  for (const DesignBody &db : designs_) rows += db.rows;
  return rows;
}

Matrix DynamicProblem::design_partials(const Vector &q, const Vector &v, const Vector &a,
                                       bool gravity, const Matrix &W) const {
  // Block by block: each rigid or FFRF design body's parameters enter its own rows of r only
  // (docs/theory.md 9.9).
  const dynamics::Mechanism &mech = scene_.mechanism;
  const Vec3 g = gravity ? mech.gravity : Vec3::Zero();
  Matrix G(design_parameters(), W.cols());
  for (const DesignBody &db : designs_) {
    if (db.acf_model()) continue;
    const int o = mech.offset(db.mechanism);
    if (db.ffrf()) {
      const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(db.mechanism));
      const int nb = body.coordinates(), n = nb - 7;
      for (Eigen::Index c = 0; c < W.cols(); ++c) {
        bodies::FfrfModel bar;
        const Vector mu = W.col(c).segment(o, nb);
        body.model_cotangent(q.segment(o, nb), v.segment(o, nb), a.segment(o, nb), g, mu, bar);
        G.col(c).segment(db.row, db.rows) = pack(bar, n, body.stiffening());
      }
      continue;
    }
    const auto &body = dynamic_cast<const bodies::RigidBody &>(mech.body(db.mechanism));
    const bodies::RigidBody::Vec7 qb = q.segment<7>(o), vb = v.segment<7>(o), ab = a.segment<7>(o);
    const Eigen::Matrix<double, 7, 10> P = body.parameter_jacobian(qb, vb, ab, g);
    G.middleRows(db.row, 10) = P.transpose() * W.middleRows(o, 7);
  }
  return G;
}

bool DynamicProblem::given_fields(const DesignBody &db) const {
  const dynamics::SceneBody &sb = scene_.bodies[static_cast<std::size_t>(db.body)];
  return db.ffrf() && (sb.elastic0.size() > 0 || sb.elastic_rate0.size() > 0);
}

void DynamicProblem::add_element_gradients(const Matrix &G, const StartAdjoint &start) {
  for (DesignBody &db : designs_) {
    if (db.rigid()) add_rigid_element_gradients(db, G.middleRows(db.row, db.rows));
    if (db.ffrf()) add_ffrf_element_gradients(db, G.middleRows(db.row, db.rows), start);
  }
}

void DynamicProblem::add_rigid_element_gradients(DesignBody &db, const Matrix &G) {
  // dPsi/dw_e = G . theta_e (+ m_e for the design body's mass), then dw/d(physical).
  const PetscInt ne = db.field->mesh().local_elements();
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    Vector g = G.col(static_cast<Eigen::Index>(i));
    if (counts_mass(i, db)) g(0) += 1;
    for (PetscInt e = 0; e < ne; ++e)
      db.ev.element_gradient[i][static_cast<std::size_t>(e)] +=
          db.ev.dw[static_cast<std::size_t>(e)] *
          g.dot(db.element_theta[static_cast<std::size_t>(e)]);
  }
}

bool DynamicProblem::add_sensor_cotangent(const DesignBody &db, std::size_t i, int n,
                                          reduce::ReductionCotangent &c,
                                          std::vector<Vec> &owned) const {
  const mesh::DistributedMesh &m = db.field->mesh();
  // The sensor's basis S = Psi(X_s): dPsi/dS = sum_n A_n^T dPsi/dy_n zeta_n^T (minus the
  // value at q0 for a displacement), then Psi-bar_k = N(X_s) S-bar(:, k).
  Matrix Sbar = Matrix::Zero(3, n);
  const auto &frames = ev_.sensor_frames[i];
  Vec3 sum = Vec3::Zero();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    Sbar += frames[k].first.transpose() * ev_.sampled[i].dy[k] * frames[k].second.transpose();
    sum += ev_.sampled[i].dy[k];
  }
  const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
  if (bs.quantity == dynamics::SensorQuantity::Displacement) {
    const int o = scene_.mechanism.offset(db.mechanism);
    Sbar -= bodies::rotation(scene_.q0.segment<4>(o + 3)).transpose() * sum *
            scene_.q0.segment(o + 7, n).transpose();
  }
  if (!Sbar.isZero(0)) {
    for (int k = 0; k < n; ++k) {
      Vec v;
      FX_PETSC(VecDuplicate(db.reduction->basis.front(), &v));
      FX_PETSC(VecZeroEntries(v));
      fem::add_point_functional(m, scene_.sensors[static_cast<std::size_t>(sensor_of_[i])].location,
                                {Sbar(0, k), Sbar(1, k), Sbar(2, k)}, v);
      c.basis.push_back(v);
      owned.push_back(v);
    }
  }
  return !Sbar.isZero(0);
}

void DynamicProblem::add_initial_field_cotangent(const DesignBody &db, std::size_t i, int n,
                                                 const StartAdjoint &start,
                                                 reduce::ReductionCotangent &c,
                                                 std::vector<Vec> &owned,
                                                 std::vector<double> &projection_w) const {
  const mesh::DistributedMesh &m = db.field->mesh();
  const dynamics::BodyDescription &spec = settings_.scene.bodies[static_cast<std::size_t>(db.body)];
  // Initial elastic fields (section 10.2): the start's sensitivities to the placed elastic
  // coordinates and rates (a displacement sensor also measures from the placed position),
  // and the cotangent of the positions' metric on the body's coordinates.
  const auto col = static_cast<Eigen::Index>(i);
  const int o = scene_.mechanism.offset(db.mechanism);
  Vector qbar = start.q.col(col);
  if (sensor_of_[i] >= 0 && sensor_design_[i] == static_cast<int>(db.index)) {
    const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
    if (bs.quantity == dynamics::SensorQuantity::Displacement) {
      Vec3 sum = Vec3::Zero();
      for (const Vec3 &dy : ev_.sampled[i].dy) sum += dy;
      qbar -= sensor_jacobian(scene_, bs, scene_.q0).transpose() * sum;
    }
  }
  const Matrix &W = start.metric[static_cast<std::size_t>(i)];
  const Matrix Wz = W.block(o + 7, o + 7, n, n);
  c.M += 0.5 * (Wz + Wz.transpose());
  const dynamics::SceneBody &dsb = scene_.bodies[static_cast<std::size_t>(db.body)];
  const double density = spec.material.density;
  for (const bool rate : {false, true}) {
    const Vector &zeta = rate ? dsb.elastic_rate0 : dsb.elastic0;
    if (zeta.size() == 0) continue;
    const Vector zbar = (rate ? start.v.col(col) : qbar).segment(o + 7, n);
    zero_basis_cotangent(*db.reduction, n, c, owned);
    reduce::project_field_adjoint(m, density, *db.reduction,
                                  dynamics::initial_elastic_field(spec, rate), zeta, zbar, c.basis,
                                  projection_w);
  }
}

void DynamicProblem::add_ffrf_element_gradients(DesignBody &db, const Matrix &G,
                                                const StartAdjoint &start) {
  const dynamics::BodyDescription &spec = settings_.scene.bodies[static_cast<std::size_t>(db.body)];
  const auto &body = dynamic_cast<const bodies::FfrfBody &>(scene_.mechanism.body(db.mechanism));
  const int n = body.coordinates() - 7;
  const mesh::DistributedMesh &m = db.field->mesh();
  std::vector<reduce::ReductionCotangent> bars;
  std::vector<std::size_t> columns; // the responses that depend on the design body
  std::vector<Vec> owned;
  // The element terms of the initial fields' projections (section 10.2), per response.
  std::vector<std::vector<double>> projection_w(specs_.size());
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    bodies::FfrfModel bar = unpack(G.col(static_cast<Eigen::Index>(i)), n, body.stiffening());
    bool used = !G.col(static_cast<Eigen::Index>(i)).isZero(0);
    if (counts_mass(i, db)) {
      bar.invariants.mass += 1;
      used = true;
    }
    reduce::ReductionCotangent c;
    // C_r = a M_r + b K_r; a strain energy integral's own sum_n w_n 1/2 zeta_n zeta_n^T.
    c.K = bar.stiffness + spec.rayleigh[1] * bar.damping;
    if (db.ev.strain_kbar[i].size() > 0) {
      c.K += db.ev.strain_kbar[i];
      used = true;
    }
    c.M = spec.rayleigh[0] * bar.damping;
    c.invariants = bar.invariants;
    c.geometric = bar.geometric;
    if (sensor_design_[i] == static_cast<int>(db.index) && n > 0 &&
        add_sensor_cotangent(db, i, n, c, owned))
      used = true;
    if (stress_[i] && stress_case_body_[i] == db.body && n > 0 &&
        basis_ == reduce::BasisDerivative::Exact) {
      // The stress shapes' cotangent into the basis vectors' (section 10.3), added to a
      // sensor's if the response has both.
      zero_basis_cotangent(*db.reduction, n, c, owned);
      ffrf_stress(i)->add_basis_cotangent(c.basis);
      used = true;
    }
    if (start.q.size() > 0 && n > 0 && given_fields(db)) {
      add_initial_field_cotangent(db, i, n, start, c, owned, projection_w[i]);
      used = true;
    }
    if (!used) continue;
    bars.push_back(std::move(c));
    columns.push_back(i);
  }
  std::vector<std::vector<double>> s_hat, w_hat;
  const double t0 = wall_time();
  try {
    const reduce::ReductionAdjointStats stats = reduce::reduction_adjoint(
        m, *db.reduction, bars, basis_, s_hat, w_hat, reduce::BasisGauge::FrozenCoordinates);
    db.reduction_cg_iterations = stats.cg_iterations;
  } catch (const Error &) {
    for (Vec &v : owned) VecDestroy(&v);
    throw;
  }
  db.reduction_adjoint_s = wall_time() - t0;
  db.ev.reduction_adjoint_s = db.reduction_adjoint_s;
  for (Vec &v : owned) FX_PETSC(VecDestroy(&v));
  const PetscInt ne = m.local_elements();
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (PetscInt e = 0; e < ne; ++e) {
      const auto k = static_cast<std::size_t>(e);
      db.ev.element_gradient[columns[c]][k] +=
          db.ev.ds[k] * s_hat[c][k] + db.ev.dw[k] * w_hat[c][k];
    }
  for (std::size_t i = 0; i < projection_w.size(); ++i)
    for (std::size_t k = 0; k < projection_w[i].size(); ++k)
      db.ev.element_gradient[i][k] += db.ev.dw[k] * projection_w[i][k];
}

} // namespace flexopt::adjoint
