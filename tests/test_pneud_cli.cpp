// pneud as a user runs it: help and version, the summary, its figures as JSON and the events file
// of the default run, the effective configuration, bad input refused with exit code 2 before anything runs (naming the
// key and the reason), and a short run on the real clock.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/config.hpp"
#include "support/child_process.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct Outcome {
  int exit_code = -1;
  std::string out;
  std::string err;
};

using pneu::test::Json;
using pneu::test::slurp;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// One line of the events file: a flat JSON object whose values are numbers, strings without
// commas or braces, true, false or null. Good enough to read pneud's own output; anything else
// makes the shape check below fail.
using JsonLine = std::map<std::string, std::string>;

bool looks_like_event_object(const std::string& line) {
  return line.starts_with("{\"event\":\"") && line.ends_with("}") &&
         line.find(",\"t\":") != std::string::npos;
}

JsonLine parse_flat_object(const std::string& line) {
  JsonLine fields;
  static const std::regex kField(R"re("([a-z_]+)":("[^"]*"|[^,}]+))re");
  for (auto it = std::sregex_iterator(line.begin(), line.end(), kField);
       it != std::sregex_iterator(); ++it)
    fields[(*it)[1]] = (*it)[2];
  return fields;
}

bool is_number(const std::string& v) {
  if (v.empty()) return false;
  char* end = nullptr;
  (void)std::strtod(v.c_str(), &end);
  return end == v.c_str() + v.size();
}

class PneudCli : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info->name();
    std::replace(name.begin(), name.end(), '/', '_');  // parameterised tests: "Test/Param"
    dir_ = fs::temp_directory_path() / ("pneud_cli_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // Runs pneud with `args` (already shell-quoted where needed), capturing stdout and stderr.
  // Telemetry is off: these tests run in the host's network namespace, and LCM multicast in tests
  // belongs inside a private one (test_lcm_integration).
  Outcome pneud(const std::string& args) const {
    const fs::path out = dir_ / "stdout.txt";
    const fs::path err = dir_ / "stderr.txt";
    const std::string command = std::string("'") + PNEU_BINARY_DIR + "/bin/pneud' " + args +
                                " --set telemetry.enabled=false > '" + out.string() + "' 2> '" +
                                err.string() + "'";
    const int status = std::system(command.c_str());
    Outcome o;
    o.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    o.out = slurp(out);
    o.err = slurp(err);
    return o;
  }
  [[nodiscard]] fs::path file(const std::string& name) const { return dir_ / name; }
  [[nodiscard]] static std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

 private:
  fs::path dir_;
};

TEST_F(PneudCli, HelpDescribesTheUsageAndExitsZero) {
  const Outcome o = pneud("--help");
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("Usage:"));
  EXPECT_THAT(o.out, HasSubstr("--events FILE"));
  EXPECT_THAT(o.out, HasSubstr("--summary-json FILE"));
  EXPECT_EQ(o.err, "");
}

TEST_F(PneudCli, VersionPrintsTheProgramAndVersionAndExitsZero) {
  const Outcome o = pneud("--version");
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, ::testing::MatchesRegex("pneud [0-9]+\\.[0-9]+\\.[0-9]+\n"));
}

TEST_F(PneudCli, DefaultRunPrintsTheSummaryOfTheTwelveSecondPaperScenario) {
  const Outcome o = pneud("");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("12.000 s on the sim backend, simulated clock"));
  EXPECT_THAT(o.out, HasSubstr("stops (sticking phases) and their restart forecasts"));
  EXPECT_THAT(o.out, HasSubstr("restart - at"));
  EXPECT_THAT(o.out, HasSubstr("loop: 12001 ticks at 1000 Hz"));
  EXPECT_THAT(o.out, Not(HasSubstr("MISSED")));
  EXPECT_THAT(o.out, Not(HasSubstr("WRONG DIR")));
  EXPECT_THAT(o.out, Not(HasSubstr("telemetry dropped")));
}

// The summary says when the linearized forecasts are not the paper's (Eq. 23 at the stop).
TEST_F(PneudCli, SummaryNamesALinearizedSlopeOtherThanThePapers) {
  const Outcome paper = pneud("");
  const Outcome chord = pneud("--set controller.predictor.linearized_slope=chord");
  ASSERT_EQ(paper.exit_code, 0) << paper.err;
  ASSERT_EQ(chord.exit_code, 0) << chord.err;
  EXPECT_THAT(paper.out, Not(HasSubstr("linearized_slope")));
  EXPECT_THAT(chord.out, HasSubstr("(controller.predictor.linearized_slope: chord)"));
  EXPECT_THAT(chord.out, HasSubstr("not the paper's tangent at the stop pressure"));
}

TEST_F(PneudCli, EventsFileHoldsOneEventObjectPerLineWithConsistentStopsAndPredictions) {
  const fs::path events = file("events.jsonl");
  const Outcome o = pneud("--quiet --events " + quoted(events));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_EQ(o.out, "");  // --quiet

  const std::vector<std::string> lines = lines_of(slurp(events));
  ASSERT_FALSE(lines.empty());
  std::map<std::string, std::string> stop_time;  // stop index -> its event's "t", as written
  std::map<std::string, int> predictions_per_stop;
  int reforecasts = 0;
  bool restart_seen = false;
  for (const std::string& line : lines) {
    SCOPED_TRACE(line);
    ASSERT_TRUE(looks_like_event_object(line));
    const JsonLine f = parse_flat_object(line);
    ASSERT_TRUE(f.contains("t"));
    EXPECT_TRUE(is_number(f.at("t")));
    const std::string& kind = f.at("event");
    if (kind == "\"stop\"") {
      stop_time[f.at("stop")] = f.at("t");
    } else if (kind == "\"prediction\"") {
      ASSERT_TRUE(stop_time.contains(f.at("stop"))) << "a prediction follows its stop";
      EXPECT_EQ(f.at("t_stop"), stop_time.at(f.at("stop")));  // same double, same text
      ++predictions_per_stop[f.at("stop")];
      EXPECT_THAT(f.at("method"), ::testing::AnyOf("\"linearized\"", "\"nonlinear\""));
      ASSERT_TRUE(f.contains("will_restart"));
      EXPECT_THAT(f.at("will_restart"), ::testing::AnyOf("true", "false"));
      EXPECT_THAT(f.at("direction"), ::testing::AnyOf("1", "-1", "0"));
      ASSERT_TRUE(f.contains("t_restart"));
      if (f.at("will_restart") == "true")
        EXPECT_TRUE(is_number(f.at("t_restart")));
      else
        EXPECT_TRUE(f.at("t_restart") == "null" || is_number(f.at("t_restart")));
    } else if (kind == "\"reforecast\"") {
      // The live predictor: made again while still stuck, after the stop's own forecasts.
      ASSERT_EQ(predictions_per_stop[f.at("stop")], 2) << "a re-forecast follows its stop's forecasts";
      EXPECT_EQ(f.at("t_stop"), stop_time.at(f.at("stop")));
      EXPECT_GT(std::stod(f.at("t")), std::stod(f.at("t_stop")));
      EXPECT_THAT(f.at("method"), ::testing::AnyOf("\"linearized\"", "\"nonlinear\""));
      EXPECT_GE(std::stoi(f.at("update")), 1);
      for (const char* key : {"force", "stop_forecast_force"}) EXPECT_TRUE(is_number(f.at(key))) << key;
      ++reforecasts;
    } else if (kind == "\"start\"") {
      ASSERT_TRUE(f.contains("restart"));
      if (f.at("restart") == "true") restart_seen = true;
    } else {
      EXPECT_EQ(kind, "\"end\"");
    }
  }
  EXPECT_FALSE(stop_time.empty());
  for (const auto& [stop, n] : predictions_per_stop)
    EXPECT_EQ(n, 2) << "stop " << stop;  // both methods
  EXPECT_EQ(predictions_per_stop.size(), stop_time.size());
  EXPECT_TRUE(restart_seen);
  EXPECT_GT(reforecasts, 2 * 20) << "the 2.5 s sticking phase is forecast again every 0.1 s";
  EXPECT_EQ(lines.back(), "{\"event\":\"end\",\"t\":12}");
}

TEST_F(PneudCli, TrajectoryFileHasAHeaderAndOneRowPerTick) {
  const fs::path trajectory = file("trajectory.csv");
  const Outcome o = pneud("--quiet --trajectory " + quoted(trajectory));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const std::vector<std::string> lines = lines_of(slurp(trajectory));
  ASSERT_EQ(lines.size(), 1u + 12001u);
  EXPECT_EQ(lines.front(),
            "seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity,"
            "p_p_linearized,p_n_linearized,force_linearized,p_p_nonlinear,p_n_nonlinear,force_nonlinear");
  EXPECT_THAT(lines.back(), ::testing::StartsWith("12000,12,"));
}

TEST_F(PneudCli, CheckConfigPrintsTheEffectiveYamlWithTheOffsetResolvedAndRunsNothing) {
  const Outcome o = pneud("--check-config");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("plant:"));
  EXPECT_THAT(o.out, ::testing::ContainsRegex("offset_v: -?[0-9]"));  // u_e of Eq. 7, not "auto"
  EXPECT_THAT(o.out, Not(HasSubstr("stops (sticking phases)")));
}

TEST_F(PneudCli, EachRunWritesItsEffectiveConfigurationBesideItsEventsAndTrajectoryWhichLoadsBackTheSame) {
  const std::string gain = " --set controller.law.position_gain_v_per_m=61";
  const Outcome o = pneud("--quiet --duration 1 --events " + quoted(file("e.jsonl")) + " --trajectory " +
                          quoted(file("t.csv")) + gain);
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const std::string beside_trajectory = slurp(file("t.csv.config.yaml"));
  EXPECT_EQ(slurp(file("e.jsonl.config.yaml")), beside_trajectory) << "the same beside both";
  EXPECT_THAT(beside_trajectory, HasSubstr("position_gain_v_per_m: 61")) << "--set applied";
  EXPECT_THAT(beside_trajectory, HasSubstr("duration_s: 1")) << "--duration applied";
  // It is the configuration the run had: loaded again, it is what --check-config gives for the run.
  const Outcome again = pneud("--check-config --config " + quoted(file("t.csv.config.yaml")));
  const Outcome original = pneud("--check-config --duration 1" + gain);
  ASSERT_EQ(again.exit_code, 0) << again.err;
  const auto body = [](const std::string& yaml) { return yaml.substr(yaml.find('\n') + 1); };  // past the comment
  EXPECT_EQ(body(again.out), body(original.out));
  EXPECT_EQ(body(beside_trajectory), body(original.out));
}

TEST_F(PneudCli, ARunThatNeverStartedWritesNoConfigurationBesideItsOutputs) {
  const Outcome o = pneud("--clock real --duration 0.1 --set hal.gpio.enabled=true --set hal.gpio.chip=pneu-no-such-chip"
                          " --events " + quoted(file("e.jsonl")) + " --trajectory " + quoted(file("t.csv")));
  EXPECT_EQ(o.exit_code, 1) << o.out;
  for (const auto& e : fs::directory_iterator(file("")))  // nor the files being written
    EXPECT_THAT(e.path().filename().string(), Not(HasSubstr(".config.yaml"))) << e.path();
}

// Bad input: exit code 2, a message on stderr naming the key (or option) and the reason, nothing
// on stdout, and no output file created (nothing ran).
struct BadInput {
  std::string name;
  std::string args;
  std::string names;   // the key or option the message must name
  std::string reason;  // and the reason it must give
};

void PrintTo(const BadInput& b, std::ostream* os) { *os << b.name; }

class PneudBadInput : public PneudCli, public ::testing::WithParamInterface<BadInput> {};

TEST_P(PneudBadInput, ExitsTwoNamingTheKeyAndReasonBeforeAnythingRuns) {
  const BadInput& b = GetParam();
  std::string args = b.args;
  if (args.find("@BAD_CONFIG@") != std::string::npos) {
    // The embedded default with one required key removed.
    std::string yaml = slurp(fs::path(PNEU_SOURCE_DIR) / "config" / "sim.yaml");
    const auto at = yaml.find("  mass_kg:");
    ASSERT_NE(at, std::string::npos);
    yaml.erase(at, yaml.find('\n', at) + 1 - at);
    std::ofstream(file("bad.yaml")) << yaml;
    args.replace(args.find("@BAD_CONFIG@"), 12, quoted(file("bad.yaml")));
  }
  if (args.find("@MISSPELT_CONFIG@") != std::string::npos) {
    // The embedded default with a required key misspelt.
    std::string yaml = slurp(fs::path(PNEU_SOURCE_DIR) / "config" / "sim.yaml");
    const auto at = yaml.find("    position_gain_v_per_m:");
    ASSERT_NE(at, std::string::npos);
    yaml.replace(at, 26, "    positon_gain_v_per_m:");
    std::ofstream(file("misspelt.yaml")) << yaml;
    args.replace(args.find("@MISSPELT_CONFIG@"), 17, quoted(file("misspelt.yaml")));
  }
  const fs::path events = file("events.jsonl");
  const Outcome o = pneud(args + " --events " + quoted(events));
  EXPECT_EQ(o.exit_code, 2) << o.out << o.err;
  EXPECT_THAT(o.err, HasSubstr(b.names));
  EXPECT_THAT(o.err, HasSubstr(b.reason));
  EXPECT_EQ(o.out, "");
  EXPECT_FALSE(fs::exists(events));
}

INSTANTIATE_TEST_SUITE_P(
    Pneud, PneudBadInput,
    ::testing::Values(
        BadInput{"UnknownSetKey", "--set controller.no_such_key=1", "controller.no_such_key",
                 "unknown key"},
        BadInput{"MalformedNumber", "--set controller.rate_hz=fast", "controller.rate_hz",
                 "expected a number"},
        BadInput{"OutOfRange", "--set controller.law.max_voltage_v=-1",
                 "controller.law.max_voltage_v", "must be > 0"},
        BadInput{"ConfigFileMissingAKey", "--config @BAD_CONFIG@", "plant.mass_kg", "missing"},
        BadInput{"ConfigFileWithAMisspeltKey", "--config @MISSPELT_CONFIG@", "controller.law.positon_gain_v_per_m",
                 "controller.law.positon_gain_v_per_m: unknown key; did you mean position_gain_v_per_m?"},
        BadInput{"MisspeltSetKey", "--set controller.law.position_gain_v_per_mm=50",
                 "controller.law.position_gain_v_per_mm",
                 "controller.law.position_gain_v_per_mm: unknown key; did you mean position_gain_v_per_m?"},
        BadInput{"SetKeyUnderAMisspeltSection", "--set controler.law.position_gain_v_per_m=50",
                 "controler.law.position_gain_v_per_m",
                 "controler.law.position_gain_v_per_m: unknown key; did you mean controller.law.position_gain_v_per_m?"},
        BadInput{"UnknownLinearizedSlope", "--set controller.predictor.linearized_slope=secant",
                 "controller.predictor.linearized_slope", "must be 'stop', 'chord' or 'equilibrium'"},
        BadInput{"UnknownClock", "--clock bogus", "--clock", "real or simulated"},
        BadInput{"DurationNotANumber", "--duration abc", "--duration", "not a finite number"},
        BadInput{"ZeroDurationOnTheSimulatedClock", "--duration 0", "controller.duration_s",
                 "needs the real clock"},
        BadInput{"ScheduledGainsThatNeedANegativeGain",
                 "--set controller.law.gains=scheduled --set controller.law.design.natural_frequency_rad_per_s=30 "
                 "--set controller.law.design.infeasible=refuse",
                 "controller.law.design", "at y = -0.25 m: K_v would be negative"},
        BadInput{"ScheduledGainsBeyondTheirLimit",
                 "--set controller.law.gains=scheduled --set controller.law.design.max_position_gain_v_per_m=300 "
                 "--set controller.law.design.infeasible=refuse",
                 "controller.law.design", "K_y = 324.085 V/m is beyond its limit 300 V/m"},
        BadInput{"ScheduledGainsTheSampledLoopCannotFollow",
                 "--set controller.law.gains=scheduled --set controller.rate_hz=300 "
                 "--set controller.law.design.infeasible=refuse",
                 "controller.law.design",
                 "the sampled loop is unstable"},
        BadInput{"UnknownGainsKind", "--set controller.law.gains=adaptive", "controller.law.gains",
                 "must be 'fixed' or 'scheduled'"}),
    [](const ::testing::TestParamInfo<BadInput>& p) { return p.param.name; });

TEST_F(PneudCli, ADesignInfeasibleSomewhereRunsOnGainsThatFallBackThereAndSaysWhereOnStderr) {
  const Outcome o = pneud("--quiet --set controller.law.design.natural_frequency_rad_per_s=30");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.err, HasSubstr("controller.law.design: the requested dynamics cannot be had everywhere"));
  EXPECT_THAT(o.err, HasSubstr("at y = -0.25 m"));
  EXPECT_THAT(o.err, HasSubstr("K_v would be negative"));
  EXPECT_THAT(o.err, HasSubstr("the sampled loop there: max |z| 0.9"));
}

TEST_F(PneudCli, ShortRunOnTheRealClockCompletesAndReportsLoopTiming) {
  const Outcome o = pneud("--clock real --duration 0.3 --summary-json " + quoted(file("summary.json")));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, HasSubstr("real clock"));
  EXPECT_THAT(o.out, HasSubstr("wake-up latency [us]"));
  EXPECT_THAT(o.out, HasSubstr("compute per tick [us]"));
  // No timing assertions (shared machines are noisy, and every overrun skips deadlines): only that
  // it ticked, and never beyond the 301 deadlines at 0, 1, ..., 300 ms.
  const auto s = pneu::test::PneudSummary::read(file("summary.json"));
  ASSERT_TRUE(s.has_loop) << o.out;
  EXPECT_GE(s.ticks, 1u);
  EXPECT_LE(s.ticks, 301u);
}

// --summary-json: the figures of the summary's lines, for programs (docs/pneud.md lists the members).
TEST_F(PneudCli, SummaryJsonHoldsTheFiguresTheSummaryPrints) {
  const Outcome o = pneud("--summary-json " + quoted(file("summary.json")));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const Json j = Json::read(file("summary.json"));  // strict JSON, or it throws
  EXPECT_EQ(j["backend"].text(), "sim");
  EXPECT_EQ(j["clock"].text(), "simulated");
  EXPECT_EQ(j["config"].text(), "embedded sim.yaml");
  EXPECT_EQ(j["t_end_s"].number(), 12.0);
  char first_line[160];
  std::snprintf(first_line, sizeof first_line, "%.3f s on the %s backend, %s clock (%s), u_0 = %+.4f V, wall time ",
                j["t_end_s"].number(), j["backend"].text().c_str(), j["clock"].text().c_str(),
                j["config"].text().c_str(), j["u_0_v"].number());
  EXPECT_THAT(o.out, HasSubstr(first_line));
  const Json& loop = j["loop"];
  EXPECT_EQ(loop["ticks"].count(), 12001u);
  EXPECT_EQ(loop["rate_hz"].number(), 1000.0);
  EXPECT_THAT(o.out, HasSubstr("loop: " + std::to_string(loop["ticks"].count()) + " ticks at 1000 Hz, " +
                               std::to_string(loop["overruns"].count()) + " overruns (" +
                               std::to_string(loop["deadlines_skipped"].count()) + " deadlines skipped)"));
  for (const char* stats : {"wake_latency_us", "compute_us"})
    for (const char* q : {"min", "median", "p99", "max"}) EXPECT_GE(loop[stats][q].number(), 0.0) << stats << q;
  EXPECT_EQ(loop["tick_records_dropped"].count(), 0u);
  EXPECT_EQ(loop["events_dropped"].count(), 0u);
  const Json& runtime = j["runtime"];
  EXPECT_EQ(runtime["ticks_seen"].count(), 12001u);
  EXPECT_EQ(runtime["sequence_gaps"].count(), 0u);
  EXPECT_EQ(runtime["stops_forgotten"].count(), 0u);
  EXPECT_EQ(runtime["stops"].count(), 2u) << "the two sticking phases of the quick start's table (docs/results.md)";
  EXPECT_TRUE(j["faults"].elements().empty());
  EXPECT_TRUE(j["telemetry"].is_null()) << "telemetry off";
  EXPECT_TRUE(j["modbus"].is_null()) << "the sim backend";
}

TEST_F(PneudCli, SummaryJsonIsWrittenUnderQuietAndListsTheFaults) {
  // A following error of 10 mm for 10 ms: the 50 mm step latches it at once.
  const Outcome o = pneud("--quiet --summary-json " + quoted(file("summary.json")) +
                          " --set controller.supervisor.following_error_m=0.01"
                          " --set controller.supervisor.following_error_s=0.01");
  ASSERT_EQ(o.exit_code, 3) << "a fault still latched at the end: " << o.err;
  EXPECT_EQ(o.out, "");
  const Json j = Json::read(file("summary.json"));
  ASSERT_EQ(j["faults"].elements().size(), 1u);
  const Json& fault = j["faults"].elements().front();
  EXPECT_EQ(fault["cause"].text(), "following-error");
  EXPECT_GT(fault["t_s"].number(), 1.0) << "after the step at 1 s";
  EXPECT_NEAR(fault["y_m"].number(), 0.2195, 0.001) << "the carriage had barely moved";
}

// A run that ends with a fault still latched is no success: exit code 3, the summary's first line
// and the last line on stderr (the journal's, quiet or not) say so, and so does --summary-json.
// Here the set-point stream times out at once: a fault 2 ms into the run.
TEST_F(PneudCli, ARunThatFaultsAtOnceExitsThreeSayingSoFirst) {
  const std::string faulting = " --set commands.setpoint_stream_timeout_s=0.001";
  const Outcome o = pneud("--summary-json " + quoted(file("summary.json")) + faulting);
  EXPECT_EQ(o.exit_code, 3) << o.err;
  EXPECT_THAT(o.out, ::testing::StartsWith("FAULTED: the run ended with a fault latched (command-timeout, since 0.002 s), "
                                           "the outputs in the safe state; exit code 3\npneud "));
  const std::vector<std::string> err = lines_of(o.err);
  ASSERT_EQ(err.size(), 2u) << o.err;
  EXPECT_THAT(err[0], ::testing::StartsWith("<3>pneud: FAULT at 0.002 s (y = 219.500 mm): command-timeout: "));
  EXPECT_THAT(err[1], ::testing::StartsWith("<3>pneud: FAULTED: the run ended with a fault latched (command-timeout"));
  const Json j = Json::read(file("summary.json"));
  EXPECT_EQ(j["exit_reason"].text(), "fault_latched");
  EXPECT_EQ(j["exit_code"].count(), 3u);
  EXPECT_EQ(j["fault_at_end"].text(), "command-timeout");

  const Outcome quiet = pneud("--quiet" + faulting);
  EXPECT_EQ(quiet.exit_code, 3);
  EXPECT_EQ(quiet.out, "");
  EXPECT_THAT(quiet.err, HasSubstr("<3>pneud: FAULT at 0.002 s"));
  EXPECT_THAT(quiet.err, HasSubstr("<3>pneud: FAULTED:"));

  const Outcome clean = pneud("--summary-json " + quoted(file("clean.json")));
  EXPECT_EQ(clean.exit_code, 0) << clean.err;
  EXPECT_EQ(clean.err, "") << "a run without faults says nothing on stderr";
  EXPECT_EQ(Json::read(file("clean.json"))["exit_reason"].text(), "ok");
  EXPECT_TRUE(Json::read(file("clean.json"))["fault_at_end"].is_null());
}

// Issue 14: with the paper's gains (config/paper.yaml) the loop is unstable at mid-stroke. The
// carriage, at rest at 0, stepped to 50 mm at 1 s, swings ever wider; the supervisor latches the
// oscillation fault within 2 s of the step, and the valves go to the neutral safe output.
TEST_F(PneudCli, ThePaperGainsAtMidStrokeLatchAnOscillationFaultWithinTwoSecondsOfTheStep) {
  const Outcome o = pneud("--quiet --config " + quoted(fs::path(PNEU_SOURCE_DIR) / "config/paper.yaml") +
                          " --summary-json " + quoted(file("summary.json")) + " --events " +
                          quoted(file("events.jsonl")) + " --trajectory " + quoted(file("traj.csv")) +
                          " --set simulation.initial_position_m=0 --set controller.setpoints.initial_m=0"
                          " --set \"controller.setpoints.schedule=[{t_s: 1, position_m: 0.05}]\"");
  ASSERT_EQ(o.exit_code, 3) << "the fault still latched at the end: " << o.err;
  const Json j = Json::read(file("summary.json"));
  ASSERT_EQ(j["faults"].elements().size(), 1u);
  const Json& fault = j["faults"].elements().front();
  EXPECT_EQ(fault["cause"].text(), "oscillation");
  const double t_fault_s = fault["t_s"].number();
  EXPECT_GT(t_fault_s, 1.0) << "after the step";
  EXPECT_LT(t_fault_s, 3.0) << "within 2 s of it";
  EXPECT_THAT(slurp(file("events.jsonl")), HasSubstr("\"event\":\"fault\",\"t\":"));
  EXPECT_THAT(slurp(file("events.jsonl")), HasSubstr("\"cause\":\"oscillation\""));

  // Not vacuous: before the fault the error swung beyond +-10 mm both ways; from the fault on, the
  // valves are at the neutral safe output u_0.
  const pneu::test::Csv traj = pneu::test::Csv::read(file("traj.csv"));
  const std::size_t t = traj.col("t"), y_d = traj.col("y_d"), y = traj.col("y"), u = traj.col("u");
  double lowest_error_m = 0.0, highest_error_m = 0.0;
  std::size_t after = 0;
  for (const auto& row : traj.rows) {
    const double error_m = std::stod(row[y_d]) - std::stod(row[y]);
    if (std::stod(row[t]) < t_fault_s) {
      lowest_error_m = std::min(lowest_error_m, error_m);
      highest_error_m = std::max(highest_error_m, error_m);
    } else {
      ++after;
      ASSERT_NEAR(std::stod(row[u]), j["u_0_v"].number(), 1e-6) << "at t = " << row[t];
    }
  }
  EXPECT_LT(lowest_error_m, -0.01);
  EXPECT_GT(highest_error_m, 0.01);
  EXPECT_GT(after, 9000u) << "the rest of the 12 s run in the safe output";
}

// The same step with the default config's designed schedule: no fault; from 1 s after the step
// to the end of the run the carriage is at rest within 1 mm of the set point.
// hal.sim.plant: the in-process bench is not the controller's model. With its stiction at -60 N
// where plant: says -50 N, the paper's step (the paper's gains) sticks 2.4 s before restarting
// while the forecasts, made on plant:, expect the restart about half as soon.
TEST_F(PneudCli, ABenchThatIsNotItsModelBreaksTheForecastsMadeOnTheModel) {
  const std::string paper = " --config " + quoted(fs::path(PNEU_SOURCE_DIR) / "config/paper.yaml");
  const Outcome exact = pneud(paper);
  const Outcome off = pneud(paper + " --set hal.sim.plant.friction.static_negative_n=-60");
  ASSERT_EQ(exact.exit_code, 0) << exact.err;
  ASSERT_EQ(off.exit_code, 0) << off.err;
  // The largest nonlinear forecast error of the summary's stop table, in % of the sticking time
  // (the last "(... %)" of a row: the stops of 0.5 s or more that restarted).
  const auto worst_percent = [](const std::string& out) {
    const std::string table = out.substr(0, out.find("while stuck:"));
    const std::regex last_percent(R"(\(([0-9.]+) %\)\s*$)");
    double worst = 0.0;
    std::istringstream lines(table);
    for (std::string line; std::getline(lines, line);)
      if (std::smatch m; std::regex_search(line, m, last_percent)) worst = std::max(worst, std::stod(m[1]));
    return worst;
  };
  EXPECT_LT(worst_percent(exact.out), 0.1) << exact.out;
  EXPECT_GT(worst_percent(off.out), 20.0) << off.out;
}

TEST_F(PneudCli, TheDesignedGainsAtMidStrokeSettleTheSameStepWithoutAFault) {
  const Outcome o = pneud("--quiet --summary-json " + quoted(file("summary.json")) + " --trajectory " +
                          quoted(file("traj.csv")) +
                          " --set simulation.initial_position_m=0 --set controller.setpoints.initial_m=0"
                          " --set \"controller.setpoints.schedule=[{t_s: 1, position_m: 0.05}]\"");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const Json j = Json::read(file("summary.json"));
  EXPECT_TRUE(j["faults"].elements().empty());
  const pneu::test::Csv traj = pneu::test::Csv::read(file("traj.csv"));
  const std::size_t t = traj.col("t"), y = traj.col("y"), stuck = traj.col("stuck");
  double widest_m = 0.0, farthest_from_start_m = 0.0;
  std::size_t rows = 0;
  for (const auto& row : traj.rows) {
    farthest_from_start_m = std::max(farthest_from_start_m, std::abs(std::stod(row[y])));
    if (std::stod(row[t]) < 2.0) continue;
    ++rows;
    EXPECT_EQ(row[stuck], "1") << "at t = " << row[t];
    widest_m = std::max(widest_m, std::abs(0.05 - std::stod(row[y])));
  }
  EXPECT_EQ(rows, 10001u);
  EXPECT_GT(farthest_from_start_m, 0.04) << "it did move";
  EXPECT_LT(widest_m, 0.001);
}

TEST_F(PneudCli, SummaryJsonIsNotLeftBehindWhenTheRunFailsNorFromAnEarlierRun) {
  std::ofstream(file("summary.json")) << "{\"from\": \"an earlier run\"}\n";
  const Outcome o = pneud("--clock real --duration 0.1 --set hal.gpio.enabled=true --set hal.gpio.chip=pneu-no-such-chip"
                          " --summary-json " + quoted(file("summary.json")));
  EXPECT_EQ(o.exit_code, 1) << o.out;
  EXPECT_FALSE(fs::exists(file("summary.json")));
  for (const auto& e : fs::directory_iterator(file("")))  // nor the file it was being written to
    EXPECT_FALSE(e.path().filename().string().starts_with("summary.json")) << e.path();
}

TEST_F(PneudCli, ASummaryJsonPathThatCannotBeWrittenFailsBeforeTheRun) {
  const Outcome o = pneud("--summary-json " + quoted(file("no-such-directory/summary.json")));
  EXPECT_EQ(o.exit_code, 1);
  EXPECT_THAT(o.err, HasSubstr("--summary-json " + file("no-such-directory/summary.json").string() + ": cannot open for writing"));
  EXPECT_EQ(o.out, "") << "nothing ran";
}

TEST_F(PneudCli, AGpioChipThatDoesNotExistIsAClearStartUpError) {
#ifndef PNEU_WITH_GPIOD
  GTEST_SKIP() << "pneud was built without libgpiod (PNEU_WITH_GPIOD=OFF)";
#endif
  const Outcome o = pneud(
      "--clock real --duration 0.1 --set telemetry.enabled=false --set hal.gpio.enabled=true --set "
      "hal.gpio.chip=pneu-no-such-chip");
  EXPECT_EQ(o.exit_code, 1);
  EXPECT_THAT(o.err, HasSubstr("cannot open GPIO chip 'pneu-no-such-chip' (hal.gpio.chip)"));
  EXPECT_THAT(o.out, Not(HasSubstr("loop:"))) << "nothing ran";
}

TEST_F(PneudCli, GpioLinesWithTheSimulatedClockAreRefused) {
  const Outcome o = pneud("--set hal.gpio.enabled=true");
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, HasSubstr("hal.gpio.enabled: real lines (e-stop, valve power) need the real clock"));
}

}  // namespace

namespace {

// pneud --identify on the simulated bench (issue 15): a bench whose stiction and null offset are
// not the model's, identified and written whole; the written file runs the same bench.
TEST_F(PneudCli, IdentifyWritesTheConfigurationWithPlantIdentifiedAndTheSameBench) {
  const fs::path out = file("identified.yaml");
  const Outcome o = pneud("--identify " + quoted(out) +
                          " --set hal.sim.plant.friction.static_positive_n=50 --set hal.sim.plant.valve.null_offset_v=0.04");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_THAT(o.out, ::testing::HasSubstr("plant.friction.static_positive_n"));
  EXPECT_THAT(o.out, ::testing::HasSubstr("written: " + out.string()));
  const pneu::config::Config c = pneu::config::load_file(out);
  EXPECT_NEAR(c.plant.friction.static_positive_n, 50.0, 0.02 * 50.0);
  EXPECT_NEAR(c.plant.valve.null_offset_v, 0.04, 0.005);
  EXPECT_TRUE(c.hal.sim.has_plant);
  EXPECT_EQ(c.hal.sim.plant.friction.static_positive_n, 50.0) << "the simulated bench as it was";
  EXPECT_EQ(c.controller.schedule.size(), 1u) << "the configured set points, not the identification run's";
  EXPECT_EQ(c.controller.duration_s, 12.0);
  // When, by what, from which run, at the top of the file; then sim.yaml's text, its comments kept.
  const std::string written = slurp(out);
  EXPECT_THAT(written, ::testing::StartsWith("# identified 20"));
  EXPECT_THAT(written, ::testing::ContainsRegex("^# identified [0-9-]+ [0-9:]+ UTC by pneud [^:]+: pneud --identify "));
  EXPECT_THAT(written, ::testing::HasSubstr("\n# from its own identification run: "));
  EXPECT_THAT(written, ::testing::HasSubstr("on the sim backend (the in-process simulated bench), simulated clock\n"));
  EXPECT_THAT(written, ::testing::HasSubstr("\n# the fit: the model fits the stuck phases' pressures: "));
  EXPECT_THAT(written, ::testing::HasSubstr("\n# pneu default configuration: the in-process simulated bench"));
  EXPECT_THAT(written, ::testing::ContainsRegex("\n    static_positive_n: [0-9.]+ +# F_S\\+: stiction, positive motion "
                                                "\\[N\\], > 0, >= F_C\\+  # identified [0-9-]+: [0-9.]+ \\+- [0-9.e-]+ "
                                                "\\(was 45\\)\n"));
}

// What a user reads first is what was identified: the parameter table, before and after with
// each sigma; the run's summary (its stops, a hundred lines) after it.
TEST_F(PneudCli, IdentifyPrintsTheParameterTableFirstAndTheRunsSummaryAfterIt) {
  const fs::path out = file("identified.yaml");
  const Outcome o = pneud("--identify " + quoted(out));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  const std::size_t table = o.out.find("\nparameter "), evidence = o.out.find("\nevidence: "),
                    written = o.out.find("\nwritten: "), stops = o.out.find("stops (sticking phases)");
  ASSERT_NE(table, std::string::npos) << o.out;
  EXPECT_THAT(o.out.substr(0, table), ::testing::StartsWith("identified from the run's own signals (")) << "its first line";
  EXPECT_EQ(std::count(o.out.begin(), o.out.begin() + static_cast<std::ptrdiff_t>(table), '\n'), 0)
      << "the table comes second, after the line saying what was identified from";
  EXPECT_LT(table, evidence);
  EXPECT_LT(evidence, written);
  EXPECT_LT(written, stops) << "the run's summary after";
}

TEST_F(PneudCli, IdentifyStopsAtAFaultInTheSafeStateAndWritesNothing) {
  const fs::path out = file("identified.yaml");
  const Outcome o = pneud("--identify " + quoted(out) +
                          " --set controller.supervisor.following_error_m=0.002 --set controller.supervisor.following_error_s=0.05");
  EXPECT_EQ(o.exit_code, 3) << "the run ended with the fault latched";
  EXPECT_THAT(o.err, ::testing::HasSubstr("by a fault, following"));
  EXPECT_THAT(o.err, ::testing::HasSubstr("nothing written"));
  EXPECT_FALSE(fs::exists(out));
}

TEST_F(PneudCli, IdentifyRefusesADurationAndArmedGoesOnlyWithIt) {
  const fs::path out = file("identified.yaml");
  Outcome o = pneud("--identify " + quoted(out) + " --duration 5");
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, ::testing::HasSubstr("no --duration"));
  o = pneud("--armed");
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, ::testing::HasSubstr("--armed goes with --identify"));
  EXPECT_FALSE(fs::exists(out));
}

}  // namespace

namespace {

// Issue 29: every output of pneud opened the same way (cli::OutputFile).

bool is_char_device(const fs::path& p) {
  struct stat st {};
  return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

// A character device like /dev/null (minor 3) or /dev/full (7): as root made in the test's
// directory (code that replaces a device then harms nothing of the machine's), as a normal user the
// system's own.
fs::path char_device(const fs::path& dir, const char* name, unsigned minor) {
  if (::geteuid() != 0) return fs::path("/dev") / name;
  const fs::path p = dir / name;
  EXPECT_EQ(::mknod(p.c_str(), S_IFCHR | 0666, makedev(1, minor)), 0);
  return p;
}

TEST_F(PneudCli, OutputsOnACharacterDeviceAreWrittenToItAndLeaveItADevice) {
  const fs::path null = char_device(file(""), "null", 3);
  const Outcome o = pneud("--quiet --duration 1 --summary-json " + quoted(null) + " --events " + quoted(null) +
                          " --trajectory " + quoted(null));
  EXPECT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(is_char_device(null));
  EXPECT_FALSE(fs::exists(file("null.config.yaml"))) << "no configuration beside a device";
}

TEST_F(PneudCli, ASummaryJsonOnAFullDeviceFailsWithExitOneAndLeavesItADevice) {
  const fs::path full = char_device(file(""), "full", 7);
  const Outcome o = pneud("--quiet --duration 1 --summary-json " + quoted(full));
  EXPECT_EQ(o.exit_code, 1) << o.err;
  EXPECT_THAT(o.err, HasSubstr("--summary-json " + full.string() + ": write failed: No space left on device"));
  EXPECT_TRUE(is_char_device(full));
}

TEST_F(PneudCli, IdentifyOnAFullDeviceFailsWithExitOneAndLeavesItADevice) {
  const fs::path full = char_device(file(""), "full", 7);
  const Outcome o = pneud("--quiet --identify " + quoted(full));
  EXPECT_EQ(o.exit_code, 1) << o.err;
  EXPECT_THAT(o.err, HasSubstr("--identify " + full.string() + ": write failed: No space left on device"));
  EXPECT_TRUE(is_char_device(full));
}

TEST_F(PneudCli, ASummaryJsonThroughASymbolicLinkIsWrittenToItsTargetAndTheLinkStays) {
  std::ofstream(file("tgt.json")) << "an earlier run's summary\n";
  fs::create_symlink("tgt.json", file("lnk"));
  const Outcome o = pneud("--quiet --duration 1 --summary-json " + quoted(file("lnk")));
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_TRUE(fs::is_symlink(file("lnk")));
  EXPECT_TRUE(Json::parse(slurp(file("tgt.json")))["t_end_s"].number() == 1.0) << slurp(file("tgt.json"));
}

TEST_F(PneudCli, OutputsReplacingAFileKeepItsMode) {
  for (const char* option : {"--summary-json", "--events", "--trajectory"}) {
    const fs::path p = file(std::string(option + 2) + ".out");
    std::ofstream(p) << "earlier\n";
    fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);  // 640
    const Outcome o = pneud(std::string("--quiet --duration 1 ") + option + " " + quoted(p));
    ASSERT_EQ(o.exit_code, 0) << o.err;
    EXPECT_NE(slurp(p), "earlier\n") << option;
    EXPECT_EQ(fs::status(p).permissions(), fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read)
        << option;
  }
}

TEST_F(PneudCli, ASummaryJsonIntoAFifoReachesItsReaderAndTheFifoStays) {
  const fs::path fifo = file("summary.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] { received = slurp(fifo); });  // as `jq < summary.fifo` would
  const Outcome o = pneud("--quiet --duration 1 --summary-json " + quoted(fifo));
  if (const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK); fd >= 0) ::close(fd);  // a reader still waiting: EOF
  reader.join();
  EXPECT_EQ(o.exit_code, 0) << o.err;
  ASSERT_FALSE(received.empty());
  EXPECT_EQ(Json::parse(received)["t_end_s"].number(), 1.0) << received;
  struct stat st {};
  ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
  EXPECT_TRUE(S_ISFIFO(st.st_mode)) << "still a FIFO";
}

TEST_F(PneudCli, TwoOutputsNamingTheSameFileAreRefusedBeforeAnythingRuns) {
  const fs::path same = file("same.csv");
  Outcome o = pneud("--trajectory " + quoted(same) + " --events " + quoted(same));
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, HasSubstr("--events " + same.string() + " and --trajectory " + same.string() + " name the same file"));
  EXPECT_EQ(o.out, "") << "nothing ran";
  EXPECT_FALSE(fs::exists(same));
  // Through a symbolic link, the file existing or not.
  fs::create_symlink("same.csv", file("lnk"));
  o = pneud("--trajectory " + quoted(same) + " --summary-json " + quoted(file("lnk")));
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, HasSubstr("--trajectory " + same.string() + " and --summary-json " + file("lnk").string()));
  std::ofstream(same) << "kept\n";
  o = pneud("--events " + quoted(file("lnk")) + " --trajectory " + quoted(same));
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_EQ(slurp(same), "kept\n");
}

TEST_F(PneudCli, ASummaryJsonOnDevStdoutGoesToStandardOutputFileOrPipe) {
  // Standard output a file (the fixture's redirection) ...
  Outcome o = pneud("--quiet --duration 1 --summary-json /dev/stdout");
  ASSERT_EQ(o.exit_code, 0) << o.err;
  EXPECT_EQ(Json::parse(o.out)["t_end_s"].number(), 1.0) << o.out;
  // ... and a pipe, as `pneud --summary-json /dev/stdout | jq`.
  const std::string command = std::string("{ '") + PNEU_BINARY_DIR + "/bin/pneud' --quiet --duration 1 " +
                              "--set telemetry.enabled=false --summary-json /dev/stdout 2>" + quoted(file("err")) +
                              "; echo $? > " + quoted(file("rc")) + "; } | cat > " + quoted(file("piped.json"));
  ASSERT_EQ(std::system(command.c_str()), 0);
  EXPECT_EQ(slurp(file("rc")), "0\n") << slurp(file("err"));
  EXPECT_EQ(Json::parse(slurp(file("piped.json")))["t_end_s"].number(), 1.0) << slurp(file("piped.json"));
  EXPECT_TRUE(fs::is_symlink("/dev/stdout")) << "/dev/stdout untouched";
}

// Item 12 of issue 29: the small things a new user meets first.
TEST_F(PneudCli, DashHIsHelpAndAnUnknownOptionPointsToIt) {
  const Outcome h = pneud("-h");
  EXPECT_EQ(h.exit_code, 0) << h.err;
  EXPECT_EQ(h.out, pneud("--help").out);
  const Outcome u = pneud("--foo");
  EXPECT_EQ(u.exit_code, 2);
  EXPECT_THAT(u.err, HasSubstr("unknown option --foo (see pneud --help)"));
}

TEST_F(PneudCli, AConfigThatIsADirectoryIsSaidToBeOne) {
  const Outcome o = pneud("--config " + quoted(file("")));
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, HasSubstr("is a directory"));
  EXPECT_THAT(o.err, Not(HasSubstr("no such file")));
}

// Item 5: a simulated start outside the soft limits would fault at t = 0.
TEST_F(PneudCli, ASimulatedStartOutsideTheSoftLimitsIsRefusedNamingTheKeyAndTheLimits) {
  const Outcome o = pneud("--set simulation.initial_position_m=0.249");
  EXPECT_EQ(o.exit_code, 2);
  EXPECT_THAT(o.err, HasSubstr("simulation.initial_position_m"));
  EXPECT_THAT(o.err, HasSubstr("soft limits (controller.soft_limit_min_m, soft_limit_max_m: [-0.24, 0.24] m, got 0.249 m)"));
  EXPECT_EQ(o.out, "");
  EXPECT_EQ(pneud("--quiet --duration 1 --set simulation.initial_position_m=0.24").exit_code, 0) << "at the limit";
}

// Item 5: a stop in the safe output has no forecast, so no F_e: the summary says n/a and why, not nan.
TEST_F(PneudCli, AStopWithoutAForecastShowsNoEquilibriumForceAndSaysWhyNeverNan) {
  // A following error of 10 mm for 10 ms latches at the step; the carriage then stops under the safe output.
  const Outcome o = pneud("--duration 3 --set controller.supervisor.following_error_m=0.01"
                          " --set controller.supervisor.following_error_s=0.01");
  ASSERT_EQ(o.exit_code, 3) << "ended with the fault latched: " << o.err;
  EXPECT_THAT(o.out, HasSubstr("fault at 1.0100 s"));
  EXPECT_THAT(o.out, ::testing::ContainsRegex("stuck; u\\* changed at"));
  EXPECT_THAT(o.out, ::testing::ContainsRegex(" n/a  stuck"));
  EXPECT_THAT(o.out, HasSubstr("(F_e n/a: no forecast at that stop"));
  EXPECT_THAT(o.out, Not(HasSubstr("nan")));
}

}  // namespace
