#include <gpiod.h>

#include <cerrno>
#include <stdexcept>
#include <string>
#include <system_error>

#include "pneu/hal/gpio_lines.hpp"

namespace pneu::hal {

namespace {

// "<what>: <system's reason>; <hint>", for a user who has to fix the wiring or the config.
[[noreturn]] void fail(const std::string& what, int err, const std::string& hint) {
  const std::string reason = err != 0 ? std::generic_category().message(err) : "unknown error";
  throw std::runtime_error("gpio: " + what + ": " + reason + "; " + hint);
}

std::string line_name(unsigned offset, const std::string& chip) {
  return "line " + std::to_string(offset) + " of GPIO chip '" + chip + "'";
}

}  // namespace

void LibgpiodLines::ChipCloser::operator()(gpiod_chip* chip) const noexcept {
  gpiod_chip_close(chip);
}

LibgpiodLines::LibgpiodLines(const GpioConfig& p) {
  if (p.chip.empty())
    throw std::runtime_error(
        "gpio: no GPIO chip given (hal.gpio.chip); name one, e.g. gpiochip0 or /dev/gpiochip0 "
        "(`gpiodetect` lists the chips of this machine)");
  if (p.estop_line == p.valve_power_line)
    throw std::runtime_error(
        "gpio: the e-stop input and the valve power output are both " +
        line_name(p.estop_line, p.chip) +
        " (hal.gpio.estop_line, hal.gpio.valve_power_line); they need two lines");

  errno = 0;
  chip_.reset(gpiod_chip_open_lookup(p.chip.c_str()));
  if (!chip_)
    fail("cannot open GPIO chip '" + p.chip + "' (hal.gpio.chip)", errno,
         "give its name (gpiochip0), path (/dev/gpiochip0), label or number; `gpiodetect` lists "
         "the chips of this machine, and the user needs read-write access to /dev/gpiochip*");

  const unsigned num_lines = gpiod_chip_num_lines(chip_.get());
  // Requests one line; on failure the chip (and any line already requested) is released by chip_.
  auto request = [&](unsigned offset, bool output, bool active_low, const char* role,
                     const char* key) -> gpiod_line* {
    const std::string name = line_name(offset, p.chip);
    if (offset >= num_lines)
      throw std::runtime_error("gpio: " + name + " does not exist (" + key +
                               "): the chip has lines 0.." +
                               std::to_string(num_lines == 0 ? 0 : num_lines - 1) + "; `gpioinfo " +
                               p.chip + "` lists them");
    errno = 0;
    gpiod_line* line = gpiod_chip_get_line(chip_.get(), offset);
    if (line == nullptr)
      fail("cannot get " + name + " (" + key + ")", errno,
           "`gpioinfo " + p.chip + "` lists the lines");
    const int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
    errno = 0;
    const int rc =
        output ? gpiod_line_request_output_flags(line, p.consumer.c_str(), flags, 0)  // 0: off
               : gpiod_line_request_input_flags(line, p.consumer.c_str(), flags);
    if (rc != 0)
      fail(std::string("cannot request ") + name + " as the " + role + " (" + key + ")", errno,
           "`gpioinfo " + p.chip + "` shows whether another consumer holds it");
    return line;
  };
  estop_ = request(p.estop_line, false, p.estop_active_low, "e-stop input", "hal.gpio.estop_line");
  valve_power_ = request(p.valve_power_line, true, p.valve_power_active_low, "valve power output",
                         "hal.gpio.valve_power_line");
}

LibgpiodLines::~LibgpiodLines() {
  // A released output keeps its last level on most drivers: leave the valves unpowered.
  (void)set_valve_power(false);
  gpiod_line_release(valve_power_);
  gpiod_line_release(estop_);
}

Status LibgpiodLines::read_estop(bool& active) noexcept {
  const int value = gpiod_line_get_value(estop_);  // logical: ACTIVE_LOW already applied
  if (value < 0) {
    last_errno_.store(errno, std::memory_order_relaxed);
    active = true;  // fail safe: an e-stop that cannot be read counts as pressed
    return Status::kDeviceError;
  }
  active = value != 0;
  return Status::kOk;
}

Status LibgpiodLines::set_valve_power(bool on) noexcept {
  if (gpiod_line_set_value(valve_power_, on ? 1 : 0) != 0) {
    last_errno_.store(errno, std::memory_order_relaxed);
    return Status::kDeviceError;
  }
  return Status::kOk;
}

}  // namespace pneu::hal
