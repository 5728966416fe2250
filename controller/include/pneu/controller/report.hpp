// The non-real-time side of a run: drains the loop's records, runs the restart predictors at each
// stop, follows their forecasts against the measurements while the carriage stays stuck and makes
// them again from the pressures of the moment, writes the events (JSON lines) and the trajectory,
// and judges each forecast made at a stop at the end.
#pragma once

#include <algorithm>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/controller/clock.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/stop_outcome.hpp"
#include "pneu/controller/verdict.hpp"

namespace pneu::controller {

/// A command's verdict, as the command channel (telemetry::LcmBridge) gave it: written to the
/// events file as a "command" event. The strings are borrowed for the call.
struct CommandRecord {
  bool accepted = false;
  /// Rejected: why, in a word (malformed, oversized, foreign, stale, sequence, invalid, rate,
  /// mode, queue_full); accepted: empty.
  std::string_view reason;
  /// Whether the datagram decoded as a command_t: else `kind`, `seq` and `value` are unknown.
  bool decoded = false;
  std::string_view kind;       ///< set_point, set_point_step, arm, disarm, fault_reset, unknown
  std::int64_t seq = 0;        ///< command_t.seq
  double value = std::numeric_limits<double>::quiet_NaN();  ///< command_t.value as sent [m]
  std::string_view text;       ///< what was done, or why not, for people
};

/// Receives what the report drains, in order, on the non-real-time side (LCM telemetry).
class ReportListener {
 public:
  virtual ~ReportListener() = default;
  virtual void on_tick(const TickRecord& record) = 0;
  virtual void on_event(const LoopEvent& event) = 0;
  virtual void on_prediction(const StopOutcome& stop, const Prediction& prediction) = 0;
  virtual void on_reforecast(const StopOutcome& stop, const Reforecast& reforecast) = 0;
  virtual void on_health(const HealthRecord& health) = 0;
  virtual void on_end(double t_end_s) = 0;
};

class RunReport {
 public:
  /// `events` (JSON lines) and `trajectory` (CSV) may be null. While stuck, the forecasts are
  /// made again every `update_period_s` (0: only at the stop).
  RunReport(const PredictorModel& model, bool linearized, bool nonlinear, std::ostream* events,
            std::ostream* trajectory, double update_period_s = 0.0);

  /// Whether each forecast made at a stop is followed tick by tick against the measured force
  /// (the trajectory's forecast columns, the gaps of StopOutcome; on by default). The forecasts
  /// made again every update period do not depend on it.
  void set_follow_forecasts(bool on) noexcept { follow_ = on; }
  /// Whether each stop keeps its forecasts made again after it ended (tests, the sweep); else
  /// only its half-way ones, so that a daemon's memory does not grow with the time spent at rest.
  void set_keep_reforecasts(bool on) noexcept { keep_reforecasts_ = on; }
  /// The law the loop runs: the forecasts made again while stuck then take u* (Eq. 11) at the
  /// mean position read since the stop, not at the one sample the stop's snapshot had. With a
  /// quantised or noisy potentiometer the reading toggles between codes while the carriage is
  /// still, the law's output with it, and the valves follow the mean.
  void set_control_law(const ControlLaw& law) noexcept { law_ = law; }
  /// Forwards everything drained to `listener` (may be null; must outlive the report).
  void set_listener(ReportListener* listener) noexcept { listener_ = listener; }

  /// Pops everything the loop queued, each event before the record of the tick that raised it,
  /// so that the result does not depend on how often it is called. Not real-time: call from the
  /// service thread or between simulated ticks.
  void drain(LoopOutputs& outputs);
  /// Closes the run at `t_end_s`.
  void finish(double t_end_s);
  /// Writes a command's verdict to the events file, dated by the last tick drained. Not
  /// real-time, not thread-safe: call from the thread that drains (the service thread).
  void record_command(const CommandRecord& command);

  /// The stops of the run, the last max_stops_kept of them (kMaxStopsKept unless set; at least 4).
  [[nodiscard]] const std::vector<StopOutcome>& stops() const noexcept { return stops_; }
  [[nodiscard]] std::uint64_t stops_forgotten() const noexcept { return stops_forgotten_; }
  static constexpr std::size_t kMaxStopsKept = 4096;
  void set_max_stops_kept(std::size_t n) noexcept { max_stops_kept_ = std::max<std::size_t>(n, 4); }
  [[nodiscard]] double end_time_s() const noexcept { return t_end_s_; }
  /// The faults latched during the run (kind kFault events), in order.
  [[nodiscard]] const std::vector<LoopEvent>& faults() const noexcept { return faults_; }
  [[nodiscard]] std::uint64_t ticks_seen() const noexcept { return ticks_seen_; }
  [[nodiscard]] std::uint64_t sequence_gaps() const noexcept { return sequence_gaps_; }
  /// The readable end-of-run summary.
  void print_summary(std::FILE* out, const LoopTiming& timing) const;

 private:
  void on_tick(const TickRecord& r);
  void print_live_summary(std::FILE* out) const;
  void on_event(const LoopEvent& e);
  void write_prediction(const StopOutcome& s, const Prediction& p);
  void reforecast(StopOutcome& s, const TickRecord& r, const ForecastPoint (&expected)[2]);
  void settle(StopOutcome& s) const;

  // The forecasts of the open stop, followed while they hold.
  struct Following {
    std::optional<ForecastTrack> tracks[2];  // linearized, nonlinear
    double next_update_s = 0.0;
    double sum_y_m = 0.0;      // readings since the snapshot, for u*
    std::uint64_t readings = 0;
    std::uint32_t stride = 1;  // updates kept: every stride-th (thinned beyond kMaxReforecastsKept)
  };

  PredictorModel model_;
  bool linearized_, nonlinear_;
  double update_period_s_;
  bool follow_ = true;
  bool keep_reforecasts_ = false;
  std::uint64_t stops_forgotten_ = 0;
  std::size_t max_stops_kept_ = kMaxStopsKept;
  std::ostream* events_;
  std::ostream* trajectory_;
  ReportListener* listener_ = nullptr;
  std::optional<ControlLaw> law_;
  std::vector<StopOutcome> stops_;
  std::optional<Following> following_;
  std::vector<LoopEvent> faults_;  // the faults latched, for the summary
  double t_end_s_ = 0.0;
  std::uint64_t ticks_seen_ = 0;
  std::uint64_t next_seq_ = 0;
  std::uint64_t sequence_gaps_ = 0;
};

}  // namespace pneu::controller
