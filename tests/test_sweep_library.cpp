// The sweep as a library (pneu_sweep): scenarios drawn from its options, each run to a result
// value, the results aggregated into statistics, the statistics written as JSON. In-process, on
// the data, not on the summary's sentences.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>

#include "pneu/config/config.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/sweep/report.hpp"
#include "pneu/sweep/run.hpp"
#include "pneu/sweep/scenario.hpp"
#include "pneu/sweep/statistics.hpp"
#include "support/json.hpp"

namespace {

using namespace pneu;
using controller::Verdict;
using sweep::Outcome;

constexpr double kHalfStroke_m = 0.25;

sweep::Options options(int steps) {
  sweep::Options o;
  o.steps = steps;
  return o;
}

TEST(SweepScenarios, AreTheSameForASeedAndTheirStepsStayThoseOfTheSeedWhateverTheBenchSpread) {
  sweep::Options o = options(50);
  const auto a = sweep::draw_scenarios(o, kHalfStroke_m);
  const auto b = sweep::draw_scenarios(o, kHalfStroke_m);
  o.bench_spread = 0.2;
  o.bench_thermal_s = {0.5, 3.0};
  const auto spread = sweep::draw_scenarios(o, kHalfStroke_m);
  o.seed = 2;
  const auto other = sweep::draw_scenarios(o, kHalfStroke_m);
  ASSERT_EQ(a.size(), 50u);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].index, static_cast<int>(i));
    EXPECT_EQ(a[i].y0_m, b[i].y0_m);
    EXPECT_EQ(a[i].y0_m, spread[i].y0_m);
    EXPECT_EQ(a[i].y_d_m, spread[i].y_d_m);
    EXPECT_EQ(a[i].y_d_m, other[i].y_d_m);  // the targets do not depend on the seed
  }
  EXPECT_NE(a[0].y0_m, other[0].y0_m);
}

TEST(SweepScenarios, SpreadTheTargetsEvenlyOverTheStrokeLessTheMarginEachStartAtLeastTheMinimumStepAway) {
  sweep::Options o = options(40);
  o.margin_m = 0.03;
  o.min_step_m = 0.01;
  const auto scenarios = sweep::draw_scenarios(o, kHalfStroke_m);
  const double lo = -kHalfStroke_m + o.margin_m, hi = kHalfStroke_m - o.margin_m;
  for (std::size_t i = 0; i < scenarios.size(); ++i) {
    const sweep::Scenario& s = scenarios[i];
    EXPECT_NEAR(s.y_d_m, lo + (hi - lo) * (static_cast<double>(i) + 0.5) / 40.0, 1e-15);
    EXPECT_GE(s.y0_m, lo);
    EXPECT_LE(s.y0_m, hi);
    EXPECT_GE(std::abs(s.y0_m - s.y_d_m), o.min_step_m);
    EXPECT_EQ(s.friction_scale, 1.0);  // no spread asked
    EXPECT_EQ(s.gain_scale, 1.0);
    EXPECT_EQ(s.bench.static_positive, 1.0);
    EXPECT_TRUE(std::isnan(s.bench.thermal_time_constant_s));
  }
}

TEST(SweepScenarios, DrawEachBenchWithinTheSpreadAroundTheModelAndNoTwoAlike) {
  sweep::Options o = options(30);
  o.bench_spread = 0.2;
  o.bench_spool_lag_s = {0.0, 0.005};
  const auto scenarios = sweep::draw_scenarios(o, kHalfStroke_m);
  for (const sweep::Scenario& s : scenarios) {
    for (const double f : {s.bench.static_positive, s.bench.coulomb_negative, s.bench.max_conductance, s.bench.dead_volume_n}) {
      EXPECT_GE(f, 0.8);
      EXPECT_LE(f, 1.2);
    }
    EXPECT_LE(std::abs(s.bench.null_offset_v), 0.1);
    EXPECT_GE(s.bench.spool_time_constant_s, 0.0);
    EXPECT_LE(s.bench.spool_time_constant_s, 0.005);
  }
  EXPECT_NE(scenarios[0].bench.static_positive, scenarios[1].bench.static_positive);
  // Applied to a model: each Coulomb level within its stiction bound.
  model::PlantParams model = config::load_file_or_default("").plant;
  for (const sweep::Scenario& s : scenarios) {
    const model::PlantParams bench = s.bench.applied_to(model);
    EXPECT_LE(bench.friction.coulomb_positive_n, bench.friction.static_positive_n);
    EXPECT_GE(bench.friction.coulomb_negative_n, bench.friction.static_negative_n);
    EXPECT_EQ(bench.valve.spool_time_constant_s, s.bench.spool_time_constant_s);
  }
}

TEST(SweepScenarios, AreRefusedWhenTheOptionsLeaveNoRoomInTheStroke) {
  sweep::Options o = options(4);
  o.min_step_m = kHalfStroke_m;  // the mid-stroke target has no start that far inside the stroke
  EXPECT_THROW((void)sweep::draw_scenarios(o, kHalfStroke_m), std::invalid_argument);
  o = options(0);
  EXPECT_THROW((void)sweep::draw_scenarios(o, kHalfStroke_m), std::invalid_argument);
}

// A few scenarios of the shipped default, the nonlinear forecasts held, run once for the tests below.
class SweepOfAFewScenarios : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    config_ = new config::Config(config::load_file_or_default("", {"controller.predictor.methods=[nonlinear]"}));
    options_ = options(6);
    scenarios_ = new std::vector<sweep::Scenario>(sweep::draw_scenarios(options_, config_->plant.geometry.half_stroke_m()));
    int calls = 0, last_done = -1;
    run_ = new sweep::SweepRun(sweep::run_all(*config_, options_, *scenarios_, 2, [&](int done, int total, double) {
      ++calls;
      EXPECT_EQ(total, 6);
      EXPECT_GE(done, last_done);
      last_done = done;
    }));
    EXPECT_GE(calls, 1);
    EXPECT_EQ(last_done, 6);  // the last call: all done
  }
  static void TearDownTestSuite() {
    delete run_;
    delete scenarios_;
    delete config_;
  }
  static config::Config* config_;
  static sweep::Options options_;
  static std::vector<sweep::Scenario>* scenarios_;
  static sweep::SweepRun* run_;
};
config::Config* SweepOfAFewScenarios::config_ = nullptr;
sweep::Options SweepOfAFewScenarios::options_;
std::vector<sweep::Scenario>* SweepOfAFewScenarios::scenarios_ = nullptr;
sweep::SweepRun* SweepOfAFewScenarios::run_ = nullptr;

TEST_F(SweepOfAFewScenarios, GiveEveryScenarioItsResultInOrderWithAnOutcomeAndItsStopsJudged) {
  ASSERT_EQ(run_->results.size(), 6u);
  EXPECT_EQ(run_->jobs, 2);
  int restarts = 0;
  EXPECT_GT(run_->wall_s, 0.0);
  for (std::size_t i = 0; i < run_->results.size(); ++i) {
    const sweep::ScenarioResult& r = run_->results[i];
    EXPECT_EQ(r.scenario.index, static_cast<int>(i));
    EXPECT_TRUE(r.ran());
    EXPECT_FALSE(r.identified);  // not asked
    // The shipped default settles every scenario of the acceptance sweep.
    EXPECT_EQ(r.settling.outcome, Outcome::kSettled) << "scenario " << i;
    EXPECT_GE(r.settling.settle_time_s, 0.0);
    EXPECT_LT(r.settling.final_error_m, 1e-3);
    EXPECT_EQ(r.settling.fault, controller::FaultCause::kNone);
    EXPECT_NEAR(r.t_end_s, options_.duration_s + options_.tail_s, 0.01);
    ASSERT_FALSE(r.stops.empty());
    for (const sweep::JudgedStop& j : r.stops) {
      EXPECT_LE(j.stop.t_stop_s, options_.duration_s);  // none of the tail's
      EXPECT_FALSE(j.at_stop[0]);                       // the linearized method not asked
      ASSERT_TRUE(j.at_stop[1]);
      EXPECT_TRUE(j.at_stop[1]->within_criteria);  // the nonlinear criteria hold (unjudged: trivially)
      EXPECT_FALSE(j.on_slow_side);                 // not --online
      if (j.fate == sweep::StopFate::kRestart) {    // the plant's restart, forecast as such
        ++restarts;
        EXPECT_EQ(j.at_stop[1]->verdict.kind, Verdict::Kind::kTruePositive);
      }
    }
  }
  EXPECT_GT(restarts, 0);
}

TEST_F(SweepOfAFewScenarios, RunOneScenarioAloneToTheSameResultAsAmongTheOthersOnThreads) {
  const sweep::ScenarioResult alone = sweep::run_scenario(*config_, options_, (*scenarios_)[3]);
  const sweep::ScenarioResult& among = run_->results[3];
  EXPECT_EQ(alone.settling.settle_time_s, among.settling.settle_time_s);
  EXPECT_EQ(alone.settling.final_error_m, among.settling.final_error_m);
  ASSERT_EQ(alone.stops.size(), among.stops.size());
  for (std::size_t k = 0; k < alone.stops.size(); ++k) {
    EXPECT_EQ(alone.stops[k].fate, among.stops[k].fate);
    EXPECT_EQ(alone.stops[k].stop.t_end_s, among.stops[k].stop.t_end_s);
    EXPECT_EQ(alone.stops[k].at_stop[1]->verdict.error_s, among.stops[k].at_stop[1]->verdict.error_s);
  }
}

TEST_F(SweepOfAFewScenarios, AggregateToCountsThatAddUpToTheScenariosAndTheirStops) {
  const sweep::Statistics st = sweep::aggregate(sweep::setting_of(*config_, options_), *run_);
  EXPECT_EQ(st.scenarios, 6);
  EXPECT_EQ(st.scenarios_run, 6u);
  std::uint64_t outcomes = 0;
  for (const auto& o : st.outcomes) outcomes += o.count;
  EXPECT_EQ(outcomes, 6u);
  EXPECT_EQ(st.count(Outcome::kSettled), 6u);
  EXPECT_EQ(st.settle_time_s.count, 6u);
  EXPECT_EQ(st.in_window_after_s.count + st.never_in_window, 6u);
  std::uint64_t stops = 0, restarts = 0;
  for (const auto& r : run_->results) {
    stops += r.stops.size();
    for (const auto& j : r.stops) restarts += j.judged() && j.stop.restarted ? 1 : 0;
  }
  EXPECT_EQ(st.stops, stops);
  EXPECT_EQ(st.restarts, restarts);
  const sweep::MethodStatistics& nl = st.methods[1];
  EXPECT_EQ(nl.judged() + nl.not_judged, stops);  // every stop forecast, judged or not
  EXPECT_EQ(nl.true_restart, restarts);
  EXPECT_EQ(nl.outside_criteria, 0u);
  EXPECT_EQ(st.methods[0].judged() + st.methods[0].not_judged, 0u);  // linearized: not asked
  EXPECT_EQ(st.wall_s, run_->wall_s);
  EXPECT_EQ(st.jobs, 2);
  EXPECT_TRUE(st.settling_rules_checked);  // the shipped rules, not supervised
}

TEST_F(SweepOfAFewScenarios, WriteTheirStatisticsAsJsonWithTheSameFigures) {
  const sweep::Statistics st = sweep::aggregate(sweep::setting_of(*config_, options_), *run_);
  std::ostringstream text;
  sweep::write_summary_json(text, st);
  const auto j = pneu::test::Json::parse(text.str());
  EXPECT_EQ(j["scenarios"].count(), 6u);
  EXPECT_EQ(j["outcomes"]["settled"]["count"].count(), st.count(Outcome::kSettled));
  EXPECT_EQ(j["outcomes"]["never_settled"]["count"].count(), 0u);
  EXPECT_TRUE(j["outcomes"]["never_settled"]["y0_min_m"].is_null());  // none: no range
  EXPECT_EQ(j["stops"]["count"].count(), st.stops);
  EXPECT_EQ(j["stops"]["restarts"].count(), st.restarts);
  EXPECT_NEAR(j["settle_time_s"]["p90"].number(), st.settle_time_s.p90, 1e-9);
  EXPECT_EQ(j["methods"]["nonlinear"]["true_restart"].count(), st.methods[1].true_restart);
  EXPECT_EQ(j["methods"]["nonlinear"]["judged"].count(), st.methods[1].judged());
  EXPECT_FALSE(j["setting"]["identify"].flag());
  EXPECT_FALSE(j.has("identification"));  // only with --identify
  EXPECT_EQ(j["jobs"].count(), 2u);
}

// Hand-made results: a scenario of each outcome, one whose identification failed.
sweep::ScenarioResult result(int index, Outcome outcome, double settle_time_s) {
  sweep::ScenarioResult r;
  r.scenario.index = index;
  r.scenario.y0_m = 0.01 * index;
  r.scenario.y_d_m = -0.01 * index;
  r.settling.outcome = outcome;
  r.settling.fault = controller::FaultCause::kNone;
  r.settling.settle_time_s = settle_time_s;
  r.settling.final_error_m = 1e-4 * index;
  r.settling.in_window_after_s = settle_time_s;
  return r;
}

// A judged restart after `sticking_s`, forecast by the nonlinear method `error_percent` off.
sweep::JudgedStop restart(double sticking_s, double error_percent) {
  sweep::JudgedStop j;
  j.stop.t_stop_s = 1.0;
  j.stop.t_end_s = 1.0 + sticking_s;
  j.stop.ended = j.stop.restarted = true;
  j.fate = sweep::StopFate::kRestart;
  sweep::JudgedForecast f;
  f.verdict.kind = Verdict::Kind::kTruePositive;
  f.verdict.error_percent = error_percent;
  f.verdict.error_s = error_percent / 100 * sticking_s;
  f.within_criteria = error_percent <= 1.0;
  j.at_stop[1] = f;
  j.long_restart = sticking_s >= sweep::kLongSticking_s;
  return j;
}

TEST(SweepStatistics, OfHandMadeResultsGiveTheirCountsAndPercentiles) {
  std::vector<sweep::ScenarioResult> results;
  for (int i = 0; i < 4; ++i) results.push_back(result(i, Outcome::kSettled, 1.0 + i));  // 1, 2, 3, 4 s
  results.push_back(result(4, Outcome::kNeverSettled, NAN));
  results.back().settling.in_window_after_s = NAN;
  results.push_back(result(5, Outcome::kFault, NAN));
  results.back().settling.fault = controller::FaultCause::kOscillation;
  results.back().settling.in_window_after_s = NAN;
  results.push_back(result(6, Outcome::kSettled, 0.5));
  results.back().identification_failed = "too little shown";
  results[0].stops = {restart(0.8, 0.5), restart(2.0, 3.0), restart(0.1, 0.0)};
  results[1].stops = {restart(0.6, 1.5)};
  sweep::JudgedStop unjudged = restart(1.0, 0.0);
  unjudged.fate = sweep::StopFate::kPlantNotAtRest;
  unjudged.truth.not_at_rest = true;
  unjudged.at_stop[1]->verdict = Verdict{};
  unjudged.long_restart = false;
  results[1].stops.push_back(unjudged);

  sweep::Setting setting;
  setting.settling_rules.sign_changes = 4;
  const sweep::Statistics st = sweep::aggregate(setting, results);
  EXPECT_EQ(st.scenarios, 7);
  EXPECT_EQ(st.scenarios_run, 6u);  // the one whose identification failed did not run
  EXPECT_EQ(st.count(Outcome::kSettled), 4u);
  EXPECT_EQ(st.count(Outcome::kNeverSettled), 1u);
  EXPECT_EQ(st.count(Outcome::kEndStop), 0u);
  EXPECT_EQ(st.count(Outcome::kFault), 1u);
  EXPECT_EQ(st.faults_by_cause[controller::fault_number(controller::FaultCause::kOscillation)], 1u);
  EXPECT_EQ(st.outcomes[static_cast<std::size_t>(Outcome::kNeverSettled)].y0_min_m, 0.04);
  ASSERT_EQ(st.identification.failures.size(), 1u);
  EXPECT_EQ(st.identification.failures[0], "scenario 6: too little shown");
  // The settle times of the settled ones that ran: 1, 2, 3, 4 s.
  EXPECT_EQ(st.settle_time_s.count, 4u);
  EXPECT_DOUBLE_EQ(st.settle_time_s.p50, 2.5);
  EXPECT_NEAR(st.settle_time_s.p90, 3.7, 1e-12);
  EXPECT_DOUBLE_EQ(st.settle_time_s.max, 4.0);
  // Into the window: 4 came, 2 never; over all 6, p90 is never.
  EXPECT_EQ(st.in_window_after_s.count, 4u);
  EXPECT_EQ(st.never_in_window, 2u);
  EXPECT_DOUBLE_EQ(st.in_window_all_p50_s, 3.5);
  EXPECT_TRUE(std::isinf(st.in_window_all_p90_s));
  // The stops: 5, of them 4 judged restarts, 3 long (>= 0.5 s), 1 after >= 1 s; 1 not at rest.
  EXPECT_EQ(st.stops, 5u);
  EXPECT_EQ(st.restarts, 4u);
  EXPECT_EQ(st.long_restarts, 3u);
  EXPECT_EQ(st.restarts_after_1_s, 1u);
  EXPECT_EQ(st.not_at_rest, 1u);
  const sweep::MethodStatistics& nl = st.methods[1];
  EXPECT_EQ(nl.true_restart, 4u);
  EXPECT_EQ(nl.not_judged, 1u);
  EXPECT_EQ(nl.judged(), 4u);
  EXPECT_EQ(nl.outside_criteria, 2u);  // 3 % and 1.5 %
  EXPECT_EQ(nl.long_error_percent.count, 3u);
  EXPECT_DOUBLE_EQ(nl.long_error_percent.p50, 1.5);
  EXPECT_DOUBLE_EQ(nl.long_error_percent.max, 3.0);
  EXPECT_EQ(nl.long_within, (sweep::Within2510{2, 3, 3}));
  EXPECT_EQ(nl.short_error_ms.count, 1u);
  // No forecast made again half-way: counted only where the method forecasts half-way.
  EXPECT_EQ(nl.halfway_missing, 0u);
  setting.halfway_enabled[1] = true;
  EXPECT_EQ(sweep::aggregate(setting, results).methods[1].halfway_missing, 3u);
}

TEST(SweepStatistics, PercentilesInterpolateBetweenTheOrderStatisticsAndNeverIsNever) {
  EXPECT_TRUE(std::isnan(sweep::percentile({}, 0.5)));
  EXPECT_DOUBLE_EQ(sweep::percentile({3.0, 1.0, 2.0}, 0.5), 2.0);
  EXPECT_DOUBLE_EQ(sweep::percentile({1.0, 2.0}, 0.5), 1.5);
  const double never = std::numeric_limits<double>::infinity();
  EXPECT_DOUBLE_EQ(sweep::percentile({1.0, 2.0, never}, 0.25), 1.5);
  EXPECT_TRUE(std::isinf(sweep::percentile({1.0, 2.0, never}, 0.75)));
  EXPECT_EQ(sweep::within_2_5_10({1.0, 2.0, 4.0, 9.0, 11.0}), (sweep::Within2510{2, 3, 4}));
}

}  // namespace
