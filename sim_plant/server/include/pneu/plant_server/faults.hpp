// The HIL plant server's fault schedule: what `pneu-plant serve --fault CHANNEL:MODE@T` and
// `--watchdog-outputs` say, parsed into values and checked against the register map before
// serving.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>

#include "pneu/hal/modbus_params.hpp"

namespace pneu::plant_server {

enum class FaultChannel { kPosition, kPressureP, kPressureN, kValveP, kValveN, kTubes, kPressureSensors };
enum class FaultMode { kRailLow, kRailHigh, kRaw, kVolts, kFreeze, kNan, kStuck, kDead, kSwapped };

/// Whether a channel is a valve's (it takes stuck=V only).
[[nodiscard]] bool is_valve(FaultChannel c) noexcept;
/// A miswiring of the bench (the tubes, the pressure transmitters' channels) rather than one channel.
[[nodiscard]] bool is_wiring(FaultChannel c) noexcept;

/// One fault of the schedule, parsed and validated against the register map.
struct Fault {
  std::string spec;                    ///< as given: CHANNEL:MODE@T (named when it becomes active)
  FaultChannel channel = FaultChannel::kPosition;
  FaultMode mode = FaultMode::kFreeze;
  double t_s = 0.0;                    ///< acts from this time after the server's start on
  double stuck_v = 0.0;                ///< valve faults: the voltage the stuck spool drives
  std::array<std::uint16_t, 2> words{};  ///< sensor faults: what the register(s) read (freeze: set on activation)
};

/// A fault or watchdog-outputs text that does not parse; what() is "'TEXT': why", for the caller
/// to prefix with its option's name.
class SpecError : public std::invalid_argument {
 public:
  SpecError(const std::string& text, const std::string& why) : std::invalid_argument("'" + text + "': " + why) {}
};

/// Parses CHANNEL:MODE@T (the vocabulary of `pneu-plant serve --help`) against the register map
/// `mb`; `u_max_v`: the simulated valve's largest voltage, the bound of stuck=V. Throws SpecError.
[[nodiscard]] Fault parse_fault(const std::string& spec, const hal::ModbusConfig& mb, double u_max_v);

/// Valve outputs [V], each valve its own.
struct ValveVoltages {
  double u_p_v = 0.0, u_n_v = 0.0;
};

/// What the module's watchdog sets: "neutral" (nullopt: the neutral voltages the server starts
/// with), "exhaust" (both valves at -exhaust_v) or "U_P,U_N" in volts. Throws SpecError.
[[nodiscard]] std::optional<ValveVoltages> parse_watchdog_outputs(const std::string& text, double exhaust_v);

}  // namespace pneu::plant_server
