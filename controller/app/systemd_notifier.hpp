// pneud's side of systemd (Type=notify), run on the service thread: READY=1 after the loop's first
// tick, WATCHDOG=1 only while the loop's heartbeat advances, STATUS= on mode changes, STOPPING=1
// once asked to stop. Without NOTIFY_SOCKET (not under systemd), or built without libsystemd,
// every call is a no-op.
#pragma once

#include <atomic>
#include <cstdint>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/watchdog.hpp"

namespace pneu::pneud {

class SystemdNotifier {
 public:
  /// `stop_requested`: set by SIGTERM/SIGINT.
  SystemdNotifier(const controller::LoopOutputs& loop, const std::atomic<bool>& stop_requested);
  /// Called by the service thread between drains.
  void service();
  /// Asked to stop (SIGTERM/SIGINT): said once, from the service thread or after the run.
  void stopping();

 private:
  const controller::LoopOutputs& loop_;
  const std::atomic<bool>& stop_requested_;
  controller::WatchdogGate watchdog_;
  bool ready_ = false, stopping_ = false;
  bool status_said_ = false;  // STATUS= sent at least once
  controller::Mode last_mode_ = controller::Mode::kArmed;
  controller::FaultCause last_cause_ = controller::FaultCause::kNone;
};

}  // namespace pneu::pneud
