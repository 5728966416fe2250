// Numbers and strings as JSON text, streamed without building a string (private to the sinks).
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ostream>
#include <string_view>

namespace pneu::controller::json {

// A JSON number (printf's %.*g, by std::to_chars: the same text, several times faster), or null
// for NaN / infinity. The trajectory writes 18 per tick.
struct Num {
  char text[32];
  std::size_t size;
};
inline Num num(double v, int precision = 9) {
  Num n{};
  if (!std::isfinite(v)) {
    std::memcpy(n.text, "null", 4);
    n.size = 4;
    return n;
  }
  const auto r = std::to_chars(n.text, n.text + sizeof n.text, v, std::chars_format::general, precision);
  n.size = static_cast<std::size_t>(r.ptr - n.text);
  return n;
}
inline std::ostream& operator<<(std::ostream& os, const Num& n) {
  return os.write(n.text, static_cast<std::streamsize>(n.size));
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

}  // namespace pneu::controller::json
