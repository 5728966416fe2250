// Specification of a sensor channel's calibration (docs/model.md section 8): volts = gain * value
// + offset, and back.
#include <gtest/gtest.h>

#include "pneu/model/sensors.hpp"

namespace pneu::model {
namespace {

// The paper bench's potentiometer, 0..10 V over the stroke, and its pressure transmitters.
constexpr SensorChannelParams kPotentiometer{.gain_v_per_unit = 20.0, .offset_v = 5.0};
constexpr SensorChannelParams kTransmitter{.gain_v_per_unit = 1.0e-5, .offset_v = 0.5};

TEST(SensorCalibration, MapsValueToVoltsThroughGainAndOffset) {
  for (double y : {-0.25, -0.1, 0.0, 0.0731, 0.2195, 0.25})
    EXPECT_NEAR(kPotentiometer.to_volts(y), 20.0 * y + 5.0, 1e-14) << y;  // rounding only
  EXPECT_EQ(kPotentiometer.to_volts(0.0), 5.0);  // the offset is the output at a zero value
}

TEST(SensorCalibration, ToSiInvertsTheCalibration) {
  for (double p : {1.0e5, 3.3e5, 7.0e5}) {
    EXPECT_NEAR(kTransmitter.to_si(1.0e-5 * p + 0.5), p, 1e-9);  // 1e-9 Pa: rounding of ~7 V / 1e-5
    EXPECT_NEAR(kTransmitter.to_si(kTransmitter.to_volts(p)), p, 1e-9);
  }
  EXPECT_NEAR(kPotentiometer.to_si(0.0), -0.25, 1e-15);  // 0 V: the - end of the stroke
  EXPECT_NEAR(kPotentiometer.to_si(10.0), 0.25, 1e-15);
}

}  // namespace
}  // namespace pneu::model
