// The bench's three analog sensors as configured (sensors.*, docs/model.md section 8): each
// channel's calibration, volts <-> SI, written here once, and what its converter does (noise,
// electrical range, resolution). The simulated sensors (pneu::plant::SensorChannel) produce the
// volts; the modbus backend takes the module's volts back to SI.
#pragma once

#include <cstdint>

namespace pneu::model {

/// One analog sensor channel. Its calibration is linear: volts = gain * value + offset.
struct SensorChannelParams {
  double gain_v_per_unit = 1.0;  ///< sensitivity [V per SI unit: V/m or V/Pa], != 0
  double offset_v = 0.0;         ///< output at a zero value [V]
  double noise_std_v = 0.0;      ///< standard deviation of additive white Gaussian noise [V], >= 0
  int adc_bits = 0;              ///< ADC resolution [bits], 0 = no quantisation, else 1..24
  double range_min_v = 0.0;      ///< electrical range of the input: outputs are clamped to it [V]
  double range_max_v = 10.0;     ///< [V], > range_min_v

  /// SI -> volts through the calibration (no noise, no range, no quantisation). Real-time safe.
  [[nodiscard]] constexpr double to_volts(double value) const noexcept {
    return gain_v_per_unit * value + offset_v;
  }
  /// Volts -> SI, the calibration inverted. Real-time safe.
  [[nodiscard]] constexpr double to_si(double volts) const noexcept {
    return (volts - offset_v) / gain_v_per_unit;
  }
};

/// Parameters of the bench's three sensors.
struct SensorParams {
  std::uint64_t seed = 1;              ///< seed of the noise generator (runs are reproducible)
  SensorChannelParams position;        ///< potentiometer, gain in V/m
  SensorChannelParams pressure_p;      ///< chamber P transmitter, gain in V/Pa
  SensorChannelParams pressure_n;      ///< chamber N transmitter, gain in V/Pa
};

}  // namespace pneu::model
