#pragma once
/// \file The validating YAML reader of case.yaml (src/io/case*.cpp; docs/case-format.md): every
/// failure a collective flexopt::Error naming file, line and column. Private to src/io/.
#include "flexopt/core/error.hpp"
#include "flexopt/core/expression.hpp"
#include "flexopt/io/location.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>
#include <yaml-cpp/yaml.h>

namespace flexopt::io::detail {

/// Validating reader over one YAML document: every failure names file, line and column.
class Reader {
public:
  explicit Reader(std::string file) : file_(std::move(file)) {}

  Location where(const YAML::Node &n) const {
    const YAML::Mark m = n.Mark();
    return Location{file_, m.line + 1, m.column + 1};
  }

  [[noreturn]] void fail(const YAML::Node &n, const std::string &message) const {
    throw Error(where(n).str() + ": " + message, true);
  }

  void require_map(const YAML::Node &n, const std::string &path) const {
    if (!n.IsMap()) fail(n, path + ": expected a mapping ({key: value, ...})");
  }

  void require_sequence(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence()) fail(n, path + ": expected a list ([...] or '- ' items)");
  }

  /// Rejects keys outside `allowed`.
  void check_keys(const YAML::Node &n, const std::string &path,
                  std::initializer_list<const char *> allowed) const {
    for (const auto &kv : n) {
      const std::string key = kv.first.as<std::string>();
      bool ok =
          std::any_of(allowed.begin(), allowed.end(), [&](const char *a) { return key == a; });
      if (!ok) {
        std::string list;
        for (const char *a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(kv.first, "unknown key '" + (path.empty() ? key : path + "." + key) +
                           "' (allowed here: " + list + ")");
      }
    }
  }

  YAML::Node require(const YAML::Node &parent, const char *key, const std::string &path) const {
    YAML::Node n = parent[key];
    if (!n) fail(parent, "missing required key '" + (path.empty() ? "" : path + ".") + key + "'");
    return n;
  }

  double number(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a number");
    try {
      double v = n.as<double>();
      if (!std::isfinite(v)) fail(n, path + ": expected a finite number");
      return v;
    } catch (const YAML::BadConversion &) {
      fail(n, path + ": expected a number, got '" + n.Scalar() + "'");
    }
  }

  int integer(const YAML::Node &n, const std::string &path) const {
    double v = number(n, path);
    if (v != std::floor(v) || std::abs(v) > 1e9) fail(n, path + ": expected an integer");
    return static_cast<int>(v);
  }

  bool boolean(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected true or false");
    try {
      return n.as<bool>();
    } catch (const YAML::BadConversion &) {
      fail(n, path + ": expected true or false, got '" + n.Scalar() + "'");
    }
  }

  std::string string(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a string");
    return n.Scalar();
  }

  std::string choice(const YAML::Node &n, const std::string &path,
                     std::initializer_list<const char *> options) const {
    std::string s = string(n, path);
    for (const char *o : options)
      if (s == o) return s;
    std::string list;
    for (const char *o : options) list += std::string(list.empty() ? "" : " | ") + o;
    fail(n, path + ": '" + s + "' is not one of " + list);
  }

  /// The enumerator a name stands for (names and enumerators in `options`, in order).
  template <class E>
  E enumerated(const YAML::Node &n, const std::string &path,
               std::initializer_list<std::pair<const char *, E>> options) const {
    const std::string s = string(n, path);
    for (const auto &o : options)
      if (s == o.first) return o.second;
    std::string list;
    for (const auto &o : options) list += std::string(list.empty() ? "" : " | ") + o.first;
    fail(n, path + ": '" + s + "' is not one of " + list);
  }

  std::array<double, 3> vector3(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence() || n.size() != 3)
      fail(n, path + ": expected a list of 3 numbers [x, y, z]");
    return {number(n[0], path + "[0]"), number(n[1], path + "[1]"), number(n[2], path + "[2]")};
  }

  /// A nonzero 3-vector, normalized.
  std::array<double, 3> direction(const YAML::Node &n, const std::string &path) const {
    std::array<double, 3> d = vector3(n, path);
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(norm > 0)) fail(n, path + ": must not be zero");
    for (double &x : d) x /= norm;
    return d;
  }

  /// A number or a muParser expression in t (docs/case-format.md, "Expressions"), compiled to
  /// check it; returns the text as written.
  std::string expression(const YAML::Node &n, const std::string &path) const {
    if (!n.IsScalar()) fail(n, path + ": expected a number or an expression in t (a string)");
    try {
      const Expression compiled(n.Scalar());
    } catch (const ExpressionError &e) {
      fail(n, path + ": " + e.what());
    }
    return n.Scalar();
  }

  /// A list of three numbers or muParser expressions in x, y, z (a vector field over a body),
  /// each compiled to check it; returns the texts as written.
  std::array<std::string, 3> point_field(const YAML::Node &n, const std::string &path) const {
    if (!n.IsSequence() || n.size() != 3)
      fail(n, path + ": expected [fx, fy, fz]: three numbers or expressions in x, y, z");
    std::array<std::string, 3> out;
    for (std::size_t k = 0; k < 3; ++k) {
      const std::string p = path + "[" + std::to_string(k) + "]";
      if (!n[k].IsScalar()) fail(n[k], p + ": expected a number or an expression in x, y, z");
      try {
        const PointExpression compiled(n[k].Scalar());
      } catch (const ExpressionError &e) {
        fail(n[k], p + ": " + e.what());
      }
      out[k] = n[k].Scalar();
    }
    return out;
  }

  /// The key node (not the value) of `key` in the mapping `map`, for messages about the key.
  YAML::Node key_node(const YAML::Node &map, const std::string &key) const {
    for (const auto &kv : map)
      if (kv.first.as<std::string>() == key) return kv.first;
    return map;
  }

  std::vector<std::string> string_list(const YAML::Node &n, const std::string &path) const {
    require_sequence(n, path);
    std::vector<std::string> out;
    for (std::size_t i = 0; i < n.size(); ++i)
      out.push_back(string(n[i], path + "[" + std::to_string(i) + "]"));
    return out;
  }

private:
  std::string file_;
};

/// "a, b, c", or `none` for an empty list.
inline std::string join(const std::vector<std::string> &names, const char *none = "none") {
  std::string out;
  for (const auto &n : names) out += (out.empty() ? "" : ", ") + n;
  return out.empty() ? none : out;
}

} // namespace flexopt::io::detail
