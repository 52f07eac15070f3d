#include "flexopt/adjoint/dynamic_problem.hpp"

#include "flexopt/core/context.hpp"
#include "flexopt/core/error.hpp"
#include "flexopt/core/expression.hpp"
#include "flexopt/core/log.hpp"
#include "flexopt/dynamics/consistent_start.hpp"
#include "flexopt/fem/probe.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace flexopt::adjoint {

using bodies::Vec3;

namespace {

/// Sum_i lambda_i H_i over the enforced rows (n x n).
Matrix constraint_hessian(const dynamics::Mechanism &mech, const Vector &q, double t,
                          const Vector &lambda) {
  const int n = mech.coordinates();
  Matrix H = Matrix::Zero(n, n);
  mech.add_constraint_hessian(q, t, lambda, H);
  return H;
}

/// Column c: grad_q (w_c . f(q)) for a vector function f that is a polynomial of degree <= 6
/// in each coordinate (the constraint rows and their time derivatives, docs/theory.md section
/// 9.2 item 6): the seven-point central difference, exact for such polynomials, with the steps
/// h_j.
Matrix polynomial_gradient(const std::function<Vector(const Vector &)> &f, const Vector &q,
                           const Vector &h, const Matrix &w) {
  static constexpr double coefficient[3] = {45.0 / 60, -9.0 / 60, 1.0 / 60};
  const auto n = q.size();
  Matrix out = Matrix::Zero(n, w.cols());
  for (Eigen::Index j = 0; j < n; ++j) {
    Vector d = Vector::Zero(w.rows());
    for (int k = 1; k <= 3; ++k) {
      Vector qp = q, qm = q;
      qp(j) += k * h(j);
      qm(j) -= k * h(j);
      d += coefficient[k - 1] * (f(qp) - f(qm));
    }
    out.row(j) = (w.transpose() * d).transpose() / h(j);
  }
  return out;
}

/// grad_q sum_c x_c^T M(q) y_c over the columns of X and Y: sum_c (K(q, 0, y_c) -
/// K(q, 0, 0))^T x_c, K = dr/dq of Mechanism::dynamics (r is linear in its acceleration
/// argument).
Vector mass_gradient(const dynamics::Mechanism &mech, const Vector &q, double t, const Matrix &X,
                     const Matrix &Y) {
  const int n = mech.coordinates();
  Vector r, out = Vector::Zero(n);
  Matrix K0, K;
  mech.dynamics(q, Vector::Zero(n), Vector::Zero(n), t, r, &K0, nullptr, nullptr);
  for (Eigen::Index c = 0; c < X.cols(); ++c) {
    mech.dynamics(q, Vector::Zero(n), Y.col(c), t, r, &K, nullptr, nullptr);
    out += (K - K0).transpose() * X.col(c);
  }
  return out;
}

} // namespace

StartAdjoint initial_state_adjoint(const dynamics::GeneralizedAlpha &ga, const dynamics::State &s0,
                                   const dynamics::StartTrace &trace, const Matrix &gbar,
                                   const ResidualPartials &partials, bool given) {
  const dynamics::Mechanism &mech = ga.mechanism();
  const int n = mech.coordinates(), m = mech.constraints();
  const auto r = gbar.cols();
  const double t0 = s0.t;
  const Vector &q = s0.q;
  StartAdjoint out;
  // Accelerations and multipliers: [M J^T; J 0] [acc; lambda] = [-r(q, v, 0); gamma(q, v)].
  Vector res, phi;
  Matrix K, C, M, J;
  mech.dynamics(q, s0.v, Vector::Zero(n), t0, res, nullptr, &C, &M);
  mech.constraint(q, t0, phi, &J);
  Matrix A = Matrix::Zero(n + m, n + m);
  A.topLeftCorner(n, n) = M;
  A.topRightCorner(n, m) = J.transpose();
  A.bottomLeftCorner(m, n) = J;
  Matrix rhs(n + m, r);
  rhs.topRows(n) = gbar.middleRows(3 * n, n) + gbar.middleRows(2 * n, n); // acc and a = acc
  rhs.bottomRows(m) = gbar.middleRows(4 * n, m);
  const Eigen::PartialPivLU<Matrix> lu(A.transpose());
  const Matrix nu = lu.solve(rhs);
  if (!nu.allFinite()) throw Error("adjoint: the initial acceleration system is singular", true);
  const Matrix nu_acc = nu.topRows(n), nu_lambda = nu.bottomRows(m);
  out.design = partials(q, s0.v, s0.acc, true, -nu_acc);
  // d gamma/dv^T nu_lambda = -2 (sum_i nu_i H_i) v - 2 Phi_qt^T nu_lambda; Phi_qt column by
  // column from the linear map v -> Phi_qt v.
  Matrix Phi_qt(m, n);
  {
    Vector phi_t, phi_tt, phi_qt_v;
    for (int j = 0; j < n; ++j) {
      mech.constraint_time_terms(q, Vector::Unit(n, j), t0, phi_t, phi_tt, phi_qt_v);
      Phi_qt.col(j) = phi_qt_v;
    }
  }
  Matrix gv = gbar.middleRows(n, n) - C.transpose() * nu_acc - 2 * Phi_qt.transpose() * nu_lambda;
  for (Eigen::Index c = 0; c < r; ++c)
    gv.col(c) -= 2 * constraint_hessian(mech, q, t0, nu_lambda.col(c)) * s0.v;

  // The q-dependence of every stage (item 6): the steps of the exact polynomial gradients.
  Matrix gq;
  Vector h;
  auto time_terms = [&](const Vector &x, const Vector &v, int which) {
    Vector phi_t, phi_tt, phi_qt_v;
    mech.constraint_time_terms(x, v, t0, phi_t, phi_tt, phi_qt_v);
    return which == 0 ? phi_t : which == 1 ? phi_tt : phi_qt_v;
  };
  if (given) {
    double L = 1;
    for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b)
      L = std::max(L, q.segment<3>(mech.offset(b)).cwiseAbs().maxCoeff());
    h.resize(n);
    for (int j = 0; j < n; ++j)
      h(j) = 0.1 * L / std::max(m > 0 ? J.col(j).cwiseAbs().maxCoeff() : 0.0, 0.1);
    gq = gbar.topRows(n);
    Matrix Kd;
    mech.dynamics(q, s0.v, s0.acc, t0, res, &Kd, nullptr, nullptr);
    gq -= Kd.transpose() * nu_acc;
    const Matrix Hl = constraint_hessian(mech, q, t0, s0.lambda);
    gq -= Hl * nu_acc;
    for (Eigen::Index c = 0; c < r; ++c)
      gq.col(c) -= constraint_hessian(mech, q, t0, nu_lambda.col(c)) * s0.acc;
    if (m > 0)
      gq -= polynomial_gradient(
          [&](const Vector &x) {
            return Vector(mech.constraint_convective(x, s0.v, t0) + 2 * time_terms(x, s0.v, 2) +
                          time_terms(x, s0.v, 1));
          },
          q, h, nu_lambda);
  }

  // The velocity correction, as the forward start made it (trace): first the rigid-body
  // velocities, v_r = v_given + T y; then, if they could not satisfy the joints, the elastic
  // fallback v_0 = v_r + dv with [M J^T; J 0] [dv; mu] = [0; -(J v_r + Phi_t)] (section 9.2):
  // nu = A^-T [gv; 0], dPsi/dx += -nu_v^T dM dv, and gv_r = gv - J^T nu_lambda.
  const dynamics::VelocityCorrection &vc = trace.rigid;
  // W^T dM(x)/dx a: r(q, 0, a) less r(q, 0, 0), which holds the elastic forces of a deformed
  // FFRF body (K_r zeta) and must not enter.
  auto mass_partials = [&](const Vector &a, const Matrix &W) {
    return Matrix(partials(q, Vector::Zero(n), a, false, W) -
                  partials(q, Vector::Zero(n), Vector::Zero(n), false, W));
  };
  Vector v_r = s0.v;
  if (trace.fallback.size() > 0) {
    v_r -= trace.fallback;
    Matrix rhs_v = Matrix::Zero(n + m, r);
    rhs_v.topRows(n) = gv;
    const Matrix nu_v = lu.solve(rhs_v);
    out.design += mass_partials(trace.fallback, -nu_v.topRows(n));
    if (given) {
      Vector f = Vector::Zero(n + m);
      f.tail(m) = -(J * v_r + time_terms(q, v_r, 0));
      const Vector mu = lu.solve(f).tail(m); // A is symmetric: lu (of A^T) solves it too
      const Matrix Hmu = constraint_hessian(mech, q, t0, mu);
      for (Eigen::Index c = 0; c < r; ++c) {
        const Vector nv = nu_v.col(c).head(n), nm = nu_v.col(c).tail(m);
        gq.col(c) -= mass_gradient(mech, q, t0, nv, trace.fallback) + Hmu * nv +
                     constraint_hessian(mech, q, t0, nm) * s0.v; // dv + v_r = v_0
      }
      if (m > 0)
        gq -= polynomial_gradient([&](const Vector &x) { return time_terms(x, v_r, 0); }, q, h,
                                  nu_v.bottomRows(m));
    }
    gv -= J.transpose() * nu_v.bottomRows(m);
  }
  // The rigid correction v_r = v_given + T y: dy = -Pi dW y, dW = T^T dM T (also for joints that
  // rigid-body velocities cannot satisfy: y is then the least-W-norm solution of the consistent
  // P y = P P^+ b, whose set of least-squares solutions does not depend on W).
  Matrix gvg = gv; // dPsi/dv_given
  if (vc.T.size() > 0) {
    const Matrix U = vc.T * (vc.Pi * (vc.T.transpose() * gv));
    const Vector ay = vc.T * vc.y;
    out.design += mass_partials(ay, -U);
    if (given) {
      // Item 6: the least-W-norm least-squares y = W^-1 P^T S^+ b differentiated at constant
      // rank, S^+ = B^+T B^+, S S^+ = B B^+.
      const auto k = vc.T.cols();
      const Vector v_g = v_r - vc.T * vc.y;
      const Eigen::LLT<Matrix> W(vc.W);
      const Matrix Sp = vc.Bp.transpose() * vc.Bp;
      auto range_complement = [&](const Vector &x) { return Vector(x - vc.B * (vc.Bp * x)); };
      const Vector mu = Sp * vc.b, f = Sp * mu, e = range_complement(vc.b);
      const Matrix WiPt = W.solve(vc.P.transpose());
      for (Eigen::Index c = 0; c < r; ++c) {
        const Vector ybar = vc.T.transpose() * gv.col(c), yhat = W.solve(ybar);
        const Vector tt = vc.P * yhat, a = Sp * tt, g = range_complement(tt);
        const Matrix Sbar = -a * mu.transpose() + (Sp * a) * e.transpose() + g * f.transpose();
        const Matrix Pbar = mu * yhat.transpose() + (Sbar + Sbar.transpose()) * WiPt.transpose();
        Matrix Wbar = -yhat * vc.y.transpose() - WiPt * Sbar * WiPt.transpose();
        for (Eigen::Index i = 0; i < k; ++i) // W is block diagonal (6 x 6 blocks)
          for (Eigen::Index j = 0; j < k; ++j)
            if (i / 6 != j / 6) Wbar(i, j) = 0;
        const Vector &bbar = a;
        Vector g_c = Vector::Zero(n);
        for (Eigen::Index col = 0; col < k; ++col)
          g_c += constraint_hessian(mech, q, t0, Pbar.col(col)) * vc.T.col(col);
        // <Tbar, T(q)>: T's Euler-parameter blocks 1/2 G(p)^T are linear in p.
        const Matrix Tbar = gv.col(c) * vc.y.transpose() + J.transpose() * Pbar +
                            M * vc.T * (Wbar + Wbar.transpose());
        for (int b = 0; b < static_cast<int>(mech.bodies.size()); ++b) {
          const int o = mech.offset(b);
          for (Eigen::Index col = 0; col + 2 < k; col += 6) {
            if (vc.T.block(o + 3, col + 3, 4, 3).isZero(0)) continue;
            for (int j = 0; j < 4; ++j)
              g_c(o + 3 + j) +=
                  (Tbar.block(o + 3, col + 3, 4, 3).array() *
                   (0.5 * bodies::g_matrix(bodies::Vec4::Unit(j)).transpose()).array())
                      .sum();
          }
        }
        g_c += mass_gradient(mech, q, t0, vc.T * Wbar, vc.T);
        g_c -= constraint_hessian(mech, q, t0, bbar) * v_g;
        gq.col(c) += g_c;
        gvg.col(c) -= J.transpose() * bbar;
      }
      if (m > 0) {
        Matrix B_bar(m, r);
        for (Eigen::Index c = 0; c < r; ++c)
          B_bar.col(c) = Sp * (vc.P * W.solve(Vector(vc.T.transpose() * gv.col(c))));
        gq -= polynomial_gradient([&](const Vector &x) { return time_terms(x, v_g, 0); }, q, h,
                                  B_bar);
      }
    }
  }
  if (!given) return out;
  // The positions: the closest point q0 of the joints' manifold to the placed coordinates,
  // F = [W (q0 - q_g) + J^T mu; Phi(q0)] = 0 with W = I: [I + H(mu), J^T; J, 0] [a; b] =
  // [gq; 0] gives dPsi/dq_g = a and the metric's cotangent -a (q0 - q_g)^T (item 6). Also when
  // the placement satisfied the joints (mu = 0): skipping the correction is the same map.
  if (!trace.closest)
    throw Error("adjoint: the start's position correction did not converge to the closest "
                "point of the joints to the placed coordinates, whose derivative the adjoint "
                "takes (the initial placement is far from an assembled configuration)",
                true);
  out.metric.assign(static_cast<std::size_t>(r), Matrix::Zero(n, n));
  if (m > 0) {
    Matrix Ak = Matrix::Zero(n + m, n + m);
    Ak.topLeftCorner(n, n) = Matrix::Identity(n, n);
    const Vector mu = trace.multipliers.size() == m ? trace.multipliers : Vector::Zero(m);
    mech.add_constraint_hessian(q, t0, mu, Ak);
    Ak.topRightCorner(n, m) = J.transpose();
    Ak.bottomLeftCorner(m, n) = J;
    Matrix rhs_q = Matrix::Zero(n + m, r);
    rhs_q.topRows(n) = gq;
    const Matrix ab = Ak.transpose().partialPivLu().solve(rhs_q);
    gq = ab.topRows(n);
    const Vector dq = q - (trace.given.size() == n ? trace.given : q);
    for (Eigen::Index c = 0; c < r; ++c)
      out.metric[static_cast<std::size_t>(c)] = -gq.col(c) * dq.transpose();
  }
  out.q = gq;
  out.v = gvg;
  return out;
}

double trapezoid_weight(std::size_t n, std::size_t N) {
  if (N == 0) return 1.0;
  return (n == 0 || n == N ? 0.5 : 1.0) / static_cast<double>(N);
}

SampledResponse sampled_response(const optimize::ResponseSettings &r, const std::vector<Vec3> &y,
                                 double h) {
  SampledResponse out;
  const std::size_t N = y.size() - 1;
  out.dy.assign(y.size(), Vec3::Zero());
  auto weight = [&](std::size_t n) { return trapezoid_weight(n, N); };
  const int K = r.component;
  if (r.type == optimize::ResponseType::TrackingError) {
    std::array<Expression, 3> target;
    for (int k = 0; k < 3; ++k)
      target[static_cast<std::size_t>(k)] = Expression(r.target[static_cast<std::size_t>(k)]);
    for (std::size_t n = 0; n <= N; ++n) {
      const double t = static_cast<double>(n) * h;
      Vec3 e;
      for (int k = 0; k < 3; ++k) {
        const double yt = target[static_cast<std::size_t>(k)](t);
        if (!std::isfinite(yt)) {
          std::ostringstream msg;
          msg << r.where.str() << ": tracking_error: target[" << k << "] = '"
              << r.target[static_cast<std::size_t>(k)] << "' is not finite at t = " << t << " s";
          throw Error(msg.str(), true);
        }
        e(k) = y[n](k) - yt;
      }
      out.value += weight(n) * e.squaredNorm();
      out.dy[n] = 2 * weight(n) * e;
    }
    return out;
  }
  // type sensor
  if (r.measure == optimize::SensorMeasure::Final) {
    out.value = y[N](K);
    out.dy[N](K) = 1;
  } else if (r.measure == optimize::SensorMeasure::MeanSquare) {
    for (std::size_t n = 0; n <= N; ++n) {
      out.value += weight(n) * y[n](K) * y[n](K);
      out.dy[n](K) = 2 * weight(n) * y[n](K);
    }
  } else { // ks_max
    double Y = -std::numeric_limits<double>::infinity();
    for (const Vec3 &v : y) Y = std::max(Y, v(K));
    double sum = 0;
    std::vector<double> e(N + 1);
    for (std::size_t n = 0; n <= N; ++n) {
      e[n] = weight(n) * std::exp(r.ks * (y[n](K) - Y));
      sum += e[n];
    }
    out.value = Y + std::log(sum) / r.ks;
    for (std::size_t n = 0; n <= N; ++n) out.dy[n](K) = e[n] / sum;
  }
  return out;
}

/// dy/dq of a sensor of a rigid or FFRF body at q (3 x n, the body's columns only).
Matrix sensor_jacobian(const dynamics::Scene &scene, const dynamics::BoundSensor &s,
                       const Vector &q) {
  const dynamics::Mechanism &mech = scene.mechanism;
  const int o = mech.offset(s.body), nb = mech.size(s.body);
  Matrix D = Matrix::Zero(3, mech.coordinates());
  if (s.quantity == dynamics::SensorQuantity::ElasticDisplacement) {
    if (nb > 7) D.block(0, o + 7, 3, nb - 7) = s.S;
    return D;
  }
  D.block(0, o, 3, nb) = joints::anchor_jacobian(q.segment(o, nb), s.s, s.S);
  return D;
}

namespace {

/// A flexible design body's interfaces are tied rigidly by the joints: a design region that
/// touches one is refused (`refuse`, optimize) or warned about (the derivatives of such a
/// region are still right, and check-gradient and simulate take it).
void check_interfaces(const optimize::DesignField &f, const dynamics::BodyDescription &body,
                      const optimize::DesignSettings &d, bool refuse) {
  const optimize::DesignField::SurfaceContact c = f.touched_surface(body.interfaces);
  if (c.elements == 0) return;
  const std::string what =
      d.where.str() + ": design.region '" + d.region + "' of body '" + d.body +
      "' touches its interface '" + c.surface + "' (" + std::to_string(c.elements) +
      " design elements have nodes on it, e.g. Gmsh element " + std::to_string(c.tag) + ")";
  if (refuse)
    throw Error(what + ": a joint ties the interface rigidly, so the material around it must stay "
                       "solid for the design to hold the joint. Keep the interface out of the "
                       "design region: give the material around it (a boss around a pin) its own "
                       "physical volume",
                true);
  print0(f.mesh().comm,
         "design: warning: %s; optimize refuses such a region (a void there would cut the joint "
         "off)\n",
         what.c_str());
}

/// A mass bound on the design body that even an empty design region exceeds cannot hold: it is
/// refused before any computation, with the mass of the material outside the region.
void check_mass_bounds(const optimize::DesignField &f, const DynamicSettings &c) {
  const optimize::DesignSettings &d = c.design;
  const double density = c.scene.body(d.body).material.density;
  const std::vector<double> &volume = f.element_volumes();
  double mass[2] = {0, 0}; // outside the region, inside it
  for (PetscInt e = 0; e < f.mesh().local_elements(); ++e)
    mass[f.is_design(e) ? 1 : 0] += density * volume[static_cast<std::size_t>(e)];
  MPI_Allreduce(MPI_IN_PLACE, mass, 2, MPI_DOUBLE, MPI_SUM, f.mesh().comm);
  for (const optimize::ResponseSettings &r : c.constraints)
    if (r.type == optimize::ResponseType::Mass && r.body == d.body && r.max <= mass[0]) {
      std::ostringstream msg;
      msg << r.where.str() << ": constraint mass of body '" << d.body << "' <= " << r.max
          << " kg cannot hold: the material outside design.region '" << d.region
          << "' alone weighs " << mass[0] << " kg (the solid body " << mass[0] + mass[1]
          << " kg). Raise the bound or enlarge the design region";
      throw Error(msg.str(), true);
    }
}

} // namespace

std::unique_ptr<DynamicProblem> DynamicProblem::create(MPI_Comm comm, const DynamicSettings &c,
                                                       const std::string &scratch,
                                                       bool refuse_interfaces) {
  const optimize::DesignSettings &d = c.design;
  const dynamics::BodyDescription &body = c.scene.body(d.body);
  using dynamics::BodyModel;
  const BodyModel model = dynamics::simulated_model(body.model);
  if (model == BodyModel::Ffrf)
    // What the FFRF design body's adjoint does not differentiate yet: say so before computing.
    for (const dynamics::BodyDescription &b : c.scene.bodies)
      if (dynamics::simulated_model(b.model) == BodyModel::Acf)
        throw Error(d.where.str() + ": design.body '" + d.body +
                        "' is an FFRF body in a scene with ACF bodies (body '" + b.name +
                        "'), whose design sensitivities are not built yet (FFRF design bodies: "
                        "scenes of rigid and FFRF bodies)",
                    true);
  std::unique_ptr<DynamicProblem> p(new DynamicProblem());
  p->settings_ = c;
  p->scratch_ = scratch;
  // An FFRF design body is reduced once, with its first design (the reduction is reused by
  // the first evaluation at that design).
  reduce::ElementFactors first;
  // The design field is made on the design body's mesh as soon as it is meshed (the scene keeps
  // its meshes at fixed addresses) and kept: its filter is built once.
  std::unique_ptr<optimize::DesignField> field;
  const dynamics::InitialDesign initial{d.body, [&](const mesh::DistributedMesh &m) {
                                          field = std::make_unique<optimize::DesignField>(m, d);
                                          optimize::DesignField &f = *field;
                                          check_interfaces(f, body, d, refuse_interfaces);
                                          check_mass_bounds(f, c);
                                          Vec x = f.create_design_vector();
                                          f.initial_design(x);
                                          f.update(x);
                                          std::vector<double> dw, ds;
                                          f.mass_factors(first.mass, dw);
                                          f.stiffness_factors(first.stiffness, ds);
                                          VecDestroy(&x);
                                          return first;
                                        }};
  p->scene_ = dynamics::build_scene(comm, c.scene, model == BodyModel::Ffrf ? &initial : nullptr);
  for (std::size_t b = 0; b < c.scene.bodies.size(); ++b)
    if (c.scene.bodies[b].name == d.body) p->design_body_ = static_cast<int>(b);
  const dynamics::SceneBody &dsb = p->scene_.bodies[static_cast<std::size_t>(p->design_body_)];
  p->mechanism_body_ = dsb.mechanism;
  p->acf_design_ = dsb.acf;
  p->ffrf_design_ = model == BodyModel::Ffrf;
  if (p->ffrf_design_) {
    p->reduction_ = dsb.reduction;
    p->reduced_factors_ = first;
    p->reduction_s_ = p->scene_.reduction_seconds[static_cast<std::size_t>(p->design_body_)];
  }
  p->basis_ = c.adjoint.basis;
  const mesh::DistributedMesh &m = p->scene_.meshes[static_cast<std::size_t>(p->design_body_)];
  if (field && &field->mesh() != &m)
    throw Error("DynamicProblem: the design field's mesh is not the scene's", true);
  p->field_ = field ? std::move(field) : std::make_unique<optimize::DesignField>(m, d);
  // A flexible body's interfaces are tied rigidly (FFRF: checked before the reduction, above).
  if (model == BodyModel::Acf) check_interfaces(*p->field_, body, d, refuse_interfaces);
  if (model != BodyModel::Ffrf) check_mass_bounds(*p->field_, c);
  p->grad_physical_ = p->field_->filter().create_element_vector();

  if (model == BodyModel::Rigid) {
    // The design body keeps its solid centre of mass as its reference point (section 9.1).
    const auto &solid =
        dynamic_cast<const bodies::RigidBody &>(p->scene_.mechanism.body(p->mechanism_body_));
    p->reference_ = solid.center();
    const double density = body.material.density;
    p->element_theta_.resize(static_cast<std::size_t>(m.local_elements()));
    for (PetscInt e = 0; e < m.local_elements(); ++e)
      p->element_theta_[static_cast<std::size_t>(e)] =
          bodies::element_mass_parameters(m.type, m.element_coordinates(e), density, p->reference_);
  }

  p->bind_responses(model);
  p->integration_ = dynamics::IntegratorSettings::from(c.time);
  p->steps_ = p->integration_.steps;
  return p;
}

void DynamicProblem::bind_responses(dynamics::BodyModel model) {
  using dynamics::BodyModel;
  specs_.push_back(&settings_.objective);
  for (const auto &r : settings_.constraints) specs_.push_back(&r);
  names_.push_back(std::string("objective:") +
                   optimize::response_type_name(settings_.objective.type));
  for (std::size_t i = 0; i < settings_.constraints.size(); ++i)
    names_.push_back("constraint" + std::to_string(i) + ":" +
                     optimize::response_type_name(settings_.constraints[i].type));
  for (const optimize::ResponseSettings *r : specs_) {
    int sensor = -1;
    if (!r->sensor.empty())
      for (std::size_t k = 0; k < scene_.sensors.size(); ++k)
        if (scene_.sensors[k].name == r->sensor) sensor = static_cast<int>(k);
    sensor_of_.push_back(sensor);
    sensor_frames_.emplace_back();
    bool on_design = false;
    if (sensor >= 0 && ffrf_design_) {
      const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor)];
      on_design = s.acf_body < 0 && s.body == mechanism_body_ &&
                  s.quantity != dynamics::SensorQuantity::RotationAngle;
    }
    sensor_on_design_.push_back(on_design);
    strain_body_.push_back(-1);
    if (r->type == optimize::ResponseType::StrainEnergyIntegral) {
      const BodyModel bm = dynamics::simulated_model(settings_.scene.body(r->body).model);
      if (bm == BodyModel::Rigid)
        throw Error(r->where.str() + ": strain_energy_integral of body '" + r->body +
                        "': a rigid body has no strain energy (ACF and FFRF bodies have)",
                    true);
      if (bm == BodyModel::Ffrf && !scene_.acf.empty())
        throw Error(r->where.str() + ": strain_energy_integral of FFRF body '" + r->body +
                        "' in a scene with ACF bodies is not built yet (ACF bodies' strain "
                        "energy is, and FFRF bodies' in scenes without ACF bodies)",
                    true);
      if (bm == BodyModel::Ffrf)
        for (std::size_t b = 0; b < settings_.scene.bodies.size(); ++b)
          if (settings_.scene.bodies[b].name == r->body)
            strain_body_.back() = scene_.bodies[b].mechanism;
    }
    if (sensor >= 0 && model == BodyModel::Acf) {
      const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor)];
      if (s.acf_body >= 0 && s.quantity == dynamics::SensorQuantity::ElasticDisplacement)
        throw Error(r->where.str() + ": sensor '" + s.name +
                        "' measures the elastic displacement of an ACF body, which a response "
                        "cannot use yet (position, displacement)",
                    true);
    }
  }
}

DynamicProblem::~DynamicProblem() {
  VecDestroy(&grad_physical_);
}

const mesh::DistributedMesh &DynamicProblem::mesh() const {
  return scene_.meshes[static_cast<std::size_t>(design_body_)];
}

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

} // namespace

int DynamicProblem::design_parameters() const {
  if (!ffrf_design_) return 10;
  const auto &body = dynamic_cast<const bodies::FfrfBody &>(scene_.mechanism.body(mechanism_body_));
  return packed_size(body.coordinates() - 7, body.stiffening());
}

Matrix DynamicProblem::design_partials(const Vector &q, const Vector &v, const Vector &a,
                                       bool gravity, const Matrix &W) const {
  const dynamics::Mechanism &mech = scene_.mechanism;
  const int o = mech.offset(mechanism_body_);
  if (ffrf_design_) {
    const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(mechanism_body_));
    const int nb = body.coordinates(), n = nb - 7;
    Matrix G(packed_size(n, body.stiffening()), W.cols());
    for (Eigen::Index c = 0; c < W.cols(); ++c) {
      bodies::FfrfModel bar;
      const Vector mu = W.col(c).segment(o, nb);
      body.model_cotangent(q.segment(o, nb), v.segment(o, nb), a.segment(o, nb),
                           gravity ? mech.gravity : Vec3::Zero(), mu, bar);
      G.col(c) = pack(bar, n, body.stiffening());
    }
    return G;
  }
  const auto &body = dynamic_cast<const bodies::RigidBody &>(mech.body(mechanism_body_));
  const bodies::RigidBody::Vec7 qb = q.segment<7>(o), vb = v.segment<7>(o), ab = a.segment<7>(o);
  const Eigen::Matrix<double, 7, 10> P =
      body.parameter_jacobian(qb, vb, ab, gravity ? mech.gravity : Vec3::Zero());
  return P.transpose() * W.middleRows(o, 7);
}

double DynamicProblem::response_value(std::size_t i) const {
  const optimize::ResponseSettings &r = *specs_[i];
  if (r.type == optimize::ResponseType::VolumeFraction) return field_->volume_fraction();
  if (r.type == optimize::ResponseType::Mass) {
    if (r.body == settings_.design.body && acf_design_ < 0 && !ffrf_design_) return theta_(0);
    for (std::size_t b = 0; b < settings_.scene.bodies.size(); ++b)
      if (settings_.scene.bodies[b].name == r.body) {
        const dynamics::SceneBody &sb = scene_.bodies[b];
        if (sb.acf >= 0) return scene_.acf[static_cast<std::size_t>(sb.acf)]->total_mass();
        return scene_.mechanism.body(sb.mechanism).mass();
      }
  }
  return sampled_[i].value;
}

void DynamicProblem::apply_design(Vec x) {
  field_->update(x);
  // Mass factors w (section 9.1) and, for an ACF body, SIMP modulus factors s (section 9.6).
  field_->mass_factors(w_, dw_);
  field_->stiffness_factors(s_, ds_);
  if (acf_design_ >= 0) {
    scene_.acf[static_cast<std::size_t>(acf_design_)]->set_factors(s_, w_);
  } else if (ffrf_design_) {
    // Collective: every rank compares its own elements (a change of one element's density
    // moves the factors on its rank only).
    int changed = s_ != reduced_factors_.stiffness || w_ != reduced_factors_.mass, any = 0;
    MPI_Allreduce(&changed, &any, 1, MPI_INT, MPI_LOR, mesh().comm);
    if (any) {
      const double t0 = wall_time();
      reduced_factors_ = reduce::ElementFactors{s_, w_};
      reduction_ =
          dynamics::set_ffrf_design(mesh().comm, settings_.scene, scene_,
                                    static_cast<std::size_t>(design_body_), reduced_factors_);
      reduction_s_ = wall_time() - t0;
      last_.reduction = reduction_s_;
    }
  } else {
    set_rigid_design();
  }
}

void DynamicProblem::evaluate(Vec x, bool gradients, optimize::Evaluation &out) {
  LogScope log("FxDynamicEvaluate");
  ++evaluations_;
  last_ = {};
  apply_design(x);
  const mesh::DistributedMesh &m = mesh();
  const PetscInt ne = m.local_elements();
  const std::size_t nr = specs_.size();
  element_gradient_.assign(nr, std::vector<double>(static_cast<std::size_t>(ne), 0.0));
  if (!scene_.acf.empty())
    evaluate_distributed(gradients, out);
  else
    evaluate_rigid(gradients, out);
  if (!gradients) return;
  last_.adjoint = adjoint_s_;
  if (!out.d_objective) {
    out.d_objective = create_design_vector();
    for (std::size_t i = 0; i < settings_.constraints.size(); ++i)
      out.d_constraints.push_back(create_design_vector());
  }
  for (std::size_t i = 0; i < nr; ++i) {
    if (specs_[i]->type == optimize::ResponseType::VolumeFraction) {
      field_->volume_fraction_gradient(grad_physical_);
    } else {
      PetscScalar *g;
      FX_PETSC(VecGetArray(grad_physical_, &g));
      for (PetscInt e = 0; e < ne; ++e) g[e] = element_gradient_[i][static_cast<std::size_t>(e)];
      FX_PETSC(VecRestoreArray(grad_physical_, &g));
    }
    field_->pull_back(grad_physical_, out.gradient(i));
  }
  // A response that the densities cannot move (a kinematic response of a fully driven rigid
  // mechanism, say) has a gradient of round-off: say so once, rather than let an optimizer
  // stall on it silently.
  if (!zero_gradient_warned_) {
    for (std::size_t i = 0; i < nr; ++i) {
      PetscReal g = 0;
      FX_PETSC(VecNorm(out.gradient(i), NORM_INFINITY, &g));
      const double value = out.value(i);
      if (g <= 1e-12 * std::max(std::abs(value), 1e-300)) {
        print0(m.comm,
               "adjoint: warning: %s does not depend on the densities (max |dPsi/dx| = %.2e, "
               "value %.6g): a kinematic response of a mechanism whose motion the drivers fix, "
               "or a body the design does not reach\n",
               names_[i].c_str(), static_cast<double>(g), value);
        zero_gradient_warned_ = true;
      }
    }
  }
}

void DynamicProblem::set_rigid_design() {
  const mesh::DistributedMesh &m = mesh();
  bodies::MassParameters local = bodies::MassParameters::Zero();
  for (PetscInt e = 0; e < m.local_elements(); ++e)
    local += w_[static_cast<std::size_t>(e)] * element_theta_[static_cast<std::size_t>(e)];
  MPI_Allreduce(local.data(), theta_.data(), 10, MPI_DOUBLE, MPI_SUM, m.comm);
  dynamics::set_body_model(m.comm, settings_.scene, scene_, static_cast<std::size_t>(design_body_),
                           std::make_shared<bodies::RigidBody>(
                               settings_.scene.bodies[static_cast<std::size_t>(design_body_)].name,
                               bodies::from_parameters(theta_, reference_)));
}

void DynamicProblem::add_rigid_element_gradients(const Matrix &G) {
  // dPsi/dw_e = G . theta_e (+ m_e for the design body's mass), then dw/d(physical).
  const PetscInt ne = mesh().local_elements();
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const optimize::ResponseSettings &r = *specs_[i];
    Vector g = G.col(static_cast<Eigen::Index>(i));
    if (r.type == optimize::ResponseType::Mass && r.body == settings_.design.body) g(0) += 1;
    for (PetscInt e = 0; e < ne; ++e)
      element_gradient_[i][static_cast<std::size_t>(e)] +=
          dw_[static_cast<std::size_t>(e)] * g.dot(element_theta_[static_cast<std::size_t>(e)]);
  }
}

void DynamicProblem::evaluate_rigid(bool gradients, optimize::Evaluation &out) {
  dynamics::Mechanism &mech = scene_.mechanism;

  // Forward run (section 9.4): the records the backward sweep needs go to the store, all of
  // them or those of the binomial schedule's first descent; every main step's sensor samples.
  const double t_forward = wall_time();
  const dynamics::Integrator integrator(scene_, integration_);
  const dynamics::GeneralizedAlpha &ga = integrator.dense();
  dynamics::StartTrace trace; // what the start did to the velocities (section 9.2)
  StepRecord record{ga.initial_state(scene_.q0, scene_.v0, 0.0, nullptr, &trace), {}};
  const dynamics::State s0 = record.state;
  std::unique_ptr<BinomialSchedule> schedule;
  std::vector<char> keep;
  std::unique_ptr<CheckpointStore> store;
  if (gradients) {
    keep = plan_checkpoints(schedule);
    store = settings_.adjoint.storage == CheckpointStorage::Disk ? disk_store(checkpoint_file())
                                                                 : memory_store();
    store->put(0, record);
  }
  const std::size_t nr = specs_.size();
  samples_.assign(nr, {});
  for (auto &f : sensor_frames_) f.clear();
  const int od = mech.offset(mechanism_body_), nd = mech.size(mechanism_body_);
  // FFRF strain energies U_n = 1/2 zeta^T K_r zeta, summed with the trapezoid weights as the
  // steps come (their number is known), and sum_n w_n 1/2 zeta_n zeta_n^T for the design body.
  strain_kbar_.assign(nr, Matrix());
  std::vector<double> strain_value(nr, 0.0);
  long long sampled_steps = 0;
  auto sample = [&](const dynamics::State &s) {
    const double w = trapezoid_weight(static_cast<std::size_t>(sampled_steps++),
                                      static_cast<std::size_t>(steps_));
    for (std::size_t i = 0; i < nr; ++i) {
      if (strain_body_[i] < 0) continue;
      const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(strain_body_[i]));
      const Vector z = s.q.segment(mech.offset(strain_body_[i]) + 7, body.coordinates() - 7);
      strain_value[i] += w * 0.5 * z.dot(body.data().stiffness * z);
      if (strain_body_[i] == mechanism_body_ && ffrf_design_) {
        if (strain_kbar_[i].size() == 0) strain_kbar_[i].setZero(z.size(), z.size());
        strain_kbar_[i] += w * 0.5 * z * z.transpose();
      }
    }
    for (std::size_t i = 0; i < nr; ++i) {
      if (sensor_of_[i] < 0) continue;
      const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
      samples_[i].push_back(dynamics::sensor_value(scene_, bs, s.q));
      if (sensor_on_design_[i])
        sensor_frames_[i].emplace_back(bs.quantity == dynamics::SensorQuantity::ElasticDisplacement
                                           ? bodies::Mat3::Identity()
                                           : bodies::rotation(s.q.segment<4>(od + 3)),
                                       s.q.segment(od + 7, nd - 7));
    }
  };
  sample(record.state);
  if (observer_) observer_(0, dynamics::StepInfo{}, &record.state, nullptr);
  const double h = settings_.time.step;
  dynamics::run_steps(ga, steps_, h, record, &substep_sizes_,
                      [&](long long j, const dynamics::StepInfo &info) {
                        sample(record.state);
                        if (gradients && keep[static_cast<std::size_t>(j)]) store->put(j, record);
                        if (observer_) observer_(j, info, &record.state, nullptr);
                      });
  // The responses on the time grid.
  sampled_.assign(nr, SampledResponse{});
  for (std::size_t i = 0; i < nr; ++i) {
    if (sensor_of_[i] >= 0) sampled_[i] = sampled_response(*specs_[i], samples_[i], h);
    if (strain_body_[i] >= 0) sampled_[i].value = strain_value[i];
  }
  if (!finish_forward(t_forward, gradients, out)) return;

  // Backward sweep for all responses at once (one column each), main step by main step.
  const double t_adjoint = wall_time();
  const int n = mech.coordinates();
  const int cols = static_cast<int>(nr);
  BackwardSweep sweep(ga, cols);
  Matrix G = Matrix::Zero(design_parameters(), cols); // dPsi/dtheta
  auto backward = [&](const dynamics::State &s, double dt, const Matrix &dpsi) {
    const Matrix mu = sweep.step(s, dt, dpsi);
    G += design_partials(s.q, s.v, s.acc, true, mu.middleRows(3 * n, n));
  };
  auto visit = [&](long long j, const StepRecord &r) {
    if (r.substeps.empty()) {
      backward(r.state, h, state_partials(j, r.state));
      return;
    }
    // A halved step: its substeps backwards, the responses only at its end (section 9.3).
    for (std::size_t k = r.substeps.size(); k-- > 0;)
      backward(k + 1 == r.substeps.size() ? r.state : r.substeps[k].first, r.substeps[k].second,
               k + 1 == r.substeps.size() ? state_partials(j, r.state) : Matrix());
  };
  recomputed_ = reverse_steps<StepRecord>(
      schedule.get(), *store, steps_,
      [&](const StepRecord &previous, long long j) { return recompute(ga, previous, j); }, visit);
  checkpoint_bytes_ = store->peak_bytes();
  adjoint_factorizations_ = sweep.factorizations();
  const Matrix mu0 = sweep.finish(state_partials(0, s0));
  // The placed state depends on the design when the FFRF design body has initial elastic fields
  // (section 10.2): then the start returns its sensitivities to it too.
  const dynamics::SceneBody &dsb = scene_.bodies[static_cast<std::size_t>(design_body_)];
  const bool given = ffrf_design_ && (dsb.elastic0.size() > 0 || dsb.elastic_rate0.size() > 0);
  const StartAdjoint start = initial_state_adjoint(
      ga, s0, trace, -mu0,
      [&](const Vector &q, const Vector &v, const Vector &a, bool gravity, const Matrix &W) {
        return design_partials(q, v, a, gravity, W);
      },
      given);
  G += start.design;
  adjoint_s_ = wall_time() - t_adjoint;
  if (ffrf_design_)
    add_ffrf_element_gradients(G, start);
  else
    add_rigid_element_gradients(G);
}

void DynamicProblem::add_ffrf_element_gradients(const Matrix &G, const StartAdjoint &start) {
  const dynamics::BodyDescription &spec =
      settings_.scene.bodies[static_cast<std::size_t>(design_body_)];
  const auto &body = dynamic_cast<const bodies::FfrfBody &>(scene_.mechanism.body(mechanism_body_));
  const int n = body.coordinates() - 7;
  const mesh::DistributedMesh &m = mesh();
  std::vector<reduce::ReductionCotangent> bars;
  std::vector<std::size_t> columns; // the responses that depend on the design body
  std::vector<Vec> owned;
  // The element terms of the initial fields' projections (section 10.2), per response.
  std::vector<std::vector<double>> projection_w(specs_.size());
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    const optimize::ResponseSettings &r = *specs_[i];
    bodies::FfrfModel bar = unpack(G.col(static_cast<Eigen::Index>(i)), n, body.stiffening());
    bool used = !G.col(static_cast<Eigen::Index>(i)).isZero(0);
    if (r.type == optimize::ResponseType::Mass && r.body == settings_.design.body) {
      bar.invariants.mass += 1;
      used = true;
    }
    reduce::ReductionCotangent c;
    // C_r = a M_r + b K_r; a strain energy integral's own sum_n w_n 1/2 zeta_n zeta_n^T.
    c.K = bar.stiffness + spec.rayleigh[1] * bar.damping;
    if (strain_kbar_[i].size() > 0) {
      c.K += strain_kbar_[i];
      used = true;
    }
    c.M = spec.rayleigh[0] * bar.damping;
    c.invariants = bar.invariants;
    c.geometric = bar.geometric;
    if (sensor_on_design_[i] && n > 0) {
      // The sensor's basis S = Psi(X_s): dPsi/dS = sum_n A_n^T dPsi/dy_n zeta_n^T (minus the
      // value at q0 for a displacement), then Psi-bar_k = N(X_s) S-bar(:, k).
      Matrix Sbar = Matrix::Zero(3, n);
      const auto &frames = sensor_frames_[i];
      Vec3 sum = Vec3::Zero();
      for (std::size_t k = 0; k < frames.size(); ++k) {
        Sbar += frames[k].first.transpose() * sampled_[i].dy[k] * frames[k].second.transpose();
        sum += sampled_[i].dy[k];
      }
      const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
      if (bs.quantity == dynamics::SensorQuantity::Displacement) {
        const int o = scene_.mechanism.offset(mechanism_body_);
        Sbar -= bodies::rotation(scene_.q0.segment<4>(o + 3)).transpose() * sum *
                scene_.q0.segment(o + 7, n).transpose();
      }
      if (!Sbar.isZero(0)) {
        for (int k = 0; k < n; ++k) {
          Vec v;
          FX_PETSC(VecDuplicate(reduction_->basis.front(), &v));
          FX_PETSC(VecZeroEntries(v));
          fem::add_point_functional(
              m, scene_.sensors[static_cast<std::size_t>(sensor_of_[i])].location,
              {Sbar(0, k), Sbar(1, k), Sbar(2, k)}, v);
          c.basis.push_back(v);
          owned.push_back(v);
        }
        used = true;
      }
    }
    if (start.q.size() > 0 && n > 0) {
      // Initial elastic fields (section 10.2): the start's sensitivities to the placed elastic
      // coordinates and rates (a displacement sensor also measures from the placed position),
      // and the cotangent of the positions' metric on the body's coordinates.
      const auto col = static_cast<Eigen::Index>(i);
      const int o = scene_.mechanism.offset(mechanism_body_);
      Vector qbar = start.q.col(col);
      if (sensor_of_[i] >= 0 && sensor_on_design_[i]) {
        const dynamics::BoundSensor &bs = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
        if (bs.quantity == dynamics::SensorQuantity::Displacement) {
          Vec3 sum = Vec3::Zero();
          for (const Vec3 &dy : sampled_[i].dy) sum += dy;
          qbar -= sensor_jacobian(scene_, bs, scene_.q0).transpose() * sum;
        }
      }
      const Matrix &W = start.metric[static_cast<std::size_t>(i)];
      const Matrix Wz = W.block(o + 7, o + 7, n, n);
      c.M += 0.5 * (Wz + Wz.transpose());
      const dynamics::SceneBody &dsb = scene_.bodies[static_cast<std::size_t>(design_body_)];
      const double density = spec.material.density;
      for (const bool rate : {false, true}) {
        const Vector &zeta = rate ? dsb.elastic_rate0 : dsb.elastic0;
        if (zeta.size() == 0) continue;
        const Vector zbar = (rate ? start.v.col(col) : qbar).segment(o + 7, n);
        if (c.basis.empty())
          for (int k = 0; k < n; ++k) {
            Vec v;
            FX_PETSC(VecDuplicate(reduction_->basis.front(), &v));
            FX_PETSC(VecZeroEntries(v));
            c.basis.push_back(v);
            owned.push_back(v);
          }
        reduce::project_field_adjoint(m, density, *reduction_,
                                      dynamics::initial_elastic_field(spec, rate), zeta, zbar,
                                      c.basis, projection_w[i]);
      }
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
        m, *reduction_, bars, basis_, s_hat, w_hat, reduce::BasisGauge::FrozenCoordinates);
    reduction_cg_iterations_ = stats.cg_iterations;
  } catch (const Error &) {
    for (Vec &v : owned) VecDestroy(&v);
    throw;
  }
  reduction_adjoint_s_ = wall_time() - t0;
  last_.reduction_adjoint = reduction_adjoint_s_;
  for (Vec &v : owned) FX_PETSC(VecDestroy(&v));
  const PetscInt ne = m.local_elements();
  for (std::size_t c = 0; c < columns.size(); ++c)
    for (PetscInt e = 0; e < ne; ++e) {
      const auto k = static_cast<std::size_t>(e);
      element_gradient_[columns[c]][k] += ds_[k] * s_hat[c][k] + dw_[k] * w_hat[c][k];
    }
  for (std::size_t i = 0; i < projection_w.size(); ++i)
    for (std::size_t k = 0; k < projection_w[i].size(); ++k)
      element_gradient_[i][k] += dw_[k] * projection_w[i][k];
}

std::vector<char>
DynamicProblem::plan_checkpoints(std::unique_ptr<BinomialSchedule> &schedule) const {
  const int checkpoints = settings_.adjoint.checkpoints; // 0: all
  std::vector<char> keep(static_cast<std::size_t>(steps_ + 1), checkpoints == 0 ? 1 : 0);
  if (checkpoints > 0) {
    schedule = std::make_unique<BinomialSchedule>(
        steps_, static_cast<int>(std::min<long long>(checkpoints - 1, steps_)));
    for (long long j : schedule->first_descent()) keep[static_cast<std::size_t>(j)] = 1;
    keep.front() = keep.back() = 1;
  }
  return keep;
}

std::string DynamicProblem::checkpoint_file() const {
  int rank = 0;
  MPI_Comm_rank(mesh().comm, &rank);
  return scratch_ + "/adjoint_checkpoints." + std::to_string(rank) + ".h5";
}

bool DynamicProblem::finish_forward(double t_forward, bool gradients, optimize::Evaluation &out) {
  const double forward = wall_time() - t_forward;
  forward_total_s_ += forward;
  last_.forward = forward;
  out.constraints.assign(settings_.constraints.size(), 0.0);
  for (std::size_t i = 0; i < specs_.size(); ++i) out.value(i) = response_value(i);
  if (gradients) forward_s_ = forward;
  return gradients;
}

Matrix DynamicProblem::state_partials(long long j, const dynamics::State &state) const {
  const int n = scene_.mechanism.coordinates(), m = scene_.mechanism.constraints();
  Matrix P;
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (strain_body_[i] >= 0) {
      // d/dzeta of w_j 1/2 zeta^T K_r zeta.
      const dynamics::Mechanism &mech = scene_.mechanism;
      const auto &body = dynamic_cast<const bodies::FfrfBody &>(mech.body(strain_body_[i]));
      const int o = mech.offset(strain_body_[i]) + 7, ne = body.coordinates() - 7;
      if (P.size() == 0) P.setZero(4 * n + m, static_cast<Eigen::Index>(specs_.size()));
      P.col(static_cast<Eigen::Index>(i)).segment(o, ne) =
          trapezoid_weight(static_cast<std::size_t>(j), static_cast<std::size_t>(steps_)) *
          (body.data().stiffness * state.q.segment(o, ne));
      continue;
    }
    if (sampled_[i].dy.empty()) continue;
    const Vec3 &dy = sampled_[i].dy[static_cast<std::size_t>(j)];
    if (dy.isZero(0)) continue;
    if (P.size() == 0) P.setZero(4 * n + m, static_cast<Eigen::Index>(specs_.size()));
    const dynamics::BoundSensor &s = scene_.sensors[static_cast<std::size_t>(sensor_of_[i])];
    P.col(static_cast<Eigen::Index>(i)).head(n) =
        sensor_jacobian(scene_, s, state.q).transpose() * dy;
  }
  return P;
}

StepRecord DynamicProblem::recompute(const dynamics::GeneralizedAlpha &ga,
                                     const StepRecord &previous, long long j) const {
  return dynamics::recompute_step(ga, previous, j, settings_.time.step,
                                  substep_sizes_[static_cast<std::size_t>(j)]);
}

long long DynamicProblem::dofs() const {
  long long n = scene_.mechanism.coordinates();
  for (std::size_t b = 0; b < scene_.bodies.size(); ++b)
    if (scene_.bodies[b].acf >= 0) n += 3LL * scene_.meshes[b].global_nodes;
  return n;
}

std::vector<std::string> DynamicProblem::solve_to_round_off() {
  // Newton's method proper: responses smooth in the design to round-off (docs/theory.md 9.5).
  set_newton_reuse(0);
  std::vector<std::string> limits;
  const std::string filter = field_->filter().solve_to_round_off();
  filter_limited_ = !filter.empty();
  if (filter_limited_) limits.push_back(filter);
  if (ffrf_design_) {
    // The reduction's fixed-interface modes are solved to 1e-13 (reduce_flexible_body) unless
    // -eps_tol says otherwise.
    PetscReal tol = 0;
    PetscBool given = PETSC_FALSE;
    FX_PETSC(PetscOptionsGetReal(nullptr, nullptr, "-eps_tol", &tol, &given));
    if (given && tol > 1e-13)
      limits.push_back("the FFRF reduction's eigenpairs stop at -eps_tol " + std::to_string(tol));
  }
  return limits;
}

bool DynamicProblem::set_random_start(unsigned long seed) {
  // Every other solve of a dynamic evaluation is direct, or Newton's to 1e-12, whatever its
  // start; the filter's own tolerance (1e-12) keeps its noise below noise_floor(). Only a
  // filter loosened by the user's options is worth two more runs to measure.
  return field_->filter().set_random_start(filter_limited_ ? seed : 0) && filter_limited_;
}

double DynamicProblem::noise_floor(std::size_t i) const {
  const optimize::ResponseType type = specs_[i]->type;
  return type == optimize::ResponseType::VolumeFraction || type == optimize::ResponseType::Mass
             ? 1e-14
             : noise_floor();
}

std::vector<optimize::Timing> DynamicProblem::timings() const {
  std::vector<optimize::Timing> t;
  if (ffrf_design_) t.push_back({"reduction", "reduce", last_.reduction});
  t.push_back({"forward", "forward", last_.forward});
  t.push_back({"adjoint", "adjoint", last_.adjoint});
  if (ffrf_design_) t.push_back({"reduction_adjoint", "red.adj", last_.reduction_adjoint});
  return t;
}

void DynamicProblem::describe(io::Json &s) const {
  s["dofs"] = dofs();
  s["elements"] = static_cast<long long>(mesh().global_elements);
  s["design_variables"] = static_cast<long long>(design_size());
  s["coordinates"] = scene_.mechanism.coordinates();
  s["constraint_rows"] = scene_.mechanism.constraints();
  s["steps"] = steps_;
  s["evaluations"] = evaluations_;
  s["forward_s"] = forward_s_; // of the last evaluation with gradients
  s["adjoint_s"] = adjoint_s_;
  s["forward_total_s"] = forward_total_s_;
  if (settings_.adjoint.checkpoints > 0)
    s["checkpoints"] = settings_.adjoint.checkpoints;
  else
    s["checkpoints"] = "all";
  s["storage"] = settings_.adjoint.storage == CheckpointStorage::Disk ? "disk" : "memory";
  s["recomputed_steps"] = recomputed_;
  s["adjoint_factorizations"] = adjoint_factorizations_;
  s["newton_reuse"] = integration_.newton.reuse_contraction;
  if (ffrf_design_) {
    s["reduction_s"] = reduction_s_; // of the last design
    s["reduction_adjoint_s"] = reduction_adjoint_s_;
    s["reduction_adjoint_cg_iterations"] = reduction_cg_iterations_;
    s["basis_derivative"] =
        settings_.adjoint.basis == reduce::BasisDerivative::Fixed ? "fixed" : "exact";
  }
  s["checkpoint_bytes"] = checkpoint_bytes_;
}

} // namespace flexopt::adjoint
