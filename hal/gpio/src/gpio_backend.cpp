#include "pneu/hal/gpio_backend.hpp"

#include <stdexcept>

namespace pneu::hal {

void GpioBackend::open(double t0_s) {
  inner_.open(t0_s);
  estop_active_ = true;  // until the first read says otherwise
  if (lines_.set_valve_power(false) != Status::kOk)
    throw std::runtime_error(
        "gpio: the valve power output refused to switch off at start (hal.gpio.valve_power_line); "
        "check the chip and the line with `gpioinfo`");
}

void GpioBackend::close() noexcept {
  (void)lines_.set_valve_power(false);
  inner_.close();
}

Status GpioBackend::read(double t_s, SensorFrame& frame) noexcept {
  Status status = inner_.read(t_s, frame);
  bool line_active = true;
  if (lines_.read_estop(line_active) != Status::kOk) {
    line_active = true;  // whatever the adapter left in the flag: unreadable counts as pressed
    if (status == Status::kOk || status == Status::kStale) status = Status::kDeviceError;
  }
  frame.estop = frame.estop || line_active;
  estop_active_ = frame.estop;
  return status;
}

Status GpioBackend::write(const ActuatorCommand& command) noexcept {
  ActuatorCommand driven = command;
  driven.valve_power = command.valve_power && !estop_active_;
  // Cut power before anything else; grant it only once the valves hold the new voltages.
  Status line = Status::kOk;
  if (!driven.valve_power) line = lines_.set_valve_power(false);
  const Status inner = inner_.write(driven);
  if (driven.valve_power) line = lines_.set_valve_power(true);
  if (inner != Status::kOk) return inner;
  return line == Status::kOk ? Status::kOk : Status::kDeviceError;
}

}  // namespace pneu::hal
