#include "pneu/controller/movement_test.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "pneu/config/config.hpp"
#include "pneu/controller/clock.hpp"
#include "pneu/controller/loop_params.hpp"

namespace pneu::controller {

const char* movement_finding_name(MovementFinding f) noexcept {
  switch (f) {
    case MovementFinding::kPassed: return "passed";
    case MovementFinding::kTubesSwapped: return "tubes-swapped";
    case MovementFinding::kPressureSensorsSwapped: return "pressure-sensors-swapped";
    case MovementFinding::kPositionReversed: return "position-reversed";
    case MovementFinding::kPositionNotResponding: return "position-not-responding";
    case MovementFinding::kPressurePDead: return "p_P-dead";
    case MovementFinding::kPressureNDead: return "p_N-dead";
    case MovementFinding::kNoResponse: return "no-response";
    case MovementFinding::kInconsistent: return "inconsistent";
    case MovementFinding::kInvalidReading: return "invalid-reading";
    case MovementFinding::kEStop: return "e-stop";
    case MovementFinding::kComms: return "comms";
    case MovementFinding::kInterrupted: return "interrupted";
  }
  return "unknown";
}

const char* movement_finding_text(MovementFinding f) noexcept {
  switch (f) {
    case MovementFinding::kPassed:
      return "+u moved the carriage towards +y, raised p_P and lowered p_N; every sensor responded";
    case MovementFinding::kTubesSwapped:
      return "tubes swapped: +u moved the carriage towards -y, lowered p_P and raised p_N (valve P feeds chamber N, "
             "valve N chamber P)";
    case MovementFinding::kPressureSensorsSwapped:
      return "pressure sensors swapped: +u moved the carriage towards +y, but the p_P reading fell and the p_N reading "
             "rose (the chamber P and N transmitters are on each other's channel)";
    case MovementFinding::kPositionReversed:
      return "position sensor reversed: the pressures answered +u rightly, but the position reading went towards -y";
    case MovementFinding::kPositionNotResponding:
      return "position sensor not responding: the pressures changed, the position reading did not (a dead sensor, "
             "or the carriage blocked)";
    case MovementFinding::kPressurePDead:
      return "p_P sensor dead: the chamber P pressure reading did not change while the valves drove the chambers";
    case MovementFinding::kPressureNDead:
      return "p_N sensor dead: the chamber N pressure reading did not change while the valves drove the chambers";
    case MovementFinding::kNoResponse:
      return "no response: neither the position nor a pressure reading changed (valve power, the supply pressure, "
             "or the valve outputs' wiring)";
    case MovementFinding::kInconsistent:
      return "inconsistent: the readings changed, but not as a working bench or a single wiring fault makes them";
    case MovementFinding::kInvalidReading:
      return "a sensor reading was invalid during the test (out of its converter's range, or not a number)";
    case MovementFinding::kEStop: return "the e-stop was pressed during the test";
    case MovementFinding::kComms:
      return "no good sample from the backend for longer than controller.comms_fault_after_s during the test";
    case MovementFinding::kInterrupted: return "interrupted by a stop request";
  }
  return "unknown";
}

std::string describe(const MovementTestResult& r) {
  char buf[512];
  std::string s = r.passed() ? "passed" : movement_finding_name(r.finding);
  std::snprintf(buf, sizeof buf, " in %.2f s (y %.1f -> %.1f mm)", r.duration_s, r.y_start_m * 1e3, r.y_end_m * 1e3);
  s += buf;
  for (int i = 0; i < r.pulses; ++i) {
    const MovementPulse& p = r.pulse[i];
    const bool up = p.du_v > 0.0;
    // The change of each pressure the way +u or -u should move it, and the other way.
    std::snprintf(buf, sizeof buf,
                  "%su_0 %+.2f V for %.2f s: y %+.2f mm, p_P %s%.0f / %s%.0f Pa, p_N %s%.0f / %s%.0f Pa",
                  i == 0 ? ": " : "; ", p.du_v, p.duration_s, p.moved_m * 1e3, up ? "+" : "-",
                  up ? p.p_p_rise_pa : p.p_p_fall_pa, up ? "-" : "+", up ? p.p_p_fall_pa : p.p_p_rise_pa,
                  up ? "-" : "+", up ? p.p_n_fall_pa : p.p_n_rise_pa, up ? "+" : "-",
                  up ? p.p_n_rise_pa : p.p_n_fall_pa);
    s += buf;
  }
  return s;
}

namespace {

// From controller.* as the configuration holds it or as the loop does (the same keys).
template <class Controller>
MovementTestBench bench_of(const Controller& c) noexcept {
  MovementTestBench b;
  b.u_0_v = c.law.offset_v;
  b.comms_fault_after_s = std::max(c.comms_fault_after_s, c.period_s());
  b.soft_min_m = c.soft_limit_min_m;
  b.soft_max_m = c.soft_limit_max_m;
  return b;
}

}  // namespace

MovementTestBench MovementTestBench::of(const LoopSettings& c) noexcept { return bench_of(c); }
MovementTestBench MovementTestBench::of(const config::Config& config) noexcept { return bench_of(config.controller); }

MovementTest::MovementTest(const MovementTestConfig& cfg, const MovementTestBench& bench) noexcept
    : cfg_(cfg), bench_(bench) {}

void MovementTest::finish(MovementFinding f) noexcept {
  if (phase_ == Phase::kDone) return;
  result_.finding = f;
  result_.y_end_m = y_m_;
  phase_ = Phase::kDone;
}

void MovementTest::start_pulse(double t_s, const hal::SensorFrame& f) noexcept {
  phase_ = Phase::kPulse;
  t_phase_s_ = t_s;
  y0_m_ = f.y_m;
  p_p0_pa_ = f.p_p_pa;
  p_n0_pa_ = f.p_n_pa;
  result_.pulse[result_.pulses] = MovementPulse{};
  result_.pulse[result_.pulses].du_v = sign_ * cfg_.pulse_v;
}

hal::ActuatorCommand MovementTest::step(double t_s, hal::Status status, const hal::SensorFrame& frame) noexcept {
  if (phase_ == Phase::kDone) return hal::ActuatorCommand::from_control(bench_.u_0_v, false);
  if (!started_) {
    started_ = true;
    t_start_s_ = t_s;
    last_good_s_ = t_s;
  }
  result_.duration_s = t_s - t_start_s_;
  constexpr std::uint32_t kReadingInvalid = hal::kPositionInvalid | hal::kPressurePInvalid | hal::kPressureNInvalid;
  if (frame.estop) {
    finish(MovementFinding::kEStop);
  } else if (status == hal::Status::kOk &&
             ((frame.validity & kReadingInvalid) != 0 || !std::isfinite(frame.y_m) || !std::isfinite(frame.p_p_pa) ||
              !std::isfinite(frame.p_n_pa))) {
    finish(MovementFinding::kInvalidReading);
  } else if (status != hal::Status::kOk || !frame.valid()) {
    if (t_s - last_good_s_ > bench_.comms_fault_after_s) finish(MovementFinding::kComms);
  } else {  // a good sample
    last_good_s_ = t_s;
    y_m_ = frame.y_m;
    if (!have_good_) {
      have_good_ = true;
      result_.y_start_m = frame.y_m;
      // The first pulse towards the side with more room.
      sign_ = frame.y_m >= 0.5 * (bench_.soft_min_m + bench_.soft_max_m) ? -1 : +1;
      start_pulse(t_s, frame);
    } else if (phase_ == Phase::kPulse) {
      MovementPulse& p = result_.pulse[result_.pulses];
      const double dy = frame.y_m - y0_m_;
      const double dp = frame.p_p_pa - p_p0_pa_, dn = frame.p_n_pa - p_n0_pa_;
      p.p_p_rise_pa = std::max(p.p_p_rise_pa, dp);
      p.p_p_fall_pa = std::max(p.p_p_fall_pa, -dp);
      p.p_n_rise_pa = std::max(p.p_n_rise_pa, dn);
      p.p_n_fall_pa = std::max(p.p_n_fall_pa, -dn);
      p.moved_m = dy;
      p.duration_s = t_s - t_phase_s_;
      const bool outside = (frame.y_m > bench_.soft_max_m && dy > 0.0) || (frame.y_m < bench_.soft_min_m && dy < 0.0);
      if (std::abs(dy) >= cfg_.travel_m || p.duration_s >= cfg_.pulse_s || outside) {
        moved_right_ = sign_ * dy >= 0.5 * cfg_.travel_m;
        ++result_.pulses;
        phase_ = Phase::kBrake;
        t_phase_s_ = t_best_s_ = t_s;
        best_m_ = std::abs(dy);
        brake_sign_ = dy >= 0.0 ? +1 : -1;
      }
    } else if (phase_ == Phase::kBrake) {
      // The pressures that broke the carriage away would carry it on for several times the
      // travel: the other way until it goes no further (no new extreme for kBrakeStill_s).
      const double along = brake_sign_ * (frame.y_m - y0_m_);
      if (along > best_m_) best_m_ = along, t_best_s_ = t_s;
      if (t_s - t_best_s_ >= kBrakeStill_s || t_s - t_phase_s_ >= cfg_.pulse_s) {
        phase_ = Phase::kRest;
        t_phase_s_ = t_s;
        // A carriage not seen to go the right way is driven no more (swapped tubes: even u_0 drives
        // it then; a dead position sensor: how far it went is not known): valve power off at once.
        if (!moved_right_) finish(judge());
      }
    } else if (phase_ == Phase::kRest && t_s - t_phase_s_ >= cfg_.rest_s) {
      if (result_.pulses >= 2) {
        finish(judge());
      } else {
        sign_ = -sign_;
        start_pulse(t_s, frame);
      }
    }
  }
  if (phase_ == Phase::kDone) return hal::ActuatorCommand::from_control(bench_.u_0_v, false);
  const double u = phase_ == Phase::kPulse   ? bench_.u_0_v + sign_ * cfg_.pulse_v
                   : phase_ == Phase::kBrake ? bench_.u_0_v - sign_ * cfg_.pulse_v  // the pulse reversed, whatever the wiring
                                             : bench_.u_0_v;
  return hal::ActuatorCommand::from_control(u, true);
}

namespace {
// How a reading answered the pulses: the way a working bench answers, the other way, not at all,
// or each pulse differently.
enum class Way { kRight, kReversed, kNone, kMixed };

Way combine(const Way* ways, int n) noexcept {
  bool right = false, reversed = false;
  for (int i = 0; i < n; ++i) {
    right = right || ways[i] == Way::kRight;
    reversed = reversed || ways[i] == Way::kReversed;
  }
  return right && reversed ? Way::kMixed : right ? Way::kRight : reversed ? Way::kReversed : Way::kNone;
}

// `good`: the change the way a working bench makes it; `bad`: the other way.
Way pressure_way(double good, double bad, double threshold) noexcept {
  if (good >= threshold && good >= bad) return Way::kRight;
  if (bad >= threshold && bad > good) return Way::kReversed;
  return Way::kNone;
}
}  // namespace

MovementFinding MovementTest::judge() const noexcept {
  Way y[2], p[2], n[2];
  const int count = std::min(result_.pulses, 2);
  const double thr = cfg_.min_pressure_change_pa;
  for (int i = 0; i < count; ++i) {
    const MovementPulse& q = result_.pulse[i];
    const bool up = q.du_v > 0.0;
    const double along = (up ? 1.0 : -1.0) * q.moved_m;  // the motion the way +u / -u should make it
    y[i] = along >= 0.5 * cfg_.travel_m ? Way::kRight : along <= -0.5 * cfg_.travel_m ? Way::kReversed : Way::kNone;
    p[i] = up ? pressure_way(q.p_p_rise_pa, q.p_p_fall_pa, thr) : pressure_way(q.p_p_fall_pa, q.p_p_rise_pa, thr);
    n[i] = up ? pressure_way(q.p_n_fall_pa, q.p_n_rise_pa, thr) : pressure_way(q.p_n_rise_pa, q.p_n_fall_pa, thr);
  }
  const Way wy = combine(y, count), wp = combine(p, count), wn = combine(n, count);
  using F = MovementFinding;
  if (wy == Way::kNone && wp == Way::kNone && wn == Way::kNone) return F::kNoResponse;
  if (wp == Way::kReversed && wn == Way::kReversed) return wy == Way::kRight ? F::kPressureSensorsSwapped : F::kTubesSwapped;
  if (wp == Way::kNone) return F::kPressurePDead;
  if (wn == Way::kNone) return F::kPressureNDead;
  if (wp == Way::kRight && wn == Way::kRight) {
    if (wy == Way::kReversed) return F::kPositionReversed;
    if (wy == Way::kNone) return F::kPositionNotResponding;
    if (wy == Way::kRight) return F::kPassed;
  }
  return F::kInconsistent;
}

MovementTestResult run_movement_test(hal::Backend& backend, Clock& clock, double period_s, MovementTest& test,
                                     const std::atomic<bool>& stop_requested) noexcept {
  const double t0 = clock.now_s();
  std::uint64_t k = 0;  // deadline index
  while (!test.done()) {
    if (stop_requested.load(std::memory_order_relaxed)) {
      test.interrupt();
      break;
    }
    const double deadline = t0 + static_cast<double>(k) * period_s;
    clock.sleep_until(deadline);
    const double t = (clock.simulated() ? deadline : clock.now_s()) - t0;
    hal::SensorFrame frame;
    const hal::Status status = backend.read(t, frame);
    (void)backend.write(test.step(t, status, frame));
    ++k;
    if (!clock.simulated()) {  // skip the deadlines passed after an overrun
      const double now = clock.now_s() - t0;
      k = std::max(k, static_cast<std::uint64_t>(std::floor(now / period_s)) + 1);
    }
  }
  (void)backend.write(test.step(0.0, hal::Status::kOk, hal::SensorFrame{}));  // done: u_0, valve power off
  return test.result();
}

}  // namespace pneu::controller
