// Specification of the state feedback of Eq. 4 (docs/model.md section 5),
//   u = K_y (y_d - y) - K_v v_hat - K_a a_hat + u_0, saturated to [-u_max, u_max],
// and of the constant control u* = K_y (y_d - y*) + u_0 held while the carriage is stuck (Eq. 11).
// Expected values are worked out by hand in the comments.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>

#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/controller/loop_params.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/model/valve.hpp"
#include "support/config_error_matcher.hpp"

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

// --- gains scheduled by position (controller.law.gains: scheduled) -------------------------------

// Three nodes, 0.1 m apart from -0.1 m, gains that differ at each so that interpolation shows.
model::GainSchedule three_nodes() {
  return model::GainSchedule(-0.1, 0.1, {{100.0, 1.0, 0.01}, {200.0, 3.0, 0.03}, {400.0, 7.0, 0.07}});
}

TEST(ScheduledControlLaw, TakesTheGainsInterpolatedAtTheMeasuredPosition) {
  const ControlLaw law(gains(), three_nodes());
  // At y = -0.05, halfway between the first two nodes: K_y 150, K_v 2, K_a 0.02.
  // 150 (0 - (-0.05)) - 2 (0.1) - 0.02 (-3) + 0.25 = 7.5 - 0.2 + 0.06 + 0.25 = 7.61 V
  EXPECT_NEAR(law.control_v(0.0, -0.05, 0.1, -3.0), 7.61, kToleranceV);
  // At y = 0.05, halfway between the last two: K_y 300, K_v 5, K_a 0.05.
  // 300 (0.06 - 0.05) - 5 (-0.2) - 0.05 (10) + 0.25 = 3 + 1 - 0.5 + 0.25 = 3.75 V
  EXPECT_NEAR(law.control_v(0.06, 0.05, -0.2, 10.0), 3.75, 1e-11);
}

TEST(ScheduledControlLaw, HoldsTheEndNodesGainsBeyondTheTable) {
  const ControlLaw law(gains(), three_nodes());
  // Below the first node: K_y 100; 100 (-0.2 - (-0.21)) + 0.25 = 1.25 V
  EXPECT_NEAR(law.control_v(-0.2, -0.21, 0.0, 0.0), 1.25, 1e-11);
  // Above the last node: K_v 7; -7 (0.1) + 0.25 = -0.45 V
  EXPECT_NEAR(law.control_v(0.2, 0.2, 0.1, 0.0), -0.45, kToleranceV);
}

TEST(ScheduledControlLaw, RestingControlTakesTheGainsAtTheStopPosition) {
  const ControlLaw law(gains(), three_nodes());
  // u* of Eq. 11 with K_y at y* = 0.0 (the middle node, 200): 200 (0.01 - 0) + 0.25 = 2.25 V
  EXPECT_NEAR(law.resting_control_v(0.01, 0.0), 2.25, 1e-11);
  // ... and at y* = 0.05 (300): 300 (0.04 - 0.05) + 0.25 = -2.75 V
  EXPECT_NEAR(law.resting_control_v(0.04, 0.05), -2.75, 1e-11);
}

TEST(ScheduledControlLaw, FixedGainsStayThoseOfTheConfiguration) {
  const ControlLaw law(gains());
  EXPECT_TRUE(law.schedule().empty());
  EXPECT_EQ(law.gains_at(-0.2).position_gain_v_per_m, 80.0);
  EXPECT_EQ(law.gains_at(0.2).acceleration_gain_v_s2_per_m, 0.002);
}

TEST(ScheduledControlLaw, ScaledMultipliesEveryGainFixedOrScheduledAndKeepsTheOffset) {
  // A sweep's mistuned law (--gain-spread): every gain times the factor, u_0 and u_max unchanged.
  const ControlLaw scheduled = ControlLaw(gains(), three_nodes()).scaled(1.5);
  EXPECT_DOUBLE_EQ(scheduled.gains_at(-0.05).position_gain_v_per_m, 225.0);  // 1.5 x 150
  EXPECT_DOUBLE_EQ(scheduled.gains_at(0.1).velocity_gain_v_s_per_m, 10.5);   // 1.5 x 7
  EXPECT_DOUBLE_EQ(scheduled.gains_at(-0.1).acceleration_gain_v_s2_per_m, 0.015);
  EXPECT_NEAR(scheduled.resting_control_v(0.01, 0.0), 300.0 * 0.01 + 0.25, 1e-11);  // K_y 1.5 x 200
  const ControlLaw fixed = ControlLaw(gains()).scaled(0.5);
  EXPECT_DOUBLE_EQ(fixed.gains_at(0.0).position_gain_v_per_m, 40.0);
  EXPECT_DOUBLE_EQ(fixed.gains_at(0.0).velocity_gain_v_s_per_m, gains().velocity_gain_v_s_per_m * 0.5);
  EXPECT_EQ(fixed.params().offset_v, gains().offset_v);
  EXPECT_NEAR(fixed.resting_control_v(-0.2, 0.0), -7.75, 1e-12);  // 40 (-0.2) + 0.25, not saturated
}

config::Config scheduled_config(std::vector<std::string> overrides = {}) {
  overrides.push_back("controller.law.gains=scheduled");
  return config::load_string(config::default_config_yaml(), overrides);
}

TEST(ScheduledControlLaw, IsDesignedFromTheConfigurationAtEveryNode) {
  const assembly::RunSpec spec = assembly::RunSpec::of(scheduled_config());
  const config::Config& c = spec.config();
  const model::ValveCharacteristic& valve = spec.valve();
  const ControlLaw& law = spec.law();
  const auto& d = c.controller.law.design;
  const model::GainSchedule expected = model::design_schedule(
      c.plant, valve, c.controller.law.offset_v, {d.real_pole_1_per_s, d.natural_frequency_rad_per_s, d.damping},
      {d.max_position_gain_v_per_m, d.max_velocity_gain_v_s_per_m, d.max_acceleration_gain_v_s2_per_m},
      d.node_spacing_m);
  ASSERT_EQ(law.schedule().size(), expected.size());
  ASSERT_GT(law.schedule().size(), 40u);  // 10 mm over the 0.5 m stroke: 51 nodes
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(law.gains_at(expected.position_m(i)).position_gain_v_per_m, expected.node(i).position_gain_v_per_m);
    EXPECT_EQ(law.gains_at(expected.position_m(i)).velocity_gain_v_s_per_m, expected.node(i).velocity_gain_v_s_per_m);
  }
  // The loop's parameters carry the same law.
  EXPECT_EQ(LoopParams::from(c, law).law.gains_at(0.123).position_gain_v_per_m, law.gains_at(0.123).position_gain_v_per_m);
}

TEST(ScheduledControlLaw, RefusingADesignThatNeedsANegativeGainStopsItBeforeTheLoopWithTheReason) {
  // omega 20 rad/s is below sqrt(k_s / M) at the stroke's ends: K_v would be negative there.
  config::Config c = scheduled_config(
      {"controller.law.design.natural_frequency_rad_per_s=20", "controller.law.design.infeasible=refuse"});
  EXPECT_THAT([&] { (void)assembly::RunSpec::of(c); },
              ::testing::Throws<config::ConfigError>(test::IsConfigError(
                  "controller.law.design", ::testing::AllOf(::testing::HasSubstr("at y = -0.25 m"),
                                                            ::testing::HasSubstr("K_v would be negative")))));
}

TEST(ScheduledControlLaw, RefusingADesignBeyondAGainLimitNamesTheGain) {
  config::Config c = scheduled_config(
      {"controller.law.design.max_position_gain_v_per_m=100", "controller.law.design.infeasible=refuse"});
  EXPECT_THAT([&] { (void)assembly::RunSpec::of(c); },
              ::testing::Throws<config::ConfigError>(test::IsConfigError(
                  "controller.law.design", ::testing::AllOf(::testing::HasSubstr("K_y = "),
                                                            ::testing::HasSubstr("beyond its limit 100 V/m")))));
}

TEST(ScheduledControlLaw, RefusingADesignTheSampledLoopCannotFollowNamesTheLoop) {
  // Stable on the continuous model everywhere, but at 300 Hz the sampled loop is not (pneu-plant
  // tune: max |z| 1.0089 near mid-stroke); at the default 1 kHz it is.
  config::Config c = scheduled_config({"controller.rate_hz=300", "controller.law.design.infeasible=refuse"});
  EXPECT_THAT([&] { (void)assembly::RunSpec::of(c); },
              ::testing::Throws<config::ConfigError>(test::IsConfigError(
                  "controller.law.design", ::testing::AllOf(::testing::HasSubstr("the sampled loop is unstable"),
                                                            ::testing::HasSubstr("higher loop rate")))));
}

// Where the requested dynamics cannot be had, the gains fall back node by node (the default): each
// fallback named, its gains feasible and the sampled loop stable with them there, every other node
// the requested design's.
void expect_falls_back_only_where(const std::vector<std::string>& overrides, const char* reason, double lo_m,
                                  double hi_m) {
  const assembly::RunSpec spec = assembly::RunSpec::of(scheduled_config(overrides));
  const config::Config& c = spec.config();
  const model::ValveCharacteristic& valve = spec.valve();
  const std::vector<model::DesignFallback>& fallbacks = spec.fallbacks();
  const ControlLaw& law = spec.law();
  ASSERT_FALSE(fallbacks.empty());
  const double u_e = model::equilibrium_voltage_v(valve, c.plant.geometry, c.plant.gas.exhaust_pressure_pa);
  const model::SampledLoop loop = sampled_loop(c);
  for (const model::DesignFallback& f : fallbacks) {
    SCOPED_TRACE(f.position_m);
    EXPECT_THAT(f.reason, ::testing::HasSubstr(reason));
    EXPECT_GE(f.position_m, lo_m - 1e-9);
    EXPECT_LE(f.position_m, hi_m + 1e-9);
    std::size_t node = 0;
    while (std::abs(law.schedule().position_m(node) - f.position_m) > 1e-9) ++node;
    const model::LawGains g = law.schedule().node(node);
    EXPECT_EQ(g.velocity_gain_v_s_per_m, f.gains.velocity_gain_v_s_per_m);
    EXPECT_GE(g.velocity_gain_v_s_per_m, 0.0);
    EXPECT_GE(g.acceleration_gain_v_s2_per_m, 0.0);
    const auto m = model::tangent_linear_model(c.plant, valve, f.position_m, u_e);
    EXPECT_LT(model::max_magnitude(model::sampled_poles(m, g, loop)), 1.0);
  }
  // Everywhere else: the requested design, as the strict one places it.
  const auto& d = c.controller.law.design;
  for (std::size_t i = 0; i < law.schedule().size(); ++i) {
    const double y = law.schedule().position_m(i);
    if (std::any_of(fallbacks.begin(), fallbacks.end(), [&](const auto& f) { return std::abs(f.position_m - y) < 1e-9; }))
      continue;
    const auto t = model::tangent_linear_model(c.plant, valve, y, u_e).third_order;
    const model::LawGains placed = model::place_poles(
        t, {d.real_pole_1_per_s, d.natural_frequency_rad_per_s, d.damping},
        {d.max_position_gain_v_per_m, d.max_velocity_gain_v_s_per_m, d.max_acceleration_gain_v_s2_per_m});
    // (The node's position as the table keeps it: the last bits of the gains may differ.)
    EXPECT_NEAR(law.schedule().node(i).position_gain_v_per_m / placed.position_gain_v_per_m, 1.0, 1e-9) << y;
  }
}

TEST(ScheduledControlLaw, ADesignThatNeedsANegativeGainAtTheStrokesEndFallsBackThereAlone) {
  // omega 20 rad/s: K_v < 0 near the ends, where the air spring is stiffest.
  expect_falls_back_only_where({"controller.law.design.natural_frequency_rad_per_s=20"}, "K_v would be negative", -0.25,
                               0.25);
}

TEST(ScheduledControlLaw, ALoopTooSlowForTheRequestedPolesFallsBackToSlowerOnesWhereItFails) {
  expect_falls_back_only_where({"controller.rate_hz=300"}, "the sampled loop is unstable", -0.25, 0.25);
}

TEST(ScheduledControlLaw, TheLoopsParametersRefuseAScheduledLawWithoutItsTable) {
  EXPECT_THROW((void)LoopParams::from(scheduled_config()), std::invalid_argument);
}

}  // namespace
}  // namespace pneu::controller
