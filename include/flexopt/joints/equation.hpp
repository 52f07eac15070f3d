#pragma once
/// \file Kinematic constraint equations between bodies (docs/theory.md sections 6.3 and 7.4).
///
/// Every joint and driver is a list of primitive equations on two attachments (a body or the
/// ground). Each primitive gives its value phi(q, t), its gradient d phi/dq, the Hessian
/// contraction sum_i lambda_i d^2 phi_i/dq^2 (the derivative of Phi_q^T lambda that Newton
/// needs), and the time derivatives used for consistent initial conditions.
///
/// Coordinates: body b owns the block q[o_b .. o_b + 7 + n_b) = [r, p, zeta] (reference point,
/// Euler parameters, n_b elastic coordinates; n_b = 0 for a rigid body). Attachment points and
/// vectors are affine in the body's elastic coordinates: a point s + S zeta relative to the
/// body's reference point and a vector u + U zeta, in body axes (S, U: 3 x n_b; for a flexible
/// body they carry the interface node's elastic translation and linearized rotation). On the
/// ground (body = -1) both are world quantities.
#include "flexopt/bodies/body.hpp"
#include "flexopt/core/expression.hpp"

#include <Eigen/Dense>
#include <memory>
#include <string>

namespace flexopt::joints {

using bodies::Mat3;
using bodies::Mat4;
using bodies::Vec3;
using bodies::Vec4;
using Vector = Eigen::VectorXd;
using Matrix = Eigen::MatrixXd;
using Elastic = Eigen::Matrix3Xd;

/// A gradient row over one body's coordinates (fixed capacity: no heap allocation).
using Row =
    Eigen::Matrix<double, 1, Eigen::Dynamic, Eigen::RowMajor, 1, bodies::kMaxBodyCoordinates>;
/// The 3 x (7 + n_b) Jacobian of a body point or vector.
using Jacobian =
    Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, bodies::kMaxBodyCoordinates>;

/// A body as the sinks see it: its index and the offset of its coordinates in q.
struct BodyRef {
  int index = -1;
  int offset = 0;
};

/// Where gradients and Hessian contributions go: a dense matrix, or the blocks of a sparse one.
class Sink {
public:
  virtual ~Sink() = default;
  /// Phi_q(row, body's columns) += g.
  virtual void add_row(int row, const BodyRef &body, const Row &g) = 0;
  /// H(rows of body bi from i0, columns of body bj from j0) += B.
  virtual void add_block(const BodyRef &bi, const BodyRef &bj, int i0, int j0,
                         const Eigen::Ref<const Matrix> &B) = 0;
  /// H(body bi, body bj) += scale X^T Y (X: 3 x size of bi, Y: 3 x size of bj).
  virtual void add_product(const BodyRef &bi, const BodyRef &bj, double scale, const Jacobian &X,
                           const Jacobian &Y) = 0;
};

/// A Sink writing into dense matrices J (rows x n) and H (n x n); either may be null.
class DenseSink : public Sink {
public:
  DenseSink(Matrix *J, Matrix *H) : J_(J), H_(H) {}
  void add_row(int row, const BodyRef &b, const Row &g) override {
    J_->block(row, b.offset, 1, g.size()) += g;
  }
  void add_block(const BodyRef &bi, const BodyRef &bj, int i0, int j0,
                 const Eigen::Ref<const Matrix> &B) override {
    H_->block(bi.offset + i0, bj.offset + j0, B.rows(), B.cols()) += B;
  }
  void add_product(const BodyRef &bi, const BodyRef &bj, double scale, const Jacobian &X,
                   const Jacobian &Y) override {
    // Inner dimension 3: a coefficient-wise product (the blocked GEMM only adds packing).
    H_->block(bi.offset, bj.offset, X.cols(), Y.cols()).noalias() +=
        (scale * X.transpose()).lazyProduct(Y);
  }

private:
  Matrix *J_, *H_;
};

/// A primitive constraint equation (or the 3 equations of a point coincidence).
struct Equation {
  enum class Kind {
    Coincide,          ///< x_a(s_a) - x_b(s_b) = 0                          (3 rows)
    Perpendicular,     ///< u_a . v_b - c = 0                                (1 row)
    PointOnPlane,      ///< u_a . (x_b(s_b) - x_a(s_a)) - c = 0              (1 row)
    Normalize,         ///< (p_a . p_a - 1) / 2 = 0                          (1 row)
    RotationDriver,    ///< u_a(t) . v_b - c = 0, u_a(t) = sin f(t) u1 - cos f(t) u2 (1 row)
    TranslationDriver, ///< u_a . (x_b - x_a) - c - f(t) = 0               (1 row)
    ElasticCoordinate  ///< zeta_a[coordinate] = 0: holds one elastic coordinate of body a
                       ///< (the plan's rigid pre-run, docs/theory.md section 12.1)  (1 row)
  };
  Kind kind = Kind::Coincide;
  int a = -1, b = -1;            ///< bodies (-1: ground)
  Vec3 sa{0, 0, 0}, sb{0, 0, 0}; ///< attachment points
  Vec3 ua{0, 0, 0}, vb{0, 0, 0}; ///< vectors (RotationDriver: ua = u1, ua2 = u2)
  Vec3 ua2{0, 0, 0};
  /// Elastic parts of the points and vectors (3 x n_a or 3 x n_b; empty for rigid bodies;
  /// Mechanism::finalize() fills unset ones of flexible bodies with zeros).
  Elastic Sa, Sb, Ua, Vb, Ua2;
  /// Coordinate offsets of bodies a and b in q (Mechanism::finalize() sets them).
  int oa = 0, ob = 0;
  /// Elastic coordinates of bodies a and b (Mechanism::finalize() sets them).
  int na = 0, nb = 0;
  double c = 0;
  int coordinate = 0; ///< ElasticCoordinate: which of body a's elastic coordinates
  std::shared_ptr<const Expression> driver; ///< f(t) for drivers
  std::string owner;                        ///< joint / driver / body name, for messages
  int row_in_owner = 0;                     ///< index of the first row within its owner

  int rows() const { return kind == Kind::Coincide ? 3 : 1; }
  /// phi (rows()) into out and, if J is non-null, its gradient rows (numbered from `row`) into
  /// J: one pass, sharing the rotation matrices and attachment points between the two.
  /// `rotations`: A(p_b) of every body b (indexed by body), precomputed for all equations by
  /// the caller, or null (computed here).
  void evaluate(const Vector &q, double t, double *out, Sink *J, int row,
                const Mat3 *rotations = nullptr) const;
  /// phi (rows()) into out.
  void value(const Vector &q, double t, double *out) const { evaluate(q, t, out, nullptr, 0); }
  /// Rows of Phi_q into J (rows() x n, starting at row `row`; other columns untouched).
  void gradient(const Vector &q, double t, Matrix &J, int row) const {
    DenseSink sink(&J, nullptr);
    gradient(q, t, sink, row);
  }
  void gradient(const Vector &q, double t, Sink &sink, int row) const;
  /// H += sum_i lambda_i d^2 phi_i / dq^2 (n x n).
  void add_hessian(const Vector &q, double t, const double *lambda, Matrix &H) const {
    DenseSink sink(nullptr, &H);
    add_hessian(q, t, lambda, sink);
  }
  void add_hessian(const Vector &q, double t, const double *lambda, Sink &sink,
                   const Mat3 *rotations = nullptr) const;
  /// d phi/dt, d^2 phi/dt^2 and (d Phi_q/dt) v (time enters through drivers only).
  void time_derivatives(const Vector &q, const Vector &v, double t, double *phi_t, double *phi_tt,
                        double *phi_qt_v) const;
};

/// A body point s + S zeta (S empty for a rigid body): its world position, its 3 x (7 + n)
/// Jacobian [I, D(p, s + S zeta), A S], and the Hessian blocks of w . x (d^2/dp^2 = K(s + S
/// zeta, w); d^2/dp dzeta_l = D(p, S_l)^T w; no r or zeta-zeta terms). q_b is the body's block.
Vec3 anchor_position(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S);
Jacobian anchor_jacobian(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S);
/// The two nonzero Hessian blocks of w . x(q_b): pp (4 x 4) and p-zeta (4 x n).
void anchor_hessian(const Eigen::Ref<const Vector> &q_b, const Vec3 &s, const Elastic &S,
                    const Vec3 &w, Mat4 &pp, Eigen::Matrix<double, 4, Eigen::Dynamic> &pz);

} // namespace flexopt::joints
