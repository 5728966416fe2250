#include "systemd_notifier.hpp"

#include <chrono>

#ifdef PNEU_WITH_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

#include "pneu/controller/supervisor.hpp"

namespace pneu::pneud {

namespace {

// A quarter of WatchdogSec (systemd's WATCHDOG_USEC); 0 when the watchdog is off.
double watchdog_interval_s() {
#ifdef PNEU_WITH_SYSTEMD
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) return static_cast<double>(usec) * 1e-6 / 4.0;
#endif
  return 0.0;
}

}  // namespace

SystemdNotifier::SystemdNotifier(const controller::LoopOutputs& loop, const std::atomic<bool>& stop_requested)
    : loop_(loop), stop_requested_(stop_requested), watchdog_(watchdog_interval_s()) {}

void SystemdNotifier::service() {
#ifdef PNEU_WITH_SYSTEMD
  const std::uint64_t beat = loop_.heartbeat.load(std::memory_order_acquire);
  if (!ready_ && beat > 0) {
    ready_ = true;
    sd_notify(0, "READY=1");
  }
  const auto mode = loop_.mode.load(std::memory_order_relaxed);
  const auto cause = loop_.fault_cause.load(std::memory_order_relaxed);
  if (ready_ && (!status_said_ || mode != last_mode_ || cause != last_cause_)) {
    status_said_ = true;
    last_mode_ = mode;
    last_cause_ = cause;
    using controller::Mode;
    sd_notifyf(0, "STATUS=%s%s%s",
               mode == Mode::kDisarmed ? "disarmed"
               : mode == Mode::kArmed  ? "armed"
               : mode == Mode::kHold   ? "armed, holding in position"
               : mode == Mode::kMovementTest ? "armed, movement test (set points refused until it passed)"
                                       : "FAULT: ",
               mode == Mode::kFault ? controller::fault_name(cause) : "",
               mode == Mode::kDisarmed ? " (send ARM to drive)" : "");
  }
  const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  if (watchdog_.due(beat, now_s)) sd_notify(0, "WATCHDOG=1");  // the loop ticked since the last check
  if (stop_requested_.load()) stopping();
#endif
}

void SystemdNotifier::stopping() {
#ifdef PNEU_WITH_SYSTEMD
  if (stopping_) return;
  stopping_ = true;
  sd_notify(0, "STOPPING=1\nSTATUS=stopping: safe output written, final health published");
#endif
}

}  // namespace pneu::pneud
