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

/// What the force and the tangent of an element need of its current configuration (docs/theory.md
/// section 8.1; the names follow it). Fixed node count NN.
template <int NN> struct Kinematics {
  static constexpr int kNd = 3 * NN;
  using Nodes = Eigen::Matrix<double, NN, 3, Eigen::RowMajor>;
  using Vecd = Eigen::Matrix<double, kNd, 1>;
  using Matd = Eigen::Matrix<double, kNd, kNd, Eigen::RowMajor>;
  using Mat3d = Eigen::Matrix<double, 3, kNd>;
  using Matd3 = Eigen::Matrix<double, kNd, 3>;

  Nodes h, y, ut;
  Eigen::Matrix<double, NN, 1> Nc;
  Mat3 R, U, Gi;
  Mat3d Omega; ///< w = Omega d: the element spin of the local perturbations d_b = R^T dx_b
  Matd3 Y, Hx; ///< blocks [y_a]x and [h_a]x

  /// Throws flexopt::Error naming the element if it is inverted at the centroid. Omega, Y and Hx
  /// (only the tangents use them) are set if `tangent_data`.
  Kinematics(const CorotatedElement &e, const ElementCoords &x, bool tangent_data)
      : h(e.h), Nc(e.Nc) {
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
    R = polar_rotation(F);
    const Mat3 U0 = R.transpose() * F;
    U = 0.5 * (U0 + U0.transpose());
    Gi = (U.trace() * Mat3::Identity() - U).inverse();
    const Vec3 xc = (Nc.transpose() * dx).transpose(), Xc = (Nc.transpose() * dX).transpose();
    for (int a = 0; a < NN; ++a) {
      y.row(a) = (R.transpose() * (dx.row(a).transpose() - xc)).transpose();
      ut.row(a) = y.row(a) - (dX.row(a) - Xc.transpose());
    }
    if (!tangent_data) return;
    for (int b = 0; b < NN; ++b) {
      const Mat3 hb = skew(h.row(b).transpose());
      Omega.template middleCols<3>(3 * b) = Gi * hb;
      Y.template middleRows<3>(3 * b) = skew(y.row(b).transpose());
      Hx.template middleRows<3>(3 * b) = hb;
    }
  }

  /// The co-rotated displacement u~ (3n).
  Vecd displacement() const {
    Vecd u;
    for (int a = 0; a < NN; ++a) u.template segment<3>(3 * a) = ut.row(a).transpose();
    return u;
  }

  /// The local force f~ = B~^T g of local nodal forces g with sum_a g_a = 0:
  /// f~_a = g_a + c x h_a, c = G^-1 sum_a g_a x y_a.
  Vecd force(const Vecd &g, Vec3 &c) const {
    Vec3 m = Vec3::Zero();
    for (int a = 0; a < NN; ++a) m += g.template segment<3>(3 * a).cross(y.row(a).transpose());
    c = Gi * m;
    Vecd ft;
    for (int a = 0; a < NN; ++a)
      ft.template segment<3>(3 * a) = g.template segment<3>(3 * a) + c.cross(h.row(a).transpose());
    return ft;
  }

  /// The local derivative of f = R_blk f~(g) along the local perturbations d, where dg = dg/dd:
  /// T~ d = -[f~]x w + dg d - [h]x dc.
  Matd tangent(const Vecd &g, const Vecd &ft, const Vec3 &c, const Matd &dg) const {
    Matd3 Fx;
    for (int b = 0; b < NN; ++b)
      Fx.template middleRows<3>(3 * b) = skew(ft.template segment<3>(3 * b));
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
    Am.noalias() = Mg.lazyProduct(dg);
    Am.noalias() += gy * Omega;
    const Mat3 Gs = skew(gsum);
    for (int b = 0; b < NN; ++b)
      Am.template middleCols<3>(3 * b) += skew(g.template segment<3>(3 * b)) - Nc(b) * Gs;
    // dc = G^-1 (dm - dG c), dG c = sum_b (c h_b^T - (h_b . c) I) d_b - [U c]x w.
    Mat3d Ac;
    for (int b = 0; b < NN; ++b) {
      const Vec3 hb = h.row(b).transpose();
      Ac.template middleCols<3>(3 * b) = c * hb.transpose() - hb.dot(c) * Mat3::Identity();
    }
    Ac.noalias() -= skew(U * c) * Omega;
    const Mat3d Cc = Gi * (Am - Ac);
    Matd Tl = dg;
    Tl.noalias() -= Fx.lazyProduct(Omega);
    Tl.noalias() -= Hx.lazyProduct(Cc);
    return Tl;
  }

  /// R_blk v (3n).
  ElementVector global(const Vecd &v) const {
    ElementVector out(kNd);
    for (int a = 0; a < NN; ++a) out.template segment<3>(3 * a) = R * v.template segment<3>(3 * a);
    return out;
  }

  /// R_blk A R_blk^T (3n x 3n) into `out`, symmetrized if `symmetric` (the exact Hessian is
  /// symmetric; this removes round-off): (B + B^T) / 2 block by block, without temporaries.
  void global(const Matd &A, bool symmetric, ElementMatrix &out) const {
    out.resize(kNd, kNd);
    const Mat3 Rt = R.transpose();
    if (!symmetric) {
      for (int a = 0; a < NN; ++a)
        for (int b = 0; b < NN; ++b)
          out.template block<3, 3>(3 * a, 3 * b).noalias() =
              R.lazyProduct(Mat3(A.template block<3, 3>(3 * a, 3 * b))).lazyProduct(Rt);
      return;
    }
    for (int a = 0; a < NN; ++a) {
      const Mat3 d = R.lazyProduct(Mat3(A.template block<3, 3>(3 * a, 3 * a))).lazyProduct(Rt);
      out.template block<3, 3>(3 * a, 3 * a) = 0.5 * (d + d.transpose());
      for (int b = a + 1; b < NN; ++b) {
        const Mat3 ab = R.lazyProduct(Mat3(A.template block<3, 3>(3 * a, 3 * b))).lazyProduct(Rt);
        const Mat3 ba = R.lazyProduct(Mat3(A.template block<3, 3>(3 * b, 3 * a))).lazyProduct(Rt);
        const Mat3 sym = 0.5 * (ab + ba.transpose());
        out.template block<3, 3>(3 * a, 3 * b) = sym;
        out.template block<3, 3>(3 * b, 3 * a) = sym.transpose();
      }
    }
  }
};

/// Energy, force and tangent (section 8.1).
template <int NN>
double state_impl(const CorotatedElement &e, const ElementCoords &x, ElementVector *f,
                  ElementMatrix *T) {
  using Kin = Kinematics<NN>;
  const Kin k(e, x, T != nullptr);
  const Eigen::Map<const typename Kin::Matd> K(e.K.data()); // row-major, packed: no copy
  const typename Kin::Vecd u = k.displacement();
  const typename Kin::Vecd g = K * u;
  const double energy = 0.5 * u.dot(g);
  if (!f && !T) return energy;
  Vec3 c;
  const typename Kin::Vecd ft = k.force(g, c);
  if (f) *f = k.global(ft);
  if (T) {
    // dg/dd = K (I - 1 Nc^T + Y Omega) = K + K Y Omega (K annihilates translations).
    // Coefficient-based products: Eigen's blocked GEMM path costs more than it saves at 12.
    typename Kin::Matd dg = K;
    const typename Kin::Matd3 KY = K.lazyProduct(k.Y);
    dg.noalias() += KY.lazyProduct(k.Omega);
    k.global(k.tangent(g, ft, c, dg), true, *T);
  }
  return energy;
}

/// Stiffness-proportional damping on the co-rotated velocities (section 8.1, "Damping").
template <int NN>
double damping_impl(const CorotatedElement &e, const ElementCoords &x, const ElementVector &v,
                    double beta, ElementVector *f, ElementMatrix *Cv, ElementMatrix *Cx) {
  using Kin = Kinematics<NN>;
  using Matd = typename Kin::Matd;
  using Mat3d = typename Kin::Mat3d;
  const Kin k(e, x, Cv || Cx);
  // d_a = R^T v_a; the element spin rate w = G^-1 sum_b h_b x d_b; u~'_a = d_a - d_bar + y_a x w.
  typename Kin::Vecd d;
  Vec3 dbar = Vec3::Zero(), s = Vec3::Zero();
  for (int a = 0; a < NN; ++a) {
    d.template segment<3>(3 * a) = k.R.transpose() * v.template segment<3>(3 * a);
    dbar += k.Nc(a) * d.template segment<3>(3 * a);
    s += k.h.row(a).transpose().cross(d.template segment<3>(3 * a));
  }
  const Vec3 w = k.Gi * s;
  typename Kin::Vecd ud;
  for (int a = 0; a < NN; ++a)
    ud.template segment<3>(3 * a) =
        d.template segment<3>(3 * a) - dbar + k.y.row(a).transpose().cross(w);
  const Eigen::Map<const Matd> K(e.K.data());
  const typename Kin::Vecd g = beta * (K * ud);
  const double power = ud.dot(g);
  if (!f && !Cv && !Cx) return power;
  Vec3 c;
  const typename Kin::Vecd ft = k.force(g, c);
  if (f) *f = k.global(ft);
  if (Cv) {
    // df/dv = R_blk B~^T (beta K) B~ R_blk^T, B~ = I - 1 Nc^T + Y Omega; 1^T K = 0.
    Matd KB = K;
    const typename Kin::Matd3 KY = K.lazyProduct(k.Y);
    KB.noalias() += KY.lazyProduct(k.Omega);
    Matd C = KB;
    const Mat3d YKB = k.Y.transpose().lazyProduct(KB);
    C.noalias() += k.Omega.transpose().lazyProduct(YKB);
    C *= beta;
    k.global(C, true, *Cv);
  }
  if (Cx) {
    // du~'/dd at fixed v, with theta = Omega d the variation of R (section 8.1):
    //   block a: [d_a - d_bar]x Omega - [w]x (E_a - Nc^T + [y_a]x Omega) + [y_a]x dw,
    //   dw = G^-1 (sum_b [h_b]x [d_b]x Omega - dG w).
    Mat3 hd = Mat3::Zero();
    for (int b = 0; b < NN; ++b)
      hd += skew(k.h.row(b).transpose()) * skew(d.template segment<3>(3 * b));
    Mat3d dG; // dG w
    for (int b = 0; b < NN; ++b) {
      const Vec3 hb = k.h.row(b).transpose();
      dG.template middleCols<3>(3 * b) = w * hb.transpose() - hb.dot(w) * Mat3::Identity();
    }
    dG.noalias() -= skew(k.U * w) * k.Omega;
    Mat3d dw = hd * k.Omega;
    dw -= dG;
    dw = (k.Gi * dw).eval();
    const Mat3 wx = skew(w);
    Matd D;
    for (int a = 0; a < NN; ++a) {
      const Mat3 ya = skew(k.y.row(a).transpose());
      auto rows = D.template middleRows<3>(3 * a);
      rows.noalias() = skew(d.template segment<3>(3 * a) - dbar) * k.Omega;
      rows.noalias() -= (wx * ya) * k.Omega;
      rows.noalias() += ya * dw;
      for (int b = 0; b < NN; ++b)
        rows.template middleCols<3>(3 * b) += wx * (k.Nc(b) - (a == b ? 1.0 : 0.0));
    }
    const Matd dg = beta * K.lazyProduct(D);
    k.global(k.tangent(g, ft, c, dg), false, *Cx);
  }
  return power;
}

/// The von Mises stress of sigma = S u~ and its gradient (section 8.3).
template <int NN>
double von_mises_impl(const CorotatedElement &e, const StressMatrix &S, const ElementCoords &x,
                      ElementVector *grad) {
  using Kin = Kinematics<NN>;
  const Kin k(e, x, false);
  const typename Kin::Vecd u = k.displacement();
  const Voigt sigma = S * u;
  const double v = von_mises(sigma);
  if (!grad) return v;
  // (du~/dx)^T g = R_blk f~(g) for local forces g with sum_a g_a = 0, which S^T a is (the
  // columns of B sum to zero over the nodes).
  const typename Kin::Vecd g = S.transpose() * von_mises_gradient(sigma);
  Vec3 c;
  *grad = k.global(k.force(g, c));
  return v;
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

double corotated_damping(const CorotatedElement &e, const ElementCoords &x, const ElementVector &v,
                         double beta, ElementVector *f, ElementMatrix *Cv, ElementMatrix *Cx) {
  if (x.rows() != e.nodes() || v.size() != 3 * e.nodes())
    throw Error("corotated_damping: " + std::to_string(x.rows()) + " positions and " +
                std::to_string(v.size()) + " velocities for a " + element_name(e.type) +
                " element");
  switch (e.type) {
  case ElementType::Tet4:
    return damping_impl<4>(e, x, v, beta, f, Cv, Cx);
  case ElementType::Tet10:
    return damping_impl<10>(e, x, v, beta, f, Cv, Cx);
  case ElementType::Hex8:
    return damping_impl<8>(e, x, v, beta, f, Cv, Cx);
  }
  throw Error("corotated_damping: invalid element type");
}

double corotated_von_mises(const CorotatedElement &e, const StressMatrix &S, const ElementCoords &x,
                           ElementVector *grad) {
  if (x.rows() != e.nodes() || S.cols() != 3 * e.nodes())
    throw Error("corotated_von_mises: " + std::to_string(x.rows()) +
                " positions and a stress "
                "matrix of " +
                std::to_string(S.cols()) + " columns for a " + element_name(e.type) + " element");
  switch (e.type) {
  case ElementType::Tet4:
    return von_mises_impl<4>(e, S, x, grad);
  case ElementType::Tet10:
    return von_mises_impl<10>(e, S, x, grad);
  case ElementType::Hex8:
    return von_mises_impl<8>(e, S, x, grad);
  }
  throw Error("corotated_von_mises: invalid element type");
}

} // namespace flexopt::fem
