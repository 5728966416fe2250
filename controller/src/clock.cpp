#include "pneu/controller/clock.hpp"

#include "pneu/hal/monotonic.hpp"

#include <sys/prctl.h>

#include <chrono>
#include <algorithm>
#include <cmath>

namespace pneu::controller {

namespace {
using hal::monotonic_s;
double steady_s() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

RealClock::RealClock() noexcept : epoch_s_(monotonic_s()) {}

double RealClock::now_s() noexcept { return monotonic_s() - epoch_s_; }

void RealClock::sleep_until(double t_s) noexcept { hal::sleep_until_monotonic_s(epoch_s_ + t_s); }

std::unique_ptr<Clock> make_clock(ClockKind kind) {
  if (kind == ClockKind::kReal) return std::make_unique<RealClock>();
  return std::make_unique<SimulatedClock>();
}

void RealClock::prepare_loop_thread() noexcept {
  // Cannot fail for a value above 0 (0 would restore the default slack).
  (void)prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
}

namespace {
void fill(const TimingStats& s, double (&out)[4]) noexcept {
  out[0] = s.min_s();
  out[1] = s.quantile_s(0.5);
  out[2] = s.quantile_s(0.99);
  out[3] = s.max_s();
}
}  // namespace

namespace {
// Statistics of the current health period (the run's totals are in `timing`).
thread_local TimingStats window_wake, window_compute;

void push_health(const ControlLoop& loop, const LoopTiming& timing, double t_s, LoopOutputs& out,
                 bool is_final) noexcept {
  HealthRecord h;
  h.t_s = t_s;
  h.ticks = timing.ticks;
  h.overruns = timing.overruns;
  h.deadlines_skipped = timing.deadlines_skipped;
  fill(window_wake, h.wake_latency_s);
  fill(window_compute, h.compute_s);
  h.ticks_dropped = out.ticks_dropped;
  h.events_dropped = out.events_dropped;
  h.mode = loop.mode();
  h.comms_errors = loop.comms_errors();
  h.fault_cause = loop.fault_cause();
  h.faults = loop.faults();
  h.is_final = is_final;
  (void)out.health.try_push(h);
  window_wake.reset();
  window_compute.reset();
}
}  // namespace

void run_loop(ControlLoop& loop, Clock& clock, double period_s, std::uint64_t deadlines,
              const std::atomic<bool>& stop_requested, LoopTiming& timing,
              const std::function<void()>& between_ticks, double health_period_s,
              LoopOutputs* health, const std::function<void()>& after_start,
              const std::function<void()>& before_time) {
  timing.period_s = period_s;
  window_wake.reset();
  window_compute.reset();
  const auto health_every = health && health_period_s > 0.0
                                ? std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(health_period_s / period_s)))
                                : 0;
  std::uint64_t next_health = health_every;
  clock.prepare_loop_thread();
  if (after_start) after_start();  // first: a thread the backend starts inherits the loop thread's set-up
  loop.open(0.0);  // opens the backend (a connect, a first exchange) before time starts
  if (before_time) before_time();
  loop.begin(0.0);
  const double epoch = clock.now_s();
  timing.epoch_monotonic_s = clock.monotonic_s_at(epoch);
  std::uint64_t k = 0;  // deadline index: deadline k is at k * period (no accumulated rounding)
  while ((deadlines == 0 || k < deadlines) &&
         !stop_requested.load(std::memory_order_relaxed)) {
    const double deadline = static_cast<double>(k) * period_s;
    clock.sleep_until(epoch + deadline);
    const double wake = clock.now_s() - epoch;
    const double c0 = steady_s();
    loop.tick(clock.simulated() ? deadline : wake);
    const double c1 = steady_s();
    timing.wake_latency.add(wake - deadline);
    timing.compute.add(c1 - c0);
    window_wake.add(wake - deadline);
    window_compute.add(c1 - c0);
    ++timing.ticks;
    ++k;
    if (!clock.simulated()) {
      const double end = clock.now_s() - epoch;
      const double next = static_cast<double>(k) * period_s;
      const bool overran = end > next;
      if (overran) {  // skip the deadlines already passed
        ++timing.overruns;
        auto resume = static_cast<std::uint64_t>(std::floor(end / period_s)) + 1;
        if (deadlines != 0) resume = std::min(resume, deadlines);  // the run's own deadlines only
        timing.deadlines_skipped += resume - k;
        k = resume;
      }
      loop.note_overrun(overran);
    }
    if (health_every && timing.ticks >= next_health) {
      next_health += health_every;
      push_health(loop, timing, deadline, *health, false);
    }
    if (between_ticks) between_ticks();
  }
  // The final record: the operator sees how the run ended (mode, cause, counters) even when it
  // ended between two health periods.
  if (health) push_health(loop, timing, static_cast<double>(k) * period_s, *health, true);
}

}  // namespace pneu::controller
