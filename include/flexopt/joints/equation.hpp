#pragma once
/// \file Kinematic constraint equations between rigid bodies (docs/theory.md section 6.3).
///
/// Every joint and driver is a list of primitive equations on two attachments (a body or the
/// ground). Each primitive gives its value phi(q, t), its gradient d phi/dq, the Hessian
/// contraction sum_i lambda_i d^2 phi_i/dq^2 (the derivative of Phi_q^T lambda that Newton
/// needs), and the time derivatives used for consistent initial conditions.
///
/// Coordinates: body b owns q[7b .. 7b+7) = [r (centre of mass), p (Euler parameters)].
/// Points are given relative to the centre of mass in body axes (s), vectors in body axes (u);
/// on the ground (body = -1) both are world quantities.
#include "flexopt/bodies/quaternion.hpp"
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

using Row7 = Eigen::Matrix<double, 1, 7>;
using Block7 = Eigen::Matrix<double, 7, 7>;

/// Where gradients and Hessian contributions go: a dense matrix, or the blocks of a sparse one.
class Sink {
public:
  virtual ~Sink() = default;
  /// Phi_q(row, body's 7 columns) += g.
  virtual void add_row(int row, int body, const Row7 &g) = 0;
  /// H(body bi's 7 rows, body bj's 7 columns) += B.
  virtual void add_block(int bi, int bj, const Block7 &B) = 0;
};

/// A Sink writing into dense matrices J (rows x n) and H (n x n); either may be null.
class DenseSink : public Sink {
public:
  DenseSink(Matrix *J, Matrix *H) : J_(J), H_(H) {}
  void add_row(int row, int body, const Row7 &g) override { J_->block<1, 7>(row, 7 * body) += g; }
  void add_block(int bi, int bj, const Block7 &B) override { H_->block<7, 7>(7 * bi, 7 * bj) += B; }

private:
  Matrix *J_, *H_;
};

/// A primitive constraint equation (or the 3 equations of a point coincidence).
struct Equation {
  enum class Kind {
    Coincide,         ///< x_a(s_a) - x_b(s_b) = 0                          (3 rows)
    Perpendicular,    ///< u_a . v_b - c = 0                                (1 row)
    PointOnPlane,     ///< u_a . (x_b(s_b) - x_a(s_a)) - c = 0              (1 row)
    Normalize,        ///< (p_a . p_a - 1) / 2 = 0                          (1 row)
    RotationDriver,   ///< u_a(t) . v_b = 0, u_a(t) = sin f(t) u1 - cos f(t) u2 (1 row)
    TranslationDriver ///< u_a . (x_b - x_a) - c - f(t) = 0                (1 row)
  };
  Kind kind = Kind::Coincide;
  int a = -1, b = -1;            ///< bodies (-1: ground)
  Vec3 sa{0, 0, 0}, sb{0, 0, 0}; ///< attachment points
  Vec3 ua{0, 0, 0}, vb{0, 0, 0}; ///< vectors (RotationDriver: ua = u1, va2 = u2)
  Vec3 ua2{0, 0, 0};
  double c = 0;
  std::shared_ptr<const Expression> driver; ///< f(t) for drivers
  std::string owner;                        ///< joint / driver / body name, for messages
  int row_in_owner = 0;                     ///< index of the first row within its owner

  int rows() const { return kind == Kind::Coincide ? 3 : 1; }
  /// phi (rows()) into out.
  void value(const Vector &q, double t, double *out) const;
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
  void add_hessian(const Vector &q, double t, const double *lambda, Sink &sink) const;
  /// d phi/dt, d^2 phi/dt^2 and (d Phi_q/dt) v (time enters through drivers only).
  void time_derivatives(const Vector &q, const Vector &v, double t, double *phi_t, double *phi_tt,
                        double *phi_qt_v) const;
};

/// World position of attachment point s of body `b` and its 3 x 7 Jacobian block.
Vec3 point_position(const Vector &q, int b, const Vec3 &s);
/// World direction of body vector u.
Vec3 vector_direction(const Vector &q, int b, const Vec3 &u);

} // namespace flexopt::joints
