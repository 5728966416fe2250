// One scenario run to its result, and all of them on threads.
#include "pneu/sweep/run.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/identify.hpp"
#include "pneu/identify/online.hpp"

namespace pneu::sweep {

using controller::Verdict;

namespace {

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

// A rest this close to an end of the stroke is against its end stop [m] (the targets keep
// --margin-m from the ends; a noisy, quantised sensor reads an end stop within tens of um).
constexpr double kEndStopTolerance_m = 1.0e-3;

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
    s_.fault = controller::FaultCause::kNone;
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
    c.by_key.push_back({e.key, 1, sigmas <= 3.0 ? 1 : 0});
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

// Tolerance of the acceptance criteria for one forecast.
bool within_criteria(const controller::StopOutcome& s, const Verdict& v, bool nonlinear) {
  if (v.kind == Verdict::Kind::kFalseNegative || v.kind == Verdict::Kind::kFalsePositive) return false;
  if (v.kind != Verdict::Kind::kTruePositive) return true;
  if (!v.direction_ok) return false;
  if (s.sticking_s() >= kLongSticking_s) return v.error_percent <= (nonlinear ? 1.0 : 5.0);
  return std::abs(v.error_s) <= 0.010;
}

// The CSV's and the summary's order: lin, nl, rx (the relaxation method: half-way only).
constexpr controller::PredictionMethod kMethods[kMethodCount] = {controller::PredictionMethod::kLinearized,
                                                                 controller::PredictionMethod::kNonlinear,
                                                                 controller::PredictionMethod::kRelaxation};

// The scenario's stops judged, in order: the fate of each, its forecasts' verdicts, and (--online)
// whether it was forecast before learning or on a side the bench had broken away to slowly.
void judge_stops(ScenarioResult& r, bool online) {
  int restarts_seen = 0;  // by the daemon, before this stop
  // --online: the sides the bench broke away to after kLongSticking_s or more stuck, before this
  // stop ([0] positive, [1] negative)
  std::array<bool, 2> slow_breakaway_seen{};
  for (JudgedStop& j : r.stops) {
    const controller::StopOutcome& s = j.stop;
    const bool before_learning = online && restarts_seen < kOnlineLearningRestarts;
    if (s.restarted) ++restarts_seen;
    // else the forecast's premise, rest, was not there
    j.fate = before_learning          ? StopFate::kBeforeLearning
             : j.truth.not_at_rest    ? StopFate::kPlantNotAtRest
             : !s.ended               ? StopFate::kStuckToEnd
             : s.restarted            ? StopFate::kRestart
                                      : StopFate::kSetpointChanged;
    const bool judged = j.judged();
    const controller::Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
    // The side the forecast turns on, as pneud counts it: the restart's, or the one the force
    // relaxes towards.
    const int side = any ? controller::side_turned_on(*any, s.force_n) : 0;
    j.on_slow_side = online && side != 0 && slow_breakaway_seen[side > 0 ? 0 : 1];
    if (s.restarted && !j.truth.not_at_rest && s.sticking_s() >= kLongSticking_s && s.direction != 0)
      slow_breakaway_seen[s.direction > 0 ? 0 : 1] = true;
    const std::optional<controller::Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
    for (int m = 0; m < 2; ++m) {
      if (!*ps[m]) continue;
      JudgedForecast f;
      f.prediction = **ps[m];
      f.verdict = judged ? controller::judge(s, f.prediction, r.t_end_s) : Verdict{};
      f.within_criteria = within_criteria(s, f.verdict, m == 1);
      j.at_stop[static_cast<std::size_t>(m)] = f;
    }
    // The live predictor: the forecast made again from the last pressures before half the
    // sticking time (restarts after >= 0.5 s only; not an acceptance figure). (The half-way of
    // the plant's truth: the runtime settled its own by the detector's.)
    j.long_restart = judged && s.restarted && s.sticking_s() >= kLongSticking_s;
    for (std::size_t m = 0; m < kMethodCount; ++m) {
      const controller::Reforecast* halfway = j.long_restart ? controller::halfway_reforecast(s, kMethods[m]) : nullptr;
      if (halfway) j.halfway[m] = controller::judge(s, halfway->prediction, r.t_end_s);
    }
    j.stop.reforecasts = {};  // judged: what is left of them is not read again
  }
}

}  // namespace

const char* outcome_name(Outcome o) noexcept {
  switch (o) {
    case Outcome::kSettled: return "settled";
    case Outcome::kNeverSettled: return "never-settled";
    case Outcome::kEndStop: return "end-stop";
    case Outcome::kFault: return "fault";
  }
  return "?";
}

const char* fate_name(StopFate f) noexcept {
  switch (f) {
    case StopFate::kBeforeLearning: return "before_learning";
    case StopFate::kPlantNotAtRest: return "plant_not_at_rest";
    case StopFate::kStuckToEnd: return "stuck_to_end";
    case StopFate::kRestart: return "restart";
    case StopFate::kSetpointChanged: return "setpoint_changed";
  }
  return "?";
}

ScenarioResult run_scenario(const config::Config& loaded, const Options& o, const Scenario& s) {
  config::Config cfg = loaded;
  const config::SupervisorConfig settling_rules = loaded.controller.supervisor;  // checked alongside
  if (!o.supervised) {
    auto& v = cfg.controller.supervisor;
    v.oscillation_sign_changes = 0;
    v.settle_time_s = 0.0;
    v.position_min_m = v.pressure_min_pa = -1e300;
    v.position_max_m = v.pressure_max_pa = 1e300;
    v.overtravel_m = 1e300;
    v.following_error_s = 0.0;
    v.max_speed_m_per_s = 0.0;
  }
  const double half = cfg.plant.geometry.half_stroke_m();
  cfg.simulation.initial_position_m = s.y0_m;
  cfg.controller.initial_setpoint_m = s.y0_m;
  cfg.controller.schedule = {{o.step_time_s, s.y_d_m}};
  cfg.controller.duration_s = o.duration_s + o.tail_s;
  cfg.controller.clock = config::ClockKind::kSimulated;
  // The friction spread scales the model's friction and the bench's alike.
  for (model::FrictionParams* f : {&cfg.plant.friction, &cfg.hal.sim.plant.friction}) {
    f->static_positive_n *= s.friction_scale;
    f->coulomb_positive_n *= s.friction_scale;
    f->static_negative_n *= s.friction_scale;
    f->coulomb_negative_n *= s.friction_scale;
    f->viscous_n_s_per_m *= s.friction_scale;
  }
  ScenarioResult r;
  r.scenario = s;
  r.bench = s.bench.applied_to(config::simulated_bench(cfg));
  if (o.identify) {
    // pneud --identify on the scenario's bench, from the configured model; the scenario then
    // runs on what it identified.
    const assembly::RunSpec prior = assembly::RunSpec::of(cfg, {o.config_dir, true, std::nullopt});
    try {
      const identify::Identification id =
          identify::identify_by_run(prior.with_law(identify::identification_law(prior)), r.bench, s.y0_m);
      r.identified = id.plant;
      r.check = check_identified(id, r.bench);
      r.check.null_pressure_error_pa = identify::largest_null_pressure_difference_pa(*r.identified, r.bench, 1.0);
      // As pneud --identify writes it: the forecasts on a model that did not fit say so.
      if (id.evidence.fitted_phases > 0) {
        cfg.controller.predictor.has_model_fit = true;
        cfg.controller.predictor.model_fit = {id.evidence.pressure_rms_residual_pa, id.evidence.pressure_explained_pa};
      }
    } catch (const std::exception& e) {
      r.identified.reset();
      r.check = {};
      r.identification_failed = e.what();
      return r;
    }
    cfg.plant = *r.identified;
  }
  // The gains, fixed or scheduled, mistuned by the scenario's factor. Designed on an identified
  // model, the design may be refused (the bench's air spring stiffer than the model's): the
  // scenario is then counted with the reason, as pneud would refuse to start on it.
  std::optional<assembly::RunSpec> designed;
  try {
    const assembly::RunSpec spec = assembly::RunSpec::of(cfg, {o.config_dir, true, std::nullopt});
    designed.emplace(spec.with_law(spec.law().scaled(s.gain_scale)));
  } catch (const config::ConfigError& e) {
    if (!r.identified) throw;
    r.identification_failed = std::string("the gain design on the identified model is refused: ") + e.what();
    return r;
  }
  assembly::AssembledRun sim = assembly::AssembledRun::on_simulated_bench(*designed, r.bench);
  const hal::SimBackend& bench = *sim.simulated_bench();  // the simulated truth, owned by the run
  sim.runtime().set_follow_forecasts(false);  // nobody sees the tick-by-tick comparison here
  sim.runtime().set_keep_reforecasts(true);   // judged below against the plant's breakaways
  const config::Config& run_cfg = sim.config();
  ScenarioWatch& watch = sim.emplace_sink<ScenarioWatch>(
      o.supervised ? std::nullopt
                   : std::optional(settling_rules_only(controller::LoopParams::from(run_cfg, sim.spec().law()),
                                                       settling_rules)),
      o.step_time_s, run_cfg.controller.duration_s, half, run_cfg.controller.hold.window_m,
      run_cfg.controller.stop_detector.motion_band_m);
  std::optional<identify::OnlineIdentifier> learner;
  if (o.online) learner.emplace(run_cfg, sim.runtime());
  controller::SimulatedClock clock;
  std::atomic<bool> never{false};
  sim.execute(clock, never);
  r.t_end_s = sim.runtime().end_time_s();
  r.settling = watch.settling(bench.motion_events(), bench.plant().state().y_m);
  if (bench.motion_events_dropped() > 0)
    throw std::runtime_error("scenario " + std::to_string(s.index) + ": more plant events than recorded");
  // Stops from the tail are not judged: the tail only lets the carriage show what it did after
  // the stops of the judged window.
  for (const controller::StopOutcome& stop : sim.runtime().stops()) {
    if (stop.t_stop_s > o.duration_s) continue;
    JudgedStop& j = r.stops.emplace_back();
    j.stop = stop;
    j.truth = apply_plant_truth(j.stop, bench.motion_events(), r.t_end_s);
    j.truth.on_configured_bound = learner && learner->forecast_on_a_configured_bound(stop.index);
  }
  judge_stops(r, o.online);
  return r;
}

SweepRun run_all(const config::Config& config, const Options& options, std::span<const Scenario> scenarios, int jobs,
                 const ProgressFn& progress) {
  const int n = static_cast<int>(scenarios.size());
  SweepRun run;
  run.jobs = jobs;
  run.results.resize(scenarios.size());
  std::atomic<int> next{0}, done{0};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  const auto wall0 = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point finished = wall0;  // written once, read after the joins
  const auto worker = [&] {
    for (int i; (i = next.fetch_add(1)) < n;) {
      try {
        run.results[static_cast<std::size_t>(i)] = run_scenario(config, options, scenarios[static_cast<std::size_t>(i)]);
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
  if (progress)
    for (;;) {
      const int d = done.load();
      progress(d, n, std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count());
      if (d == n) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  for (auto& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  run.wall_s = std::chrono::duration<double>(finished - wall0).count();
  return run;
}

}  // namespace pneu::sweep
