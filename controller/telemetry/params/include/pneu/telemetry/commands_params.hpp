// The parameters of the command channel (commands): which inbound commands on <prefix>COMMAND are
// taken, how many, how old, how large a step (command_validator.hpp), and the set-point stream's
// timeout.
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::telemetry {

/// Inbound commands on <prefix>COMMAND (real clock only).
struct CommandsConfig {
  bool enabled = true;
  double max_rate_hz = 20.0;   ///< sustained command rate accepted [1/s]; above it: rejected
  double burst = 5.0;          ///< commands accepted back to back before the rate applies
  /// A command stamped (utime) further than this from this host's clock, past or future, is
  /// refused as stale or replayed [s].
  double max_age_s = 0.5;
  /// Largest set-point change one command may make [m] (rate of change of the set point).
  double max_setpoint_step_m = 0.5;
  /// With a set-point stream configured (> 0): armed, no set point for this long latches a
  /// fault [s]; 0 = set points come when they come.
  double setpoint_stream_timeout_s = 0.0;
};

}  // namespace pneu::telemetry

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using telemetry::CommandsConfig;

void describe(auto& a, Like<CommandsConfig> auto& c) {
  a.field(PNEU_NVP(c, enabled), "accept commands on <prefix>COMMAND");
  a.field(PNEU_NVP(c, max_rate_hz), Range::closed(0.01, 1000.0), "sustained accepted command rate [1/s]");
  a.field(PNEU_NVP(c, burst), Range::closed(1.0, 1000.0), "commands accepted back to back before the rate applies");
  a.field(PNEU_NVP(c, max_age_s), Range::closed(0.001, 3600.0), "older or newer commands are refused [s]");
  a.field(PNEU_NVP(c, max_setpoint_step_m), Range::positive(), "largest set-point change of one command [m]");
  a.field(PNEU_NVP(c, setpoint_stream_timeout_s), Range::closed(0.0, 3600.0),
          "> 0: armed, no set point this long is a fault [s]");
}

}  // namespace pneu::config::schema
