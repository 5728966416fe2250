// Hostile configuration input (issue 6). A matrix derived from the schema (schema::keys_of) over
// the documents it writes for the shipped files, so that a key added to the schema is covered
// without touching this file: every key left out (refused naming its path, unless it is
// optional), given a value of the wrong type, joined by an unknown sibling, misspelt (refused
// naming the typo and the key it stands for, in the file and in an override), and every number set
// to extreme values (loaded or refused as a ConfigError naming the key, never another exception or
// a crash), one test per family looping over the keys; the shipped files mark optional exactly the
// keys the schema lets be left out. Then values known to be out of range; documents nested too
// deeply, too large or multiplied by aliases; a sample of the matrix through the real pneud and
// `pneu-plant serve`: exit code 2, the key path and the reason on stderr, and nothing driven (no
// connection to the I/O module, no output file).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/config/schema.hpp"
#include "support/config_error_matcher.hpp"
#include "support/child_process.hpp"

namespace pneu::config {
namespace {

using pneu::test::IsConfigError;
using schema::KeyKind;

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

// ---------------------------------------------------------------------------------------------
// The shipped files, the documents the schema writes for them, their keys, edits by key path

// The files the matrix is generated from, by the name its cases carry.
const std::vector<std::pair<std::string, std::string>> kShippedFiles = {{"Sim", "config/sim.yaml"},
                                                                        {"Hil", "config/hil.yaml"}};

std::string shipped_text(const std::string& file) {
  for (const auto& [name, relative] : kShippedFiles)
    if (name == file) {
      const std::string text = test::slurp(fs::path(PNEU_SOURCE_DIR) / relative);
      if (text.empty()) throw std::runtime_error("cannot read " + relative);
      return text;
    }
  throw std::logic_error("no shipped file " + file);
}

// What the schema writes for a shipped file (to_yaml): its values under every key of the schema,
// the optional keys it leaves out included.
const std::string& written(const std::string& file) {
  static std::map<std::string, std::string> documents;
  auto it = documents.find(file);
  if (it == documents.end()) it = documents.emplace(file, to_yaml(load_string(shipped_text(file)))).first;
  return it->second;
}

// One key of the matrix.
struct Key {
  std::string file;  // "Sim", "Hil"
  std::string path;  // as ConfigError names it: "controller.setpoints.schedule[0].t_s"
  KeyKind kind = KeyKind::kNumber;
  bool optional = false;
};

// Every key of the documents written for the shipped files, as the schema lists them; a key of
// hil.yaml that sim.yaml has too, of the same kind and optionality, only once (from sim.yaml).
const std::vector<Key>& shipped_keys() {
  static const std::vector<Key> keys = [] {
    std::vector<Key> all;
    for (const auto& [file, relative] : kShippedFiles)
      for (const schema::KeyInfo& k : schema::keys_of(load_string(written(file)))) {
        const Key key{file, k.path, k.kind, k.presence == schema::Presence::kOptional};
        const bool seen = std::any_of(all.begin(), all.end(), [&](const Key& o) {
          return o.path == key.path && o.kind == key.kind && o.optional == key.optional;
        });
        if (!seen) all.push_back(key);
      }
    return all;
  }();
  return keys;
}

std::vector<Key> keys_where(const std::function<bool(const Key&)>& keep) {
  std::vector<Key> out;
  for (const Key& k : shipped_keys())
    if (keep(k)) out.push_back(k);
  return out;
}

// "a.b[0].c" as steps: a key, or the index of a list element.
struct Step {
  std::string key;
  int index = -1;
};

std::vector<Step> steps_of(const std::string& path) {
  std::vector<Step> steps;
  std::stringstream ss(path);
  for (std::string part; std::getline(ss, part, '.');) {
    const auto bracket = part.find('[');
    steps.push_back({part.substr(0, bracket)});
    for (auto b = bracket; b != std::string::npos; b = part.find('[', b + 1))
      steps.push_back({"", std::stoi(part.substr(b + 1))});
  }
  return steps;
}

// The parent of the node at `path`, and the key it has there. yaml-cpp nodes are handles: walk
// with fresh copies, never by assigning one handle to another (that would overwrite the node).
std::pair<YAML::Node, std::string> parent_of(YAML::Node root, const std::string& path) {
  const std::vector<Step> steps = steps_of(path);
  std::vector<YAML::Node> chain{root};
  for (std::size_t i = 0; i + 1 < steps.size(); ++i)
    chain.push_back(steps[i].index >= 0 ? chain.back()[steps[i].index] : chain.back()[steps[i].key]);
  if (steps.back().index >= 0) throw std::logic_error("not a key: " + path);
  return {chain.back(), steps.back().key};
}

// The document written for a shipped file, parsed, edited and written back to YAML.
std::string edited(const std::string& file, const std::function<void(YAML::Node&)>& edit) {
  YAML::Node root = YAML::Load(written(file));
  edit(root);
  return YAML::Dump(root) + "\n";
}

std::function<void(YAML::Node&)> removing(const std::string& path) {
  return [path](YAML::Node& root) {
    auto [parent, key] = parent_of(root, path);
    if (!parent.remove(key)) throw std::logic_error("no key " + path);
  };
}

// Sets the key at `path` to the YAML value `value` (creating it when absent).
std::function<void(YAML::Node&)> setting(const std::string& path, const std::string& value) {
  return [path, value](YAML::Node& root) {
    auto [parent, key] = parent_of(root, path);
    parent[key] = YAML::Load(value);
  };
}

std::string test_name(std::string text) {
  for (char& c : text)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  std::string out;
  for (char c : text)
    if (!(c == '_' && !out.empty() && out.back() == '_')) out += c;
  while (!out.empty() && out.back() == '_') out.pop_back();
  return out;
}

std::string trace(const Key& k) { return k.file + " " + k.path; }

// ---------------------------------------------------------------------------------------------
// Matchers

auto refuses(const std::string& key_path, const std::string& reason) {
  return ::testing::Throws<ConfigError>(IsConfigError(
      ::testing::Eq(key_path), AllOf(HasSubstr(key_path + ": "), HasSubstr(reason))));
}

auto loading(std::string yaml, std::vector<std::string> overrides = {}, std::string origin = "<string>") {
  return [yaml = std::move(yaml), overrides = std::move(overrides), origin = std::move(origin)] {
    (void)load_string(yaml, overrides, origin);
  };
}

// ---------------------------------------------------------------------------------------------
// What the matrix covers

// Both files, every kind of key, and every key of the schema (list entries as "list[]").
TEST(ShippedKeys, CoverBothFilesEveryKindAndEveryKeyOfTheSchema) {
  for (const auto& [file, relative] : kShippedFiles)
    EXPECT_TRUE(std::any_of(shipped_keys().begin(), shipped_keys().end(),
                            [&](const Key& k) { return k.file == file; }))
        << relative;
  for (KeyKind kind : {KeyKind::kNumber, KeyKind::kInteger, KeyKind::kBoolean, KeyKind::kText, KeyKind::kChoice,
                       KeyKind::kNumberOrAuto, KeyKind::kNames, KeyKind::kList, KeyKind::kSection})
    EXPECT_TRUE(std::any_of(shipped_keys().begin(), shipped_keys().end(),
                            [&](const Key& k) { return k.kind == kind; }))
        << static_cast<int>(kind);
  std::set<std::string> covered;
  for (const Key& k : shipped_keys()) covered.insert(std::regex_replace(k.path, std::regex(R"(\[\d+\])"), "[]"));
  // hal.sim.plant's keys are plant:'s, read by the same descriptions (covered here under plant.);
  // the section's own reading, laid over plant:, is specified in test_config.cpp (SimulatedBench).
  // plant.thermal is in neither file (sim.yaml and hil.yaml keep the polytropic process), nor is
  // controller.predictor.model_fit (pneud --identify writes it): their reading and refusals are
  // specified in test_config.cpp (ThermalSection, ModelFitSection).
  for (const schema::KeyInfo& k : schema::all_keys()) {
    if (k.path.starts_with("hal.sim") || k.path.starts_with("plant.thermal") ||
        k.path.starts_with("controller.predictor.model_fit"))
      continue;
    EXPECT_TRUE(covered.count(k.path)) << k.path;
  }
  EXPECT_GT(shipped_keys().size(), 150u);
}

// The comments of the shipped files, which users read (and docs/configuration.md is generated
// from), say "optional" on exactly the keys the schema lets be left out.
TEST(ShippedFiles, MarkOptionalExactlyTheKeysTheSchemaLetsBeLeftOut) {
  for (const char* relative : {"config/sim.yaml", "config/paper.yaml", "config/hil.yaml", "config/bench.yaml"}) {
    const std::string text = test::slurp(fs::path(PNEU_SOURCE_DIR) / relative);
    std::vector<std::string> lines;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    std::map<std::string, schema::Presence> presence;
    for (const schema::KeyInfo& k : schema::keys_of(load_string(text))) presence[k.path] = k.presence;
    int checked = 0;
    const std::function<void(const YAML::Node&, const std::string&)> walk = [&](const YAML::Node& node,
                                                                                 const std::string& path) {
      if (node.IsSequence()) {
        for (std::size_t i = 0; i < node.size(); ++i)
          if (node[i].IsMap()) walk(node[i], path + "[" + std::to_string(i) + "]");
        return;
      }
      for (const auto& kv : node) {
        const std::string child = path.empty() ? kv.first.Scalar() : path + "." + kv.first.Scalar();
        const std::size_t line = static_cast<std::size_t>(kv.first.Mark().line);
        const std::string comment = line < lines.size() && lines[line].find(" #") != std::string::npos
                                        ? lines[line].substr(lines[line].find(" #"))
                                        : "";
        SCOPED_TRACE(std::string(relative) + " " + child + ":" + comment);
        ASSERT_TRUE(presence.count(child)) << "not a key of the schema";
        EXPECT_EQ(comment.find("optional") != std::string::npos, presence[child] == schema::Presence::kOptional);
        ++checked;
        if (kv.second.IsMap() || kv.second.IsSequence()) walk(kv.second, child);
      }
    };
    walk(YAML::Load(text), "");
    EXPECT_GT(checked, 100) << relative;
  }
}

// ---------------------------------------------------------------------------------------------
// The matrix: every key left out

TEST(ShippedFiles, EveryRequiredKeyLeftOutIsRefusedNamingItsPath) {
  const std::vector<Key> keys = keys_where([](const Key& k) { return !k.optional; });
  ASSERT_GT(keys.size(), 150u);
  for (const Key& k : keys) {
    SCOPED_TRACE(trace(k));
    EXPECT_THAT(loading(edited(k.file, removing(k.path))), refuses(k.path, "missing"));
  }
}

TEST(ShippedFiles, EveryOptionalKeyLeftOutLoadsWithItsDefault) {
  const std::vector<Key> keys = keys_where([](const Key& k) { return k.optional; });
  ASSERT_GT(keys.size(), 20u);
  for (const Key& k : keys) {
    SCOPED_TRACE(trace(k));
    const Config defaulted = load_string(edited(k.file, removing(k.path)));
    // ... the default of its struct: what it had in a configuration of all defaults.
    const auto value_of = [&](const Config& c) {
      std::string out;
      for (const auto& [path, value] : schema::values_of(c))
        if (path == k.path || path.starts_with(k.path + ".")) out += path + "=" + value + "\n";
      return out;
    };
    if (k.path.find('[') == std::string::npos) {
      EXPECT_EQ(value_of(defaulted), value_of(Config{}));
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The matrix: every key given a value of the wrong type

TEST(ShippedFiles, EveryKeyOfTheWrongTypeIsRefusedNamingItsPath) {
  const std::string mapping = "{a: 1}", list = "[1, 2]", text = "x";
  int cases = 0;
  for (const Key& k : shipped_keys()) {
    std::vector<std::string> wrong;
    switch (k.kind) {
      case KeyKind::kNumber:
      case KeyKind::kInteger:
      case KeyKind::kBoolean:
      case KeyKind::kNumberOrAuto: wrong = {mapping, list, text}; break;
      case KeyKind::kText:
      case KeyKind::kChoice: wrong = {mapping, list}; break;  // "x" may be a fine text
      case KeyKind::kNames:
      case KeyKind::kList: wrong = {mapping, text}; break;
      case KeyKind::kSection: wrong = {list, text}; break;
    }
    for (const std::string& value : wrong) {
      SCOPED_TRACE(trace(k) + " = " + value);
      EXPECT_THAT(loading(edited(k.file, setting(k.path, value))), refuses(k.path, "expected"));
      ++cases;
    }
  }
  EXPECT_GT(cases, 400);
}

// ---------------------------------------------------------------------------------------------
// The matrix: an unknown key beside every key

TEST(ShippedFiles, EveryUnknownKeyBesideAKnownOneIsRefusedNamingTheUnknownKey) {
  for (const Key& k : shipped_keys()) {
    SCOPED_TRACE(trace(k));
    const std::string unknown = k.path + "_unknown";
    EXPECT_THAT(loading(edited(k.file, setting(unknown, "1"))), refuses(unknown, "unknown key"));
  }
}

// ---------------------------------------------------------------------------------------------
// The matrix: every key misspelt, in the file and in an override

// Two typos of a key: two adjacent characters swapped (the first pair that differs), and the
// last character dropped.
struct Typo {
  Key key;
  std::string typed;  // the misspelt key
};

std::string leaf_of(const std::string& path) { return path.substr(path.rfind('.') + 1); }

std::vector<Typo> typos() {
  std::vector<Typo> out;
  for (const Key& k : shipped_keys()) {
    const std::string leaf = leaf_of(k.path);
    std::string swapped = leaf;
    for (std::size_t i = 0; i + 1 < swapped.size(); ++i)
      if (swapped[i] != swapped[i + 1]) {
        std::swap(swapped[i], swapped[i + 1]);
        break;
      }
    if (swapped != leaf) out.push_back({k, swapped});
    if (leaf.size() > 1) out.push_back({k, leaf.substr(0, leaf.size() - 1)});
  }
  return out;
}

// Renames the key at `path` to `typed`, keeping its value.
std::function<void(YAML::Node&)> renaming(const std::string& path, const std::string& typed) {
  return [path, typed](YAML::Node& root) {
    auto [parent, key] = parent_of(root, path);
    parent[typed] = YAML::Clone(parent[key]);
    if (!parent.remove(key)) throw std::logic_error("no key " + path);
  };
}

std::string with_leaf(const std::string& path, const std::string& leaf) {
  return path.substr(0, path.rfind('.') + 1) + leaf;
}

// The loader meets the key missing first when it is required, the typo unknown first when it is
// optional: either way the refusal names the typo, and the key it stands for.
TEST(ShippedFiles, EveryMisspeltKeyIsRefusedNamingTheTypoAndTheKeyItStandsFor) {
  const std::vector<Typo> all = typos();
  ASSERT_GT(all.size(), 300u);
  for (const Typo& t : all) {
    SCOPED_TRACE(trace(t.key) + " as " + t.typed);
    const std::string typed_path = with_leaf(t.key.path, t.typed);
    // A typo as near two keys (pulse_ for pulse_s and pulse_v) names both: the key is one of them.
    const std::string leaf = leaf_of(t.key.path);
    EXPECT_THAT(loading(edited(t.key.file, renaming(t.key.path, t.typed))),
                ::testing::Throws<ConfigError>(IsConfigError(
                    ::testing::Eq(typed_path),
                    AllOf(HasSubstr(typed_path + ": unknown key; did you mean "),
                          ::testing::ContainsRegex("did you mean ([a-z0-9_]+ or )*" + leaf + "( or [a-z0-9_]+)*\\?")))));
  }
}

// An override sets keys outside lists, and values, not sections. The key the override stands for
// is in the file too: a typo as close to one of its siblings (following_error_ for
// following_error_m and following_error_s) names both.
TEST(ShippedFiles, EveryMisspeltOverrideIsRefusedNamingTheTypoAndTheKeyItStandsFor) {
  int cases = 0;
  for (const Typo& t : typos()) {
    if (t.key.path.find('[') != std::string::npos || t.key.kind == KeyKind::kSection) continue;
    SCOPED_TRACE(trace(t.key) + " as " + t.typed);
    const std::string typed_path = with_leaf(t.key.path, t.typed);
    const std::string meant = leaf_of(t.key.path);
    EXPECT_THAT(loading(written(t.key.file), {typed_path + "=1"}),
                ::testing::Throws<ConfigError>(IsConfigError(
                    ::testing::Eq(typed_path),
                    ::testing::ContainsRegex("^" + typed_path + ": unknown key; did you mean ([a-z0-9_]+, |[a-z0-9_]+ or )*" +
                                             meant + "( or [a-z0-9_]+)?\\?$"))));
    ++cases;
  }
  EXPECT_GT(cases, 250);
}

// ---------------------------------------------------------------------------------------------
// The matrix: every number set to extreme values

// Checks between two keys whose refusal names the other key of the pair and not this one (only
// in words: "the stroke", "the supply pressure", "the soft limits").
const std::map<std::string, std::string> kRefusedUnderAnotherKey = {
    {"plant.geometry.stroke_m", "controller.supervisor.position_min_m"},
    {"plant.gas.supply_pressure_pa", "controller.supervisor.pressure_max_pa"},
    {"controller.soft_limit_max_m", "controller.setpoints.initial_m"},
};

// Loads, or is refused as a ConfigError naming the key: by its path, or in the message of a key
// checked against it (as rod_diameter_m: "must be smaller than geometry.bore_diameter_m").
TEST(ShippedFiles, EveryNumberSetToAnExtremeLoadsOrIsRefusedNamingTheKeyNeverOtherwise) {
  const std::vector<std::string> extremes = {"-1e300", "1e300", ".nan", ".inf", "-.inf", "-0", "0"};
  int cases = 0;
  for (const Key& k : shipped_keys()) {
    if (k.kind != KeyKind::kNumber && k.kind != KeyKind::kInteger && k.kind != KeyKind::kNumberOrAuto) continue;
    for (const std::string& value : extremes) {
      SCOPED_TRACE(trace(k) + " = " + value);
      ++cases;
      const std::string yaml = edited(k.file, setting(k.path, value));
      try {
        (void)load_string(yaml);
      } catch (const ConfigError& error) {
        const std::string leaf = leaf_of(k.path);
        const auto other = kRefusedUnderAnotherKey.find(k.path);
        EXPECT_TRUE(error.key_path() == k.path || std::string(error.what()).find(leaf) != std::string::npos ||
                    (other != kRefusedUnderAnotherKey.end() && error.key_path() == other->second))
            << "refused, but naming neither " << k.path << " nor " << leaf << ": " << error.what();
        if (value == ".nan" || value == ".inf" || value == "-.inf") {
          EXPECT_EQ(error.key_path(), k.path) << error.what();
        }
      } catch (const std::exception& other) {
        ADD_FAILURE() << "not a ConfigError: " << other.what();
      } catch (...) {
        ADD_FAILURE() << "not a ConfigError, not even a std::exception";
      }
    }
  }
  EXPECT_GT(cases, 700);
}

// The list of exceptions names keys of the shipped files only: it cannot hide a key that is gone
// or renamed.
TEST(ListedExceptions, AreAllKeysOfTheShippedFiles) {
  const auto shipped = [](const std::string& path) {
    return std::any_of(shipped_keys().begin(), shipped_keys().end(), [&](const Key& k) { return k.path == path; });
  };
  for (const auto& [path, other] : kRefusedUnderAnotherKey) {
    EXPECT_TRUE(shipped(path)) << path;
    EXPECT_TRUE(shipped(other)) << other;
  }
}

// ---------------------------------------------------------------------------------------------
// Values known to be out of range

struct OutOfRangeCase {
  std::string name;
  std::string file;
  std::string path;    // the key set
  std::string value;   // to this YAML value
  std::string names;   // the key path the refusal names
  std::string reason;  // and the reason it gives
};

void PrintTo(const OutOfRangeCase& c, std::ostream* os) { *os << c.path << " = " << c.value; }

class OutOfRange : public ::testing::TestWithParam<OutOfRangeCase> {};

TEST_P(OutOfRange, IsRefusedNamingTheKeyAndTheReason) {
  const OutOfRangeCase& c = GetParam();
  EXPECT_THAT(loading(edited(c.file, setting(c.path, c.value))), refuses(c.names, c.reason));
}

INSTANTIATE_TEST_SUITE_P(
    Limits, OutOfRange,
    ::testing::Values(
        OutOfRangeCase{"LoopRateOfZero", "Sim", "controller.rate_hz", "0", "controller.rate_hz", "must be in [1, 20000]"},
        OutOfRangeCase{"LoopRateAbove20kHz", "Sim", "controller.rate_hz", "20001", "controller.rate_hz", "must be in [1, 20000]"},
        OutOfRangeCase{"NegativeMass", "Sim", "plant.mass_kg", "-1", "plant.mass_kg", "must be > 0 (got -1)"},
        OutOfRangeCase{"ZeroMass", "Sim", "plant.mass_kg", "0", "plant.mass_kg", "must be > 0"},
        OutOfRangeCase{"TcpPortBeyond65535", "Hil", "hal.modbus.port", "70000", "hal.modbus.port", "must be in [1, 65535]"},
        OutOfRangeCase{"TcpPortZero", "Hil", "hal.modbus.port", "0", "hal.modbus.port", "must be in [1, 65535]"},
        OutOfRangeCase{"FractionalTcpPort", "Hil", "hal.modbus.port", "1502.5", "hal.modbus.port", "expected an integer"},
        OutOfRangeCase{"PressureCeilingBelowTheSupply", "Sim", "controller.supervisor.pressure_max_pa", "6.0e5",
                       "controller.supervisor.pressure_max_pa", "must exceed the supply pressure"},
        OutOfRangeCase{"PressureFloorAboveTheExhaust", "Sim", "controller.supervisor.pressure_min_pa", "1.5e5",
                       "controller.supervisor.pressure_min_pa", "must lie below the exhaust pressure"},
        OutOfRangeCase{"PositionRangeInsideTheStroke", "Sim", "controller.supervisor.position_max_m", "0.2",
                       "controller.supervisor.position_max_m", "must contain the stroke"},
        OutOfRangeCase{"TickIntervalCheckShorterThanTheLoopPeriod", "Sim", "controller.supervisor.max_tick_interval_s",
                       "0.0005", "controller.supervisor.max_tick_interval_s", "must exceed the loop period"},
        OutOfRangeCase{"NegativeOverrunCount", "Sim", "controller.supervisor.overruns_in_a_row", "-1",
                       "controller.supervisor.overruns_in_a_row", "must be in [0, 1000000]"},
        OutOfRangeCase{"RealtimePriority100", "Sim", "controller.realtime.priority", "100", "controller.realtime.priority",
                       "must be in [0, 99]"},
        OutOfRangeCase{"CpuBelowMinusOne", "Sim", "controller.realtime.cpu", "-2", "controller.realtime.cpu",
                       "must be a CPU number"},
        OutOfRangeCase{"UnitIdZero", "Hil", "hal.modbus.unit_id", "0", "hal.modbus.unit_id", "must be in [1, 247]"},
        OutOfRangeCase{"UnitId248", "Hil", "hal.modbus.unit_id", "248", "hal.modbus.unit_id", "must be in [1, 247]"},
        OutOfRangeCase{"BaudBelow300", "Hil", "hal.modbus.baud", "299", "hal.modbus.baud", "must be in [300, 4000000]"},
        OutOfRangeCase{"NineDataBits", "Hil", "hal.modbus.data_bits", "9", "hal.modbus.data_bits", "must be in [5, 8]"},
        OutOfRangeCase{"ThreeStopBits", "Hil", "hal.modbus.stop_bits", "3", "hal.modbus.stop_bits", "must be 1 or 2"},
        OutOfRangeCase{"RegisterBeyond65535", "Hil", "hal.modbus.channels.position.register", "70000",
                       "hal.modbus.channels.position.register", "must be in [0, 65535]"},
        OutOfRangeCase{"RawCountBeyondAnUnsignedRegister", "Hil", "hal.modbus.channels.position.raw_max", "65536",
                       "hal.modbus.channels.position.raw_max", "16-bit register"},
        OutOfRangeCase{"ReconnectCeilingBelowItsFloor", "Hil", "hal.modbus.reconnect_max_s", "0.01",
                       "hal.modbus.reconnect_max_s", "must be in [0.05, 600]"},
        OutOfRangeCase{"AdcOf25Bits", "Sim", "sensors.position.adc_bits", "25", "sensors.position.adc_bits", "1..24"},
        OutOfRangeCase{"NegativeSeed", "Sim", "sensors.seed", "-1", "sensors.seed", "must be >= 0"},
        OutOfRangeCase{"PolytropicIndexBelowOne", "Sim", "plant.gas.polytropic_index", "0.9", "plant.gas.polytropic_index",
                       "must be in [1, 1.4]"},
        OutOfRangeCase{"CriticalPressureRatioOfOne", "Sim", "plant.valve.critical_pressure_ratio", "1",
                       "plant.valve.critical_pressure_ratio", "must be in (0, "},
        OutOfRangeCase{"SmoothingAboveOne", "Sim", "controller.differentiator.smoothing", "1.5",
                       "controller.differentiator.smoothing", "must be in (0, 1]"},
        OutOfRangeCase{"SoftLimitBeyondTheStroke", "Sim", "controller.soft_limit_max_m", "0.3",
                       "controller.soft_limit_max_m", "must lie inside the stroke"},
        OutOfRangeCase{"HealthPeriodOfZero", "Sim", "telemetry.health_period_s", "0", "telemetry.health_period_s",
                       "must be in [0.01, 60]"},
        OutOfRangeCase{"CommandBurstBelowOne", "Sim", "commands.burst", "0.5", "commands.burst", "must be in [1, 1000]"},
        OutOfRangeCase{"EstopAndValvePowerOnOneLine", "Sim", "hal.gpio.valve_power_line", "17",
                       "hal.gpio.valve_power_line", "must differ from estop_line"},
        OutOfRangeCase{"MaxStepOfOneSecond", "Sim", "plant.max_step_s", "1", "plant.max_step_s", "must be in [1e-07, 0.01]"}),
    [](const auto& p) { return p.param.name; });

// ---------------------------------------------------------------------------------------------
// Documents too deep, too large, or multiplied by aliases

std::string repeated(const std::string& piece, std::size_t n) {
  std::string s;
  s.reserve(piece.size() * n);
  for (std::size_t i = 0; i < n; ++i) s += piece;
  return s;
}

// 100,000 levels in each way YAML nests. yaml-cpp 0.7 (Debian 12) recurses once per level but
// stops itself at 500 with "bad file"; the loader refuses them first, saying why.
struct DeepDocument {
  std::string name;
  std::function<std::string()> text;  // made when the test runs: gtest copies its parameters
};

void PrintTo(const DeepDocument& d, std::ostream* os) { *os << d.name; }

std::vector<DeepDocument> deep_documents() {
  constexpr std::size_t n = 100000;
  return {
      {"FlowSequences", [] { return "plant: " + std::string(n, '[') + std::string(n, ']') + "\n"; }},
      {"UnclosedFlowSequences", [] { return "plant: " + std::string(n, '[') + "\n"; }},
      {"FlowMappings", [] { return "plant: " + repeated("{a: ", n) + "1" + std::string(n, '}') + "\n"; }},
      {"MixedFlowCollections", [] { return "plant: " + repeated("[{a: ", n / 2) + "\n"; }},
      {"CompactBlockSequences", [] { return "plant:\n  " + repeated("- ", n) + "x\n"; }},
      {"BlockMappingsByIndentation",
       [] {  // one more space per level: 1,000 levels is 500 kB
         std::string yaml = "plant:\n";
         for (std::size_t i = 1; i <= 1000; ++i) yaml += std::string(i, ' ') + "a:\n";
         return yaml;
       }},
      {"BlockSequencesAtTheirKeysColumn",
       [] {  // "- a:" at the key's own column
         std::string yaml = "plant:\n";
         for (std::size_t i = 0; i < 500; ++i) yaml += std::string(2 * i, ' ') + "- a:\n";
         return yaml;
       }},
      {"ExplicitKeys", [] { return repeated("? ", n) + "x\n"; }},
      {"FlowSequencesAfterAnchorsAndTags", [] { return "plant: " + repeated("&a !!seq [", n) + "\n"; }},
  };
}

class DeeplyNestedDocument : public ::testing::TestWithParam<DeepDocument> {};

TEST_P(DeeplyNestedDocument, IsRefusedNamingTheOriginAndTheReason) {
  EXPECT_THAT(loading(GetParam().text(), {}, "deep.yaml"), refuses("deep.yaml", "nested too deeply: more than 64 levels"));
}

INSTANTIATE_TEST_SUITE_P(HundredThousandLevels, DeeplyNestedDocument, ::testing::ValuesIn(deep_documents()),
                         [](const auto& p) { return p.param.name; });

TEST(NestingScan, NamesTheFirstLineBeyondTheLimit) {
  std::string yaml = "plant:\n";
  for (std::size_t i = 1; i <= 100; ++i) yaml += std::string(i, ' ') + "a:\n";
  // Line 1 opens the first level, line k the k-th: line 65 is the first beyond 64.
  EXPECT_THAT(loading(yaml, {}, "deep.yaml"), refuses("deep.yaml", "more than 64 levels at line 65"));
}

TEST(NestingScan, NestingWithinTheLimitIsParsedAndJudgedByTheSchema) {
  // The top-level mapping and 60 flow sequences.
  EXPECT_THAT(loading("plant: " + std::string(60, '[') + std::string(60, ']') + "\n"),
              refuses("plant", "expected a mapping"));
}

TEST(NestingScan, BracketsInCommentsQuotesAndBlockScalarsDoNotCount) {
  const std::string deep = std::string(200, '[');
  const std::string yaml = edited("Sim", setting("hal.gpio.consumer", "\"" + deep + "\"")) +
                           "# " + deep + "\n";
  EXPECT_EQ(load_string(yaml).hal.gpio.consumer, deep);
  // A block scalar whose text is deep in brackets and indentation, as the value of an unknown
  // key: refused by the schema, not by the nesting scan.
  std::string block = "notes: |\n";
  for (int i = 0; i < 200; ++i) block += "  " + std::string(static_cast<std::size_t>(i), ' ') + "[{ line\n";
  EXPECT_THAT(loading(shipped_text("Sim") + block), refuses("notes", "unknown key"));
}

// Random documents in every style yaml-cpp's emitter writes (block and flow collections,
// collections as keys, text full of YAML's indicators quoted as needed, literal block scalars),
// nested exactly `depth` collections deep along one path.
std::string indicator_text(std::mt19937& rng) {
  static const std::vector<std::string> pieces = {"a",  "[",  "]",  "{",  "}",   "#",  " #", "'",  "\"", "|", ">",
                                                  "- ", "? ", ": ", ",",  "\n", "x y", "&a", "*a", "!!", "\\", "  "};
  std::string s;
  for (int n = std::uniform_int_distribution<int>(0, 5)(rng); n > 0; --n)
    s += pieces[std::uniform_int_distribution<std::size_t>(0, pieces.size() - 1)(rng)];
  return s;
}

void emit_nested(YAML::Emitter& e, std::mt19937& rng, int depth) {
  const auto pick = [&](int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng); };
  if (depth == 0) {
    const std::string text = indicator_text(rng);
    const int style = pick(4);
    if (style == 1 && text.find('\n') != std::string::npos) e << YAML::Literal;
    else if (style == 2) e << YAML::DoubleQuoted;
    else if (style == 3) e << YAML::SingleQuoted;
    e << text;
    return;
  }
  if (pick(3) == 0) e << YAML::Flow;
  const int n = 1 + pick(3), deep = pick(n);
  const auto sibling_depth = [&] { return pick(std::min(depth, 3)); };  // shallower than the path
  if (pick(2) == 0) {
    e << YAML::BeginSeq;
    for (int i = 0; i < n; ++i) emit_nested(e, rng, i == deep ? depth - 1 : sibling_depth());
    e << YAML::EndSeq;
  } else {
    e << YAML::BeginMap;
    for (int i = 0; i < n; ++i) {
      e << YAML::Key;
      if (depth > 3 && pick(6) == 0) emit_nested(e, rng, 1 + pick(2));  // a collection as the key
      else e << "k" + std::to_string(i) + indicator_text(rng);
      e << YAML::Value;
      emit_nested(e, rng, i == deep ? depth - 1 : sibling_depth());
    }
    e << YAML::EndMap;
  }
}

// sim.yaml with a random document `depth` deep under the unknown key "extra": 1 + depth levels.
std::string with_random_extra(std::mt19937& rng, int depth) {
  YAML::Emitter e;
  e.SetIndent(static_cast<std::size_t>(2 + std::uniform_int_distribution<int>(0, 2)(rng)));
  emit_nested(e, rng, depth);
  if (!e.good()) throw std::logic_error("emitter: " + e.GetLastError());
  std::string extra = "extra:\n";
  std::istringstream in(e.c_str());
  for (std::string line; std::getline(in, line);) extra += "  " + line + "\n";
  return shipped_text("Sim") + extra;
}

TEST(NestingScan, RandomDocumentsWithinTheLimitAreParsed) {
  std::mt19937 rng(6);  // fixed seed: reproducible
  for (int trial = 0; trial < 300; ++trial) {
    const int depth = 1 + trial % 62;  // up to 63 levels with "extra"
    const std::string yaml = with_random_extra(rng, depth);
    EXPECT_THAT(loading(yaml), refuses("extra", "unknown key")) << "depth " << depth << ":\n" << yaml;
  }
}

TEST(NestingScan, RandomDocumentsBeyondTheLimitAreRefusedBeforeParsing) {
  std::mt19937 rng(66);
  for (int trial = 0; trial < 300; ++trial) {
    const int depth = 64 + trial % 100;  // from 65 levels with "extra" on
    const std::string yaml = with_random_extra(rng, depth);
    EXPECT_THAT(loading(yaml, {}, "deep.yaml"), refuses("deep.yaml", "nested too deeply")) << "depth " << depth;
  }
}

TEST(NestingScan, InAnOverrideValueIsRefusedNamingTheKey) {
  EXPECT_THAT(loading(shipped_text("Sim"), {"plant.mass_kg=" + std::string(100000, '[')}),
              refuses("plant.mass_kg", "nested too deeply"));
}

TEST(NestingScan, ListOfListsBuiltByAnchorsIsNotNestedTextAndIsJudgedByTheSchema) {
  // 20,000 levels of lists, each element an alias of the previous list: deep as a graph, flat as
  // text (yaml-cpp shares an aliased node, it does not copy it).
  std::string yaml = "l0: &l0 [x]\n";
  for (int i = 1; i < 20000; ++i)
    yaml += "l" + std::to_string(i) + ": &l" + std::to_string(i) + " [*l" + std::to_string(i - 1) + "]\n";
  yaml += "plant: *l19999\n";
  EXPECT_THAT(loading(yaml), refuses("plant", "expected a mapping"));
}

TEST(LargeDocument, AboveOneMebibyteIsRefusedBeforeParsing) {
  // 2 MiB of one flat list: yaml-cpp would take seconds and about 500 MB to parse it.
  std::string yaml = "plant: [";
  while (yaml.size() < (2u << 20)) yaml += "0,";
  yaml += "0]\n";
  EXPECT_THAT(loading(yaml, {}, "large.yaml"), refuses("large.yaml", "too large: "));
  EXPECT_THAT(loading(yaml, {}, "large.yaml"), refuses("large.yaml", "at most 1048576 (1 MiB)"));
}

TEST(LargeDocument, OfExactlyOneMebibyteIsParsed) {
  std::string yaml = shipped_text("Sim");
  yaml += repeated("#", (1u << 20) - yaml.size() - 1) + "\n";
  ASSERT_EQ(yaml.size(), 1u << 20);
  EXPECT_NO_THROW((void)load_string(yaml));
}

TEST(LargeDocument, FileAboveOneMebibyteIsRefusedByItsSizeNamingThePath) {
  const fs::path path = fs::temp_directory_path() / ("pneu_large_" + std::to_string(::getpid()) + ".yaml");
  {
    std::ofstream out(path);
    out << shipped_text("Sim") << repeated("# padding\n", 200000);
  }
  EXPECT_THAT([&] { (void)load_file(path); }, refuses(path.string(), "too large: "));
  fs::remove(path);
}

TEST(LargeDocument, InAnOverrideValueIsRefusedNamingTheKey) {
  EXPECT_THAT(loading(shipped_text("Sim"), {"controller.setpoints.schedule=[" + repeated("0,", 600000) + "0]"}),
              refuses("controller.setpoints.schedule", "too large"));
}

// "Billion laughs": nine levels of ten aliases of the level below, 10^9 leaves if expanded.
// yaml-cpp shares aliased nodes instead of copying them, and the loader only walks the keys of
// its schema, so nothing is expanded.
std::string laughs(const std::string& bottom) {
  std::string yaml = "l0: &l0 " + bottom + "\n";
  for (int i = 1; i <= 9; ++i) {
    yaml += "l" + std::to_string(i) + ": &l" + std::to_string(i) + " [";
    for (int j = 0; j < 10; ++j) yaml += std::string(j ? ", " : "") + "*l" + std::to_string(i - 1);
    yaml += "]\n";
  }
  return yaml;
}

std::string indented(const std::string& text, const std::string& by) {
  std::string out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out += by + line + "\n";
  return out;
}

TEST(AliasExpansion, BillionLaughsUnderAnUnknownKeyIsRefusedNamingIt) {
  EXPECT_THAT(loading(shipped_text("Sim") + "laughs:\n" + indented(laughs("[lol, lol, lol]"), "  ")),
              refuses("laughs", "unknown key"));
}

TEST(AliasExpansion, BillionLaughsAsASectionIsRefusedNamingIt) {
  EXPECT_THAT(loading(laughs("[lol]") + "plant: *l9\n"), refuses("plant", "expected a mapping"));
}

TEST(AliasExpansion, BillionLaughsAsAListOfTheSchemaIsRefusedAtItsFirstElement) {
  const std::string methods = "methods: [linearized, nonlinear]";
  std::string text = shipped_text("Sim");
  ASSERT_NE(text.find(methods), std::string::npos);
  text.replace(text.find(methods), methods.size(), "methods: *l9");
  EXPECT_THAT(loading(laughs("lol") + text), refuses("controller.predictor.methods[0]", "unknown method"));
}

// An alias of an enclosing anchor makes the parsed document a cycle (yaml-cpp accepts it): the
// loader walks the keys of its schema only, so it never goes round.
TEST(AliasExpansion, RecursiveAliasAsASectionIsRefusedAtTheFirstMissingKey) {
  EXPECT_THAT(loading("plant: &p {geometry: *p, gas: *p}\n"), refuses("plant.mass_kg", "missing"));
  std::string text = shipped_text("Sim");
  const std::size_t geometry = text.find("\n  geometry:") + 1;  // the line, with its comment
  ASSERT_NE(geometry, 0u);
  text.replace(geometry, text.find('\n', geometry) + 1 - geometry, "  geometry: &g\n    again: *g\n");
  EXPECT_THAT(loading(text), refuses("plant.geometry.again", "unknown key"));
}

TEST(AliasExpansion, RecursiveAliasAsAListOfTheSchemaIsRefusedAtItsFirstElement) {
  const std::string methods = "methods: [linearized, nonlinear]";
  std::string text = shipped_text("Sim");
  text.replace(text.find(methods), methods.size(), "methods: &m [*m]");
  EXPECT_THAT(loading(text), refuses("controller.predictor.methods[0]", "unknown method"));
  text = shipped_text("Sim");
  const std::string step = "- {t_s: 1.0, position_m: 0.170}";
  ASSERT_NE(text.find(step), std::string::npos);
  text.replace(text.find(step), step.size(), "- &s [*s]");
  EXPECT_THAT(loading(text), refuses("controller.setpoints.schedule[0]", "expected a mapping"));
}

TEST(AliasExpansion, MappingsOfAliasedMappingsAsASectionAreRefusedAtTheFirstMissingKey) {
  std::string yaml = "m0: &m0 {a: 1, b: 2}\n";
  for (int i = 1; i <= 9; ++i) {
    yaml += "m" + std::to_string(i) + ": &m" + std::to_string(i) + " {";
    for (int j = 0; j < 10; ++j)
      yaml += std::string(j ? ", " : "") + static_cast<char>('a' + j) + ": *m" + std::to_string(i - 1);
    yaml += "}\n";
  }
  EXPECT_THAT(loading(yaml + "plant: *m9\n"), refuses("plant.mass_kg", "missing"));
}

// ---------------------------------------------------------------------------------------------
// Through the real binaries: exit code 2, the key path and the reason on stderr, nothing driven

// One bad document for both binaries: from sim.yaml (for pneud on the sim backend) or from
// hil.yaml (for pneud on the modbus backend, and for pneu-plant serve), or raw text.
struct BinaryCase {
  std::string name;
  std::function<void(YAML::Node&)> edit;  // applied to either shipped file; empty: `raw`
  std::function<std::string()> raw;       // the whole document, made when the test runs
  std::string names;                      // the key path stderr names; empty: the file's path
  std::string reason;
};

void PrintTo(const BinaryCase& c, std::ostream* os) { *os << c.name; }

// A sample of the matrix: in each top-level section of sim.yaml, its first required key left
// out; a wrong type, an unknown key, a value out of range; the deep, large and aliased documents.
std::vector<BinaryCase> binary_cases() {
  std::vector<BinaryCase> out;
  std::set<std::string> sections;
  for (const Key& k : shipped_keys()) {
    if (k.file != "Sim" || k.optional || k.kind == KeyKind::kSection) continue;
    const std::string section = k.path.substr(0, k.path.find('.'));
    if (!sections.insert(section).second) continue;
    out.push_back({"Missing_" + test_name(k.path), removing(k.path), nullptr, k.path, "missing"});
  }
  out.push_back({"WrongType_plant_mass_kg", setting("plant.mass_kg", "{a: 1}"), nullptr, "plant.mass_kg",
                 "expected a number, got a mapping"});
  out.push_back({"UnknownKey_controller_law_colour", setting("controller.law.colour", "red"), nullptr,
                 "controller.law.colour", "unknown key"});
  out.push_back({"MisspeltKey_controller_law_position_gain_v_per_m",
                 renaming("controller.law.position_gain_v_per_m", "positon_gain_v_per_m"), nullptr,
                 "controller.law.positon_gain_v_per_m", "unknown key; did you mean position_gain_v_per_m?"});
  out.push_back({"OutOfRange_controller_rate_hz", setting("controller.rate_hz", "0"), nullptr, "controller.rate_hz",
                 "must be in [1, 20000]"});
  out.push_back({"DeepDocument", nullptr, [] { return "plant: " + std::string(100000, '[') + "\n"; }, "",
                 "nested too deeply: more than 64 levels at line 1"});
  out.push_back({"LargeDocument", nullptr,
                 [] {
                   std::string large = "plant: [";
                   while (large.size() < (2u << 20)) large += "0,";
                   return large + "0]\n";
                 },
                 "", "too large: "});
  out.push_back({"BillionLaughs", nullptr, [] { return laughs("[lol]") + "plant: *l9\n"; }, "plant",
                 "expected a mapping"});
  out.push_back({"RecursiveAlias", nullptr, [] { return std::string("plant: &p {geometry: *p}\n"); }, "plant.mass_kg",
                 "missing"});
  return out;
}

// A TCP listener on a free loopback port, standing for the I/O module: any connection to it
// would be pneud starting to drive the bench.
class Listener {
 public:
  Listener() {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = 0;  // a free port, as test::free_port, but held from now on
    socklen_t len = sizeof a;
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(fd_, 8) != 0 ||
        ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0)
      throw std::runtime_error("cannot listen on loopback");
    port_ = ntohs(a.sin_port);
  }
  ~Listener() { ::close(fd_); }
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;
  [[nodiscard]] int port() const { return port_; }
  // A connection has arrived (waiting up to `ms` for one).
  [[nodiscard]] bool connected(int ms) const {
    pollfd p{fd_, POLLIN, 0};
    return ::poll(&p, 1, ms) > 0;
  }

 private:
  int fd_ = -1;
  int port_ = 0;
};

struct Outcome {
  int exit_code = -1;  // -2: still running after the time limit (killed)
  std::string out, err;
};

// Runs the programs of the build on documents written to a directory of its own.
class BinaryHarness : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string name = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::replace(name.begin(), name.end(), '/', '_');
    dir_ = fs::temp_directory_path() / ("pneu_hostile_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  [[nodiscard]] fs::path file(const std::string& name) const { return dir_ / name; }

  // The case's document from shipped file `base`, made safe to run should it be accepted: no
  // telemetry, a short run, the I/O module at `port`. Written to a file; its path.
  [[nodiscard]] fs::path bad_config(const BinaryCase& c, const std::string& base, int port) const {
    std::string text;
    if (c.raw) text = c.raw();
    if (c.edit) {
      text = edited(base, [&](YAML::Node& root) {
        root["telemetry"]["enabled"] = false;
        root["controller"]["duration_s"] = 0.5;
        if (root["hal"]["modbus"]) root["hal"]["modbus"]["port"] = port;
        c.edit(root);
      });
    }
    const fs::path path = file(base + "_bad.yaml");
    std::ofstream(path) << text;
    return path;
  }

  // Runs a program of the build, killing it after `limit_s`.
  [[nodiscard]] Outcome run(std::vector<std::string> args, double limit_s = 20.0) const {
    args[0] = std::string(PNEU_BINARY_DIR) + "/bin/" + args[0];
    const fs::path out = file("stdout.txt"), err = file("stderr.txt");
    test::Child child = test::Child::spawn(args, out, err);
    Outcome o;
    if (child.pid <= 0) {
      ADD_FAILURE() << "cannot start " << args[0];
      return o;
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(limit_s);
    for (;;) {
      int status = 0;
      const pid_t r = ::waitpid(child.pid, &status, WNOHANG);
      if (r == child.pid) {
        child.pid = -1;
        o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        break;
      }
      if (std::chrono::steady_clock::now() > deadline) {
        o.exit_code = -2;  // the Child's destructor kills it
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    if (o.exit_code == -2) {
      ::kill(child.pid, SIGKILL);
      (void)child.wait();
    }
    o.out = test::slurp(out);
    o.err = test::slurp(err);
    return o;
  }

  static void expect_refused(const Outcome& o, const std::string& program, const std::string& names,
                             const std::string& reason) {
    EXPECT_EQ(o.exit_code, 2) << o.out << o.err;
    EXPECT_THAT(o.err, HasSubstr(program + ": config: " + names + ": "));
    EXPECT_THAT(o.err, HasSubstr(reason));
    EXPECT_EQ(o.out, "") << "nothing on stdout: nothing ran";
  }

  fs::path dir_;
};

class HostileConfigThroughTheBinaries : public BinaryHarness, public ::testing::WithParamInterface<BinaryCase> {};

TEST_P(HostileConfigThroughTheBinaries, PneudOnTheSimBackendExitsTwoWritingNothing) {
  const BinaryCase& c = GetParam();
  const fs::path config = bad_config(c, "Sim", 0);
  const fs::path events = file("events.jsonl"), trajectory = file("trajectory.csv");
  const Outcome o = run({"pneud", "--config", config.string(), "--events", events.string(), "--trajectory",
                         trajectory.string()});
  expect_refused(o, "pneud", c.names.empty() ? config.string() : c.names, c.reason);
  EXPECT_FALSE(fs::exists(events)) << "the events file was created";
  EXPECT_FALSE(fs::exists(trajectory)) << "the trajectory file was created";
}

TEST_P(HostileConfigThroughTheBinaries, PneudOnTheModbusBackendExitsTwoNeverConnecting) {
  const BinaryCase& c = GetParam();
  const Listener module;
  const fs::path config = bad_config(c, "Hil", module.port());
  const fs::path events = file("events.jsonl"), trajectory = file("trajectory.csv");
  const Outcome o = run({"pneud", "--config", config.string(), "--events", events.string(), "--trajectory",
                         trajectory.string()});
  expect_refused(o, "pneud", c.names.empty() ? config.string() : c.names, c.reason);
  EXPECT_FALSE(module.connected(200)) << "pneud connected to the I/O module";
  EXPECT_FALSE(fs::exists(events));
  EXPECT_FALSE(fs::exists(trajectory));
}

#ifdef PNEU_WITH_MODBUS  // pneu-plant serve needs libmodbus
TEST_P(HostileConfigThroughTheBinaries, PlantServerExitsTwoNeverListening) {
  const BinaryCase& c = GetParam();
  const int port = test::free_port();
  const fs::path config = bad_config(c, "Hil", port);
  const Outcome o = run({"pneu-plant", "serve", "--config", config.string(), "--duration", "1"});
  expect_refused(o, "pneu-plant", c.names.empty() ? config.string() : c.names, c.reason);  // no "listening on"
}
#endif

INSTANTIATE_TEST_SUITE_P(Sample, HostileConfigThroughTheBinaries, ::testing::ValuesIn(binary_cases()),
                         [](const auto& p) { return p.param.name; });

// The controls: the same harness with a good document does drive, so the absences above mean
// something.
class GoodConfigThroughTheBinaries : public BinaryHarness {};

TEST_F(GoodConfigThroughTheBinaries, PneudOnTheSimBackendWritesItsFiles) {
  const fs::path config = bad_config({"Good", [](YAML::Node&) {}, nullptr, "", ""}, "Sim", 0);
  const fs::path events = file("events.jsonl"), trajectory = file("trajectory.csv");
  const Outcome o = run({"pneud", "--quiet", "--config", config.string(), "--events", events.string(),
                         "--trajectory", trajectory.string()});
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(fs::exists(events));
  EXPECT_TRUE(fs::exists(trajectory));
}

#ifdef PNEU_WITH_MODBUS
TEST_F(GoodConfigThroughTheBinaries, PneudOnTheModbusBackendConnectsToTheModule) {
  const Listener module;
  const fs::path config = bad_config({"Good", [](YAML::Node&) {}, nullptr, "", ""}, "Hil", module.port());
  const Outcome o = run({"pneud", "--quiet", "--config", config.string()});
  EXPECT_NE(o.exit_code, -2) << "still running";
  EXPECT_TRUE(module.connected(0)) << o.out << o.err;
}
#endif

#ifdef PNEU_WITH_MODBUS
TEST_F(GoodConfigThroughTheBinaries, PlantServerListens) {
  const fs::path config = bad_config({"Good", [](YAML::Node&) {}, nullptr, "", ""}, "Hil", test::free_port());
  const Outcome o = run({"pneu-plant", "serve", "--config", config.string(), "--duration", "0.2"});
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("listening on 127.0.0.1:"));
}
#endif

}  // namespace
}  // namespace pneu::config
