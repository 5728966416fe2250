#include "pneu/controller/supervisor.hpp"

#include <algorithm>
#include <cmath>
#include <string_view>

namespace pneu::controller {

namespace {
// Keeps the first cause a check reports in a tick: the order of the checks is their priority.
// With it, the config key of the rule that found it.
struct FirstCause {
  FaultCause cause = FaultCause::kNone;
  const char* key = nullptr;
  void operator()(FaultCause c, const char* rule_key = nullptr) noexcept {
    if (cause != FaultCause::kNone || c == FaultCause::kNone) return;
    cause = c;
    key = rule_key != nullptr ? rule_key : default_key(c);
  }
  // The key of a cause one rule decides.
  static const char* default_key(FaultCause c) noexcept {
    switch (c) {
      case FaultCause::kComms: return "controller.comms_fault_after_s";
      case FaultCause::kSensorFrozen: return "controller.supervisor.frozen_after_s";
      case FaultCause::kSensorJump: return "controller.supervisor.max_speed_m_per_s";
      case FaultCause::kSoftLimit: return "controller.supervisor.overtravel_m";
      case FaultCause::kFollowingError: return "controller.supervisor.following_error_s";
      case FaultCause::kCommandTimeout: return "commands.setpoint_stream_timeout_s";
      case FaultCause::kOscillation: return "controller.supervisor.oscillation_sign_changes";
      case FaultCause::kNotSettled: return "controller.supervisor.settle_time_s";
      default: return nullptr;
    }
  }
};
}  // namespace

const char* fault_name(FaultCause cause) noexcept {
  switch (cause) {
    case FaultCause::kNone: return "none";
    case FaultCause::kEStop: return "e-stop";
    case FaultCause::kComms: return "comms";
    case FaultCause::kSensorRange: return "sensor-range";
    case FaultCause::kSensorNonFinite: return "sensor-non-finite";
    case FaultCause::kSensorFrozen: return "sensor-frozen";
    case FaultCause::kSensorJump: return "sensor-jump";
    case FaultCause::kSoftLimit: return "soft-limit";
    case FaultCause::kFollowingError: return "following-error";
    case FaultCause::kOverrun: return "overrun";
    case FaultCause::kCommandTimeout: return "command-timeout";
    case FaultCause::kOscillation: return "oscillation";
    case FaultCause::kNotSettled: return "not-settled";
    case FaultCause::kAnotherController: return "another-controller";
    case FaultCause::kMovementTest: return "movement-test";
    default: return "unknown";
  }
}

const char* fault_text(FaultCause cause) noexcept {
  switch (cause) {
    case FaultCause::kEStop: return "e-stop pressed: valve power off, safe output until a fault reset once released";
    case FaultCause::kComms: return "sensor samples stale, lost or unreadable (controller.comms_fault_after_s): safe output until a fault reset with good samples";
    case FaultCause::kSensorRange: return "a sensor reading is out of range (controller.supervisor position/pressure range, or the converter's raw range: a rail, a broken wire)";
    case FaultCause::kSensorNonFinite: return "a sensor reading is not a finite number";
    case FaultCause::kSensorFrozen: return "a pressure reading has not changed for controller.supervisor.frozen_after_s: sensor or converter frozen";
    case FaultCause::kSensorJump: return "the position jumped faster than controller.supervisor.max_speed_m_per_s allows: sensor fault";
    case FaultCause::kSoftLimit: return "armed, the position left the soft limits by more than controller.supervisor.overtravel_m";
    case FaultCause::kFollowingError: return "following error: |y_d - y| above controller.supervisor.following_error_m for longer than following_error_s";
    case FaultCause::kOverrun: return "the loop overran its deadlines (controller.supervisor.overruns_in_a_row or max_tick_interval_s)";
    case FaultCause::kCommandTimeout: return "armed, no set point for commands.setpoint_stream_timeout_s: the set-point stream fell silent";
    case FaultCause::kOscillation: return "the loop does not settle: y_d - y changed sign controller.supervisor.oscillation_sign_changes times beyond +-oscillation_amplitude_m within oscillation_window_s (the gains unstable at this position?)";
    case FaultCause::kNotSettled: return "the loop does not settle: no rest within controller.supervisor.settle_time_s of a set-point change (the carriage still moving: unstable or creeping gains?)";
    case FaultCause::kAnotherController: return "another controller publishes its health on this one's LCM channels: two controllers on one bench? Both latch this fault; stop one, then reset the other";
    case FaultCause::kMovementTest: return "the movement test at ARM (controller.movement_test) found the wiring wrong before closed loop: valve power off, safe output; mend what the finding names, reset the fault, and the next ARM tests again";
    default: return "fault";
  }
}

const char* relaxing_costs(const char* key) noexcept {
  if (key == nullptr) return "no key relaxes it: find and remove the cause";
  const std::string_view k = key;
  if (k == "controller.supervisor.max_tick_interval_s")
    return "a longer gap between two ticks is let pass: for that long the valves keep their last command and nothing is "
           "checked. On a PC without a real-time kernel a supervised run (an identification) may raise it to about "
           "0.2 s; a bench left running should not";
  if (k == "controller.supervisor.overruns_in_a_row")
    return "the loop may run late for that many ticks in a row: each late tick acts on an older sample. On a PC without "
           "a real-time kernel raising it (or 0, off) costs only the record's timing, which identification counts and "
           "reports (timing:); max_tick_interval_s still bounds any one gap";
  if (k == "controller.comms_fault_after_s")
    return "stale or lost samples are let pass that long: the loop acts on the last good sample meanwhile";
  if (k == "controller.supervisor.frozen_after_s")
    return "a frozen pressure sensor goes unnoticed that long (0: for ever): the forecasts and the hold act on a stuck "
           "reading";
  if (k == "controller.supervisor.max_speed_m_per_s")
    return "a faster jump of the position reading is taken for motion: a failing potentiometer drives the valves";
  if (k == "controller.supervisor.following_error_s" || k == "controller.supervisor.following_error_m")
    return "the carriage may lag the set point further or longer before the safe output: a blocked carriage pushes "
           "harder meanwhile";
  if (k == "controller.supervisor.settle_time_s" || k == "controller.supervisor.oscillation_sign_changes")
    return "a loop that does not settle drives on that much longer: look at the gains first";
  if (k == "controller.supervisor.overtravel_m")
    return "the carriage may pass the soft limits further before the safe output: it nears the end stops";
  if (k == "controller.movement_test")
    return "controller.movement_test.enabled: false arms without the test: the law then drives a miswired bench the "
           "wrong way, at full gain; mend the wiring instead";
  if (k == "commands.setpoint_stream_timeout_s")
    return "the set points may fall silent longer before the safe output: the carriage holds the last one meanwhile";
  return "the check it decides is made later or not at all: see docs/configuration.md";
}

Supervisor::Supervisor(const LoopParams& params)
    : cfg_(params.controller.supervisor),
      period_s_(params.controller.period_s()),
      comms_fault_after_s_(params.controller.comms_fault_after_s),
      soft_min_m_(params.controller.soft_limit_min_m),
      soft_max_m_(params.controller.soft_limit_max_m),
      stream_timeout_s_(params.setpoint_stream_timeout_s) {}

void Supervisor::reset(double t_s) noexcept {
  estop_ = false;
  frozen_ = false;
  sample_good_ = true;
  bad_since_s_ = -1.0;
  have_last_y_ = false;
  p_p_changed_s_ = p_n_changed_s_ = t_s;
  last_p_p_pa_ = last_p_n_pa_ = std::nan("");
  following_since_s_ = -1.0;
  forget_settling();
  last_tick_t_s_ = -1.0;
  overruns_in_a_row_ = 0;
  overrun_fault_ = false;
}

void Supervisor::on_arm() noexcept {
  following_since_s_ = -1.0;
  forget_settling();
}

void Supervisor::forget_settling() noexcept {
  last_y_d_m_ = std::nan("");
  error_side_ = 0;
  sign_changes_ = 0;
  settle_since_s_ = -1.0;
  was_at_rest_ = true;
}

FaultCause Supervisor::not_settling(const SupervisedTick& tick) noexcept {
  const double t = tick.t_s;
  const double amplitude_m = cfg_.oscillation_amplitude_m;
  const bool first = std::isnan(last_y_d_m_);  // the first armed tick: as if the set point just changed
  const bool changed = first || tick.y_d_m != last_y_d_m_;
  // A step beyond the band starts a new move: the swings before it were not this move's. (A
  // stream of small increments, a ramp, keeps counting: an oscillation while tracking is one.)
  if (first || std::abs(tick.y_d_m - last_y_d_m_) > amplitude_m) {
    error_side_ = 0;
    sign_changes_ = 0;
  }
  last_y_d_m_ = tick.y_d_m;
  FaultCause fault = FaultCause::kNone;

  // Oscillation: the side changes only once the error is beyond the band on the other side, so
  // each counted half-swing exceeded the amplitude and noise around zero error counts nothing.
  const double error_m = tick.y_d_m - tick.frame->y_m;
  const int side = error_m > amplitude_m ? +1 : error_m < -amplitude_m ? -1 : error_side_;
  if (error_side_ != 0 && side != error_side_) {
    constexpr std::size_t kRing = SupervisorConfig::kMaxOscillationSignChanges;
    sign_change_t_s_[sign_changes_ % kRing] = t;
    ++sign_changes_;
    const std::uint32_t n = cfg_.oscillation_sign_changes;
    // The n-th last sign change lies within the window.
    if (n > 0 && sign_changes_ >= n && t - sign_change_t_s_[(sign_changes_ - n) % kRing] <= cfg_.oscillation_window_s)
      fault = FaultCause::kOscillation;
  }
  error_side_ = side;

  // Settle time: from each change of the set point, a rest must begin (a stop confirmed) within
  // settle_time_s, unless the carriage is at rest then anyway (a step too small to move it).
  if (changed) settle_since_s_ = t;
  const bool rest_began = tick.at_rest && !was_at_rest_ && !changed;
  was_at_rest_ = tick.at_rest;
  if (rest_began) settle_since_s_ = -1.0;
  if (cfg_.settle_time_s > 0.0 && settle_since_s_ >= 0.0 && t - settle_since_s_ > cfg_.settle_time_s) {
    if (!tick.at_rest && fault == FaultCause::kNone) fault = FaultCause::kNotSettled;
    settle_since_s_ = -1.0;
  }
  return fault;
}

void Supervisor::note_overrun(bool overran) noexcept {
  overruns_in_a_row_ = overran ? overruns_in_a_row_ + 1 : 0;
  if (cfg_.overruns_in_a_row > 0 && overruns_in_a_row_ >= cfg_.overruns_in_a_row) overrun_fault_ = true;
}

FaultCause Supervisor::check_reading(const hal::SensorFrame& f) noexcept {
  using namespace hal;
  reading_key_ = nullptr;
  if (!std::isfinite(f.y_m) || !std::isfinite(f.p_p_pa) || !std::isfinite(f.p_n_pa)) return FaultCause::kSensorNonFinite;
  if ((f.validity & (kPositionInvalid | kPressurePInvalid | kPressureNInvalid)) != 0) {
    reading_key_ = "hal.sensors (a converter's raw range)";
    return FaultCause::kSensorRange;
  }
  if (f.y_m < cfg_.position_min_m || f.y_m > cfg_.position_max_m) {
    reading_key_ = "controller.supervisor.position_min_m/position_max_m";
    return FaultCause::kSensorRange;
  }
  for (const double p : {f.p_p_pa, f.p_n_pa})
    if (p < cfg_.pressure_min_pa || p > cfg_.pressure_max_pa) {
      reading_key_ = "controller.supervisor.pressure_min_pa/pressure_max_pa";
      return FaultCause::kSensorRange;
    }
  return FaultCause::kNone;
}

FaultCause Supervisor::check(const SupervisedTick& tick) noexcept {
  const FaultCause sample = check_sample(tick);
  const char* sample_key = decided_by_;
  const FaultCause motion = check_motion(tick);
  if (sample == FaultCause::kNone) return motion;
  decided_by_ = sample_key;
  return sample;
}

FaultCause Supervisor::check_sample(const SupervisedTick& tick) noexcept {
  const hal::SensorFrame& f = *tick.frame;
  const double t = tick.t_s;
  FirstCause first;

  estop_ = f.estop;
  if (estop_) first(FaultCause::kEStop);

  // The sample: a reading that is there but wrong is a sensor fault at once; a sample that is
  // missing or old is a comms fault once it has lasted comms_fault_after_s.
  const bool delivered = tick.status == hal::Status::kOk &&
                         (f.validity & (hal::kSampleStale | hal::kCommsError)) == 0;
  const FaultCause reading = delivered ? check_reading(f) : FaultCause::kNone;
  sample_good_ = delivered && reading == FaultCause::kNone;
  sample_cause_ = sample_good_ ? FaultCause::kNone : delivered ? reading : FaultCause::kComms;
  if (!sample_good_) {
    if (bad_since_s_ < 0.0) bad_since_s_ = t;
  } else {
    bad_since_s_ = -1.0;
  }
  first(reading, reading_key_);
  if (!delivered && bad_since_s_ >= 0.0 && t - bad_since_s_ >= comms_fault_after_s_ - 1e-9) first(FaultCause::kComms);

  if (sample_good_ && f.fresh) {
    // The position sensor jumped: further than the fastest plausible motion since the last good
    // sample. The carriage may have moved from the earliest instant the last sample may have been
    // read to the latest this one may have been (each was read within read_span_s before its
    // date): a sample dated late by a stalled I/O thread, then the next one on time, are dated
    // closer together than they were read. At least one loop period, so that two samples taken
    // close together by a fast link are judged over a period.
    if (cfg_.max_speed_m_per_s > 0.0 && have_last_y_) {
      const double dt = std::max(f.t_s - last_y_earliest_t_s_, period_s_);
      if (std::abs(f.y_m - last_y_m_) > cfg_.max_speed_m_per_s * dt) first(FaultCause::kSensorJump);
    }
    have_last_y_ = true;
    last_y_m_ = f.y_m;
    last_y_earliest_t_s_ = f.t_s - std::max(f.read_span_s, 0.0);
    // Frozen pressures: real sensors flicker by at least one converter step.
    if (f.p_p_pa != last_p_p_pa_) {
      p_p_changed_s_ = t;
      last_p_p_pa_ = f.p_p_pa;
    }
    if (f.p_n_pa != last_p_n_pa_) {
      p_n_changed_s_ = t;
      last_p_n_pa_ = f.p_n_pa;
    }
  }
  // Judged on every tick with a good sample, a repeated one too (the module's and the loop's 1 kHz
  // are not in phase: now and then a tick finds no new sample), so that the fault latches on the
  // first tick past the limit.
  if (sample_good_) {
    frozen_ = cfg_.frozen_after_s > 0.0 &&
              (t - p_p_changed_s_ > cfg_.frozen_after_s || t - p_n_changed_s_ > cfg_.frozen_after_s);
    if (frozen_) first(FaultCause::kSensorFrozen);
  }

  decided_by_ = first.key;
  return first.cause;
}

FaultCause Supervisor::check_motion(const SupervisedTick& tick) noexcept {
  const hal::SensorFrame& f = *tick.frame;
  const double t = tick.t_s;
  FirstCause first;
  if (tick.armed && sample_good_) {
    if (f.y_m < soft_min_m_ - cfg_.overtravel_m || f.y_m > soft_max_m_ + cfg_.overtravel_m) first(FaultCause::kSoftLimit);
    if (cfg_.following_error_s > 0.0) {
      if (std::abs(tick.y_d_m - f.y_m) > cfg_.following_error_m) {
        if (following_since_s_ < 0.0) following_since_s_ = t;
        if (t - following_since_s_ > cfg_.following_error_s) first(FaultCause::kFollowingError);
      } else {
        following_since_s_ = -1.0;
      }
    }
    if (const FaultCause c = not_settling(tick); c != FaultCause::kNone) first(c);
  } else if (!tick.armed) {
    following_since_s_ = -1.0;
    forget_settling();
  }

  // Timing: the interval since the last tick (real clock: wake-up times) and overruns in a row.
  if (cfg_.max_tick_interval_s > 0.0 && last_tick_t_s_ >= 0.0 && t - last_tick_t_s_ > cfg_.max_tick_interval_s)
    first(FaultCause::kOverrun, "controller.supervisor.max_tick_interval_s");
  last_tick_t_s_ = t;
  if (overrun_fault_) {
    overrun_fault_ = false;
    first(FaultCause::kOverrun, "controller.supervisor.overruns_in_a_row");
  }

  if (tick.armed && stream_timeout_s_ > 0.0 && t - tick.last_setpoint_t_s > stream_timeout_s_)
    first(FaultCause::kCommandTimeout);
  decided_by_ = first.key;
  return first.cause;
}

}  // namespace pneu::controller
