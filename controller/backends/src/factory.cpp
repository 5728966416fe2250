#include "pneu/backends/factory.hpp"
#include "pneu/config/config.hpp"

#include <utility>

#ifdef PNEU_WITH_MODBUS
#include "pneu/hal/modbus_backend.hpp"
#endif
#ifdef PNEU_WITH_GPIOD
#include "pneu/hal/gpio_backend.hpp"
#include "pneu/hal/gpio_lines.hpp"
#endif

namespace pneu::backends {

namespace {

#ifdef PNEU_WITH_GPIOD
// The GPIO decorator together with what it borrows: the backend inside it and the lines. Destroyed
// in reverse order of declaration: the decorator, then the lines (their destructor switches valve
// power off), then the device.
class WithGpioLines final : public hal::Backend {
 public:
  WithGpioLines(std::unique_ptr<hal::Backend> inner, std::unique_ptr<hal::LibgpiodLines> lines)
      : inner_(std::move(inner)), lines_(std::move(lines)), gpio_(*inner_, *lines_) {}

  void open(double t0_s) override { gpio_.open(t0_s); }
  void close() noexcept override { gpio_.close(); }
  [[nodiscard]] hal::Status read(double t_s, hal::SensorFrame& frame) noexcept override {
    return gpio_.read(t_s, frame);
  }
  [[nodiscard]] hal::Status write(const hal::ActuatorCommand& command) noexcept override {
    return gpio_.write(command);
  }
  [[nodiscard]] std::optional<hal::LinkReport> link_report() const override { return gpio_.link_report(); }

 private:
  std::unique_ptr<hal::Backend> inner_;
  std::unique_ptr<hal::LibgpiodLines> lines_;
  hal::GpioBackend gpio_;
};
#endif

// The device: the I/O module or the in-process plant.
std::unique_ptr<hal::Backend> make_device(const config::Config& config, double first_output_v) {
#ifdef PNEU_WITH_MODBUS
  if (config.hal.backend == config::BackendKind::kModbus)
    return std::make_unique<hal::ModbusBackend>(config.hal.modbus, config.sensors);
#endif
  return make_sim_backend(config, first_output_v);
}

}  // namespace

std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config, double first_output_v,
                                                  const model::PlantParams& bench) {
  return std::make_unique<hal::SimBackend>(bench, config.sensors, config.simulation.initial_position_m, first_output_v,
                                           config.hal.sim.pushes);
}

std::unique_ptr<hal::SimBackend> make_sim_backend(const config::Config& config, double first_output_v) {
  return make_sim_backend(config, first_output_v, config::simulated_bench(config));
}

void require_built(const config::Config& config) {
#ifndef PNEU_WITH_MODBUS
  if (config.hal.backend == config::BackendKind::kModbus)
    throw config::ConfigError("hal.backend", "this pneud was built without the modbus backend");
#endif
#ifndef PNEU_WITH_GPIOD
  if (config.hal.gpio.enabled) throw config::ConfigError("hal.gpio.enabled", "this pneud was built without libgpiod");
#endif
  (void)config;
}

std::unique_ptr<hal::Backend> make_backend(const config::Config& config, double first_output_v) {
  require_built(config);
  std::unique_ptr<hal::Backend> device = make_device(config, first_output_v);
#ifdef PNEU_WITH_GPIOD
  if (config.hal.gpio.enabled) {
    auto lines = std::make_unique<hal::LibgpiodLines>(config.hal.gpio);
    return std::make_unique<WithGpioLines>(std::move(device), std::move(lines));
  }
#endif
  return device;
}

}  // namespace pneu::backends
