// Specification of the plant (docs/model.md sections 1, 2 and 4): Eq. 2 with hybrid Karnopp friction,
// events located inside the step, hard end stops.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <utility>
#include <vector>

#include "pneu/model/chamber.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/valve.hpp"
#include "pneu/sim_plant/plant.hpp"

namespace pneu::plant {
namespace {

using Kind = PlantEvent::Kind;
using model::equilibrium_force_n;
using model::equilibrium_voltage_v;
using model::PlantParams;

constexpr double kSampleS = 1.0e-3;  // the bench's sample period (docs/model.md section 7)
constexpr double kExhaustPa = 1.0e5;
constexpr double kForceSPlus = 45.0;
constexpr double kForceSMinus = -50.0;
constexpr double kHalfStrokeM = 0.25;

double area_p() { return std::numbers::pi / 4.0 * 0.032 * 0.032; }
double area_n() { return area_p() - std::numbers::pi / 4.0 * 0.020 * 0.020; }
double force_of(const PlantState& s) {
  return area_p() * s.p_p_pa - area_n() * s.p_n_pa -
         std::numbers::pi / 4.0 * 0.020 * 0.020 * kExhaustPa;
}

double equilibrium_voltage(const Plant& plant) {
  return equilibrium_voltage_v(plant.valve(), plant.params().geometry, kExhaustPa);
}

// The voltage whose equilibrium force F_e(u) equals `force_n`, by bisection on the increasing
// force gain characteristic.
double voltage_for_equilibrium_force(const Plant& plant, double force_n) {
  double lo = -10.0, hi = 10.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    const double f = equilibrium_force_n(plant.valve(), plant.params().geometry, kExhaustPa, mid);
    (f < force_n ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

int count_events(const std::vector<PlantEvent>& events, Kind kind) {
  return static_cast<int>(std::count_if(events.begin(), events.end(),
                                        [&](const PlantEvent& e) { return e.kind == kind; }));
}

// An open-loop run from rest at mid-stroke: u_e, then steps that make the carriage slide, stick,
// slide back and stop again. Returns the state after every 1 ms sample and every event.
struct Trajectory {
  std::vector<PlantState> samples;
  std::vector<PlantEvent> events;
};
Trajectory run_open_loop_sequence(const PlantParams& params) {
  Plant plant(params);
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.0, u_e);
  // (voltage [V], duration [s])
  const std::vector<std::pair<double, double>> profile{
      {u_e, 0.5}, {u_e + 0.6, 1.0}, {u_e - 0.8, 1.0}, {u_e + 0.3, 1.0}};
  Trajectory run;
  for (const auto& [u, duration] : profile) {
    const int n = static_cast<int>(std::lround(duration / kSampleS));
    for (int i = 0; i < n; ++i) {
      plant.step(kSampleS, u);
      run.samples.push_back(plant.state());
      for (const PlantEvent& e : plant.last_events()) run.events.push_back(e);
    }
  }
  return run;
}

// --- Pressure dynamics --------------------------------------------------------------------------

TEST(Plant, ClosedChambersFollowThePolytropicLaw) {
  PlantParams params;
  params.valve.leak_conductance_in_m3_per_s_pa = 0.0;  // u = 0 then closes both orifices
  params.valve.leak_conductance_out_m3_per_s_pa = 0.0;
  params.friction = {.static_positive_n = 1e-3,
                     .coulomb_positive_n = 1e-3,
                     .static_negative_n = -1e-3,
                     .coulomb_negative_n = -1e-3,
                     .viscous_n_s_per_m = 0.0,
                     .stribeck_velocity_m_per_s = 0.01,
                     .stick_velocity_m_per_s = 0.0};
  Plant plant(params);
  // A gas spring: launched at 0.5 m/s it oscillates over several cm (period ~0.6 s).
  plant.reset({.t_s = 0.0, .y_m = 0.0, .v_m_per_s = 0.5, .p_p_pa = 3.0e5, .p_n_pa = 3.0e5});
  const double k = 1.2;
  const auto volume_p = [](double y) { return 1.0e-5 + area_p() * (kHalfStrokeM + y); };
  const auto volume_n = [](double y) { return 1.0e-5 + area_n() * (kHalfStrokeM - y); };
  const double invariant_p = 3.0e5 * std::pow(volume_p(0.0), k);
  const double invariant_n = 3.0e5 * std::pow(volume_n(0.0), k);

  double y_min = 0.0, y_max = 0.0, worst = 0.0;
  for (int i = 0; i < 3000; ++i) {
    plant.step(kSampleS, 0.0);
    const PlantState& s = plant.state();
    y_min = std::min(y_min, s.y_m);
    y_max = std::max(y_max, s.y_m);
    worst = std::max({worst, std::abs(s.p_p_pa * std::pow(volume_p(s.y_m), k) / invariant_p - 1.0),
                      std::abs(s.p_n_pa * std::pow(volume_n(s.y_m), k) / invariant_n - 1.0)});
  }
  EXPECT_GT(y_max - y_min, 0.05);  // the piston really moved
  // RK4 at the sliding step h = 1/3 ms on a ~10 rad/s oscillation has a local error ~(h omega)^5
  // ~ 4e-15; measured worst 2.6e-13 over 3 s (9000 steps and 10 reversals; 3.4e-14 at 0.2 ms, about
  // the (5/3)^4 of RK4's order). 1e-12 leaves room for rounding; a wrong exponent, volume or sign of
  // the v-terms of Eq. 2 gives > 1e-2.
  EXPECT_LT(worst, 1e-12) << "measured " << worst;
}

// --- Friction -----------------------------------------------------------------------------------

TEST(Plant, SlidingFrictionFollowsTheAsymmetricStribeckCurve) {
  const Plant plant(PlantParams{});
  for (double v : {1e-4, 0.005, 0.01, 0.03, 0.2, 1.5}) {
    const double stribeck = std::exp(-(v / 0.01) * (v / 0.01));
    // Rounding of forces of tens of N: 1e-12 N.
    EXPECT_NEAR(plant.sliding_friction_n(Motion::kSlidingPositive, v),
                35.0 + (45.0 - 35.0) * stribeck + 60.0 * v, 1e-12)
        << v;
    EXPECT_NEAR(plant.sliding_friction_n(Motion::kSlidingNegative, -v),
                -38.0 + (-50.0 + 38.0) * stribeck - 60.0 * v, 1e-12)
        << v;
  }
}

// --- Stiction -----------------------------------------------------------------------------------

TEST(Plant, StuckCarriageStaysExactlyStillWhilePressuresEvolve) {
  Plant plant(PlantParams{});
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.1, u_e);
  const PlantState null = plant.state();
  // Both chambers 30 kPa above their null pressures with the same force as at equilibrium (F = 0):
  // each term of F decays monotonically from S_P * 30 kPa = 24 N, so |F| < 24 N < 45 N throughout.
  const double dp = 3.0e4;
  PlantState start = null;
  start.p_p_pa += dp;
  start.p_n_pa += dp * area_p() / area_n();
  plant.reset(start);
  ASSERT_EQ(plant.state().motion, Motion::kStuck);

  for (int i = 0; i < 10000; ++i) {  // 10 s
    plant.step(kSampleS, u_e);
    const PlantState& s = plant.state();
    ASSERT_GT(force_of(s), kForceSMinus);  // precondition of the test: F inside the band
    ASSERT_LT(force_of(s), kForceSPlus);
    ASSERT_EQ(s.y_m, 0.1) << "t = " << s.t_s;  // bitwise: no creep
    ASSERT_EQ(s.v_m_per_s, 0.0) << "t = " << s.t_s;
    ASSERT_EQ(s.motion, Motion::kStuck);
    ASSERT_TRUE(plant.last_events().empty());
  }
  // Not vacuous: the pressures did relax most of the way back to their null values.
  EXPECT_LT(std::abs(plant.state().p_p_pa - null.p_p_pa), 0.3 * dp);
  EXPECT_LT(std::abs(plant.state().p_n_pa - null.p_n_pa), 0.3 * dp * area_p() / area_n());
}

// Holds `u` from complete equilibrium at u_e until the first event; checks it is a breakaway at
// `bound` in `direction` and that nothing moved before.
void expect_breakaway_at_stiction_bound(double target_force_n, double bound, int direction) {
  Plant plant(PlantParams{});
  plant.reset_at_rest(0.0, equilibrium_voltage(plant));
  const double u = voltage_for_equilibrium_force(plant, target_force_n);

  std::vector<PlantEvent> events;
  for (int i = 0; i < 30000 && events.empty(); ++i) {  // up to 30 s
    const PlantState before = plant.state();
    plant.step(kSampleS, u);
    for (const PlantEvent& e : plant.last_events()) events.push_back(e);
    if (!events.empty()) {
      // The step that breaks away started inside the band.
      EXPECT_LT(direction * force_of(before), direction * bound);
      EXPECT_GT(events.front().t_s, before.t_s);
      EXPECT_LE(events.front().t_s, plant.state().t_s);
      break;
    }
    // No event yet: the carriage has not moved, and F is still inside the band.
    ASSERT_EQ(plant.state().y_m, 0.0);
    ASSERT_EQ(plant.state().v_m_per_s, 0.0);
    ASSERT_LT(direction * force_of(plant.state()), direction * bound) << plant.state().t_s;
  }
  ASSERT_EQ(count_events(events, Kind::kBreakaway), 1);
  ASSERT_EQ(events.size(), 1u);
  const PlantEvent& breakaway = events.front();
  EXPECT_EQ(breakaway.direction, direction);
  EXPECT_EQ(breakaway.y_m, 0.0);
  // Located to 1e-11 s while F rises at < 1e3 N/s: well below 1e-6 N, on the breaking side.
  EXPECT_NEAR(breakaway.force_n, bound, 1e-6);
  EXPECT_GE(direction * breakaway.force_n, direction * bound);

  // Then it moves in `direction`: friction starts at F_S, so it gathers speed slowly, but it does.
  double previous_y = plant.state().y_m;
  for (int i = 0; i < 100; ++i) {
    plant.step(kSampleS, u);
    EXPECT_GT(direction * (plant.state().y_m - previous_y), 0.0) << "t = " << plant.state().t_s;
    previous_y = plant.state().y_m;
  }
  EXPECT_GT(direction * plant.state().y_m, 1e-5);  // 100 ms later: tens of um (not a rounding)
}

TEST(Plant, BreaksAwayForwardWhenForceCrossesPositiveStiction) {
  // F_e 5 N beyond F_S+: the pressures creep towards it and cross F_S+ after a few seconds.
  expect_breakaway_at_stiction_bound(kForceSPlus + 5.0, kForceSPlus, +1);
}

TEST(Plant, BreaksAwayBackwardWhenForceCrossesNegativeStiction) {
  expect_breakaway_at_stiction_bound(kForceSMinus - 5.0, kForceSMinus, -1);
}

TEST(Plant, SticksOnlyWithForceInsideTheStictionBand) {
  const Trajectory run = run_open_loop_sequence(PlantParams{});
  ASSERT_GE(count_events(run.events, Kind::kStick), 2);  // the profile stops the carriage twice
  for (const PlantEvent& e : run.events) {
    if (e.kind != Kind::kStick) continue;
    EXPECT_GE(e.force_n, kForceSMinus) << "t = " << e.t_s;
    EXPECT_LE(e.force_n, kForceSPlus) << "t = " << e.t_s;
  }
}

TEST(Plant, ReversesInsteadOfStickingWhenForceIsBeyondStictionAtZeroVelocity) {
  Plant plant(PlantParams{});
  // Sliding backwards at 0.3 m/s against F ~ 220 N (> F_S+): it stops within ~20 ms, then must go
  // on forwards without sticking.
  plant.reset({.t_s = 0.0, .y_m = 0.0, .v_m_per_s = -0.3, .p_p_pa = 5.0e5, .p_n_pa = 3.0e5});
  std::vector<PlantEvent> events;
  for (int i = 0; i < 100 && events.empty(); ++i) {
    plant.step(kSampleS, 2.0);
    for (const PlantEvent& e : plant.last_events()) events.push_back(e);
  }
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().kind, Kind::kReversal);
  EXPECT_EQ(events.front().direction, +1);
  EXPECT_GT(events.front().force_n, kForceSPlus);
  EXPECT_EQ(count_events(events, Kind::kStick), 0);
  plant.step(kSampleS, 2.0);
  EXPECT_GT(plant.state().v_m_per_s, 0.0);
}

TEST(Plant, SlowApproachToZeroVelocityDoesNotStickWithForceBeyondStiction) {
  PlantParams params;
  params.mass_kg = 2000.0;  // decelerates at ~0.075 m/s^2: |v| < 1e-4 m/s for ~1.3 ms, 6 sub-steps
  Plant plant(params);
  const double u = voltage_for_equilibrium_force(plant, 100.0);
  plant.reset_at_rest(0.0, u);  // F = 100 N > F_S+, held there by u
  PlantState start = plant.state();
  start.v_m_per_s = -1.0e-3;
  plant.reset(start);
  std::vector<PlantEvent> events;
  for (int i = 0; i < 100 && events.empty(); ++i) {
    plant.step(kSampleS, u);
    for (const PlantEvent& e : plant.last_events()) events.push_back(e);
  }
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.front().kind, Kind::kReversal);  // not a stick inside the velocity band
  EXPECT_EQ(count_events(events, Kind::kStick), 0);
}

// --- End stops ----------------------------------------------------------------------------------

void expect_stops_at_end(double u, double end_m, int direction) {
  Plant plant(PlantParams{});
  plant.reset_at_rest(0.0, equilibrium_voltage(plant));
  std::vector<PlantEvent> events;
  bool reached = false;
  for (int i = 0; i < 3000; ++i) {  // 3 s at full opening
    plant.step(kSampleS, u);
    const PlantState& s = plant.state();
    ASSERT_LE(std::abs(s.y_m), kHalfStrokeM) << "t = " << s.t_s;
    for (const PlantEvent& e : plant.last_events()) events.push_back(e);
    if (s.y_m == end_m) reached = true;
    if (reached) {  // and stays there, at rest, pressed against the stop
      ASSERT_EQ(s.y_m, end_m);
      ASSERT_EQ(s.v_m_per_s, 0.0);
    }
  }
  EXPECT_TRUE(reached);
  ASSERT_EQ(count_events(events, Kind::kEndStop), 1);
  const auto stop = std::find_if(events.begin(), events.end(),
                                 [](const PlantEvent& e) { return e.kind == Kind::kEndStop; });
  EXPECT_EQ(stop->y_m, end_m);
  EXPECT_EQ(stop->direction, direction);
  EXPECT_EQ(plant.state().motion, Motion::kStuck);
}

TEST(Plant, FullOpeningDrivesTheCarriageOntoThePositiveEndStop) {
  expect_stops_at_end(+10.0, +kHalfStrokeM, +1);
}

TEST(Plant, FullReverseOpeningDrivesTheCarriageOntoTheNegativeEndStop) {
  expect_stops_at_end(-10.0, -kHalfStrokeM, -1);
}

// --- Numerics -----------------------------------------------------------------------------------

TEST(Plant, HalvingTheStepsChangesTheTrajectoryLessThanTheStatedTolerance) {
  PlantParams coarse, fine;  // the shipped steps (0.34 ms sliding, 1 ms stuck), and half of them
  fine.max_step_s = coarse.max_step_s / 2.0;
  fine.max_stuck_step_s = coarse.max_stuck_step_s / 2.0;
  ASSERT_EQ(coarse.max_step_s, 3.4e-4);
  ASSERT_EQ(coarse.max_stuck_step_s, 1.0e-3);

  const Trajectory a = run_open_loop_sequence(coarse);
  const Trajectory b = run_open_loop_sequence(fine);
  ASSERT_EQ(a.samples.size(), b.samples.size());
  double y_range = 0.0, dy = 0.0, dp = 0.0;
  for (std::size_t i = 0; i < a.samples.size(); ++i) {
    y_range = std::max(y_range, std::abs(a.samples[i].y_m));
    dy = std::max(dy, std::abs(a.samples[i].y_m - b.samples[i].y_m));
    dp = std::max({dp, std::abs(a.samples[i].p_p_pa - b.samples[i].p_p_pa),
                   std::abs(a.samples[i].p_n_pa - b.samples[i].p_n_pa)});
  }
  EXPECT_GT(y_range, 0.02);  // the profile does move the carriage (measured 0.157 m)
  EXPECT_EQ(a.events.size(), b.events.size());  // same stick/breakaway sequence (5 events)
  // Measured: max |dy| = 2.7e-12 m, max |dp| = 1.6e-5 Pa (the largest differences come from the
  // stick-velocity band, tested only at sub-step ends). Tolerances about 5x above.
  EXPECT_LT(dy, 1.5e-11) << "measured " << dy;
  EXPECT_LT(dp, 8.0e-5) << "measured " << dp;
}

TEST(Plant, AStuckCarriageWithItsValvesHeldTakesOneStepPerSampleWhereTheOpeningAllowsIt) {
  Plant plant(PlantParams{});  // max_stuck_step_s 1 ms
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.0, u_e);  // mid-stroke, near null: the pressures drift slowly
  const auto before = plant.rhs_evaluations();
  for (int i = 0; i < 100; ++i) plant.step(kSampleS, u_e + 0.02);
  ASSERT_EQ(plant.state().motion, Motion::kStuck);
  EXPECT_EQ(plant.rhs_evaluations() - before, 100u * 4u);  // one RK4 step (4 stages) per sample
}

// Valve P wide open to the exhaust with piston P on its end stop: the fastest pressure mode there
// is (the smallest volume, the largest opening). A 1 ms RK4 step on it is unstable (h lambda near
// 5); the plant subdivides the sample to its stable step and agrees with a fine integration.
TEST(Plant, AWideOpenValveOnADeadVolumeIsIntegratedAtItsStableStepEvenWhileStuck) {
  PlantParams params, reference;
  reference.max_step_s = reference.max_stuck_step_s = 1.0e-5;
  Plant plant(params), fine(reference);
  ASSERT_GT(1.0e-3 / plant.step_size_s(), 2.0);  // 1 ms would be beyond RK4's stability
  for (Plant* p : {&plant, &fine}) {
    p->set_external_force_n(-2000.0);  // holds the carriage on its negative end stop
    p->reset_at_rest(-kHalfStrokeM, 10.0);  // P at the supply's pressure, N vented
  }
  const auto before = plant.rhs_evaluations();
  double dp = 0.0;
  for (int i = 0; i < 50; ++i) {
    plant.step(kSampleS, -10.0);  // P vents through its wide-open exhaust, N fills
    fine.step(kSampleS, -10.0);
    ASSERT_EQ(plant.state().motion, Motion::kStuck);
    ASSERT_EQ(plant.state().y_m, -kHalfStrokeM);
    dp = std::max({dp, std::abs(plant.state().p_p_pa - fine.state().p_p_pa),
                   std::abs(plant.state().p_n_pa - fine.state().p_n_pa)});
  }
  EXPECT_GE(plant.rhs_evaluations() - before, 50u * 4u * 5u);  // at least 5 sub-steps a sample
  EXPECT_LT(plant.state().p_p_pa, 1.05 * kExhaustPa);          // vented, no overshoot or blow-up
  EXPECT_LT(dp, 15.0);  // Pa; measured 2.7 (of a 5 bar swing); one 1 ms step a sample diverges
}

TEST(Plant, StepIsDeterministic) {
  const Trajectory a = run_open_loop_sequence(PlantParams{});
  const Trajectory b = run_open_loop_sequence(PlantParams{});
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (std::size_t i = 0; i < a.samples.size(); ++i) {  // bitwise equal
    ASSERT_EQ(a.samples[i].y_m, b.samples[i].y_m);
    ASSERT_EQ(a.samples[i].v_m_per_s, b.samples[i].v_m_per_s);
    ASSERT_EQ(a.samples[i].p_p_pa, b.samples[i].p_p_pa);
    ASSERT_EQ(a.samples[i].p_n_pa, b.samples[i].p_n_pa);
    ASSERT_EQ(a.samples[i].t_s, b.samples[i].t_s);
    ASSERT_EQ(a.samples[i].motion, b.samples[i].motion);
  }
  ASSERT_EQ(a.events.size(), b.events.size());
  for (std::size_t i = 0; i < a.events.size(); ++i) {
    EXPECT_EQ(a.events[i].t_s, b.events[i].t_s);
    EXPECT_EQ(a.events[i].force_n, b.events[i].force_n);
  }
}

// --- Independent valve voltages -----------------------------------------------------------------

TEST(Plant, BothValvesAtFullReverseVentBothChambersAndTheCarriageStaysPut) {
  // The safe state "exhaust both chambers": u_P = u_N = -u_max, which Eq. 1 cannot express.
  Plant plant(PlantParams{});
  plant.reset_at_rest(0.0, equilibrium_voltage(plant));  // mid-stroke, complete equilibrium
  const double u_max = plant.params().valve.max_voltage_v;
  // Each chamber vents to the exhaust through the wide-open outlet orifice; the inlet leak keeps
  // it a little above p_E, at the null-flow pressure of w = -u_max.
  const double p_vented = plant.valve().null_pressure_pa(-u_max);
  ASSERT_GT(p_vented, kExhaustPa);
  ASSERT_LT(p_vented, kExhaustPa + 5.0e3);

  PlantState before = plant.state();
  double max_abs_force = 0.0;
  for (int i = 0; i < 2000; ++i) {  // 2 s
    plant.step(kSampleS, -u_max, -u_max);
    const PlantState& s = plant.state();
    ASSERT_LE(s.p_p_pa, before.p_p_pa) << "t = " << s.t_s;  // monotonically down
    ASSERT_LE(s.p_n_pa, before.p_n_pa) << "t = " << s.t_s;
    ASSERT_GE(s.p_p_pa, p_vented) << "t = " << s.t_s;       // never below where it settles
    ASSERT_GE(s.p_n_pa, p_vented) << "t = " << s.t_s;
    // Chamber N (smaller volume) vents faster, so F rises on the way (measured peak 28.4 N at
    // mid-stroke), but never to the stiction bound of 45 N: the carriage does not move at all.
    max_abs_force = std::max(max_abs_force, std::abs(force_of(s)));
    ASSERT_EQ(s.y_m, 0.0) << "t = " << s.t_s;
    ASSERT_EQ(s.v_m_per_s, 0.0) << "t = " << s.t_s;
    ASSERT_EQ(s.motion, Motion::kStuck);
    ASSERT_TRUE(plant.last_events().empty());
    before = s;
  }
  EXPECT_GT(max_abs_force, 10.0);  // not vacuous: the venting did push
  EXPECT_LT(max_abs_force, kForceSPlus);
  // Vented: within 10 Pa of the null-flow pressure after 2 s (from 3.4 and 4.9 bar).
  EXPECT_NEAR(plant.state().p_p_pa, p_vented, 10.0);
  EXPECT_NEAR(plant.state().p_n_pa, p_vented, 10.0);
}

TEST(Plant, OppositeVoltagesOnBothValvesAreEquation1BitForBit) {
  // step(dt, u) is the shorthand of step(dt, u, -u): the same trajectory and events, bit for bit,
  // over a sequence that slides, sticks, reverses and breaks away.
  Plant eq1(PlantParams{}), both(PlantParams{});
  const double u_e = equilibrium_voltage(eq1);
  eq1.reset_at_rest(0.0, u_e);
  both.reset_at_rest(0.0, u_e);
  std::size_t events = 0;
  for (const auto& [u, duration] : std::vector<std::pair<double, double>>{
           {u_e, 0.5}, {u_e + 0.6, 1.0}, {u_e - 0.8, 1.0}, {u_e + 0.3, 1.0}, {10.0, 0.3}}) {
    for (int i = 0; i < static_cast<int>(std::lround(duration / kSampleS)); ++i) {
      eq1.step(kSampleS, u);
      both.step(kSampleS, u, -u);
      const PlantState &a = eq1.state(), &b = both.state();
      ASSERT_EQ(a.t_s, b.t_s);
      ASSERT_EQ(a.y_m, b.y_m) << "t = " << a.t_s;
      ASSERT_EQ(a.v_m_per_s, b.v_m_per_s) << "t = " << a.t_s;
      ASSERT_EQ(a.p_p_pa, b.p_p_pa) << "t = " << a.t_s;
      ASSERT_EQ(a.p_n_pa, b.p_n_pa) << "t = " << a.t_s;
      ASSERT_EQ(a.motion, b.motion) << "t = " << a.t_s;
      ASSERT_EQ(eq1.last_events().size(), both.last_events().size());
      for (std::size_t k = 0; k < eq1.last_events().size(); ++k) {
        ASSERT_EQ(eq1.last_events()[k].t_s, both.last_events()[k].t_s);
        ASSERT_EQ(eq1.last_events()[k].force_n, both.last_events()[k].force_n);
      }
      events += eq1.last_events().size();
    }
  }
  EXPECT_GE(events, 5u);  // the sequence did exercise the event location
  EXPECT_EQ(eq1.rhs_evaluations(), both.rhs_evaluations());
}

TEST(Plant, EachValveDrivesItsOwnChamber) {
  // Valve P wide open to supply, valve N held at its equilibrium voltage: only chamber P fills.
  Plant plant(PlantParams{});
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.0, u_e);
  const PlantState start = plant.state();
  for (int i = 0; i < 2; ++i) plant.step(kSampleS, 10.0, -u_e);  // 2 ms: before any motion matters
  EXPECT_GT(plant.state().p_p_pa, start.p_p_pa + 1.0e4);
  EXPECT_NEAR(plant.state().p_n_pa, start.p_n_pa, 1.0e3);
}


// The disturbance input (hal.sim.pushes): an external force on the carriage adds to the pressure
// force against friction.
TEST(PlantPush, AForceWithinTheStictionBandMovesNothingAndOneBeyondItBreaksAwayAtOnce) {
  Plant plant(PlantParams{});
  const double u_e = equilibrium_voltage(plant);  // F = 0 at rest
  plant.reset_at_rest(0.05, u_e);
  const std::vector<model::Push> within{{0.1, 40.0, 0.3}};  // 40 N < F_S+ = 45 N
  for (int i = 1; i <= 500; ++i)
    step_with_pushes(plant, i * kSampleS, u_e, -u_e, within, [](auto events) { ASSERT_TRUE(events.empty()); });
  EXPECT_EQ(plant.state().y_m, 0.05);
  // 60 N from 0.6 s: beyond F_S+, the carriage breaks away at the push's start, towards +.
  const std::vector<model::Push> beyond{{0.6, 60.0, 0.05}};
  std::vector<PlantEvent> events;
  for (int i = 501; i <= 1500; ++i)
    step_with_pushes(plant, i * kSampleS, u_e, -u_e, beyond, [&](auto piece) {
      events.insert(events.end(), piece.begin(), piece.end());
    });
  ASSERT_GE(events.size(), 2u);
  EXPECT_EQ(events.front().kind, Kind::kBreakaway);
  EXPECT_EQ(events.front().direction, +1);
  EXPECT_NEAR(events.front().t_s, 0.6, 1e-9);
  EXPECT_NEAR(events.front().force_n, 0.0, 1e-6);  // the events report the pressure force
  // It slides on after the push (50 ms at 15 N net), then the air spring and friction stop it.
  EXPECT_GT(plant.state().y_m, 0.05 + 1e-4);
  EXPECT_EQ(plant.state().motion, Motion::kStuck);
  EXPECT_EQ(plant.external_force_n(), 0.0);  // the push is over
}

TEST(PlantPush, PushesAddUpWhileTheyOverlapAndChangeOnlyAtTheirEnds) {
  const std::vector<model::Push> pushes{{1.0, 10.0, 2.0}, {2.0, -25.0, 0.5}};
  EXPECT_EQ(push_force_n(pushes, 0.5), 0.0);
  EXPECT_EQ(push_force_n(pushes, 1.0), 10.0);
  EXPECT_EQ(push_force_n(pushes, 2.25), -15.0);
  EXPECT_EQ(push_force_n(pushes, 2.5), 10.0);
  EXPECT_EQ(push_force_n(pushes, 3.0), 0.0);
  EXPECT_EQ(next_push_change_s(pushes, 0.0), 1.0);
  EXPECT_EQ(next_push_change_s(pushes, 1.0), 2.0);
  EXPECT_EQ(next_push_change_s(pushes, 2.0), 2.5);
  EXPECT_EQ(next_push_change_s(pushes, 2.5), 3.0);
  EXPECT_TRUE(std::isinf(next_push_change_s(pushes, 3.0)));
}

TEST(PlantPush, WithoutPushesSteppingInPiecesIsPlantStepBitForBit) {
  Plant a(PlantParams{}), b(PlantParams{});
  const double u = equilibrium_voltage(a) + 0.4;
  a.reset_at_rest(0.0, u - 0.4);
  b.reset_at_rest(0.0, u - 0.4);
  for (int i = 1; i <= 2000; ++i) {
    const double t = i * kSampleS;  // as the sim backend steps: to the tick's time
    a.step(t - a.state().t_s, u);
    step_with_pushes(b, t, u, -u, {}, [](auto) {});
    ASSERT_EQ(a.state().y_m, b.state().y_m);
    ASSERT_EQ(a.state().p_p_pa, b.state().p_p_pa);
  }
  EXPECT_GT(a.state().y_m, 1e-3);  // not vacuous: it moved
}


// --- Heat exchange and the spool's lag (docs/model.md section 2) -------------------------------

namespace thermal {

constexpr double kGamma = 1.4;
constexpr double kR = 287.0;
constexpr double kWallK = 293.15;

// The default bench with the energy balance of plant.thermal, closed valves (no leak, u = 0 shuts
// both orifices) and, unless `sliding`, friction that holds the carriage whatever the force.
PlantParams closed_thermal_bench(double h_w_per_m2_k, bool sliding) {
  PlantParams params;
  params.has_thermal = true;
  params.thermal.heat_transfer_w_per_m2_k = h_w_per_m2_k;
  params.valve.leak_conductance_in_m3_per_s_pa = 0.0;
  params.valve.leak_conductance_out_m3_per_s_pa = 0.0;
  const double f = sliding ? 1e-3 : 1e6;
  params.friction = {.static_positive_n = f,
                     .coulomb_positive_n = f,
                     .static_negative_n = -f,
                     .coulomb_negative_n = -f,
                     .viscous_n_s_per_m = 0.0,
                     .stribeck_velocity_m_per_s = 0.01,
                     .stick_velocity_m_per_s = 0.0};
  return params;
}

double volume_p(double y) { return 1.0e-5 + area_p() * (kHalfStrokeM + y); }
double volume_n(double y) { return 1.0e-5 + area_n() * (kHalfStrokeM - y); }

// The largest relative change of p V^n and T V^(n-1) (n: the process's exponent) in both chambers
// of the gas spring launched at 0.5 m/s from mid-stroke, over `seconds`; `moved` the stroke covered.
struct SpringRun {
  double worst_pressure = 0.0, worst_temperature = 0.0, moved_m = 0.0;
};
SpringRun gas_spring(const PlantParams& params, double exponent, double seconds) {
  Plant plant(params);
  plant.reset({.t_s = 0.0, .y_m = 0.0, .v_m_per_s = 0.5, .p_p_pa = 3.0e5, .p_n_pa = 3.0e5});
  const double pressure_p = 3.0e5 * std::pow(volume_p(0.0), exponent);
  const double pressure_n = 3.0e5 * std::pow(volume_n(0.0), exponent);
  const double temperature_p = kWallK * std::pow(volume_p(0.0), exponent - 1.0);
  const double temperature_n = kWallK * std::pow(volume_n(0.0), exponent - 1.0);
  SpringRun run;
  double y_min = 0.0, y_max = 0.0;
  for (int i = 0; i < static_cast<int>(std::lround(seconds / kSampleS)); ++i) {
    plant.step(kSampleS, 0.0);
    const PlantState& s = plant.state();
    y_min = std::min(y_min, s.y_m);
    y_max = std::max(y_max, s.y_m);
    run.worst_pressure = std::max({run.worst_pressure,
                                   std::abs(s.p_p_pa * std::pow(volume_p(s.y_m), exponent) / pressure_p - 1.0),
                                   std::abs(s.p_n_pa * std::pow(volume_n(s.y_m), exponent) / pressure_n - 1.0)});
    run.worst_temperature = std::max(
        {run.worst_temperature, std::abs(s.t_p_k * std::pow(volume_p(s.y_m), exponent - 1.0) / temperature_p - 1.0),
         std::abs(s.t_n_k * std::pow(volume_n(s.y_m), exponent - 1.0) / temperature_n - 1.0)});
  }
  run.moved_m = y_max - y_min;
  return run;
}

TEST(ThermalPlant, WithoutHeatExchangeClosedChambersFollowTheAdiabaticLaw) {
  const SpringRun run = gas_spring(closed_thermal_bench(0.0, true), kGamma, 3.0);

  EXPECT_GT(run.moved_m, 0.05);  // the piston really moved
  // p V^gamma and T V^(gamma - 1), as the polytropic test's p V^k: RK4 at 1/3 ms on a ~10 rad/s
  // spring (measured 3.3e-13 and 5.9e-14). 1e-12 leaves room for rounding; gamma taken for k, or a
  // missing (gamma - 1) p dV/dt in dT/dt, gives > 1e-2.
  EXPECT_LT(run.worst_pressure, 1e-12) << "measured " << run.worst_pressure;
  EXPECT_LT(run.worst_temperature, 1e-12) << "measured " << run.worst_temperature;
}

TEST(ThermalPlant, WithAVeryLargeHeatTransferClosedChambersStayAtTheWallTemperature) {
  // h for a thermal time constant of 0.2 ms at mid-stroke: the gas follows the wall.
  PlantParams params = closed_thermal_bench(0.0, true);
  params.thermal.heat_transfer_w_per_m2_k = model::heat_transfer_for_time_constant(params, 2.0e-4);
  const SpringRun run = gas_spring(params, 1.0, 1.0);

  EXPECT_GT(run.moved_m, 0.05);
  // Isothermal, p V and T constant, but for the lag of the heat behind the compression:
  // T - T_w ~ -(gamma - 1) tau T dV/dt / V, with tau ~2e-4 s and |dV/dt / V| up to ~2 1/s:
  // ~1.6e-4 relative (measured 1.2e-4). Adiabatic, the chambers would go 5 % and more off pV.
  EXPECT_LT(run.worst_pressure, 3e-4);
  EXPECT_LT(run.worst_temperature, 3e-4);
}

TEST(ThermalPlant, AClosedChamberRelaxesToTheWallWithItsThermalTimeConstant) {
  const PlantParams params = closed_thermal_bench(25.9, false);
  Plant plant(params);
  // Chamber P warm after a fast fill, chamber N cool after a fast exhaust; the carriage held.
  const double y = 0.05, t_p0 = 330.0, t_n0 = 270.0, p_p0 = 5.0e5, p_n0 = 2.0e5;
  plant.reset({.t_s = 0.0, .y_m = y, .v_m_per_s = 0.0, .p_p_pa = p_p0, .p_n_pa = p_n0, .t_p_k = t_p0,
               .t_n_k = t_n0, .w_p_v = 0.0, .w_n_v = 0.0});
  // Closed, at constant volume: m c_v dT/dt = h A (T_w - T), an exponential with tau = m c_v / (h A),
  // and p = m r T / V follows T.
  const auto& g = params.geometry;
  const double c_v = kR / (kGamma - 1.0);
  const double mass_p = p_p0 * volume_p(y) / (kR * t_p0), mass_n = p_n0 * volume_n(y) / (kR * t_n0);
  const double tau_p = mass_p * c_v / (25.9 * model::wall_area_p_m2(g, y));
  const double tau_n = mass_n * c_v / (25.9 * model::wall_area_n_m2(g, y));
  ASSERT_GT(tau_p, 0.5);  // seconds: the figure benches are quoted by
  ASSERT_GT(tau_n, 0.2);
  for (int i = 1; i <= 3000; ++i) {
    plant.step(kSampleS, 0.0);
    if (i % 500 != 0) continue;
    const double t = i * kSampleS;
    const double temperature_p = kWallK + (t_p0 - kWallK) * std::exp(-t / tau_p);
    const double temperature_n = kWallK + (t_n0 - kWallK) * std::exp(-t / tau_n);
    const PlantState& s = plant.state();
    // RK4 at 0.2 ms on a time constant of tenths of seconds: 1e-12 relative is rounding.
    EXPECT_NEAR(s.t_p_k / temperature_p, 1.0, 1e-12) << t;
    EXPECT_NEAR(s.t_n_k / temperature_n, 1.0, 1e-12) << t;
    EXPECT_NEAR(s.p_p_pa / (mass_p * kR * temperature_p / volume_p(y)), 1.0, 1e-12) << t;
    EXPECT_NEAR(s.p_n_pa / (mass_n * kR * temperature_n / volume_n(y)), 1.0, 1e-12) << t;
    EXPECT_EQ(s.y_m, y);
  }
}

TEST(ThermalPlant, TheThirtyTwoMillimetreBenchIsQuotedAtOneAndThreeSeconds) {
  PlantParams params;
  params.has_thermal = true;
  params.thermal.heat_transfer_w_per_m2_k = 25.9;
  // The textbook values of docs/model.md: 25.9 W/(m^2 K) for 1 s, 8.6 for 3 s, to their 3 digits.
  EXPECT_NEAR(model::thermal_time_constant_s(params), 1.0, 0.01);
  params.thermal.heat_transfer_w_per_m2_k = 8.6;
  EXPECT_NEAR(model::thermal_time_constant_s(params), 3.0, 0.01);
  // (Those figures are rounded: 1 s takes 25.72 W/(m^2 K).)
  EXPECT_NEAR(model::heat_transfer_for_time_constant(params, 1.0), 25.9, 0.26);
}

TEST(ThermalPlant, AtRestAtTheWallTemperatureTheNullFlowPressuresHold) {
  PlantParams params;
  params.has_thermal = true;
  Plant plant(params);
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.1, u_e);
  const PlantState start = plant.state();
  for (int i = 0; i < 2000; ++i) plant.step(kSampleS, u_e);
  // A complete equilibrium stays one: the pressures move by rounding only (the chambers' flows
  // vanish at p_null to the root finder's 1e-7 Pa).
  EXPECT_NEAR(plant.state().p_p_pa, start.p_p_pa, 1e-3);
  EXPECT_NEAR(plant.state().p_n_pa, start.p_n_pa, 1e-3);
  EXPECT_NEAR(plant.state().t_p_k, kWallK, 1e-9);
  EXPECT_EQ(plant.state().y_m, 0.1);
}

TEST(ThermalPlant, WithWallsWarmerThanTheSupplyTheChambersRestBetweenTheTwoAndEquation7TakesThem) {
  PlantParams params;
  params.has_thermal = true;
  params.thermal.wall_temperature_auto = false;
  params.thermal.wall_temperature_k = 313.15;  // 20 K above the supply
  Plant plant(params);
  const model::ChamberProcess process(params);
  const double y = 0.1;
  const double u_0 = equilibrium_voltage_v(plant.valve(), process, y);
  plant.reset_at_rest(y, u_0);
  const PlantState start = plant.state();
  // The valve's through-flow brings supply air in at 293.15 K, the wall warms it: each chamber
  // settles in between, where the two balance.
  EXPECT_GT(start.t_p_k, 293.15 + 1.0);
  EXPECT_LT(start.t_p_k, 313.15 - 1.0);
  EXPECT_NEAR(plant.pressure_force_n(), 0.0, 1e-6) << "Eq. 7 at those temperatures";
  for (int i = 0; i < 2000; ++i) plant.step(kSampleS, u_0);
  std::printf("at rest: T_P %.3f K, T_N %.3f K; u_0 %.5f V (%.5f V with the supply's temperature)\n", start.t_p_k,
              start.t_n_k, u_0, equilibrium_voltage(plant));
  EXPECT_NEAR(plant.state().t_p_k, start.t_p_k, 1e-6) << "a complete equilibrium stays one";
  EXPECT_NEAR(plant.state().t_n_k, start.t_n_k, 1e-6);
  EXPECT_NEAR(plant.pressure_force_n(), 0.0, 1e-4);
  // The chambers taken at the supply's temperature would be 1 N and more off.
  Plant other(params);
  PlantState at_supply = start;
  at_supply.t_p_k = at_supply.t_n_k = 293.15;
  at_supply.p_p_pa = plant.valve().null_pressure_pa(u_0);
  at_supply.p_n_pa = plant.valve().null_pressure_pa(-u_0);
  other.reset(at_supply);
  for (int i = 0; i < 2000; ++i) other.step(kSampleS, u_0);
  EXPECT_GT(std::abs(other.pressure_force_n()), 1.0);
}

}  // namespace thermal

// What no sensor gives, estimated from what is measured: the model's ChamberObserver, fed the
// bench's position and pressures every millisecond and the commands, against the bench's own
// temperatures and spools, on the open-loop sequence (slide, stick, slide back, stop).
TEST(ChamberObserver, FollowsTheBenchsTemperaturesAndSpoolsFromTheMeasuredPressuresAndTheCommands) {
  PlantParams params;
  params.has_thermal = true;
  params.thermal.heat_transfer_w_per_m2_k = 25.72;  // 1 s at mid-stroke
  params.valve.spool_time_constant_s = 0.003;
  Plant plant(params);
  const model::ValveModel valve(params.valve, params.gas);
  model::ChamberObserver observer(model::ChamberProcess(params), valve, model::SpoolLag{0.003});
  const double u_e = equilibrium_voltage(plant);
  plant.reset_at_rest(0.0, u_e);
  observer.reset(0.0, 0.0, plant.state().p_p_pa, plant.state().p_n_pa, u_e, -u_e);
  double worst_moving_k = 0.0, worst_still_k = 0.0, worst_spool_v = 0.0, swing_k = 0.0;
  const std::vector<std::pair<double, double>> profile{{u_e, 0.5}, {u_e + 0.6, 1.0}, {u_e - 0.8, 1.0}, {u_e + 0.3, 1.0}};
  for (const auto& [u, duration] : profile) {
    observer.command(u, -u);
    for (int i = 0; i < static_cast<int>(std::lround(duration / kSampleS)); ++i) {
      plant.step(kSampleS, u);
      const PlantState& s = plant.state();
      observer.advance(s.t_s, s.y_m, s.p_p_pa, s.p_n_pa);
      const model::ChamberState& e = observer.state();
      const double error_k = std::max(std::abs(e.t_p_k - s.t_p_k), std::abs(e.t_n_k - s.t_n_k));
      double& worst_k = s.v_m_per_s == 0.0 ? worst_still_k : worst_moving_k;
      worst_k = std::max(worst_k, error_k);
      worst_spool_v = std::max({worst_spool_v, std::abs(e.w_p_v - s.w_p_v), std::abs(e.w_n_v - s.w_n_v)});
      swing_k = std::max({swing_k, std::abs(s.t_p_k - thermal::kWallK), std::abs(s.t_n_k - thermal::kWallK)});
    }
  }
  std::printf("temperatures swing up to %.2f K; the estimate's error: %.2g K while still, %.2g K while sliding; spools %.2g V\n",
              swing_k, worst_still_k, worst_moving_k, worst_spool_v);
  EXPECT_GT(swing_k, 5.0) << "the sequence moves the chambers' temperatures";
  // The spools are the commands through the same exact exponential.
  EXPECT_LT(worst_spool_v, 1e-9);
  // Between samples the estimate takes the position and pressures linearly, the bench does not: a
  // slide costs a fraction of a millikelvin (0.3 mK here; 7 mK after a saturated move across the
  // stroke), which the wall then forgets (0.1 mK here once stuck).
  EXPECT_LT(worst_moving_k, 3e-3);
  EXPECT_LT(worst_still_k, 3e-3);
}


TEST(SpoolLag, TheSpoolFollowsItsCommandWithAFirstOrderLag) {
  PlantParams lagged;
  lagged.valve.spool_time_constant_s = 0.003;
  lagged.friction.static_positive_n = 1e6;  // held: only the chambers move
  lagged.friction.static_negative_n = -1e6;
  PlantParams instant = lagged;
  instant.valve.spool_time_constant_s = 0.0;
  Plant a(lagged), b(instant);
  a.reset_at_rest(0.0, 0.0);
  b.reset_at_rest(0.0, 0.0);
  // A step to 2 V through the lag, against the valve without one driven, in steps of 10 us, by the
  // spool's exact position at each step's middle.
  const double tau = 0.003, u = 2.0;
  for (int k = 1; k <= 20; ++k) {
    a.step(kSampleS, u);
    for (int i = 0; i < 100; ++i) {
      const double t_mid = (k - 1) * kSampleS + (i + 0.5) * 1e-5;
      const double w = u * (1.0 - std::exp(-t_mid / tau));
      b.step(1e-5, w);
    }
    const double t = k * kSampleS;
    EXPECT_NEAR(a.state().w_p_v, u * (1.0 - std::exp(-t / tau)), 1e-12) << t;
    EXPECT_NEAR(a.state().w_n_v, -u * (1.0 - std::exp(-t / tau)), 1e-12) << t;
    // The midpoint rule on a curve of time constant 3 ms over 10 us: the pressures agree to
    // ~(10 us / 3 ms)^2 of a change of ~100 kPa, 1 Pa; without the lag they part by kPa.
    EXPECT_NEAR(a.state().p_p_pa, b.state().p_p_pa, 2.0) << t;
    EXPECT_NEAR(a.state().p_n_pa, b.state().p_n_pa, 2.0) << t;
  }
  Plant c(instant);
  c.reset_at_rest(0.0, 0.0);
  for (int k = 0; k < 5; ++k) c.step(kSampleS, u);
  EXPECT_GT(std::abs(c.state().p_p_pa - a.state().p_p_pa), 1e3);  // (the first 5 ms of the lag)
}

TEST(SpoolLag, TheSpoolStopsAtTheValvesTravel) {
  PlantParams params;
  params.valve.spool_time_constant_s = 0.003;
  Plant plant(params);
  plant.reset_at_rest(0.0, 0.0);
  for (int k = 0; k < 100; ++k) plant.step(kSampleS, 25.0);  // beyond u_max = 10 V
  EXPECT_NEAR(plant.state().w_p_v, 10.0, 1e-9);
  EXPECT_NEAR(plant.state().w_n_v, -10.0, 1e-9);
  plant.step(kSampleS, 0.0);  // comes back from the stop, not from 25 V
  EXPECT_NEAR(plant.state().w_p_v, 10.0 * std::exp(-1.0 / 3.0), 1e-9);
}

}  // namespace
}  // namespace pneu::plant
