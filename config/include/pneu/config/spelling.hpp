// Telling a misspelt key from an unknown one: the edit distance between two names, and the known
// name a typed one is plausibly a typo of. Used by the configuration loader's messages
// ("unknown key; did you mean position_gain_v_per_m?").
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace pneu::config {

/// The number of single-character edits (insertion, deletion, substitution, or the swap of two
/// adjacent characters) that turn `a` into `b`: the optimal string alignment distance, byte by
/// byte. Symmetric, 0 only for equal strings, at most max(|a|, |b|).
[[nodiscard]] std::size_t edit_distance(std::string_view a, std::string_view b);

/// Whether `typed` is close enough to `known` to be taken for a typo of it: at most one edit per
/// four characters of `known`, at least one and at most three (`t_s` tolerates one edit,
/// `position_gain_v_per_m` three).
[[nodiscard]] bool plausible_typo(std::string_view typed, std::string_view known);

/// Of `known`, the names `typed` is most plausibly a typo of: those closest by edit_distance
/// among the ones plausible_typo accepts (several on a tie), in `known`'s order; none when none is
/// accepted, or when `typed` is itself one of `known`.
[[nodiscard]] std::vector<std::string> closest_known(std::string_view typed,
                                                     const std::vector<std::string>& known);

}  // namespace pneu::config
