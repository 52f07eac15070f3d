#include "flexopt/dynamics/consistent_start.hpp"

#include "flexopt/core/error.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>

namespace flexopt::dynamics {

namespace {

/// Singular values of the weighted constraint gradient below this fraction of the largest are
/// taken as zero: rows that the rigid-body velocities cannot tell apart (dependent rows, the
/// Euler normalizations, which a spin never changes) and directions no row restricts.
constexpr double kRankThreshold = 1e-10;

} // namespace

VelocityCorrection rigid_velocity_correction(const Mechanism &mech, const Vector &q,
                                             const Vector &v, double t,
                                             const std::vector<RigidField> &fields) {
  const int n = mech.coordinates(), m = mech.constraints();
  const int nb = static_cast<int>(mech.bodies.size());
  // Which field moves each body (-1: its own frame velocity).
  std::vector<int> field_of(static_cast<std::size_t>(nb), -1);
  for (std::size_t f = 0; f < fields.size(); ++f)
    for (int b : fields[f].nodes) field_of[static_cast<std::size_t>(b)] = static_cast<int>(f);
  std::vector<int> own; // bodies with their own six parameters
  for (int b = 0; b < nb; ++b)
    if (field_of[static_cast<std::size_t>(b)] < 0) {
      if (!(mech.body(b).mass() > 0))
        throw Error("initial conditions: body " + mech.body(b).name() +
                        " has no mass and no body carries it: its velocity is undetermined",
                    true);
      own.push_back(b);
    }
  const int k = 6 * static_cast<int>(own.size() + fields.size());
  // T maps the parameters y (per body: du, dw; per field: du, dw) to the change of v:
  // a frame moves by dr = du (+ dw x (r - centre) for a field's node), dp = 1/2 G(p)^T dw.
  Matrix T = Matrix::Zero(n, k);
  auto frame_columns = [&](int b, int col, const Vec3 *centre) {
    const int o = mech.offset(b);
    const bodies::Vec4 p = q.segment<4>(o + 3);
    T.block<3, 3>(o, col).setIdentity();
    if (centre) T.block<3, 3>(o, col + 3) = -bodies::skew(q.segment<3>(o) - *centre);
    T.block<4, 3>(o + 3, col + 3) = 0.5 * bodies::g_matrix(p).transpose();
  };
  for (std::size_t i = 0; i < own.size(); ++i)
    frame_columns(own[i], 6 * static_cast<int>(i), nullptr);
  const int field_col0 = 6 * static_cast<int>(own.size());
  for (std::size_t f = 0; f < fields.size(); ++f)
    for (int b : fields[f].nodes)
      frame_columns(b, field_col0 + 6 * static_cast<int>(f), &fields[f].centre);
  // W: the kinetic energy of the change, T^T M T per body (M is block diagonal over the
  // bodies), the fields' own metrics.
  Vector r;
  Matrix M;
  mech.dynamics(q, v, Vector::Zero(n), t, r, nullptr, nullptr, &M);
  Matrix W = Matrix::Zero(k, k);
  for (std::size_t i = 0; i < own.size(); ++i) {
    const int c = 6 * static_cast<int>(i), o = mech.offset(own[i]), s = mech.size(own[i]);
    const Matrix Tb = T.block(o, c, s, 6);
    W.block<6, 6>(c, c) = Tb.transpose() * M.block(o, o, s, s) * Tb;
  }
  for (std::size_t f = 0; f < fields.size(); ++f)
    W.block<6, 6>(field_col0 + 6 * static_cast<int>(f), field_col0 + 6 * static_cast<int>(f)) =
        fields[f].metric;

  VelocityCorrection out;
  out.dv = Vector::Zero(n);
  out.field.assign(fields.size(), Vector6::Zero());
  if (m == 0 || k == 0) return out;
  Vector phi, phi_t, phi_tt, phi_qt_v;
  Matrix J;
  mech.constraint(q, t, phi, &J);
  mech.constraint_time_terms(q, v, t, phi_t, phi_tt, phi_qt_v);
  const Vector b = -(J * v + phi_t);
  out.scale = b.cwiseAbs().maxCoeff();
  // With W = L L^T and z = L^T y: the smallest |z| among the least-squares solutions of
  // (J T L^-T) z = b.
  const Eigen::LLT<Matrix> llt(W);
  if (llt.info() != Eigen::Success)
    throw Error("initial conditions: a body's mass matrix is not positive definite (a body "
                "without mass or rotational inertia)",
                true);
  const Matrix B = llt.matrixL().solve(T.transpose() * J.transpose()).transpose();
  Eigen::CompleteOrthogonalDecomposition<Matrix> cod;
  cod.setThreshold(kRankThreshold);
  cod.compute(B);
  const Vector z = cod.solve(b);
  const Vector y = llt.matrixU().solve(z);
  out.dv = T * y;
  // Pi = L^-T (I - B^+ B) L^-1 (section 9.2).
  Matrix Linv = llt.matrixL().solve(Matrix::Identity(k, k));
  const Matrix BpB = cod.solve(B);
  out.Pi = Linv.transpose() * (Matrix::Identity(k, k) - BpB) * Linv;
  out.T = T;
  out.y = y;
  out.W = W;
  out.P = J * T;
  out.B = B;
  out.Bp = cod.pseudoInverse();
  out.b = b;
  for (std::size_t f = 0; f < fields.size(); ++f)
    out.field[f] = y.segment<6>(field_col0 + 6 * static_cast<int>(f));
  mech.constraint_time_terms(q, v + out.dv, t, phi_t, phi_tt, phi_qt_v);
  out.residual = (J * (v + out.dv) + phi_t).cwiseAbs().maxCoeff();
  return out;
}

} // namespace flexopt::dynamics
