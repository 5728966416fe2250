// A run's figures beside its stops: the loop's timing, the backend's and the command channel's
// counters, the safe output on closing. What pneud's summary prints (run_summary.hpp) for people
// and --summary-json records for programs. Plain values, filled once the run has ended.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "pneu/controller/clock.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/hal/backend.hpp"

namespace pneu::controller {

/// Datagrams received on the command channel, by verdict and, rejected, by reason
/// (telemetry::CommandValidator counts them).
struct CommandCounters {
  std::uint64_t received = 0, accepted = 0, rejected = 0;
  std::uint64_t malformed = 0, invalid = 0, rate = 0, mode = 0, sequence = 0;
  std::uint64_t stale = 0, foreign = 0, oversized = 0;
};

/// LCM while it ran (telemetry::LcmBridge::figures).
struct TelemetryFigures {
  std::string lcm_url;
  std::string channel_prefix;
  std::uint64_t publish_errors = 0;
  CommandCounters commands;
  /// Commands that passed validation (counted accepted) but found the loop's queue full.
  std::uint64_t commands_dropped = 0;
};

/// Everything about a run that its Runtime does not know.
struct RunFigures {
  std::string version;   ///< pneud's
  std::string backend;   ///< sim, modbus
  std::string clock;     ///< real, simulated
  std::string config;    ///< the configuration file, or "embedded sim.yaml"
  double u_0_v = 0.0;    ///< u_0 as run (controller.law.offset_v, resolved) [V]
  double wall_s = 0.0;   ///< wall time of the run [s]
  LoopTiming timing;
  std::uint64_t ticks_dropped = 0;   ///< tick records the loop's full queue dropped
  std::uint64_t events_dropped = 0;  ///< events the loop's full queue dropped
  std::optional<TelemetryFigures> telemetry;  ///< when LCM ran
  std::optional<hal::LinkReport> modbus;      ///< the backend's link (hal::Backend::link_report): modbus
  /// Of modbus->transactions, those before the loop's time started (the movement test's).
  std::uint64_t link_transactions_before_time = 0;
  /// The fault still latched when the run ended (ControlLoop::fault_cause; FaultCause::kNone: none).
  FaultCause fault_at_end = FaultCause::kNone;
};

}  // namespace pneu::controller
