// Value types crossing the hardware boundary. Fixed size, no allocation, faults carried as flags.
#pragma once

#include <cstdint>

namespace pneu::hal {

/// Validity flags of a SensorFrame (bitwise OR).
enum SensorValidity : std::uint32_t {
  kSensorsValid = 0,
  kPositionInvalid = 1u << 0,    ///< position reading missing, out of range or non-finite
  kPressurePInvalid = 1u << 1,   ///< chamber P reading invalid
  kPressureNInvalid = 1u << 2,   ///< chamber N reading invalid
  kSampleStale = 1u << 3,        ///< the sample is older than the backend's age limit
  kCommsError = 1u << 4,         ///< the backend could not reach its device
};

/// One sample of the bench's sensors, in SI units.
struct SensorFrame {
  double t_s = 0.0;          ///< time the sample was taken, on the loop's clock [s]: at the latest (read_span_s)
  double y_m = 0.0;          ///< carriage position from mid-stroke [m]
  double p_p_pa = 0.0;       ///< chamber P absolute pressure [Pa]
  double p_n_pa = 0.0;       ///< chamber N absolute pressure [Pa]
  double age_s = 0.0;        ///< age of the sample when the loop read it [s] (0 for the sim backend)
  bool estop = false;        ///< emergency-stop input active
  bool fresh = true;         ///< a new sample since the last read (false: the same one again)
  std::uint32_t validity = kSensorsValid;  ///< SensorValidity flags; 0 = all readings valid
  /// The sensors were read at some instant within [t_s - read_span_s, t_s] [s]: a backend that
  /// asks a device knows only that the device read them between its request and its reply (a
  /// thread stalled before it took the reply widens the span). 0: read at t_s exactly (the sim).
  double read_span_s = 0.0;

  [[nodiscard]] bool valid() const noexcept { return validity == kSensorsValid; }
};

/// What the loop drives: the two servo-valve voltages (Eq. 1: u_P = u, u_N = -u) and valve power.
struct ActuatorCommand {
  double u_p_v = 0.0;        ///< valve P voltage [V]
  double u_n_v = 0.0;        ///< valve N voltage [V]
  bool valve_power = false;  ///< valve power enable

  /// The opposite voltages of Eq. 1 for a control value u.
  [[nodiscard]] static constexpr ActuatorCommand from_control(double u_v, bool power) noexcept {
    return {u_v, -u_v, power};
  }
};

/// Result of a backend call on the loop thread.
enum class Status : std::uint8_t {
  kOk,
  kStale,        ///< no new sample since the last read; the frame holds the newest one
  kCommsError,   ///< the device is unreachable; the frame is flagged
  kDeviceError,  ///< the device answered with an error
};

}  // namespace pneu::hal
