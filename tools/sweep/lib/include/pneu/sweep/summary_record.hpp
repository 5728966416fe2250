// The sweep's summary as pneu-sweep --summary-json writes it, described once
// (pneu/records/record.hpp): its members, their nesting and their spelling are said here; the JSON
// document and its JSON Schema (share/pneu/schemas/sweep_summary.schema.json) follow.
// summary_record() (report.hpp) fills it from the statistics. Only the records' vocabulary is
// included: pneu-records writes the schema from here.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "pneu/records/record.hpp"

namespace pneu::sweep {

/// Percentiles of `count` values (null when none).
struct SummaryPercentiles {
  std::uint64_t count = 0;
  double p50 = 0.0, p90 = 0.0, p99 = 0.0, max = 0.0;
};

/// How many errors are within 2, 5 and 10 % of the sticking time.
using SummaryWithin = std::array<std::uint64_t, 3>;
inline constexpr std::array<records::IndexName, 3> kWithinPercent = {
    records::IndexName{"2_percent"}, records::IndexName{"5_percent"}, records::IndexName{"10_percent"}};

struct SummarySetting {
  std::uint64_t seed = 0;
  double targets_lo_m = 0.0, targets_hi_m = 0.0, duration_s = 0.0, step_time_s = 0.0, tail_s = 0.0;
  double friction_spread = 0.0, gain_spread = 0.0, bench_spread = 0.0, bench_null_offset_within_v = 0.0;
  bool supervised = false, identify = false, online = false, hold_enabled = false;
  double hold_window_m = 0.0;
};

struct SummaryStops {
  std::uint64_t count = 0, restarts = 0, restarts_after_0_5_s = 0, restarts_after_1_s = 0,
                restarts_below_motion_band = 0, plant_not_at_rest = 0, before_learning = 0;
  SummaryPercentiles start_before_breakaway_ms, start_after_breakaway_ms, start_gap_ms;
};

struct SummaryOutcome {
  std::uint64_t count = 0;
  double y0_min_m = 0.0, y0_max_m = 0.0, y_d_min_m = 0.0, y_d_max_m = 0.0;
  std::uint64_t settling_rules_would_latch = 0;
};

struct SummaryInWindow {
  double window_m = 0.0;
  SummaryPercentiles after_s;
  std::uint64_t never = 0;
  double all_p50_s = 0.0, all_p90_s = 0.0;
};

struct SummaryHold {
  bool enabled = false;
  std::uint64_t began = 0, restarts_after = 0, scenarios_restarted_after = 0, held_forecasts = 0,
                held_restart_forecasts = 0;
  SummaryPercentiles reach_forecast_error_ms;
  std::uint64_t reach_forecasts_within_1_ms = 0, reach_forecasts_within_2_ms = 0, reach_forecasts_within_5_ms = 0,
                reaches_forecast_none = 0;
};

struct SummarySettlingRules {
  bool checked_alongside = false;
  std::uint64_t sign_changes = 0;
  double amplitude_m = 0.0, window_s = 0.0, settle_time_s = 0.0;
  SummaryPercentiles would_latch_after_s;
};

struct SummaryKeyTally {
  std::uint64_t published = 0, within_3_sigma = 0;
};

struct SummaryIdentification {
  std::uint64_t identified_and_run = 0;
  std::vector<std::string> failed;
  SummaryPercentiles static_positive_error_percent, static_negative_error_percent, null_pressure_error_pa,
      residual_in_noise;
  std::uint64_t fits = 0, published = 0, within_3_sigma = 0;
  std::vector<std::pair<std::string, SummaryKeyTally>> by_key;
  std::vector<std::string> outside;
  SummaryPercentiles heat_transfer_error_percent, spool_lag_error_ms;
};

struct SummarySplit {
  std::uint64_t stops = 0, wrong = 0, long_restarts = 0;
  SummaryWithin long_within{};
};

struct SummaryHalfway {
  std::uint64_t restarts = 0;
  SummaryPercentiles error_percent;
  SummaryWithin within{};
  std::uint64_t wrong_direction = 0, forecast_none = 0, restart_after_run = 0, no_forecast = 0;
};

struct SummaryMethod {
  std::uint64_t judged = 0, true_restart = 0, true_no_restart = 0, false_restart = 0, missed_restart = 0,
                not_judged = 0, wrong_direction = 0, outside_criteria = 0;
  SummaryPercentiles long_error_percent;
  SummaryWithin long_within{};
  SummaryPercentiles short_error_ms;
  SummaryHalfway halfway;
  SummarySplit online_unidentified_bound, online_slow_side;
};

struct SummaryMethods {
  SummaryMethod linearized, nonlinear, relaxation;
};

/// The sweep's summary.
struct SweepSummary {
  std::uint64_t scenarios = 0, scenarios_run = 0;
  SummarySetting setting;
  SummaryStops stops;
  std::vector<std::pair<std::string, SummaryOutcome>> outcomes;  ///< every outcome, in order
  std::vector<std::pair<std::string, std::uint64_t>> faults_by_cause;  ///< the causes met, in order
  SummaryPercentiles settle_time_s, final_error_m;
  SummaryInWindow in_window;
  SummaryHold hold;
  SummarySettlingRules settling_rules;
  bool identified = false;  ///< --identify: `identification` is written
  SummaryIdentification identification;
  SummaryMethods methods;
  double wall_s = 0.0;
  std::uint64_t jobs = 0;
};

}  // namespace pneu::sweep

template <>
struct pneu::records::Description<pneu::sweep::SummaryPercentiles> {
  using R = pneu::sweep::SummaryPercentiles;
  static constexpr const char* kName = "percentiles";
  static constexpr const char* kDoc = "percentiles of count values (null when none; never: null for infinity)";
  static constexpr auto kFields = std::tuple{
      field("count", &R::count, "", "how many values"),
      field("p50", &R::p50, "", "median"),
      field("p90", &R::p90, "", "90th percentile"),
      field("p99", &R::p99, "", "99th percentile"),
      field("max", &R::max, "", "largest"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummarySetting> {
  using R = pneu::sweep::SummarySetting;
  static constexpr const char* kName = "setting";
  static constexpr const char* kDoc = "what was swept";
  static constexpr auto kFields = std::tuple{
      field("seed", &R::seed, "", "--seed"),
      field("targets_lo_m", &R::targets_lo_m, "m", "the targets' range: lowest"),
      field("targets_hi_m", &R::targets_hi_m, "m", "the targets' range: highest"),
      field("duration_s", &R::duration_s, "s", "--duration"),
      field("step_time_s", &R::step_time_s, "s", "--step-time"),
      field("tail_s", &R::tail_s, "s", "--tail"),
      field("friction_spread", &R::friction_spread, "", "--friction-spread"),
      field("gain_spread", &R::gain_spread, "", "--gain-spread"),
      field("bench_spread", &R::bench_spread, "", "--bench-spread"),
      field("bench_null_offset_within_v", &R::bench_null_offset_within_v, "V", "the benches' null offsets within +-"),
      field("supervised", &R::supervised, "", "--supervised"),
      field("identify", &R::identify, "", "--identify"),
      field("online", &R::online, "", "--online"),
      field("hold_enabled", &R::hold_enabled, "", "controller.hold.enabled"),
      field("hold_window_m", &R::hold_window_m, "m", "controller.hold.window_m"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryStops> {
  using R = pneu::sweep::SummaryStops;
  static constexpr const char* kName = "stops";
  static constexpr const char* kDoc = "the judged window's stops";
  static constexpr auto kFields = std::tuple{
      field("count", &R::count, "", "stops"),
      field("restarts", &R::restarts, "", "restarts"),
      field("restarts_after_0_5_s", &R::restarts_after_0_5_s, "", "restarts after 0.5 s or more stuck"),
      field("restarts_after_1_s", &R::restarts_after_1_s, "", "restarts after 1 s or more stuck"),
      field("restarts_below_motion_band", &R::restarts_below_motion_band, "", "true restarts the stop detector did not see"),
      field("plant_not_at_rest", &R::plant_not_at_rest, "", "confirmed while the plant slid: not judged"),
      field("before_learning", &R::before_learning, "", "--online: before the bench's 3rd restart"),
      group("start_before_breakaway_ms", &R::start_before_breakaway_ms, "",
            "the detector's start before the plant's breakaway [ms]"),
      group("start_after_breakaway_ms", &R::start_after_breakaway_ms, "",
            "the detector's start at or after the plant's breakaway [ms]"),
      group("start_gap_ms", &R::start_gap_ms, "", "|the detector's start minus the plant's breakaway| [ms]"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryOutcome> {
  using R = pneu::sweep::SummaryOutcome;
  static constexpr const char* kName = "outcome";
  static constexpr const char* kDoc = "the scenarios of one outcome";
  static constexpr auto kFields = std::tuple{
      field("count", &R::count, "", "scenarios"),
      field("y0_min_m", &R::y0_min_m, "m", "lowest start"),
      field("y0_max_m", &R::y0_max_m, "m", "highest start"),
      field("y_d_min_m", &R::y_d_min_m, "m", "lowest target"),
      field("y_d_max_m", &R::y_d_max_m, "m", "highest target"),
      field("settling_rules_would_latch", &R::settling_rules_would_latch, "", "in how many the settling rules would latch"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryInWindow> {
  using R = pneu::sweep::SummaryInWindow;
  static constexpr const char* kName = "in_window";
  static constexpr const char* kDoc = "the first rest within controller.hold.window_m, from the step";
  static constexpr auto kFields = std::tuple{
      field("window_m", &R::window_m, "m", "controller.hold.window_m"),
      group("after_s", &R::after_s, "", "over those that came there [s]"),
      field("never", &R::never, "", "those that never did"),
      field("all_p50_s", &R::all_p50_s, "s", "over all run, never counted as infinity (null: never)"),
      field("all_p90_s", &R::all_p90_s, "s", "over all run, never counted as infinity (null: never)"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryHold> {
  using R = pneu::sweep::SummaryHold;
  static constexpr const char* kName = "hold";
  static constexpr const char* kDoc = "the in-position hold";
  static constexpr auto kFields = std::tuple{
      field("enabled", &R::enabled, "", "controller.hold.enabled"),
      field("began", &R::began, "", "holds begun"),
      field("restarts_after", &R::restarts_after, "", "restarts after a hold"),
      field("scenarios_restarted_after", &R::scenarios_restarted_after, "", "scenarios that restarted after a hold"),
      field("held_forecasts", &R::held_forecasts, "", "forecasts made under the hold"),
      field("held_restart_forecasts", &R::held_restart_forecasts, "", "of them, forecasting a restart"),
      group("reach_forecast_error_ms", &R::reach_forecast_error_ms, "",
            "|error| of each reach's forecast against the start seen [ms]"),
      field("reach_forecasts_within_1_ms", &R::reach_forecasts_within_1_ms, "", "reach forecasts within 1 ms"),
      field("reach_forecasts_within_2_ms", &R::reach_forecasts_within_2_ms, "", "reach forecasts within 2 ms"),
      field("reach_forecasts_within_5_ms", &R::reach_forecasts_within_5_ms, "", "reach forecasts within 5 ms"),
      field("reaches_forecast_none", &R::reaches_forecast_none, "", "reaches for which it forecast none"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummarySettlingRules> {
  using R = pneu::sweep::SummarySettlingRules;
  static constexpr const char* kName = "settling_rules";
  static constexpr const char* kDoc = "the supervisor's settling rules (controller.supervisor.oscillation_*, settle_time_s)";
  static constexpr auto kFields = std::tuple{
      field("checked_alongside", &R::checked_alongside, "", "checked alongside (not supervised, and some rule on)"),
      field("sign_changes", &R::sign_changes, "", "controller.supervisor.oscillation_sign_changes"),
      field("amplitude_m", &R::amplitude_m, "m", "controller.supervisor.oscillation_amplitude_m"),
      field("window_s", &R::window_s, "s", "controller.supervisor.oscillation_window_s"),
      field("settle_time_s", &R::settle_time_s, "s", "controller.supervisor.settle_time_s"),
      group("would_latch_after_s", &R::would_latch_after_s, "", "when they would latch, from the step [s]"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryKeyTally> {
  using R = pneu::sweep::SummaryKeyTally;
  static constexpr const char* kName = "key_tally";
  static constexpr const char* kDoc = "one identified parameter over the benches";
  static constexpr auto kFields = std::tuple{
      field("published", &R::published, "", "benches it was published for"),
      field("within_3_sigma", &R::within_3_sigma, "", "of them, within 3 sigma of the bench's"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryIdentification> {
  using R = pneu::sweep::SummaryIdentification;
  static constexpr const char* kName = "identification";
  static constexpr const char* kDoc = "--identify: what was identified against each bench";
  static constexpr auto kFields = std::tuple{
      field("identified_and_run", &R::identified_and_run, "", "scenarios identified and run"),
      field("failed", &R::failed, "", "\"scenario I: reason\", in order"),
      group("static_positive_error_percent", &R::static_positive_error_percent, "", "F_S+ error [%]"),
      group("static_negative_error_percent", &R::static_negative_error_percent, "", "F_S- error [%]"),
      group("null_pressure_error_pa", &R::null_pressure_error_pa, "", "p_null(u) over |u| < 1 V, largest error [Pa]"),
      group("residual_in_noise", &R::residual_in_noise, "", "the pressure residual in what the noise explains"),
      field("fits", &R::fits, "", "residuals within twice the noise"),
      field("published", &R::published, "", "parameters published that the bench has too"),
      field("within_3_sigma", &R::within_3_sigma, "", "of them, within 3 sigma"),
      field("by_key", &R::by_key, "", "each parameter by its config key, in the order first met"),
      field("outside", &R::outside, "", "\"scenario I: key X sigma; ...\""),
      group("heat_transfer_error_percent", &R::heat_transfer_error_percent, "", "the walls' heat transfer error [%]"),
      group("spool_lag_error_ms", &R::spool_lag_error_ms, "", "the spool lag's error [ms]"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummarySplit> {
  using R = pneu::sweep::SummarySplit;
  static constexpr const char* kName = "split";
  static constexpr const char* kDoc = "--online: a subset of the judged stops";
  static constexpr auto kFields = std::tuple{
      field("stops", &R::stops, "", "judged stops"),
      field("wrong", &R::wrong, "", "wrong verdicts"),
      field("long_restarts", &R::long_restarts, "", "restarts after 0.5 s or more stuck"),
      field("long_within", &R::long_within, "", "of them, forecast within 2, 5, 10 % of the sticking time")
          .indexed(pneu::sweep::kWithinPercent, ""),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryHalfway> {
  using R = pneu::sweep::SummaryHalfway;
  static constexpr const char* kName = "halfway";
  static constexpr const char* kDoc = "the long restarts' forecasts made again half-way (not judged)";
  static constexpr auto kFields = std::tuple{
      field("restarts", &R::restarts, "", "the long restarts"),
      group("error_percent", &R::error_percent, "", "the timed ones' errors [% of the sticking time]"),
      field("within", &R::within, "", "within 2, 5, 10 %").indexed(pneu::sweep::kWithinPercent, ""),
      field("wrong_direction", &R::wrong_direction, "", "timed in the wrong direction"),
      field("forecast_none", &R::forecast_none, "", "forecast none"),
      field("restart_after_run", &R::restart_after_run, "", "forecast after the run"),
      field("no_forecast", &R::no_forecast, "", "none made by half-way"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryMethod> {
  using R = pneu::sweep::SummaryMethod;
  static constexpr const char* kName = "method";
  static constexpr const char* kDoc = "one method's forecasts over the sweep";
  static constexpr auto kFields = std::tuple{
      field("judged", &R::judged, "", "forecasts made at the stop, judged"),
      field("true_restart", &R::true_restart, "", "restart forecast, and it restarted"),
      field("true_no_restart", &R::true_no_restart, "", "none forecast, and it stayed"),
      field("false_restart", &R::false_restart, "", "restart forecast, and it stayed"),
      field("missed_restart", &R::missed_restart, "", "none forecast, and it restarted"),
      field("not_judged", &R::not_judged, "", "not judged"),
      field("wrong_direction", &R::wrong_direction, "", "among the true restarts"),
      field("outside_criteria", &R::outside_criteria, "", "the acceptance criteria missed"),
      group("long_error_percent", &R::long_error_percent, "",
            "true restarts after 0.5 s or more stuck [% of the sticking time]"),
      field("long_within", &R::long_within, "", "of them, within 2, 5, 10 %").indexed(pneu::sweep::kWithinPercent, ""),
      group("short_error_ms", &R::short_error_ms, "", "the shorter ones, |error| [ms]"),
      group("halfway", &R::halfway, "", "the forecasts made again half-way"),
      group("online_unidentified_bound", &R::online_unidentified_bound, "",
            "--online: forecast on a stiction bound not identified yet"),
      group("online_slow_side", &R::online_slow_side, "", "--online: on a side the bench had broken away to slowly"),
  };
};

template <>
struct pneu::records::Description<pneu::sweep::SummaryMethods> {
  using R = pneu::sweep::SummaryMethods;
  static constexpr const char* kName = "methods";
  static constexpr const char* kDoc = "each method's forecasts";
  static constexpr auto kFields = std::tuple{
      group("linearized", &R::linearized, "", "the linearized method"),
      group("nonlinear", &R::nonlinear, "", "the nonlinear method"),
      group("relaxation", &R::relaxation, "", "the relaxation fit (made again only)"),
  };
};

/// The sweep's summary (pneu-sweep --summary-json).
template <>
struct pneu::records::Description<pneu::sweep::SweepSummary> {
  using R = pneu::sweep::SweepSummary;
  static constexpr const char* kName = "sweep_summary";
  static constexpr const char* kDoc = "the sweep's summary (pneu-sweep --summary-json)";
  static constexpr auto kFields = std::tuple{
      field("scenarios", &R::scenarios, "", "scenarios drawn"),
      field("scenarios_run", &R::scenarios_run, "", "all but those whose identification failed"),
      group("setting", &R::setting, "", "what was swept"),
      group("stops", &R::stops, "", "the judged window's stops"),
      field("outcomes", &R::outcomes, "", "the scenarios by outcome (settled, never_settled, end_stop, fault)"),
      field("faults_by_cause", &R::faults_by_cause, "", "faults latched, by cause (the causes met)"),
      group("settle_time_s", &R::settle_time_s, "", "over the settled ones [s]"),
      group("final_error_m", &R::final_error_m, "", "over the settled ones [m]"),
      group("in_window", &R::in_window, "", "the first rest within controller.hold.window_m"),
      group("hold", &R::hold, "", "the in-position hold"),
      group("settling_rules", &R::settling_rules, "", "the supervisor's settling rules"),
      group("identification", &R::identification, "", "--identify only: what was identified against each bench")
          .when(+[](const R& r) { return r.identified; }),
      group("methods", &R::methods, "", "each method's forecasts"),
      field("wall_s", &R::wall_s, "s", "wall time"),
      field("jobs", &R::jobs, "", "threads"),
  };
};
