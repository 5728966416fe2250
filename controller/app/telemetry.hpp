// pneud's LCM telemetry and commands (telemetry.*, commands.*): telemetry_lcm.cpp in a build with
// LCM; in one without, telemetry_without_lcm.cpp says so (a refusal of --require-telemetry, a
// warning when telemetry is configured).
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "pneu/config/config.hpp"
#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/session.hpp"

namespace pneu::pneud {

class Telemetry {
 public:
  virtual ~Telemetry() = default;

  /// Refuses `--require-telemetry` in a build without LCM (cli::UsageError); else nothing.
  static void require_built(bool required);
  /// LCM for `run` when telemetry.enabled and the clock is real or telemetry.in_simulated_time:
  /// a sink of its runtime and, on the real clock with commands.enabled, the command channel into
  /// its loop. Null when off, or when LCM cannot start: then a warning on stderr says why, unless
  /// `required`, which throws instead.
  [[nodiscard]] static std::unique_ptr<Telemetry> start(const config::Config& config, controller::Run& run,
                                                        bool required);

  /// The service thread's wait between drains: up to `timeout_ms` for commands, then handles them.
  virtual void handle(int timeout_ms) = 0;
  /// One controller per bench, before the run: listens `listen_s` on the health channel for
  /// another pneud's health, and names the first heard (nothing: none). When nothing can be heard
  /// there (not a udpm:// URL), says why in `why_not`.
  [[nodiscard]] virtual std::optional<std::string> another_controller(double listen_s, std::string& why_not) = 0;
  /// For the run's summary.
  [[nodiscard]] virtual controller::TelemetryFigures figures() const = 0;
};

}  // namespace pneu::pneud
