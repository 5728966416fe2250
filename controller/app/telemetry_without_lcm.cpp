#include <cstdio>

#include "pneu/config/cli.hpp"
#include "telemetry.hpp"

namespace pneu::pneud {

void Telemetry::require_built(bool required) {
  if (required) throw cli::UsageError("--require-telemetry: this pneud was built without LCM");
}

std::unique_ptr<Telemetry> Telemetry::start(const config::Config& config, controller::Run&, bool) {
  const bool real_clock = config.controller.clock == config::ClockKind::kReal;
  if (config.telemetry.enabled && (real_clock || config.telemetry.in_simulated_time))
    std::fprintf(stderr, "pneud: warning: telemetry off: this pneud was built without LCM\n");
  return nullptr;
}

}  // namespace pneu::pneud
