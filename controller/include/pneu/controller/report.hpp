// The non-real-time side of a run: drains the loop's records, runs the restart predictors at each
// stop, writes the events (JSON lines) and the trajectory, and judges each forecast at the end.
#pragma once

#include <cstdio>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "pneu/controller/clock.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"

namespace pneu::controller {

/// One sticking phase, what was forecast at its start and what happened.
struct StopOutcome {
  std::uint64_t index = 0;
  double t_stop_s = 0.0;           ///< the stop event's time
  double y_stop_m = 0.0;
  double force_n = 0.0;            ///< F at confirmation
  double y_d_m = 0.0;
  StopSnapshot snapshot;
  std::optional<Prediction> linearized;
  std::optional<Prediction> nonlinear;
  bool ended = false;              ///< the carriage left rest before the run ended
  bool restarted = false;          ///< ... and the set point had not changed (a true restart)
  double t_end_s = 0.0;            ///< the start's time, or the run's end
  int direction = 0;               ///< of the start

  [[nodiscard]] double sticking_s() const noexcept { return t_end_s - t_stop_s; }
};

/// How a forecast compares with what happened (stops ended by a set-point change are not judged).
struct Verdict {
  enum class Kind { kTruePositive, kTrueNegative, kFalsePositive, kFalseNegative, kNotJudged };
  Kind kind = Kind::kNotJudged;
  double error_s = 0.0;       ///< predicted minus actual restart time (true positives) [s]
  double error_percent = 0.0; ///< |error| in percent of the sticking duration
  bool direction_ok = true;
};
/// How far before the end of a run a forecast restart must lie to be judged: max(10 ms, 1 % of the
/// sticking time), the acceptance tolerance.
[[nodiscard]] double observation_tolerance_s(const StopOutcome& stop) noexcept;
/// Stops ended by a set-point change, and restart forecasts within observation_tolerance_s() of
/// the end of the run, are not judged.
[[nodiscard]] Verdict judge(const StopOutcome& stop, const Prediction& prediction, double t_end_s) noexcept;

/// Receives what the report drains, in order, on the non-real-time side (LCM telemetry).
class ReportListener {
 public:
  virtual ~ReportListener() = default;
  virtual void on_tick(const TickRecord& record) = 0;
  virtual void on_event(const LoopEvent& event) = 0;
  virtual void on_prediction(const StopOutcome& stop, const Prediction& prediction) = 0;
  virtual void on_health(const HealthRecord& health) = 0;
  virtual void on_end(double t_end_s) = 0;
};

class RunReport {
 public:
  /// `events` (JSON lines) and `trajectory` (CSV) may be null.
  RunReport(const PredictorModel& model, bool linearized, bool nonlinear, std::ostream* events,
            std::ostream* trajectory);

  /// Forwards everything drained to `listener` (may be null; must outlive the report).
  void set_listener(ReportListener* listener) noexcept { listener_ = listener; }

  /// Pops everything the loop queued. Not real-time: call from the service thread or between
  /// simulated ticks.
  void drain(LoopOutputs& outputs);
  /// Closes the run at `t_end_s`.
  void finish(double t_end_s);

  [[nodiscard]] const std::vector<StopOutcome>& stops() const noexcept { return stops_; }
  [[nodiscard]] double end_time_s() const noexcept { return t_end_s_; }
  /// The faults latched during the run (kind kFault events), in order.
  [[nodiscard]] const std::vector<LoopEvent>& faults() const noexcept { return faults_; }
  [[nodiscard]] std::uint64_t ticks_seen() const noexcept { return ticks_seen_; }
  [[nodiscard]] std::uint64_t sequence_gaps() const noexcept { return sequence_gaps_; }
  /// The readable end-of-run summary.
  void print_summary(std::FILE* out, const LoopTiming& timing) const;

 private:
  void on_event(const LoopEvent& e);
  void write_prediction(const StopOutcome& s, const Prediction& p);

  PredictorModel model_;
  bool linearized_, nonlinear_;
  std::ostream* events_;
  std::ostream* trajectory_;
  ReportListener* listener_ = nullptr;
  std::vector<StopOutcome> stops_;
  std::vector<LoopEvent> faults_;  // the faults latched, for the summary
  double t_end_s_ = 0.0;
  std::uint64_t ticks_seen_ = 0;
  std::uint64_t next_seq_ = 0;
  std::uint64_t sequence_gaps_ = 0;
};

}  // namespace pneu::controller
