#include "pneu/controller/supervisor.hpp"

#include <algorithm>
#include <cmath>

namespace pneu::controller {

namespace {
// Keeps the first cause a check reports in a tick: the order of the checks is their priority.
struct FirstCause {
  FaultCause cause = kFaultNone;
  void operator()(FaultCause c) noexcept {
    if (cause == kFaultNone) cause = c;
  }
};
}  // namespace

const char* fault_name(std::uint8_t cause) noexcept {
  switch (cause) {
    case kFaultNone: return "none";
    case kFaultEStop: return "e-stop";
    case kFaultComms: return "comms";
    case kFaultSensorRange: return "sensor-range";
    case kFaultSensorNonFinite: return "sensor-non-finite";
    case kFaultSensorFrozen: return "sensor-frozen";
    case kFaultSensorJump: return "sensor-jump";
    case kFaultSoftLimit: return "soft-limit";
    case kFaultFollowingError: return "following-error";
    case kFaultOverrun: return "overrun";
    case kFaultCommandTimeout: return "command-timeout";
    default: return "unknown";
  }
}

const char* fault_text(std::uint8_t cause) noexcept {
  switch (cause) {
    case kFaultEStop: return "e-stop pressed: valve power off, safe output until a fault reset once released";
    case kFaultComms: return "sensor samples stale, lost or unreadable (controller.comms_fault_after_s): safe output until a fault reset with good samples";
    case kFaultSensorRange: return "a sensor reading is out of range (controller.supervisor position/pressure range, or the converter's raw range: a rail, a broken wire)";
    case kFaultSensorNonFinite: return "a sensor reading is not a finite number";
    case kFaultSensorFrozen: return "a pressure reading has not changed for controller.supervisor.frozen_after_s: sensor or converter frozen";
    case kFaultSensorJump: return "the position jumped faster than controller.supervisor.max_speed_m_per_s allows: sensor fault";
    case kFaultSoftLimit: return "armed, the position left the soft limits by more than controller.supervisor.overtravel_m";
    case kFaultFollowingError: return "following error: |y_d - y| above controller.supervisor.following_error_m for longer than following_error_s";
    case kFaultOverrun: return "the loop overran its deadlines (controller.supervisor.overruns_in_a_row or max_tick_interval_s)";
    case kFaultCommandTimeout: return "armed, no set point for commands.setpoint_stream_timeout_s: the set-point stream fell silent";
    default: return "fault";
  }
}

Supervisor::Supervisor(const config::Config& config)
    : cfg_(config.controller.supervisor),
      period_s_(config.controller.period_s()),
      comms_fault_after_s_(config.controller.comms_fault_after_s),
      soft_min_m_(config.controller.soft_limit_min_m),
      soft_max_m_(config.controller.soft_limit_max_m),
      stream_timeout_s_(config.commands.setpoint_stream_timeout_s) {}

void Supervisor::reset(double t_s) noexcept {
  estop_ = false;
  frozen_ = false;
  sample_good_ = true;
  bad_since_s_ = -1.0;
  have_last_y_ = false;
  p_p_changed_s_ = p_n_changed_s_ = t_s;
  last_p_p_pa_ = last_p_n_pa_ = std::nan("");
  following_since_s_ = -1.0;
  last_tick_t_s_ = -1.0;
  overruns_in_a_row_ = 0;
  overrun_fault_ = false;
}

void Supervisor::note_overrun(bool overran) noexcept {
  overruns_in_a_row_ = overran ? overruns_in_a_row_ + 1 : 0;
  if (cfg_.overruns_in_a_row > 0 && overruns_in_a_row_ >= cfg_.overruns_in_a_row) overrun_fault_ = true;
}

FaultCause Supervisor::check_reading(const hal::SensorFrame& f) noexcept {
  using namespace hal;
  if (!std::isfinite(f.y_m) || !std::isfinite(f.p_p_pa) || !std::isfinite(f.p_n_pa)) return kFaultSensorNonFinite;
  if ((f.validity & (kPositionInvalid | kPressurePInvalid | kPressureNInvalid)) != 0) return kFaultSensorRange;
  if (f.y_m < cfg_.position_min_m || f.y_m > cfg_.position_max_m) return kFaultSensorRange;
  for (const double p : {f.p_p_pa, f.p_n_pa})
    if (p < cfg_.pressure_min_pa || p > cfg_.pressure_max_pa) return kFaultSensorRange;
  return kFaultNone;
}

FaultCause Supervisor::check(const SupervisedTick& tick) noexcept {
  const FaultCause sample = check_sample(tick);
  const FaultCause motion = check_motion(tick);
  return sample != kFaultNone ? sample : motion;
}

FaultCause Supervisor::check_sample(const SupervisedTick& tick) noexcept {
  const hal::SensorFrame& f = *tick.frame;
  const double t = tick.t_s;
  FirstCause first;

  estop_ = f.estop;
  if (estop_) first(kFaultEStop);

  // The sample: a reading that is there but wrong is a sensor fault at once; a sample that is
  // missing or old is a comms fault once it has lasted comms_fault_after_s.
  const bool delivered = tick.status == hal::Status::kOk &&
                         (f.validity & (hal::kSampleStale | hal::kCommsError)) == 0;
  const FaultCause reading = delivered ? check_reading(f) : kFaultNone;
  sample_good_ = delivered && reading == kFaultNone;
  sample_cause_ = sample_good_ ? kFaultNone : delivered ? reading : kFaultComms;
  if (!sample_good_) {
    if (bad_since_s_ < 0.0) bad_since_s_ = t;
  } else {
    bad_since_s_ = -1.0;
  }
  first(reading);
  if (!delivered && bad_since_s_ >= 0.0 && t - bad_since_s_ >= comms_fault_after_s_ - 1e-9) first(kFaultComms);

  if (sample_good_ && f.fresh) {
    // The position sensor jumped: further than the fastest plausible motion since the last good
    // sample (at least one loop period apart, so that two samples taken close together by a
    // fast link are judged over a period).
    if (cfg_.max_speed_m_per_s > 0.0 && have_last_y_) {
      const double dt = std::max(f.t_s - last_y_t_s_, period_s_);
      if (std::abs(f.y_m - last_y_m_) > cfg_.max_speed_m_per_s * dt) first(kFaultSensorJump);
    }
    have_last_y_ = true;
    last_y_m_ = f.y_m;
    last_y_t_s_ = f.t_s;
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
    if (frozen_) first(kFaultSensorFrozen);
  }

  return first.cause;
}

FaultCause Supervisor::check_motion(const SupervisedTick& tick) noexcept {
  const hal::SensorFrame& f = *tick.frame;
  const double t = tick.t_s;
  FirstCause first;
  if (tick.armed && sample_good_) {
    if (f.y_m < soft_min_m_ - cfg_.overtravel_m || f.y_m > soft_max_m_ + cfg_.overtravel_m) first(kFaultSoftLimit);
    if (cfg_.following_error_s > 0.0) {
      if (std::abs(tick.y_d_m - f.y_m) > cfg_.following_error_m) {
        if (following_since_s_ < 0.0) following_since_s_ = t;
        if (t - following_since_s_ > cfg_.following_error_s) first(kFaultFollowingError);
      } else {
        following_since_s_ = -1.0;
      }
    }
  } else if (!tick.armed) {
    following_since_s_ = -1.0;
  }

  // Timing: the interval since the last tick (real clock: wake-up times) and overruns in a row.
  if (cfg_.max_tick_interval_s > 0.0 && last_tick_t_s_ >= 0.0 && t - last_tick_t_s_ > cfg_.max_tick_interval_s)
    first(kFaultOverrun);
  last_tick_t_s_ = t;
  if (overrun_fault_) {
    overrun_fault_ = false;
    first(kFaultOverrun);
  }

  if (tick.armed && stream_timeout_s_ > 0.0 && t - tick.last_setpoint_t_s > stream_timeout_s_)
    first(kFaultCommandTimeout);
  return first.cause;
}

}  // namespace pneu::controller
