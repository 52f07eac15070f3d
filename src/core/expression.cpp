#include "flexopt/core/expression.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <muParser.h>
#include <numbers>
#include <vector>

namespace flexopt {

namespace {

const char *const kFunctions =
    "functions: sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp ln log "
    "log2 log10 sqrt abs sign rint min max sum avg";

std::string format_error(const std::string &text, const std::string &message, int position) {
  std::string msg = message;
  if (position >= 0) {
    // Show the expression with a caret under the character (past the end: after the last).
    const std::size_t col = std::min(static_cast<std::size_t>(position), text.size());
    msg += "\n    " + text + "\n    " + std::string(col, ' ') + "^";
  }
  return msg;
}

/// muParser's message, lower-cased first letter, no trailing period, with the position if the
/// message does not already give it.
std::string clean_reason(std::string m, int position) {
  while (!m.empty() && (m.back() == '.' || m.back() == ' ')) m.pop_back();
  if (!m.empty() && std::isupper(static_cast<unsigned char>(m[0])) &&
      !(m.size() > 1 && std::isupper(static_cast<unsigned char>(m[1]))))
    m[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(m[0])));
  if (position >= 0 && m.find("position") == std::string::npos)
    m += " at position " + std::to_string(position);
  return m;
}

/// Position of an assignment '=' (not part of == <= >= !=), or -1.
int assignment_position(const std::string &s) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '=') continue;
    const char prev = i > 0 ? s[i - 1] : ' ', next = i + 1 < s.size() ? s[i + 1] : ' ';
    if (next == '=') {
      ++i; // "==" or "<==": skip the pair
      continue;
    }
    if (prev == '<' || prev == '>' || prev == '!' || prev == '=') continue;
    return static_cast<int>(i);
  }
  return -1;
}

} // namespace

ExpressionError::ExpressionError(std::string text, std::string message, int position)
    : std::runtime_error(format_error(text, message, position)), text_(std::move(text)),
      message_(std::move(message)), position_(position) {}

/// A compiled expression in up to three named variables (Expression: t; PointExpression: x, y,
/// z).
struct ExpressionImpl {
  std::string text;
  std::vector<std::string> names; ///< the variables, bound to var[0], var[1], ...
  /// The variables' values; the parser holds their addresses, so an ExpressionImpl never moves.
  std::array<double, 3> var{0, 0, 0};
  mu::Parser parser;

  ExpressionImpl(const std::string &s, std::vector<std::string> variables)
      : text(s), names(std::move(variables)) {
    std::string listed; // "t" or "x, y, z", for the messages
    for (const auto &n : names) listed += (listed.empty() ? "" : ", ") + n;
    auto fail = [&](const std::string &reason, int pos) {
      throw ExpressionError(text, "cannot parse \"" + text + "\": " + reason, pos);
    };
    const std::string blank = " \t\r\n";
    if (text.find_first_not_of(blank) == std::string::npos)
      throw ExpressionError(
          text, "empty expression (write a number or an expression in " + listed + ")", -1);
    const int eq = assignment_position(text);
    if (eq >= 0) fail("'=' assigns, which an expression may not (compare with ==)", eq);
    try {
      for (std::size_t k = 0; k < names.size(); ++k) parser.DefineVar(names[k], &var[k]);
      // muParser built with GCC defines _pi as 3.141592653589 (muParserTemplateMagic.h, to keep
      // sin(_pi*a) fast); redefine it to the double nearest pi.
      parser.DefineConst("_pi", std::numbers::pi);
      parser.DefineConst("_e", std::numbers::e);
      parser.SetExpr(text);
      parser.Eval(); // muParser parses lazily: this reports syntax errors
    } catch (const mu::Parser::exception_type &e) {
      const int pos = static_cast<int>(e.GetPos());
      const std::string &tok = e.GetToken();
      if (e.GetCode() == mu::ecUNASSIGNABLE_TOKEN && !tok.empty() &&
          (std::isalpha(static_cast<unsigned char>(tok[0])) || tok[0] == '_')) {
        // An identifier muParser does not know: a variable or a function name.
        const std::size_t after = static_cast<std::size_t>(pos) + tok.size();
        const std::size_t next = text.find_first_not_of(blank, after);
        if (next != std::string::npos && text[next] == '(')
          fail("unknown function \"" + tok + "\" at position " + std::to_string(pos) + " (" +
                   kFunctions + ")",
               pos);
        fail("unknown name \"" + tok + "\" at position " + std::to_string(pos) +
                 (names.size() == 1 ? " (the only variable is " : " (the variables are ") + listed +
                 "; constants: _pi, _e)",
             pos);
      }
      fail(clean_reason(e.GetMsg(), pos), pos);
    }
    if (parser.GetNumResults() != 1)
      fail("an expression gives one value (no comma-separated list)", -1);
    const double v0 = parser.Eval();
    if (!std::isfinite(v0))
      throw ExpressionError(text,
                            "\"" + text + "\" evaluates to " + (std::isnan(v0) ? "nan" : "inf") +
                                " at " + listed + " = 0 (an expression must be finite)",
                            -1);
  }

  double eval(double at) {
    var[0] = at;
    return parser.Eval();
  }
};

struct Expression::Impl : ExpressionImpl {
  explicit Impl(const std::string &s) : ExpressionImpl(s, {"t"}) {}
};

Expression::Expression() : Expression("0") {}

Expression::Expression(const std::string &text) : impl_(std::make_unique<Impl>(text)) {}

Expression::Expression(const Expression &other)
    : impl_(other.impl_ ? std::make_unique<Impl>(other.impl_->text) : nullptr) {}

Expression::Expression(Expression &&other) noexcept = default;

Expression &Expression::operator=(const Expression &other) {
  if (this != &other) impl_ = other.impl_ ? std::make_unique<Impl>(other.impl_->text) : nullptr;
  return *this;
}

Expression &Expression::operator=(Expression &&other) noexcept = default;

Expression::~Expression() = default;

double Expression::operator()(double t) const {
  return impl_->eval(t);
}

// The differences use the points t +- s as rounded and the steps actually taken (tp - t,
// t - tm), which keeps them consistent when t is large and t + s is not exact.

double Expression::derivative(double t) const {
  auto central = [&](double s) {
    const double tp = t + s, tm = t - s;
    return (impl_->eval(tp) - impl_->eval(tm)) / (tp - tm);
  };
  const double h = kFirstStep;
  return (4 * central(h / 2) - central(h)) / 3;
}

double Expression::second_derivative(double t) const {
  const double f0 = impl_->eval(t);
  auto central = [&](double s) {
    const double tp = t + s, tm = t - s, hp = tp - t, hm = t - tm;
    return 2 * ((impl_->eval(tp) - f0) / hp - (f0 - impl_->eval(tm)) / hm) / (hp + hm);
  };
  const double h = kSecondStep;
  return (4 * central(h / 2) - central(h)) / 3;
}

const std::string &Expression::text() const {
  return impl_->text;
}

struct PointExpression::Impl : ExpressionImpl {
  explicit Impl(const std::string &s) : ExpressionImpl(s, {"x", "y", "z"}) {}
};

PointExpression::PointExpression(const std::string &text) : impl_(std::make_shared<Impl>(text)) {}

double PointExpression::operator()(double x, double y, double z) const {
  impl_->var = {x, y, z};
  return impl_->parser.Eval();
}

const std::string &PointExpression::text() const {
  return impl_->text;
}

} // namespace flexopt
