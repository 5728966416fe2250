// What the non-real-time runtime (Runtime) emits, as typed records, and the one interface its
// sinks implement: the events file (EventsFile), the trajectory file (TrajectoryFile), LCM
// (telemetry::LcmBridge). Everything here runs on the non-real-time side (the service thread, or
// between simulated ticks), never on the loop thread.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string_view>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"

namespace pneu::controller {

/// What each forecast made at the open stop expects at a tick (ForecastTrack::at), while the
/// runtime follows it; NaN everywhere otherwise.
struct ExpectedAtTick {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  ForecastPoint linearized{kNaN, kNaN, kNaN};
  ForecastPoint nonlinear{kNaN, kNaN, kNaN};
};

/// A restart forecast: made at a stop (update 0) or made again while the carriage is still stuck
/// (update 1, 2, ...: the live predictor).
struct ForecastRecord {
  std::uint64_t stop = 0;      ///< the stop's index (from 1)
  double t_stop_s = 0.0;       ///< the stop event's time [s]
  std::uint32_t update = 0;    ///< 0: the forecast made at the stop
  double t_s = 0.0;            ///< the tick it was made from: the stop's snapshot for update 0 [s]
  double u_star_v = 0.0;       ///< the u* it assumed (Eq. 11) [V]
  double force_n = 0.0;        ///< F measured at t_s (update 0: at the stop's confirmation) [N]
  /// F the same method's forecast made at the stop expected at t_s (update 0: force_n; NaN when
  /// the runtime does not follow the forecasts) [N]
  double stop_forecast_force_n = std::numeric_limits<double>::quiet_NaN();
  Prediction prediction;
};

/// A command's verdict, as the command channel (telemetry::LcmBridge) gave it. The strings are
/// borrowed for the call.
struct CommandRecord {
  double t_s = 0.0;            ///< dated by the last tick drained (Runtime::record_command sets it) [s]
  bool accepted = false;
  /// Rejected: why, in a word (malformed, oversized, foreign, stale, sequence, invalid, rate,
  /// mode, queue_full); accepted: empty.
  std::string_view reason;
  /// Whether the datagram decoded as a command_t: else `kind`, `seq` and `value` are unknown.
  bool decoded = false;
  std::string_view kind;       ///< set_point, set_point_step, arm, disarm, fault_reset, hold_on, hold_off, unknown
  std::int64_t seq = 0;        ///< command_t.seq
  double value = std::numeric_limits<double>::quiet_NaN();  ///< command_t.value as sent [m]
  std::string_view origin;     ///< command_t.origin: who sent it, as it said (printable ASCII)
  std::int64_t session = 0;    ///< command_t.session: the sender's session, 0 for none
  std::string_view text;       ///< what was done, or why not, for people
};

/// The parameters online identification estimates, in the order of IdentificationRecord's
/// arrays (and of <prefix>IDENTIFICATION's): their config keys.
/// The wall's heat transfer and the spool lag are the model's only when it has them (plant.thermal,
/// a spool lag > 0): else never identified.
inline constexpr std::array<const char*, 13> kIdentifiedParameterKeys = {
    "plant.friction.static_positive_n",           "plant.friction.static_negative_n",
    "plant.friction.coulomb_positive_n",          "plant.friction.coulomb_negative_n",
    "plant.friction.viscous_n_s_per_m",           "plant.valve.max_conductance_m3_per_s_pa",
    "plant.valve.leak_conductance_in_m3_per_s_pa", "plant.valve.leak_conductance_out_m3_per_s_pa",
    "plant.valve.null_offset_v",                  "plant.geometry.dead_volume_p_m3",
    "plant.geometry.dead_volume_n_m3",            "plant.thermal.heat_transfer_w_per_m2_k",
    "plant.valve.spool_time_constant_s"};

/// The running estimate of online identification, after an update.
struct IdentificationRecord {
  double t_s = 0.0;               ///< the update's loop time [s]
  std::uint32_t updates = 0;      ///< updates since the start
  std::array<double, kIdentifiedParameterKeys.size()> value{};   ///< unit of the key
  std::array<double, kIdentifiedParameterKeys.size()> sigma{};   ///< 1 sigma; 0 when not identified
  std::array<bool, kIdentifiedParameterKeys.size()> identified{};
};

/// A new model of the bench for the forecasts, from what learns it while the run goes on (online
/// identification: identify::OnlineIdentifier), with what the sinks are told of it.
struct ModelUpdate {
  PredictorModel model;  ///< its valve is `valve`'s
  /// Owns model.valve: the runtime keeps it while the model is in use or a forecast made on it is
  /// followed, and lets it go after.
  std::shared_ptr<const model::ValveCharacteristic> valve;
  IdentificationRecord record;
};

/// What learns the bench while the run goes on: the runtime asks it for an update each time every
/// sink has had a record (Runtime::set_model_source), so that a sink never changes the runtime
/// while the runtime is handing it a record.
class ModelSource {
 public:
  virtual ~ModelSource() = default;
  /// The update made since the last call, if any (each once).
  [[nodiscard]] virtual std::optional<ModelUpdate> take_model_update() = 0;
  /// Whether an update for the event just handed (a stop's) is being made and is not ready yet
  /// (take_model_update() gave none): the runtime then waits for it before it acts on the event
  /// (Runtime::drain). None by default: a source that makes its update while it is handed the
  /// event has it ready when asked.
  [[nodiscard]] virtual bool update_coming() const { return false; }
  /// The runtime waited for the update update_coming() said was coming as long as it could
  /// (Runtime::kMaxTicksQueuedWaiting) and went on without it: the event's forecasts are made on
  /// the model in force. The update, once made, is still given by take_model_update(), and taken
  /// over from then on.
  virtual void update_late() {}
};

/// A sink of the runtime: receives, in order, what the runtime drains from the loop and what it
/// makes of it. For each tick: its events (each before the record of the tick that raised it; a
/// stop's event before its forecasts), then the tick, then the forecasts made again from it. Each
/// call is on the thread that drains; a sink does nothing it does not need (the defaults).
class RunListener {
 public:
  virtual ~RunListener() = default;
  /// A tick record, with what the forecasts made at the open stop expect at it.
  virtual void on_tick(const TickRecord& /*tick*/, const ExpectedAtTick& /*expected*/) {}
  /// A start, stop, fault, fault reset or refused reset, as the loop raised it.
  virtual void on_event(const LoopEvent& /*event*/) {}
  /// A forecast made at a stop (update 0) or again while stuck.
  virtual void on_forecast(const ForecastRecord& /*forecast*/) {}
  /// The loop's statistics of a health period.
  virtual void on_health(const HealthRecord& /*health*/) {}
  /// A command's verdict (Runtime::record_command).
  virtual void on_command(const CommandRecord& /*command*/) {}
  /// An update of online identification (a ModelSource's, as the runtime took it over).
  virtual void on_identification(const IdentificationRecord& /*record*/) {}
  /// The end of the run at `t_end_s`.
  virtual void on_end(double /*t_end_s*/) {}
};

}  // namespace pneu::controller
