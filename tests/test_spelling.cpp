// Specification of the spelling helpers behind "unknown key; did you mean ...?": the edit
// distance, the bound on a plausible typo, and the choice of the known name.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "pneu/config/spelling.hpp"

namespace pneu::config {
namespace {

TEST(EditDistance, IsZeroForEqualNamesOnly) {
  EXPECT_EQ(edit_distance("position_gain_v_per_m", "position_gain_v_per_m"), 0u);
  EXPECT_EQ(edit_distance("", ""), 0u);
  EXPECT_GT(edit_distance("rate_hz", "rate_Hz"), 0u);  // byte by byte: case counts
}

TEST(EditDistance, FromTheEmptyNameIsTheOtherNamesLength) {
  EXPECT_EQ(edit_distance("", "mass_kg"), 7u);
  EXPECT_EQ(edit_distance("mass_kg", ""), 7u);
}

TEST(EditDistance, CountsOneForEachInsertionDeletionOrSubstitution) {
  EXPECT_EQ(edit_distance("position_gain_v_per_mm", "position_gain_v_per_m"), 1u);  // inserted
  EXPECT_EQ(edit_distance("positon_gain_v_per_m", "position_gain_v_per_m"), 1u);    // deleted
  EXPECT_EQ(edit_distance("pesition_gain_v_per_m", "position_gain_v_per_m"), 1u);   // substituted
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3u);  // k->s, e->i, +g
}

TEST(EditDistance, CountsTheSwapOfTwoAdjacentCharactersAsOneEdit) {
  EXPECT_EQ(edit_distance("postiion_gain_v_per_m", "position_gain_v_per_m"), 1u);
  EXPECT_EQ(edit_distance("ab", "ba"), 1u);
  // Optimal string alignment: a swapped pair is not edited again ("ca" -> "ac" -> "abc" is not
  // one path of 2), as the unrestricted Damerau-Levenshtein distance would allow.
  EXPECT_EQ(edit_distance("ca", "abc"), 3u);
}

TEST(EditDistance, IsSymmetricAndAtMostTheLongerLengthForRandomNames) {
  std::mt19937 rng(20250612);  // fixed seed: reproducible
  std::uniform_int_distribution<int> length(0, 12), letter(0, 3);  // few letters: many matches
  const auto random_name = [&] {
    std::string s(static_cast<std::size_t>(length(rng)), 'a');
    for (char& c : s) c = static_cast<char>('a' + letter(rng));
    return s;
  };
  for (int i = 0; i < 2000; ++i) {
    const std::string a = random_name(), b = random_name();
    const std::size_t d = edit_distance(a, b);
    EXPECT_EQ(d, edit_distance(b, a)) << a << " " << b;
    EXPECT_LE(d, std::max(a.size(), b.size())) << a << " " << b;
    EXPECT_GE(d, a.size() > b.size() ? a.size() - b.size() : b.size() - a.size()) << a << " " << b;
    EXPECT_EQ(d == 0, a == b) << a << " " << b;
  }
}

TEST(PlausibleTypo, AllowsOneEditPerFourCharactersOfTheKnownName) {
  EXPECT_TRUE(plausible_typo("mass_gk", "mass_kg"));          // 7 characters: 1 edit allowed
  EXPECT_FALSE(plausible_typo("mas_gk", "mass_kg"));          // 2 edits
  EXPECT_TRUE(plausible_typo("rst_bnd_m", "rest_band_m"));    // 11 characters: 2 edits allowed
  EXPECT_FALSE(plausible_typo("rst_bnd_", "rest_band_m"));    // 3 edits
  EXPECT_TRUE(plausible_typo("moin_bnd_m", "motion_band_m")); // 13 characters: 3 edits allowed
  EXPECT_FALSE(plausible_typo("motin_bnd", "motion_band_m")); // 4 edits
}

TEST(PlausibleTypo, AllowsOneEditInAShortNameAndThreeInTheLongest) {
  EXPECT_TRUE(plausible_typo("ts", "t_s"));
  EXPECT_FALSE(plausible_typo("x", "t_s"));
  const std::string longest = "leak_conductance_out_m3_per_s_pa";
  EXPECT_TRUE(plausible_typo("leak_conductnce_ot_m3_per_s_p", longest));    // 3 edits
  EXPECT_FALSE(plausible_typo("leak_conductnce_ot_m3_per_s_", longest));    // 4 edits
}

using Names = std::vector<std::string>;

TEST(ClosestKnown, NamesTheNearestPlausibleKnownName) {
  const Names known = {"dead_volume_p_m3", "dead_volume_n_m3", "stroke_m"};
  EXPECT_EQ(closest_known("dead_volume_p_m", known), Names{"dead_volume_p_m3"});
  EXPECT_EQ(closest_known("dead_volume_n_m33", known), Names{"dead_volume_n_m3"});
  EXPECT_EQ(closest_known("stroek_m", known), Names{"stroke_m"});
}

TEST(ClosestKnown, NamesEachOfTheNearestOnATieInTheGivenOrder) {
  EXPECT_EQ(closest_known("valve_", {"valve_p", "stroke_m", "valve_n"}), (Names{"valve_p", "valve_n"}));
  EXPECT_EQ(closest_known("valve_", {"valve_n", "valve_p"}), (Names{"valve_n", "valve_p"}));
}

TEST(ClosestKnown, NamesNothingWhenNoKnownNameIsAPlausibleTypo) {
  EXPECT_EQ(closest_known("colour", {"stroke_m", "bore_diameter_m", "rod_diameter_m"}), Names{});
  EXPECT_EQ(closest_known("mass_kg_unknown", {"mass_kg"}), Names{});
  EXPECT_EQ(closest_known("anything", {}), Names{});
}

TEST(ClosestKnown, NamesNothingForAKnownName) {
  EXPECT_EQ(closest_known("valve_p", {"valve_p", "valve_n"}), Names{});
}

}  // namespace
}  // namespace pneu::config
