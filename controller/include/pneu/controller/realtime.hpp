// Real-time set-up of the loop thread: SCHED_FIFO priority and CPU affinity for the calling
// thread only, memory locked and the stack pre-faulted, so that the loop neither waits behind
// ordinary threads nor page-faults once it runs.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "pneu/controller/realtime_params.hpp"

namespace pneu::controller {

class RealtimeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What was applied, and what could not be (with the reason and the remedy).
struct RealtimeReport {
  bool scheduling = false;  ///< SCHED_FIFO at the configured priority
  bool affinity = false;    ///< pinned to the configured CPU
  bool memory = false;      ///< mlockall done and the stack pre-faulted
  std::vector<std::string> warnings;
};

/// Applies controller.realtime to the CALLING thread (call it on the loop thread, before the
/// loop starts). Settings left at their "off" values are not touched. Without `require`, what is
/// not permitted becomes a warning in the report; with it, a RealtimeError.
RealtimeReport setup_realtime_thread(const RealtimeConfig& rt, bool require);

}  // namespace pneu::controller
