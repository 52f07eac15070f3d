#pragma once
/// \file A mechanism of rigid and FFRF bodies: coordinates, equations of motion, constraints
/// (joints, drivers, Euler-parameter normalization) and loads, evaluated densely (Eigen,
/// replicated on every rank; docs/theory.md sections 6 and 7).
#include "flexopt/bodies/body.hpp"
#include "flexopt/joints/equation.hpp"

#include <algorithm>
#include <array>
#include <memory>
#include <string>
#include <vector>

namespace flexopt::dynamics {

using bodies::Vec3;
using joints::Matrix;
using joints::Vector;

/// A force [N] (world frame, function of t) at a body point s + S zeta (relative to the body's
/// reference point, body axes; S: the elastic part, empty for rigid bodies).
struct PointForce {
  int body = 0;
  Vec3 s{0, 0, 0};
  joints::Elastic S;
  std::array<Expression, 3> value;
};

class Mechanism {
public:
  std::vector<std::shared_ptr<const bodies::Body>> bodies;
  std::vector<joints::Equation> equations; ///< normalizations, drivers, then joints
  std::vector<PointForce> forces;
  Vec3 gravity{0, 0, 0};

  /// Size of q: the sum of the bodies' coordinate blocks (after finalize()).
  int coordinates() const { return coordinates_; }
  /// Offset of body b's block in q and its size (after finalize()).
  int offset(int b) const { return offsets_[static_cast<std::size_t>(b)]; }
  int size(int b) const { return bodies[static_cast<std::size_t>(b)]->coordinates(); }
  const bodies::Body &body(int b) const { return *bodies[static_cast<std::size_t>(b)]; }
  /// Number of enforced constraint rows (redundant rows excluded).
  int constraints() const { return active_rows_; }
  /// Total rows of all equations, enforced or not.
  int all_rows() const { return all_rows_; }

  /// Lays out the coordinates (body blocks in order), gives every equation and force its
  /// bodies' offsets and elastic sizes (zero elastic parts where unset) and marks every row
  /// enforced; call after filling `bodies`, `equations` and `forces`. Throws flexopt::Error for
  /// an elastic part of the wrong size.
  void finalize();
  /// Finds rows of Phi_q(q, t) that are linear combinations of rows before them (tolerance
  /// `tol` relative to the row norm, modified Gram-Schmidt in equation order) and stops
  /// enforcing them. Returns one line per dropped row: "<owner> row k".
  std::vector<std::string> drop_redundant_rows(const Vector &q, double t, double tol = 1e-9);
  /// Whether row r (over all rows) is enforced.
  bool enforced(int r) const { return enforced_[static_cast<std::size_t>(r)]; }
  /// Row r's (over all rows) number among the enforced rows (its entry in lambda), or -1.
  int enforced_index(int r) const { return enforced_index_[static_cast<std::size_t>(r)]; }
  /// The first row (over all rows) of equation e.
  int first_row(int e) const {
    return static_cast<int>(std::find(row_equation_.begin(), row_equation_.end(), e) -
                            row_equation_.begin());
  }

  /// Enforced constraints: Phi (m) and, if J is non-null, Phi_q (m x n).
  void constraint(const Vector &q, double t, Vector &phi, Matrix *J) const;
  /// Enforced constraints into a Sink (rows numbered among the enforced ones): Phi (m) and the
  /// gradient rows. For the sparse Newton path.
  void constraint(const Vector &q, double t, Vector &phi, joints::Sink &sink) const;
  /// Sum of lambda_k d^2 phi_k/dq^2 over the enforced rows into a Sink (body blocks).
  void add_constraint_hessian(const Vector &q, double t, const Vector &lambda,
                              joints::Sink &sink) const;
  /// The dynamics residual r (n) and its per-body diagonal blocks of K, C, M (the equations
  /// of motion couple bodies only through the constraints).
  void dynamics_blocks(const Vector &q, const Vector &v, const Vector &a, double t, Vector &r,
                       std::vector<Matrix> &K, std::vector<Matrix> &C,
                       std::vector<Matrix> &M) const;
  /// The dynamics residual r alone (no derivatives): for Newton iterations on a kept matrix.
  void dynamics_residual(const Vector &q, const Vector &v, const Vector &a, double t,
                         Vector &r) const;
  /// Every row (enforced or not): for the violation monitor and messages.
  void all_constraint_values(const Vector &q, double t, Vector &phi) const;
  /// H += d(Phi_q^T lambda)/dq for the enforced rows.
  void add_constraint_hessian(const Vector &q, double t, const Vector &lambda, Matrix &H) const;
  /// Enforced rows: Phi_t, Phi_tt and (Phi_q)_t v.
  void constraint_time_terms(const Vector &q, const Vector &v, double t, Vector &phi_t,
                             Vector &phi_tt, Vector &phi_qt_v) const;
  /// (Phi_q v)_q v for the enforced rows (row by row: v^T H_i v).
  Vector constraint_convective(const Vector &q, const Vector &v, double t) const;

  /// The equations of motion without the constraint forces:
  ///   r = M(q) a + Q_v(q, v) - Q_ext(q, t)
  /// and its derivatives K = dr/dq, C = dr/dv, M = dr/da (each may be null).
  void dynamics(const Vector &q, const Vector &v, const Vector &a, double t, Vector &r, Matrix *K,
                Matrix *C, Matrix *M) const;
  /// Kinetic energy plus strain energy plus the potential of gravity (the interface forces are
  /// not conservative and are not included).
  double energy(const Vector &q, const Vector &v) const;

  /// Owner name and row within the owner of row r (over all rows).
  std::string describe_row(int r) const;

private:
  /// The residual r and, for non-null K, C, M (sized by the caller), the body blocks.
  void evaluate_dynamics(const Vector &q, const Vector &v, const Vector &a, double t, Vector &r,
                         std::vector<Matrix> *K, std::vector<Matrix> *C,
                         std::vector<Matrix> *M) const;
  /// A(p_b) of every body at q, into a reused buffer: the equations share them.
  const bodies::Mat3 *rotations(const Vector &q) const;

  std::vector<int> offsets_;
  mutable std::vector<bodies::Mat3> rotations_;
  int coordinates_ = 0;
  std::vector<char> enforced_;
  std::vector<int> enforced_index_; ///< per row: its number among the enforced rows, or -1
  std::vector<int> row_equation_, row_index_; ///< per row: equation and row within it
  int active_rows_ = 0, all_rows_ = 0;
};

} // namespace flexopt::dynamics
