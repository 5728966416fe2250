// Numbers and strings as JSON text, streamed without building a string: the sinks' and the
// summaries' writer (pneud's --summary-json, pneu-sweep's).
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ostream>
#include <cstdint>
#include <string>
#include <string_view>

#include "pneu/records/text.hpp"

namespace pneu::controller::json {

// A JSON number (pneu/records/text.hpp: printf's %.*g), or null for NaN / infinity.
using Num = records::NumberText;
inline Num num(double v, int precision = 9) {
  if (std::isfinite(v)) return records::number_text(v, precision);
  Num n{};
  std::memcpy(n.text, "null", 4);
  n.size = 4;
  return n;
}

// A JSON string: quotes, backslashes and control characters escaped (RFC 8259).
struct Str {
  std::string_view text;
};
inline std::ostream& operator<<(std::ostream& os, const Str& s) {
  os << '"';
  for (const char c : s.text) {
    if (c == '"' || c == '\\') {
      os << '\\' << c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      os << buf;
    } else {
      os << c;
    }
  }
  return os << '"';
}

// A JSON document written as it goes, one member per line, indented by two spaces per level.
// Members of an object take a key; elements of an array do not (an empty key).
class Writer {
 public:
  explicit Writer(std::ostream& os) : os_(os) {}
  void begin_object(std::string_view key = {}) { begin('{', key); }
  void end_object() { end('}'); }
  void begin_array(std::string_view key = {}) { begin('[', key); }
  void end_array() { end(']'); }
  void number(std::string_view key, double v, int precision = 9) { item(key) << num(v, precision); }
  void count(std::string_view key, std::uint64_t v) { item(key) << v; }
  void flag(std::string_view key, bool v) { item(key) << (v ? "true" : "false"); }
  void text(std::string_view key, std::string_view v) { item(key) << Str{v}; }
  void null(std::string_view key) { item(key) << "null"; }

 private:
  void begin(char bracket, std::string_view key) {
    if (depth_ > 0) item(key);
    os_ << bracket;
    ++depth_;
    first_ = true;
  }
  void end(char bracket) {
    --depth_;
    if (!first_) os_ << '\n' << std::string(2 * depth_, ' ');
    os_ << bracket;
    first_ = false;
    if (depth_ == 0) os_ << '\n';
  }
  std::ostream& item(std::string_view key) {
    if (!first_) os_ << ',';
    os_ << '\n' << std::string(2 * depth_, ' ');
    if (!key.empty()) os_ << Str{key} << ": ";
    first_ = false;
    return os_;
  }

  std::ostream& os_;
  int depth_ = 0;
  bool first_ = true;
};

}  // namespace pneu::controller::json
