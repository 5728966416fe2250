// The configuration an identification writes (identify::identified_config_yaml): the text of the
// file the run's configuration came from, its comments kept byte for byte, each identified value
// replaced in place with its sigma beside it, under a header saying when, from which run on which
// backend, with which fit residual; and the report that leads with the parameter table.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <regex>
#include <string>

#include "pneu/config/config.hpp"
#include "pneu/config/yaml_text.hpp"
#include "pneu/config/schema.hpp"
#include "pneu/identify/identification_run.hpp"
#include "support/edited_text.hpp"
#include "support/paths.hpp"

namespace {

using namespace pneu;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using ::testing::StartsWith;

constexpr std::time_t k20261128At0831Utc = 1795854660;
constexpr std::time_t k20261129At0900Utc = 1795942800;

// An identification of `c`'s bench, as identify() reports one: two values identified, one kept.
identify::Identification identified_from(const config::Config& c, double f_s_pos = 47.25) {
  identify::Identification id;
  id.plant = c.plant;
  id.plant.friction.static_positive_n = f_s_pos;
  id.plant.valve.null_offset_v = 0.0375;
  id.estimates = {
      {"plant.friction.static_positive_n", c.plant.friction.static_positive_n, f_s_pos, 0.12, true, "7 breakaways"},
      {"plant.valve.null_offset_v", c.plant.valve.null_offset_v, 0.0375, 0.002, true, "11 stuck phases"},
      {"plant.mass_kg", c.plant.mass_kg, c.plant.mass_kg, 0.0, false, "not identified: taken from the configuration"}};
  id.evidence.fitted_phases = 11;
  id.evidence.pressure_rms_residual_pa = 4.5;
  id.evidence.pressure_explained_pa = 10.0;
  return id;
}

identify::Provenance run_at(std::time_t when, std::string source = "config/sim.yaml") {
  return {"pneud 0.1.0", "pneud --identify out.yaml --config " + source,
          "its own identification run: 34701 ticks over 34.70 s", std::move(source), when};
}

// The text below the header.
std::string body_of(const std::string& text) {
  const std::string end = std::string("\n") + identify::kEndOfIdentifiedHeader + "\n";
  const std::size_t at = text.find(end);
  return at == std::string::npos ? std::string() : text.substr(at + end.size());
}

// The values of `c` under `prefix` (its dot included), by their path below it.
std::vector<std::pair<std::string, std::string>> values_below(const config::Config& c, const std::string& prefix) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& [path, value] : config::schema::values_of(c))
    if (path.starts_with(prefix)) out.emplace_back(path.substr(prefix.size()), value);
  return out;
}

TEST(IdentifiedYaml, KeepsTheSourcesTextAndCommentsAndReplacesTheIdentifiedValuesInPlace) {
  const std::string text = config::text_of(test::shipped_config("sim.yaml"));
  const config::Config cfg = config::load_string(text);
  const identify::Identification id = identified_from(cfg);
  const identify::IdentifiedYaml y = identify::identified_config_yaml(text, cfg, id, run_at(k20261128At0831Utc));
  EXPECT_THAT(y.text_not_kept, IsEmpty());
  const std::string body = body_of(y.text);
  const test::Edits e = test::edits(text, body);
  EXPECT_THAT(e.lost, IsEmpty()) << "every line of sim.yaml is kept, or replaced with its key and comment";
  ASSERT_THAT(e.replaced, ElementsAre(HasSubstr("null_offset_v: 0.0 "), HasSubstr("static_positive_n: 45.0 ")))
      << "the identified values, and only they";
  EXPECT_THAT(body, HasSubstr("\n    static_positive_n: 47.25        # F_S+: stiction, positive motion [N], > 0, >= F_C+"
                              "  # identified 2026-11-28: 47.25 +- 0.12 (was 45)\n"));
  EXPECT_THAT(body, HasSubstr("\n    null_offset_v: 0.0375                      # optional: w_0: "));
  EXPECT_THAT(body, HasSubstr("  # identified 2026-11-28: 0.0375 +- 0.002 (was 0)\n"));
  // Added, in their sections: the fit's residual, and the simulated bench as it was.
  ASSERT_FALSE(e.added.empty());
  EXPECT_EQ(e.added.front(), "    model_fit:");
  EXPECT_THAT(body, HasSubstr("\n  sim:\n    plant:\n      mass_kg: 17\n"));
  // Loaded back: the identified values, the same bench, the fit.
  const config::Config loaded = config::load_string(y.text);
  config::Config expected = cfg;
  expected.plant = id.plant;
  EXPECT_EQ(values_below(loaded, "plant."), values_below(expected, "plant."));
  EXPECT_EQ(values_below(loaded, "hal.sim.plant."), values_below(cfg, "plant.")) << "the simulated bench as it was";
  EXPECT_TRUE(loaded.controller.predictor.has_model_fit);
  EXPECT_EQ(loaded.controller.predictor.model_fit.pressure_residual_pa, 4.5);
  EXPECT_EQ(values_below(loaded, "controller.setpoints."), values_below(cfg, "controller.setpoints."));
  // The header: when, by what, from which run on which backend, the fit, what the file is.
  EXPECT_THAT(y.text, StartsWith("# identified 2026-11-28 08:31 UTC by pneud 0.1.0: pneud --identify out.yaml --config "
                                 "config/sim.yaml\n"
                                 "# from its own identification run: 34701 ticks over 34.70 s, on the sim backend (the "
                                 "in-process simulated bench), simulated clock\n"
                                 "# the fit: the model fits the stuck phases' pressures: 4.5 Pa rms"));
  EXPECT_THAT(y.text, HasSubstr("\n# below: config/sim.yaml as it was, its comments kept; "));
  EXPECT_THAT(y.text, HasSubstr("\n# not identified, kept: plant.mass_kg (not identified: taken from the configuration)\n"));
  EXPECT_THAT(y.text, StartsWith(y.text.substr(0, y.text.size() - body.size()))) << "the header, then the text";
  EXPECT_EQ(y.text.substr(y.text.size() - body.size() - 1 - std::string(identify::kEndOfIdentifiedHeader).size() - 1,
                          std::string(identify::kEndOfIdentifiedHeader).size() + 2),
            "\n" + std::string(identify::kEndOfIdentifiedHeader) + "\n");
}

TEST(IdentifiedYaml, AFileIdentifiedAgainGetsOneHeaderAndOneNoteAKey) {
  const std::string text = config::text_of(test::shipped_config("sim.yaml"));
  const config::Config cfg = config::load_string(text);
  const std::string first =
      identify::identified_config_yaml(text, cfg, identified_from(cfg), run_at(k20261128At0831Utc)).text;
  const config::Config again = config::load_string(first);
  const identify::IdentifiedYaml second = identify::identified_config_yaml(
      first, again, identified_from(again, 48.5), run_at(k20261129At0900Utc, "identified.yaml"));
  EXPECT_THAT(second.text, StartsWith("# identified 2026-11-29 09:00 UTC by pneud 0.1.0: "));
  EXPECT_THAT(second.text, Not(HasSubstr("2026-11-28 08:31"))) << "the earlier header replaced";
  EXPECT_THAT(second.text, HasSubstr("# F_S+: stiction, positive motion [N], > 0, >= F_C+  # identified 2026-11-29: "
                                     "48.5 +- 0.12 (was 47.25)\n"));
  EXPECT_THAT(second.text, Not(HasSubstr("(was 45)"))) << "the earlier note replaced";
  // Nothing else changed but the values identified again and their notes.
  const auto without_notes = [](const std::string& written) {
    return std::regex_replace(written, std::regex("  # identified [^\n]*"), "");
  };
  const test::Edits e = test::edits(without_notes(body_of(first)), without_notes(body_of(second.text)));
  EXPECT_THAT(e.lost, IsEmpty());
  EXPECT_THAT(e.added, IsEmpty());
  EXPECT_THAT(e.replaced, ElementsAre(HasSubstr("static_positive_n: 47.25")));
  // A value identified again the same: its note renewed.
  EXPECT_THAT(second.text, HasSubstr("  # identified 2026-11-29: 0.0375 +- 0.002 (was 0.0375)\n"));
  EXPECT_EQ(config::load_string(second.text).plant.friction.static_positive_n, 48.5);
}

TEST(IdentifiedYaml, AnIdentifiedKeyTheSourceLacksIsAddedInItsSection) {
  std::string text = config::text_of(test::shipped_config("sim.yaml"));
  const std::size_t line = text.find("    null_offset_v:");
  text.erase(line, text.find('\n', line) + 1 - line);
  const config::Config cfg = config::load_string(text);
  const identify::IdentifiedYaml y = identify::identified_config_yaml(text, cfg, identified_from(cfg), run_at(k20261128At0831Utc));
  EXPECT_THAT(y.text, HasSubstr("    spool_time_constant_s: 0.0                 # optional: the spool follows"));
  EXPECT_THAT(y.text, HasSubstr("\n    null_offset_v: 0.0375                      # identified 2026-11-28: 0.0375 +- "
                                "0.002 (was 0)\n  friction:"))
      << "at the end of plant.valve, its note at the column of the comments above";
  EXPECT_EQ(config::load_string(y.text).plant.valve.null_offset_v, 0.0375);
}

TEST(IdentifiedYaml, FromTheEmbeddedDefaultSaysSo) {
  const std::string text(config::default_config_yaml());
  const config::Config cfg = config::load_string(text);
  const identify::IdentifiedYaml y = identify::identified_config_yaml(text, cfg, identified_from(cfg), run_at(k20261128At0831Utc, ""));
  EXPECT_THAT(y.text, HasSubstr("\n# below: the embedded sim.yaml as it was, its comments kept; "));
  EXPECT_THAT(test::edits(text, body_of(y.text)).lost, IsEmpty());
}

TEST(IdentifiedYaml, WhereTheTextCannotBeKeptWritesTheWholeConfigurationAndSaysWhy) {
  std::string text = config::text_of(test::shipped_config("paper.yaml"));
  const std::size_t from = text.find("  friction:"), to = text.find("  max_step_s:");
  text.replace(from, to - from,
               "  friction: {static_positive_n: 45.0, coulomb_positive_n: 35.0, static_negative_n: -50.0, "
               "coulomb_negative_n: -38.0, viscous_n_s_per_m: 60.0, stribeck_velocity_m_per_s: 0.01, "
               "stick_velocity_m_per_s: 1.0e-4}\n");
  const config::Config cfg = config::load_string(text);
  const identify::IdentifiedYaml y = identify::identified_config_yaml(text, cfg, identified_from(cfg), run_at(k20261128At0831Utc));
  EXPECT_THAT(y.text_not_kept, HasSubstr("plant.friction is a section in flow style"));
  EXPECT_THAT(y.text, HasSubstr("# below: the whole configuration, as pneud writes it: the text of config/sim.yaml could "
                                "not be kept (plant.friction.static_positive_n: plant.friction is a section in flow style"));
  EXPECT_EQ(config::load_string(y.text).plant.friction.static_positive_n, 47.25);
}

TEST(IdentifiedYaml, IdentifiedValuesThatBreakARuleAreRefused) {
  const std::string text = config::text_of(test::shipped_config("sim.yaml"));
  const config::Config cfg = config::load_string(text);
  // F_S+ under F_C+ (35 N).
  EXPECT_THROW((void)identify::identified_config_yaml(text, cfg, identified_from(cfg, 30.0), run_at(k20261128At0831Utc)),
               config::ConfigError);
}

TEST(IdentificationReport, LeadsWithTheParameterTableThenTheEvidence) {
  const config::Config cfg = config::load_string(config::default_config_yaml());
  char* buffer = nullptr;
  std::size_t size = 0;
  std::FILE* out = open_memstream(&buffer, &size);
  ASSERT_NE(out, nullptr);
  identify::print_report(out, identified_from(cfg));
  std::fclose(out);
  const std::string report(buffer, size);
  std::free(buffer);
  const std::vector<std::string> lines = test::lines_of(report);
  ASSERT_GE(lines.size(), 5u);
  EXPECT_THAT(lines[0], StartsWith("parameter "));
  EXPECT_THAT(lines[1], StartsWith("plant.friction.static_positive_n "));
  EXPECT_THAT(lines[3], StartsWith("plant.mass_kg "));
  EXPECT_THAT(lines[4], StartsWith("evidence: "));
  EXPECT_THAT(lines[5], StartsWith("fit: the model fits"));
}

}  // namespace
