#include "pneu/sim_plant/sensors.hpp"

#include <algorithm>
#include <cmath>

namespace pneu::plant {

double SensorChannel::lsb_v() const noexcept {
  if (params_.adc_bits <= 0) return 0.0;
  const double levels = std::ldexp(1.0, params_.adc_bits) - 1.0;
  return (params_.range_max_v - params_.range_min_v) / levels;
}

double SensorChannel::quantise(double volts) const noexcept {
  volts = std::clamp(volts, params_.range_min_v, params_.range_max_v);
  const double lsb = lsb_v();
  if (lsb <= 0.0) return volts;
  return params_.range_min_v + std::round((volts - params_.range_min_v) / lsb) * lsb;
}

}  // namespace pneu::plant
