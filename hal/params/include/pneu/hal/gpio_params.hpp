// The parameters of the e-stop input and the valve power-enable output beside either backend
// (hal.gpio, libgpiod; hal/gpio).
#pragma once

#include <string>

#include "pneu/config/describe.hpp"

namespace pneu::hal {

/// Digital lines beside either backend (hal.gpio.*, libgpiod; hal::LibgpiodLines opens them):
/// where the two lines are. Values are logical: with `*_active_low` the kernel inverts the
/// electrical level, so "e-stop active" and "valve power on" keep their meaning either way.
struct GpioConfig {
  bool enabled = false;                 ///< open the lines at start-up (the backends' factory reads it)
  std::string chip = "gpiochip0";       ///< name (gpiochip0), /dev path (/dev/gpiochip0), label or number
  unsigned estop_line = 0;              ///< e-stop input: line offset on `chip`
  bool estop_active_low = true;         ///< pressed = electrically low (a broken wire reads pressed)
  unsigned valve_power_line = 1;        ///< valve power-enable output: line offset, != estop_line
  bool valve_power_active_low = false;  ///< power on = driven electrically low
  std::string consumer = "pneud";       ///< consumer name shown by `gpioinfo` for both lines
};

}  // namespace pneu::hal

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using hal::GpioConfig;

void describe(auto& a, Like<GpioConfig> auto& g) {
  a.field(PNEU_NVP(g, enabled), "open the lines at start-up");
  a.field(optional(PNEU_NVP(g, chip)), "GPIO chip: name, /dev path, label or number");
  a.check("chip", !g.chip.empty(), "must not be empty");
  a.field(optional(PNEU_NVP(g, estop_line)), IntRange::in(0, 65535).says("must be a line offset >= 0"),
          "e-stop input line offset");
  a.field(optional(PNEU_NVP(g, estop_active_low)), "pressed = electrically low");
  a.field(optional(PNEU_NVP(g, valve_power_line)), IntRange::in(0, 65535).says("must be a line offset >= 0"),
          "valve power-enable output line offset");
  a.check("valve_power_line", g.valve_power_line != g.estop_line, "must differ from estop_line");
  a.field(optional(PNEU_NVP(g, valve_power_active_low)), "power on = electrically low");
  a.field(optional(PNEU_NVP(g, consumer)), "the name gpioinfo shows for both lines");
}

}  // namespace pneu::config::schema
