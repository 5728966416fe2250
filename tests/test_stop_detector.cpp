// Specification of the stop detector: moving -> stopped once the position stays within the rest
// band of a first still sample for hold_s, stopped -> moving once it leaves the stop position by
// more than the motion band; event times backdated to the signal. Synthetic 1 ms position traces
// whose stop and departure instants are known by construction.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/stop_detector.hpp"

namespace pneu::controller {
namespace {

using Event = StopDetectorEvent;

constexpr double kPeriodS = 1.0e-3;  // the bench's sample period (docs/model.md section 7)

double time_of(int k) { return k * kPeriodS; }

struct Emitted {
  int k;  // sample index at which update() returned the event
  Event kind;
  double event_t_s;  // event_time_s() right after
  double event_y_m;  // event_position_m() right after
};

// Resets the detector at rest at y(0), feeds samples k = 1 .. n-1 and records every event.
std::vector<Emitted> run(StopDetector& detector, const std::function<double(int)>& y_of_k, int n) {
  detector.reset_at_rest(time_of(0), y_of_k(0));
  std::vector<Emitted> events;
  for (int k = 1; k < n; ++k) {
    const Event e = detector.update(time_of(k), y_of_k(k));
    if (e != Event::kNone)
      events.push_back({k, e, detector.event_time_s(), detector.event_position_m()});
  }
  return events;
}

int count(const std::vector<Emitted>& events, Event kind) {
  int n = 0;
  for (const Emitted& e : events) n += e.kind == kind ? 1 : 0;
  return n;
}

StopDetectorParams params(double rest_band_m, double motion_band_m, double hold_s) {
  StopDetectorParams p;
  p.rest_band_m = rest_band_m;
  p.motion_band_m = motion_band_m;
  p.hold_s = hold_s;
  return p;
}

// Rest at 0.22 m until sample 100, then a 0.05 m/s move (50 um per sample) that ends at sample
// kStillK: from there on the position is held bit for bit.
constexpr int kDepartK = 100;
constexpr int kStillK = 400;
constexpr double kStartM = 0.22;
constexpr double kSpeedMPerS = -0.05;
double move_then_hold(int k) {
  const int moving = std::clamp(k, kDepartK, kStillK) - kDepartK;
  return kStartM + kSpeedMPerS * moving * kPeriodS;
}

// --- Stops ---------------------------------------------------------------------------------------

TEST(StopDetector, ResetAtRestGivesNoEvent) {
  StopDetector detector(params(0.0, 1e-6, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(
      detector, [](int) { return 0.1717; }, 2000);
  EXPECT_TRUE(events.empty());
  EXPECT_TRUE(detector.stopped());
  EXPECT_EQ(detector.rest_position_m(), 0.1717);
}

TEST(StopDetector, MoveThenHoldGivesOneStopBackdatedToTheFirstStillSample) {
  constexpr double kHoldS = 0.005;
  StopDetector detector(params(0.0, 1e-6, kHoldS), kPeriodS);
  const std::vector<Emitted> events = run(detector, move_then_hold, 3000);

  ASSERT_EQ(count(events, Event::kStop), 1);
  ASSERT_EQ(events.size(), 2u);  // the departure from the reset rest, then the stop
  EXPECT_EQ(events[0].kind, Event::kStart);
  const Emitted& stop = events[1];
  EXPECT_EQ(stop.kind, Event::kStop);
  // Emitted hold_s (5 samples) after the first still sample, sample kStillK; the times are
  // sample times themselves, so exact equality is the contract.
  EXPECT_EQ(stop.k, kStillK + 5);
  EXPECT_EQ(stop.event_t_s, time_of(kStillK));
  EXPECT_EQ(stop.event_y_m, move_then_hold(kStillK));
  EXPECT_TRUE(detector.stopped());
  EXPECT_EQ(detector.rest_position_m(), move_then_hold(kStillK));
}

TEST(StopDetector, LongerHoldDelaysTheConfirmationButNotTheStopTime) {
  constexpr double kHoldS = 0.020;
  StopDetector detector(params(0.0, 1e-6, kHoldS), kPeriodS);
  const std::vector<Emitted> events = run(detector, move_then_hold, 3000);
  ASSERT_EQ(count(events, Event::kStop), 1);
  EXPECT_EQ(events.back().k, kStillK + 20);
  EXPECT_EQ(events.back().event_t_s, time_of(kStillK));
}

TEST(StopDetector, PauseShorterThanTheHoldIsNotAStop) {
  // Moving, still for 4 samples (< hold 5 ms), moving again: no stop until the final hold.
  const auto y = [](int k) {
    if (k < 100) return 0.1 + 1e-4 * k;
    if (k < 104) return 0.1 + 1e-4 * 100;  // samples 100..103 equal: 3 ms after the first
    if (k < 200) return 0.1 + 1e-4 * (k - 3);
    return 0.1 + 1e-4 * 197;  // from sample 200 on
  };
  StopDetector detector(params(0.0, 1e-6, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(detector, y, 1000);
  ASSERT_EQ(count(events, Event::kStop), 1);
  EXPECT_EQ(events.back().event_t_s, time_of(200));  // first sample of the final hold
}

TEST(StopDetector, NoStopWhileMovingSlowly) {
  // 0.1 mm/s: 1e-7 m between samples, far above the position's resolution (~3e-17 m), so with a
  // zero rest band no two samples are equal and the carriage is never "still".
  StopDetector detector(params(0.0, 1e-6, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(
      detector, [](int k) { return 0.17 + 1.0e-4 * time_of(k); }, 10'000);
  EXPECT_EQ(count(events, Event::kStop), 0);
  EXPECT_EQ(count(events, Event::kStart), 1);  // leaving the reset rest
  EXPECT_FALSE(detector.stopped());
}

TEST(StopDetector, DitherWithinTheRestBandStillStops) {
  // Noise-like dither of up to 0.9 rest band about the first still sample (fixed seed), for 2 s.
  constexpr double kRestBandM = 5e-6;
  constexpr double kMotionBandM = 2e-5;
  std::mt19937 rng(20050101);
  std::uniform_real_distribution<double> dither(-0.9 * kRestBandM, 0.9 * kRestBandM);
  std::vector<double> y(2400);
  for (int k = 0; k < 2400; ++k) y[k] = move_then_hold(k) + (k > kStillK ? dither(rng) : 0.0);

  StopDetector detector(params(kRestBandM, kMotionBandM, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(
      detector, [&](int k) { return y[k]; }, 2400);

  ASSERT_EQ(count(events, Event::kStop), 1);
  // Only the departure at sample 101: the dither stays within the motion band.
  EXPECT_EQ(count(events, Event::kStart), 1);
  EXPECT_EQ(events.back().kind, Event::kStop);
  EXPECT_EQ(events.back().k, kStillK + 5);
  EXPECT_EQ(events.back().event_t_s, time_of(kStillK));
  // The rest position is the mean of the still samples kStillK .. kStillK + 5: the dither
  // averages out of it instead of one dithered sample standing for it.
  double mean = 0.0;
  for (int k = kStillK; k <= kStillK + 5; ++k) mean += y[static_cast<std::size_t>(k)] - move_then_hold(kStillK);
  mean = move_then_hold(kStillK) + mean / 6.0;
  EXPECT_NEAR(events.back().event_y_m, mean, 1e-15);
  EXPECT_TRUE(detector.stopped());
}

// --- Starts --------------------------------------------------------------------------------------

TEST(StopDetector, DepartureGivesAStartMidwayAfterTheLastStillSample) {
  // At rest at 0.17 m until sample 300, then away at 0.02 m/s (20 um per sample > motion band).
  constexpr int kLastStillK = 300;
  const auto y = [](int k) { return 0.17 + (k > kLastStillK ? 2e-5 * (k - kLastStillK) : 0.0); };
  StopDetector detector(params(0.0, 1e-6, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(detector, y, 600);

  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Event::kStart);
  EXPECT_EQ(events[0].k, kLastStillK + 1);
  // t_300 + T/2: two roundings of numbers ~0.3 s.
  EXPECT_NEAR(events[0].event_t_s, time_of(kLastStillK) + 0.5 * kPeriodS, 1e-15);
  EXPECT_EQ(events[0].event_y_m, 0.17);  // the position it left
  EXPECT_FALSE(detector.stopped());
}

TEST(StopDetector, NoStartWhileMovementStaysWithinTheMotionBand) {
  // Still until 300, then a creep that wanders within +-0.9 motion band (but outside the zero rest
  // band) until 800, then a real departure. The start comes only then, and is still backdated to
  // the last sample at rest, 300.
  constexpr double kMotionBandM = 1e-5;
  constexpr int kLastStillK = 300;
  constexpr int kDepartK2 = 800;
  const auto y = [](int k) {
    if (k <= kLastStillK) return 0.17;
    if (k < kDepartK2) return 0.17 + 0.9 * kMotionBandM * std::sin(0.05 * (k - kLastStillK) + 0.3);
    return 0.17 + 1e-4 * (k - kDepartK2 + 1);
  };
  StopDetector detector(params(0.0, kMotionBandM, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(detector, y, 1000);

  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].kind, Event::kStart);
  EXPECT_EQ(events[0].k, kDepartK2);
  EXPECT_NEAR(events[0].event_t_s, time_of(kLastStillK) + 0.5 * kPeriodS, 1e-15);
  EXPECT_EQ(events[0].event_y_m, 0.17);
}

TEST(StopDetector, StopThenRestartThenStopAgain) {
  // The paper's sequence in miniature: move, stick, restart, move, stick.
  const auto y = [](int k) {
    if (k < 50) return 0.22 - 1e-4 * k;
    if (k < 1000) return 0.22 - 1e-4 * 50;                // stuck from sample 50
    if (k < 1100) return 0.22 - 1e-4 * (50 + (k - 999));  // restart after sample 999
    return 0.22 - 1e-4 * (50 + 101);                      // stuck again from sample 1100
  };
  StopDetector detector(params(0.0, 1e-6, 0.005), kPeriodS);
  const std::vector<Emitted> events = run(detector, y, 2000);

  ASSERT_EQ(events.size(), 4u);
  EXPECT_EQ(events[1].kind, Event::kStop);
  EXPECT_EQ(events[1].event_t_s, time_of(50));
  EXPECT_EQ(events[2].kind, Event::kStart);
  EXPECT_NEAR(events[2].event_t_s, time_of(999) + 0.5 * kPeriodS, 1e-15);
  EXPECT_EQ(events[2].event_y_m, y(50));
  EXPECT_EQ(events[3].kind, Event::kStop);
  EXPECT_EQ(events[3].event_t_s, time_of(1100));
  EXPECT_EQ(events[3].event_y_m, y(1100));
}



// A breakaway under a force ramping through stiction: d(t) = c (t - t0)^3 from t0 on, seen through
// 16-bit quantisation steps of 7.6 um plus dither, as pneu-plant serve's sensors give it.
double cubic_departure(int k, double t0_s, double dither_m) {
  const double t = time_of(k);
  // m/s^3: 20 um after 19 ms; slower starts (under rest band / hold = 4 mm/s) look like rest.
  const double c = 3.0;
  const double d = t > t0_s ? c * (t - t0_s) * (t - t0_s) * (t - t0_s) : 0.0;
  const double lsb = 7.6e-6;
  const double noisy = 0.1 + d + ((k * 7919) % 13 - 6) / 6.0 * dither_m;
  return std::round(noisy / lsb) * lsb;
}


TEST(StopDetector, WithNoisySensorsAStartIsDatedByTheCubicLawOfABreakawayNotByTheBand) {
  // Rest band 20 um, motion band 40 um: the carriage is seen leaving only ~24 ms after it did.
  constexpr double kT0 = 0.5003;
  StopDetector detector(params(2e-5, 4e-5, 0.005), kPeriodS);
  const auto events = run(detector, [&](int k) { return cubic_departure(k, kT0, 2.5e-6); }, 800);
  ASSERT_EQ(count(events, Event::kStart), 1);
  const Emitted& start = events.back();
  EXPECT_GT(time_of(start.k) - kT0, 0.020) << "the band alone would date it this late";
  // The fit over the samples that left the rest band recovers t0 to within a few ticks despite
  // the quantisation and dither.
  EXPECT_NEAR(start.event_t_s, kT0, 0.003);
}

}  // namespace
}  // namespace pneu::controller
