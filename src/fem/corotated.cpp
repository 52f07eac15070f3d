#include "flexopt/fem/corotated.hpp"

#include <cmath>
#include <sstream>

namespace flexopt::fem {

namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

Mat3 skew(const Vec3 &a) {
  Mat3 s;
  s << 0, -a(2), a(1), a(2), 0, -a(0), -a(1), a(0), 0;
  return s;
}

/// Energy, force and tangent for a fixed node count NN (docs/theory.md section 8.1; the names
/// follow it).
template <int NN>
double state_impl(const CorotatedElement &e, const ElementCoords &x, ElementVector *f,
                  ElementMatrix *T) {
  constexpr int kNd = 3 * NN;
  using Nodes = Eigen::Matrix<double, NN, 3, Eigen::RowMajor>;
  using Vecd = Eigen::Matrix<double, kNd, 1>;
  using Matd = Eigen::Matrix<double, kNd, kNd, Eigen::RowMajor>;
  using Mat3d = Eigen::Matrix<double, 3, kNd>;
  using Matd3 = Eigen::Matrix<double, kNd, 3>;
  const Nodes h = e.h;
  const Eigen::Matrix<double, NN, 1> Nc = e.Nc;
  // Differences to node 0 keep full relative accuracy far from the origin (sum_a h_a = 0,
  // sum_a Nc_a = 1).
  const Nodes dx = x.rowwise() - x.row(0), dX = e.X.rowwise() - e.X.row(0);
  const Mat3 F = dx.transpose() * h;
  const double det = F.determinant();
  if (!(det > 0)) {
    std::ostringstream msg;
    msg.precision(6);
    msg << "co-rotated " << element_name(e.type) << " element: inverted (det F = " << det
        << " <= 0 at the centroid; first node at (" << e.X(0, 0) << ", " << e.X(0, 1) << ", "
        << e.X(0, 2) << "))";
    throw Error(msg.str());
  }
  const Mat3 R = polar_rotation(F);
  const Mat3 U0 = R.transpose() * F;
  const Mat3 U = 0.5 * (U0 + U0.transpose());
  const Vec3 xc = (Nc.transpose() * dx).transpose(), Xc = (Nc.transpose() * dX).transpose();
  Nodes y, ut;
  for (int a = 0; a < NN; ++a) {
    y.row(a) = (R.transpose() * (dx.row(a).transpose() - xc)).transpose();
    ut.row(a) = y.row(a) - (dX.row(a) - Xc.transpose());
  }
  const Eigen::Map<const Vecd> u(ut.data());
  const Matd K = e.K;
  const Vecd g = K * u;
  const double energy = 0.5 * u.dot(g);
  if (!f && !T) return energy;

  Vec3 m = Vec3::Zero();
  for (int a = 0; a < NN; ++a) m += g.template segment<3>(3 * a).cross(y.row(a).transpose());
  const Mat3 G = U.trace() * Mat3::Identity() - U;
  const Mat3 Gi = G.inverse();
  const Vec3 c = Gi * m;
  Vecd ft; // f~ (local)
  for (int a = 0; a < NN; ++a)
    ft.template segment<3>(3 * a) = g.template segment<3>(3 * a) + c.cross(h.row(a).transpose());
  if (f) {
    f->resize(kNd);
    for (int a = 0; a < NN; ++a) f->template segment<3>(3 * a) = R * ft.template segment<3>(3 * a);
  }
  if (!T) return energy;

  // Tangent in local perturbations d_b = R^T dx_b: T~ = Ag - [f~]x Omega - [h]x Cc.
  Mat3d Omega;
  Matd3 Y, Fx, Hx;
  for (int b = 0; b < NN; ++b) {
    const Mat3 hb = skew(h.row(b).transpose());
    Omega.template middleCols<3>(3 * b) = Gi * hb;
    Y.template middleRows<3>(3 * b) = skew(y.row(b).transpose());
    Fx.template middleRows<3>(3 * b) = skew(ft.template segment<3>(3 * b));
    Hx.template middleRows<3>(3 * b) = hb;
  }
  const Matd3 KY = K * Y;
  Matd Ag = K;
  Ag.noalias() += KY * Omega;
  // dm = sum_a (-[y_a]x dg_a + [g_a]x dy_a), dy_a = d_a - sum_b Nc_b d_b + [y_a]x w.
  Mat3d Mg;
  Mat3 gy = Mat3::Zero();
  Vec3 gsum = Vec3::Zero();
  for (int a = 0; a < NN; ++a) {
    const Vec3 ga = g.template segment<3>(3 * a);
    Mg.template middleCols<3>(3 * a) = -skew(y.row(a).transpose());
    gy += skew(ga) * skew(y.row(a).transpose());
    gsum += ga;
  }
  Mat3d Am;
  Am.noalias() = Mg * Ag;
  Am.noalias() += gy * Omega;
  const Mat3 Gs = skew(gsum);
  for (int b = 0; b < NN; ++b)
    Am.template middleCols<3>(3 * b) += skew(g.template segment<3>(3 * b)) - Nc(b) * Gs;
  // dG c = sum_b (c h_b^T - (h_b . c) I) d_b - [U c]x w.
  Mat3d Ac;
  const Mat3 Ucx = skew(U * c);
  for (int b = 0; b < NN; ++b) {
    const Vec3 hb = h.row(b).transpose();
    Ac.template middleCols<3>(3 * b) = c * hb.transpose() - hb.dot(c) * Mat3::Identity();
  }
  Ac.noalias() -= Ucx * Omega;
  const Mat3d Cc = Gi * (Am - Ac);
  Matd Tl = Ag;
  Tl.noalias() -= Fx * Omega;
  Tl.noalias() -= Hx * Cc;
  // T = R_blk T~ R_blk^T, symmetrized (the exact Hessian is symmetric; this removes round-off).
  T->resize(kNd, kNd);
  for (int a = 0; a < NN; ++a)
    for (int b = 0; b < NN; ++b)
      T->template block<3, 3>(3 * a, 3 * b) =
          R * Tl.template block<3, 3>(3 * a, 3 * b) * R.transpose();
  const ElementMatrix Ts = 0.5 * (*T + T->transpose());
  *T = Ts;
  return energy;
}

} // namespace

Eigen::Matrix3d polar_rotation(const Eigen::Matrix3d &F) {
  Mat3 R = F;
  for (int it = 0; it < 60; ++it) {
    const Mat3 Rit = R.inverse().transpose();
    // Higham's scaling (Frobenius norms) while far from orthogonal; plain Newton near it, where
    // it converges quadratically.
    double gamma = 1.0;
    const double change = (R - Rit).norm();
    if (change > 1e-2) gamma = std::sqrt(Rit.norm() / R.norm());
    const Mat3 next = 0.5 * (gamma * R + Rit / gamma);
    const double step = (next - R).norm();
    R = next;
    if (step <= 4e-16 * std::sqrt(3.0)) return R;
  }
  if ((R * R.transpose() - Mat3::Identity()).norm() < 1e-13) return R;
  throw Error("polar_rotation: the iteration did not converge (a singular deformation gradient)");
}

CorotatedElement corotated_element(ElementType type, const ElementCoords &X,
                                   const IsotropicMaterial &mat, double modulus_factor) {
  CorotatedElement e;
  e.type = type;
  e.X = X;
  e.K = element_stiffness(type, X, mat, modulus_factor);
  const int n = nodes_per_element(type);
  double N[kMaxNodes], dN[3 * kMaxNodes];
  shape_functions(type, reference_centroid(type), N, dN);
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> dNm(dN, n, 3);
  const ElementCoords dX = X.rowwise() - X.row(0);
  const Mat3 J = dX.transpose() * dNm; // dx/dxi
  e.h = dNm * J.inverse();
  e.Nc.resize(n);
  for (int a = 0; a < n; ++a) e.Nc(a) = N[a];
  return e;
}

double corotated_state(const CorotatedElement &e, const ElementCoords &x, ElementVector *f,
                       ElementMatrix *T) {
  if (x.rows() != e.nodes())
    throw Error("corotated_state: " + std::to_string(x.rows()) + " positions for a " +
                element_name(e.type) + " element");
  switch (e.type) {
  case ElementType::Tet4:
    return state_impl<4>(e, x, f, T);
  case ElementType::Tet10:
    return state_impl<10>(e, x, f, T);
  case ElementType::Hex8:
    return state_impl<8>(e, x, f, T);
  }
  throw Error("corotated_state: invalid element type");
}

} // namespace flexopt::fem
