// Specification of the state feedback of Eq. 4 (docs/model.md section 5),
//   u = K_y (y_d - y) - K_v v_hat - K_a a_hat + u_0, saturated to [-u_max, u_max],
// and of the constant control u* = K_y (y_d - y*) + u_0 held while the carriage is stuck (Eq. 11).
// Expected values are worked out by hand in the comments.
#include <gtest/gtest.h>

#include "pneu/config/config.hpp"
#include "pneu/controller/control_law.hpp"

namespace pneu::controller {
namespace {

// Not the defaults, so that a swapped or ignored gain shows.
ControlLawParams gains() {
  ControlLawParams p;
  p.position_gain_v_per_m = 80.0;
  p.velocity_gain_v_s_per_m = 1.5;
  p.acceleration_gain_v_s2_per_m = 0.002;
  p.offset_v = 0.25;
  p.max_voltage_v = 10.0;
  return p;
}

// Sums of a handful of terms of magnitude <= 10 V: a few ulps, 1e-12 V is generous.
constexpr double kToleranceV = 1e-12;

TEST(ControlLaw, FollowsEquation4TermByTerm) {
  const ControlLaw law(gains());
  // 80 (0.17 - 0.20) - 1.5 (0.1) - 0.002 (-3) + 0.25 = -2.4 - 0.15 + 0.006 + 0.25 = -2.294 V
  EXPECT_NEAR(law.control_v(0.17, 0.20, 0.1, -3.0), -2.294, kToleranceV);
  // 80 (0.22 - 0.17) - 1.5 (-0.2) - 0.002 (40) + 0.25 = 4 + 0.3 - 0.08 + 0.25 = 4.47 V
  EXPECT_NEAR(law.control_v(0.22, 0.17, -0.2, 40.0), 4.47, kToleranceV);
}

TEST(ControlLaw, EachTermHasItsOwnGainAndSign) {
  const ControlLaw law(gains());
  const double at_rest_on_target = law.control_v(0.1, 0.1, 0.0, 0.0);
  EXPECT_NEAR(at_rest_on_target, 0.25, kToleranceV);                                      // u_0
  EXPECT_NEAR(law.control_v(0.1, 0.09, 0.0, 0.0) - at_rest_on_target, 0.8, 1e-11);        // +K_y dy
  EXPECT_NEAR(law.control_v(0.1, 0.1, 0.2, 0.0) - at_rest_on_target, -0.3, kToleranceV);  // -K_v v
  EXPECT_NEAR(law.control_v(0.1, 0.1, 0.0, 50.0) - at_rest_on_target, -0.1, kToleranceV);  // -K_a a
}

TEST(ControlLaw, SaturatesAtPlusUMax) {
  const ControlLaw law(gains());
  // 80 (0.3 - 0.1) + 0.25 = 16.25 V -> 10 V; exactly at the limit is not altered either.
  EXPECT_EQ(law.control_v(0.3, 0.1, 0.0, 0.0), 10.0);
  EXPECT_EQ(law.control_v(0.1, 0.1, -1.0e3, 0.0), 10.0);
  EXPECT_NEAR(law.control_v(0.1 + 9.75 / 80.0, 0.1, 0.0, 0.0), 10.0, 1e-12);
}

TEST(ControlLaw, SaturatesAtMinusUMax) {
  const ControlLaw law(gains());
  // 80 (-0.2) + 0.25 = -15.75 V -> -10 V
  EXPECT_EQ(law.control_v(-0.1, 0.1, 0.0, 0.0), -10.0);
  EXPECT_EQ(law.control_v(0.1, 0.1, 0.0, 1.0e5), -10.0);
}

TEST(ControlLaw, SaturationFollowsTheConfiguredLimit) {
  ControlLawParams p = gains();
  p.max_voltage_v = 2.5;
  const ControlLaw law(p);
  EXPECT_EQ(law.control_v(0.3, 0.1, 0.0, 0.0), 2.5);
  EXPECT_EQ(law.control_v(-0.1, 0.1, 0.0, 0.0), -2.5);
  EXPECT_NEAR(law.control_v(0.12, 0.1, 0.0, 0.0), 1.85, kToleranceV);  // 1.6 + 0.25, inside
}

TEST(ControlLaw, RestingControlIsEquation11) {
  const ControlLaw law(gains());
  // u* = K_y (y_d - y*) + u_0 = 80 (0.17 - 0.16913) + 0.25 = 0.0696 + 0.25 = 0.3196 V
  EXPECT_NEAR(law.resting_control_v(0.17, 0.16913), 0.3196, 1e-11);
  // Stopped beyond the set point: 80 (0.17 - 0.1717) + 0.25 = -0.136 + 0.25 = 0.114 V
  EXPECT_NEAR(law.resting_control_v(0.17, 0.1717), 0.114, 1e-11);
}

TEST(ControlLaw, RestingControlIsTheSaturatedValueActuallyHeld) {
  const ControlLaw law(gains());
  // 80 (0.2 - 0.0) + 0.25 = 16.25 V: the valve only ever sees 10 V, so u* is 10 V.
  EXPECT_EQ(law.resting_control_v(0.2, 0.0), 10.0);
  EXPECT_EQ(law.resting_control_v(-0.2, 0.0), -10.0);
}

}  // namespace
}  // namespace pneu::controller
