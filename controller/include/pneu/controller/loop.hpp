// One tick of the controller: read the sensors, differentiate, control (Eq. 4), detect stops and
// starts, write the valves, hand the tick's record and events to the non-real-time side.
#pragma once

#include <atomic>
#include <cstdint>

#include "pneu/controller/control_law.hpp"
#include "pneu/controller/differentiator.hpp"
#include "pneu/controller/hold_law.hpp"
#include "pneu/controller/loop_params.hpp"
#include "pneu/controller/modes.hpp"
#include "pneu/controller/movement_test.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/spsc_queue.hpp"
#include "pneu/controller/stop_detector.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/model/pressure_force.hpp"

namespace pneu::controller {

/// How the movement test at ARM ended (LoopEvent::Kind::kMovementTest).
enum class MovementTestEnd : std::uint8_t {
  kNone = 0,
  kPassed,    ///< passed: armed from then on
  kFinding,   ///< a finding (LoopEvent::movement_test.finding): the movement-test fault latches
  kDisarmed,  ///< aborted by a disarm command
  kFault,     ///< aborted by another fault (LoopEvent::fault_cause)
  kStopped,   ///< aborted as the run stopped (SIGTERM, SIGINT, the end of its duration)
};
[[nodiscard]] const char* movement_test_end_name(MovementTestEnd why) noexcept;

/// Why a hold ended (LoopEvent::Kind::kHoldEnd).
enum class HoldEnd : std::uint8_t {
  kNone = 0,
  kSetPoint,    ///< the set point changed
  kLeftWindow,  ///< the position read left the window (a push)
  kMoved,       ///< the stop detector saw the carriage start inside the window
  kFault,       ///< a fault latched
  kDisarmed,    ///< a disarm command
  kOff,         ///< a hold-off command: the hold is not allowed any more
};
[[nodiscard]] const char* hold_end_name(HoldEnd why) noexcept;

/// Everything one tick computed: the per-tick telemetry record.
struct TickRecord {
  std::uint64_t seq = 0;       ///< tick sequence number, from 0, no gaps
  double t_s = 0.0;            ///< loop time of the sample [s]
  double y_d_m = 0.0;          ///< set point [m]
  double y_m = 0.0;            ///< measured position [m]
  double v_hat_m_per_s = 0.0;  ///< estimated velocity [m/s]
  double a_hat_m_per_s2 = 0.0; ///< estimated acceleration [m/s^2]
  double p_p_pa = 0.0;         ///< measured chamber P pressure [Pa]
  double p_n_pa = 0.0;         ///< measured chamber N pressure [Pa]
  double force_n = 0.0;        ///< pressure force of Eq. 14 from the measured pressures [N]
  double u_v = 0.0;            ///< control sent: u_P = u, u_N = -u [V]
  double u_n_v = 0.0;          ///< the voltage valve N was sent: -u, but for the exhaust safe output [V]
  bool stuck = false;          ///< the stop detector holds the carriage at rest
  Mode mode = Mode::kArmed;
  std::uint32_t sensor_validity = 0;  ///< hal::SensorValidity flags of the sample
  double hold_integral_v = 0.0;       ///< in hold: the hold law's integral term after this tick [V]
};

/// A start or stop of the carriage (with the snapshot the predictor needs at a stop), or a fault
/// latched by the loop (cause: FaultCause).
struct LoopEvent {
  /// kFaultReset: a reset cleared the fault (now disarmed); kResetRefused: a reset came while
  /// the cause was still present (fault_cause: which).
  /// kHoldStart / kHoldEnd: the in-position hold took over from Eq. 4 / handed back (hold_end: why).
  /// kMovementTest: the movement test at ARM ended (movement_end: how; movement_test: its result).
  enum class Kind : std::uint8_t { kStop, kStart, kFault, kFaultReset, kResetRefused, kHoldStart, kHoldEnd, kMovementTest };
  Kind kind = Kind::kStop;
  std::uint64_t stop_index = 0;  ///< stops are numbered from 1; a start refers to the last stop (0: none)
  double t_s = 0.0;              ///< backdated to the signals (see StopDetector) [s]
  double y_m = 0.0;              ///< stop: the rest position; start: the position it left [m]
  double force_n = 0.0;          ///< stop: F when the stop was confirmed [N]
  double y_d_m = 0.0;            ///< the set point at the event [m]
  bool restart = false;          ///< start: the set point did not change since the stop
  int direction = 0;             ///< start: +1 / -1; hold start: the way it reaches for the window, 0 within it
  StopSnapshot snapshot;         ///< stop: state at confirmation, u* of Eq. 11
  bool controlled = true;        ///< stop: the law was driving (armed), so u* applies and a forecast makes sense
  FaultCause fault_cause = FaultCause::kNone;  ///< fault, reset, reset refused: which cause
  /// fault: the config key of the rule that latched it (Supervisor::decided_by; a static string),
  /// or nullptr
  const char* fault_key = nullptr;
  HoldEnd hold_end = HoldEnd::kNone;           ///< hold end: why
  HoldState hold;                              ///< hold start: the hold's law as it starts
  MovementTestEnd movement_end = MovementTestEnd::kNone;  ///< movement test: how it ended
  /// movement test, and a movement-test fault: the test's result (its finding and figures)
  MovementTestResult movement_test;
  std::uint64_t tick_seq = 0;    ///< the tick that raised it (its TickRecord::seq)
};


/// A validated command for the loop (see CommandValidator).
struct LoopCommand {
  /// kHoldOn / kHoldOff: the in-position hold allowed or not from now on (controller.hold.enabled
  /// at start); a hold in force ends at a hold off (hold_end: off).
  enum class Kind : std::uint8_t { kSetPoint, kSetPointStep, kArm, kDisarm, kFaultReset, kHoldOn, kHoldOff };
  Kind kind = Kind::kSetPoint;
  double value_m = 0.0;  ///< set point, or its change [m]
  std::uint64_t seq = 0;
};

/// Loop statistics handed out once per health period.
struct HealthRecord {
  double t_s = 0.0;
  std::uint64_t ticks = 0;
  std::uint64_t overruns = 0;
  std::uint64_t deadlines_skipped = 0;
  double wake_latency_s[4] = {};  ///< min, median, p99, max over the period
  double compute_s[4] = {};
  std::uint64_t ticks_dropped = 0;
  std::uint64_t events_dropped = 0;
  std::uint64_t comms_errors = 0;  ///< backend reads and writes that did not return kOk, since start
  Mode mode = Mode::kArmed;
  FaultCause fault_cause = FaultCause::kNone;  ///< latched (kNone unless in fault)
  std::uint64_t faults = 0;        ///< faults latched since start
  bool is_final = false;           ///< the last record, sent as the loop stops
};

/// The loop's lock-free boundary with the non-real-time side. Records leave through
/// single-producer queues (a full queue drops and counts; the loop never waits); validated
/// commands arrive through one. Two atomics publish what command validation needs to know.
struct LoopOutputs {
  SpscQueue<TickRecord, 8192> ticks;
  SpscQueue<LoopEvent, 256> events;
  SpscQueue<HealthRecord, 16> health;
  SpscQueue<LoopCommand, 64> commands;  ///< producer: the command thread; consumer: the loop
  std::uint64_t ticks_dropped = 0;   ///< written by the loop thread only
  std::uint64_t events_dropped = 0;  ///< written by the loop thread only
  std::atomic<double> setpoint_m{0.0};  ///< the loop's current set point
  std::atomic<Mode> mode{Mode::kArmed};
  std::atomic<FaultCause> fault_cause{FaultCause::kNone};  ///< latched
  std::atomic<std::uint64_t> heartbeat{0};   ///< ticks run: the watchdog checks that it advances
  /// A cause of fault only the non-real-time side can see (FaultCause::kAnotherController), held
  /// while it is present: the loop latches it at its next tick and refuses a reset while it is
  /// still set. Written by the service thread, read by the loop (relaxed, lock-free).
  std::atomic<FaultCause> external_fault{FaultCause::kNone};
};

/// The controller's tick. Construct and start() outside the loop; tick() is real-time safe.
class ControlLoop {
 public:
  /// `params.controller.law.offset_v` must already hold u_0 (see assembly::RunSpec). The loop keeps
  /// its parameters; it refers to `backend` and `outputs`, which must outlive it.
  ControlLoop(LoopParams params, hal::Backend& backend, LoopOutputs& outputs);

  /// Opens the backend at loop time `t0_s` and arms the detector at rest at the first reading:
  /// open() then begin().
  void start(double t0_s);
  /// Opens the backend at loop time `t0_s` (before time starts: a movement test may drive it
  /// between open() and begin()).
  void open(double t0_s) { backend_->open(t0_s); }
  /// The loop's state from the first reading at loop time `t0_s`, the backend open.
  void begin(double t0_s);
  /// One tick at loop time `t_s`. Real-time safe.
  void tick(double t_s) noexcept;
  /// After each tick on the real clock: whether it overran its deadline (the supervisor counts
  /// overruns in a row).
  void note_overrun(bool overran) noexcept { supervisor_.note_overrun(overran); }
  /// Drives the safe output for the end of the run (SIGTERM, end of the duration): the
  /// configured safe voltages, valve power off.
  void stop() noexcept;
  /// The fault output: valve power off and controller.supervisor.safe_output.
  [[nodiscard]] hal::ActuatorCommand safe_command() const noexcept;

  [[nodiscard]] std::uint64_t ticks() const noexcept { return seq_; }
  [[nodiscard]] const ControlLaw& law() const noexcept { return law_; }
  [[nodiscard]] Mode mode() const noexcept { return mode_; }
  /// Backend reads and writes that did not return kOk (stale samples, comms or device errors).
  [[nodiscard]] std::uint64_t comms_errors() const noexcept { return comms_errors_; }
  [[nodiscard]] FaultCause fault_cause() const noexcept { return fault_cause_; }
  [[nodiscard]] std::uint64_t faults() const noexcept { return faults_; }
  /// Whether the next ARM runs the movement test first: LoopParams::movement_test_at_arm, until
  /// it passed in this run.
  [[nodiscard]] bool movement_test_due() const noexcept { return movement_test_due_; }

 private:
  /// This tick's sample: as read, and as the loop goes on with it (a bad one keeps the last good
  /// position).
  struct Sample {
    hal::Status status = hal::Status::kOk;
    hal::SensorFrame as_read;  ///< what the backend returned: the supervisor and the movement test judge it
    hal::SensorFrame frame;    ///< ... its position the last good one unless the sample is good
    bool good = false;         ///< Supervisor::sample_good(): may reach the differentiator and the detector
  };
  /// An event for the state machine (ModeEvent) with what its actions need, at the tick's time.
  struct ModeInput {
    ModeEvent event = ModeEvent::kArm;
    double y_m = 0.0;                      ///< the position the loop's event records carry
    FaultCause cause = FaultCause::kNone;  ///< fault, reset refused: which cause
    const char* key = nullptr;             ///< fault: the config key of the rule that latched it
    HoldEnd why = HoldEnd::kNone;          ///< hold end: why
    double force_n = 0.0;                  ///< hold start: the force measured [N]
    int direction = 0;                     ///< hold start: +1 / -1 reaching that way, 0 within the window
  };

  // The tick's steps, in order (tick()).
  [[nodiscard]] Sample read_sample(double t_s) noexcept;
  void apply_commands(double y_m) noexcept;
  void follow_schedule(double t_s) noexcept;
  [[nodiscard]] hal::ActuatorCommand step_movement_test(const Sample& s) noexcept;
  void check_motion(const Sample& s) noexcept;
  [[nodiscard]] double observe(const Sample& s) noexcept;
  void watch_hold(const Sample& s, double force_n) noexcept;
  [[nodiscard]] hal::ActuatorCommand output(const Sample& s, double force_n, const hal::ActuatorCommand& test) noexcept;
  void publish(const Sample& s, double force_n, const hal::ActuatorCommand& command) noexcept;

  /// The state machine: the change kModeTransitions lists for `in.event` in the mode in force, with
  /// what it does on the way; nothing when it lists none.
  void transition(const ModeInput& in) noexcept;
  // The actions of transition().
  void arm_here(double y_m) noexcept;
  void start_movement_test(double y_m) noexcept;
  /// Pushes the movement test's end (aborting it unless it passed or found).
  void end_movement_test(MovementTestEnd why, double y_m, FaultCause cause = FaultCause::kNone) noexcept;
  void start_hold(double y_m, double force_n, int reach_direction) noexcept;
  void end_hold(HoldEnd why, double y_m) noexcept;

  void push(LoopEvent e) noexcept;
  /// An event of `kind` at `t_s`, position `y_m`: the last stop's index and the set point filled.
  [[nodiscard]] LoopEvent event(LoopEvent::Kind kind, double t_s, double y_m) const noexcept;

  LoopParams params_;
  hal::Backend* backend_;  // pointers, not references: the loop can be moved
  LoopOutputs* out_;
  ControlLaw law_;
  Differentiator differentiator_;
  StopDetector detector_;
  double half_stroke_m_;
  model::PressureForce force_;
  std::uint64_t seq_ = 0;
  std::size_t next_step_ = 0;
  double y_d_m_ = 0.0;
  std::uint64_t stops_ = 0;
  double y_d_at_stop_m_ = 0.0;
  Mode mode_ = Mode::kArmed;
  bool schedule_active_ = true;  ///< a set-point command ends the configured schedule
  bool hold_allowed_ = false;    ///< controller.hold.enabled, then as hold on / off commands say
  Supervisor supervisor_;
  FaultCause fault_cause_ = FaultCause::kNone;
  std::uint64_t faults_ = 0;
  double last_setpoint_t_s_ = 0.0;        // loop time of the last set point received, or of arming
  double t_s_ = 0.0;                      // the current tick's loop time
  std::uint64_t comms_errors_ = 0;
  std::uint64_t ticks_since_sample_ = 0;  // ticks since the differentiator took a new sample
  double detector_last_y_ = 0.0;         // the last good position
  // The hold's law, and the hold in force (mode kHold) with the set point it holds.
  HoldLaw hold_law_;
  HoldState hold_;
  double hold_y_d_m_ = 0.0;
  // Reaching: the direction of the last reach for this set point (0: none yet), and the share of
  // reach_rate_n_per_s in force, halved each time a reach went past the set point.
  int last_reach_direction_ = 0;
  double reach_rate_scale_ = 1.0;
  double reach_y_d_m_ = 0.0;  // the set point those hold for
  // The movement test at ARM: due until it passed; the one running in mode kMovementTest.
  bool movement_test_due_ = false;
  MovementTest movement_test_;
};

}  // namespace pneu::controller
