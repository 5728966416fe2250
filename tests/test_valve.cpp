// Specification of the servo-distributor model (docs/model.md section 3): the ISO 6358 orifice, the
// 3-way valve's mass flow q(w, p), its null-flow pressure and the force gain characteristic.
// Expected values come from the formulas of docs/model.md written out again in this file, not from the
// code under test.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include "pneu/model/params.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::model {
namespace {

// Paper bench constants (docs/model.md section 7), restated so that the tests do not trust params.hpp.
constexpr double kSupplyPa = 7.0e5;
constexpr double kExhaustPa = 1.0e5;
constexpr double kCriticalRatio = 0.3;
constexpr double kRho0 = 1.185;
constexpr double kT0 = 293.15;
constexpr double kCMax = 1.6e-8;
constexpr double kCLeakIn = 8.0e-10;
constexpr double kCLeakOut = 1.28e-9;
constexpr double kUMax = 10.0;

// ISO 6358 mass flow from p_up to p_down (p_down <= p_up, ratio <= 0.999), docs/model.md section 3.
double iso6358_flow(double c, double p_up, double p_down, double temperature_k) {
  const double choked = c * kRho0 * p_up * std::sqrt(kT0 / temperature_k);
  const double x = p_down / p_up;
  if (x <= kCriticalRatio) return choked;
  const double s = (x - kCriticalRatio) / (1.0 - kCriticalRatio);
  return choked * std::sqrt(1.0 - s * s);
}

double inlet_conductance(double w) { return kCLeakIn + kCMax * std::clamp(w / kUMax, 0.0, 1.0); }
double outlet_conductance(double w) { return kCLeakOut + kCMax * std::clamp(-w / kUMax, 0.0, 1.0); }

// A valve at a chamber temperature other than T_0, so that sqrt(T_0 / T) is exercised.
constexpr double kWarmK = 313.15;
ValveModel warm_valve() {
  Gas gas;
  gas.temperature_k = kWarmK;
  return ValveModel(ValveParams{}, gas);
}

std::vector<double> linspace(double lo, double hi, int n) {
  std::vector<double> out;
  for (int i = 0; i < n; ++i) out.push_back(lo + (hi - lo) * i / (n - 1));
  return out;
}

// --- ISO 6358 orifice ---------------------------------------------------------------------------

TEST(Orifice, FlowIsChokedAtOrBelowCriticalPressureRatio) {
  const ValveModel valve = warm_valve();
  const double c = 1.0e-8, p_up = 6.0e5;
  for (double x : {0.0, 0.05, 0.1, 0.2, 0.29, 0.3}) {
    const double expected = c * kRho0 * p_up * std::sqrt(kT0 / kWarmK);
    // Same product evaluated in another order: a few ulps.
    EXPECT_NEAR(valve.orifice().mass_flow_kg_per_s(c, p_up, x * p_up), expected, 1e-14 * expected)
        << "x = " << x;
  }
}

TEST(Orifice, SubsonicFlowFollowsTheIsoEllipse) {
  const ValveModel valve = warm_valve();
  const double c = 1.0e-8, p_up = 6.0e5;
  for (double x : linspace(0.301, 0.999, 200)) {
    const double p_down = x * p_up;
    const double ratio = p_down / p_up;
    const double s = (ratio - kCriticalRatio) / (1.0 - kCriticalRatio);
    const double expected = c * kRho0 * p_up * std::sqrt(kT0 / kWarmK) * std::sqrt(1.0 - s * s);
    // 1 - s^2 falls to 3e-3 at x = 0.999, which amplifies rounding of s to ~1e-13 relative.
    EXPECT_NEAR(valve.orifice().mass_flow_kg_per_s(c, p_up, p_down), expected, 1e-12 * expected)
        << "x = " << x;
  }
}

TEST(Orifice, ReversedFlowIsTheNegativeOfTheSwappedFlow) {
  const ValveModel valve = warm_valve();
  const Orifice& orifice = valve.orifice();
  const double c = 1.0e-8;
  for (double p_low : {1.0e5, 2.0e5, 4.5e5, 5.999e5}) {
    const double p_high = 6.0e5;
    EXPECT_DOUBLE_EQ(orifice.mass_flow_kg_per_s(c, p_low, p_high),
                     -orifice.mass_flow_kg_per_s(c, p_high, p_low));
    EXPECT_LT(orifice.mass_flow_kg_per_s(c, p_low, p_high), 0.0);
  }
  // And the reversed value is the ISO formula with p_b upstream (1e-12: see the subsonic test).
  const double expected = -iso6358_flow(c, 5.0e5, 2.0e5, kWarmK);
  EXPECT_NEAR(orifice.mass_flow_kg_per_s(c, 2.0e5, 5.0e5), expected, 1e-12 * std::abs(expected));
}

TEST(Orifice, NoFlowAtEqualPressures) {
  const ValveModel valve = warm_valve();
  for (double p : {1.0e5, 3.3e5, 7.0e5}) {
    EXPECT_EQ(valve.orifice().mass_flow_kg_per_s(1.0e-8, p, p), 0.0);
  }
}

TEST(Orifice, LaminarRegionIsTheSecantFromRatio0999ToZeroAtOne) {
  const ValveModel valve = warm_valve();
  const double c = 1.0e-8, p_up = 6.0e5;
  const double at_threshold = iso6358_flow(c, p_up, 0.999 * p_up, kWarmK);
  for (double x : {0.99901, 0.9993, 0.9995, 0.9999, 0.999999, 1.0}) {
    const double p_down = x * p_up;
    const double expected = at_threshold * (1.0 - p_down / p_up) / (1.0 - 0.999);
    // Rounding of the ratio near 1 only: relative 1e-9 of the flow at the threshold.
    EXPECT_NEAR(valve.orifice().mass_flow_kg_per_s(c, p_up, p_down), expected, 1e-9 * at_threshold)
        << "x = " << x;
  }
  // Continuous at the switch: one part in 1e6 of the pressure ratio past 0.999 changes the flow by
  // about 1e-6 / 1e-3 = 1e-3 of its value, so 2e-3 is continuity, a jump would be far larger.
  const double just_past = valve.orifice().mass_flow_kg_per_s(c, p_up, 0.999001 * p_up);
  EXPECT_NEAR(just_past, at_threshold, 2e-3 * at_threshold);
  EXPECT_LT(just_past, at_threshold);
}

// Central finite differences with a 1 Pa step. The points keep > 100 Pa from the kinks of phi
// (x = b, x = 0.999, x = 1), so the truncation error (h / (p_up (1 - x)))^2 stays below 1e-7 of
// the slope; rounding adds eps * m / h ~ 1e-18 kg/(s Pa). Tolerance: 1e-6 of K = C rho_0
// sqrt(T0/T), the natural scale of both derivatives (they range from 0 to ~55 K).
TEST(Orifice, AnalyticPressureDerivativesMatchCentralDifferences) {
  const ValveModel valve = warm_valve();
  const Orifice& orifice = valve.orifice();
  const double c = 1.0e-8;
  const double scale = c * kRho0 * std::sqrt(kT0 / kWarmK);
  const double h = 1.0;
  const double p_up = 5.0e5;
  for (double x : {0.1, 0.2, 0.5, 0.8, 0.95, 0.99, 0.9995}) {
    for (bool reversed : {false, true}) {
      const double p_a = reversed ? x * p_up : p_up;
      const double p_b = reversed ? p_up : x * p_up;
      const double fd_pb = (orifice.mass_flow_kg_per_s(c, p_a, p_b + h) -
                            orifice.mass_flow_kg_per_s(c, p_a, p_b - h)) /
                           (2.0 * h);
      const double fd_pa = (orifice.mass_flow_kg_per_s(c, p_a + h, p_b) -
                            orifice.mass_flow_kg_per_s(c, p_a - h, p_b)) /
                           (2.0 * h);
      EXPECT_NEAR(orifice.d_mass_flow_d_pb(c, p_a, p_b), fd_pb, 1e-6 * scale)
          << "x = " << x << (reversed ? " reversed" : "");
      EXPECT_NEAR(orifice.d_mass_flow_d_pa(c, p_a, p_b), fd_pa, 1e-6 * scale)
          << "x = " << x << (reversed ? " reversed" : "");
      EXPECT_LE(orifice.d_mass_flow_d_pb(c, p_a, p_b), 0.0);
      EXPECT_GE(orifice.d_mass_flow_d_pa(c, p_a, p_b), 0.0);
    }
  }
}

// --- The 3-way valve ----------------------------------------------------------------------------

TEST(ValveModel, ConductancesOpenLinearlyFromTheLeaksToFullOpening) {
  const ValveModel valve(ValveParams{}, Gas{});
  for (double w : linspace(-12.0, 12.0, 97)) {  // also beyond +-u_max, where they saturate
    // Rounding of values ~1e-8: 1e-22.
    EXPECT_NEAR(valve.inlet_conductance_m3_per_s_pa(w), inlet_conductance(w), 1e-22) << w;
    EXPECT_NEAR(valve.outlet_conductance_m3_per_s_pa(w), outlet_conductance(w), 1e-22) << w;
  }
}

// A real servo-valve's null offset w_0: the valve closes at w_0, not at 0, and opens from there.
TEST(ValveModel, ANullOffsetShiftsTheOpeningAndTheValveClosesAtTheOffset) {
  ValveParams shifted;
  shifted.null_offset_v = 0.05;
  const ValveModel valve(shifted, Gas{}), ideal(ValveParams{}, Gas{});
  EXPECT_EQ(valve.inlet_conductance_m3_per_s_pa(0.05), kCLeakIn);
  EXPECT_EQ(valve.outlet_conductance_m3_per_s_pa(0.05), kCLeakOut);
  EXPECT_GT(valve.outlet_conductance_m3_per_s_pa(0.0), kCLeakOut) << "at 0 V it vents";
  for (double w : linspace(-9.9, 9.9, 67))
    for (double p : {1.5e5, 3.0e5, 5.5e5}) {
      EXPECT_NEAR(valve.mass_flow_kg_per_s(w + 0.05, p), ideal.mass_flow_kg_per_s(w, p), 1e-15) << w << " " << p;
      EXPECT_NEAR(valve.null_pressure_pa(w + 0.05), ideal.null_pressure_pa(w), 1e-6) << w;
    }
  // Near u = 0 the null-flow pressure moves by kilopascals per 10 mV: an offset of 10 mV is a
  // pressure the forecasts must not ignore.
  EXPECT_GT(ideal.null_pressure_pa(0.01) - ideal.null_pressure_pa(0.0), 1e3);
}

TEST(ValveModel, FlowIsTheInletOrificeMinusTheOutletOrifice) {
  const ValveModel valve(ValveParams{}, Gas{});
  for (double w : {-10.0, -4.0, -0.3, 0.0, 0.2, 5.0, 10.0}) {
    for (double p : {1.2e5, 2.0e5, 3.0e5, 4.0e5, 6.0e5, 6.9e5}) {
      const double expected = iso6358_flow(inlet_conductance(w), kSupplyPa, p, kT0) -
                              iso6358_flow(outlet_conductance(w), p, kExhaustPa, kT0);
      // Difference of two flows of up to 1.4e-2 kg/s, each good to ~1e-13 relative.
      EXPECT_NEAR(valve.mass_flow_kg_per_s(w, p), expected, 1e-14) << "w = " << w << " p = " << p;
    }
  }
}

TEST(ValveModel, FlowDecreasesWithChamberPressure) {
  const ValveModel valve(ValveParams{}, Gas{});
  for (double w : linspace(-10.0, 10.0, 81)) {
    double previous = valve.mass_flow_kg_per_s(w, kExhaustPa);
    for (double p = kExhaustPa + 1000.0; p <= kSupplyPa; p += 1000.0) {
      const double q = valve.mass_flow_kg_per_s(w, p);
      EXPECT_LT(q, previous) << "w = " << w << " p = " << p;
      previous = q;
    }
  }
}

TEST(ValveModel, FillsAtExhaustPressureAndEmptiesAtSupplyPressure) {
  const ValveModel valve(ValveParams{}, Gas{});
  for (double w : linspace(-10.0, 10.0, 41)) {
    const double q_at_exhaust = valve.mass_flow_kg_per_s(w, kExhaustPa);
    const double q_at_supply = valve.mass_flow_kg_per_s(w, kSupplyPa);
    EXPECT_GE(q_at_exhaust, 0.0) << w;
    EXPECT_LE(q_at_supply, 0.0) << w;
    // Only the inlet flows at p = p_E, only the outlet at p = p_S (1e-14: as in the flow test).
    EXPECT_NEAR(q_at_exhaust, iso6358_flow(inlet_conductance(w), kSupplyPa, kExhaustPa, kT0),
                1e-14);
    EXPECT_NEAR(q_at_supply, -iso6358_flow(outlet_conductance(w), kSupplyPa, kExhaustPa, kT0),
                1e-14);
  }
}

TEST(ValveModel, DqDpMatchesCentralDifferences) {
  const ValveModel valve(ValveParams{}, Gas{});
  // Step 1 Pa; the pressures avoid the kinks at b p_S, p_E / b, 0.999 p_S and p_E / 0.999.
  const double h = 1.0;
  for (double w : {-10.0, -3.0, -0.5, 0.0, 0.2, 1.0, 10.0}) {
    for (double p : {1.05e5, 1.5e5, 2.5e5, 4.0e5, 5.5e5, 6.5e5, 6.95e5}) {
      const double fd =
          (valve.mass_flow_kg_per_s(w, p + h) - valve.mass_flow_kg_per_s(w, p - h)) / (2.0 * h);
      // Truncation (h / (p (1 - x)))^2 < 1e-7 relative at the closest point (x = 0.993); 1e-6.
      EXPECT_NEAR(valve.dq_dp(w, p), fd, 1e-6 * std::abs(fd)) << "w = " << w << " p = " << p;
      EXPECT_LT(valve.dq_dp(w, p), 0.0);
    }
  }
}

TEST(ValveModel, NullPressureRisesMonotonicallyWithVoltageInsideTheSupplyRange) {
  const ValveModel valve(ValveParams{}, Gas{});
  double previous = valve.null_pressure_pa(-kUMax);
  EXPECT_GE(previous, kExhaustPa);
  for (double w : linspace(-kUMax, kUMax, 4001)) {  // 5 mV steps
    const double p_null = valve.null_pressure_pa(w);
    EXPECT_GE(p_null, kExhaustPa) << w;
    EXPECT_LE(p_null, kSupplyPa) << w;
    if (w > -kUMax) {
      EXPECT_GT(p_null, previous) << "w = " << w;
    }
    previous = p_null;
  }
}

TEST(ValveModel, NoFlowAtTheNullPressure) {
  const ValveModel valve(ValveParams{}, Gas{});
  for (double w : linspace(-kUMax, kUMax, 201)) {
    const double p_null = valve.null_pressure_pa(w);
    // The root is bracketed to 1e-7 Pa, so the residual flow is below |dq/dp| * 1e-7 Pa;
    // allow ten times that, and require the sign change over +-1e-4 Pa around it.
    EXPECT_LE(std::abs(valve.mass_flow_kg_per_s(w, p_null)),
              1e-6 * std::abs(valve.dq_dp(w, p_null)))
        << "w = " << w;
    EXPECT_GT(valve.mass_flow_kg_per_s(w, p_null - 1e-4), 0.0) << w;
    EXPECT_LT(valve.mass_flow_kg_per_s(w, p_null + 1e-4), 0.0) << w;
  }
}

TEST(ValveModel, EquilibriumVoltageBalancesThePressureForces) {
  const ValveModel valve(ValveParams{}, Gas{});
  const Geometry geometry;
  const double u_e = equilibrium_voltage_v(valve, geometry, kExhaustPa);
  ASSERT_GT(u_e, -kUMax);
  ASSERT_LT(u_e, kUMax);
  const double s_p = std::numbers::pi / 4.0 * 0.032 * 0.032;
  const double s_r = std::numbers::pi / 4.0 * 0.020 * 0.020;
  const double s_n = s_p - s_r;
  // u_e is solved to 1e-12 V with dF_e/du ~ 450 N/V, p_null to 1e-7 Pa: residual < 1e-8 N.
  EXPECT_NEAR(s_p * valve.null_pressure_pa(u_e) - s_n * valve.null_pressure_pa(-u_e),
              s_r * kExhaustPa, 1e-6);
  // It is a true crossing, not a clamped end: 1 mV either side the force has opposite signs.
  EXPECT_LT(equilibrium_force_n(valve, geometry, kExhaustPa, u_e - 1e-3), 0.0);
  EXPECT_GT(equilibrium_force_n(valve, geometry, kExhaustPa, u_e + 1e-3), 0.0);
}

TEST(ValveModel, EquilibriumForceIncreasesWithVoltage) {
  const ValveModel valve(ValveParams{}, Gas{});
  const Geometry geometry;
  double previous = equilibrium_force_n(valve, geometry, kExhaustPa, -kUMax);
  for (double u : linspace(-kUMax, kUMax, 4001)) {
    const double force = equilibrium_force_n(valve, geometry, kExhaustPa, u);
    if (u > -kUMax) {
      EXPECT_GT(force, previous) << "u = " << u;
    }
    previous = force;
  }
}

}  // namespace
}  // namespace pneu::model
