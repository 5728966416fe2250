// CLOCK_MONOTONIC in seconds, and an absolute sleep on it: the time base of the loop, the Modbus
// I/O thread and the HIL plant. Real-time safe (no allocation, no throw).
#pragma once

#include <time.h>

#include <cerrno>
#include <cmath>

namespace pneu::hal {

/// CLOCK_MONOTONIC now [s].
[[nodiscard]] inline double monotonic_s() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// Sleeps until CLOCK_MONOTONIC reaches `t_s` (clock_nanosleep, TIMER_ABSTIME; resumed after a
/// signal).
inline void sleep_until_monotonic_s(double t_s) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(std::floor(t_s));
  ts.tv_nsec = static_cast<long>((t_s - std::floor(t_s)) * 1e9);
  if (ts.tv_nsec >= 1000000000L) {
    ts.tv_sec += 1;
    ts.tv_nsec -= 1000000000L;
  }
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

}  // namespace pneu::hal
