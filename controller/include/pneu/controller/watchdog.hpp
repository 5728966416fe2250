// When to tell systemd's watchdog that the daemon is alive: only when the loop has ticked since
// the last time it was asked. A loop stuck anywhere (a hung backend, a deadlock, a runaway
// computation) stops the heartbeat, the petting stops, and systemd restarts the service.
#pragma once

#include <cstdint>

namespace pneu::controller {

class WatchdogGate {
 public:
  /// `interval_s`: how often to consider petting (a quarter of WatchdogSec); 0 disables it.
  explicit WatchdogGate(double interval_s) noexcept : interval_s_(interval_s) {}

  /// Called from the service thread with the loop's heartbeat (ticks run) and a monotonic time.
  /// Returns true when WATCHDOG=1 is due: the interval has passed since the last check and the
  /// heartbeat advanced since then.
  [[nodiscard]] bool due(std::uint64_t heartbeat, double now_s) noexcept {
    if (interval_s_ <= 0.0 || (!checked_ && heartbeat == 0)) return false;  // off, or not started
    if (checked_ && now_s - last_check_s_ < interval_s_) return false;
    const bool alive = !checked_ || heartbeat != last_heartbeat_;
    checked_ = true;
    last_check_s_ = now_s;
    last_heartbeat_ = heartbeat;
    return alive;
  }

 private:
  double interval_s_;
  bool checked_ = false;
  double last_check_s_ = 0.0;
  std::uint64_t last_heartbeat_ = 0;
};

}  // namespace pneu::controller
