#include "pneu/controller/loop.hpp"

#include <algorithm>
#include <cmath>
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

// Commands were validated off the loop; here they only take effect. A set point leaves the soft
// limits only through a step that the validator could not foresee: clamp it.
void ControlLoop::apply_commands(double y_m) noexcept {
  const auto& c = params_.controller;
  LoopCommand cmd;
  while (out_->commands.try_pop(cmd)) {
    switch (cmd.kind) {
      case LoopCommand::Kind::kSetPoint:
        // Queued before the fault: stale now. During the movement test the validator refuses set
        // points (the pass holds where the carriage is): one queued before it is dropped.
        if (mode_ == Mode::kFault || mode_ == Mode::kMovementTest) break;
        y_d_m_ = std::clamp(cmd.value_m, c.soft_limit_min_m, c.soft_limit_max_m);
        schedule_active_ = false;
        last_setpoint_t_s_ = t_s_;
        break;
      case LoopCommand::Kind::kSetPointStep:
        if (mode_ == Mode::kFault || mode_ == Mode::kMovementTest) break;
        y_d_m_ = std::clamp(y_d_m_ + cmd.value_m, c.soft_limit_min_m, c.soft_limit_max_m);
        schedule_active_ = false;
        last_setpoint_t_s_ = t_s_;
        break;
      case LoopCommand::Kind::kArm:
        // The first ARM of a run started disarmed on a real backend tests the wiring first.
        if (mode_ == Mode::kDisarmed) {
          if (movement_test_due_) start_movement_test(y_m);
          else arm_here(y_m);
        }
        break;
      case LoopCommand::Kind::kDisarm:
        if (mode_ == Mode::kHold) end_hold(HoldEnd::kDisarmed, t_s_, y_m, Mode::kDisarmed);
        if (mode_ == Mode::kMovementTest) {
          end_movement_test(MovementTestEnd::kDisarmed, t_s_, y_m);
          mode_ = Mode::kDisarmed;
        }
        if (mode_ == Mode::kArmed) mode_ = Mode::kDisarmed;
        break;
      case LoopCommand::Kind::kFaultReset:
        // The cause must be gone: a reset while the e-stop is still pressed, or while the
        // samples are still bad, keeps the fault. A reset disarms: arming again is a separate,
        // later command, and only what is measured from then on drives the valves.
        if (mode_ == Mode::kFault) {
          LoopEvent e = event(LoopEvent::Kind::kFaultReset, t_s_, y_m);
          const FaultCause external = out_->external_fault.load(std::memory_order_relaxed);
          if (supervisor_.cause_present() || external != FaultCause::kNone) {
            e.kind = LoopEvent::Kind::kResetRefused;
            e.fault_cause = supervisor_.cause_present() ? supervisor_.present_cause() : external;
          } else {
            e.kind = LoopEvent::Kind::kFaultReset;
            e.fault_cause = fault_cause_;
            mode_ = Mode::kDisarmed;
            fault_cause_ = FaultCause::kNone;
          }
          push(e);
        }
        break;
    }
  }
}

void ControlLoop::arm_here(double y_m) noexcept {
  const auto& c = params_.controller;
  mode_ = Mode::kArmed;
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
  mode_ = Mode::kMovementTest;
  movement_test_ = MovementTest(c.movement_test, MovementTestBench::of(c));
  // The set point shown meanwhile: where the carriage is (a pass arms holding where it is then).
  y_d_m_ = std::clamp(y_m, c.soft_limit_min_m, c.soft_limit_max_m);
  schedule_active_ = false;
}

void ControlLoop::end_movement_test(MovementTestEnd why, double t_s, double y_m, FaultCause cause) noexcept {
  if (why != MovementTestEnd::kPassed && why != MovementTestEnd::kFinding) movement_test_.interrupt();
  LoopEvent e = event(LoopEvent::Kind::kMovementTest, t_s, y_m);
  e.movement_end = why;
  e.movement_test = movement_test_.result();
  e.fault_cause = cause;
  push(e);
}

void ControlLoop::latch_fault(FaultCause cause, double t_s, double y_m, const char* key) noexcept {
  if (mode_ == Mode::kFault) return;
  if (mode_ == Mode::kHold) end_hold(HoldEnd::kFault, t_s, y_m, Mode::kFault);
  if (mode_ == Mode::kMovementTest && cause != FaultCause::kMovementTest)
    end_movement_test(MovementTestEnd::kFault, t_s, y_m, cause);
  mode_ = Mode::kFault;
  fault_cause_ = cause;
  ++faults_;
  LoopEvent e = event(LoopEvent::Kind::kFault, t_s, y_m);
  e.fault_cause = cause;
  e.fault_key = key;
  if (cause == FaultCause::kMovementTest) e.movement_test = movement_test_.result();
  push(e);
}

void ControlLoop::start_hold(double t_s, double y_m, double force_n, int reach_direction) noexcept {
  mode_ = Mode::kHold;
  hold_ = HoldState{};
  hold_.t0_s = t_s;
  hold_.force0_n = force_n;
  if (reach_direction != 0) {
    // Reaching: the reference starts at hold.reach_preload of the bound it must cross (unless the
    // force is past that already), so that the ramp's slow part is spent near the breakaway.
    const double bound = reach_direction > 0 ? params_.friction.static_positive_n : params_.friction.static_negative_n;
    const double preload = params_.controller.hold.reach_preload * bound;
    hold_.force0_n = reach_direction > 0 ? std::max(force_n, preload) : std::min(force_n, preload);
  }
  hold_.u0_v = law_.resting_control_v(y_d_m_, detector_.rest_position_m());  // the u* in force
  hold_.target_n = 0.5 * (params_.friction.static_positive_n + params_.friction.static_negative_n);
  hold_.reach_direction = reach_direction;
  hold_.reach_rate_n_per_s = reach_rate_scale_ * params_.controller.hold.reach_rate_n_per_s;
  hold_y_d_m_ = y_d_m_;
  LoopEvent e = event(LoopEvent::Kind::kHoldStart, t_s, y_m);
  e.force_n = force_n;
  e.direction = reach_direction;
  e.hold = hold_;
  push(e);
}

void ControlLoop::end_hold(HoldEnd why, double t_s, double y_m, Mode next) noexcept {
  mode_ = next;
  LoopEvent e = event(LoopEvent::Kind::kHoldEnd, t_s, y_m);
  e.hold_end = why;
  push(e);
}

void ControlLoop::tick(double t_s) noexcept {
  t_s_ = t_s;
  hal::SensorFrame frame;
  const hal::Status status = backend_->read(t_s, frame);
  if (status != hal::Status::kOk) ++comms_errors_;  // counted for health
  const hal::SensorFrame sample = frame;  // as read: the movement test judges it itself

  // The supervisor, first on the sample: e-stop, readings, comms. A fault latches the safe output
  // until a reset once the cause is gone.
  SupervisedTick st;
  st.t_s = t_s;
  st.status = status;
  st.frame = &frame;
  if (const FaultCause cause = supervisor_.check_sample(st); cause != FaultCause::kNone)
    latch_fault(cause, t_s, frame.y_m, supervisor_.decided_by());
  if (const FaultCause cause = out_->external_fault.load(std::memory_order_relaxed); cause != FaultCause::kNone)
    latch_fault(cause, t_s, frame.y_m);  // what the service thread sees: another controller
  const bool read_ok = supervisor_.sample_good();
  const double y_measured_m = frame.y_m;
  // Without a good sample, keep the last position: a stale or invalid value must not reach the
  // differentiator or the detector.
  if (!read_ok) frame.y_m = detector_last_y_;
  apply_commands(frame.y_m);
  const auto& schedule = params_.controller.schedule;
  while (schedule_active_ && next_step_ < schedule.size() && schedule[next_step_].t_s <= t_s + 1e-9)
    y_d_m_ = schedule[next_step_++].position_m;
  // The movement test at ARM drives the valves open loop until it ends: a pass arms the law here
  // and now, holding where the carriage is; a finding latches the movement-test fault. (A fault
  // above, a disarm or the run's stop abort it: see latch_fault, apply_commands, stop.)
  hal::ActuatorCommand test_command;
  if (mode_ == Mode::kMovementTest) {
    test_command = movement_test_.step(t_s, status, sample);
    if (movement_test_.done() && movement_test_.result().passed()) {
      // Not again at a later ARM of this run: the wiring does not change while pneud runs, and
      // each test moves the carriage open loop by millimetres.
      movement_test_due_ = false;
      arm_here(frame.y_m);
      end_movement_test(MovementTestEnd::kPassed, t_s, frame.y_m);  // with the set point armed
    } else if (movement_test_.done()) {
      // Still due: after a reset the next ARM tests again (the wiring may have been mended).
      end_movement_test(MovementTestEnd::kFinding, t_s, y_measured_m);
      latch_fault(FaultCause::kMovementTest, t_s, y_measured_m, "controller.movement_test");
    }
  }
  // ... then on the motion, with this tick's commands and set point in force: soft limits,
  // following error, settling, timing, the set-point stream.
  st.armed = drives(mode_);
  st.y_d_m = y_d_m_;
  st.last_setpoint_t_s = last_setpoint_t_s_;
  st.at_rest = detector_.stopped();  // as of the last good sample: the detector runs below
  if (const FaultCause cause = supervisor_.check_motion(st); cause != FaultCause::kNone)
    latch_fault(cause, t_s, y_measured_m, supervisor_.decided_by());

  // Differentiate new samples only (a slow link repeats them), over the ticks since the last new
  // one: the loop's period keeps the arrival jitter of the samples out of the derivatives.
  ++ticks_since_sample_;
  if (read_ok && frame.fresh) {
    differentiator_.update(frame.y_m, static_cast<double>(ticks_since_sample_) * params_.controller.period_s());
    ticks_since_sample_ = 0;
  }
  detector_last_y_ = frame.y_m;
  const double force = force_.force_n(frame.p_p_pa, frame.p_n_pa);
  // Stops and starts are judged from good samples only (a snapshot must hold real pressures).
  switch (read_ok ? detector_.update(t_s, frame.y_m) : StopDetectorEvent::kNone) {
    case StopDetectorEvent::kStop: {
      LoopEvent e;
      e.kind = LoopEvent::Kind::kStop;
      e.stop_index = ++stops_;
      e.t_s = detector_.event_time_s();
      e.y_m = detector_.event_position_m();
      e.force_n = force;
      e.y_d_m = y_d_m_;
      e.snapshot.t_s = t_s;
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

  // The in-position hold: handed back on a set-point change, on a reading outside the window (the
  // tick it comes), on any start; taken once at rest within the window, away from the end stops.
  const auto& hold = params_.controller.hold;
  if (mode_ == Mode::kHold) {
    // A reading beyond the window by more than the stop detector's rest band: the band is what the
    // sensor's noise and steps span at rest, so that a rest on the window's edge is not handed
    // back and taken again tick after tick.
    const double rest_band_m = params_.controller.stop_detector.rest_band_m;
    const bool reaching = hold_.reach_direction != 0;
    const HoldEnd why = y_d_m_ != hold_y_d_m_ ? HoldEnd::kSetPoint
                        : !reaching && read_ok && std::abs(frame.y_m - y_d_m_) > hold.window_m + rest_band_m ? HoldEnd::kLeftWindow
                        : !detector_.stopped() ? HoldEnd::kMoved
                                               : HoldEnd::kNone;
    if (why != HoldEnd::kNone) end_hold(why, t_s, frame.y_m, Mode::kArmed);
  } else if (hold.enabled && mode_ == Mode::kArmed && read_ok && detector_.stopped() &&
             std::abs(detector_.rest_position_m()) < half_stroke_m_ - kEndStopTolerance_m) {
    const double error_m = y_d_m_ - detector_.rest_position_m();
    if (std::abs(error_m) <= hold.window_m) {
      start_hold(t_s, frame.y_m, force, 0);
    } else if (std::abs(error_m) <= hold.reach_m) {
      // A new set point starts afresh; a reach back the other way means the last one went past the
      // set point: gentler from now on (each breakaway then carries the carriage less far).
      const int direction = error_m > 0.0 ? +1 : -1;
      if (y_d_m_ != reach_y_d_m_) {
        reach_y_d_m_ = y_d_m_;
        last_reach_direction_ = 0;
        reach_rate_scale_ = 1.0;
      }
      if (last_reach_direction_ == -direction) reach_rate_scale_ = std::max(reach_rate_scale_ * 0.5, 1.0 / 64.0);
      last_reach_direction_ = direction;
      start_hold(t_s, frame.y_m, force, direction);
    }
  }

  const double v_hat = differentiator_.velocity_m_per_s();
  const double a_hat = differentiator_.acceleration_m_per_s2();
  // Valve power follows the armed state. Disarmed, the outputs sit at the neutral voltage u_0
  // (F_e(u_0) = 0: the chambers hold); in fault, at the configured safe output.
  const bool armed = drives(mode_);
  // At rest the law holds u* (Eq. 11) at the rest position, exactly as the restart forecasts
  // assume: the carriage has no velocity or acceleration to damp, and neither the differentiator's
  // decaying residue nor the sensor's noise and steps reach the valves through the gains.
  const double u = !armed                    ? params_.controller.law.offset_v
                   : mode_ == Mode::kHold   ? hold_law_.command_v(hold_, t_s, force, read_ok)
                   : detector_.stopped()    ? law_.resting_control_v(y_d_m_, detector_.rest_position_m())
                                            : law_.control_v(y_d_m_, frame.y_m, v_hat, a_hat);
  const hal::ActuatorCommand command = mode_ == Mode::kFault          ? safe_command()
                                       : mode_ == Mode::kMovementTest ? test_command
                                                                      : hal::ActuatorCommand::from_control(u, armed);
  if (backend_->write(command) != hal::Status::kOk) ++comms_errors_;
  out_->setpoint_m.store(y_d_m_, std::memory_order_relaxed);
  out_->mode.store(mode_, std::memory_order_relaxed);
  out_->fault_cause.store(fault_cause_, std::memory_order_relaxed);

  TickRecord r;
  r.seq = seq_++;
  r.t_s = t_s;
  r.y_d_m = y_d_m_;
  r.y_m = frame.y_m;
  r.v_hat_m_per_s = v_hat;
  r.a_hat_m_per_s2 = a_hat;
  r.p_p_pa = frame.p_p_pa;
  r.p_n_pa = frame.p_n_pa;
  r.force_n = force;
  r.u_v = command.u_p_v;
  r.u_n_v = command.u_n_v;
  r.stuck = detector_.stopped();
  r.mode = mode_;
  r.sensor_validity = frame.validity;
  r.hold_integral_v = mode_ == Mode::kHold ? hold_.integral_v : 0.0;
  if (!out_->ticks.try_push(r)) ++out_->ticks_dropped;
  out_->heartbeat.store(seq_, std::memory_order_release);
}

hal::ActuatorCommand ControlLoop::safe_command() const noexcept {
  const auto& law = params_.controller.law;
  if (params_.controller.supervisor.safe_output == config::SafeOutput::kExhaust)
    return {-law.max_voltage_v, -law.max_voltage_v, false};  // both chambers to the exhaust
  return hal::ActuatorCommand::from_control(law.offset_v, false);
}

void ControlLoop::stop() noexcept {
  if (mode_ == Mode::kMovementTest) {  // the run stops during the movement test: aborted
    end_movement_test(MovementTestEnd::kStopped, t_s_, detector_last_y_);
    mode_ = Mode::kDisarmed;
    out_->mode.store(mode_, std::memory_order_relaxed);
  }
  (void)backend_->write(safe_command());
}

}  // namespace pneu::controller
