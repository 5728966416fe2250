// pneu-dash's /metrics (tools/dash/metrics): a bench's records in, the Prometheus text exposition
// format out, checked line by line where it matters, held to promtool's parser and linter, and
// the documentation's table held to the code's.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "pneu/controller/records.hpp"
#include "pneu/dash/metrics.hpp"
#include "pneu/dash/metrics_feed.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
#include "support/child_process.hpp"

namespace {

using pneu::controller::EventMessage;
using pneu::controller::FaultCause;
using pneu::controller::ForecastRecord;
using pneu::controller::HealthMessage;
using pneu::controller::IdentificationRecord;
using pneu::controller::LoopEvent;
using pneu::controller::PredictionMethod;
using pneu::dash::Metrics;
using ::testing::HasSubstr;
using ::testing::Not;
namespace kind = pneu::controller::event_kind;
namespace fs = std::filesystem;

Metrics metrics(const std::string& bench = "bench-7") {
  return Metrics(bench, [] { return 1.7e9; });
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// Whether `text` has the line `line`, whole.
bool has_line(const std::string& text, const std::string& line) {
  for (const std::string& l : lines(text))
    if (l == line) return true;
  return false;
}
#define EXPECT_LINE(text, line) \
  EXPECT_TRUE(has_line(text, line)) << "no line\n  " << (line) << "\nin\n" << (text)

HealthMessage health(std::int64_t overruns = 3) {
  HealthMessage h;
  h.t_s = 12.0;
  h.mode = static_cast<std::int8_t>(pneu::controller::Mode::kArmed);
  h.ticks = 12000;
  h.overruns = overruns;
  h.wake_latency_us = {2.0, 9.5, 42.0, 180.0};
  h.compute_us = {1.0, 3.0, 6.0, 11.0};
  h.comms_errors = 5;
  h.commands_received = 4;
  h.commands_accepted = 3;
  h.commands_rejected = 1;
  h.rejected_rate = 1;
  h.host = "rig";
  h.pid = 4242;
  h.start_utime = 1'699'999'000'000'000;
  h.nonce = 99;
  h.period_s = 1.0;
  return h;
}

EventMessage event(std::int8_t k, double t_s, std::int64_t stop = 0) {
  EventMessage e;
  e.kind = k;
  e.t_s = t_s;
  e.stop = stop;
  return e;
}

// The event_t pneud sends when a fault with `cause` latches (its own text).
EventMessage fault(FaultCause cause, double t_s) {
  LoopEvent e;
  e.kind = LoopEvent::Kind::kFault;
  e.fault_cause = cause;
  e.t_s = t_s;
  return pneu::controller::event_message(e);
}

ForecastRecord forecast(PredictionMethod m, std::uint64_t stop, bool will_restart,
                        double t_restart_s, std::uint32_t update = 0) {
  ForecastRecord f;
  f.stop = stop;
  f.update = update;
  f.t_s = 1.0 + 0.1 * update;
  f.prediction.method = m;
  f.prediction.will_restart = will_restart;
  f.prediction.t_restart_s = t_restart_s;
  return f;
}

std::size_t index_of(const char* name) {
  for (std::size_t i = 0; i < pneu::controller::kIdentifiedParameters.size(); ++i)
    if (std::string(pneu::controller::kIdentifiedParameters[i].name) == name) return i;
  ADD_FAILURE() << "no parameter " << name;
  return 0;
}

IdentificationRecord identification(std::uint32_t updates, double static_positive_n,
                                    double static_negative_n) {
  IdentificationRecord r;
  r.t_s = 5.0 * updates;
  r.updates = updates;
  r.value[index_of("static_positive_n")] = static_positive_n;
  r.sigma[index_of("static_positive_n")] = 0.5;
  r.identified[index_of("static_positive_n")] = true;
  r.value[index_of("static_negative_n")] = static_negative_n;
  r.identified[index_of("static_negative_n")] = true;
  r.value[index_of("null_offset_v")] = 0.02;  // not identified: served nowhere
  return r;
}

// A bench fed with one of each record: every family has samples.
void feed(Metrics& m) {
  m.on_health(health());
  m.on_event(event(kind::kStop, 1.0, 1));
  m.on_forecast(forecast(PredictionMethod::kLinearized, 1, true, 2.5));
  m.on_forecast(forecast(PredictionMethod::kNonlinear, 1, true, 2.3));
  ForecastRecord again = forecast(PredictionMethod::kLinearized, 1, true, 2.5, 1);
  again.force_n = 40.0;
  again.stop_forecast_force_n = 41.5;
  m.on_forecast(again);
  m.on_event(event(kind::kRestart, 2.4, 1));
  m.on_event(fault(FaultCause::kFollowingError, 3.0));
  m.on_identification(identification(1, 50.0, -48.0));
  m.on_identification(identification(2, 53.0, -48.5));
}
std::string fed_text(const std::string& bench = "bench-7") {
  Metrics m = metrics(bench);
  feed(m);
  return m.text();
}

TEST(DashMetrics, EveryFamilyHasItsHelpAndTypeOnceAndEverySampleTheBenchLabelFirst) {
  const std::string text = fed_text();
  for (const auto& f : pneu::dash::metric_families()) {
    EXPECT_LINE(text, "# TYPE " + f.name + " " + f.type);
    EXPECT_THAT(text, HasSubstr("# HELP " + f.name + " "));
  }
  std::set<std::string> named;
  for (const std::string& l : lines(text)) {
    if (l.starts_with("# HELP ")) {
      EXPECT_TRUE(named.insert(l.substr(7, l.find(' ', 7) - 7)).second) << "twice: " << l;
      continue;
    }
    if (l.starts_with("#")) continue;
    EXPECT_THAT(l, HasSubstr("{bench=\"bench-7\"")) << "every series is the bench's";
  }
  EXPECT_EQ(named.size(), pneu::dash::metric_families().size());
}

TEST(DashMetrics, CountersEndInTotalAndNamesSayTheirUnit) {
  for (const auto& f : pneu::dash::metric_families()) {
    if (std::string(f.type) == "counter")
      EXPECT_TRUE(f.name.ends_with("_total")) << f.name;
    else
      EXPECT_FALSE(f.name.ends_with("_total")) << f.name;
    EXPECT_TRUE(f.name.starts_with("pneu_")) << f.name;
  }
}

TEST(DashMetrics, HealthCountersAreServedAsPneudCountedThemAndLatenciesInSeconds) {
  const std::string text = fed_text();
  EXPECT_LINE(text, "pneu_overruns_total{bench=\"bench-7\"} 3");
  EXPECT_LINE(text, "pneu_ticks_total{bench=\"bench-7\"} 12000");
  EXPECT_LINE(text, "pneu_comms_errors_total{bench=\"bench-7\"} 5");
  EXPECT_LINE(text, "pneu_commands_accepted_total{bench=\"bench-7\"} 3");
  EXPECT_LINE(text, "pneu_commands_rejected_total{bench=\"bench-7\",reason=\"rate\"} 1");
  EXPECT_LINE(text, "pneu_commands_rejected_total{bench=\"bench-7\",reason=\"oversized\"} 0");
  EXPECT_LINE(text, "pneu_wake_latency_seconds{bench=\"bench-7\",quantile=\"0.5\"} 9.5e-06");
  EXPECT_LINE(text, "pneu_wake_latency_seconds{bench=\"bench-7\",quantile=\"0.99\"} 4.2e-05");
  EXPECT_LINE(text, "pneu_wake_latency_seconds{bench=\"bench-7\",quantile=\"1\"} 0.00018");
  EXPECT_LINE(text, "pneu_compute_seconds{bench=\"bench-7\",quantile=\"0\"} 1e-06");
  EXPECT_LINE(text, "pneu_mode{bench=\"bench-7\",mode=\"ARMED\"} 1");
  EXPECT_LINE(text, "pneu_mode{bench=\"bench-7\",mode=\"FAULT\"} 0");
  EXPECT_LINE(text, "pneu_fault_latched{bench=\"bench-7\",cause=\"comms\"} 0");
  EXPECT_LINE(text, "pneu_pneud_start_time_seconds{bench=\"bench-7\"} 1699999000");
  EXPECT_LINE(text, "pneu_last_health_timestamp_seconds{bench=\"bench-7\"} 1700000000");
  // A later health message replaces the figures.
  Metrics m = metrics();
  m.on_health(health(3));
  m.on_health(health(8));
  EXPECT_LINE(m.text(), "pneu_overruns_total{bench=\"bench-7\"} 8");
}

TEST(DashMetrics, BeforeAnyHealthTheHealthFamiliesHaveNoSamplesAndTheEventCountersZero) {
  const std::string text = metrics().text();
  EXPECT_THAT(text, Not(HasSubstr("pneu_overruns_total{")));
  EXPECT_THAT(text, Not(HasSubstr("pneu_mode{")));
  EXPECT_LINE(text, "pneu_restarts_total{bench=\"bench-7\"} 0");
  EXPECT_LINE(text, "pneu_faults_total{bench=\"bench-7\",cause=\"e-stop\"} 0");
}

TEST(DashMetrics, StopsRestartsAndFaultsByCauseAreCountedFromTheEvents) {
  Metrics m = metrics();
  for (int i = 1; i <= 3; ++i) {
    m.on_event(event(kind::kStop, i, i));
    m.on_event(event(i == 2 ? kind::kStart : kind::kRestart, i + 0.5, i));
  }
  m.on_event(fault(FaultCause::kComms, 9.0));
  m.on_event(fault(FaultCause::kComms, 19.0));
  m.on_event(fault(FaultCause::kMovementTest, 29.0));
  EventMessage odd = event(kind::kFault, 30.0);
  odd.text = "fault (flux-capacitor): a cause from a newer pneud";
  m.on_event(odd);
  m.on_event(event(kind::kFaultReset, 31.0));
  m.on_event(event(kind::kCommandAccepted, 32.0));
  const std::string text = m.text();
  EXPECT_LINE(text, "pneu_stops_total{bench=\"bench-7\"} 3");
  EXPECT_LINE(text, "pneu_restarts_total{bench=\"bench-7\"} 2");
  EXPECT_LINE(text, "pneu_starts_total{bench=\"bench-7\"} 1");
  EXPECT_LINE(text, "pneu_faults_total{bench=\"bench-7\",cause=\"comms\"} 2");
  EXPECT_LINE(text, "pneu_faults_total{bench=\"bench-7\",cause=\"movement-test\"} 1");
  EXPECT_LINE(text, "pneu_faults_total{bench=\"bench-7\",cause=\"unknown\"} 1");
  EXPECT_LINE(text, "pneu_faults_total{bench=\"bench-7\",cause=\"e-stop\"} 0");
  EXPECT_LINE(text, "pneu_fault_resets_total{bench=\"bench-7\",result=\"cleared\"} 1");
}

TEST(DashMetrics, EveryFaultCauseIsReadBackFromTheTextPneudSendsForIt) {
  for (std::size_t c = 1; c < pneu::controller::kFaultCauseCount; ++c) {
    const auto cause = static_cast<FaultCause>(c);
    EXPECT_EQ(Metrics::fault_cause_of(fault(cause, 1.0).text), cause)
        << pneu::controller::fault_name(cause);
  }
  EXPECT_EQ(Metrics::fault_cause_of("stop"), FaultCause::kNone);
}

TEST(DashMetrics, AForecastAtAStopIsJudgedByHowTheStopEndsAndAHitsErrorIsObserved) {
  const std::string text = fed_text();
  // linearized forecast 2.5 s, nonlinear 2.3 s, the restart at 2.4 s: both hits, 0.1 s off each
  // way.
  EXPECT_LINE(text,
              "pneu_forecasts_total{bench=\"bench-7\",method=\"linearized\",made=\"at_stop\"} 1");
  EXPECT_LINE(text,
              "pneu_forecasts_total{bench=\"bench-7\",method=\"linearized\",made=\"again\"} 1");
  EXPECT_LINE(
      text,
      "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"linearized\",outcome=\"hit\"} 1");
  EXPECT_LINE(
      text,
      "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"nonlinear\",outcome=\"hit\"} 1");
  EXPECT_LINE(
      text,
      "pneu_forecast_error_seconds{bench=\"bench-7\",method=\"linearized\"} 0.10000000000000009");
  EXPECT_LINE(
      text,
      "pneu_forecast_error_seconds{bench=\"bench-7\",method=\"nonlinear\"} -0.10000000000000009");
  EXPECT_LINE(text,
              "pneu_forecast_abs_error_seconds_bucket{bench=\"bench-7\",method=\"linearized\",le="
              "\"0.05\"} 0");
  EXPECT_LINE(text,
              "pneu_forecast_abs_error_seconds_bucket{bench=\"bench-7\",method=\"linearized\",le="
              "\"0.2\"} 1");
  EXPECT_LINE(text,
              "pneu_forecast_abs_error_seconds_bucket{bench=\"bench-7\",method=\"linearized\",le="
              "\"+Inf\"} 1");
  EXPECT_LINE(text,
              "pneu_forecast_abs_error_seconds_count{bench=\"bench-7\",method=\"linearized\"} 1");
  EXPECT_LINE(text, "pneu_forecast_abs_error_seconds_count{bench=\"bench-7\",method=\"held\"} 0");
  EXPECT_LINE(text,
              "pneu_forecast_force_error_newtons{bench=\"bench-7\",method=\"linearized\"} 1.5");
  EXPECT_THAT(text,
              Not(HasSubstr("pneu_forecast_error_seconds{bench=\"bench-7\",method=\"held\"}")))
      << "no hit, no error";

  Metrics m = metrics();
  // Stop 1: linearized forecasts no restart, it restarts (missed); nonlinear forecasts one at 1.5
  // s, the set point changes at 3 s, later (false alarm).
  m.on_event(event(kind::kStop, 1.0, 1));
  m.on_forecast(forecast(PredictionMethod::kLinearized, 1, false, std::nan("")));
  m.on_forecast(forecast(PredictionMethod::kNonlinear, 1, true, 1.5));
  m.on_event(event(kind::kRestart, 1.2, 1));
  // Stop 2: a forecast at 9 s, the set point changes at 3 s (untested).
  m.on_event(event(kind::kStop, 2.0, 2));
  m.on_forecast(forecast(PredictionMethod::kLinearized, 2, true, 9.0));
  m.on_event(event(kind::kStart, 3.0, 2));
  const std::string t2 = m.text();
  EXPECT_LINE(
      t2,
      "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"linearized\",outcome=\"missed\"} 1");
  EXPECT_LINE(
      t2, "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"nonlinear\",outcome=\"hit\"} 1");
  EXPECT_LINE(t2,
              "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"linearized\",outcome="
              "\"untested\"} 1");
  EXPECT_LINE(
      t2,
      "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"linearized\",outcome=\"hit\"} 0");

  Metrics f = metrics();
  f.on_event(event(kind::kStop, 1.0, 1));
  f.on_forecast(forecast(PredictionMethod::kLinearized, 1, true, 1.5));
  f.on_event(event(kind::kStart, 3.0, 1));
  EXPECT_LINE(f.text(),
              "pneu_forecast_outcomes_total{bench=\"bench-7\",method=\"linearized\",outcome="
              "\"false_alarm\"} 1");
}

TEST(DashMetrics, HoldTimeCountsEachHoldAndAnOpenOneUpToTheLatestLoopTime) {
  Metrics m = metrics();
  m.on_event(event(kind::kHoldStart, 10.0));
  m.on_event(event(kind::kHoldEnd, 12.5));
  m.on_event(event(kind::kHoldStart, 20.0));
  HealthMessage h = health();
  h.t_s = 21.0;
  m.on_health(h);
  EXPECT_LINE(m.text(), "pneu_holds_total{bench=\"bench-7\"} 2");
  EXPECT_LINE(m.text(), "pneu_hold_seconds_total{bench=\"bench-7\"} 3.5");
  m.on_event(event(kind::kHoldEnd, 21.25));
  EXPECT_LINE(m.text(), "pneu_hold_seconds_total{bench=\"bench-7\"} 3.75");
}

TEST(DashMetrics, StictionIsServedWithItsDriftSinceTheProcesssFirstIdentification) {
  Metrics m = metrics();
  feed(m);
  const std::string text = m.text();
  EXPECT_LINE(text, "pneu_stiction_newtons{bench=\"bench-7\",direction=\"positive\"} 53");
  EXPECT_LINE(text, "pneu_stiction_newtons{bench=\"bench-7\",direction=\"negative\"} 48.5");
  EXPECT_LINE(text, "pneu_stiction_drift_newtons{bench=\"bench-7\",direction=\"positive\"} 3");
  EXPECT_LINE(text, "pneu_stiction_drift_newtons{bench=\"bench-7\",direction=\"negative\"} 0.5");
  EXPECT_LINE(text, "pneu_stiction_sigma_newtons{bench=\"bench-7\",direction=\"positive\"} 0.5");
  EXPECT_LINE(text,
              "pneu_identified_value{bench=\"bench-7\",parameter=\"static_negative_n\"} -48.5");
  EXPECT_LINE(text, "pneu_identification_updates_total{bench=\"bench-7\"} 2");
  EXPECT_THAT(text, Not(HasSubstr("parameter=\"null_offset_v\""))) << "not identified, not served";
  EXPECT_THAT(text, Not(HasSubstr("pneu_coulomb_friction_newtons{")))
      << "not identified, not served";
  // pneud started again (its updates count from 1 again): the drift from its first identification.
  m.on_identification(identification(1, 60.0, -50.0));
  m.on_identification(identification(2, 61.0, -50.0));
  EXPECT_LINE(m.text(), "pneu_stiction_drift_newtons{bench=\"bench-7\",direction=\"positive\"} 1");
  // ... or a new health identity says so.
  HealthMessage h = health();
  h.nonce = 100;
  m.on_health(h);
  m.on_identification(identification(3, 62.5, -50.0));
  EXPECT_LINE(m.text(), "pneu_stiction_drift_newtons{bench=\"bench-7\",direction=\"positive\"} 0");
}

TEST(DashMetrics, LabelValuesAndValuesAreWrittenAsTheFormatWantsThem) {
  EXPECT_EQ(pneu::dash::escape_label_value("a\"b\\c\nd"), "a\\\"b\\\\c\\nd");
  EXPECT_EQ(pneu::dash::format_sample_value(std::nan("")), "NaN");
  EXPECT_EQ(pneu::dash::format_sample_value(-1.0 / 0.0), "-Inf");
  EXPECT_EQ(pneu::dash::format_sample_value(1e21), "1e+21");
  EXPECT_EQ(pneu::dash::format_sample_value(1.7e9), "1700000000");
  EXPECT_EQ(pneu::dash::format_sample_value(-2.5e-7), "-2.5e-07");
  EXPECT_EQ(pneu::dash::format_sample_value(12000), "12000");
  EXPECT_LINE(metrics("rig \"A\"").text(), "pneu_stops_total{bench=\"rig \\\"A\\\"\"} 0");
}

TEST(DashMetrics, AnotherPartsMetricsGetTheBenchLabelFirstOnEverySample) {
  EXPECT_EQ(
      pneu::dash::with_label(
          "# HELP a_total x\n# TYPE a_total counter\na_total{channel=\"S\"} 3\nb 1\nc{} 2\n",
          "bench", "rig \"A\""),
      "# HELP a_total x\n# TYPE a_total counter\na_total{bench=\"rig \\\"A\\\"\",channel=\"S\"} 3\n"
      "b{bench=\"rig \\\"A\\\"\"} 1\nc{bench=\"rig \\\"A\\\"\"} 2\n");
}

// The bytes pneud publishes for `record` as LCM type Message.
template <class Message, class Record>
std::vector<std::uint8_t> lcm_bytes(const Record& record) {
  Message m{};
  pneu::records::to_lcm(record, m);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())),
            static_cast<int>(bytes.size()));
  return bytes;
}

TEST(DashMetricsFeed, PneudsLcmMessagesReachTheMetricsAsTheirRecordsAndNothingElseDoes) {
  Metrics m = metrics();
  pneu::dash::MetricsFeed feed(m, "RIG7_");
  const auto forward = [&](const std::string& channel, const std::vector<std::uint8_t>& bytes) {
    return feed.forward(channel, bytes.data(), bytes.size());
  };
  EXPECT_TRUE(forward("RIG7_HEALTH", lcm_bytes<pneu_lcm::health_t>(health(11))));
  EXPECT_TRUE(forward("RIG7_EVENT", lcm_bytes<pneu_lcm::event_t>(event(kind::kStop, 1.0, 1))));
  EXPECT_TRUE(forward("RIG7_PREDICTION", lcm_bytes<pneu_lcm::prediction_t>(forecast(
                                             PredictionMethod::kNonlinear, 1, true, 2.0))));
  EXPECT_TRUE(forward("RIG7_EVENT", lcm_bytes<pneu_lcm::event_t>(event(kind::kRestart, 2.25, 1))));
  EXPECT_TRUE(forward("RIG7_IDENTIFICATION",
                      lcm_bytes<pneu_lcm::identification_t>(identification(1, 50.0, -48.0))));
  // Another bench's prefix, a channel the metrics do not read, a message cut short, another type.
  EXPECT_FALSE(forward("PNEU_EVENT", lcm_bytes<pneu_lcm::event_t>(event(kind::kRestart, 3.0, 1))));
  EXPECT_FALSE(forward("RIG7_STATE", lcm_bytes<pneu_lcm::event_t>(event(kind::kRestart, 3.0, 1))));
  std::vector<std::uint8_t> cut = lcm_bytes<pneu_lcm::event_t>(event(kind::kRestart, 3.0, 1));
  cut.resize(cut.size() - 1);
  EXPECT_FALSE(forward("RIG7_EVENT", cut));
  EXPECT_FALSE(forward("RIG7_EVENT", lcm_bytes<pneu_lcm::health_t>(health())));
  EXPECT_EQ(feed.undecodable(), 2u);

  const std::string text = m.text();
  EXPECT_LINE(text, "pneu_overruns_total{bench=\"bench-7\"} 11");
  EXPECT_LINE(text, "pneu_stops_total{bench=\"bench-7\"} 1");
  EXPECT_LINE(text, "pneu_restarts_total{bench=\"bench-7\"} 1");
  EXPECT_LINE(text, "pneu_forecast_error_seconds{bench=\"bench-7\",method=\"nonlinear\"} -0.25");
  EXPECT_LINE(text, "pneu_stiction_newtons{bench=\"bench-7\",direction=\"positive\"} 50");
}

// promtool (Debian's prometheus) checks the text: parses it, and lints the names and help.
std::string promtool() {
  for (const char* p : {"/usr/bin/promtool", "/usr/local/bin/promtool"})
    if (fs::exists(p)) return p;
  return "";
}
struct Checked {
  int status;
  std::string output;
};
Checked promtool_check(const std::string& text) {
  pneu::test::TestDir dir("dash_metrics_");
  const fs::path in = dir / "metrics.txt", out = dir / "promtool.out";
  {
    std::ofstream f(in);
    f << text;
  }
  const int rc = std::system(
      (promtool() + " check metrics < " + in.string() + " > " + out.string() + " 2>&1").c_str());
  return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, pneu::test::slurp(out)};
}

TEST(DashMetrics, PromtoolParsesAndLintsTheTextCleanAndRefusesAMalformedLine) {
  if (promtool().empty())
    GTEST_SKIP() << "promtool (Debian's prometheus, in scripts/deps) is not installed";
  const std::string text = fed_text("rig \"A\"");
  const Checked good = promtool_check(text);
  EXPECT_EQ(good.status, 0) << good.output << "\n" << text;
  EXPECT_EQ(good.output, "") << "no lint";
  EXPECT_EQ(promtool_check(metrics().text()).status, 0) << "nothing heard yet: still well formed";
  // A family more, well formed, passes; the same with one line malformed does not.
  const std::string probe = "# HELP pneu_probe_total a probe\n# TYPE pneu_probe_total counter\n";
  const Checked more = promtool_check(text + probe + "pneu_probe_total{bench=\"x\"} 1\n");
  EXPECT_EQ(more.status, 0) << more.output;
  const Checked bad = promtool_check(text + probe + "pneu_probe_total{bench=\"x\" 1\n");
  EXPECT_NE(bad.status, 0) << "a malformed line: " << bad.output;
  const Checked unescaped = promtool_check(text + probe + "pneu_probe_total{bench=\"a\"b\"} 1\n");
  EXPECT_NE(unescaped.status, 0) << "an unescaped quote: " << unescaped.output;
}

// docs/dashboard.md's table of the metrics is the code's: between its markers, as
// metric_families_markdown() writes it.
TEST(DashMetrics, TheDocumentationsTableOfMetricsIsTheCodes) {
  const std::string doc = pneu::test::slurp(fs::path(PNEU_SOURCE_DIR) / "docs" / "dashboard.md");
  const std::string begin =
      "<!-- metrics table: begin (tests/test_dash_metrics.cpp checks it) -->\n";
  const std::string end = "<!-- metrics table: end -->";
  const auto b = doc.find(begin), e = doc.find(end);
  ASSERT_NE(b, std::string::npos) << "docs/dashboard.md has no line " << begin;
  ASSERT_NE(e, std::string::npos) << "docs/dashboard.md has no line " << end;
  EXPECT_EQ(doc.substr(b + begin.size(), e - b - begin.size()),
            pneu::dash::metric_families_markdown())
      << "docs/dashboard.md's table, as it should be between the markers:\n"
      << pneu::dash::metric_families_markdown();
}

}  // namespace
