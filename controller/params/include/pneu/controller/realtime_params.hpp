// The real-time set-up of the loop thread (controller.realtime).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

/// Real-time set-up of the loop thread (controller.realtime.*), real clock only; a thread the
/// backend starts (the Modbus I/O thread) inherits it.
struct RealtimeConfig {
  int priority = 0;           ///< SCHED_FIFO priority of the loop thread, 1..99; 0 = normal scheduling
  int cpu = -1;               ///< pin the loop thread to this CPU; -1 = no pinning
  bool lock_memory = false;   ///< mlockall(MCL_CURRENT | MCL_FUTURE) and a pre-faulted stack
};

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::RealtimeConfig;

void describe(auto& a, Like<RealtimeConfig> auto& r) {
  a.field(PNEU_NVP(r, priority), IntRange::in(0, 99).says("must be in [0, 99] (0 = normal scheduling)"),
          "SCHED_FIFO priority; 0 = normal scheduling");
  a.field(PNEU_NVP(r, cpu), IntRange::in(-1, 1023).says("must be a CPU number, or -1 (no pinning)"),
          "the loop thread's CPU; -1 = no pinning");
  a.field(PNEU_NVP(r, lock_memory), "mlockall and a pre-faulted stack");
}

}  // namespace pneu::config::schema
