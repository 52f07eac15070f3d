#pragma once
/// \file A small ordered JSON value for summary.json (the contract read by scripts and tests).
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace flexopt::io {

/// JSON value: null, bool, number, string, array or object. Objects keep insertion order.
class Json {
public:
  using Array = std::vector<Json>;
  using Object = std::vector<std::pair<std::string, Json>>;

  Json() : value_(nullptr) {}
  Json(std::nullptr_t) : value_(nullptr) {}
  Json(bool b) : value_(b) {}
  Json(int v) : value_(static_cast<double>(v)) {}
  Json(long v) : value_(static_cast<double>(v)) {}
  Json(long long v) : value_(static_cast<double>(v)) {}
  Json(unsigned long v) : value_(static_cast<double>(v)) {}
  Json(double v) : value_(v) {}
  Json(const char *s) : value_(std::string(s)) {}
  Json(std::string s) : value_(std::move(s)) {}
  Json(const std::vector<double> &v);
  static Json array() {
    Json j;
    j.value_ = Array{};
    return j;
  }
  static Json object() {
    Json j;
    j.value_ = Object{};
    return j;
  }

  /// A value already serialized by dump() (a value made on another rank, sent as text); dump
  /// writes it as it is.
  static Json serialized(std::string text) {
    Json j;
    j.value_ = Serialized{std::move(text)};
    return j;
  }

  /// Object member access; creates the member (and turns a null into an object) if absent.
  Json &operator[](const std::string &key);
  /// Appends to an array (turns a null into an array).
  void push_back(Json v);

  bool is_null() const { return std::holds_alternative<std::nullptr_t>(value_); }
  /// Serialises with two-space indentation; numbers with 17 significant digits.
  std::string dump(int indent = 0) const;

private:
  struct Serialized {
    std::string text;
  };
  std::variant<std::nullptr_t, bool, double, std::string, Array, Object, Serialized> value_;
};

/// Writes text to `path` atomically: to `path.tmp`, then renamed. Throws flexopt::Error.
void write_file_atomic(const std::string &path, const std::string &text);

} // namespace flexopt::io
