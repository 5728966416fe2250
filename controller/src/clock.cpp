#include "pneu/controller/clock.hpp"

#include <time.h>

#include <cerrno>
#include <chrono>
#include <cmath>

namespace pneu::controller {

namespace {
double monotonic_s() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}
double steady_s() noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
}  // namespace

RealClock::RealClock() noexcept : epoch_s_(monotonic_s()) {}

double RealClock::now_s() noexcept { return monotonic_s() - epoch_s_; }

void RealClock::sleep_until(double t_s) noexcept {
  const double abs_s = epoch_s_ + t_s;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(std::floor(abs_s));
  ts.tv_nsec = static_cast<long>((abs_s - std::floor(abs_s)) * 1e9);
  if (ts.tv_nsec >= 1000000000L) {
    ts.tv_sec += 1;
    ts.tv_nsec -= 1000000000L;
  }
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

void run_loop(ControlLoop& loop, Clock& clock, double period_s, std::uint64_t deadlines,
              const std::atomic<bool>& stop_requested, LoopTiming& timing,
              const std::function<void()>& between_ticks) {
  timing.period_s = period_s;
  const double epoch = clock.now_s();
  loop.start(0.0);
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
    ++timing.ticks;
    ++k;
    if (!clock.simulated()) {
      const double end = clock.now_s() - epoch;
      const double next = static_cast<double>(k) * period_s;
      if (end > next) {  // overrun: skip the deadlines already passed
        ++timing.overruns;
        k = static_cast<std::uint64_t>(std::floor(end / period_s)) + 1;
      }
    }
    if (between_ticks) between_ticks();
  }
}

}  // namespace pneu::controller
