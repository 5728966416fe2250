// The descriptions of the controller's records (pneu/records/record.hpp): the fields the outside
// world sees of each, in order, each spelled once. The trajectory file's columns, the events
// file's lines (views of the event line, the forecast, the command), the state_t, event_t,
// prediction_t, health_t and identification_t messages (their .lcm definitions are written from
// here at build time), pneu-log2csv's columns and the JSON Schemas all follow from them: a new
// field is one line here.
#pragma once

#include <array>
#include <cstdint>
#include <iterator>
#include <limits>
#include <string>
#include <tuple>
#include <utility>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/controller/summary_record.hpp"
#include "pneu/records/record.hpp"

namespace pneu::controller {

/// An event as event_t carries it: one flat message for every kind, what happened said for
/// people in `text` (event_message() makes it from a LoopEvent; the command channel's verdicts and
/// the end of the run are events of their own).
struct EventMessage {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::int8_t kind = 0;    ///< kEventKinds' numbers
  double t_s = 0.0;
  std::int64_t stop = 0;
  double y_m = kNaN;
  double force_n = kNaN;
  double y_d_m = kNaN;
  std::int8_t direction = 0;
  std::int64_t seq = 0;
  std::string origin;
  std::int64_t session = 0;
  std::string text;
};

/// event_t's kinds (KIND_*): their numbers on the wire, and names.
namespace event_kind {
inline constexpr std::int8_t kStart = 1, kRestart = 2, kStop = 3, kFault = 4, kCommandAccepted = 5,
                             kCommandRejected = 6, kEnd = 7, kFaultReset = 8, kFaultResetRefused = 9,
                             kHoldStart = 10, kHoldEnd = 11, kMovementTest = 12;
}  // namespace event_kind
inline constexpr records::Named<std::int8_t> kEventKinds[] = {
    {event_kind::kStart, event_kind::kStart, "start"},
    {event_kind::kRestart, event_kind::kRestart, "restart"},
    {event_kind::kStop, event_kind::kStop, "stop"},
    {event_kind::kFault, event_kind::kFault, "fault"},
    {event_kind::kCommandAccepted, event_kind::kCommandAccepted, "command_accepted"},
    {event_kind::kCommandRejected, event_kind::kCommandRejected, "command_rejected"},
    {event_kind::kEnd, event_kind::kEnd, "end"},
    {event_kind::kFaultReset, event_kind::kFaultReset, "fault_reset"},
    {event_kind::kFaultResetRefused, event_kind::kFaultResetRefused, "fault_reset_refused"},
    {event_kind::kHoldStart, event_kind::kHoldStart, "hold_start"},
    {event_kind::kHoldEnd, event_kind::kHoldEnd, "hold_end"},
    {event_kind::kMovementTest, event_kind::kMovementTest, "movement_test"},
};

/// The event_t message of a loop event.
[[nodiscard]] EventMessage event_message(const LoopEvent& e);

/// A line of the events file that a loop event (or the run's end) writes: every member any such
/// line has; the line's view (kEventLineViews) says which it writes, in which order.
struct EventLine {
  double t_s = 0.0;
  std::uint64_t stop = 0;
  bool restart = false;
  int direction = 0;
  const char* why = nullptr;
  double y_m = 0.0;
  double force_n = 0.0;
  double y_d_m = 0.0;
  int reach = 0;
  const char* end = nullptr;
  const char* finding = nullptr;
  int pulses = 0;
  double duration_s = 0.0;
  double y_start_m = 0.0;
  double y_end_m = 0.0;
  const char* cause = nullptr;
  std::string text;
  const char* key = nullptr;
};

/// The daemon's health as health_t carries it (telemetry::LcmBridge fills it about once a second).
struct HealthMessage {
  double t_s = 0.0;
  std::int8_t mode = 0;
  std::int64_t ticks = 0, overruns = 0;
  DurationsSummary wake_latency_us, compute_us;
  std::int64_t comms_errors = 0, telemetry_dropped = 0;
  std::int64_t commands_received = 0, commands_accepted = 0, commands_rejected = 0;
  std::int64_t rejected_malformed = 0, rejected_invalid = 0, rejected_rate = 0, rejected_mode = 0;
  std::int64_t rejected_sequence = 0, rejected_stale = 0, rejected_foreign = 0, rejected_oversized = 0;
  std::int64_t deadlines_skipped = 0;
  std::int8_t fault_cause = 0;
  std::int64_t faults = 0;
  bool is_final = false;
  std::string host;
  std::int32_t pid = 0;
  std::int64_t start_utime = 0, nonce = 0;
  double period_s = 0.0;
};

/// The methods of a forecast: their numbers on the wire (prediction_t's METHOD_*) and names.
inline constexpr records::Named<PredictionMethod> kPredictionMethods[] = {
    {PredictionMethod::kLinearized, 1, "linearized"},
    {PredictionMethod::kNonlinear, 2, "nonlinear"},
    {PredictionMethod::kRelaxation, 3, "relaxation"},
    {PredictionMethod::kHeld, 4, "held"},
};

/// A command's verdict in words.
inline constexpr records::Named<bool> kVerdicts[] = {{true, 1, "accepted"}, {false, 0, "rejected"}};

/// The parameters online identification estimates, as identification_t's arrays are indexed: each
/// named by its config key's last part (kIdentifiedParameterKeys), with the message's constant
/// for its index.
inline constexpr std::array<records::IndexName, kIdentifiedParameterKeys.size()> kIdentifiedParameters = [] {
  constexpr const char* kConstants[] = {
      "STATIC_POSITIVE_N", "STATIC_NEGATIVE_N", "COULOMB_POSITIVE_N", "COULOMB_NEGATIVE_N", "VISCOUS_N_S_PER_M",
      "MAX_CONDUCTANCE",   "LEAK_IN",           "LEAK_OUT",           "NULL_OFFSET_V",      "DEAD_VOLUME_P_M3",
      "DEAD_VOLUME_N_M3",  "HEAT_TRANSFER_W_PER_M2_K", "SPOOL_TIME_CONSTANT_S"};
  static_assert(std::size(kConstants) == kIdentifiedParameterKeys.size());
  std::array<records::IndexName, kIdentifiedParameterKeys.size()> table{};
  for (std::size_t i = 0; i < table.size(); ++i) table[i] = {records::last_part(kIdentifiedParameterKeys[i]), kConstants[i]};
  return table;
}();

/// The loop's modes as the messages name them (state_t's MODE_* constants).
inline constexpr std::pair<Mode, const char*> kModeNames[] = {
    {Mode::kDisarmed, "DISARMED"}, {Mode::kArmed, "ARMED"},  {Mode::kFault, "FAULT"},
    {Mode::kHold, "HOLD"},         {Mode::kMovementTest, "MOVEMENT_TEST"},
};

}  // namespace pneu::controller

/// One tick of the loop: the trajectory file's row, the state_t message.
template <>
struct pneu::records::Description<pneu::controller::TickRecord> {
  using R = pneu::controller::TickRecord;
  static constexpr const char* kName = "tick";
  static constexpr const char* kDoc = "one tick of the loop: the sample, the estimates, the control sent, the loop's state";
  static constexpr auto kFields = std::tuple{
      field("seq", &R::seq, "", "tick sequence number, from 0 at start-up, no gaps"),
      field("t", &R::t_s, "s", "loop time of the sample since start-up", 12),
      field("y_d", &R::y_d_m, "m", "set point, from mid-stroke"),
      field("y", &R::y_m, "m", "measured position, from mid-stroke", 12),
      field("v_hat", &R::v_hat_m_per_s, "m/s", "estimated velocity"),
      field("a_hat", &R::a_hat_m_per_s2, "m/s^2", "estimated acceleration"),
      field("p_p", &R::p_p_pa, "Pa", "chamber P pressure, absolute"),
      field("p_n", &R::p_n_pa, "Pa", "chamber N pressure, absolute"),
      field("force", &R::force_n, "N", "pressure force S_P p_P - S_N p_N - S_r p_E (Eq. 14)"),
      field("u", &R::u_v, "V", "control sent: u_P = u, u_N = -u"),
      field("stuck", &R::stuck, "", "the stop detector holds the carriage at rest"),
      field("mode", &R::mode, "", "the loop's mode: MODE_*"),
      field("validity", &R::sensor_validity, "", "sensor validity flags, 0 = all readings valid"),
  };
};

/// What a forecast made at the stop expects at a tick while the carriage is stuck: the trajectory
/// file's columns NAME_linearized and NAME_nonlinear (empty when there is none).
template <>
struct pneu::records::Description<pneu::controller::ForecastPoint> {
  using R = pneu::controller::ForecastPoint;
  static constexpr const char* kName = "expected";
  static constexpr const char* kDoc = "what a forecast made at the stop expects at this tick";
  static constexpr auto kFields = std::tuple{
      field("p_p", &R::p_p_pa, "Pa", "chamber P pressure expected, absolute"),
      field("p_n", &R::p_n_pa, "Pa", "chamber N pressure expected, absolute"),
      field("force", &R::force_n, "N", "pressure force expected (Eq. 14)"),
  };
};

/// An event as event_t carries it.
template <>
struct pneu::records::Description<pneu::controller::EventMessage> {
  using R = pneu::controller::EventMessage;
  static constexpr const char* kName = "event_message";
  static constexpr const char* kDoc = "something that happened, as event_t carries it";
  static constexpr auto kFields = std::tuple{
      field("kind", &R::kind, "", "what happened: KIND_*").named(pneu::controller::kEventKinds),
      field("t", &R::t_s, "s", "loop time; starts/stops are dated from the signals (see README)", 12),
      field("stop", &R::stop, "", "index of the stop this event belongs to (0: none)"),
      field("y", &R::y_m, "m", "stop: rest position; start/restart: position it left", 12),
      field("force", &R::force_n, "N", "stop: pressure force when confirmed"),
      field("y_d", &R::y_d_m, "m", "set point at the event"),
      field("direction", &R::direction, "", "start/restart: +1 or -1"),
      field("seq", &R::seq, "",
            "command accepted/rejected: the command's sequence number (command_t.seq); 0 for a datagram that "
            "did not decode as a command, and for other events"),
      field("origin", &R::origin, "",
            "command accepted/rejected: who sent it, as it said (command_t.origin: e.g. \"pneu-dash 127.0.0.1:8765\", "
            "\"pneu-command alice\"); empty when it did not say, or did not decode, and for other events"),
      field("session", &R::session, "",
            "command accepted/rejected: the sender's session (command_t.session: pneu-dash, the browser's login; "
            "pneu-command, its pid); 0 for none, and for other events"),
      field("text", &R::text, "",
            "what happened, for people: a fault's cause, what a command did or why it was rejected"),
  };
};

/// A line of the events file written by a loop event or the run's end (views: kEventLineViews).
template <>
struct pneu::records::Description<pneu::controller::EventLine> {
  using R = pneu::controller::EventLine;
  static constexpr const char* kName = "event_line";
  static constexpr const char* kDoc = "a line of the events file that a loop event writes";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "loop time; starts and stops are dated from the signals (see README)", 12),
      field("stop", &R::stop, "", "index of the stop (from 1; a start: the last stop, 0 for none)"),
      field("restart", &R::restart, "", "start: the set point did not change since the stop"),
      field("direction", &R::direction, "", "start: +1 or -1"),
      field("why", &R::why, "", "hold end: why (setpoint, left_window, moved, fault, disarmed, off)"),
      field("y", &R::y_m, "m", "stop: rest position; start: position it left; the position then", 12),
      field("force", &R::force_n, "N", "pressure force when the stop was confirmed (Eq. 14)"),
      field("y_d", &R::y_d_m, "m", "set point at the event"),
      field("reach", &R::reach, "", "hold start: the way it reaches for the window, 0 within it"),
      field("end", &R::end, "", "movement test: how it ended"),
      field("finding", &R::finding, "", "movement test: its finding").when(+[](const R& r) { return r.finding != nullptr; }),
      field("pulses", &R::pulses, "", "movement test: pulses completed (0 to 2)"),
      field("duration", &R::duration_s, "s", "movement test: how long it took"),
      field("y_start", &R::y_start_m, "m", "movement test: the position it started from", 12),
      field("y_end", &R::y_end_m, "m", "movement test: the position it ended at", 12),
      field("cause", &R::cause, "", "the fault's cause").when(+[](const R& r) { return r.cause != nullptr; }),
      field("text", &R::text, "", "what happened, for people"),
      field("key", &R::key, "", "fault: the config key of the rule that latched it").when(+[](const R& r) {
        return r.key != nullptr;
      }),
  };
};

/// A restart forecast: prediction_t, and the events file's prediction and reforecast lines.
template <>
struct pneu::records::Description<pneu::controller::ForecastRecord> {
  using R = pneu::controller::ForecastRecord;
  using P = pneu::controller::Prediction;
  static constexpr const char* kName = "forecast";
  static constexpr const char* kDoc =
      "a restart forecast (docs/model.md section 6): made at a stop (update 0), then, while the carriage stays "
      "stuck under the same u*, made again from the pressures of the moment every controller.predictor.update_period_s";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "loop time the forecast was made (update 0: the stop's confirmation)", 12),
      field("stop", &R::stop, "", "index of the stop"),
      field("t_stop", &R::t_stop_s, "s", "time of the stop (its event's t)", 12),
      field("update", &R::update, "", "0: made at the stop; k: the k-th made again while still stuck"),
      field("method", &R::prediction, &P::method, "", "how it was made: METHOD_*").named(pneu::controller::kPredictionMethods),
      field("will_restart", &R::prediction, &P::will_restart, "", "whether it forecasts a restart"),
      field("direction", &R::prediction, &P::direction, "", "+1 / -1, 0 when no restart").as<std::int8_t>(),
      field("t_restart", &R::prediction, &P::t_restart_s, "s", "forecast restart time, NaN when none", 12),
      field("u_star", &R::u_star_v, "V", "control held while stuck (Eq. 11)"),
      field("equilibrium_force", &R::prediction, &P::equilibrium_force_n, "N", "F at complete equilibrium under u*"),
      field("p_p_equilibrium", &R::prediction, &P::p_p_equilibrium_pa, "Pa", "p_null(u*)"),
      field("p_n_equilibrium", &R::prediction, &P::p_n_equilibrium_pa, "Pa", "p_null(-u*)"),
      field("tau_p", &R::prediction, &P::tau_p_s, "s", "chamber P time constant, Eq. 23"),
      field("tau_n", &R::prediction, &P::tau_n_s, "s", "chamber N time constant, Eq. 23"),
      field("min_margin", &R::prediction, &P::min_margin_n, "N", "smallest distance of F(t) to a stiction bound"),
      field("horizon_reached", &R::prediction, &P::horizon_reached, "", "nonlinear: undecided at its horizon"),
      field("force", &R::force_n, "N", "F measured when it was made (Eq. 14)"),
      field("stop_forecast_force", &R::stop_forecast_force_n, "N",
            "F that this method's forecast made at the stop expected then"),
      field("model_fits", &R::prediction, &P::model_fits, "",
            "made on a model that fitted the bench when identified (false: uncertain, whatever it says; in JSON "
            "only when false)")
          .when(+[](const R& r) { return !r.prediction.model_fits; }),
  };
};

/// A command's verdict: the events file's command line.
template <>
struct pneu::records::Description<pneu::controller::CommandRecord> {
  using R = pneu::controller::CommandRecord;
  static constexpr const char* kName = "command";
  static constexpr const char* kDoc = "a command's verdict, as the command channel gave it";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "dated by the last tick drained", 12),
      field("verdict", &R::accepted, "", "accepted or rejected").named(pneu::controller::kVerdicts),
      field("reason", &R::reason, "",
            "rejected: why, in a word (malformed, oversized, foreign, stale, sequence, invalid, rate, mode, "
            "queue_full); null when accepted")
          .null_when(+[](const R& r) { return r.accepted; }),
      field("kind", &R::kind, "", "set_point, set_point_step, arm, disarm, fault_reset, hold_on, hold_off, unknown; null when the "
                                  "datagram did not decode as a command")
          .null_when(+[](const R& r) { return !r.decoded; }),
      field("seq", &R::seq, "", "command_t.seq; null when it did not decode").null_when(+[](const R& r) {
        return !r.decoded;
      }),
      field("value", &R::value, "m", "command_t.value as sent; null when it did not decode")
          .null_when(+[](const R& r) { return !r.decoded; }),
      field("origin", &R::origin, "",
            "who sent it, as it said (command_t.origin: the program and where, e.g. \"pneu-dash 127.0.0.1:8765\"); "
            "null when it did not decode")
          .null_when(+[](const R& r) { return !r.decoded; }),
      field("session", &R::session, "",
            "the sender's session (command_t.session: pneu-dash, the browser's login; pneu-command, its pid; 0: "
            "none); null when it did not decode")
          .null_when(+[](const R& r) { return !r.decoded; }),
      field("text", &R::text, "", "what the command did or why it was refused, for people"),
  };
};

namespace pneu::controller {

namespace detail {
inline constexpr const char* kStopLine[] = {"t", "stop", "y", "force", "y_d"};
inline constexpr const char* kStartLine[] = {"t", "stop", "restart", "direction", "y", "y_d"};
inline constexpr const char* kFaultLine[] = {"t", "y", "cause", "text", "key", "finding"};
inline constexpr const char* kMovementTestLine[] = {"t", "end", "finding", "pulses", "duration",
                                                    "y_start", "y_end", "cause", "text"};
inline constexpr const char* kResetLine[] = {"t", "cause"};
inline constexpr const char* kHoldStartLine[] = {"t", "stop", "y", "force", "y_d", "reach"};
inline constexpr const char* kHoldEndLine[] = {"t", "stop", "why", "y", "y_d"};
inline constexpr const char* kEndLine[] = {"t"};
inline constexpr const char* kPredictionLine[] = {"t", "stop", "t_stop", "method", "will_restart", "direction",
                                                  "t_restart", "u_star", "equilibrium_force", "tau_p", "tau_n",
                                                  "min_margin", "horizon_reached", "model_fits"};
inline constexpr const char* kReforecastLine[] = {"t", "stop", "t_stop", "update", "method", "will_restart",
                                                  "direction", "t_restart", "u_star", "force",
                                                  "stop_forecast_force", "min_margin", "horizon_reached",
                                                  "model_fits"};
inline constexpr const char* kCommandLine[] = {"t", "verdict", "reason", "kind", "seq", "value", "origin", "session",
                                               "text"};
}  // namespace detail

/// The events file's lines that a loop event or the run's end writes (views of EventLine).
namespace event_lines {
inline constexpr records::View kStart{"start", "the carriage started moving (restart: the set point did not change "
                                               "since the stop)", detail::kStartLine};
inline constexpr records::View kStop{"stop", "the carriage stopped", detail::kStopLine};
inline constexpr records::View kFault{"fault", "a fault latched", detail::kFaultLine};
inline constexpr records::View kMovementTest{"movement_test", "the movement test at ARM ended",
                                             detail::kMovementTestLine};
inline constexpr records::View kFaultReset{"fault_reset", "a fault reset cleared the fault (now disarmed)",
                                           detail::kResetLine};
inline constexpr records::View kFaultResetRefused{"fault_reset_refused", "a fault reset came while the cause was "
                                                                         "still present", detail::kResetLine};
inline constexpr records::View kHoldStart{"hold_start", "the in-position hold took over", detail::kHoldStartLine};
inline constexpr records::View kHoldEnd{"hold_end", "the in-position hold handed back", detail::kHoldEndLine};
inline constexpr records::View kEnd{"end", "the end of the run", detail::kEndLine};
}  // namespace event_lines
inline constexpr records::View kEventLineViews[] = {
    event_lines::kStart,      event_lines::kStop,      event_lines::kFault,
    event_lines::kMovementTest, event_lines::kFaultReset, event_lines::kFaultResetRefused,
    event_lines::kHoldStart,  event_lines::kHoldEnd,   event_lines::kEnd};

/// The events file's forecast lines (views of ForecastRecord): made at a stop, made again.
inline constexpr records::View kPredictionLine{"prediction", "a forecast made at a stop", detail::kPredictionLine};
inline constexpr records::View kReforecastLine{"reforecast", "a forecast made again while the carriage is still stuck",
                                               detail::kReforecastLine};
/// The events file's command line (a view of CommandRecord).
inline constexpr records::View kCommandLine{"command", "a command's verdict", detail::kCommandLine};

static_assert(records::names_fields_of<EventLine>(event_lines::kStart) &&
              records::names_fields_of<EventLine>(event_lines::kStop) &&
              records::names_fields_of<EventLine>(event_lines::kFault) &&
              records::names_fields_of<EventLine>(event_lines::kMovementTest) &&
              records::names_fields_of<EventLine>(event_lines::kFaultReset) &&
              records::names_fields_of<EventLine>(event_lines::kHoldStart) &&
              records::names_fields_of<EventLine>(event_lines::kHoldEnd) &&
              records::names_fields_of<EventLine>(event_lines::kEnd));
static_assert(records::names_fields_of<ForecastRecord>(kPredictionLine) &&
              records::names_fields_of<ForecastRecord>(kReforecastLine));
static_assert(records::names_fields_of<CommandRecord>(kCommandLine));

/// The events file's line of a loop event: its view and its members.
struct EventLineOf {
  const records::View* view;
  EventLine line;
};
[[nodiscard]] EventLineOf event_line(const LoopEvent& e);

}  // namespace pneu::controller

/// The daemon's health: health_t.
template <>
struct pneu::records::Description<pneu::controller::HealthMessage> {
  using R = pneu::controller::HealthMessage;
  static constexpr const char* kName = "health";
  static constexpr const char* kDoc =
      "The daemon's health, about once a second on <prefix>HEALTH. Counters run from start-up.\n"
      "// Which pneud this is: two on one bench's channels tell each other apart by host, pid, start_utime\n"
      "// and nonce (one controller per bench: a pneud refuses to start while it hears another's health,\n"
      "// and both latch a fault when they hear each other while running).";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "loop time"),
      field("mode", &R::mode, "", "state_t.MODE_*"),
      field("ticks", &R::ticks, "", "ticks run"),
      field("overruns", &R::overruns, "", "ticks that ended after the next deadline"),
      group("wake_latency_us", &R::wake_latency_us, "wake_latency_us_",
            "wake-up minus deadline over the last period: min, median, p99, max [us]"),
      group("compute_us", &R::compute_us, "compute_us_", "one tick's computation over the last period: min, median, p99, max [us]"),
      field("comms_errors", &R::comms_errors, "", "backend read/write failures"),
      field("telemetry_dropped", &R::telemetry_dropped, "", "tick records and events the loop could not queue"),
      field("commands_received", &R::commands_received, "", "commands received"),
      field("commands_accepted", &R::commands_accepted, "", "commands accepted"),
      field("commands_rejected", &R::commands_rejected, "", "all rejections; the kinds below add up to it"),
      field("rejected_malformed", &R::rejected_malformed, "", "undecodable or of the wrong type"),
      field("rejected_invalid", &R::rejected_invalid, "", "non-finite, unknown kind, out of bounds"),
      field("rejected_rate", &R::rejected_rate, "", "over the rate limit"),
      field("rejected_mode", &R::rejected_mode, "", "not allowed in the current mode"),
      field("rejected_sequence", &R::rejected_sequence, "", "sequence number not increasing"),
      field("rejected_stale", &R::rejected_stale, "", "stamped too far from this host's clock (a replay, a stuck sender)"),
      field("rejected_foreign", &R::rejected_foreign, "", "sent from another host"),
      field("rejected_oversized", &R::rejected_oversized, "", "longer than any command"),
      field("deadlines_skipped", &R::deadlines_skipped, "", "deadlines passed over after overruns"),
      field("fault_cause", &R::fault_cause, "",
            "the latched fault's cause (0: none; the numbers of FaultCause in "
            "controller/include/pneu/controller/supervisor.hpp); event_t's text names it"),
      field("faults", &R::faults, "", "faults latched since start"),
      field("is_final", &R::is_final, "", "the last health message, sent as the daemon stops (\"final\" is a Java keyword)"),
      field("host", &R::host, "", "the host's name (gethostname)"),
      field("pid", &R::pid, "", "its process id"),
      field("start_utime", &R::start_utime, "us", "when it started, microseconds since the Unix epoch"),
      field("nonce", &R::nonce, "", "a random number drawn at start-up (pids repeat across containers)"),
      field("period", &R::period_s, "s",
            "the period of these messages (telemetry.health_period_s): another pneud counts this one gone after 3 of them"),
  };
};

/// The running estimate of online identification: identification_t.
template <>
struct pneu::records::Description<pneu::controller::IdentificationRecord> {
  using R = pneu::controller::IdentificationRecord;
  static constexpr const char* kName = "identification";
  static constexpr const char* kDoc =
      "The bench as pneud has identified it online so far (controller.predictor.learn_online), on\n"
      "// <prefix>IDENTIFICATION after each update. Fixed size. Entry i of the arrays is parameter i, in\n"
      "// the order of the constants below; its config key is plant.<section>.<name> (README,\n"
      "// \"Identifying the bench\"). Not identified: the value is the configuration's, sigma 0.";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "loop time of the update", 12),
      field("updates", &R::updates, "", "updates since start-up"),
      field("value", &R::value, "", "in the unit of its config key (N, N s/m, m^3/(s Pa), V, m^3, W/(m^2 K), s)")
          .indexed(pneu::controller::kIdentifiedParameters, ""),
      field("sigma", &R::sigma, "", "1 sigma uncertainty, same unit; 0 when not identified")
          .indexed(pneu::controller::kIdentifiedParameters, "_sigma"),
      field("identified", &R::identified, "",
            "1 identified; 0: not seen yet, or not separable, or not the model's (the heat transfer without "
            "plant.thermal, the spool lag without one): the configuration's value (int8_t: lcm-gen 1.4's Python for "
            "a boolean array does not run)")
          .indexed(pneu::controller::kIdentifiedParameters, "_identified")
          .as<std::int8_t>(),
  };
};
