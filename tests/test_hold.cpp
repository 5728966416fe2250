// The in-position hold (controller.hold, docs/model.md section 11) on the simulated bench, end to
// end: the loop, the plant, a push of hal.sim.pushes. The loop's own rules (when it takes over,
// when it hands back, and why) are specified in test_loop_modes.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/controller/session.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/simulated_run.hpp"

namespace {

using namespace pneu;
using controller::LoopEvent;
using controller::Mode;

// Every tick's record and every event of a run.
struct Recorder final : controller::RunListener {
  std::vector<controller::TickRecord> ticks;
  std::vector<LoopEvent> events;
  std::vector<controller::ForecastRecord> held;  // the forecasts under the hold's commands
  void on_tick(const controller::TickRecord& r, const controller::ExpectedAtTick&) override { ticks.push_back(r); }
  void on_event(const LoopEvent& e) override { events.push_back(e); }
  void on_forecast(const controller::ForecastRecord& f) override {
    if (f.prediction.method == controller::PredictionMethod::kHeld) held.push_back(f);
  }
};

// The default configuration (embedded sim.yaml: 12 s, the step to 170 mm at 1 s) with `overrides`.
struct HoldRun {
  assembly::AssembledRun assembled;
  const config::Config& config = assembled.config();
  controller::Run& run = assembled.run();
  const hal::SimBackend* bench = assembled.simulated_bench();
  Recorder& record = assembled.emplace_sink<Recorder>();

  explicit HoldRun(const std::vector<std::string>& overrides, std::string_view yaml = config::default_config_yaml())
      : assembled(test::simulated_run(config::load_string(yaml, overrides))) {
    const double period = config.controller.period_s();
    const auto ticks = static_cast<int>(std::llround(config.controller.duration_s / period));
    run.loop->start(0.0);
    for (int k = 1; k <= ticks; ++k) {
      run.loop->tick(k * period);
      run.runtime->drain(*run.outputs);
    }
    run.runtime->finish(run.runtime->end_time_s());
  }
  HoldRun(const HoldRun&) = delete;
  HoldRun& operator=(const HoldRun&) = delete;

  [[nodiscard]] double window_m() const { return config.controller.hold.window_m; }
  [[nodiscard]] std::vector<const LoopEvent*> events_of(LoopEvent::Kind kind, double from_s = 0.0) const {
    std::vector<const LoopEvent*> v;
    for (const auto& e : record.events)
      if (e.kind == kind && e.t_s >= from_s) v.push_back(&e);
    return v;
  }
  // The plant's breakaways from `from_s` on.
  [[nodiscard]] std::vector<plant::PlantEvent> breakaways(double from_s) const {
    std::vector<plant::PlantEvent> v;
    for (const auto& e : bench->motion_events())
      if (e.kind == plant::PlantEvent::Kind::kBreakaway && e.t_s >= from_s) v.push_back(e);
    return v;
  }
};

TEST(InPositionHold, TheDefaultRunsStopWithinTheWindowIsHeldAndTheRestartItWouldHaveNeverComes) {
  // Without the hold the carriage, at rest 0.42 mm from its set point from 1.44 s, restarts at 3.9 s.
  const HoldRun without({});
  EXPECT_FALSE(without.breakaways(2.0).empty());
  EXPECT_TRUE(without.events_of(LoopEvent::Kind::kHoldStart).empty());

  const HoldRun with({"controller.hold.enabled=true"});
  const auto holds = with.events_of(LoopEvent::Kind::kHoldStart, 1.0);
  ASSERT_EQ(holds.size(), 1u);
  const double t_hold = holds.front()->t_s;
  EXPECT_LT(std::abs(holds.front()->y_m - holds.front()->y_d_m), with.window_m());
  EXPECT_TRUE(with.breakaways(t_hold).empty()) << "no breakaway at all after the hold began";
  EXPECT_TRUE(with.events_of(LoopEvent::Kind::kHoldEnd, t_hold).empty());
  // Every tick from the hold's start on is a hold, and its force settles at the middle of the
  // stiction band, (45 - 50) / 2 = -2.5 N, never nearer a bound than 10 N on the way (measured:
  // -28.8 N at worst, the relaxation under way at the stop before the hold catches it).
  double nearest_bound_n = 1e9;
  for (const auto& r : with.record.ticks) {
    if (r.t_s < t_hold) continue;
    ASSERT_EQ(r.mode, Mode::kHold) << r.t_s;
    nearest_bound_n = std::min({nearest_bound_n, 45.0 - r.force_n, r.force_n + 50.0});
  }
  EXPECT_GT(nearest_bound_n, 10.0);
  EXPECT_NEAR(with.record.ticks.back().force_n, -2.5, 0.05);
  EXPECT_TRUE(with.run.runtime->faults().empty());
}

TEST(InPositionHold, APushBeyondTheWindowHandsBackByTheTickItLeavesAndTheCarriageReturnsAndHoldsAgain) {
  const HoldRun r({"controller.hold.enabled=true", "hal.sim.pushes=[{t_s: 6, force_n: 150, duration_s: 0.1}]"});
  const double y_d = r.config.controller.schedule.back().position_m;
  // Holding when the push comes.
  const auto before = std::find_if(r.record.ticks.begin(), r.record.ticks.end(),
                                   [](const controller::TickRecord& t) { return t.t_s >= 6.0 - 1e-9; });
  ASSERT_NE(before, r.record.ticks.end());
  ASSERT_EQ(before->mode, Mode::kHold);
  // The first reading beyond the window: Eq. 4 drives by then. The stop detector saw the carriage
  // start (40 um) before it left the window (0.5 mm): the hold ended then, saying so, and held to
  // that tick.
  const auto out = std::find_if(before, r.record.ticks.end(), [&](const controller::TickRecord& t) {
    return std::abs(t.y_m - y_d) > r.window_m();
  });
  ASSERT_NE(out, r.record.ticks.end());
  EXPECT_EQ(out->mode, Mode::kArmed);
  const auto ends = r.events_of(LoopEvent::Kind::kHoldEnd, 6.0);
  ASSERT_FALSE(ends.empty());
  EXPECT_EQ(ends.front()->hold_end, controller::HoldEnd::kMoved) << controller::hold_end_name(ends.front()->hold_end);
  EXPECT_LE(ends.front()->t_s, out->t_s);
  for (auto t = before; t->t_s < ends.front()->t_s; ++t) ASSERT_EQ(t->mode, Mode::kHold) << t->t_s;
  // Eq. 4 brings it back; at rest within the window again, it holds again, to the end.
  const auto again = r.events_of(LoopEvent::Kind::kHoldStart, out->t_s);
  ASSERT_FALSE(again.empty());
  EXPECT_LT(std::abs(again.front()->y_m - y_d), r.window_m());
  EXPECT_EQ(r.record.ticks.back().mode, Mode::kHold);
  EXPECT_TRUE(r.breakaways(again.back()->t_s).empty());
  EXPECT_TRUE(r.run.runtime->faults().empty());
}

TEST(InPositionHold, ReachingTheWindowBringsTheDefaultRunsStopWithinATenthOfAMillimetreAndHoldsIt) {
  // The stop at 170.42 mm is 0.42 mm from the set point: outside a 0.1 mm window, within reach.
  const HoldRun r({"controller.hold.enabled=true", "controller.hold.window_m=0.0001", "controller.hold.reach_m=0.005",
                   "controller.hold.reach_rate_n_per_s=2000"});
  const double y_d = r.config.controller.schedule.back().position_m;
  const auto starts = r.events_of(LoopEvent::Kind::kHoldStart, 1.0);
  const auto reaching = std::count_if(starts.begin(), starts.end(), [](const LoopEvent* e) { return e->direction != 0; });
  EXPECT_GE(reaching, 1) << "it broke away towards the set point at least once";
  ASSERT_FALSE(starts.empty());
  const LoopEvent& held = *starts.back();
  EXPECT_EQ(held.direction, 0) << "the last: holding within the window";
  EXPECT_LE(std::abs(held.y_m - y_d), 1e-4);
  EXPECT_LE(std::abs(r.bench->plant().state().y_m - y_d), 1e-4);
  EXPECT_EQ(r.record.ticks.back().mode, Mode::kHold);
  EXPECT_TRUE(r.breakaways(held.t_s).empty());
  EXPECT_TRUE(r.run.runtime->faults().empty());
}

TEST(InPositionHold, WhileItHoldsTheForecastUnderItsCommandsSaysNoRestartEveryUpdatePeriod) {
  // The default run's hold from 1.445 s: a forecast under the hold's commands as it begins, then
  // every update period (0.1 s) to the end, each "no restart", the force settling on -2.5 N.
  const HoldRun r({"controller.hold.enabled=true"});
  EXPECT_TRUE(r.run.runtime->forecasts(controller::PredictionMethod::kHeld));
  const auto holds = r.events_of(LoopEvent::Kind::kHoldStart, 1.0);
  ASSERT_EQ(holds.size(), 1u);
  const double t_hold = holds.front()->t_s;
  ASSERT_FALSE(r.record.held.empty());
  EXPECT_NEAR(r.record.held.front().t_s, t_hold, 1e-9) << "the first as the hold begins";
  const double period = r.config.controller.predictor.update_period_s;
  EXPECT_EQ(r.record.held.size(), static_cast<std::size_t>(std::floor((12.0 - t_hold) / period + 1e-6)) + 1);
  for (const auto& f : r.record.held) {
    EXPECT_EQ(f.stop, holds.front()->stop_index);
    EXPECT_FALSE(f.prediction.will_restart) << f.t_s;
    EXPECT_NEAR(f.prediction.equilibrium_force_n, -2.5, 1e-6);
    // The way from the force measured then to -2.5 N: never nearer a bound than 10 N.
    EXPECT_GT(f.prediction.min_margin_n, 10.0) << f.t_s;
  }
  // The stop's account.
  const auto& stop = r.run.runtime->stops().back();
  EXPECT_EQ(stop.held_forecasts, r.record.held.size());
  EXPECT_EQ(stop.held_restart_forecasts, 0u);
  // Without the hold, no such forecast.
  const HoldRun without({});
  EXPECT_FALSE(without.run.runtime->forecasts(controller::PredictionMethod::kHeld));
  EXPECT_TRUE(without.record.held.empty());
}

TEST(InPositionHold, ReachingEachBreakawayIsForecastAsTheReachBeginsWithinATick) {
  const HoldRun r({"controller.hold.enabled=true", "controller.hold.window_m=0.0001", "controller.hold.reach_m=0.005"});
  int reaches = 0;
  for (const LoopEvent* start : r.events_of(LoopEvent::Kind::kHoldStart, 1.0)) {
    if (start->direction == 0) continue;
    ++reaches;
    // The forecast made as the reach began, and the start the stop detector dated.
    const auto f = std::find_if(r.record.held.begin(), r.record.held.end(),
                                [&](const controller::ForecastRecord& x) { return x.t_s == start->t_s; });
    ASSERT_NE(f, r.record.held.end());
    const auto moved = r.events_of(LoopEvent::Kind::kStart, start->t_s);
    ASSERT_FALSE(moved.empty());
    ASSERT_TRUE(f->prediction.will_restart);
    EXPECT_EQ(f->prediction.direction, start->direction);
    EXPECT_NEAR(f->prediction.t_restart_s, moved.front()->t_s, 1e-3) << "reach at " << start->t_s;
  }
  EXPECT_GE(reaches, 1);
}

TEST(InPositionHold, ThePapersScenarioReachesTheWindowAndOnceHeldWithinItNeverRestarts) {
  // config/paper.yaml: the paper's gains stop the step 1.7 mm from the set point (then restart at
  // 4.97 s); reaching from 5 mm brings it into the 0.5 mm window, where it is held to the end.
  const std::string paper = pneu::test::slurp(pneu::test::shipped_config("paper.yaml"));
  const HoldRun without({}, paper);
  EXPECT_FALSE(without.breakaways(2.0).empty()) << "without the hold, the paper's restart";
  const HoldRun r({"controller.hold.enabled=true", "controller.hold.reach_m=0.005"}, paper);
  const double y_d = r.config.controller.schedule.back().position_m;
  const auto starts = r.events_of(LoopEvent::Kind::kHoldStart, 1.0);
  const auto first_held = std::find_if(starts.begin(), starts.end(), [](const LoopEvent* e) { return e->direction == 0; });
  ASSERT_NE(first_held, starts.end()) << "it settled within the window";
  const double t_held = (*first_held)->t_s;
  std::printf("first held within the window at %.3f s, %.3f mm from the set point\n", t_held,
              ((*first_held)->y_m - y_d) * 1e3);
  EXPECT_LE(std::abs((*first_held)->y_m - y_d), r.window_m());
  EXPECT_TRUE(r.breakaways(t_held).empty()) << "no restart once held within the window";
  EXPECT_TRUE(r.events_of(LoopEvent::Kind::kHoldEnd, t_held).empty());
  EXPECT_EQ(r.record.ticks.back().mode, Mode::kHold);
  EXPECT_TRUE(r.run.runtime->faults().empty());
}

}  // namespace
