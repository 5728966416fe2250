// The sweep's results aggregated into statistics (aggregate): the figures its summary prints and
// its --summary-json writes (report.hpp), each computed once, here.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "pneu/sweep/run.hpp"
#include "pneu/sweep/scenario.hpp"

namespace pneu::config {
struct Config;
}

namespace pneu::sweep {

/// The supervisor's settling rules (controller.supervisor.oscillation_*, settle_time_s).
struct SettlingRules {
  unsigned sign_changes = 0;
  double amplitude_m = 0.0, window_s = 0.0, settle_time_s = 0.0;
};

/// What of the options and the configuration the statistics state.
struct Setting {
  Options options;
  TargetRange targets;
  double hold_window_m = 0.0;  ///< controller.hold.window_m
  bool hold_enabled = false;   ///< controller.hold.enabled
  SettlingRules settling_rules;  ///< as configured: checked alongside unless options.supervised
  /// The methods that forecast half-way (made again: controller.predictor.update_period_s > 0):
  /// linearized, nonlinear, relaxation.
  std::array<bool, kMethodCount> halfway_enabled{};
  /// The linearized method's name in the summary: its slope named unless the paper's.
  std::string linearized_name = "linearized";
};
/// The setting of a sweep of `options` on `config` (as loaded).
[[nodiscard]] Setting setting_of(const config::Config& config, const Options& options);

/// Linear interpolation between the order statistics; towards an infinity ("never"): infinity;
/// NaN when empty.
[[nodiscard]] double percentile(std::vector<double> values, double q);

/// Percentiles of `count` values (NaN when none).
struct Percentiles {
  std::size_t count = 0;
  double p50 = NAN, p90 = NAN, p99 = NAN, max = NAN;
};
[[nodiscard]] Percentiles percentiles_of(const std::vector<double>& values);

/// How many values are within 2, 5 and 10 (% of the sticking time).
using Within2510 = std::array<std::size_t, 3>;
[[nodiscard]] Within2510 within_2_5_10(const std::vector<double>& errors_pct);

/// A subset of the judged stops (--online): how many, the wrong verdicts among them, and their
/// restarts after kLongSticking_s or more: how many, and within 2 / 5 / 10 %.
struct Split {
  std::uint64_t stops = 0, wrong = 0;
  std::size_t long_restarts = 0;
  Within2510 long_within{};
};

/// One method's forecasts over the sweep.
struct MethodStatistics {
  // The verdicts on the forecasts made at the stop.
  std::uint64_t true_restart = 0, true_no_restart = 0, false_restart = 0, missed_restart = 0, not_judged = 0;
  std::uint64_t wrong_direction = 0;    ///< among the true restarts
  std::uint64_t outside_criteria = 0;   ///< the acceptance criteria missed
  Percentiles long_error_percent;       ///< true restarts after >= kLongSticking_s [% of the sticking time]
  Within2510 long_within{};
  Percentiles short_error_ms;           ///< the shorter ones, |error| [ms]
  /// The long restarts' forecasts made again half-way (the live predictor; not judged): the
  /// errors of the timed ones [%], within 2 / 5 / 10 %; and of those restarts, how many it forecast
  /// none, forecast after the run, made none by half-way, and timed in the wrong direction.
  Percentiles halfway_error_percent;
  Within2510 halfway_within{};
  std::uint64_t halfway_none = 0, halfway_after_run = 0, halfway_missing = 0, halfway_wrong_direction = 0;
  Split unidentified_bound;  ///< --online: forecast on a stiction bound not identified yet
  Split slow_side;           ///< --online: on a side the bench had broken away to slowly
  [[nodiscard]] std::uint64_t judged() const noexcept {
    return true_restart + true_no_restart + false_restart + missed_restart;
  }
  [[nodiscard]] std::uint64_t wrong() const noexcept { return false_restart + missed_restart; }
  /// The half-way figures' restarts (the long restarts, when the method forecasts half-way).
  [[nodiscard]] std::uint64_t halfway_restarts() const noexcept {
    return halfway_error_percent.count + halfway_none + halfway_after_run + halfway_missing;
  }
};

/// The scenarios of one outcome.
struct OutcomeStatistics {
  std::uint64_t count = 0;
  double y0_min_m = NAN, y0_max_m = NAN, y_d_min_m = NAN, y_d_max_m = NAN;  ///< where they lie
  std::size_t settling_rules_latched = 0;  ///< in how many the settling rules would latch
};

/// --identify: what was identified against each bench.
struct IdentificationStatistics {
  std::size_t identified_and_run = 0;
  std::vector<std::string> failures;  ///< "scenario I: reason", in order
  std::array<Percentiles, 2> stiction_error_percent;  ///< F_S+, F_S- (the scenarios run)
  Percentiles null_pressure_error_pa;                 ///< p_null(u) over |u| < 1 V, largest error
  Percentiles residual_ratio;  ///< the pressure residual in what the noise explains (every identified one)
  std::size_t fits = 0;        ///< ... within twice
  int published = 0, within_3_sigma = 0;  ///< parameters published that the bench has too
  std::vector<IdentifiedCheck::KeyTally> by_key;  ///< in the order first met
  std::vector<std::string> outside;               ///< "scenario I: key X sigma; ..."
  Percentiles heat_transfer_error_percent, spool_lag_error_ms;
};

/// The sweep's statistics.
struct Statistics {
  Setting setting;
  int scenarios = 0;
  std::size_t scenarios_run = 0;  ///< all but those whose identification failed
  // The judged window's stops.
  std::uint64_t stops = 0, restarts = 0, long_restarts = 0, restarts_after_1_s = 0;
  std::uint64_t restarts_below_motion_band = 0;  ///< true restarts the stop detector did not see
  std::uint64_t not_at_rest = 0;                 ///< confirmed while the plant slid: not judged
  std::uint64_t before_learning = 0;             ///< --online: before the bench's 3rd restart
  /// The detector's start minus the plant's breakaway over the starts it saw [ms]: before it
  /// (early) and at or after it (late), and |gap|.
  Percentiles start_early_ms, start_late_ms, start_gap_ms;
  std::array<OutcomeStatistics, std::size(kOutcomes)> outcomes;
  std::vector<std::uint64_t> faults_by_cause;  ///< indexed by controller::fault_number
  Percentiles settle_time_s, final_error_m;    ///< over the settled ones
  /// The first rest within controller.hold.window_m, from the step, over those that came there;
  /// those that never did; over all run, those counted as never (infinity).
  Percentiles in_window_after_s;
  std::size_t never_in_window = 0;
  double in_window_all_p50_s = NAN, in_window_all_p90_s = NAN;
  // The in-position hold.
  std::uint64_t held = 0, restarts_after_hold = 0, restarted_after_hold = 0;
  std::uint64_t held_forecasts = 0, held_restart_forecasts = 0, reaches_forecast_none = 0;
  Percentiles reach_forecast_error_ms;  ///< |error| of each reach's forecast against the start seen
  std::array<std::size_t, 3> reach_forecasts_within_1_2_5_ms{};
  bool settling_rules_checked = false;  ///< alongside (not supervised, and some rule on)
  Percentiles settling_rules_latched_after_s;
  IdentificationStatistics identification;  ///< --identify
  std::array<MethodStatistics, kMethodCount> methods;  ///< linearized, nonlinear, relaxation
  double wall_s = 0.0;
  int jobs = 1;
  /// Merged from this many shards (pneu-sweep merge; 0: one run): wall_s is then the shards' wall
  /// times summed, jobs the most threads a shard ran on.
  int shards = 0;

  [[nodiscard]] std::uint64_t count(Outcome o) const noexcept { return outcomes[static_cast<std::size_t>(o)].count; }
};

/// The statistics of `results` (in the scenarios' order).
[[nodiscard]] Statistics aggregate(const Setting& setting, std::span<const ScenarioResult> results);
/// ... and of a run_all's, its wall time and threads.
[[nodiscard]] Statistics aggregate(const Setting& setting, const SweepRun& run);

}  // namespace pneu::sweep
