// Test support: how an edited YAML text differs from its source, line by line (config::
// with_values_of, the identified configuration): which of the source's lines were kept byte for
// byte, which were replaced (the same key, its inline comment kept), which lines were added.
#pragma once

#include <cstddef>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace pneu::test {

inline std::vector<std::string> lines_of(std::string_view text) {
  std::vector<std::string> lines;
  std::istringstream in{std::string(text)};
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

/// The source's lines in the edited text, in order.
struct Edits {
  std::vector<std::string> replaced;  ///< the source's lines whose value was replaced (as they were)
  std::vector<std::string> added;     ///< the edited text's lines the source does not have
  std::vector<std::string> lost;      ///< the source's lines neither kept nor replaced (must be none)
};

/// A source line's key and comment: "  mass_kg: 17.0  # M [kg]" -> "  mass_kg:", "# M [kg]" (no
/// comment: "").
inline std::pair<std::string, std::string> key_and_comment(const std::string& line) {
  const std::size_t colon = line.find(": ");
  const std::size_t hash = line.find(" #");
  return {colon == std::string::npos ? std::string() : line.substr(0, colon + 1),
          hash == std::string::npos ? std::string() : line.substr(line.find_first_not_of(' ', hash))};
}

/// Aligns `edited` on `source`: each source line is kept byte for byte, or replaced by a line with
/// its key and its whole inline comment (a note may follow), or lost; the other lines were added.
inline Edits edits(std::string_view source, std::string_view edited) {
  const std::vector<std::string> s = lines_of(source), e = lines_of(edited);
  Edits out;
  std::size_t j = 0;
  for (const std::string& line : s) {
    const auto [key, comment] = key_and_comment(line);
    std::size_t k = j;
    for (; k < e.size(); ++k) {
      if (e[k] == line) break;
      if (!key.empty() && e[k].starts_with(key) && e[k].find(comment) != std::string::npos &&
          key_and_comment(e[k]).first == key)
        break;
    }
    if (k == e.size()) {
      out.lost.push_back(line);
      continue;
    }
    for (; j < k; ++j) out.added.push_back(e[j]);
    if (e[k] != line) out.replaced.push_back(line);
    j = k + 1;
  }
  for (; j < e.size(); ++j) out.added.push_back(e[j]);
  return out;
}

}  // namespace pneu::test
