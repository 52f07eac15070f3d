// Expression: values, derivative accuracy (the figures documented in expression.hpp), copies,
// and parse errors with their positions.
#include "flexopt/core/expression.hpp"

#include <cmath>
#include <functional>
#include <gtest/gtest.h>
#include <numbers>
#include <vector>

using flexopt::Expression;
using flexopt::ExpressionError;

namespace {

/// The error of compiling `text` (fails the test if it compiles).
ExpressionError error_of(const std::string &text) {
  try {
    Expression e(text);
  } catch (const ExpressionError &e) {
    return e;
  }
  ADD_FAILURE() << "'" << text << "' compiled";
  return ExpressionError(text, "", -1);
}

bool contains(const std::string &s, const std::string &part) {
  return s.find(part) != std::string::npos;
}

struct Errors {
  double first = 0, second = 0;             ///< largest absolute errors
  double first_scale = 0, second_scale = 0; ///< largest |exact derivative|
};

/// Largest derivative errors on 4001 points of t in [-2, 2] (the interval of expression.hpp).
Errors derivative_errors(const Expression &f, const std::function<double(double)> &d1,
                         const std::function<double(double)> &d2) {
  Errors e{0, 0, 0, 0};
  for (int i = 0; i <= 4000; ++i) {
    const double t = -2 + i * 1e-3;
    e.first = std::max(e.first, std::abs(f.derivative(t) - d1(t)));
    e.second = std::max(e.second, std::abs(f.second_derivative(t) - d2(t)));
    e.first_scale = std::max(e.first_scale, std::abs(d1(t)));
    e.second_scale = std::max(e.second_scale, std::abs(d2(t)));
  }
  return e;
}

} // namespace

TEST(Expression, Values) {
  EXPECT_EQ(Expression("2*t + 1")(3.0), 7.0);
  EXPECT_EQ(Expression("t^2")(-3.0), 9.0);
  EXPECT_EQ(Expression("-t^2")(3.0), -9.0);   // unary minus binds looser than ^
  EXPECT_EQ(Expression("2^3^2")(0.0), 512.0); // ^ is right-associative
  EXPECT_DOUBLE_EQ(Expression("sin(t) + cos(t) + exp(t) + sqrt(t)")(1.0),
                   std::sin(1.0) + std::cos(1.0) + std::exp(1.0) + 1.0);
  EXPECT_EQ(Expression("_pi")(0.0), std::numbers::pi); // exact, not muParser's 3.141592653589
  EXPECT_EQ(Expression("_e")(0.0), std::numbers::e);
  EXPECT_EQ(Expression("0.25")(5.0), 0.25);
  EXPECT_EQ(Expression("1.5e-3")(5.0), 1.5e-3);
  EXPECT_EQ(Expression()(1.0), 0.0);
  EXPECT_EQ(Expression().text(), "0");
  EXPECT_EQ(Expression(" t ").text(), " t ");
}

TEST(Expression, TernaryAndComparisons) {
  const Expression f("t < 1 ? t^2 : 2*t - 1");
  EXPECT_EQ(f(0.5), 0.25);
  EXPECT_EQ(f(3.0), 5.0);
  EXPECT_EQ(Expression("t >= 1 && t != 2 || t == 3")(1.0), 1.0);
  EXPECT_EQ(Expression("t >= 1 && t != 2 || t == 3")(2.0), 0.0);
  // The driver of CASE_FORMAT.md: a smooth spin-up to 6 rad/s over 15 s, then constant speed.
  const Expression d("t < 15 ? 0.4*(t^2/2 + (15/(2*_pi))^2*(cos(2*_pi*t/15)-1)) : 6*(t-7.5)");
  EXPECT_NEAR(d(0.0), 0.0, 1e-15);
  EXPECT_NEAR(d(15.0), 6 * 7.5, 1e-12);
  EXPECT_NEAR(d(20.0), 6 * 12.5, 1e-12);
  EXPECT_NEAR(d.derivative(15.0 - 0.1), 6.0, 1e-3); // continuous speed at the switch
}

TEST(Expression, FirstDerivativeAccuracy) {
  // expression.hpp: sin(3t) 1.8e-13, t^3 1.6e-13, exp(t) 1.7e-13 (relative to max |f'|).
  auto e = derivative_errors(
      Expression("sin(3*t)"), [](double t) { return 3 * std::cos(3 * t); },
      [](double t) { return -9 * std::sin(3 * t); });
  EXPECT_LT(e.first / e.first_scale, 2e-12);
  e = derivative_errors(
      Expression("t^3"), [](double t) { return 3 * t * t; }, [](double t) { return 6 * t; });
  EXPECT_LT(e.first / e.first_scale, 2e-12);
  e = derivative_errors(
      Expression("exp(t)"), [](double t) { return std::exp(t); },
      [](double t) { return std::exp(t); });
  EXPECT_LT(e.first / e.first_scale, 2e-12);
}

TEST(Expression, SecondDerivativeAccuracy) {
  // expression.hpp: sin(3t) 2.0e-11, t^3 6.2e-11, exp(t) 7.6e-11 (relative to max |f''|).
  auto e = derivative_errors(
      Expression("sin(3*t)"), [](double t) { return 3 * std::cos(3 * t); },
      [](double t) { return -9 * std::sin(3 * t); });
  EXPECT_LT(e.second / e.second_scale, 1e-9);
  e = derivative_errors(
      Expression("t^3"), [](double t) { return 3 * t * t; }, [](double t) { return 6 * t; });
  EXPECT_LT(e.second / e.second_scale, 1e-9);
  e = derivative_errors(
      Expression("exp(t)"), [](double t) { return std::exp(t); },
      [](double t) { return std::exp(t); });
  EXPECT_LT(e.second / e.second_scale, 1e-9);
  // A faster function: sin(30t), 1.5e-9 and 1.3e-7.
  e = derivative_errors(
      Expression("sin(30*t)"), [](double t) { return 30 * std::cos(30 * t); },
      [](double t) { return -900 * std::sin(30 * t); });
  EXPECT_LT(e.first / e.first_scale, 2e-8);
  EXPECT_LT(e.second / e.second_scale, 2e-6);
}

TEST(Expression, PolynomialsOfDegreeTwoExactToRoundOff) {
  // expression.hpp: absolute errors 4e-12 (first) and 1.2e-9 (second, ~ eps |f| / h^2).
  auto e = derivative_errors(
      Expression("2*t^2 - 3*t + 1"), [](double t) { return 4 * t - 3; },
      [](double) { return 4.0; });
  EXPECT_LT(e.first, 4e-11);
  EXPECT_LT(e.second, 1e-8);
  e = derivative_errors(
      Expression("5*t - 2"), [](double) { return 5.0; }, [](double) { return 0.0; });
  EXPECT_LT(e.first, 1e-11);
  EXPECT_LT(e.second, 1e-8);
  const Expression c("7");
  EXPECT_EQ(c.derivative(0.3), 0.0);
  EXPECT_EQ(c.second_derivative(0.3), 0.0);
}

TEST(Expression, DerivativesAtLargeTimes) {
  // The steps are absolute: a fast function keeps its accuracy at large t.
  const Expression f("sin(3*t)");
  for (double t : {50.3, 1000.7}) {
    EXPECT_NEAR(f.derivative(t), 3 * std::cos(3 * t), 1e-11) << t;
    EXPECT_NEAR(f.second_derivative(t), -9 * std::sin(3 * t), 1e-9) << t;
  }
}

TEST(Expression, CopiesAreIndependentOfTheOriginal) {
  auto original = std::make_unique<Expression>("3*t + 1");
  Expression copy(*original);
  Expression assigned("0");
  assigned = *original;
  EXPECT_EQ((*original)(2.0), 7.0);
  original.reset(); // the original parser and its variable are gone
  EXPECT_EQ(copy(1.0), 4.0);
  EXPECT_EQ(assigned(2.0), 7.0);
  EXPECT_EQ(copy.text(), "3*t + 1");
  EXPECT_DOUBLE_EQ(copy.derivative(5.0), 3.0);

  // Evaluating one copy does not change the other's variable.
  Expression a("t"), b(a);
  EXPECT_EQ(a(1.0), 1.0);
  EXPECT_EQ(b(2.0), 2.0);
  EXPECT_EQ(a(3.0), 3.0);
}

TEST(Expression, MovesAndContainers) {
  Expression a("t^2");
  Expression moved(std::move(a));
  EXPECT_EQ(moved(3.0), 9.0);
  Expression target;
  target = std::move(moved);
  EXPECT_EQ(target(4.0), 16.0);
  std::vector<Expression> v;
  for (int k = 0; k < 20; ++k) v.emplace_back(std::to_string(k) + "*t"); // reallocations move
  for (int k = 0; k < 20; ++k) EXPECT_EQ(v[static_cast<std::size_t>(k)](2.0), 2.0 * k);
  std::vector<Expression> w = v; // copies
  v.clear();
  EXPECT_EQ(w[7](3.0), 21.0);
}

TEST(Expression, ParseErrorHasMessageAndPosition) {
  const auto e = error_of("t <* 2");
  EXPECT_EQ(e.position(), 3);
  EXPECT_EQ(e.text(), "t <* 2");
  EXPECT_TRUE(contains(e.message(), "cannot parse \"t <* 2\": ")) << e.message();
  EXPECT_TRUE(contains(e.message(), "at position 3")) << e.message();
  EXPECT_EQ(std::string(e.what()), e.message() + "\n    t <* 2\n       ^");

  const auto p = error_of("sin(3*t");
  EXPECT_TRUE(contains(p.message(), "missing parenthesis")) << p.message();
  EXPECT_GE(p.position(), 7);
  const auto end = error_of("t +");
  EXPECT_TRUE(contains(end.message(), "unexpected end of expression")) << end.message();
  // A caret past the end is drawn after the last character.
  EXPECT_TRUE(contains(end.what(), "\n    t +\n       ^")) << end.what();
}

TEST(Expression, UnknownNamesAreNamed) {
  const auto v = error_of("omega*t");
  EXPECT_EQ(v.position(), 0);
  EXPECT_TRUE(contains(v.message(), "unknown name \"omega\" at position 0")) << v.message();
  EXPECT_TRUE(contains(v.message(), "the only variable is t")) << v.message();
  const auto x = error_of("2*t + x");
  EXPECT_EQ(x.position(), 6);
  EXPECT_TRUE(contains(x.message(), "unknown name \"x\"")) << x.message();
  const auto pi = error_of("sin(2*pi*t)");
  EXPECT_TRUE(contains(pi.message(), "unknown name \"pi\" at position 6")) << pi.message();
  const auto f = error_of("foo (t)");
  EXPECT_TRUE(contains(f.message(), "unknown function \"foo\" at position 0")) << f.message();
  EXPECT_TRUE(contains(f.message(), "functions: sin cos")) << f.message();
}

TEST(Expression, OtherRejections) {
  const auto a = error_of("t = 3");
  EXPECT_EQ(a.position(), 2);
  EXPECT_TRUE(contains(a.message(), "'=' assigns")) << a.message();
  EXPECT_EQ(Expression("t == 3")(3.0), 1.0); // comparisons stay allowed
  EXPECT_EQ(Expression("t <= 3")(3.0), 1.0);

  const auto list = error_of("1, 2");
  EXPECT_TRUE(contains(list.message(), "one value")) << list.message();

  const auto inf = error_of("1/t");
  EXPECT_EQ(inf.position(), -1);
  EXPECT_EQ(std::string(inf.what()), "\"1/t\" evaluates to inf at t = 0 (an expression must be "
                                     "finite)");
  EXPECT_TRUE(contains(error_of("sqrt(t - 1)").message(), "evaluates to nan at t = 0"));
  EXPECT_TRUE(contains(error_of("log(t)").message(), "evaluates to inf at t = 0"));
  EXPECT_TRUE(contains(error_of("").message(), "empty expression"));
  EXPECT_TRUE(contains(error_of("   ").message(), "empty expression"));
  // Finite at t = 0 is all that is checked: 1/(t-1) compiles and is inf at t = 1.
  EXPECT_TRUE(std::isinf(Expression("1/(t-1)")(1.0)));
}

TEST(PointExpression, ValuesAndErrors) {
  const flexopt::PointExpression f("x + 2*y - z^2 + sin(_pi*x/0.3)");
  EXPECT_NEAR(f(0.15, 1.0, 3.0), 0.15 + 2 - 9 + 1.0, 1e-15);
  const flexopt::PointExpression copy = f; // copies share the parser; still evaluates
  EXPECT_NEAR(copy(0.0, 0.0, 0.0), 0.0, 0.0);
  try {
    flexopt::PointExpression("x*t");
    FAIL() << "t must be an unknown name in a point expression";
  } catch (const flexopt::ExpressionError &e) {
    EXPECT_TRUE(contains(e.message(), "unknown name \"t\" at position 2")) << e.message();
    EXPECT_TRUE(contains(e.message(), "the variables are x, y, z")) << e.message();
  }
  try {
    flexopt::PointExpression("1/x");
    FAIL() << "inf at the origin must be rejected";
  } catch (const flexopt::ExpressionError &e) {
    EXPECT_TRUE(contains(e.message(), "at x, y, z = 0")) << e.message();
  }
}
