#include "flexopt/bodies/ffrf_body.hpp"

#include "flexopt/core/error.hpp"
#include "flexopt/reduce/geometric_stiffness.hpp"

namespace flexopt::bodies {

namespace {

using Mat3X = Eigen::Matrix3Xd;

/// d(A(p)^T w)/dp: A(p)^T = A(p*) with p* = (e0, -e).
Mat34 rotate_transpose_jacobian(const Vec4 &p, const Vec3 &w) {
  const Vec4 conj(p(0), -p(1), -p(2), -p(3));
  Mat34 d = rotate_jacobian(conj, w);
  d.rightCols<3>() *= -1;
  return d;
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
  mzz_.resize(n_, n_);
  g_.resize(static_cast<std::size_t>(n_ * n_));
  s2_.resize(static_cast<std::size_t>(n_ * n_));
  for (int l = 0; l < n_; ++l)
    for (int k = 0; k < n_; ++k) {
      const Mat3 &S = inv.S2[static_cast<std::size_t>(l)][static_cast<std::size_t>(k)];
      s2_[static_cast<std::size_t>(l * n_ + k)] = S;
      g_[static_cast<std::size_t>(l * n_ + k)] = axial(S);
      mzz_(l, k) = S.trace();
    }
}

void FfrfBody::couplings(const Vector &z, std::vector<Mat3> &Ck, Eigen::Matrix3Xd &Cm) const {
  const int n = n_;
  Ck.resize(static_cast<std::size_t>(n));
  Cm.resize(3, n);
  for (int k = 0; k < n; ++k) {
    Mat3 c = model_.invariants.S1[static_cast<std::size_t>(k)];
    for (int l = 0; l < n; ++l) c += z(l) * s2_[static_cast<std::size_t>(l * n + k)];
    Ck[static_cast<std::size_t>(k)] = c;
    Cm.col(k) = axial(c);
  }
}

void FfrfBody::residual(const ConstVectorRef &q, const ConstVectorRef &v, const ConstVectorRef &a,
                        const Vec3 &gravity, Eigen::Ref<Vector> res, Matrix *K, Matrix *C,
                        Matrix *M) const {
  const int n = n_;
  const auto &inv = model_.invariants;
  const Mat3 I3 = Mat3::Identity();
  const Vec4 p = q.segment<4>(3), vp = v.segment<4>(3), ap = a.segment<4>(3);
  const Vector z = q.tail(n), zd = v.tail(n), zdd = a.tail(n);
  const Mat3 A = rotation(p);
  const Mat34 G = gbar_matrix(p);
  const Vec3 w = 2 * G * vp, wd = 2 * G * ap;
  const Vec3 rho = a.head<3>() - gravity, rb = A.transpose() * rho;
  const Vec3 d = inv.first_moment(z);
  const Mat3 S = inv.second_moment(z);
  const Mat3 J = S.trace() * I3 - S;
  // C_k = S1[k] + sum_l zeta_l S2[l][k] (sum m u_i Psi_jk^T), c_k = axial(C_k),
  // P = sum_k zeta'_k C_k, h_k = sum_l zeta'_l g_lk.
  std::vector<Mat3> Ck;
  Mat3X Cm, Hm(3, n);
  couplings(z, Ck, Cm);
  Mat3 P = Mat3::Zero();
  for (int k = 0; k < n; ++k) {
    Vec3 h = Vec3::Zero();
    for (int l = 0; l < n; ++l) h += zd(l) * g_[static_cast<std::size_t>(l * n + k)];
    Hm.col(k) = h;
    P += zd(k) * Ck[static_cast<std::size_t>(k)];
  }
  const Vec3 Dzd = inv.D * zd, Dzdd = inv.D * zdd;
  Eigen::Matrix<double, 6, 3> ds;
  const Eigen::Matrix<double, 6, 1> s = reduce::centrifugal_coefficients(w, &ds);
  // K_r + sum_c s_c G_c and the columns G_c zeta (for the omega derivatives).
  Matrix Kg = model_.stiffness, Gz;
  if (stiffening()) {
    Gz.resize(n, 6);
    for (int c = 0; c < 6; ++c) {
      Kg += s(c) * model_.geometric[static_cast<std::size_t>(c)];
      Gz.col(c) = model_.geometric[static_cast<std::size_t>(c)] * z;
    }
  }

  const Vec3 yr = wd.cross(d) + Dzdd + w.cross(w.cross(d)) + 2 * w.cross(Dzd);
  const Vec3 Fr = inv.mass * rho + A * yr;
  const Mat3 Pt = P.trace() * I3 - P.transpose();
  const Vec3 Fw = d.cross(rb) + J * wd + Cm * zdd + w.cross(J * w) + 2 * Pt * w;
  Vector Fz =
      inv.D.transpose() * rb + Cm.transpose() * wd + mzz_ * zdd + Kg * z + model_.damping * zd;
  for (int k = 0; k < n; ++k) {
    const Mat3 &c = Ck[static_cast<std::size_t>(k)];
    Fz(k) += -(c.trace() * w.squaredNorm() - w.dot(c * w)) + 2 * w.dot(Hm.col(k));
  }
  res.head<3>() = Fr;
  res.segment<4>(3) = 2 * G.transpose() * Fw;
  res.tail(n) = Fz;

  const int N = 7 + n;
  if (M) {
    M->setZero(N, N);
    M->block<3, 3>(0, 0) = inv.mass * I3;
    M->block<3, 4>(0, 3) = -2 * A * skew(d) * G;
    M->block(0, 7, 3, n) = A * inv.D;
    M->block<4, 3>(3, 0) = 2 * G.transpose() * skew(d) * A.transpose();
    M->block<4, 4>(3, 3) = 4 * G.transpose() * J * G;
    M->block(3, 7, 4, n) = 2 * G.transpose() * Cm;
    M->block(7, 0, n, 3) = inv.D.transpose() * A.transpose();
    M->block(7, 3, n, 4) = 2 * Cm.transpose() * G;
    M->block(7, 7, n, n) = mzz_;
  }
  if (!K && !C) return;
  const Mat34 Wp = -2 * gbar_matrix(vp), Wv = 2 * G, Ap = -2 * gbar_matrix(ap);
  const Mat34 Rp = rotate_transpose_jacobian(p, rho);
  // d yr / d omega, d F_w / d omega, d F_z / d omega.
  const Mat3 Yw = w.dot(d) * I3 + w * d.transpose() - 2 * d * w.transpose() - 2 * skew(Dzd);
  const Mat3 Ww = -skew(J * w) + skew(w) * J + 2 * Pt;
  Eigen::Matrix<double, Eigen::Dynamic, 3> Fzw(n, 3);
  for (int k = 0; k < n; ++k) {
    const Mat3 &c = Ck[static_cast<std::size_t>(k)];
    Fzw.row(k) = -(2 * c.trace() * w.transpose() - w.transpose() * (c + c.transpose())) +
                 2 * Hm.col(k).transpose();
  }
  if (stiffening()) Fzw += Gz * ds;
  if (K) {
    K->setZero(N, N);
    // Row block r.
    K->block<3, 4>(0, 3) = rotate_jacobian(p, yr) + A * (-skew(d) * Ap + Yw * Wp);
    K->block(0, 7, 3, n) = A * (skew(wd) + skew(w) * skew(w)) * inv.D;
    // Row block p: 2 Gbar^T F_w.
    const Mat34 Fwp = skew(d) * Rp + J * Ap + Ww * Wp;
    Mat3X Fwz(3, n);
    for (int l = 0; l < n; ++l) {
      Mat3 Sl =
          inv.S1[static_cast<std::size_t>(l)] + inv.S1[static_cast<std::size_t>(l)].transpose();
      Mat3 Pl = Mat3::Zero();
      Vec3 gz = Vec3::Zero();
      for (int k = 0; k < n; ++k) {
        const Mat3 &Slk = s2_[static_cast<std::size_t>(l * n + k)];
        Sl += z(k) * (Slk + Slk.transpose());
        Pl += zd(k) * Slk;
        gz += zdd(k) * g_[static_cast<std::size_t>(l * n + k)];
      }
      const Mat3 dJ = Sl.trace() * I3 - Sl;
      Fwz.col(l) = -skew(rb) * inv.D.col(l) + dJ * wd + gz + w.cross(dJ * w) +
                   2 * (Pl.trace() * I3 - Pl.transpose()) * w;
    }
    K->block<4, 4>(3, 3) = 2 * gbar_transpose_matrix(Fw) + 2 * G.transpose() * Fwp;
    K->block(3, 7, 4, n) = 2 * G.transpose() * Fwz;
    // Row block zeta.
    K->block(7, 3, n, 4) = inv.D.transpose() * Rp + Cm.transpose() * Ap + Fzw * Wp;
    Matrix Kzz = Kg;
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l) {
        const Mat3 &Slk = s2_[static_cast<std::size_t>(l * n + k)];
        Kzz(k, l) += g_[static_cast<std::size_t>(l * n + k)].dot(wd) -
                     (Slk.trace() * w.squaredNorm() - w.dot(Slk * w));
      }
    K->block(7, 7, n, n) = Kzz;
  }
  if (C) {
    C->setZero(N, N);
    C->block<3, 4>(0, 3) = A * Yw * Wv;
    C->block(0, 7, 3, n) = 2 * A * skew(w) * inv.D;
    Mat3X Fwzd(3, n);
    for (int k = 0; k < n; ++k) {
      const Mat3 &c = Ck[static_cast<std::size_t>(k)];
      Fwzd.col(k) = 2 * (c.trace() * I3 - c.transpose()) * w;
    }
    C->block<4, 4>(3, 3) = 2 * G.transpose() * Ww * Wv;
    C->block(3, 7, 4, n) = 2 * G.transpose() * Fwzd;
    C->block(7, 3, n, 4) = Fzw * Wv;
    Matrix Czz = model_.damping;
    for (int k = 0; k < n; ++k)
      for (int l = 0; l < n; ++l) Czz(k, l) += 2 * w.dot(g_[static_cast<std::size_t>(l * n + k)]);
    C->block(7, 7, n, n) = Czz;
  }
}

double FfrfBody::energy(const ConstVectorRef &q, const ConstVectorRef &v,
                        const Vec3 &gravity) const {
  const int n = n_;
  const auto &inv = model_.invariants;
  const Vec4 p = q.segment<4>(3);
  const Vector z = q.tail(n), zd = v.tail(n);
  const Mat3 A = rotation(p);
  const Vec3 w = 2 * gbar_matrix(p) * v.segment<4>(3);
  const Vec3 rd = v.head<3>();
  const Vec3 d = inv.first_moment(z);
  const Mat3 S = inv.second_moment(z);
  const Mat3 J = S.trace() * Mat3::Identity() - S;
  std::vector<Mat3> Ck;
  Mat3X Cm;
  couplings(z, Ck, Cm);
  const double T = 0.5 * (inv.mass * rd.squaredNorm() + 2 * rd.dot(A * (w.cross(d) + inv.D * zd)) +
                          w.dot(J * w) + 2 * w.dot(Cm * zd) + zd.dot(mzz_ * zd));
  const double U = 0.5 * z.dot(model_.stiffness * z);
  return T + U - gravity.dot(inv.mass * q.head<3>() + A * d);
}

} // namespace flexopt::bodies
