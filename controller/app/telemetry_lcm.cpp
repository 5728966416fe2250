#include <cstdio>

#include "pneu/telemetry/lcm_bridge.hpp"
#include "telemetry.hpp"

namespace pneu::pneud {

namespace {

class LcmTelemetry final : public Telemetry {
 public:
  LcmTelemetry(const config::Config& config, controller::Run& run, bool accept_commands)
      : bridge_(config.telemetry,
                telemetry::CommandValidator(config.commands, config.controller.soft_limit_min_m,
                                            config.controller.soft_limit_max_m),
                *run.outputs, accept_commands) {
    run.runtime->add_sink(bridge_);
    bridge_.set_command_log(run.runtime.get());  // both on the service thread (execute)
  }
  void handle(int timeout_ms) override { (void)bridge_.handle(timeout_ms); }
  std::optional<std::string> another_controller(double listen_s, std::string& why_not) override {
    why_not = bridge_.watch_off();
    return bridge_.listen_for_another(listen_s);
  }
  [[nodiscard]] controller::TelemetryFigures figures() const override { return bridge_.figures(); }

 private:
  telemetry::LcmBridge bridge_;
};

}  // namespace

void Telemetry::require_built(bool) {}

std::unique_ptr<Telemetry> Telemetry::start(const config::Config& config, controller::Run& run, bool required) {
  const bool real_clock = config.controller.clock == config::ClockKind::kReal;
  if (!config.telemetry.enabled || !(real_clock || config.telemetry.in_simulated_time)) return nullptr;
  try {
    return std::make_unique<LcmTelemetry>(config, run, real_clock && config.commands.enabled);
  } catch (const telemetry::LcmError& e) {
    if (required) throw;
    std::fprintf(stderr, "pneud: warning: telemetry off: %s\n", e.what());
    return nullptr;
  }
}

}  // namespace pneu::pneud
