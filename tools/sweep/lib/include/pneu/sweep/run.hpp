// One scenario run to a result value (run_scenario): identified first (--identify), designed, run
// in simulated time on its bench, its outcome and its stops judged against the simulated plant;
// and all of them on threads (run_all).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "pneu/controller/stop_outcome.hpp"
#include "pneu/controller/verdict.hpp"
#include "pneu/model/params.hpp"
#include "pneu/sweep/scenario.hpp"

namespace pneu::config {
struct Config;
}

namespace pneu::controller {
enum class FaultCause : std::uint8_t;
}

namespace pneu::sweep {

/// A restart counts as long after this much sticking: the acceptance criteria's split [s].
inline constexpr double kLongSticking_s = 0.5;
/// --online: a stop is judged once the scenario's bench has restarted this many times.
inline constexpr int kOnlineLearningRestarts = 3;

/// How a scenario ended up, from the first time the carriage came to rest after the step.
enum class Outcome : std::uint8_t { kSettled, kNeverSettled, kEndStop, kFault };
inline constexpr Outcome kOutcomes[] = {Outcome::kSettled, Outcome::kNeverSettled, Outcome::kEndStop, Outcome::kFault};
/// "settled", "never-settled", "end-stop", "fault" (the scenarios file's outcome column).
[[nodiscard]] const char* outcome_name(Outcome o) noexcept;

/// What became of the scenario after its step (times from the step; NaN: not applicable).
struct Settling {
  Outcome outcome = Outcome::kNeverSettled;
  double settle_time_s = NAN;     ///< the first rest after the step, before any fault
  double rest_y_m = NAN;          ///< ... its position
  double final_error_m = NAN;     ///< |y_d - y| at the end of the run
  controller::FaultCause fault{};  ///< the first fault latched (kNone: none)
  double fault_after_s = NAN;
  std::uint64_t stops = 0, restarts = 0;  ///< over the whole run, tail included
  bool at_rest_at_end = false;
  double last_second_swing_m = NAN;       ///< peak-to-peak position over the run's last second
  double oscillation_rule_after_s = NAN;  ///< when the settling rules checked alongside would latch
  /// The first rest within controller.hold.window_m that the plant confirms; the in-position
  /// hold's first start within the window; the plant's breakaways beyond the motion band after it.
  double in_window_after_s = NAN;
  double hold_after_s = NAN;
  std::uint64_t restarts_after_hold = 0;
  /// The forecasts under the hold's commands (method held, after the step): made while held within
  /// the window, and how many said restart; for each reach that broke away, the forecast made as
  /// it began against the start seen [ms]; the reaches it forecast no breakaway for.
  std::uint64_t held_forecasts = 0, held_restart_forecasts = 0;
  std::vector<double> reach_forecast_error_ms;
  std::uint64_t reaches_forecast_none = 0;
};

/// A stop against the plant's truth.
struct Truth {
  bool unseen = false;  ///< a true restart the stop detector did not see (below its motion band)
  /// --online: forecast on a stiction bound the running estimate had not identified (the side it
  /// forecast a restart towards, or the force relaxes towards): the configured one
  bool on_configured_bound = false;
  bool not_at_rest = false;     ///< the plant was sliding when the stop was confirmed: not judged
  double start_dating_s = NAN;  ///< the detector's start time minus the plant's breakaway, when it saw one
};

/// What happened after a stop, as the stops file's outcome column names it.
enum class StopFate : std::uint8_t { kBeforeLearning, kPlantNotAtRest, kStuckToEnd, kRestart, kSetpointChanged };
/// "before_learning", "plant_not_at_rest", "stuck_to_end", "restart", "setpoint_changed".
[[nodiscard]] const char* fate_name(StopFate f) noexcept;

/// One method's forecast made at the stop, judged (not judged when the stop is not).
struct JudgedForecast {
  controller::Prediction prediction;
  controller::Verdict verdict;
  bool within_criteria = true;  ///< the acceptance criteria: 1 % (nonlinear) / 5 % or 10 ms
};

/// The methods in the stops file's and the summary's order: linearized, nonlinear, relaxation
/// (which forecasts half-way only).
inline constexpr std::size_t kMethodCount = 3;

/// One stop of a scenario's judged window, its forecasts judged against the plant.
struct JudgedStop {
  controller::StopOutcome stop;  ///< as the plant's truth has it (its reforecasts dropped once judged)
  Truth truth;
  StopFate fate = StopFate::kStuckToEnd;
  std::array<std::optional<JudgedForecast>, 2> at_stop;  ///< linearized, nonlinear: none when not made
  /// A judged restart after kLongSticking_s or more stuck.
  bool long_restart = false;
  /// Of a long restart, each method's forecast made again half-way (the live predictor), judged:
  /// none when it made none by then.
  std::array<std::optional<controller::Verdict>, kMethodCount> halfway;
  /// --online: its forecast turns on a side the bench had broken away to after kLongSticking_s
  /// or more stuck earlier in the scenario.
  bool on_slow_side = false;
  [[nodiscard]] bool judged() const noexcept {
    return fate != StopFate::kBeforeLearning && fate != StopFate::kPlantNotAtRest;
  }
};

/// --identify: how the identification went against the scenario's bench.
struct IdentifiedCheck {
  double residual_pa = NAN, explained_pa = NAN;  ///< the valve fit's residual, and what the noise explains
  bool fits = true;
  /// The parameters it published (identified) that the bench has too, and those within 3 of their
  /// stated sigmas of the bench's value; the others named with their error in sigmas.
  int published = 0, within_3_sigma = 0;
  std::string outside;
  struct KeyTally {
    std::string key;
    int published = 0, within_3_sigma = 0;
  };
  std::vector<KeyTally> by_key;
  double null_pressure_error_pa = NAN;  ///< p_null(u) over |u| < 1 V, largest error against the bench
};

/// A scenario's result.
struct ScenarioResult {
  Scenario scenario;
  model::PlantParams bench;  ///< the simulated bench it ran (the model's plant: unless --bench-spread)
  std::optional<model::PlantParams> identified;  ///< --identify: the model the scenario ran on
  /// --identify: why it failed, or why its model could not run (the scenario did not run); empty: it ran
  std::string identification_failed;
  std::vector<JudgedStop> stops;  ///< those of the judged window (not the tail's)
  double t_end_s = 0.0;
  Settling settling;
  IdentifiedCheck check;  ///< --identify
  [[nodiscard]] bool ran() const noexcept { return identification_failed.empty(); }
};

/// Runs one scenario on `config` (as loaded: unless options.supervised, the supervisor's checks
/// are turned off here, its settling rules checked alongside). A scenario whose identification
/// fails, or whose identified model cannot be designed for, is returned with the reason; anything
/// else that goes wrong throws.
[[nodiscard]] ScenarioResult run_scenario(const config::Config& config, const Options& options, const Scenario& scenario);

/// The results of run_all, in the scenarios' order.
struct SweepRun {
  std::vector<ScenarioResult> results;
  double wall_s = 0.0;  ///< from the start to the last scenario done
  int jobs = 1;
};
/// Called about every 100 ms while run_all runs, and once all are done (done == total).
using ProgressFn = std::function<void(int done, int total, double elapsed_s)>;
/// run_scenario on each of `scenarios`, on `jobs` threads sharing them. Rethrows the first
/// exception a scenario threw, once all threads have ended.
[[nodiscard]] SweepRun run_all(const config::Config& config, const Options& options, std::span<const Scenario> scenarios,
                               int jobs, const ProgressFn& progress = {});

}  // namespace pneu::sweep
