// Specification of the in-place editing of a configuration's YAML text (pneu/config/yaml_text.hpp,
// config::with_values_of): a value replaced and every other byte kept, its comments among them; a
// key the text lacks added in its section; what cannot be edited line by line refused by name.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/config/schema.hpp"
#include "pneu/config/yaml_text.hpp"
#include "support/config_error_matcher.hpp"
#include "support/edited_text.hpp"
#include "support/paths.hpp"

namespace pneu::config {
namespace {

using pneu::test::IsConfigError;
using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::Eq;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using ::testing::Throws;
using yaml_text::with_value;

auto refused(const std::string& key, const std::string& reason) {
  return Throws<ConfigError>(IsConfigError(Eq(key), HasSubstr(reason)));
}

// ---------------------------------------------------------------------------------------------
// One value

constexpr const char* kBench =
    "# the bench\n"
    "plant:                  # the model\n"
    "  mass_kg: 17.0         # M: moving mass [kg]\n"
    "  friction:             # Karnopp\n"
    "    static_positive_n: 45.0   # F_S+ [N]\n"
    "    coulomb_positive_n: 35.0  # F_C+ [N]\n"
    "                              # (continued)\n"
    "\n"
    "telemetry:\n"
    "  lcm_url: \"udpm://239.255.76.67:7667?ttl=0#x\"   # a '#' inside quotes\n"
    "  'channel_prefix': 'PNEU_'  # a quoted key\n";

TEST(YamlText, ReplacesAValueAndKeepsEveryOtherByteItsCommentAtItsColumn) {
  const std::string out = with_value(kBench, "plant.friction.static_positive_n", "45.5");
  std::string expected = kBench;
  expected.replace(expected.find("45.0 "), 4, "45.5");
  EXPECT_EQ(out, expected) << "the same length: the comment stays at its column";
  // Longer: the comment moves only as far as it must; shorter: it stays at its column.
  EXPECT_THAT(with_value(kBench, "plant.friction.static_positive_n", "45.31234567"),
              HasSubstr("\n    static_positive_n: 45.31234567  # F_S+ [N]\n"));
  EXPECT_THAT(with_value(kBench, "plant.mass_kg", "9"), HasSubstr("\n  mass_kg: 9            # M: moving mass [kg]\n"));
}

TEST(YamlText, FindsTheValueBesideItsInlineCommentAndInsideQuotes) {
  const std::string text = kBench;
  const auto at = yaml_text::find(text, "telemetry.lcm_url");
  ASSERT_TRUE(at.has_value());
  EXPECT_EQ(text.substr(at->value_begin, at->value_end - at->value_begin), "\"udpm://239.255.76.67:7667?ttl=0#x\"");
  EXPECT_EQ(text.substr(at->comment, 5), "# a '");
  const auto quoted_key = yaml_text::find(text, "telemetry.channel_prefix");
  ASSERT_TRUE(quoted_key.has_value());
  EXPECT_EQ(text.substr(quoted_key->value_begin, quoted_key->value_end - quoted_key->value_begin), "'PNEU_'");
  EXPECT_FALSE(yaml_text::find(text, "plant.friction.viscous_n_s_per_m").has_value());
  EXPECT_FALSE(yaml_text::find(text, "plant.mass").has_value()) << "a key is matched whole";
  EXPECT_THAT(with_value(text, "telemetry.lcm_url", "\"udpm://239.255.76.67:7667?ttl=1\""),
              HasSubstr("  lcm_url: \"udpm://239.255.76.67:7667?ttl=1\"     # a '#' inside quotes\n"))
      << "two characters shorter: the comment at its column";
}

TEST(YamlText, AddsANoteAfterTheCommentAndReplacesAnEarlierNoteOfTheSameWord) {
  const std::string once = with_value(kBench, "plant.mass_kg", "17.5", "identified 2026-11-28: 17.5 +- 0.1 (was 17)");
  EXPECT_THAT(once, HasSubstr("\n  mass_kg: 17.5         # M: moving mass [kg]  # identified 2026-11-28: 17.5 +- 0.1 "
                              "(was 17)\n"));
  const std::string twice = with_value(once, "plant.mass_kg", "18", "identified 2026-11-29: 18 +- 0.2 (was 17.5)");
  EXPECT_THAT(twice, HasSubstr("\n  mass_kg: 18           # M: moving mass [kg]  # identified 2026-11-29: 18 +- 0.2 "
                               "(was 17.5)\n"));
  EXPECT_THAT(twice, Not(HasSubstr("2026-11-28"))) << "the earlier note is replaced, not stacked";
  // A key with no comment gets the note alone.
  EXPECT_THAT(with_value("a:\n  b: 1\n", "a.b", "2", "identified today"), Eq("a:\n  b: 2  # identified today\n"));
}

TEST(YamlText, AddsAKeyTheTextLacksAtTheEndOfItsSectionAfterItsLastCommentLines) {
  const std::string out = with_value(kBench, "plant.friction.viscous_n_s_per_m", "60", "added");
  EXPECT_THAT(out, HasSubstr("    coulomb_positive_n: 35.0  # F_C+ [N]\n"
                             "                              # (continued)\n"
                             "    viscous_n_s_per_m: 60     # added\n"
                             "\n"
                             "telemetry:"));
  // The sections on its way that the text lacks too, indented as the section's keys are.
  EXPECT_THAT(with_value(kBench, "plant.thermal.heat_transfer_w_per_m2_k", "25.7"),
              HasSubstr("                              # (continued)\n"
                        "  thermal:\n"
                        "    heat_transfer_w_per_m2_k: 25.7\n"
                        "\n"));
  EXPECT_THAT(with_value("a:\n    b: 1\n", "a.c.d", "2"), Eq("a:\n    b: 1\n    c:\n        d: 2\n"))
      << "four spaces a level where the text indents by four";
  // A section of its own at the end, after a blank line; a text without its last line's end.
  EXPECT_EQ(with_value("a: 1", "b.c", "2"), "a: 1\n\nb:\n  c: 2\n");
  EXPECT_EQ(with_value("a:\nb: 1\n", "a.c", "2"), "a:\n  c: 2\nb: 1\n") << "a section with no keys yet";
  // Every line of the source kept, one line added.
  const test::Edits e = test::edits(kBench, out);
  EXPECT_THAT(e.lost, IsEmpty());
  EXPECT_THAT(e.replaced, IsEmpty());
  EXPECT_THAT(e.added, ElementsAre("    viscous_n_s_per_m: 60     # added"));
}

TEST(YamlText, ReplacesAListInBlockStyleWholeAndAListInFlowStyleInPlace) {
  const std::string text =
      "setpoints:\n"
      "  schedule:          # the steps\n"
      "    - {t_s: 1.0, position_m: 0.17}\n"
      "    # between\n"
      "    - {t_s: 2.0, position_m: 0.1}\n"
      "  # after\n"
      "  initial_m: 0.2\n"
      "methods: [linearized, nonlinear]  # the methods\n";
  EXPECT_EQ(with_value(text, "setpoints.schedule", "[{t_s: 3, position_m: 0}]"),
            "setpoints:\n"
            "  schedule: [{t_s: 3, position_m: 0}]  # the steps\n"
            "  # after\n"
            "  initial_m: 0.2\n"
            "methods: [linearized, nonlinear]  # the methods\n");
  EXPECT_EQ(with_value(text, "methods", "[nonlinear]"),
            std::string(text).replace(text.find("[linearized, nonlinear]"), 23, "[nonlinear]" + std::string(12, ' ')))
      << "shorter: the comment stays at its column";
  // A list at its key's column.
  EXPECT_EQ(with_value("s:\n- 1\n- 2\nb: 3\n", "s", "[4]"), "s: [4]\nb: 3\n");
}

TEST(YamlText, KeepsTheLinesEndsOfAWindowsText) {
  EXPECT_EQ(with_value("a:\r\n  b: 1  # c\r\n", "a.b", "2"), "a:\r\n  b: 2  # c\r\n");
  EXPECT_EQ(with_value("a:\r\n  b: 1\r\n", "a.d", "2"), "a:\r\n  b: 1\r\n  d: 2\r\n");
}

TEST(YamlText, RefusesWhatCannotBeEditedLineByLineNamingTheKey) {
  const std::string flow = "hal:\n  channels:\n    pressure_p: {register: 1, signed: false}  # input\n";
  EXPECT_THAT([&] { (void)with_value(flow, "hal.channels.pressure_p.register", "5"); },
              refused("hal.channels.pressure_p.register", "hal.channels.pressure_p is a section in flow style"));
  EXPECT_THAT([&] { (void)with_value("a: 1\n", "a.b", "2"); }, refused("a.b", "a is a value, not a section"));
  EXPECT_THAT([&] { (void)with_value("a:\n  - b: 1\n", "a.b", "2"); }, refused("a.b", "a is a list"));
  EXPECT_THAT([&] { (void)with_value("a:\n  b: 1\n", "a", "2"); }, refused("a", "is a section"));
  EXPECT_THAT([&] { (void)with_value("a: &one 1\nb: *one\n", "a", "2"); }, refused("a", "an anchor (&)"));
  EXPECT_THAT([&] { (void)with_value("a: !!float 1\n", "a", "2"); }, refused("a", "a tag (!)"));
  EXPECT_THAT([&] { (void)with_value("a: |\n  text\n", "a", "2"); }, refused("a", "a block scalar"));
  EXPECT_THAT([&] { (void)with_value("a: some\n  words\n", "a", "2"); }, refused("a", "spans lines"));
  EXPECT_THAT([&] { (void)with_value("a: [1,\n  2]\n", "a", "2"); }, refused("a", "spans lines"));
  EXPECT_THAT([&] { (void)with_value("a: 'one\n  two'\n", "a", "2"); }, refused("a", "spans lines"));
  // An alias is a value like another: replaced, the anchor it named left to the other keys.
  EXPECT_EQ(with_value("a: &one 1\nb: *one  # b\n", "b", "2"), "a: &one 1\nb: 2     # b\n");
}

// ---------------------------------------------------------------------------------------------
// A configuration written into its own text (config::with_values_of)

std::string note(const std::string& path, const std::string& was) { return "set " + path + " (was " + was + ")"; }

TEST(ConfigText, AConfigurationWrittenIntoItsOwnTextIsThatTextByteForByte) {
  for (const char* file : {"sim.yaml", "bench.yaml", "hil.yaml", "paper.yaml"}) {
    const std::string text = text_of(test::shipped_config(file));
    EXPECT_EQ(with_values_of(text, load_string(text), {}, note, file), text) << file;
  }
}

// Every shipped configuration, values changed, keys and optional sections added: each of its
// lines kept byte for byte but those of the values changed (their key and whole comment kept), and
// the text loads to the configuration written.
TEST(ConfigText, EveryShippedTextKeepsItsLinesWhenValuesAreWrittenIntoIt) {
  for (const char* file : {"sim.yaml", "bench.yaml", "hil.yaml", "paper.yaml"}) {
    SCOPED_TRACE(file);
    const std::string text = text_of(test::shipped_config(file));
    const Config source = load_string(text);
    Config target = source;
    target.plant.friction.static_positive_n = 47.125;
    target.plant.valve.max_conductance_m3_per_s_pa = 1.7e-8;
    target.controller.predictor.has_model_fit = true;  // a section none of them has
    target.controller.predictor.model_fit = {12.5, 10.0};
    target.hal.has_sim = target.hal.sim.has_plant = true;
    target.hal.sim.plant = source.plant;
    const std::string out = with_values_of(text, target, {"plant.mass_kg"}, note, file);
    EXPECT_EQ(schema::values_of(load_string(out)), schema::values_of(target));
    const test::Edits e = test::edits(text, out);
    EXPECT_THAT(e.lost, IsEmpty());
    ASSERT_EQ(e.replaced.size(), 3u) << "F_S+, C_max, and the mass (always)";
    EXPECT_THAT(e.replaced[0], HasSubstr("mass_kg:"));
    EXPECT_THAT(e.replaced[1], HasSubstr("max_conductance_m3_per_s_pa:"));
    EXPECT_THAT(e.replaced[2], HasSubstr("static_positive_n:"));
    EXPECT_THAT(out, HasSubstr("static_positive_n: 47.125")) << "the value in place";
    EXPECT_THAT(out, HasSubstr("# set plant.friction.static_positive_n (was 45)"));
    EXPECT_THAT(out, HasSubstr("# set plant.mass_kg (was 17)")) << "a key of `always`, its value unchanged";
    // Added: the model fit's section with both keys, and hal.sim with every key of the bench.
    EXPECT_THAT(out, HasSubstr("    model_fit:\n      pressure_residual_pa: 12.5"));
  }
}

TEST(ConfigText, WritesAListWholeAndASectionTheTextLacks) {
  for (const char* file : {"sim.yaml", "bench.yaml"}) {  // the schedule in block style; in flow style, empty
    SCOPED_TRACE(file);
    const std::string text = text_of(test::shipped_config(file));
    Config target = load_string(text);
    target.controller.schedule = {{1.0, 0.05}, {2.5, -0.05}};
    target.plant.has_thermal = true;  // sim.yaml has no plant.thermal; bench.yaml has
    target.plant.thermal.heat_transfer_w_per_m2_k = 12.5;
    const std::string out = with_values_of(text, target, {}, nullptr, file);
    EXPECT_EQ(schema::values_of(load_string(out)), schema::values_of(target));
    EXPECT_THAT(out, HasSubstr("    schedule: [{t_s: 1, position_m: 0.05}, {t_s: 2.5, position_m: -0.05}]"));
    EXPECT_THAT(out, HasSubstr("  thermal:"));
    EXPECT_THAT(out, HasSubstr("    heat_transfer_w_per_m2_k: 12.5"));
    // The list's lines in block style are its value, replaced; nothing else is.
    const test::Edits e = test::edits(text, out);
    if (std::string(file) == "sim.yaml") EXPECT_THAT(e.lost, ElementsAre("      - {t_s: 1.0, position_m: 0.170}"));
    else EXPECT_THAT(e.lost, IsEmpty());
  }
}

// hal.sim.plant gives only the keys it changes, each over plant:'s: a plant: written anew would
// change the simulated bench too; the keys that keep it as it was are written into hal.sim.plant.
TEST(ConfigText, KeepsASimulatedBenchLaidOverPlantAsItWasWhenPlantChanges) {
  std::string text = text_of(test::shipped_config("sim.yaml"));
  const std::string hal = "  backend: sim";
  text.insert(text.find('\n', text.find(hal)) + 1,
              "  sim:                             # the simulated bench: plant: but these\n"
              "    plant:\n"
              "      friction:\n"
              "        static_positive_n: 50.0     # a bench that sticks more\n");
  const Config source = load_string(text);
  ASSERT_EQ(source.hal.sim.plant.friction.coulomb_positive_n, 35.0);
  Config target = source;
  target.plant.friction.coulomb_positive_n = 33.5;
  target.plant.friction.viscous_n_s_per_m = 61.0;
  const std::string out = with_values_of(text, target, {}, nullptr, "sim.yaml");
  EXPECT_EQ(schema::values_of(load_string(out)), schema::values_of(target));
  EXPECT_EQ(load_string(out).hal.sim.plant.friction.coulomb_positive_n, 35.0) << "the bench as it was";
  EXPECT_THAT(out, HasSubstr("        static_positive_n: 50.0     # a bench that sticks more\n"
                             "        coulomb_positive_n: 35\n"
                             "        viscous_n_s_per_m: 60\n"));
  EXPECT_THAT(test::edits(text, out).lost, IsEmpty());
}

TEST(ConfigText, RefusesWhatItCannotWriteInPlace) {
  const std::string bench = text_of(test::shipped_config("bench.yaml"));
  Config target = load_string(bench);
  target.hal.modbus.pressure_p.address = 7;
  EXPECT_THAT([&] { (void)with_values_of(bench, target, {}, nullptr, "bench.yaml"); },
              Throws<ConfigError>(IsConfigError(Eq("hal.modbus.channels.pressure_p.register"),
                                                HasSubstr("hal.modbus.channels.pressure_p is a section in flow style"))));
  // A section is not removed.
  Config no_thermal = load_string(bench);
  no_thermal.plant.has_thermal = false;
  EXPECT_THAT([&] { (void)with_values_of(bench, no_thermal, {}, nullptr, "bench.yaml"); },
              Throws<ConfigError>(IsConfigError(Eq("plant.thermal"), HasSubstr("a section is not removed"))));
  // A source that does not load.
  EXPECT_THAT([&] { (void)with_values_of("plant: [", no_thermal, {}, nullptr, "broken.yaml"); },
              Throws<ConfigError>(IsConfigError(Eq("broken.yaml"), HasSubstr("not valid YAML"))));
}

}  // namespace
}  // namespace pneu::config
