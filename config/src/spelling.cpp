#include "pneu/config/spelling.hpp"

#include <algorithm>

namespace pneu::config {

std::size_t edit_distance(std::string_view a, std::string_view b) {
  // Three rows of the dynamic programme: d[i][j] is the distance between a's first i and b's
  // first j characters; the swap looks two rows back.
  std::vector<std::size_t> before(b.size() + 1), previous(b.size() + 1), row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) previous[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitution = previous[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      row[j] = std::min({previous[j] + 1, row[j - 1] + 1, substitution});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1])
        row[j] = std::min(row[j], before[j - 2] + 1);
    }
    std::swap(before, previous);
    std::swap(previous, row);
  }
  return previous[b.size()];
}

bool plausible_typo(std::string_view typed, std::string_view known) {
  const std::size_t allowed = std::clamp<std::size_t>(known.size() / 4, 1, 3);
  return edit_distance(typed, known) <= allowed;
}

std::vector<std::string> closest_known(std::string_view typed, const std::vector<std::string>& known) {
  std::vector<std::string> closest;
  std::size_t closest_distance = 0;
  for (const std::string& k : known) {
    const std::size_t d = edit_distance(typed, k);
    if (d == 0) return {};
    if (!plausible_typo(typed, k) || (!closest.empty() && d > closest_distance)) continue;
    if (closest.empty() || d < closest_distance) closest.clear();
    closest.push_back(k);
    closest_distance = d;
  }
  return closest;
}

}  // namespace pneu::config
