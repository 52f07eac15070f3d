#include "flexopt/io/json.hpp"

#include "flexopt/core/error.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace flexopt::io {

Json::Json(const std::vector<double> &v) : value_(Array{}) {
  auto &a = std::get<Array>(value_);
  a.reserve(v.size());
  for (double x : v) a.emplace_back(x);
}

Json &Json::operator[](const std::string &key) {
  if (std::holds_alternative<std::nullptr_t>(value_)) value_ = Object{};
  auto &obj = std::get<Object>(value_);
  for (auto &kv : obj)
    if (kv.first == key) return kv.second;
  obj.emplace_back(key, Json());
  return obj.back().second;
}

void Json::push_back(Json v) {
  if (std::holds_alternative<std::nullptr_t>(value_)) value_ = Array{};
  std::get<Array>(value_).push_back(std::move(v));
}

static void escape_string(std::ostringstream &out, const std::string &s) {
  out << '"';
  for (char c : s) {
    switch (c) {
    case '"':
      out << "\\\"";
      break;
    case '\\':
      out << "\\\\";
      break;
    case '\n':
      out << "\\n";
      break;
    case '\t':
      out << "\\t";
      break;
    default:
      if (static_cast<unsigned char>(c) < 0x20) {
        char buf[8];
        std::snprintf(buf, sizeof buf, "\\u%04x", c);
        out << buf;
      } else {
        out << c;
      }
    }
  }
  out << '"';
}

std::string Json::dump(int indent) const {
  std::ostringstream out;
  const std::string pad(static_cast<std::size_t>(indent), ' ');
  const std::string pad_in(static_cast<std::size_t>(indent + 2), ' ');
  if (std::holds_alternative<std::nullptr_t>(value_)) {
    out << "null";
  } else if (auto b = std::get_if<bool>(&value_)) {
    out << (*b ? "true" : "false");
  } else if (auto d = std::get_if<double>(&value_)) {
    if (!std::isfinite(*d)) {
      out << "null";
    } else {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.17g", *d);
      out << buf;
    }
  } else if (auto s = std::get_if<std::string>(&value_)) {
    escape_string(out, *s);
  } else if (auto t = std::get_if<Serialized>(&value_)) {
    out << t->text;
  } else if (auto a = std::get_if<Array>(&value_)) {
    // Arrays of numbers stay on one line; others one element per line.
    bool flat = true;
    for (const auto &e : *a)
      if (std::holds_alternative<Array>(e.value_) || std::holds_alternative<Object>(e.value_))
        flat = false;
    out << '[';
    for (std::size_t i = 0; i < a->size(); ++i) {
      if (i) out << (flat ? ", " : ",");
      if (!flat) out << '\n' << pad_in;
      out << (*a)[i].dump(indent + 2);
    }
    if (!flat && !a->empty()) out << '\n' << pad;
    out << ']';
  } else {
    const auto &o = std::get<Object>(value_);
    out << '{';
    for (std::size_t i = 0; i < o.size(); ++i) {
      out << (i ? ",\n" : "\n") << pad_in;
      escape_string(out, o[i].first);
      out << ": " << o[i].second.dump(indent + 2);
    }
    if (!o.empty()) out << '\n' << pad;
    out << '}';
  }
  return out.str();
}

void write_file_atomic(const std::string &path, const std::string &text) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw Error("cannot write '" + tmp + "'");
    f << text;
    f.flush();
    if (!f) throw Error("error while writing '" + tmp + "'");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    throw Error("cannot rename '" + tmp + "' to '" + path + "'");
}

} // namespace flexopt::io
