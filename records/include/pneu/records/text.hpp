// A number as the text formats write it: printf's %.*g by std::to_chars (the same text, several
// times faster: "inf" and "-inf" too); nothing for NaN (the formats say "no value" their own way:
// an empty CSV cell, JSON's null, which JSON also writes for an infinity).
#pragma once

#include <charconv>
#include <cmath>
#include <cstddef>
#include <ostream>
#include <string>
#include <string_view>

namespace pneu::records {

/// Significant digits that read back to the same double (printf's %.17g).
inline constexpr int kDigitsToTheLastBit = 17;

struct NumberText {
  char text[32];
  std::size_t size;  ///< 0: not a number (NaN)
  [[nodiscard]] bool empty() const { return size == 0; }
};

[[nodiscard]] inline NumberText number_text(double v, int digits = 9) {
  NumberText n{};
  if (std::isnan(v)) return n;
  const auto r = std::to_chars(n.text, n.text + sizeof n.text, v, std::chars_format::general, digits);
  n.size = static_cast<std::size_t>(r.ptr - n.text);
  return n;
}

inline std::ostream& operator<<(std::ostream& os, const NumberText& n) {
  return os.write(n.text, static_cast<std::streamsize>(n.size));
}

/// Where the formats write: a stream, or a string appended to.
inline void put(std::ostream& out, const char* text, std::size_t size) {
  out.write(text, static_cast<std::streamsize>(size));
}
inline void put(std::string& out, const char* text, std::size_t size) { out.append(text, size); }
template <class Out>
void put(Out& out, char c) {
  put(out, &c, 1);
}
template <class Out>
void put(Out& out, std::string_view s) {
  put(out, s.data(), s.size());
}

}  // namespace pneu::records
