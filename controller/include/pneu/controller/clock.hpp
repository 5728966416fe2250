// The loop's clocks and the fixed-rate runner.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>

#include "pneu/controller/clock_params.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/timing_stats.hpp"

namespace pneu::controller {

/// Time source of the loop, in seconds since an epoch of the clock's choosing.
class Clock {
 public:
  virtual ~Clock() = default;
  [[nodiscard]] virtual double now_s() noexcept = 0;
  /// Returns at or after `t_s`. Real-time safe.
  virtual void sleep_until(double t_s) noexcept = 0;
  [[nodiscard]] virtual bool simulated() const noexcept = 0;
  /// The CLOCK_MONOTONIC reading [s] at this clock's `t_s`, so that other processes' records line
  /// up with the loop's times; NaN for a clock that is not the real one.
  [[nodiscard]] virtual double monotonic_s_at(double /*t_s*/) const noexcept { return std::numeric_limits<double>::quiet_NaN(); }
  /// Prepares the calling thread for sleep_until; run_loop calls it once on the loop thread, after
  /// the loop has started and before time starts. Does nothing unless a clock needs it.
  virtual void prepare_loop_thread() noexcept {}
};

/// CLOCK_MONOTONIC, absolute-deadline sleep with clock_nanosleep(TIMER_ABSTIME).
class RealClock final : public Clock {
 public:
  RealClock() noexcept;
  [[nodiscard]] double now_s() noexcept override;
  void sleep_until(double t_s) noexcept override;
  [[nodiscard]] bool simulated() const noexcept override { return false; }
  [[nodiscard]] double monotonic_s_at(double t_s) const noexcept override { return epoch_s_ + t_s; }
  /// Sets the calling thread's timer slack to 1 ns (prctl PR_SET_TIMERSLACK). A thread under
  /// normal scheduling has 50 us, by which the kernel may defer its wake-ups to group them: the
  /// loop's would sit about that much late. Real-time (SCHED_FIFO) threads have none; there the
  /// call changes nothing. Threads the loop thread creates afterwards inherit it.
  void prepare_loop_thread() noexcept override;

 private:
  double epoch_s_;
};

/// Lockstep with the in-process plant: time jumps to each deadline, nothing sleeps; runs are
/// deterministic and as fast as the CPU allows.
class SimulatedClock final : public Clock {
 public:
  [[nodiscard]] double now_s() noexcept override { return now_s_; }
  void sleep_until(double t_s) noexcept override {
    if (t_s > now_s_) now_s_ = t_s;
  }
  [[nodiscard]] bool simulated() const noexcept override { return true; }

 private:
  double now_s_ = 0.0;
};

/// The clock controller.clock names.
[[nodiscard]] std::unique_ptr<Clock> make_clock(ClockKind kind);

/// Timing of a run. Written by the loop thread; read after the run.
struct LoopTiming {
  TimingStats wake_latency;   ///< actual wake-up minus deadline (0 on the simulated clock)
  TimingStats compute;        ///< wake-up to end of tick, measured on the steady clock
  std::uint64_t ticks = 0;
  std::uint64_t overruns = 0; ///< ticks that ended after the next deadline (those deadlines are skipped)
  std::uint64_t deadlines_skipped = 0;  ///< deadlines passed without a tick after overruns
  double period_s = 0.0;
  /// CLOCK_MONOTONIC at loop time 0 [s] (the real clock; NaN on the simulated one): loop time t is
  /// monotonic t + this, the time base of other processes' records (pneu-plant serve --events).
  double epoch_monotonic_s = std::numeric_limits<double>::quiet_NaN();
};

/// Runs `loop` at a fixed period from loop time 0 over the deadlines 0 .. `deadlines` - 1 (0 = no
/// limit; deadlines skipped after an overrun count, so the run never outlasts them) or until
/// `stop_requested`. `between_ticks`, when set, runs after each tick outside the timed part (the
/// simulated clock's way of servicing the non-real-time side deterministically).
/// Every `health_period_s` (0: never) the period's timing goes to `health` (a full queue drops it).
/// `after_start`, when set, runs on the loop thread before the backend opens and before time
/// starts: the place for the loop thread's real-time set-up, which a thread the backend starts
/// inherits (a Modbus module's I/O thread: each tick's reading comes through it, so it keeps the
/// loop's priority and CPU). `clock.prepare_loop_thread()` runs just before it. `before_time`,
/// when set, runs on the loop thread after `after_start`, the backend open and the loop not begun
/// yet (its first reading is taken after it): the movement test's place; what it throws ends the
/// run before any tick.
void run_loop(ControlLoop& loop, Clock& clock, double period_s, std::uint64_t deadlines,
              const std::atomic<bool>& stop_requested, LoopTiming& timing,
              const std::function<void()>& between_ticks = {}, double health_period_s = 0.0,
              LoopOutputs* health = nullptr, const std::function<void()>& after_start = {},
              const std::function<void()>& before_time = {});

}  // namespace pneu::controller
