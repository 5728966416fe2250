// pneu-sweep: runs many set-point steps across the stroke in simulated time, in parallel, and
// judges every restart forecast against what the simulated bench did.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <mutex>
#include <random>
#include <span>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <vector>

#include "pneu/backends/factory.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/online.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/controller/verdict.hpp"
#include "pneu/model/chamber.hpp"

namespace {

using namespace pneu;
using controller::Verdict;

constexpr const char* kHelp = R"(pneu-sweep: the restart predictor against many simulated set-point steps

Usage:
  pneu-sweep [--config FILE] --out SWEEP.csv [--steps N] [--seed S] [--jobs J] [--duration S]
             [--step-time S] [--tail S] [--margin-m M] [--min-step-m D] [--friction-spread F] [--gain-spread G]
             [--bench-spread B] [--bench-thermal-s LO[:HI]] [--bench-spool-lag-s LO[:HI]]
             [--scenarios-out SCENARIOS.csv] [--set KEY=VALUE ...] [--supervised] [--strict]
             [--strict-forecasts] [--identify] [--online] [--quiet]

Scenario i starts at rest at a random position y0 and steps the set point at --step-time
(default 1 s) to y_d, the targets spread evenly over the stroke less --margin-m (default 0.02 m)
at each end, |y_d - y0| >= --min-step-m (default 0.005 m). --friction-spread F scales all friction
values of a scenario by a factor drawn in [1-F, 1+F], --gain-spread G the three gains likewise,
fixed or scheduled (every node of the table) (default 0: the config's values): model and bench
alike. --bench-spread B gives each scenario a simulated bench of its own, drawn around the configured
one (plant:, or hal.sim.plant over it), while plant: stays the controller's model: each friction value (F_S+, F_C+, F_S-, F_C-, sigma; a Coulomb level kept
within its stiction bound), each valve conductance (C_max, both leaks) and each dead volume
scaled by its own factor drawn in [1-B, 1+B], and a valve null offset drawn in [-B/2, B/2] V
(from a generator of its own: the scenarios stay those of the seed). Each scenario runs --duration seconds (default 12) in simulated
time, then --tail seconds more (default 1) in which no new stop is judged: a restart forecast just
before the end of the window is then seen or refuted by the signals rather than cut off (a
breakaway with a force a hair beyond stiction moves the carriage by less than the detector's
motion band for tens of milliseconds). --jobs threads (default: the cores) share the scenarios.

--online adds pneud's online identification to each scenario's run: the forecasts use what it has
identified so far, from the configured model (with --identify, from the identified one); the
stops before the scenario's 3rd restart (while it learns) are not judged, and counted. The
summary then splits the judged stops in two: those pneud forecast on a stiction bound it had not
identified yet (the configured one: no breakaway that way yet), and the others.

--identify first runs pneud's identification run (pneud --identify) on each scenario's bench, from
the configured model, and runs the scenario on the model it identified: plant: then holds what
was identified (u_0, the gain design and the forecasts use it); the bench stays the scenario's.
A scenario whose identification fails (a fault, too little shown) is counted as such, with the
reason, and not run. The summary gives the identified stiction's and null-flow pressure's errors
against each bench; the scenarios file, identified_* columns.

The sweep studies the control law and the forecast, not the bench's protection: unless
--supervised, the supervisor's motion and range checks are off (large steps slam the carriage
into an end stop and push a chamber past the pressure sensor's range, which pneud would rightly
latch as faults and so end the scenario), and so are its settling rules (oscillation, settle
time: controller.supervisor.oscillation_* and settle_time_s), so that every scenario runs its
whole duration and every stop counts in the forecast figures. Those rules are checked alongside
instead: a supervisor of the sweep's own, with only them on, is fed each scenario's ticks and
tells when it would have latched the oscillation or the not-settled fault (the run goes on). With --supervised
every check is on as in pneud, and a fault ends the scenario's control (outcome fault).

Each scenario gets an outcome, from the first time the carriage comes to rest after the step:
the stop detector's first stop after it, before any fault, at which the plant was at rest, or came
to rest without breaking away first (noisy sensors can make the detector confirm a stop while the
plant turns slowly, or creeps onto a stiction bound its Coulomb level nearly meets; the rest then
dates from the plant's stick). settled: at rest
inside the stroke; end-stop: at rest against an end stop (it may come off it later:
final_error_m tells); never-settled: no rest to the end of the run, tail included; fault: a fault
latched (--supervised). A carriage that the step does not move has settled at once. The summary
counts them (their sum is the number of scenarios), says where on the stroke those that did not
settle lie, and gives the settle time (the first rest, from the step) and the final error
(|y_d - y| at the end of the run) percentiles over the settled ones. --scenarios-out writes one
row per scenario: scenario,y0_m,y_d_m,friction_scale,gain_scale,outcome,settle_time_s,
final_error_m,fault_cause,fault_after_s,stops,restarts,at_rest_at_end,last_second_swing_m,
oscillation_rule_after_s (times from the step, empty where not applicable; stops and restarts
over the whole run; last_second_swing_m: the peak-to-peak position over the run's last second;
oscillation_rule_after_s: when the settling rules checked alongside would have latched the
oscillation or the not-settled fault, unless --supervised), then the simulated bench the scenario
ran, bench_* (the model's friction, conductances, dead volumes and null offset unless
--bench-spread; its heat transfer and thermal time constant at mid-stroke, empty without the
energy balance, and its spool lag; y0_m, y_d_m and bench_* exactly, to all their digits: the
scenario runs again in pneud with them), then in_window_after_s (the first rest within controller.hold.window_m of the
set point that the plant confirms, at once or by sticking before any breakaway), hold_after_s (the
in-position hold's first start within the window) and restarts_after_hold (the plant's breakaways
after it beyond the detector's motion band). The summary gives the time into the window over
those that came and over all (never counted as never), and with controller.hold on, the forecasts
under the hold's commands: how many made while held said restart, and each reach's breakaway
forecast against the start seen.

Stops are those pneud's stop detector sees; what happened after each is the simulated truth: the
plant's first breakaway after the forecast was made is the restart, timed exactly, even when it
moves the carriage less than the detector's motion band (a set-point change before it ends the
stop unjudged); the summary says how far the detector's dates of the starts it saw fall from the
breakaways. With noisy sensors (e.g. --config config/hil.yaml --set hal.backend=sim) the
detector may confirm a stop while the plant still slides within its rest band: counted, not
judged (outcome plant_not_at_rest). SWEEP.csv has one row per stop: the scenario, the stop, what happened, and each
method's forecast with its verdict and error. The summary gives the confusion matrix of restart / no restart and the
error percentiles per method. Acceptance: restarts after >= 0.5 s of sticking within 1 % of the
sticking time (nonlinear) and 5 % (linearized), shorter ones within 10 ms. The forecast figures
cover every stop of every scenario, whatever its outcome (a scenario that never settles has no
stop to judge). --strict exits 1 when any forecast misses its criteria or any scenario does not
settle, saying which; --strict-forecasts only on the forecasts. For those restarts the summary
and the *_halfway_error_percent columns also give the error of the live predictor: the forecast
made again (every controller.predictor.update_period_s) from the last pressures before half the
sticking time, in % of the whole sticking time; it is not judged. With "relaxation" among
controller.predictor.methods, the relaxation method (each chamber's relaxation fitted to the
phase's own pressures, no valve model) is reported the same way: it makes no forecast at the stop,
only half-way ones (rx_halfway_error_percent). With --online, forecast_on_unidentified_bound is 1
for a stop forecast on a stiction bound online learning had not identified yet (the configured
one: no breakaway that way yet), as pneud's summary counts them; and side_broken_away_slowly is 1
for a stop whose forecast turns on a side (the side of the restart it forecast, or for "no
restart" the side the force relaxes towards) that the bench had already broken away to after
0.5 s or more stuck: a slow breakaway, the pressures' drift crossing that bound, which dates it
far better than a set-point step's (the bench's own restarts, in the scenario before the stop).
The summary gives the judged stops of that kind apart too.
)";

// A simulated bench that is not its model (--bench-spread): factors on the model's values and a
// valve null offset, drawn per scenario.
struct BenchDraw {
  double static_positive = 1.0, coulomb_positive = 1.0, static_negative = 1.0, coulomb_negative = 1.0,
         viscous = 1.0, max_conductance = 1.0, leak_in = 1.0, leak_out = 1.0, dead_volume_p = 1.0,
         dead_volume_n = 1.0, null_offset_v = 0.0;
  // --bench-thermal-s: the energy balance with this thermal time constant at mid-stroke [s];
  // --bench-spool-lag-s: this spool lag [s]. NaN: the configured bench's.
  double thermal_time_constant_s = NAN, spool_time_constant_s = NAN;

  // The bench: `model` with these applied. Each Coulomb level stays within its stiction bound.
  [[nodiscard]] model::PlantParams applied_to(model::PlantParams p) const {
    auto& f = p.friction;
    f.static_positive_n *= static_positive;
    f.static_negative_n *= static_negative;
    f.coulomb_positive_n = std::min(f.coulomb_positive_n * coulomb_positive, f.static_positive_n);
    f.coulomb_negative_n = std::max(f.coulomb_negative_n * coulomb_negative, f.static_negative_n);
    f.viscous_n_s_per_m *= viscous;
    p.valve.max_conductance_m3_per_s_pa *= max_conductance;
    p.valve.leak_conductance_in_m3_per_s_pa *= leak_in;
    p.valve.leak_conductance_out_m3_per_s_pa *= leak_out;
    p.valve.null_offset_v += null_offset_v;
    p.geometry.dead_volume_p_m3 *= dead_volume_p;
    p.geometry.dead_volume_n_m3 *= dead_volume_n;
    if (!std::isnan(thermal_time_constant_s)) {
      p.has_thermal = true;
      p.thermal.heat_transfer_w_per_m2_k = model::heat_transfer_for_time_constant(p, thermal_time_constant_s);
    }
    if (!std::isnan(spool_time_constant_s)) p.valve.spool_time_constant_s = spool_time_constant_s;
    return p;
  }
};

// "LO" or "LO:HI" of --bench-thermal-s and --bench-spool-lag-s: the range drawn from [s].
struct DrawRange {
  double lo = NAN, hi = NAN;
  [[nodiscard]] bool given() const { return !std::isnan(lo); }
};
DrawRange draw_range(const cli::Args& args, const char* option, double min_s) {
  const auto text = args.value(option);
  if (!text) return {};
  const auto colon = text->find(':');
  const auto number = [&](const std::string& t) {
    std::size_t used = 0;
    double v = NAN;
    try {
      v = std::stod(t, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != t.size() || !std::isfinite(v))
      throw cli::UsageError(std::string("--") + option + ": '" + *text + "' is not LO or LO:HI in seconds");
    return v;
  };
  DrawRange r;
  r.lo = number(text->substr(0, colon));
  r.hi = colon == std::string::npos ? r.lo : number(text->substr(colon + 1));
  if (!(r.lo >= min_s && r.hi >= r.lo))
    throw cli::UsageError(std::string("--") + option + " must be LO:HI with " + (min_s > 0 ? "0 < " : "0 <= ") +
                          "LO <= HI (got '" + *text + "')");
  return r;
}

struct Scenario {
  int index = 0;
  double y0_m = 0.0, y_d_m = 0.0, friction_scale = 1.0, gain_scale = 1.0;
  BenchDraw bench;
};

struct Truth {
  bool unseen = false;       // a true restart the stop detector did not see
  // --online: forecast on a stiction bound the running estimate had not identified (the side it
  // forecast a restart towards, or the force relaxes towards): the configured one
  bool on_configured_bound = false;
  bool not_at_rest = false;  // the plant was sliding when the stop was confirmed: not judged
  double start_dating_s = NAN;  // the detector's start time minus the plant's breakaway, when it saw one
};

// Whether the plant was at rest (stuck, or against an end stop) at `t_s`, by its motion events.
bool plant_at_rest(std::span<const plant::PlantEvent> events, double t_s) {
  bool at_rest = true;  // runs start at rest
  for (const auto& e : events) {
    if (e.t_s > t_s) break;
    if (e.kind == plant::PlantEvent::Kind::kReversal) continue;  // sliding before and after
    at_rest = e.kind != plant::PlantEvent::Kind::kBreakaway;
  }
  return at_rest;
}

// The plant's first change between sliding and rest after t_s (a reversal slides on), or none.
const plant::PlantEvent* next_motion_change(std::span<const plant::PlantEvent> events, double t_s) {
  for (const auto& e : events)
    if (e.t_s > t_s && e.kind != plant::PlantEvent::Kind::kReversal) return &e;
  return nullptr;
}

// At rest at t_s, or coming to rest after it (a stick, or an end stop) without breaking away
// first: a noisy detector can confirm a stop a few ms before the plant's last slide within its rest
// band ends.
bool plant_rests_from(std::span<const plant::PlantEvent> events, double t_s) {
  if (plant_at_rest(events, t_s)) return true;
  const plant::PlantEvent* next = next_motion_change(events, t_s);
  return next != nullptr && next->kind != plant::PlantEvent::Kind::kBreakaway;
}

// How a scenario ended up (see the help).
enum class Outcome : std::uint8_t { kSettled, kNeverSettled, kEndStop, kFault };
constexpr Outcome kOutcomes[] = {Outcome::kSettled, Outcome::kNeverSettled, Outcome::kEndStop, Outcome::kFault};

const char* outcome_name(Outcome o) {
  switch (o) {
    case Outcome::kSettled: return "settled";
    case Outcome::kNeverSettled: return "never-settled";
    case Outcome::kEndStop: return "end-stop";
    case Outcome::kFault: return "fault";
  }
  return "?";
}

// A rest this close to an end of the stroke is against its end stop [m] (the targets keep
// --margin-m from the ends; a noisy, quantised sensor reads an end stop within tens of um).
constexpr double kEndStopTolerance_m = 1.0e-3;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// What became of the scenario after its step (times from the step).
struct Settling {
  Outcome outcome = Outcome::kNeverSettled;
  double settle_time_s = kNaN;     // the first rest after the step, before any fault
  double rest_y_m = kNaN;          // ... its position
  double final_error_m = kNaN;     // |y_d - y| at the end of the run
  controller::FaultCause fault = controller::FaultCause::kNone;  // the first fault latched
  double fault_after_s = kNaN;
  std::uint64_t stops = 0, restarts = 0;  // over the whole run, tail included
  bool at_rest_at_end = false;
  double last_second_swing_m = kNaN;      // peak-to-peak position over the run's last second
  double oscillation_rule_after_s = kNaN; // when the settling rules checked alongside would latch
  // controller.hold.window_m: the first rest after the step within the window (the plant's truth
  // confirming it, at once or by sticking before any breakaway), from the step; the first hold's
  // start after the step, from the step; the plant's breakaways after it (the set point does not
  // change after the step, nothing pushes)
  double in_window_after_s = kNaN;
  double hold_after_s = kNaN;
  std::uint64_t restarts_after_hold = 0;
  // The forecasts under the hold's commands (method held, after the step): made while held within
  // the window, and how many said restart; reaching: for each reach that broke away, the forecast
  // made as it began against the start seen [ms], and the reaches it forecast no breakaway for.
  std::uint64_t held_forecasts = 0, held_restart_forecasts = 0;
  std::vector<double> reach_forecast_error_ms;
  std::uint64_t reaches_forecast_none = 0;
};

// The supervisor's settling rules alone (oscillation, settle time): every other check off.
controller::LoopParams settling_rules_only(controller::LoopParams params, const config::SupervisorConfig& rules) {
  auto& v = params.controller.supervisor;
  v = config::SupervisorConfig{};
  v.oscillation_amplitude_m = rules.oscillation_amplitude_m;
  v.oscillation_sign_changes = rules.oscillation_sign_changes;
  v.oscillation_window_s = rules.oscillation_window_s;
  v.settle_time_s = rules.settle_time_s;
  v.overtravel_m = 1e300;
  v.following_error_s = 0.0;
  v.max_tick_interval_s = 0.0;
  v.overruns_in_a_row = 0;
  params.setpoint_stream_timeout_s = 0.0;
  return params;
}

// Watches one scenario's run through the runtime's records: when and where the carriage first
// came to rest after the step, the faults, where it is at the end; and feeds every tick to a
// supervisor of its own with only the settling rules on, which tells when the oscillation or the
// not-settled fault would have latched (the run itself goes on).
class ScenarioWatch final : public controller::RunListener {
 public:
  /// `rules`: the supervisor checked alongside (none: the run has its own).
  ScenarioWatch(std::optional<controller::LoopParams> rules, double step_time_s, double end_s, double half_stroke_m,
                double window_m, double motion_band_m)
      : step_time_s_(step_time_s), end_s_(end_s), half_stroke_m_(half_stroke_m), window_m_(window_m),
        motion_band_m_(motion_band_m) {
    if (!rules) return;
    shadow_.emplace(*rules);
    shadow_->reset(0.0);
  }

  void on_tick(const controller::TickRecord& r, const controller::ExpectedAtTick&) override {
    if (shadow_) check_alongside(r);
    stuck_ = r.stuck;
    if (r.t_s >= step_time_s_ && !r.stuck) moved_ = true;
    last_ = r;
    if (r.t_s >= end_s_ - 1.0) {
      lowest_m_ = std::min(lowest_m_, r.y_m);
      highest_m_ = std::max(highest_m_, r.y_m);
    }
  }

  // The settling rules on the tick as the loop saw it.
  void check_alongside(const controller::TickRecord& r) {
    hal::SensorFrame f;
    f.t_s = r.t_s;
    f.y_m = r.y_m;
    f.p_p_pa = r.p_p_pa;
    f.p_n_pa = r.p_n_pa;
    controller::SupervisedTick st;
    st.t_s = r.t_s;
    st.frame = &f;
    st.armed = controller::drives(r.mode);
    st.y_d_m = r.y_d_m;
    st.last_setpoint_t_s = r.t_s;
    st.at_rest = stuck_;  // as the loop hands it: the detector's state before this tick's sample
    const controller::FaultCause c = shadow_->check_motion(st);
    if ((c == controller::FaultCause::kOscillation || c == controller::FaultCause::kNotSettled) &&
        std::isnan(s_.oscillation_rule_after_s) &&
        r.t_s >= step_time_s_)
      s_.oscillation_rule_after_s = r.t_s - step_time_s_;
  }

  void on_event(const controller::LoopEvent& e) override {
    using Kind = controller::LoopEvent::Kind;
    switch (e.kind) {
      case Kind::kStop:
        ++s_.stops;
        if (e.t_s >= step_time_s_ && s_.fault == controller::FaultCause::kNone && rest_candidates_.size() < kCandidates)
          rest_candidates_.push_back({e.t_s, e.snapshot.t_s, e.y_m});
        break;
      case Kind::kStart:
        if (e.restart) ++s_.restarts;
        if (reach_forecast_) {  // the breakaway a reach forecast
          if (reach_forecast_->will_restart)
            s_.reach_forecast_error_ms.push_back((reach_forecast_->t_restart_s - e.t_s) * 1e3);
          else
            ++s_.reaches_forecast_none;
          reach_forecast_.reset();
        }
        break;
      case Kind::kHoldStart:  // within the window (not reaching for it)
        if (e.direction == 0 && e.t_s >= step_time_s_ && std::isnan(s_.hold_after_s)) s_.hold_after_s = e.t_s - step_time_s_;
        hold_reach_direction_ = e.direction;
        reach_forecast_.reset();
        break;
      case Kind::kHoldEnd:  // (a breakaway's start comes first, and has taken the reach's forecast)
        hold_reach_direction_ = 0;
        reach_forecast_.reset();
        break;
      case Kind::kFault:
        if (s_.fault == controller::FaultCause::kNone) {
          s_.fault = e.fault_cause;
          s_.fault_after_s = e.t_s - step_time_s_;
        }
        break;
      default: break;
    }
  }

  void on_forecast(const controller::ForecastRecord& f) override {
    if (f.prediction.method != controller::PredictionMethod::kHeld || f.t_s < step_time_s_) return;
    if (hold_reach_direction_ != 0) {
      if (!reach_forecast_) reach_forecast_ = f.prediction;  // the one made as the reach began
      return;
    }
    ++s_.held_forecasts;
    if (f.prediction.will_restart) ++s_.held_restart_forecasts;
  }

  // The account, once the run has ended, with the plant's motion events: the first rest is the
  // first stop after the step (before any fault) that the plant confirms, at once or by sticking
  // before it breaks away again (a noisy detector can confirm a stop while the plant slides within
  // its rest band, slowly through a turn or creeping onto a stiction bound that its Coulomb level
  // nearly meets: a carriage at rest 0.18 mm from its set point by the end was counted as never
  // settled); the rest then dates from the plant's stick.
  [[nodiscard]] Settling settling(std::span<const plant::PlantEvent> plant_events, double plant_y_end_m) const {
    Settling s = s_;
    for (const RestCandidate& c : rest_candidates_)
      if (plant_rests_from(plant_events, c.confirmed_t_s)) {
        double rest_t = c.t_s;
        if (!plant_at_rest(plant_events, c.confirmed_t_s))
          rest_t = std::max(rest_t, next_motion_change(plant_events, c.confirmed_t_s)->t_s);
        s.settle_time_s = rest_t - step_time_s_;
        s.rest_y_m = c.y_m;
        break;
      }
    for (const RestCandidate& c : rest_candidates_)
      if (std::abs(c.y_m - last_.y_d_m) <= window_m_ && plant_rests_from(plant_events, c.confirmed_t_s)) {
        s.in_window_after_s = c.t_s - step_time_s_;
        break;
      }
    // A restart after the hold began: a breakaway of the plant that takes the carriage beyond the
    // stop detector's motion band before it sticks again (or by the end of the run).
    if (!std::isnan(s.hold_after_s))
      for (std::size_t i = 0; i < plant_events.size(); ++i) {
        const plant::PlantEvent& e = plant_events[i];
        if (e.kind != plant::PlantEvent::Kind::kBreakaway || e.t_s <= step_time_s_ + s.hold_after_s) continue;
        double y_next = plant_y_end_m;
        for (std::size_t j = i + 1; j < plant_events.size(); ++j)
          if (plant_events[j].kind != plant::PlantEvent::Kind::kBreakaway) {
            y_next = plant_events[j].y_m;
            break;
          }
        if (std::abs(y_next - e.y_m) > motion_band_m_) ++s.restarts_after_hold;
      }
    s.final_error_m = std::abs(last_.y_d_m - last_.y_m);
    s.at_rest_at_end = last_.stuck;
    if (lowest_m_ <= highest_m_) s.last_second_swing_m = highest_m_ - lowest_m_;
    if (s.fault != controller::FaultCause::kNone) {
      s.outcome = Outcome::kFault;
    } else if (!std::isnan(s.settle_time_s)) {
      s.outcome = std::abs(s.rest_y_m) >= half_stroke_m_ - kEndStopTolerance_m ? Outcome::kEndStop : Outcome::kSettled;
    } else if (!moved_) {  // the step did not move it: at rest all along
      s.outcome = Outcome::kSettled;
      s.settle_time_s = 0.0;
    } else {
      s.outcome = Outcome::kNeverSettled;
    }
    return s;
  }

 private:
  struct RestCandidate {
    double t_s, confirmed_t_s, y_m;  // the stop (backdated), its confirmation, its position
  };
  static constexpr std::size_t kCandidates = 4096;
  std::vector<RestCandidate> rest_candidates_;  // the stops after the step, before any fault
  std::optional<controller::Supervisor> shadow_;
  double step_time_s_, end_s_, half_stroke_m_, window_m_, motion_band_m_;
  Settling s_;
  bool stuck_ = true;  // runs start at rest
  bool moved_ = false;  // the detector saw the carriage move after the step
  controller::TickRecord last_;
  double lowest_m_ = 1e300, highest_m_ = -1e300;
  int hold_reach_direction_ = 0;                          // of the hold in force
  std::optional<controller::Prediction> reach_forecast_;  // made as the reach in force began
};

// --identify: how the identification went against the scenario's bench.
struct IdentifiedCheck {
  double residual_pa = NAN, explained_pa = NAN;  // the valve fit's residual, and what the noise explains
  bool fits = true;
  // The parameters it published (identified) that the bench has too, and those within 3 of their
  // stated sigmas of the bench's value; the others named with their error in sigmas.
  int published = 0, within_3_sigma = 0;
  std::string outside;
  // Per key: published, within 3 sigma.
  std::vector<std::tuple<std::string, int, int>> by_key;
};

// The bench's value of an identified parameter's key; NaN when the bench has no such parameter
// (the heat transfer of a bench without the energy balance).
double bench_value(const model::PlantParams& b, std::string_view key) {
  const std::pair<const char*, double> values[] = {
      {"plant.friction.static_positive_n", b.friction.static_positive_n},
      {"plant.friction.static_negative_n", b.friction.static_negative_n},
      {"plant.friction.coulomb_positive_n", b.friction.coulomb_positive_n},
      {"plant.friction.coulomb_negative_n", b.friction.coulomb_negative_n},
      {"plant.friction.viscous_n_s_per_m", b.friction.viscous_n_s_per_m},
      {"plant.valve.max_conductance_m3_per_s_pa", b.valve.max_conductance_m3_per_s_pa},
      {"plant.valve.leak_conductance_in_m3_per_s_pa", b.valve.leak_conductance_in_m3_per_s_pa},
      {"plant.valve.leak_conductance_out_m3_per_s_pa", b.valve.leak_conductance_out_m3_per_s_pa},
      {"plant.valve.null_offset_v", b.valve.null_offset_v},
      {"plant.geometry.dead_volume_p_m3", b.geometry.dead_volume_p_m3},
      {"plant.geometry.dead_volume_n_m3", b.geometry.dead_volume_n_m3},
      {"plant.thermal.heat_transfer_w_per_m2_k", b.has_thermal ? b.thermal.heat_transfer_w_per_m2_k : NAN},
      {"plant.valve.spool_time_constant_s", b.valve.spool_time_constant_s}};
  for (const auto& [k, v] : values)
    if (key == k) return v;
  return NAN;
}

IdentifiedCheck check_identified(const identify::Identification& id, const model::PlantParams& bench) {
  IdentifiedCheck c;
  c.residual_pa = id.evidence.pressure_rms_residual_pa;
  c.explained_pa = id.evidence.pressure_explained_pa;
  c.fits = id.evidence.model_fits;
  for (const identify::Estimate& e : id.estimates) {
    const double truth = bench_value(bench, e.key);
    if (!e.identified || std::isnan(truth)) continue;
    ++c.published;
    const double sigmas = std::abs(e.value - truth) / e.std;
    c.by_key.emplace_back(e.key, 1, sigmas <= 3.0 ? 1 : 0);
    if (sigmas <= 3.0) {
      ++c.within_3_sigma;
      continue;
    }
    char text[160];
    std::snprintf(text, sizeof text, "%s%s %.1f sigma", c.outside.empty() ? "" : "; ",
                  e.key.substr(e.key.rfind('.') + 1).c_str(), sigmas);
    c.outside += text;
  }
  return c;
}

struct ScenarioResult {
  Scenario scenario;
  model::PlantParams bench;  // the simulated bench it ran (the model's plant: unless --bench-spread)
  std::optional<model::PlantParams> identified;  // --identify: the model the scenario ran on
  std::string identification_failed;             // --identify: why it failed, or why its model could not
                                                 // run (the scenario did not run)
  std::vector<controller::StopOutcome> stops;
  std::vector<Truth> truth;  // per stop
  double t_end_s = 0.0;
  Settling settling;
  IdentifiedCheck check;  // --identify
};

// What happened, by the simulated truth: the plant's first breakaway after the forecast was made
// (the stop's confirmation) is the restart. The stop detector sees a start only once the carriage
// has moved beyond its motion band; a breakaway under a force a hair beyond stiction can move it
// less than that before the pneumatic stiffness stops it again, a restart all the same. The
// detector's start comes after the breakaway, once the carriage has moved; its date is
// backdated from the samples, exactly to within a period with ideal sensors and less surely with
// noisy ones (earlier or later by milliseconds): it plays no part here, and the gap is reported.
// With noisy sensors the detector can also confirm a stop while the plant still slides slowly
// within its rest band: a forecast made then assumed a rest that was not there, and is not
// judged. Stops ended by a set-point change keep that outcome.
Truth apply_plant_truth(controller::StopOutcome& s, std::span<const plant::PlantEvent> events, double run_end_s) {
  using Kind = plant::PlantEvent::Kind;
  Truth truth;
  if (s.ended && !s.restarted) return truth;
  if (!plant_at_rest(events, s.snapshot.t_s)) {
    truth.not_at_rest = true;
    return truth;
  }
  for (const auto& e : events) {
    if (e.kind != Kind::kBreakaway || e.t_s <= s.snapshot.t_s) continue;
    if (e.t_s > run_end_s) break;
    truth.unseen = !s.ended;
    if (s.ended) truth.start_dating_s = s.t_end_s - e.t_s;
    s.ended = s.restarted = true;
    s.t_end_s = e.t_s;
    s.direction = e.direction;
    return truth;
  }
  return truth;
}

constexpr double kLongSticking_s = 0.5;

// A subset of the judged stops: how many, the wrong verdicts among them, and the errors of their
// restarts after kLongSticking_s or more [% of the sticking time].
struct Split {
  std::uint64_t stops = 0, wrong = 0;
  std::vector<double> long_error_pct;
  void add(const controller::StopOutcome& s, const Verdict& v) {
    if (v.kind == Verdict::Kind::kNotJudged) return;
    ++stops;
    if (v.kind == Verdict::Kind::kFalseNegative || v.kind == Verdict::Kind::kFalsePositive) ++wrong;
    if (v.kind == Verdict::Kind::kTruePositive && s.sticking_s() >= kLongSticking_s)
      long_error_pct.push_back(v.error_percent);
  }
};

struct MethodStats {
  std::uint64_t tp = 0, tn = 0, fp = 0, fn = 0, not_judged = 0, wrong_direction = 0, misses = 0;
  std::vector<double> long_error_pct;  // sticking >= 0.5 s
  std::vector<double> short_error_ms;  // shorter
  std::vector<double> halfway_error_pct;  // sticking >= 0.5 s: the forecast made again half-way
  // ... and of those restarts: the half-way forecast was none, not judged (its restart after the
  // run's end), missing; and among the timed ones above, in the wrong direction
  std::uint64_t halfway_none = 0, halfway_not_judged = 0, halfway_missing = 0, halfway_wrong_direction = 0;
  // --online: the judged stops forecast on a stiction bound online learning had not identified
  // (no breakaway that way yet): the configured one
  Split unlearned_side;
  // --online: the judged stops forecast on a side the bench had already broken away to after
  // kLongSticking_s or more stuck (a slow breakaway)
  Split slow_side;
};

// The CSV's and the summary's order: lin, nl, rx (the relaxation method: half-way only).
constexpr controller::PredictionMethod kMethods[3] = {controller::PredictionMethod::kLinearized,
                                                      controller::PredictionMethod::kNonlinear,
                                                      controller::PredictionMethod::kRelaxation};

// Linear interpolation between the order statistics; towards an infinity ("never"): infinity.
double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  if (i + 1 < v.size() && f > 0.0) return std::isinf(v[i + 1]) ? v[i + 1] : v[i] * (1 - f) + v[i + 1] * f;
  return v[i];
}

// How many of the errors [%] are within 2, 5 and 10 %.
std::array<std::size_t, 3> within_2_5_10(const std::vector<double>& errors_pct) {
  std::array<std::size_t, 3> within{};
  for (const double e : errors_pct)
    for (std::size_t b = 0; b < within.size(); ++b) within[b] += e <= (b == 0 ? 2.0 : b == 1 ? 5.0 : 10.0) ? 1 : 0;
  return within;
}

const char* verdict_name(Verdict::Kind k) {
  switch (k) {
    case Verdict::Kind::kTruePositive: return "true_restart";
    case Verdict::Kind::kTrueNegative: return "true_no_restart";
    case Verdict::Kind::kFalsePositive: return "false_restart";
    case Verdict::Kind::kFalseNegative: return "missed_restart";
    case Verdict::Kind::kNotJudged: return "not_judged";
  }
  return "?";
}

// Tolerance of the acceptance criteria for one forecast.
bool within_criteria(const controller::StopOutcome& s, const Verdict& v, bool nonlinear) {
  if (v.kind == Verdict::Kind::kFalseNegative || v.kind == Verdict::Kind::kFalsePositive) return false;
  if (v.kind != Verdict::Kind::kTruePositive) return true;
  if (!v.direction_ok) return false;
  if (s.sticking_s() >= kLongSticking_s) return v.error_percent <= (nonlinear ? 1.0 : 5.0);
  return std::abs(v.error_s) <= 0.010;
}

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1,
                       {"config", "out", "steps", "seed", "jobs", "duration", "step-time", "margin-m",
                        "min-step-m", "friction-spread", "gain-spread", "bench-spread", "tail", "scenarios-out",
                        "bench-thermal-s", "bench-spool-lag-s"},
                       {"strict", "strict-forecasts", "quiet", "help", "supervised", "identify", "online"}, {"set"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  config::Config base = config::load_file_or_default(config_path, args.all("set"));
  const config::SupervisorConfig settling_rules = base.controller.supervisor;  // checked alongside
  const bool supervised = args.flag("supervised");
  const bool identify_first = args.flag("identify");
  const bool online = args.flag("online") || base.controller.predictor.learn_online;
  // --online: a stop is judged once the scenario's bench has restarted this many times.
  constexpr int kOnlineLearningRestarts = 3;
  if (!supervised) {
    auto& v = base.controller.supervisor;
    v.oscillation_sign_changes = 0;
    v.settle_time_s = 0.0;
    v.position_min_m = v.pressure_min_pa = -1e300;
    v.position_max_m = v.pressure_max_pa = 1e300;
    v.overtravel_m = 1e300;
    v.following_error_s = 0.0;
    v.max_speed_m_per_s = 0.0;
  }
  const std::string out_path = args.required("out");
  const double steps_d = args.number("steps", 200);
  const double seed_d = args.number("seed", 1);
  const double jobs_d = args.number("jobs", std::max(1u, std::thread::hardware_concurrency()));
  const double duration = args.number("duration", 12.0);
  const double step_time = args.number("step-time", 1.0);
  const double margin = args.number("margin-m", 0.02);
  const double min_step = args.number("min-step-m", 0.005);
  const double friction_spread = args.number("friction-spread", 0.0);
  const double gain_spread = args.number("gain-spread", 0.0);
  const double bench_spread = args.number("bench-spread", 0.0);
  const double tail = args.number("tail", 1.0);
  const double half = base.plant.geometry.half_stroke_m();
  if (!(steps_d >= 1 && steps_d == std::floor(steps_d))) throw cli::UsageError("--steps must be a whole number >= 1");
  if (!(jobs_d >= 1 && jobs_d == std::floor(jobs_d))) throw cli::UsageError("--jobs must be a whole number >= 1");
  if (!(seed_d >= 0 && seed_d == std::floor(seed_d))) throw cli::UsageError("--seed must be a whole number >= 0");
  if (!(duration > step_time && step_time >= 0)) throw cli::UsageError("--duration must exceed --step-time >= 0");
  if (!(margin >= 0 && 2 * margin + min_step < 2 * half)) throw cli::UsageError("--margin-m leaves no room in the stroke");
  if (!(min_step >= 0)) throw cli::UsageError("--min-step-m must be >= 0");
  // Every target needs a start at least min_step away inside [lo, hi]: the mid-range one too.
  if (!(min_step < half - margin)) throw cli::UsageError("--min-step-m must be below half the usable stroke");
  if (!(friction_spread >= 0 && friction_spread < 1)) throw cli::UsageError("--friction-spread must be in [0, 1)");
  if (!(gain_spread >= 0 && gain_spread < 1)) throw cli::UsageError("--gain-spread must be in [0, 1)");
  if (!(bench_spread >= 0 && bench_spread < 1)) throw cli::UsageError("--bench-spread must be in [0, 1)");
  if (!(tail >= 0)) throw cli::UsageError("--tail must be >= 0");
  const DrawRange bench_thermal = draw_range(args, "bench-thermal-s", 1e-6);
  const DrawRange bench_spool_lag = draw_range(args, "bench-spool-lag-s", 0.0);
  const auto n = static_cast<int>(steps_d);
  const auto jobs = static_cast<int>(std::min<double>(jobs_d, n));

  // The scenarios, drawn up front so they do not depend on the thread count.
  std::vector<Scenario> scenarios(static_cast<std::size_t>(n));
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed_d));
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double lo = -half + margin, hi = half - margin;
  for (int i = 0; i < n; ++i) {
    Scenario& s = scenarios[static_cast<std::size_t>(i)];
    s.index = i;
    s.y_d_m = lo + (hi - lo) * (i + 0.5) / n;
    do {
      s.y0_m = lo + (hi - lo) * 0.5 * (1.0 + unit(rng));
    } while (std::abs(s.y0_m - s.y_d_m) < min_step);
    s.friction_scale = 1.0 + friction_spread * unit(rng);
    s.gain_scale = 1.0 + gain_spread * unit(rng);
  }
  // The benches from a generator of their own, so that the scenarios above stay those of the seed.
  if (bench_spread > 0.0) {
    std::mt19937_64 bench_rng(static_cast<std::uint64_t>(seed_d) ^ 0x9e3779b97f4a7c15ULL);
    const auto factor = [&] { return 1.0 + bench_spread * unit(bench_rng); };
    for (Scenario& s : scenarios) {
      BenchDraw& b = s.bench;
      for (double* x : {&b.static_positive, &b.coulomb_positive, &b.static_negative, &b.coulomb_negative, &b.viscous,
                        &b.max_conductance, &b.leak_in, &b.leak_out, &b.dead_volume_p, &b.dead_volume_n})
        *x = factor();
      b.null_offset_v = 0.5 * bench_spread * unit(bench_rng);
    }
  }
  // The benches' physics, each from a generator of its own: the draws above stay those of the seed.
  for (const auto& [range, member, salt] : {std::tuple{bench_thermal, &BenchDraw::thermal_time_constant_s, 0x243f6a8885a308d3ULL},
                                            std::tuple{bench_spool_lag, &BenchDraw::spool_time_constant_s, 0x13198a2e03707344ULL}}) {
    if (!range.given()) continue;
    std::mt19937_64 physics_rng(static_cast<std::uint64_t>(seed_d) ^ salt);
    std::uniform_real_distribution<double> in_range(0.0, 1.0);
    for (Scenario& s : scenarios) s.bench.*member = range.lo + (range.hi - range.lo) * in_range(physics_rng);
  }

  // Created before the run: an unwritable path, or both outputs on one file, fail fast.
  if (const auto path = args.value("scenarios-out")) cli::refuse_same_file({{"--out", out_path}, {"--scenarios-out", *path}});
  cli::OutputFile out(out_path, "--out");
  std::optional<cli::OutputFile> scenarios_out;
  if (const auto path = args.value("scenarios-out")) scenarios_out.emplace(*path, "--scenarios-out");

  std::vector<ScenarioResult> results(scenarios.size());
  std::atomic<int> next{0}, done{0};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  const auto wall0 = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point finished = wall0;  // written once, read after the joins
  const auto worker = [&] {
    for (int i; (i = next.fetch_add(1)) < n;) {
      try {
        const Scenario& s = scenarios[static_cast<std::size_t>(i)];
        config::Config cfg = base;
        cfg.simulation.initial_position_m = s.y0_m;
        cfg.controller.initial_setpoint_m = s.y0_m;
        cfg.controller.schedule = {{step_time, s.y_d_m}};
        cfg.controller.duration_s = duration + tail;
        cfg.controller.clock = config::ClockKind::kSimulated;
        // The friction spread scales the model's friction and the bench's alike.
        for (model::FrictionParams* f : {&cfg.plant.friction, &cfg.hal.sim.plant.friction}) {
          f->static_positive_n *= s.friction_scale;
          f->coulomb_positive_n *= s.friction_scale;
          f->static_negative_n *= s.friction_scale;
          f->coulomb_negative_n *= s.friction_scale;
          f->viscous_n_s_per_m *= s.friction_scale;
        }
        // A scenario that cannot run is recorded as it is, and counted done.
        const auto give_up = [&](ScenarioResult failed) {
          results[static_cast<std::size_t>(i)] = std::move(failed);
          if (done.fetch_add(1) + 1 == n) finished = std::chrono::steady_clock::now();
        };
        const std::filesystem::path config_dir =
            config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path();
        const model::PlantParams bench_params = s.bench.applied_to(config::simulated_bench(cfg));
        std::optional<model::PlantParams> identified;
        IdentifiedCheck check;
        if (identify_first) {
          // pneud --identify on the scenario's bench, from the configured model; the scenario then
          // runs on what it identified.
          config::Config id_cfg = cfg;
          const auto prior_valve = controller::make_valve_characteristic(id_cfg, config_dir);
          controller::resolve_offset(id_cfg, *prior_valve);
          const controller::ControlLaw prior_law = identify::identification_law(id_cfg, *prior_valve);
          try {
            const identify::Identification id = identify::identify_by_run(
                id_cfg, *prior_valve, prior_law, backends::make_sim_backend(id_cfg, prior_law, bench_params), s.y0_m);
            identified = id.plant;
            check = check_identified(id, bench_params);
            // As pneud --identify writes it: the forecasts on a model that did not fit say so.
            if (id.evidence.fitted_phases > 0) {
              cfg.controller.predictor.has_model_fit = true;
              cfg.controller.predictor.model_fit = {id.evidence.pressure_rms_residual_pa,
                                                    id.evidence.pressure_explained_pa};
            }
          } catch (const std::exception& e) {
            give_up(ScenarioResult{s, bench_params, std::nullopt, e.what(), {}, {}, 0.0, {}, {}});
            continue;
          }
          cfg.plant = *identified;
        }
        const auto valve = controller::make_valve_characteristic(cfg, config_dir);
        controller::resolve_offset(cfg, *valve);
        // The gains, fixed or scheduled, mistuned by the scenario's factor. Designed on an identified
        // model, the design may be refused (the bench's air spring stiffer than the model's): the
        // scenario is then counted with the reason, as pneud would refuse to start on it.
        std::optional<controller::ControlLaw> designed;
        try {
          designed.emplace(controller::make_control_law(cfg, *valve).scaled(s.gain_scale));
        } catch (const config::ConfigError& e) {
          if (!identified) throw;
          give_up(ScenarioResult{s, bench_params, identified,
                                 std::string("the gain design on the identified model is refused: ") + e.what(), {}, {},
                                 0.0, {}, check});
          continue;
        }
        const controller::ControlLaw& law = *designed;
        auto plant = backends::make_sim_backend(cfg, law, bench_params);
        const hal::SimBackend& bench = *plant;  // the simulated truth, owned by the run
        auto sim = controller::make_run(cfg, *valve, std::move(plant), law);
        sim.runtime->set_follow_forecasts(false);  // nobody sees the tick-by-tick comparison here
        sim.runtime->set_keep_reforecasts(true);   // judged below against the plant's breakaways
        ScenarioWatch watch(supervised ? std::nullopt
                                       : std::optional(settling_rules_only(controller::LoopParams::from(cfg, law), settling_rules)),
                            step_time, cfg.controller.duration_s, half, cfg.controller.hold.window_m,
                            cfg.controller.stop_detector.motion_band_m);
        sim.runtime->add_sink(watch);
        std::optional<identify::OnlineIdentifier> learner;
        if (online) learner.emplace(cfg, *sim.runtime);
        controller::SimulatedClock clock;
        std::atomic<bool> never{false};
        controller::execute(sim, cfg, clock, never);
        // Stops from the tail are not judged: the tail only lets the carriage show what it did
        // after the stops of the judged window.
        ScenarioResult r{s,  bench_params, identified, "", {}, {}, sim.runtime->end_time_s(),
                         watch.settling(bench.motion_events(), bench.plant().state().y_m), check};
        if (bench.motion_events_dropped() > 0)
          throw std::runtime_error("scenario " + std::to_string(s.index) + ": more plant events than recorded");
        for (auto stop : sim.runtime->stops()) {
          if (stop.t_stop_s > duration) continue;
          r.truth.push_back(apply_plant_truth(stop, bench.motion_events(), r.t_end_s));
          r.truth.back().on_configured_bound = learner && learner->forecast_on_a_configured_bound(stop.index);
          r.stops.push_back(stop);
        }
        results[static_cast<std::size_t>(i)] = std::move(r);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        if (!failure) failure = std::current_exception();
      }
      // The last one done stamps the wall time (the progress loop below only polls every 100 ms).
      if (done.fetch_add(1) + 1 == n) finished = std::chrono::steady_clock::now();
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < jobs; ++j) threads.emplace_back(worker);

  // Progress bar on stderr: redrawn in place on a terminal, a line per 10 % otherwise.
  const bool tty = ::isatty(STDERR_FILENO) && !args.flag("quiet");
  int last_decile = -1;
  for (;;) {
    const int d = done.load();
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    if (!args.flag("quiet")) {
      constexpr int kWidth = 40;
      const int filled = kWidth * d / n;
      if (tty) {
        std::fprintf(stderr, "\r[%.*s%*s] %d/%d scenarios, %.1f s", filled,
                     "########################################", kWidth - filled, "", d, n, elapsed);
      } else if (d * 10 / n != last_decile) {
        last_decile = d * 10 / n;
        std::fprintf(stderr, "pneu-sweep: %d/%d scenarios, %.1f s\n", d, n, elapsed);
      }
    }
    if (d == n) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (tty) std::fprintf(stderr, "\n");
  for (auto& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  const double wall_s = std::chrono::duration<double>(finished - wall0).count();

  // One CSV row per stop.
  auto& os = out.stream();
  os << "scenario,y0_m,y_d_m,friction_scale,gain_scale,stop,t_stop_s,y_stop_m,force_n,u_star_v,"
        "equilibrium_force_n,outcome,t_end_s,sticking_s,direction";
  for (const char* m : {"lin", "nl"})
    os << ',' << m << "_will_restart," << m << "_t_restart_s," << m << "_direction," << m << "_verdict,"
       << m << "_error_ms," << m << "_error_percent," << m << "_within_criteria";
  os << ",lin_halfway_error_percent,nl_halfway_error_percent,rx_halfway_error_percent,forecast_on_unidentified_bound,"
        "side_broken_away_slowly\n";
  MethodStats stats[3];
  // The methods that forecast half-way (every method made again, when update_period_s > 0).
  const auto& predictor = base.controller.predictor;
  const bool halfway_enabled[3] = {predictor.update_period_s > 0.0 && predictor.linearized,
                                   predictor.update_period_s > 0.0 && predictor.nonlinear,
                                   predictor.update_period_s > 0.0 && predictor.relaxation};
  std::uint64_t stops = 0, restarts = 0, long_restarts = 0, longest_restart_count_1s = 0, unseen = 0, not_at_rest = 0;
  std::vector<double> start_dating_ms;  // detector's start - plant's breakaway, over the starts it saw
  char buf[512];
  std::uint64_t learning = 0;  // --online: stops before their bench's kOnlineLearningRestarts-th restart
  for (const auto& r : results) {
    int restarts_seen = 0;  // by the daemon, before this stop
    // --online: the sides the bench broke away to after kLongSticking_s or more stuck, before this
    // stop ([0] positive, [1] negative)
    std::array<bool, 2> slow_breakaway_seen{};
    for (std::size_t k = 0; k < r.stops.size(); ++k) {
      const auto& s = r.stops[k];
      ++stops;
      if (r.truth[k].unseen) ++unseen;
      if (!std::isnan(r.truth[k].start_dating_s)) start_dating_ms.push_back(1e3 * r.truth[k].start_dating_s);
      const bool before_learning = online && restarts_seen < kOnlineLearningRestarts;
      if (s.restarted) ++restarts_seen;
      if (before_learning) ++learning;
      // else the forecast's premise, rest, was not there
      const bool judged = !r.truth[k].not_at_rest && !before_learning;
      if (r.truth[k].not_at_rest) ++not_at_rest;
      const char* outcome = before_learning     ? "before_learning"
                            : !judged          ? "plant_not_at_rest"
                            : !s.ended ? "stuck_to_end"
                                       : (s.restarted ? "restart" : "setpoint_changed");
      if (judged && s.restarted) {
        ++restarts;
        if (s.sticking_s() >= kLongSticking_s) ++long_restarts;
        if (s.sticking_s() >= 1.0) ++longest_restart_count_1s;
      }
      const controller::Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
      // The side the forecast turns on, as pneud counts it: the restart's, or the one the force
      // relaxes towards.
      const int side = any ? controller::side_turned_on(*any, s.force_n) : 0;
      const bool on_slow_side = online && side != 0 && slow_breakaway_seen[side > 0 ? 0 : 1];
      if (s.restarted && !r.truth[k].not_at_rest && s.sticking_s() >= kLongSticking_s && s.direction != 0)
        slow_breakaway_seen[s.direction > 0 ? 0 : 1] = true;
      std::snprintf(buf, sizeof buf, "%d,%.6f,%.6f,%.4f,%.4f,%llu,%.6f,%.9f,%.4f,%.6f,%.4f,%s,%.6f,%.6f,%d",
                    r.scenario.index, r.scenario.y0_m, r.scenario.y_d_m, r.scenario.friction_scale,
                    r.scenario.gain_scale, static_cast<unsigned long long>(s.index), s.t_stop_s, s.y_stop_m,
                    s.force_n, s.snapshot.u_v, any ? any->equilibrium_force_n : NAN, outcome, s.t_end_s,
                    s.sticking_s(), s.direction);
      os << buf;
      const std::optional<controller::Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
      for (int m = 0; m < 2; ++m) {
        if (!*ps[m]) {
          os << ",,,,,,,";
          continue;
        }
        const auto& p = **ps[m];
        const Verdict v = judged ? controller::judge(s, p, r.t_end_s) : Verdict{};
        const bool ok = within_criteria(s, v, m == 1);
        MethodStats& st = stats[m];
        switch (v.kind) {
          case Verdict::Kind::kTruePositive:
            ++st.tp;
            if (!v.direction_ok) ++st.wrong_direction;
            if (s.sticking_s() >= kLongSticking_s) st.long_error_pct.push_back(v.error_percent);
            else st.short_error_ms.push_back(std::abs(v.error_s) * 1e3);
            break;
          case Verdict::Kind::kTrueNegative: ++st.tn; break;
          case Verdict::Kind::kFalsePositive: ++st.fp; break;
          case Verdict::Kind::kFalseNegative: ++st.fn; break;
          case Verdict::Kind::kNotJudged: ++st.not_judged; break;
        }
        if (!ok) ++st.misses;
        if (r.truth[k].on_configured_bound) st.unlearned_side.add(s, v);
        if (on_slow_side) st.slow_side.add(s, v);
        const bool tp = v.kind == Verdict::Kind::kTruePositive;
        std::snprintf(buf, sizeof buf, ",%d,%.6f,%d,%s,%s,%s,%d", p.will_restart ? 1 : 0, p.t_restart_s,
                      p.direction, verdict_name(v.kind), tp ? std::to_string(v.error_s * 1e3).c_str() : "",
                      tp ? std::to_string(v.error_percent).c_str() : "", ok ? 1 : 0);
        os << buf;
      }
      // The live predictor: the forecast made again from the last pressures before half the
      // sticking time (restarts after >= 0.5 s only; not an acceptance figure).
      for (int m = 0; m < 3; ++m) {
        // (The half-way of the plant's truth: the runtime settled its own by the detector's.)
        const bool long_restart = judged && s.restarted && s.sticking_s() >= kLongSticking_s;
        const controller::Reforecast* halfway = long_restart ? controller::halfway_reforecast(s, kMethods[m]) : nullptr;
        const Verdict v = halfway ? controller::judge(s, halfway->prediction, r.t_end_s) : Verdict{};
        if (long_restart && halfway_enabled[m]) {
          if (!halfway) ++stats[m].halfway_missing;
          else if (v.kind == Verdict::Kind::kFalseNegative) ++stats[m].halfway_none;
          else if (v.kind == Verdict::Kind::kNotJudged) ++stats[m].halfway_not_judged;
          else if (v.kind == Verdict::Kind::kTruePositive && !v.direction_ok) ++stats[m].halfway_wrong_direction;
        }
        if (v.kind == Verdict::Kind::kTruePositive) {
          stats[m].halfway_error_pct.push_back(v.error_percent);
          os << ',' << std::to_string(v.error_percent);
        } else {
          os << ',';
        }
      }
      // --online: 1 when the stop was forecast on a stiction bound online learning had not
      // identified yet (pneud's summary counts these), 0 otherwise; empty without --online.
      if (online) os << ',' << (r.truth[k].on_configured_bound ? 1 : 0) << ',' << (on_slow_side ? 1 : 0);
      else os << ",,";
      os << '\n';
    }
  }
  out.commit();

  // One row per scenario, and the outcomes' account.
  std::uint64_t outcome_count[std::size(kOutcomes)] = {};
  std::vector<double> settle_times_s, final_errors_m;
  std::vector<double> in_window_after_s;  // the first rest within controller.hold.window_m, from the step
  std::uint64_t held = 0, restarts_after_hold = 0, restarted_after_hold = 0;
  std::uint64_t held_forecasts = 0, held_restart_forecasts = 0, reaches_forecast_none = 0;
  std::vector<double> reach_forecast_error_ms;
  std::size_t never_in_window = 0;  // run, never at rest within the window
  std::vector<double> rule_after_s[std::size(kOutcomes)];  // when the settling rules would latch, per outcome
  std::vector<std::uint64_t> fault_count(controller::kFaultCauseCount, 0);
  double y0_range_m[std::size(kOutcomes)][2], y_d_range_m[std::size(kOutcomes)][2];
  for (std::size_t k = 0; k < std::size(kOutcomes); ++k)
    y0_range_m[k][0] = y_d_range_m[k][0] = 1e300, y0_range_m[k][1] = y_d_range_m[k][1] = -1e300;
  const auto cell = [](double v, int digits = 6) {  // empty: not applicable
    if (std::isnan(v)) return std::string();
    char b[64];
    std::snprintf(b, sizeof b, "%.*f", digits, v);
    return std::string(b);
  };
  if (scenarios_out)
    scenarios_out->stream() << "scenario,y0_m,y_d_m,friction_scale,gain_scale,outcome,settle_time_s,final_error_m,"
                               "fault_cause,fault_after_s,stops,restarts,at_rest_at_end,last_second_swing_m,"
                               "oscillation_rule_after_s,bench_static_positive_n,bench_coulomb_positive_n,"
                               "bench_static_negative_n,bench_coulomb_negative_n,bench_viscous_n_s_per_m,"
                               "bench_max_conductance_m3_per_s_pa,bench_leak_conductance_in_m3_per_s_pa,"
                               "bench_leak_conductance_out_m3_per_s_pa,bench_dead_volume_p_m3,bench_dead_volume_n_m3,"
                               "bench_null_offset_v,bench_heat_transfer_w_per_m2_k,bench_thermal_time_constant_s,"
                               "bench_spool_time_constant_s"
                            << (identify_first ? ",identified_static_positive_n,identified_static_negative_n,"
                                                 "identified_null_offset_v,identified_null_pressure_error_pa,"
                                                 "identified_pressure_residual_pa,identified_pressure_explained_pa,"
                                                 "identified_model_fits,identified_heat_transfer_w_per_m2_k,"
                                                 "identified_spool_time_constant_s,identified_published,"
                                                 "identified_within_3_sigma,identification_failed"
                                               : "")
                            << ",in_window_after_s,hold_after_s,restarts_after_hold\n";
  // --identify: what was identified against each bench.
  std::vector<double> id_stiction_error_pct[2], id_null_error_pa;
  std::vector<std::string> id_failures;
  // ... how well its model fitted (the residual in what the noise explains), the parameters
  // published that the bench has too and those within 3 sigma of it, the heat transfer's and the
  // spool lag's errors where both have them
  std::vector<double> id_residual_ratio, id_heat_error_pct, id_spool_error_ms;
  int id_fits = 0, id_published = 0, id_within = 0;
  std::vector<std::string> id_outside;
  std::vector<std::tuple<std::string, int, int>> id_by_key;  // in the order first met
  for (const auto& r : results) {
    if (r.identified) {
      const IdentifiedCheck& c = r.check;
      id_residual_ratio.push_back(c.residual_pa / c.explained_pa);
      id_fits += c.fits ? 1 : 0;
      id_published += c.published;
      id_within += c.within_3_sigma;
      if (!c.outside.empty()) id_outside.push_back("scenario " + std::to_string(r.scenario.index) + ": " + c.outside);
      for (const auto& [key, published, within] : c.by_key) {
        auto it = std::find_if(id_by_key.begin(), id_by_key.end(), [&](const auto& k) { return std::get<0>(k) == key; });
        if (it == id_by_key.end()) it = id_by_key.insert(id_by_key.end(), {key, 0, 0});
        std::get<1>(*it) += published;
        std::get<2>(*it) += within;
      }
      if (r.bench.has_thermal && r.identified->has_thermal)
        id_heat_error_pct.push_back(
            100 * std::abs(r.identified->thermal.heat_transfer_w_per_m2_k / r.bench.thermal.heat_transfer_w_per_m2_k - 1));
      if (r.identified->valve.spool_time_constant_s > 0.0)
        id_spool_error_ms.push_back(
            1e3 * std::abs(r.identified->valve.spool_time_constant_s - r.bench.valve.spool_time_constant_s));
    }
    // A scenario whose identification failed, or whose identified model could not be designed
    // for, did not run: its row has no outcome's figures, and says why.
    const bool ran = r.identification_failed.empty();
    if (!ran) id_failures.push_back("scenario " + std::to_string(r.scenario.index) + ": " + r.identification_failed);
    const double id_null_error =
        r.identified ? identify::largest_null_pressure_difference_pa(*r.identified, r.bench, 1.0) : NAN;
    const Settling& g = r.settling;
    if (ran) {
      if (r.identified) {
        id_stiction_error_pct[0].push_back(100 * std::abs(r.identified->friction.static_positive_n / r.bench.friction.static_positive_n - 1));
        id_stiction_error_pct[1].push_back(100 * std::abs(r.identified->friction.static_negative_n / r.bench.friction.static_negative_n - 1));
        id_null_error_pa.push_back(id_null_error);
      }
      const auto k = static_cast<std::size_t>(g.outcome);
      ++outcome_count[k];
      y0_range_m[k][0] = std::min(y0_range_m[k][0], r.scenario.y0_m);
      y0_range_m[k][1] = std::max(y0_range_m[k][1], r.scenario.y0_m);
      y_d_range_m[k][0] = std::min(y_d_range_m[k][0], r.scenario.y_d_m);
      y_d_range_m[k][1] = std::max(y_d_range_m[k][1], r.scenario.y_d_m);
      if (g.outcome == Outcome::kSettled) {
        settle_times_s.push_back(g.settle_time_s);
        final_errors_m.push_back(g.final_error_m);
      }
      if (!std::isnan(g.in_window_after_s)) in_window_after_s.push_back(g.in_window_after_s);
      else ++never_in_window;
      held_forecasts += g.held_forecasts;
      held_restart_forecasts += g.held_restart_forecasts;
      reaches_forecast_none += g.reaches_forecast_none;
      reach_forecast_error_ms.insert(reach_forecast_error_ms.end(), g.reach_forecast_error_ms.begin(),
                                     g.reach_forecast_error_ms.end());
      if (!std::isnan(g.hold_after_s)) {
        ++held;
        restarts_after_hold += g.restarts_after_hold;
        if (g.restarts_after_hold > 0) ++restarted_after_hold;
      }
      if (g.fault != controller::FaultCause::kNone) ++fault_count[controller::fault_number(g.fault)];
      if (!std::isnan(g.oscillation_rule_after_s)) rule_after_s[k].push_back(g.oscillation_rule_after_s);
    }
    if (!scenarios_out) continue;
    auto& os_sc = scenarios_out->stream();
    // The positions and the bench exactly (they read back as the same doubles): a scenario can be
    // run again with pneud.
    char exact[2][32];
    std::snprintf(exact[0], sizeof exact[0], "%.17g", r.scenario.y0_m);
    std::snprintf(exact[1], sizeof exact[1], "%.17g", r.scenario.y_d_m);
    os_sc << r.scenario.index << ',' << exact[0] << ',' << exact[1] << ','
          << cell(r.scenario.friction_scale, 4) << ',' << cell(r.scenario.gain_scale, 4) << ',';
    if (ran)
      os_sc << outcome_name(g.outcome) << ',' << cell(g.settle_time_s) << ',' << cell(g.final_error_m, 9) << ','
            << (g.fault == controller::FaultCause::kNone ? "" : controller::fault_name(g.fault)) << ','
            << cell(g.fault_after_s) << ',' << g.stops << ',' << g.restarts << ',' << (g.at_rest_at_end ? 1 : 0) << ','
            << cell(g.last_second_swing_m, 9) << ',' << cell(g.oscillation_rule_after_s);
    else
      os_sc << "identification_failed" << std::string(9, ',');  // the outcome's 9 figures: none
    const model::PlantParams& b = r.bench;
    char row[512];
    std::snprintf(row, sizeof row, ",%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", b.friction.static_positive_n,
                  b.friction.coulomb_positive_n, b.friction.static_negative_n, b.friction.coulomb_negative_n,
                  b.friction.viscous_n_s_per_m, b.valve.max_conductance_m3_per_s_pa,
                  b.valve.leak_conductance_in_m3_per_s_pa, b.valve.leak_conductance_out_m3_per_s_pa,
                  b.geometry.dead_volume_p_m3, b.geometry.dead_volume_n_m3, b.valve.null_offset_v);
    os_sc << row;
    if (b.has_thermal)
      std::snprintf(row, sizeof row, ",%.17g,%.17g", b.thermal.heat_transfer_w_per_m2_k, model::thermal_time_constant_s(b));
    else
      std::snprintf(row, sizeof row, ",,");
    os_sc << row;
    std::snprintf(row, sizeof row, ",%.17g", b.valve.spool_time_constant_s);
    os_sc << row;
    if (identify_first) {
      if (r.identified)
        std::snprintf(row, sizeof row, ",%.6g,%.6g,%.6g,%.1f,%.3f,%.3f,%d,%s,%.6g,%d,%d", r.identified->friction.static_positive_n,
                      r.identified->friction.static_negative_n, r.identified->valve.null_offset_v, id_null_error,
                      r.check.residual_pa, r.check.explained_pa, r.check.fits ? 1 : 0,
                      r.identified->has_thermal ? cell(r.identified->thermal.heat_transfer_w_per_m2_k, 4).c_str() : "",
                      r.identified->valve.spool_time_constant_s, r.check.published, r.check.within_3_sigma);
      else
        std::snprintf(row, sizeof row, ",,,,,,,,,,");
      std::string reason = r.identification_failed;  // one quoted cell
      std::replace(reason.begin(), reason.end(), '"', '\'');
      os_sc << row << ',' << (reason.empty() ? "" : "\"" + reason + "\"");
    }
    if (ran) os_sc << ',' << cell(g.in_window_after_s) << ',' << cell(g.hold_after_s) << ',' << g.restarts_after_hold;
    else os_sc << ",,,";
    os_sc << '\n';
  }
  if (scenarios_out) scenarios_out->commit();

  char bench_text[96] = "";
  if (bench_spread > 0.0)
    std::snprintf(bench_text, sizeof bench_text, ", bench +-%.0f %% of the model and a valve null offset within +-%.3g V",
                  bench_spread * 100, 0.5 * bench_spread);
  std::printf("pneu-sweep: %d scenarios (%d set-point steps over [%.3f, %.3f] m, seed %llu, friction +-%.0f %%, gains +-%.0f %%%s), stops of the first %.0f s judged (+ %.1f s tail)\n",
              n, n, lo, hi, static_cast<unsigned long long>(seed_d), friction_spread * 100, gain_spread * 100, bench_text,
              duration, tail);
  std::printf("  %llu stops, %llu restarts (%llu after >= 0.5 s of sticking, %llu after >= 1 s), timed by the plant's "
              "breakaways; %llu of them moved the carriage less than the stop detector's motion band\n",
              static_cast<unsigned long long>(stops), static_cast<unsigned long long>(restarts),
              static_cast<unsigned long long>(long_restarts), static_cast<unsigned long long>(longest_restart_count_1s),
              static_cast<unsigned long long>(unseen));
  if (!start_dating_ms.empty()) {
    std::vector<double> early_ms, late_ms;
    for (const double d : start_dating_ms) (d < 0.0 ? early_ms : late_ms).push_back(std::abs(d));
    std::vector<double> abs_ms;
    for (const double d : start_dating_ms) abs_ms.push_back(std::abs(d));
    std::printf("  the detector dated the %zu starts it saw %zu before the plant's breakaway (max %.1f ms), %zu at or after it (max "
                "%.1f ms); |gap| p50 %.2f ms p90 %.2f ms p99 %.1f ms\n",
                start_dating_ms.size(), early_ms.size(), early_ms.empty() ? 0.0 : percentile(early_ms, 1.0), late_ms.size(),
                late_ms.empty() ? 0.0 : percentile(late_ms, 1.0), percentile(abs_ms, 0.5), percentile(abs_ms, 0.9),
                percentile(abs_ms, 0.99));
  }
  if (not_at_rest > 0)
    std::printf("  %llu stops were confirmed while the plant was still sliding within the detector's rest band: "
                "their forecasts are not judged\n",
                static_cast<unsigned long long>(not_at_rest));
  const auto count = [&](Outcome o) { return static_cast<unsigned long long>(outcome_count[static_cast<std::size_t>(o)]); };
  std::printf("  outcomes (the first rest after the step): %llu settled, %llu never settled, %llu at rest against an end "
              "stop, %llu faults\n",
              count(Outcome::kSettled), count(Outcome::kNeverSettled), count(Outcome::kEndStop), count(Outcome::kFault));
  if (outcome_count[static_cast<std::size_t>(Outcome::kFault)] > 0) {
    std::printf("    faults by cause:");
    for (std::size_t c = 1; c < fault_count.size(); ++c)
      if (fault_count[c] > 0)
        std::printf(" %s %llu", controller::fault_name(static_cast<controller::FaultCause>(c)),
                    static_cast<unsigned long long>(fault_count[c]));
    std::printf("\n");
  }
  for (const Outcome o : {Outcome::kNeverSettled, Outcome::kEndStop, Outcome::kFault}) {
    const auto k = static_cast<std::size_t>(o);
    if (outcome_count[k] == 0) continue;
    std::printf("    %s: y0 in [%.3f, %.3f] m, y_d in [%.3f, %.3f] m\n", outcome_name(o), y0_range_m[k][0],
                y0_range_m[k][1], y_d_range_m[k][0], y_d_range_m[k][1]);
  }
  std::printf("    settle time from the step (%zu settled): p50 %.3f s  p90 %.3f s  p99 %.3f s  max %.3f s\n",
              settle_times_s.size(), percentile(settle_times_s, 0.5), percentile(settle_times_s, 0.9),
              percentile(settle_times_s, 0.99), percentile(settle_times_s, 1.0));
  std::printf("    final |y_d - y| (%zu settled): p50 %.3f mm  p90 %.3f mm  p99 %.3f mm  max %.3f mm\n",
              final_errors_m.size(), percentile(final_errors_m, 0.5) * 1e3, percentile(final_errors_m, 0.9) * 1e3,
              percentile(final_errors_m, 0.99) * 1e3, percentile(final_errors_m, 1.0) * 1e3);
  std::printf("    at rest within +-%.3f mm of the set point (controller.hold.window_m), from the step (%zu of %zu run): "
              "p50 %.3f s  p90 %.3f s  max %.3f s\n",
              base.controller.hold.window_m * 1e3, in_window_after_s.size(), results.size() - id_failures.size(),
              percentile(in_window_after_s, 0.5), percentile(in_window_after_s, 0.9), percentile(in_window_after_s, 1.0));
  {
    // Over every scenario run, those never at rest within the window counted as never: beside the
    // percentiles above, which count only those that came to rest there.
    std::vector<double> all(in_window_after_s);
    all.insert(all.end(), never_in_window, std::numeric_limits<double>::infinity());
    char p50[32], p90[32];
    for (auto [text, q] : {std::pair{p50, 0.5}, std::pair{p90, 0.9}}) {
      const double v = percentile(all, q);
      if (std::isinf(v)) std::snprintf(text, sizeof p50, "never");
      else std::snprintf(text, sizeof p50, "%.3f s", v);
    }
    std::printf("    ... over all %zu run, the %zu never at rest within it counted as never: p50 %s  p90 %s\n", all.size(),
                never_in_window, p50, p90);
  }
  std::printf("    the in-position hold (%s): began in %llu scenarios; restarts after it began (breakaways of the plant "
              "beyond the motion band): %llu, in %llu scenarios\n",
              base.controller.hold.enabled ? "on" : "off", static_cast<unsigned long long>(held),
              static_cast<unsigned long long>(restarts_after_hold), static_cast<unsigned long long>(restarted_after_hold));
  if (base.controller.hold.enabled) {
    std::vector<double> abs_ms;
    for (double e : reach_forecast_error_ms) abs_ms.push_back(std::abs(e));
    const auto within = [&](double ms) { return std::count_if(abs_ms.begin(), abs_ms.end(), [ms](double e) { return e <= ms; }); };
    std::printf("    forecasts under the hold's commands (method held): %llu made while held within the window, %llu of "
                "them a restart; reaches that broke away: %zu, forecast as each began within 1 / 2 / 5 ms of the start "
                "seen: %td / %td / %td (|error| p50 %.2f ms, max %.2f ms), %llu forecast none\n",
                static_cast<unsigned long long>(held_forecasts), static_cast<unsigned long long>(held_restart_forecasts),
                abs_ms.size(), within(1.0), within(2.0), within(5.0), percentile(abs_ms, 0.5), percentile(abs_ms, 1.0),
                static_cast<unsigned long long>(reaches_forecast_none));
  }
  if (!supervised && (settling_rules.oscillation_sign_changes > 0 || settling_rules.settle_time_s > 0.0)) {
    std::vector<double> all_after_s;
    for (const auto& v : rule_after_s) all_after_s.insert(all_after_s.end(), v.begin(), v.end());
    std::printf("    the settling rules (%u sign changes beyond +-%.1f mm within %.2f s; settle time %.2f s), checked "
                "alongside, would latch the oscillation or not-settled fault in:",
                settling_rules.oscillation_sign_changes, settling_rules.oscillation_amplitude_m * 1e3,
                settling_rules.oscillation_window_s, settling_rules.settle_time_s);
    const char* separator = " ";
    for (const Outcome o : kOutcomes) {
      const auto k = static_cast<std::size_t>(o);
      if (outcome_count[k] == 0) continue;
      std::printf("%s%zu of %llu %s", separator, rule_after_s[k].size(),
                  static_cast<unsigned long long>(outcome_count[k]), outcome_name(o));
      separator = ", ";
    }
    if (!all_after_s.empty())
      std::printf("; after the step: p50 %.3f s  max %.3f s", percentile(all_after_s, 0.5), percentile(all_after_s, 1.0));
    std::printf("\n");
  }
  if (online)
    std::printf("  online identification: %llu stops before their bench had restarted %d times (while it learns) not judged\n",
                static_cast<unsigned long long>(learning), kOnlineLearningRestarts);
  if (identify_first) {
    std::printf("  identified first (pneud's identification run on each bench): %zu of %d, %zu failed\n",
                id_null_error_pa.size(), n, id_failures.size());
    for (const auto& f : id_failures) std::printf("    failed: %s\n", f.c_str());
    if (!id_null_error_pa.empty()) {
      for (int side = 0; side < 2; ++side)
        std::printf("    %s error against the bench: p50 %.3f %%  p90 %.3f %%  max %.3f %%\n",
                    side == 0 ? "F_S+" : "F_S-", percentile(id_stiction_error_pct[side], 0.5),
                    percentile(id_stiction_error_pct[side], 0.9), percentile(id_stiction_error_pct[side], 1.0));
      std::printf("    p_null(u) over |u| < 1 V, largest error against the bench: p50 %.0f Pa  p90 %.0f Pa  max %.0f Pa\n",
                  percentile(id_null_error_pa, 0.5), percentile(id_null_error_pa, 0.9), percentile(id_null_error_pa, 1.0));
    }
    if (!id_residual_ratio.empty()) {
      std::printf("    the model fits (pressure residual within twice what the sensors' noise explains) on %d of %zu; "
                  "residual in what the noise explains: p50 %.2f  p90 %.2f  max %.2f\n",
                  id_fits, id_residual_ratio.size(), percentile(id_residual_ratio, 0.5),
                  percentile(id_residual_ratio, 0.9), percentile(id_residual_ratio, 1.0));
      std::printf("    parameters published that the bench has too, within 3 of their stated sigmas of it: %d of %d "
                  "(%.1f %%)\n",
                  id_within, id_published, id_published > 0 ? 100.0 * id_within / id_published : 0.0);
      std::printf("     ");
      for (const auto& [key, published, within] : id_by_key)
        std::printf(" %s %d of %d;", key.substr(key.rfind('.') + 1).c_str(), within, published);
      std::printf("\n");
      for (std::size_t i = 0; i < id_outside.size() && i < 10; ++i) std::printf("      outside: %s\n", id_outside[i].c_str());
      if (id_outside.size() > 10) std::printf("      ... %zu scenarios with one outside in all\n", id_outside.size());
      if (!id_heat_error_pct.empty())
        std::printf("    heat transfer error against the bench: p50 %.3f %%  p90 %.3f %%  max %.3f %%\n",
                    percentile(id_heat_error_pct, 0.5), percentile(id_heat_error_pct, 0.9),
                    percentile(id_heat_error_pct, 1.0));
      if (!id_spool_error_ms.empty())
        std::printf("    spool lag error against the bench: p50 %.4f ms  p90 %.4f ms  max %.4f ms\n",
                    percentile(id_spool_error_ms, 0.5), percentile(id_spool_error_ms, 0.9),
                    percentile(id_spool_error_ms, 1.0));
    }
  }
  std::printf("  %.2f s wall on %d threads: %.1f scenarios/s\n", wall_s, jobs, n / wall_s);
  // The live predictor's half-way forecasts of the restarts after >= 0.5 s.
  const auto print_halfway = [](const MethodStats& st) {
    std::printf("    made again half-way, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% "
                "(the live predictor, from the pressures of the moment; not judged)\n",
                st.halfway_error_pct.size(), percentile(st.halfway_error_pct, 0.5),
                percentile(st.halfway_error_pct, 0.9), percentile(st.halfway_error_pct, 0.99),
                percentile(st.halfway_error_pct, 1.0));
    const auto within = within_2_5_10(st.halfway_error_pct);
    const std::uint64_t restarts_seen =
        st.halfway_error_pct.size() + st.halfway_none + st.halfway_not_judged + st.halfway_missing;
    std::printf("      of %llu such restarts: within 2 %%: %zu, 5 %%: %zu, 10 %%: %zu (wrong direction: %llu); forecast "
                "none: %llu; restart after the run: %llu; no forecast by half-way: %llu\n",
                static_cast<unsigned long long>(restarts_seen), within[0], within[1], within[2],
                static_cast<unsigned long long>(st.halfway_wrong_direction),
                static_cast<unsigned long long>(st.halfway_none), static_cast<unsigned long long>(st.halfway_not_judged),
                static_cast<unsigned long long>(st.halfway_missing));
  };
  const config::LinearizedSlope slope = base.controller.predictor.linearized_slope;
  const std::string names[2] = {slope == config::LinearizedSlope::kStopTangent
                                    ? std::string("linearized")
                                    : std::string("linearized (slope: ") + config::to_string(slope) + ")",
                                "nonlinear"};
  for (int m = 0; m < 2; ++m) {
    const MethodStats& st = stats[m];
    if (st.tp + st.tn + st.fp + st.fn == 0) continue;
    std::printf("  %s:\n", names[m].c_str());
    std::printf("    confusion            actual restart  actual none\n");
    std::printf("      forecast restart   %14llu  %11llu\n", static_cast<unsigned long long>(st.tp),
                static_cast<unsigned long long>(st.fp));
    std::printf("      forecast none      %14llu  %11llu\n", static_cast<unsigned long long>(st.fn),
                static_cast<unsigned long long>(st.tn));
    std::printf("    not judged: %llu (the set point moved, the plant was not at rest, or the forecast restart falls after the run)\n",
                static_cast<unsigned long long>(st.not_judged));
    std::printf("    wrong direction: %llu\n", static_cast<unsigned long long>(st.wrong_direction));
    std::printf("    error, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% of the sticking time\n",
                st.long_error_pct.size(), percentile(st.long_error_pct, 0.5), percentile(st.long_error_pct, 0.9),
                percentile(st.long_error_pct, 0.99), percentile(st.long_error_pct, 1.0));
    std::printf("    error, sticking <  0.5 s (%zu): p50 %.3f ms p90 %.3f ms p99 %.3f ms max %.3f ms\n",
                st.short_error_ms.size(), percentile(st.short_error_ms, 0.5), percentile(st.short_error_ms, 0.9),
                percentile(st.short_error_ms, 0.99), percentile(st.short_error_ms, 1.0));
    {
      const auto within = within_2_5_10(st.long_error_pct);
      const std::uint64_t judged_stops = st.tp + st.tn + st.fp + st.fn;
      std::printf("    sticking >= 0.5 s, within 2 %%: %zu, 5 %%: %zu, 10 %%: %zu of %zu; verdict wrong (restart or "
                  "none): %llu of %llu judged stops (%.2f %%)\n",
                  within[0], within[1], within[2], st.long_error_pct.size(),
                  static_cast<unsigned long long>(st.fp + st.fn), static_cast<unsigned long long>(judged_stops),
                  judged_stops ? 100.0 * static_cast<double>(st.fp + st.fn) / static_cast<double>(judged_stops) : 0.0);
    }
    std::printf("    outside the acceptance criteria (%s %%, 10 ms): %llu\n", m == 0 ? "5" : "1",
                static_cast<unsigned long long>(st.misses));
    if (online) {
      const auto within = within_2_5_10(st.unlearned_side.long_error_pct);
      std::printf("    --online, judged stops forecast on a stiction bound not identified yet (the configured one: no "
                  "breakaway that way yet): %llu, verdict wrong on %llu; sticking >= 0.5 s within 2 %%: %zu, "
                  "5 %%: %zu, 10 %%: %zu of %zu\n",
                  static_cast<unsigned long long>(st.unlearned_side.stops), static_cast<unsigned long long>(st.unlearned_side.wrong),
                  within[0], within[1], within[2], st.unlearned_side.long_error_pct.size());
      // The others, on bounds it had identified.
      const auto all = within_2_5_10(st.long_error_pct);
      const std::uint64_t judged_stops = st.tp + st.tn + st.fp + st.fn;
      std::printf("    --online, the others, on identified bounds: %llu, verdict wrong on %llu; sticking >= 0.5 s within "
                  "2 %%: %zu, 5 %%: %zu, 10 %%: %zu of %zu\n",
                  static_cast<unsigned long long>(judged_stops - st.unlearned_side.stops),
                  static_cast<unsigned long long>(st.fp + st.fn - st.unlearned_side.wrong), all[0] - within[0],
                  all[1] - within[1], all[2] - within[2],
                  st.long_error_pct.size() - st.unlearned_side.long_error_pct.size());
      // Across both: the stops on a side the bench had broken away to slowly.
      const auto slow = within_2_5_10(st.slow_side.long_error_pct);
      std::printf("    --online, judged stops on a side the bench had already broken away to after >= %.1f s stuck (a slow "
                  "breakaway): %llu, verdict wrong on %llu; sticking >= 0.5 s within 2 %%: %zu, 5 %%: %zu, 10 %%: %zu "
                  "of %zu\n",
                  kLongSticking_s, static_cast<unsigned long long>(st.slow_side.stops),
                  static_cast<unsigned long long>(st.slow_side.wrong), slow[0], slow[1], slow[2],
                  st.slow_side.long_error_pct.size());
    }
    print_halfway(st);
  }
  if (halfway_enabled[2]) {
    std::printf("  relaxation (made again only, fitted to the phase's own pressures; no valve model):\n");
    print_halfway(stats[2]);
  }
  std::printf("  wrote %s\n", out_path.c_str());
  if (scenarios_out) std::printf("  wrote %s\n", scenarios_out->path().c_str());
  int exit_code = cli::kExitOk;
  if ((args.flag("strict") || args.flag("strict-forecasts")) && (stats[0].misses || stats[1].misses)) {
    std::fprintf(stderr, "pneu-sweep: strict: %llu forecasts outside the acceptance criteria (linearized %llu, nonlinear %llu)\n",
                 static_cast<unsigned long long>(stats[0].misses + stats[1].misses),
                 static_cast<unsigned long long>(stats[0].misses), static_cast<unsigned long long>(stats[1].misses));
    exit_code = cli::kExitFailure;
  }
  const unsigned long long unsettled = static_cast<unsigned long long>(n) - count(Outcome::kSettled);
  if (args.flag("strict") && unsettled > 0) {
    std::fprintf(stderr, "pneu-sweep: strict: %llu of %d scenarios did not settle (%llu never settled, %llu at an end stop, %llu faults)\n",
                 unsettled, n, count(Outcome::kNeverSettled), count(Outcome::kEndStop), count(Outcome::kFault));
    exit_code = cli::kExitFailure;
  }
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-sweep", run, argc, argv); }
