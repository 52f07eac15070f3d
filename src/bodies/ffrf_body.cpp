#include "flexopt/bodies/ffrf_body.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"

namespace flexopt::bodies {

namespace {

constexpr int kMaxElastic = kMaxBodyCoordinates - 7;
// Fixed-capacity work arrays: an evaluation allocates nothing.
using VecN = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxElastic, 1>;
using Mat3N = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kMaxElastic>;
using Mat9N = Eigen::Matrix<double, 9, Eigen::Dynamic, Eigen::ColMajor, 9, kMaxElastic>;
using MatN3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::ColMajor, kMaxElastic, 3>;
using MatN6 = Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::ColMajor, kMaxElastic, 6>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using ConstMap = Eigen::Map<const Matrix>;
using VecMap = Eigen::Map<Eigen::VectorXd>;
using ConstMat3Map = Eigen::Map<const Mat3>;

/// vec(|w|^2 I - w w^T): vec(B) . this = tr(B) |w|^2 - w^T B w.
Vec9 centrifugal_weights(const Vec3 &w) {
  Vec9 c;
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) c(3 * j + i) = (i == j ? w.squaredNorm() : 0.0) - w(i) * w(j);
  return c;
}

Vec9 vec(const Mat3 &B) {
  return Eigen::Map<const Vec9>(B.data());
}

/// The frame's kinematics at (q, v, a) (docs/theory.md section 7.3): rotation A(p), Gbar(p),
/// omega = 2 Gbar p', omega' = 2 Gbar p'', rho = r'' - g and rho_b = A^T rho.
struct FrameKinematics {
  Mat3 A;
  Mat34 G;
  Vec3 w, wd, rho, rb;
  FrameKinematics(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                  const Vec3 &gravity) {
    const Vec4 p = q.segment<4>(3);
    A = rotation(p);
    G = gbar_matrix(p);
    w = 2 * G * v.segment<4>(3);
    wd = 2 * G * a.segment<4>(3);
    rho = a.head<3>() - gravity;
    rb = A.transpose() * rho;
  }
};

/// An FFRF body's model and its invariants packed for matrix-vector products (FfrfBody's
/// members; docs/theory.md section 7.3), as the residual's parts read them.
struct PackedInvariants {
  const FfrfModel &model;
  const Matrix &mzz, &s2_by_k, &s2_by_l, &g_by_k, &g_by_l, &s1;
  bool stiffening;
};

/// The quantities of docs/theory.md section 7.3 at (q, v, a) that the residual and its
/// Jacobians share: the frame's kinematics, d, C_k (vec C_k in Cv, c_k in Cm), S, J, P, h_k
/// (Hm), D zeta', D zeta'', s_c(omega) with its derivative, (K_r + sum_c s_c G_c) zeta and the
/// G_c zeta; then the residual's own yr, F_w, tr P I - P^T and vec(|w|^2 I - w w^T).
struct ResidualTerms {
  int n;
  FrameKinematics f;
  Vec4 p, vp, ap;
  Vec3 d;
  Mat9N Cv;
  Mat3N Cm, Hm;
  Mat3 S, J, P;
  Vec3 Dzd, Dzdd;
  Eigen::Matrix<double, 6, 3> ds;
  Eigen::Matrix<double, 6, 1> s;
  VecN Kz;
  MatN6 Gz;
  Vec3 yr, Fw;
  Mat3 Pt;
  Vec9 cw;
  ResidualTerms(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                const Vec3 &gravity, int n_)
      : n(n_), f(q, v, a, gravity), p(q.segment<4>(3)), vp(v.segment<4>(3)), ap(a.segment<4>(3)) {}
};

/// J, h_k, P, D zeta', D zeta'', s_c(omega) and (K_r + sum_c s_c G_c) zeta from C_k and S
/// (docs/theory.md section 7.3).
void shared_terms(const PackedInvariants &pk, const ConstVectorRef &q, const ConstVectorRef &v,
                  const ConstVectorRef &a, ResidualTerms &t) {
  const int n = t.n;
  const auto &inv = pk.model.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Vec3 &w = t.f.w;
  const auto z = q.tail(n), zd = v.tail(n), zdd = a.tail(n);
  t.J = t.S.trace() * I3 - t.S;
  t.Hm.resize(3, n);
  VecMap(t.Hm.data(), 3 * n).noalias() = ConstMap(pk.g_by_k.data(), 3 * n, n) * zd;
  Vec9 pv;
  pv.noalias() = t.Cv * zd;
  t.P = ConstMat3Map(pv.data());
  t.Dzd = inv.D * zd;
  t.Dzdd = inv.D * zdd;
  t.s = reduce::centrifugal_coefficients(w, &t.ds);
  // (K_r + sum_c s_c G_c) zeta and the columns G_c zeta (for the omega derivatives).
  t.Kz.resize(n);
  t.Kz.noalias() = pk.model.stiffness * z;
  if (pk.stiffening) {
    t.Gz.resize(n, 6);
    for (int c = 0; c < 6; ++c)
      t.Gz.col(c).noalias() = pk.model.geometric[static_cast<std::size_t>(c)] * z;
    t.Kz.noalias() += t.Gz * t.s;
  }
}

/// res = [F_r; 2 Gbar(p)^T F_w; F_z] (docs/theory.md section 7.3, "Virtual work").
void residual_forces(const PackedInvariants &pk, const ConstVectorRef &v, const ConstVectorRef &a,
                     ResidualTerms &t, Eigen::Ref<Vector> res) {
  const int n = t.n;
  const auto &inv = pk.model.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Mat3 &A = t.f.A;
  const Mat34 &G = t.f.G;
  const Vec3 &w = t.f.w, &wd = t.f.wd, &rho = t.f.rho, &rb = t.f.rb, &d = t.d;
  const auto zd = v.tail(n), zdd = a.tail(n);
  t.yr = wd.cross(d) + t.Dzdd + w.cross(w.cross(d)) + 2 * w.cross(t.Dzd);
  const Vec3 Fr = inv.mass * rho + A * t.yr;
  t.Pt = t.P.trace() * I3 - t.P.transpose();
  t.Fw = d.cross(rb) + t.J * wd + t.Cm * zdd + w.cross(t.J * w) + 2 * t.Pt * w;
  res.head<3>() = Fr;
  res.segment<4>(3) = 2 * G.transpose() * t.Fw;
  // F_z, with -[tr C_k |w|^2 - w^T C_k w]_k + 2 [w . h_k]_k as products with vec C and Hm.
  auto Fz = res.tail(n);
  t.cw = centrifugal_weights(w);
  Fz.noalias() = inv.D.transpose() * rb;
  Fz.noalias() += t.Cm.transpose() * wd;
  Fz.noalias() += pk.mzz * zdd;
  Fz += t.Kz;
  Fz.noalias() += pk.model.damping * zd;
  Fz.noalias() -= t.Cv.transpose() * t.cw;
  Fz.noalias() += 2 * (t.Hm.transpose() * w);
}

/// M = d res / d a (docs/theory.md section 7.3, "Jacobians"): symmetric.
void mass_jacobian(const PackedInvariants &pk, const ResidualTerms &t, Matrix &M) {
  const int n = t.n, N = 7 + n;
  const auto &inv = pk.model.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Mat3 &A = t.f.A;
  const Mat34 &G = t.f.G;
  M.setZero(N, N);
  M.block<3, 3>(0, 0) = inv.mass * I3;
  M.block<3, 4>(0, 3) = -2 * A * skew(t.d) * G;
  M.block(0, 7, 3, n) = A * inv.D;
  M.block<4, 3>(3, 0) = 2 * G.transpose() * skew(t.d) * A.transpose();
  M.block<4, 4>(3, 3) = 4 * G.transpose() * t.J * G;
  M.block(3, 7, 4, n) = 2 * G.transpose() * t.Cm;
  M.block(7, 0, n, 3) = inv.D.transpose() * A.transpose();
  M.block(7, 3, n, 4) = 2 * t.Cm.transpose() * G;
  M.block(7, 7, n, n) = pk.mzz;
}

/// What K and C share (docs/theory.md section 7.3, "Jacobians"): d omega / dp, d omega / dv_p,
/// d omega' / dp, d rho_b / dp, and d yr, d F_w, d F_z with respect to omega.
struct OmegaDerivatives {
  Mat34 Wp, Wv, Ap, Rp;
  Mat3 Yw, Ww;
  MatN3 Fzw;

  OmegaDerivatives(const PackedInvariants &pk, const ResidualTerms &t)
      : Wp(-2 * gbar_matrix(t.vp)), Wv(2 * t.f.G), Ap(-2 * gbar_matrix(t.ap)),
        Rp(rotate_transpose_jacobian(t.p, t.f.rho)) {
    const int n = t.n;
    const Mat3 I3 = Mat3::Identity();
    const Vec3 &w = t.f.w, &d = t.d;
    // d yr / d omega, d F_w / d omega, d F_z / d omega.
    Yw = w.dot(d) * I3 + w * d.transpose() - 2 * d * w.transpose() - 2 * skew(t.Dzd);
    Ww = -skew(t.J * w) + skew(w) * t.J + 2 * t.Pt;
    Fzw.resize(n, 3);
    for (int k = 0; k < n; ++k) {
      const ConstMat3Map c(t.Cv.col(k).data());
      Fzw.row(k) = -(2 * c.trace() * w.transpose() - w.transpose() * (c + c.transpose())) +
                   2 * t.Hm.col(k).transpose();
    }
    if (pk.stiffening) Fzw.noalias() += t.Gz * t.ds;
  }
};

/// Row block p of K: 2 Gbar^T d F_w / d q (docs/theory.md section 7.3, "Jacobians").
void stiffness_jacobian_p(const PackedInvariants &pk, const ConstVectorRef &q,
                          const ConstVectorRef &v, const ConstVectorRef &a, const ResidualTerms &t,
                          const OmegaDerivatives &o, Matrix &K) {
  const int n = t.n;
  const auto &inv = pk.model.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Mat34 &G = t.f.G;
  const Vec3 &w = t.f.w, &wd = t.f.wd, &rb = t.f.rb, &d = t.d;
  const auto z = q.tail(n), zd = v.tail(n), zdd = a.tail(n);
  // Row block p: 2 Gbar^T F_w. d F_w / d zeta_l with dJ_l = tr(S_l) I - S_l,
  // S_l = S1[l] + S1[l]^T + Q_l + Q_l^T, Q_l = sum_k zeta_k S2[l][k],
  // P_l = sum_k zeta'_k S2[l][k], gz_l = sum_k zeta''_k g_lk.
  const Mat34 Fwp = skew(d) * o.Rp + t.J * o.Ap + o.Ww * o.Wp;
  Mat9N Q(9, n), Pl(9, n);
  Mat3N gz(3, n), Fwz(3, n);
  const ConstMap by_l(pk.s2_by_l.data(), 9 * n, n);
  VecMap(Q.data(), 9 * n).noalias() = by_l * z;
  VecMap(Pl.data(), 9 * n).noalias() = by_l * zd;
  VecMap(gz.data(), 3 * n).noalias() = ConstMap(pk.g_by_l.data(), 3 * n, n) * zdd;
  const Mat3 srb = skew(rb);
  for (int l = 0; l < n; ++l) {
    const ConstMat3Map Ql(Q.col(l).data()), Pll(Pl.col(l).data()), S1l(pk.s1.col(l).data());
    const Mat3 Sl = S1l + S1l.transpose() + Ql + Ql.transpose();
    const Mat3 dJ = Sl.trace() * I3 - Sl;
    Fwz.col(l) = -srb * inv.D.col(l) + dJ * wd + gz.col(l) + w.cross(dJ * w) +
                 2 * (Pll.trace() * I3 - Pll.transpose()) * w;
  }
  K.block<4, 4>(3, 3) = 2 * gbar_transpose_matrix(t.Fw) + 2 * G.transpose() * Fwp;
  K.block(3, 7, 4, n) = 2 * G.transpose() * Fwz;
}

/// K = d res / d q (docs/theory.md section 7.3, "Jacobians").
void stiffness_jacobian(const PackedInvariants &pk, const ConstVectorRef &q,
                        const ConstVectorRef &v, const ConstVectorRef &a, const ResidualTerms &t,
                        const OmegaDerivatives &o, Matrix &K) {
  const int n = t.n, N = 7 + n;
  const auto &inv = pk.model.invariants;
  const Mat3 &A = t.f.A;
  const Vec3 &w = t.f.w, &wd = t.f.wd;
  K.setZero(N, N);
  // Row block r.
  K.block<3, 4>(0, 3) = rotate_jacobian(t.p, t.yr) + A * (-skew(t.d) * o.Ap + o.Yw * o.Wp);
  K.block(0, 7, 3, n) = A * (skew(wd) + skew(w) * skew(w)) * inv.D;
  stiffness_jacobian_p(pk, q, v, a, t, o, K);
  // Row block zeta: K_zz = K_r + sum_c s_c G_c
  //   + [g_lk . w' - (tr S2[l][k] |w|^2 - w^T S2[l][k] w)]_kl.
  K.block(7, 3, n, 4) = inv.D.transpose() * o.Rp + t.Cm.transpose() * o.Ap + o.Fzw * o.Wp;
  auto Kzz = K.block(7, 7, n, n);
  Kzz = pk.model.stiffness;
  if (pk.stiffening)
    for (int c = 0; c < 6; ++c) Kzz += t.s(c) * pk.model.geometric[static_cast<std::size_t>(c)];
  for (int l = 0; l < n; ++l) {
    Kzz.col(l).noalias() += pk.g_by_k.middleCols(l * n, n).transpose() * wd;
    Kzz.col(l).noalias() -= pk.s2_by_k.middleCols(l * n, n).transpose() * t.cw;
  }
}

/// C = d res / d v (docs/theory.md section 7.3, "Jacobians").
void damping_jacobian(const PackedInvariants &pk, const ResidualTerms &t, const OmegaDerivatives &o,
                      Matrix &C) {
  const int n = t.n, N = 7 + n;
  const auto &inv = pk.model.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Mat3 &A = t.f.A;
  const Mat34 &G = t.f.G;
  const Vec3 &w = t.f.w;
  C.setZero(N, N);
  C.block<3, 4>(0, 3) = A * o.Yw * o.Wv;
  C.block(0, 7, 3, n) = 2 * A * skew(w) * inv.D;
  Mat3N Fwzd(3, n);
  for (int k = 0; k < n; ++k) {
    const ConstMat3Map c(t.Cv.col(k).data());
    Fwzd.col(k) = 2 * (c.trace() * I3 - c.transpose()) * w;
  }
  C.block<4, 4>(3, 3) = 2 * G.transpose() * o.Ww * o.Wv;
  C.block(3, 7, 4, n) = 2 * G.transpose() * Fwzd;
  C.block(7, 3, n, 4) = o.Fzw * o.Wv;
  // C_zz = C_d + [2 w . g_lk]_kl.
  auto Czz = C.block(7, 7, n, n);
  Czz = pk.model.damping;
  for (int l = 0; l < n; ++l)
    Czz.col(l).noalias() += 2 * (pk.g_by_k.middleCols(l * n, n).transpose() * w);
}

} // namespace

FfrfBody::FfrfBody(std::string name, FfrfModel model)
    : Body(std::move(name)), model_(std::move(model)) {
  const auto &inv = model_.invariants;
  n_ = inv.modes();
  if (7 + n_ > kMaxBodyCoordinates)
    throw Error("FFRF body '" + this->name() + "': " + std::to_string(n_) +
                    " elastic coordinates exceed the limit of " +
                    std::to_string(kMaxBodyCoordinates - 7) + " per body",
                true);
  if (model_.stiffness.rows() != n_ || model_.stiffness.cols() != n_)
    throw Error("FFRF body '" + this->name() + "': reduced stiffness of the wrong size", true);
  if (model_.damping.size() == 0) model_.damping = Matrix::Zero(n_, n_);
  if (!model_.geometric.empty() && model_.geometric.size() != 6)
    throw Error("FFRF body '" + this->name() + "': 6 geometric stiffness matrices expected", true);
  const int n = n_;
  mzz_.resize(n, n);
  s2_by_k_.resize(9, n * n);
  s2_by_l_.resize(9, n * n);
  g_by_k_.resize(3, n * n);
  g_by_l_.resize(3, n * n);
  for (int l = 0; l < n; ++l)
    for (int k = 0; k < n; ++k) {
      const Mat3 &S = inv.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)];
      s2_by_k_.col(l * n + k) = vec(S);
      s2_by_l_.col(k * n + l) = vec(S);
      g_by_k_.col(l * n + k) = axial(S);
      g_by_l_.col(k * n + l) = axial(S);
      mzz_(l, k) = S.trace();
    }
  s1_.resize(9, n);
  s1t_.resize(9, n);
  a1_.resize(3, n);
  for (int k = 0; k < n; ++k) {
    const Mat3 &S = inv.S1[static_cast<std::size_t>(k)];
    s1_.col(k) = vec(S);
    s1t_.col(k) = vec(S.transpose());
    a1_.col(k) = axial(S);
  }
}

void FfrfBody::model_cotangent(const ConstVectorRef &q, const ConstVectorRef &v,
                               const ConstVectorRef &a, const Vec3 &gravity,
                               const ConstVectorRef &mu, FfrfModel &bar) const {
  const int n = n_;
  auto &ib = bar.invariants;
  if (ib.D.cols() != n) {
    ib = reduce::FfrfInvariants{};
    ib.D.setZero(3, n);
    ib.S1.assign(static_cast<std::size_t>(n), Mat3::Zero());
    ib.S2.assign(static_cast<std::size_t>(n),
                 std::vector<Mat3>(static_cast<std::size_t>(n), Mat3::Zero()));
    bar.stiffness.setZero(n, n);
    bar.damping.setZero(n, n);
    bar.geometric.assign(stiffening() ? 6 : 0, Matrix::Zero(n, n));
  }
  const Mat3 I3 = Mat3::Identity();
  const FrameKinematics f(q, v, a, gravity);
  const Mat3 &A = f.A;
  const Mat34 &G = f.G;
  const Vec3 &w = f.w, &wd = f.wd, &rho = f.rho, &rb = f.rb;
  const auto z = q.tail(n), zd = v.tail(n), zdd = a.tail(n);
  // The multipliers of F_r (in the frame: mb), of F_w (mw = 2 Gbar mu_p) and of F_z.
  const Vec3 mr = mu.head<3>(), mb = A.transpose() * mr, mw = 2 * G * mu.segment<4>(3);
  const auto mz = mu.tail(n);
  ib.mass += mr.dot(rho);
  // d = d0 + D zeta: in F_r (A (w' x d + w x (w x d))) and F_w (d x rb).
  const Vec3 dbar = mb.cross(wd) + mb.dot(w) * w - w.squaredNorm() * mb + rb.cross(mw);
  ib.d0 += dbar;
  ib.D.noalias() += dbar * z.transpose();
  // D itself: A (D zeta'' + 2 w x D zeta') in F_r, D^T rb in F_z.
  ib.D.noalias() += mb * zdd.transpose() + 2 * mb.cross(w) * zd.transpose() + rb * mz.transpose();
  // J = tr(S) I - S: J w' + w x J w in F_w; S = S0 + sum_k z_k (S1_k + S1_k^T) + sum_kl z_k z_l
  // S2_kl.
  const Mat3 Jbar = mw * wd.transpose() + mw.cross(w) * w.transpose();
  const Mat3 Sbar = Jbar.trace() * I3 - Jbar;
  ib.S0 += Sbar;
  for (int k = 0; k < n; ++k) {
    ib.S1[static_cast<std::size_t>(k)] += z(k) * (Sbar + Sbar.transpose());
    for (int l = 0; l < n; ++l)
      ib.S2[static_cast<std::size_t>(k)][static_cast<std::size_t>(l)] += z(k) * z(l) * Sbar;
  }
  // C_k = S1_k + sum_l z_l S2_lk: axial(C_k) z''_k and 2 (tr P I - P^T) w (P = sum_k z'_k C_k)
  // in F_w; axial(C_k) . w' and -(tr C_k |w|^2 - w^T C_k w) in F_z. (a . axial(B) = <skew(a)^T,
  // B>.)
  const Mat3 Pbar = 2 * mw.dot(w) * I3 - 2 * w * mw.transpose();
  const Mat3 cw = w.squaredNorm() * I3 - w * w.transpose();
  const Mat3 skw = skew(mw).transpose(), skwd = skew(wd).transpose(), skww = skew(w).transpose();
  for (int k = 0; k < n; ++k) {
    const Mat3 Cbar = zdd(k) * skw + zd(k) * Pbar + mz(k) * skwd - mz(k) * cw;
    ib.S1[static_cast<std::size_t>(k)] += Cbar;
    for (int l = 0; l < n; ++l) {
      Mat3 &S2 = ib.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)];
      S2 += z(l) * Cbar;
      // 2 w . h_k, h_k = sum_l z'_l axial(S2_lk); M_zz(l, k) = tr S2_lk.
      S2 += 2 * mz(k) * zd(l) * skww + mz(l) * zdd(k) * I3;
    }
  }
  bar.stiffness.noalias() += mz * z.transpose();
  bar.damping.noalias() += mz * zd.transpose();
  if (stiffening()) {
    const Eigen::Matrix<double, 6, 1> sc = reduce::centrifugal_coefficients(w);
    for (int c = 0; c < 6; ++c)
      bar.geometric[static_cast<std::size_t>(c)].noalias() += sc(c) * (mz * z.transpose());
  }
}

void FfrfBody::couplings(const ConstVectorRef &z, Mat9N &Cv, Mat3N &Cm, Mat3 &S) const {
  const int n = n_;
  Cv.resize(9, n);
  Cm.resize(3, n);
  // Linear in zeta: vec C = vec S1 + (S2 as 9n x n) zeta, and likewise the axial vectors.
  VecMap cv(Cv.data(), 9 * n), cm(Cm.data(), 3 * n);
  cv.noalias() = ConstMap(s2_by_k_.data(), 9 * n, n) * z;
  cv += Eigen::Map<const Eigen::VectorXd>(s1_.data(), 9 * n);
  cm.noalias() = ConstMap(g_by_k_.data(), 3 * n, n) * z;
  cm += Eigen::Map<const Eigen::VectorXd>(a1_.data(), 3 * n);
  // sum_kl zeta_k zeta_l S2[l][k] = sum_k zeta_k (C_k - S1[k]).
  Vec9 s = vec(model_.invariants.S0);
  s.noalias() += s1t_ * z;
  s.noalias() += Cv * z;
  S = ConstMat3Map(s.data());
}

void FfrfBody::residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                        const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                        Matrix *M) const {
  const int n = n_;
  const PackedInvariants pk{model_, mzz_, s2_by_k_, s2_by_l_, g_by_k_, g_by_l_, s1_, stiffening()};
  ResidualTerms t(q, v, a, gravity, n);
  const auto z = q.tail(n);
  t.d = model_.invariants.first_moment(z);
  // C_k = S1[k] + sum_l zeta_l S2[l][k] (sum m u_i Psi_jk^T), c_k = axial(C_k),
  // P = sum_k zeta'_k C_k, h_k = sum_l zeta'_l g_lk.
  couplings(z, t.Cv, t.Cm, t.S);
  shared_terms(pk, q, v, a, t);
  residual_forces(pk, v, a, t, res);
  if (M) mass_jacobian(pk, t, *M);
  if (!K && !C) return;
  const OmegaDerivatives o(pk, t);
  if (K) stiffness_jacobian(pk, q, v, a, t, o, *K);
  if (C) damping_jacobian(pk, t, o, *C);
}

double FfrfBody::energy(const ConstVectorRef &q, const ConstVectorRef &v,
                        const Vec3 &gravity) const {
  const int n = n_;
  const auto &inv = model_.invariants;
  const Vec4 p = q.segment<4>(3);
  const auto z = q.tail(n), zd = v.tail(n);
  const Mat3 A = rotation(p);
  const Vec3 w = 2 * gbar_matrix(p) * v.segment<4>(3);
  const Vec3 rd = v.head<3>();
  const Vec3 d = inv.first_moment(z);
  Mat9N Cv;
  Mat3N Cm;
  Mat3 S;
  couplings(z, Cv, Cm, S);
  const Mat3 J = S.trace() * Mat3::Identity() - S;
  const double T = 0.5 * (inv.mass * rd.squaredNorm() + 2 * rd.dot(A * (w.cross(d) + inv.D * zd)) +
                          w.dot(J * w) + 2 * w.dot(Cm * zd) + zd.dot(mzz_ * zd));
  const double U = 0.5 * z.dot(model_.stiffness * z);
  return T + U - gravity.dot(inv.mass * q.head<3>() + A * d);
}

} // namespace flexopt::bodies
