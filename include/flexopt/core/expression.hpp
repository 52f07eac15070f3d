#pragma once
/// \file A scalar function of time written as text (`drivers[].value`, `loads.forces[].value`).
///
/// The syntax is muParser's (docs/case-format.md, "Expressions"): numbers, the variable `t`
/// [s], the operators + - * / ^ (power, right-associative), comparisons < <= > >= == !=,
/// && ||, the ternary `c ? a : b`, the functions sin cos tan asin acos atan sinh cosh tanh
/// asinh acosh atanh exp ln log (both natural) log2 log10 sqrt abs sign rint, atan2(y, x),
/// min max sum avg (any number of arguments), and the constants `_pi`, `_e`.
/// Any other name is an error; so are the assignment `=` and comma-separated lists.
#include <memory>
#include <stdexcept>
#include <string>

namespace flexopt {

/// An expression that cannot be used: a syntax error, an unknown name, or a value that is not
/// finite at t = 0. `what()` is a complete message, e.g.
///
///     cannot parse "t <* 2": unexpected operator "*" found at position 3
///         t <* 2
///            ^
///
/// (the second and third lines only when a position is known).
class ExpressionError : public std::runtime_error {
public:
  ExpressionError(std::string text, std::string message, int position);
  const std::string &text() const { return text_; } ///< the expression as given
  /// The first line of what(): what is wrong, with the expression (muParser's words for a
  /// syntax error).
  const std::string &message() const { return message_; }
  int position() const { return position_; } ///< 0-based character, -1 if unknown

private:
  std::string text_, message_;
  int position_;
};

/// A compiled muParser expression in one variable, `t`.
///
/// Copies are independent (each holds its own parser bound to its own `t`), so an Expression
/// may be copied, moved and stored in containers freely (a moved-from Expression may only be
/// assigned to or destroyed). Evaluation changes the internal variable: one Expression object
/// must not be evaluated from two threads at once (give each thread its own copy).
///
/// Derivatives are central differences with one Richardson extrapolation step (the h^2 error
/// term removed), fourth-order accurate:
///   first:  D(h) = (f(t+h) - f(t-h)) / 2h,           f'  = (4 D(h/2) - D(h)) / 3,
///   second: S(h) = (f(t+h) - 2 f(t) + f(t-h)) / h^2,  f'' = (4 S(h/2) - S(h)) / 3,
/// with the fixed steps h = kFirstStep and kSecondStep [s] (the steps actually taken, t + h - t,
/// enter the quotients, so a large t costs only its representation error eps |t| / h). The
/// steps balance the truncation error ~ h^4 f^(5) / 480 (first), h^4 f^(6) / 1440 (second)
/// against the round-off ~ eps |f| / h and ~ eps |f| / h^2 for functions that vary on a time
/// scale of about 1 s. Measured (tests/unit/test_expression.cpp asserts these with a margin of
/// about 10), on 4001 points of t in [-2, 2], as the largest error divided by the largest
/// |exact derivative| there:
///   sin(3t): first 1.8e-13, second 2.0e-11;   t^3: first 1.6e-13, second 6.2e-11;
///   exp(t):  first 1.7e-13, second 7.6e-11;
///   2t^2 - 3t + 1 and 5t - 2: exact to round-off (absolute errors: first 4e-12, second
///   1.2e-9, i.e. ~ eps |f| / h^2).
/// The truncation error grows as the 4th power of the frequency: sin(30t) gives 1.5e-9
/// (first) and 1.3e-7 (second). The round-off grows with |f|: t^3 at t = 1000 has a second
/// derivative good to 1e-5 only. Across a kink or jump (a ternary switching at t0) the
/// derivatives are smeared over |t - t0| < h.
class Expression {
public:
  /// Step h of the first derivative [s] (2^-10, about 1e-3).
  static constexpr double kFirstStep = 1.0 / 1024;
  /// Step h of the second derivative [s] (2^-8, about 4e-3).
  static constexpr double kSecondStep = 1.0 / 256;

  /// The constant 0.
  Expression();
  /// Compiles `text`; throws ExpressionError for a syntax error, a name other than t and the
  /// constants, or a value at t = 0 that is not finite.
  explicit Expression(const std::string &text);
  Expression(const Expression &other);
  Expression(Expression &&other) noexcept;
  Expression &operator=(const Expression &other);
  Expression &operator=(Expression &&other) noexcept;
  ~Expression();

  /// Value at time t.
  double operator()(double t) const;
  /// df/dt at t (see the class comment for the accuracy).
  double derivative(double t) const;
  /// d^2f/dt^2 at t.
  double second_derivative(double t) const;
  /// The expression as given.
  const std::string &text() const;

private:
  struct Impl;
  std::unique_ptr<Impl> impl_; ///< the parser and the variable it is bound to (by address)
};

/// A compiled muParser expression in the coordinates x, y, z [m] of a point (the syntax of
/// Expression; `bodies[].initial.elastic_displacement`). Copies share the parser: evaluate one
/// PointExpression (and its copies) from one thread at a time.
class PointExpression {
public:
  /// Compiles `text`; throws ExpressionError for a syntax error, a name other than x, y, z and
  /// the constants, or a value at the origin that is not finite.
  explicit PointExpression(const std::string &text);
  double operator()(double x, double y, double z) const;
  const std::string &text() const;

private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

} // namespace flexopt
