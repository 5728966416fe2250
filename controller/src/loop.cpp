#include "pneu/controller/loop.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

namespace pneu::controller {

namespace {
// A carriage within this distance of an end stop is pressed against it [m].
constexpr double kEndStopTolerance_m = 1.0e-4;
}  // namespace

const char* hold_end_name(HoldEnd why) noexcept {
  switch (why) {
    case HoldEnd::kNone: return "none";
    case HoldEnd::kSetPoint: return "setpoint";
    case HoldEnd::kLeftWindow: return "left_window";
    case HoldEnd::kMoved: return "moved";
    case HoldEnd::kFault: return "fault";
    case HoldEnd::kDisarmed: return "disarmed";
    case HoldEnd::kOff: return "off";
  }
  return "?";
}

const char* movement_test_end_name(MovementTestEnd why) noexcept {
  switch (why) {
    case MovementTestEnd::kNone: return "none";
    case MovementTestEnd::kPassed: return "passed";
    case MovementTestEnd::kFinding: return "finding";
    case MovementTestEnd::kDisarmed: return "disarmed";
    case MovementTestEnd::kFault: return "fault";
    case MovementTestEnd::kStopped: return "stopped";
  }
  return "?";
}

ControlLoop::ControlLoop(LoopParams params, hal::Backend& backend, LoopOutputs& outputs)
    : params_(std::move(params)),
      backend_(&backend),
      out_(&outputs),
      law_(params_.law),
      differentiator_(params_.controller.differentiator, params_.controller.period_s()),
      detector_(params_.controller.stop_detector, params_.controller.period_s()),
      half_stroke_m_(params_.geometry.half_stroke_m()),
      force_(params_.geometry, params_.exhaust_pressure_pa),
      supervisor_(params_),
      hold_law_(params_.controller.hold, params_.controller.law.max_voltage_v, params_.controller.period_s()),
      movement_test_(params_.controller.movement_test, MovementTestBench::of(params_.controller)) {}

void ControlLoop::start(double t0_s) {
  open(t0_s);
  begin(t0_s);
}

void ControlLoop::begin(double t0_s) {
  seq_ = 0;
  comms_errors_ = 0;
  next_step_ = 0;
  stops_ = 0;
  y_d_m_ = params_.controller.initial_setpoint_m;
  mode_ = params_.controller.start_armed ? Mode::kArmed : Mode::kDisarmed;
  fault_cause_ = FaultCause::kNone;
  faults_ = 0;
  schedule_active_ = true;
  hold_allowed_ = params_.controller.hold.enabled;
  out_->setpoint_m.store(y_d_m_, std::memory_order_relaxed);
  out_->mode.store(mode_, std::memory_order_relaxed);
  out_->fault_cause.store(FaultCause::kNone, std::memory_order_relaxed);
  hal::SensorFrame frame;
  (void)backend_->read(t0_s, frame);
  differentiator_.reset(frame.y_m);
  detector_.reset_at_rest(t0_s, frame.y_m);
  detector_last_y_ = frame.y_m;
  ticks_since_sample_ = 0;
  supervisor_.reset(t0_s);
  last_setpoint_t_s_ = t0_s;
  t_s_ = t0_s;
  y_d_at_stop_m_ = y_d_m_;
  hold_ = HoldState{};
  last_reach_direction_ = 0;
  reach_rate_scale_ = 1.0;
  reach_y_d_m_ = y_d_m_;
  movement_test_due_ = params_.movement_test_at_arm;
}

// One tick: the sample, what it says and what the commands say (events into the state machine,
// transition() below), then the output of the mode in force, written and published.
void ControlLoop::tick(double t_s) noexcept {
  t_s_ = t_s;
  const Sample s = read_sample(t_s);  // the supervisor's sample checks: a fault latches
  apply_commands(s.frame.y_m);        // set points; ARM, DISARM, FAULT_RESET
  follow_schedule(t_s);
  const hal::ActuatorCommand test_command = step_movement_test(s);  // its pass, or finding
  check_motion(s);                    // the supervisor's motion checks: a fault latches
  const double force_n = observe(s);  // derivatives; stops and starts
  watch_hold(s, force_n);             // the hold taken, or handed back
  const hal::ActuatorCommand command = output(s, force_n, test_command);
  if (backend_->write(command) != hal::Status::kOk) ++comms_errors_;
  publish(s, force_n, command);
}

// ---------------------------------------------------------------------------------------------
// The state machine (modes.hpp): every change of mode, and what it does on the way, in the order
// it happens. The table decides whether there is a change; the events recorded on the way carry
// the set point as it is once they are done (a pass's end, the one armed).

void ControlLoop::transition(const ModeInput& in) noexcept {
  const Mode from = mode_;
  const std::optional<Mode> to = next_mode(from, in.event);
  if (!to) return;  // the event means nothing in this mode
  mode_ = *to;
  switch (in.event) {
    case ModeEvent::kArm:  // disarmed -> armed
      arm_here(in.y_m);
      break;
    case ModeEvent::kArmTestDue:  // disarmed -> movement test
      start_movement_test(in.y_m);
      break;
    case ModeEvent::kTestPassed:  // movement test -> armed, as an ARM arms
      // Not again at a later ARM of this run: the wiring does not change while pneud runs, and
      // each test moves the carriage open loop by millimetres.
      movement_test_due_ = false;
      arm_here(in.y_m);
      end_movement_test(MovementTestEnd::kPassed, in.y_m);  // with the set point armed
      break;
    case ModeEvent::kHoldStart:  // armed -> hold
      start_hold(in.y_m, in.force_n, in.direction);
      break;
    case ModeEvent::kHoldEnd:  // hold -> armed, Eq. 4 again
      end_hold(in.why, in.y_m);
      break;
    case ModeEvent::kDisarm:  // armed, hold, movement test -> disarmed
      if (from == Mode::kHold) end_hold(HoldEnd::kDisarmed, in.y_m);
      if (from == Mode::kMovementTest) end_movement_test(MovementTestEnd::kDisarmed, in.y_m);
      break;
    case ModeEvent::kRunStops:  // movement test -> disarmed
      end_movement_test(MovementTestEnd::kStopped, in.y_m);
      break;
    case ModeEvent::kFault: {  // any mode but fault -> fault: the safe output until a reset
      if (from == Mode::kHold) end_hold(HoldEnd::kFault, in.y_m);
      // The test's finding ends it; any other fault aborts it. (Still due: after a reset the next
      // ARM tests again, the wiring may have been mended.)
      const bool finding = in.cause == FaultCause::kMovementTest;
      if (from == Mode::kMovementTest)
        end_movement_test(finding ? MovementTestEnd::kFinding : MovementTestEnd::kFault, in.y_m,
                          finding ? FaultCause::kNone : in.cause);
      fault_cause_ = in.cause;
      ++faults_;
      LoopEvent e = event(LoopEvent::Kind::kFault, t_s_, in.y_m);
      e.fault_cause = in.cause;
      e.fault_key = in.key;
      if (finding) e.movement_test = movement_test_.result();
      push(e);
      break;
    }
    case ModeEvent::kReset: {  // fault -> disarmed: arming again is a separate, later command
      LoopEvent e = event(LoopEvent::Kind::kFaultReset, t_s_, in.y_m);
      e.fault_cause = fault_cause_;  // the cause it cleared
      fault_cause_ = FaultCause::kNone;
      push(e);
      break;
    }
    case ModeEvent::kResetRefused: {  // fault, kept: the cause is still present
      LoopEvent e = event(LoopEvent::Kind::kResetRefused, t_s_, in.y_m);
      e.fault_cause = in.cause;
      push(e);
      break;
    }
  }
}

// Arming: the law drives from the next command on, holding where the carriage is.
void ControlLoop::arm_here(double y_m) noexcept {
  const auto& c = params_.controller;
  // Only what is measured from now on drives the valves: no stale derivative.
  differentiator_.reset(y_m);
  // Bumpless: hold where the carriage is until told otherwise.
  y_d_m_ = std::clamp(y_m, c.soft_limit_min_m, c.soft_limit_max_m);
  schedule_active_ = false;
  last_setpoint_t_s_ = t_s_;
  supervisor_.on_arm();
}

// The same test, the same parameters and findings as before the loop's time on a run started
// armed (run_movement_test), stepped here once per tick from the tick's own sample.
void ControlLoop::start_movement_test(double y_m) noexcept {
  const auto& c = params_.controller;
  movement_test_ = MovementTest(c.movement_test, MovementTestBench::of(c));
  // The set point shown meanwhile: where the carriage is (a pass arms holding where it is then).
  y_d_m_ = std::clamp(y_m, c.soft_limit_min_m, c.soft_limit_max_m);
  schedule_active_ = false;
}

void ControlLoop::end_movement_test(MovementTestEnd why, double y_m, FaultCause cause) noexcept {
  if (why != MovementTestEnd::kPassed && why != MovementTestEnd::kFinding) movement_test_.interrupt();
  LoopEvent e = event(LoopEvent::Kind::kMovementTest, t_s_, y_m);
  e.movement_end = why;
  e.movement_test = movement_test_.result();
  e.fault_cause = cause;
  push(e);
}

void ControlLoop::start_hold(double y_m, double force_n, int reach_direction) noexcept {
  const auto& hold = params_.controller.hold;
  hold_ = HoldState{};
  hold_.t0_s = t_s_;
  hold_.force0_n = force_n;
  if (reach_direction != 0) {
    // A new set point starts afresh; a reach back the other way means the last one went past the
    // set point: gentler from now on (each breakaway then carries the carriage less far).
    if (y_d_m_ != reach_y_d_m_) {
      reach_y_d_m_ = y_d_m_;
      last_reach_direction_ = 0;
      reach_rate_scale_ = 1.0;
    }
    if (last_reach_direction_ == -reach_direction) reach_rate_scale_ = std::max(reach_rate_scale_ * 0.5, 1.0 / 64.0);
    last_reach_direction_ = reach_direction;
    // The reference starts at hold.reach_preload of the bound it must cross (unless the force is
    // past that already), so that the ramp's slow part is spent near the breakaway.
    const double bound = reach_direction > 0 ? params_.friction.static_positive_n : params_.friction.static_negative_n;
    const double preload = hold.reach_preload * bound;
    hold_.force0_n = reach_direction > 0 ? std::max(force_n, preload) : std::min(force_n, preload);
  }
  hold_.u0_v = law_.resting_control_v(y_d_m_, detector_.rest_position_m());  // the u* in force
  hold_.target_n = 0.5 * (params_.friction.static_positive_n + params_.friction.static_negative_n);
  hold_.reach_direction = reach_direction;
  hold_.reach_rate_n_per_s = reach_rate_scale_ * hold.reach_rate_n_per_s;
  hold_y_d_m_ = y_d_m_;
  LoopEvent e = event(LoopEvent::Kind::kHoldStart, t_s_, y_m);
  e.force_n = force_n;
  e.direction = reach_direction;
  e.hold = hold_;
  push(e);
}

void ControlLoop::end_hold(HoldEnd why, double y_m) noexcept {
  LoopEvent e = event(LoopEvent::Kind::kHoldEnd, t_s_, y_m);
  e.hold_end = why;
  push(e);
}

// ---------------------------------------------------------------------------------------------
// The tick's steps

// The supervisor, first on the sample: e-stop, readings, comms; then what the service thread sees
// (another controller). Without a good sample the loop keeps the last position: a stale or
// invalid value must not reach the differentiator or the detector.
ControlLoop::Sample ControlLoop::read_sample(double t_s) noexcept {
  Sample s;
  s.status = backend_->read(t_s, s.as_read);
  if (s.status != hal::Status::kOk) ++comms_errors_;  // counted for health
  SupervisedTick st;
  st.t_s = t_s;
  st.status = s.status;
  st.frame = &s.as_read;
  if (const FaultCause cause = supervisor_.check_sample(st); cause != FaultCause::kNone)
    transition({.event = ModeEvent::kFault, .y_m = s.as_read.y_m, .cause = cause, .key = supervisor_.decided_by()});
  if (const FaultCause cause = out_->external_fault.load(std::memory_order_relaxed); cause != FaultCause::kNone)
    transition({.event = ModeEvent::kFault, .y_m = s.as_read.y_m, .cause = cause});
  s.good = supervisor_.sample_good();
  s.frame = s.as_read;
  if (!s.good) s.frame.y_m = detector_last_y_;
  return s;
}

// Commands were validated off the loop; here they only take effect. A set point leaves the soft
// limits only through a step that the validator could not foresee: clamp it.
void ControlLoop::apply_commands(double y_m) noexcept {
  const auto& c = params_.controller;
  LoopCommand cmd;
  while (out_->commands.try_pop(cmd)) {
    switch (cmd.kind) {
      case LoopCommand::Kind::kSetPoint:
      case LoopCommand::Kind::kSetPointStep:
        // Queued before a fault: stale now. During the movement test the validator refuses set
        // points (the pass holds where the carriage is): one queued before it is dropped.
        if (!takes_set_points(mode_)) break;
        y_d_m_ = std::clamp(cmd.kind == LoopCommand::Kind::kSetPoint ? cmd.value_m : y_d_m_ + cmd.value_m,
                            c.soft_limit_min_m, c.soft_limit_max_m);
        schedule_active_ = false;
        last_setpoint_t_s_ = t_s_;
        break;
      case LoopCommand::Kind::kArm:
        // The first ARM of a run started disarmed on a real backend tests the wiring first.
        transition({.event = movement_test_due_ ? ModeEvent::kArmTestDue : ModeEvent::kArm, .y_m = y_m});
        break;
      case LoopCommand::Kind::kDisarm:
        transition({.event = ModeEvent::kDisarm, .y_m = y_m});
        break;
      case LoopCommand::Kind::kHoldOn:
        hold_allowed_ = true;
        break;
      case LoopCommand::Kind::kHoldOff:
        hold_allowed_ = false;
        if (mode_ == Mode::kHold) transition({.event = ModeEvent::kHoldEnd, .y_m = y_m, .why = HoldEnd::kOff});
        break;
      case LoopCommand::Kind::kFaultReset: {
        // The cause must be gone: a reset while the e-stop is still pressed, or while the samples
        // are still bad, keeps the fault. A reset disarms: arming again is a separate, later
        // command, and only what is measured from then on drives the valves.
        const FaultCause external = out_->external_fault.load(std::memory_order_relaxed);
        if (supervisor_.cause_present() || external != FaultCause::kNone)
          transition({.event = ModeEvent::kResetRefused,
                      .y_m = y_m,
                      .cause = supervisor_.cause_present() ? supervisor_.present_cause() : external});
        else
          transition({.event = ModeEvent::kReset, .y_m = y_m});
        break;
      }
    }
  }
}

void ControlLoop::follow_schedule(double t_s) noexcept {
  const auto schedule = params_.controller.schedule();
  while (schedule_active_ && next_step_ < schedule.size() && schedule[next_step_].t_s <= t_s + 1e-9)
    y_d_m_ = schedule[next_step_++].position_m;
}

// The movement test at ARM drives the valves open loop until it ends, stepped on the sample as
// read (it judges it itself): a pass arms the law here and now, holding where the carriage is; a
// finding latches the movement-test fault. (A fault, a disarm or the run's stop abort it.)
hal::ActuatorCommand ControlLoop::step_movement_test(const Sample& s) noexcept {
  if (mode_ != Mode::kMovementTest) return {};
  const hal::ActuatorCommand command = movement_test_.step(t_s_, s.status, s.as_read);
  if (movement_test_.done() && movement_test_.result().passed())
    transition({.event = ModeEvent::kTestPassed, .y_m = s.frame.y_m});
  else if (movement_test_.done())
    transition({.event = ModeEvent::kFault, .y_m = s.as_read.y_m, .cause = FaultCause::kMovementTest,
                .key = "controller.movement_test"});
  return command;
}

// The supervisor on the motion, with this tick's commands and set point in force: soft limits,
// following error, settling, timing, the set-point stream.
void ControlLoop::check_motion(const Sample& s) noexcept {
  SupervisedTick st;
  st.t_s = t_s_;
  st.status = s.status;
  st.frame = &s.frame;
  st.armed = drives(mode_);
  st.y_d_m = y_d_m_;
  st.last_setpoint_t_s = last_setpoint_t_s_;
  st.at_rest = detector_.stopped();  // as of the last good sample: the detector runs below
  if (const FaultCause cause = supervisor_.check_motion(st); cause != FaultCause::kNone)
    transition({.event = ModeEvent::kFault, .y_m = s.as_read.y_m, .cause = cause, .key = supervisor_.decided_by()});
}

// Differentiates new samples only (a slow link repeats them), over the ticks since the last new
// one: the loop's period keeps the arrival jitter of the samples out of the derivatives. Stops and
// starts are judged from good samples only (a snapshot must hold real pressures). Returns the
// pressure force of Eq. 14.
double ControlLoop::observe(const Sample& s) noexcept {
  const hal::SensorFrame& frame = s.frame;
  ++ticks_since_sample_;
  if (s.good && frame.fresh) {
    differentiator_.update(frame.y_m, static_cast<double>(ticks_since_sample_) * params_.controller.period_s());
    ticks_since_sample_ = 0;
  }
  detector_last_y_ = frame.y_m;
  const double force = force_.force_n(frame.p_p_pa, frame.p_n_pa);
  switch (s.good ? detector_.update(t_s_, frame.y_m) : StopDetectorEvent::kNone) {
    case StopDetectorEvent::kStop: {
      LoopEvent e;
      e.kind = LoopEvent::Kind::kStop;
      e.stop_index = ++stops_;
      e.t_s = detector_.event_time_s();
      e.y_m = detector_.event_position_m();
      e.force_n = force;
      e.y_d_m = y_d_m_;
      e.snapshot.t_s = t_s_;
      e.snapshot.y_m = e.y_m;
      e.snapshot.p_p_pa = frame.p_p_pa;
      e.snapshot.p_n_pa = frame.p_n_pa;
      e.snapshot.u_v = law_.resting_control_v(y_d_m_, e.y_m);
      e.controlled = drives(mode_);
      e.snapshot.blocked_direction = e.y_m >= half_stroke_m_ - kEndStopTolerance_m    ? +1
                                     : e.y_m <= -half_stroke_m_ + kEndStopTolerance_m ? -1
                                                                                      : 0;
      y_d_at_stop_m_ = y_d_m_;
      push(e);
      break;
    }
    case StopDetectorEvent::kStart: {
      LoopEvent e;
      e.kind = LoopEvent::Kind::kStart;
      e.stop_index = stops_;
      e.t_s = detector_.event_time_s();
      e.y_m = detector_.event_position_m();
      e.force_n = force;
      e.y_d_m = y_d_m_;
      e.restart = stops_ > 0 && y_d_m_ == y_d_at_stop_m_;
      e.direction = frame.y_m > e.y_m ? +1 : -1;
      push(e);
      break;
    }
    case StopDetectorEvent::kNone: break;
  }
  return force;
}

// The in-position hold: handed back on a set-point change, on a reading outside the window (the
// tick it comes), on any start; taken once at rest within the window (or within reach of it,
// reaching for it), away from the end stops.
void ControlLoop::watch_hold(const Sample& s, double force_n) noexcept {
  const auto& hold = params_.controller.hold;
  const double y_m = s.frame.y_m;
  if (mode_ == Mode::kHold) {
    // A reading beyond the window by more than the stop detector's rest band: the band is what the
    // sensor's noise and steps span at rest, so that a rest on the window's edge is not handed
    // back and taken again tick after tick.
    const double rest_band_m = params_.controller.stop_detector.rest_band_m;
    const bool reaching = hold_.reach_direction != 0;
    const HoldEnd why = y_d_m_ != hold_y_d_m_ ? HoldEnd::kSetPoint
                        : !reaching && s.good && std::abs(y_m - y_d_m_) > hold.window_m + rest_band_m ? HoldEnd::kLeftWindow
                        : !detector_.stopped() ? HoldEnd::kMoved
                                               : HoldEnd::kNone;
    if (why != HoldEnd::kNone) transition({.event = ModeEvent::kHoldEnd, .y_m = y_m, .why = why});
  } else if (hold_allowed_ && mode_ == Mode::kArmed && s.good && detector_.stopped() &&
             std::abs(detector_.rest_position_m()) < half_stroke_m_ - kEndStopTolerance_m) {
    const double error_m = y_d_m_ - detector_.rest_position_m();
    if (std::abs(error_m) <= hold.window_m)
      transition({.event = ModeEvent::kHoldStart, .y_m = y_m, .force_n = force_n, .direction = 0});
    else if (std::abs(error_m) <= hold.reach_m)  // reaching for the window
      transition({.event = ModeEvent::kHoldStart, .y_m = y_m, .force_n = force_n, .direction = error_m > 0.0 ? +1 : -1});
  }
}

// The mode's output. Valve power follows the armed state. Disarmed, the outputs sit at the neutral
// voltage u_0 (F_e(u_0) = 0: the chambers hold); in fault, at the configured safe output; in the
// movement test, its pulses. At rest the law holds u* (Eq. 11) at the rest position, exactly as
// the restart forecasts assume: the carriage has no velocity or acceleration to damp, and neither
// the differentiator's decaying residue nor the sensor's noise and steps reach the valves through
// the gains.
hal::ActuatorCommand ControlLoop::output(const Sample& s, double force_n, const hal::ActuatorCommand& test) noexcept {
  switch (mode_) {
    case Mode::kFault: return safe_command();
    case Mode::kMovementTest: return test;
    case Mode::kDisarmed: return hal::ActuatorCommand::from_control(params_.controller.law.offset_v, false);
    case Mode::kHold: return hal::ActuatorCommand::from_control(hold_law_.command_v(hold_, t_s_, force_n, s.good), true);
    case Mode::kArmed: break;
  }
  const double u = detector_.stopped() ? law_.resting_control_v(y_d_m_, detector_.rest_position_m())
                                       : law_.control_v(y_d_m_, s.frame.y_m, differentiator_.velocity_m_per_s(),
                                                        differentiator_.acceleration_m_per_s2());
  return hal::ActuatorCommand::from_control(u, true);
}

// The set point, mode and fault cause in atomics (command validation, the systemd notifier); the
// tick's record; the heartbeat.
void ControlLoop::publish(const Sample& s, double force_n, const hal::ActuatorCommand& command) noexcept {
  out_->setpoint_m.store(y_d_m_, std::memory_order_relaxed);
  out_->mode.store(mode_, std::memory_order_relaxed);
  out_->fault_cause.store(fault_cause_, std::memory_order_relaxed);
  TickRecord r;
  r.seq = seq_++;
  r.t_s = t_s_;
  r.y_d_m = y_d_m_;
  r.y_m = s.frame.y_m;
  r.v_hat_m_per_s = differentiator_.velocity_m_per_s();
  r.a_hat_m_per_s2 = differentiator_.acceleration_m_per_s2();
  r.p_p_pa = s.frame.p_p_pa;
  r.p_n_pa = s.frame.p_n_pa;
  r.force_n = force_n;
  r.u_v = command.u_p_v;
  r.u_n_v = command.u_n_v;
  r.stuck = detector_.stopped();
  r.mode = mode_;
  r.sensor_validity = s.frame.validity;
  r.hold_integral_v = mode_ == Mode::kHold ? hold_.integral_v : 0.0;
  if (!out_->ticks.try_push(r)) ++out_->ticks_dropped;
  out_->heartbeat.store(seq_, std::memory_order_release);
}

// ---------------------------------------------------------------------------------------------
// Events

LoopEvent ControlLoop::event(LoopEvent::Kind kind, double t_s, double y_m) const noexcept {
  LoopEvent e;
  e.kind = kind;
  e.stop_index = stops_;
  e.t_s = t_s;
  e.y_m = y_m;
  e.y_d_m = y_d_m_;
  return e;
}

void ControlLoop::push(LoopEvent e) noexcept {
  e.tick_seq = seq_;  // the record of this tick, pushed at its end, carries seq_
  if (!out_->events.try_push(e)) ++out_->events_dropped;
}

hal::ActuatorCommand ControlLoop::safe_command() const noexcept {
  const auto& law = params_.controller.law;
  if (params_.controller.supervisor.safe_output == SafeOutput::kExhaust)
    return {-law.max_voltage_v, -law.max_voltage_v, false};  // both chambers to the exhaust
  return hal::ActuatorCommand::from_control(law.offset_v, false);
}

void ControlLoop::stop() noexcept {
  transition({.event = ModeEvent::kRunStops, .y_m = detector_last_y_});  // the movement test aborted
  out_->mode.store(mode_, std::memory_order_relaxed);
  (void)backend_->write(safe_command());
}

}  // namespace pneu::controller
