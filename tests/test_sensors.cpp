// Specification of the simulated sensors: calibration, electrical range, ADC quantisation, noise.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "pneu/sim_plant/sensors.hpp"

namespace pneu::plant {
namespace {

using model::SensorChannelParams;
using model::SensorParams;

// The paper bench's potentiometer: 0..10 V over the stroke, 5 V at mid-stroke.
SensorChannelParams potentiometer() {
  return {.gain_v_per_unit = 20.0,
          .offset_v = 5.0,
          .noise_std_v = 0.0,
          .adc_bits = 0,
          .range_min_v = 0.0,
          .range_max_v = 10.0};
}

TEST(SensorChannel, MapsValueToVoltsThroughGainAndOffset) {
  const SensorChannel channel(potentiometer());
  std::mt19937_64 rng(1);
  for (double y : {-0.25, -0.1, 0.0, 0.0731, 0.2195, 0.25}) {
    EXPECT_NEAR(channel.read_volts(y, rng), 20.0 * y + 5.0, 1e-14) << y;  // rounding only
  }
}

TEST(SensorChannel, MeasuresThroughTheCalibrationInverted) {
  const SensorChannel channel({.gain_v_per_unit = 1.0e-5,
                               .offset_v = 0.5,
                               .noise_std_v = 0.0,
                               .adc_bits = 0,
                               .range_min_v = 0.0,
                               .range_max_v = 10.0});
  std::mt19937_64 rng(1);
  for (double p : {1.0e5, 3.3e5, 7.0e5}) {
    EXPECT_NEAR(channel.measure(p, rng), p, 1e-9);  // 1e-9 Pa: rounding of ~7 V / 1e-5
  }
}

TEST(SensorChannel, ClampsToTheElectricalRange) {
  const SensorChannel channel(potentiometer());
  std::mt19937_64 rng(1);
  EXPECT_EQ(channel.read_volts(0.3, rng), 10.0);        // 11 V requested
  EXPECT_EQ(channel.read_volts(-0.4, rng), 0.0);        // -3 V requested
  EXPECT_NEAR(channel.measure(0.3, rng), 0.25, 1e-15);  // the reading saturates at full scale
  EXPECT_NEAR(channel.measure(-0.4, rng), -0.25, 1e-15);
}

TEST(SensorChannel, QuantisesToTheNearestAdcLevel) {
  SensorChannelParams params = potentiometer();
  params.adc_bits = 12;
  const SensorChannel channel(params);
  const double lsb = 10.0 / (std::pow(2.0, 12) - 1.0);  // 4095 steps over 0..10 V
  EXPECT_NEAR(channel.lsb_v(), lsb, 1e-15);
  std::mt19937_64 rng(1);
  for (int i = 0; i <= 10000; ++i) {
    const double y = -0.25 + 0.5 * i / 10000.0;
    const double ideal = 20.0 * y + 5.0;
    const double volts = channel.read_volts(y, rng);
    const double level = volts / lsb;
    EXPECT_NEAR(level, std::round(level), 1e-9) << y;                    // on a level (to rounding)
    EXPECT_LE(std::abs(volts - ideal), 0.5 * lsb * (1.0 + 1e-12)) << y;  // nearest level
  }
  EXPECT_EQ(channel.read_volts(0.25, rng), 10.0);  // full scale is a level
}

TEST(SensorChannel, NoiseHasZeroMeanAndTheConfiguredDeviation) {
  SensorChannelParams params = potentiometer();
  params.noise_std_v = 0.01;
  const SensorChannel channel(params);
  std::mt19937_64 rng(12345);
  constexpr int kSamples = 200000;
  double sum = 0.0, sum_sq = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    const double e = channel.read_volts(0.1, rng) - 7.0;
    sum += e;
    sum_sq += e * e;
  }
  const double mean = sum / kSamples;
  const double std_dev = std::sqrt(sum_sq / kSamples - mean * mean);
  // Five standard errors: sigma / sqrt(N) = 2.2e-5 V for the mean, sigma / sqrt(2N) = 1.6e-5 V
  // for the deviation.
  EXPECT_NEAR(mean, 0.0, 5.0 * 0.01 / std::sqrt(kSamples));
  EXPECT_NEAR(std_dev, 0.01, 5.0 * 0.01 / std::sqrt(2.0 * kSamples));
}

SensorParams noisy_bench(std::uint64_t seed) {
  SensorParams params;
  params.seed = seed;
  params.position = potentiometer();
  params.position.noise_std_v = 0.005;
  params.pressure_p = {.gain_v_per_unit = 1.0e-5,
                       .offset_v = 0.0,
                       .noise_std_v = 0.005,
                       .adc_bits = 16,
                       .range_min_v = 0.0,
                       .range_max_v = 10.0};
  params.pressure_n = params.pressure_p;
  return params;
}

TEST(SensorSuite, SameSeedGivesTheSameSequence) {
  SensorSuite a(noisy_bench(7)), b(noisy_bench(7)), other(noisy_bench(8));
  int differences_from_other = 0;
  for (int i = 0; i < 1000; ++i) {
    const SensorReadings ra = a.measure(0.1, 4.0e5, 3.0e5);
    const SensorReadings rb = b.measure(0.1, 4.0e5, 3.0e5);
    const SensorReadings ro = other.measure(0.1, 4.0e5, 3.0e5);
    ASSERT_EQ(ra.y_m, rb.y_m);
    ASSERT_EQ(ra.p_p_pa, rb.p_p_pa);
    ASSERT_EQ(ra.p_n_pa, rb.p_n_pa);
    differences_from_other += (ra.y_m != ro.y_m);
  }
  EXPECT_GT(differences_from_other, 900);  // another seed is another sequence
}

TEST(SensorSuite, MeasuresEachQuantityWithItsOwnChannel) {
  SensorParams params;
  params.position = potentiometer();
  params.pressure_p = {.gain_v_per_unit = 1.0e-5,
                       .offset_v = 0.0,
                       .noise_std_v = 0.0,
                       .adc_bits = 0,
                       .range_min_v = 0.0,
                       .range_max_v = 10.0};
  params.pressure_n = params.pressure_p;
  params.pressure_n.range_max_v = 5.0;  // chamber N transmitter saturates at 5 bar
  SensorSuite suite(params);
  const SensorReadings r = suite.measure(0.1, 4.0e5, 6.0e5);
  EXPECT_NEAR(r.y_m, 0.1, 1e-15);  // rounding
  EXPECT_NEAR(r.p_p_pa, 4.0e5, 1e-9);
  EXPECT_NEAR(r.p_n_pa, 5.0e5, 1e-9);  // clamped by its own range, not by chamber P's
}

}  // namespace
}  // namespace pneu::plant
