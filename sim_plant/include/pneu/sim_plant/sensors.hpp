// Simulated sensors: true physical value -> sensor voltage (the calibration of
// model::SensorChannelParams) -> Gaussian noise -> electrical range clamp -> ADC quantisation ->
// back to SI through the same calibration. This is what a backend sees from a potentiometer or a
// pressure transmitter on an analog input.
#pragma once

#include <cstdint>
#include <random>

#include "pneu/model/sensors.hpp"

namespace pneu::plant {

/// One simulated analog sensor channel. Real-time safe (no allocation) after construction.
class SensorChannel {
 public:
  explicit SensorChannel(const model::SensorChannelParams& params) noexcept : params_(params) {}

  /// The voltage the ADC reports for a true value, noise drawn from `rng`.
  template <typename Rng>
  [[nodiscard]] double read_volts(double true_value, Rng& rng) const noexcept {
    double volts = params_.to_volts(true_value);
    if (params_.noise_std_v > 0.0) volts += params_.noise_std_v * normal_(rng);
    return quantise(volts);
  }
  /// The measured value in SI units (calibration inverted) for a true value.
  template <typename Rng>
  [[nodiscard]] double measure(double true_value, Rng& rng) const noexcept {
    return params_.to_si(read_volts(true_value, rng));
  }
  /// Clamp to the electrical range, then round to the nearest ADC level.
  [[nodiscard]] double quantise(double volts) const noexcept;
  /// One ADC step [V] (0 without quantisation).
  [[nodiscard]] double lsb_v() const noexcept;
  [[nodiscard]] const model::SensorChannelParams& params() const noexcept { return params_; }

 private:
  model::SensorChannelParams params_;
  mutable std::normal_distribution<double> normal_{0.0, 1.0};
};

/// What the three sensors report, in SI units (or in volts, from read_volts()).
struct SensorReadings {
  double y_m = 0.0;
  double p_p_pa = 0.0;
  double p_n_pa = 0.0;
};

/// The potentiometer and both pressure sensors with one seeded noise source.
class SensorSuite {
 public:
  explicit SensorSuite(const model::SensorParams& params) noexcept
      : position_(params.position),
        pressure_p_(params.pressure_p),
        pressure_n_(params.pressure_n),
        rng_(params.seed) {}

  /// What the three sensors output, in volts (before any calibration back to SI).
  [[nodiscard]] SensorReadings read_volts(double y_m, double p_p_pa, double p_n_pa) noexcept {
    return {position_.read_volts(y_m, rng_), pressure_p_.read_volts(p_p_pa, rng_),
            pressure_n_.read_volts(p_n_pa, rng_)};
  }
  [[nodiscard]] SensorReadings measure(double y_m, double p_p_pa, double p_n_pa) noexcept {
    return {position_.measure(y_m, rng_), pressure_p_.measure(p_p_pa, rng_),
            pressure_n_.measure(p_n_pa, rng_)};
  }
  [[nodiscard]] const SensorChannel& position() const noexcept { return position_; }
  [[nodiscard]] const SensorChannel& pressure_p() const noexcept { return pressure_p_; }
  [[nodiscard]] const SensorChannel& pressure_n() const noexcept { return pressure_n_; }

 private:
  SensorChannel position_, pressure_p_, pressure_n_;
  std::mt19937_64 rng_;
};

}  // namespace pneu::plant
