// The supervisor's checks on synthetic ticks: each fault cause is raised by its condition, within
// its configured detection time, and not by the normal life of the bench around it.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "pneu/config/config.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/controller/watchdog.hpp"

namespace {

using pneu::controller::FaultCause;
using pneu::controller::Supervisor;
namespace c = pneu::controller;
namespace hal = pneu::hal;

constexpr double kPeriod = 1e-3;

class SupervisorChecks : public ::testing::Test {
 protected:
  SupervisorChecks()
      : config_(pneu::config::load_string(pneu::config::default_config_yaml(), {"controller.law.gains=fixed"})) {
    // Every check on, as on a bench with real (noisy) sensors.
    config_.controller.supervisor.frozen_after_s = 0.2;
    config_.commands.setpoint_stream_timeout_s = 0.0;
  }

  Supervisor make() {
    Supervisor s(pneu::controller::LoopParams::from(config_));
    s.reset(0.0);
    return s;
  }
  // A good sample at time t: a slowly moving carriage, flickering pressures.
  hal::SensorFrame good(double t) const {
    hal::SensorFrame f;
    f.t_s = t;
    f.y_m = 0.1 + 0.01 * t;
    f.p_p_pa = 4.0e5 + (static_cast<long>(std::llround(t / kPeriod)) % 2 ? 15.0 : 0.0);
    f.p_n_pa = 3.5e5 + (static_cast<long>(std::llround(t / kPeriod)) % 2 ? 0.0 : 15.0);
    return f;
  }
  FaultCause tick(Supervisor& s, double t, const hal::SensorFrame& f, hal::Status status = hal::Status::kOk,
                  bool armed = true, double y_d = std::numeric_limits<double>::quiet_NaN(), double last_sp = 0.0) {
    c::SupervisedTick st;
    st.t_s = t;
    st.status = status;
    st.frame = &f;
    st.armed = armed;
    st.y_d_m = std::isnan(y_d) ? f.y_m : y_d;
    st.last_setpoint_t_s = last_sp;
    return s.check(st);
  }
  // Runs good ticks over [t0, t1) and returns the first fault.
  FaultCause run_good(Supervisor& s, double t0, double t1) {
    for (double t = t0; t < t1 - 1e-12; t += kPeriod)
      if (const FaultCause f = tick(s, t, good(t)); f != c::FaultCause::kNone) return f;
    return c::FaultCause::kNone;
  }

  pneu::config::Config config_;
};

TEST_F(SupervisorChecks, GoodSamplesOfAMovingCarriageRaiseNothing) {
  Supervisor s = make();
  EXPECT_EQ(run_good(s, 0.0, 5.0), c::FaultCause::kNone);
  EXPECT_TRUE(s.sample_good());
  EXPECT_FALSE(s.cause_present());
}

TEST_F(SupervisorChecks, ANonFiniteReadingIsAFaultAtOnceAndTheSampleIsNotGood) {
  for (int channel = 0; channel < 3; ++channel) {
    Supervisor s = make();
    ASSERT_EQ(run_good(s, 0.0, 0.1), c::FaultCause::kNone);
    hal::SensorFrame f = good(0.1);
    (channel == 0 ? f.y_m : channel == 1 ? f.p_p_pa : f.p_n_pa) = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(tick(s, 0.1, f), c::FaultCause::kSensorNonFinite) << "channel " << channel;
    EXPECT_FALSE(s.sample_good());
    EXPECT_TRUE(s.cause_present()) << "a reset cannot clear it while the reading stays bad";
  }
}

TEST_F(SupervisorChecks, APressureAtTheSensorsRailOrBelowThePlausibleRangeIsOutOfRange) {
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  f.p_p_pa = 1.0e6;  // the 10 bar transmitter's rail
  EXPECT_EQ(tick(s, 0.0, f), c::FaultCause::kSensorRange);
  Supervisor s2 = make();
  f = good(0.0);
  f.p_n_pa = 0.0;  // the 0 V rail: no chamber holds a vacuum
  EXPECT_EQ(tick(s2, 0.0, f), c::FaultCause::kSensorRange);
}

TEST_F(SupervisorChecks, AReadingTheConverterFlagsInvalidIsOutOfRange) {
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  f.validity = hal::kPressurePInvalid;
  EXPECT_EQ(tick(s, 0.0, f), c::FaultCause::kSensorRange);
}

TEST_F(SupervisorChecks, AnEndStopIsNotOutOfRange) {
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  f.y_m = config_.plant.geometry.half_stroke_m();
  EXPECT_EQ(tick(s, 0.0, f, hal::Status::kOk, /*armed=*/false), c::FaultCause::kNone);
}

TEST_F(SupervisorChecks, APositionJumpFasterThanTheCarriageCanMoveIsASensorFault) {
  Supervisor s = make();
  ASSERT_EQ(run_good(s, 0.0, 0.1), c::FaultCause::kNone);
  hal::SensorFrame f = good(0.1);
  f.y_m = config_.plant.geometry.half_stroke_m();  // the wiper jumped to the rail
  EXPECT_EQ(tick(s, 0.1, f, hal::Status::kOk, /*armed=*/false), c::FaultCause::kSensorJump);
}

TEST_F(SupervisorChecks, AMoveAtThePlausibleSpeedIsNoJump) {
  Supervisor s = make();
  const double v = 0.9 * config_.controller.supervisor.max_speed_m_per_s;
  for (int k = 0; k < 100; ++k) {
    hal::SensorFrame f = good(k * kPeriod);
    f.y_m = -0.2 + v * k * kPeriod;
    ASSERT_EQ(tick(s, k * kPeriod, f, hal::Status::kOk, false), c::FaultCause::kNone) << k;
  }
}

// A device's sample is dated by its reply, but the device read the sensors earlier, at some
// instant between the request and the reply (SensorFrame::read_span_s). On a loaded machine the
// I/O thread may take a reply tens of milliseconds after it arrived, then exchange the next at
// once: two samples dated a fraction of a period apart were read that far apart. The carriage may
// have moved for the longest time between two readings, from the earliest read of the one to the
// latest of the other; a jump is judged over that time.
class LateDatedSamples : public SupervisorChecks {
 protected:
  static constexpr double kExchange = 0.2e-3;  // request to reply on a healthy link [s]
  static constexpr double kLateRead = 0.02;    // when the sample taken late was read [s]
  static constexpr double kStart = -0.168;     // where the carriage was at 0 [m]

  // The whole process stalls, the loop with the I/O thread, and is not faulted for it: loop
  // timing supervision off, as the HIL tests run pneud on a shared machine
  // (loop_timing_faults_off). Its next tick finds the late sample.
  LateDatedSamples() {
    config_.controller.supervisor.max_tick_interval_s = 0.0;
    config_.controller.supervisor.overruns_in_a_row = 0;
  }

  // Samples of a carriage moving at `speed`, read every period, each dated by its reply 0.1 ms
  // after the read, until the one read at kLateRead, whose reply the I/O thread takes `stall`
  // late; the next request goes out at once, and that sample's reply is taken on time. `next_y`:
  // what the sensor reads on that next sample (NaN: the carriage's true position). The first
  // fault raised, on any sample.
  FaultCause run(double speed, double stall, double next_y = std::numeric_limits<double>::quiet_NaN()) {
    Supervisor s = make();
    // Read at `read_t`, dated `dated_t`; its request went out half an exchange before the read.
    const auto sample = [&](double read_t, double dated_t) {
      hal::SensorFrame f = good(dated_t);
      f.y_m = kStart + speed * read_t;
      f.t_s = dated_t;
      f.read_span_s = dated_t - (read_t - 0.5 * kExchange);
      return f;
    };
    const auto on_time = [&](double read_t) { return sample(read_t, read_t + 0.5 * kExchange); };
    for (int k = 0; k < 20; ++k) {
      const double read_t = k * kPeriod;
      const hal::SensorFrame f = on_time(read_t);
      if (const FaultCause cause = tick(s, f.t_s, f, hal::Status::kOk, false); cause != FaultCause::kNone) return cause;
    }
    const hal::SensorFrame late = sample(kLateRead, kLateRead + stall);
    if (const FaultCause cause = tick(s, late.t_s, late, hal::Status::kOk, false); cause != FaultCause::kNone)
      return cause;
    hal::SensorFrame next = on_time(kLateRead + stall + kExchange);
    if (!std::isnan(next_y)) next.y_m = next_y;
    return tick(s, late.t_s + kPeriod, next, hal::Status::kOk, false);  // the loop's next tick
  }
  // How long the carriage may have moved between the late sample's reading and the next one's:
  // from the late request to the next reply.
  static double longest_between_s(double stall) { return stall + 1.5 * kExchange; }
  double max_speed() const { return config_.controller.supervisor.max_speed_m_per_s; }
};

TEST_F(LateDatedSamples, ASampleTakenLateThenTheNextOnTimeIsNoJumpAtThePlausibleSpeed) {
  // 57 ms of stall, as in the loaded test run that skipped 57 deadlines: between the two readings,
  // dated 0.1 ms apart, the carriage covered 0.9 x max_speed x 57 ms (0.26 m at 5 m/s).
  EXPECT_EQ(run(0.9 * max_speed(), 0.057), FaultCause::kNone);
  EXPECT_EQ(run(0.9 * max_speed(), 0.005), FaultCause::kNone);
  EXPECT_EQ(run(1.0, 0.005), FaultCause::kNone) << "a carriage at 1 m/s, a 5 ms stall";
}

TEST_F(LateDatedSamples, AJumpOfTheSensorIsStillCaughtAfterALateSample) {
  const double y_late = kStart + 1.0 * kLateRead;
  // To the rail: further than the carriage could have gone at max_speed in the whole span.
  EXPECT_EQ(run(1.0, 0.005, config_.plant.geometry.half_stroke_m()), FaultCause::kSensorJump);
  // Beyond what max_speed allows over the longest time the carriage had, by 20 %: caught; within
  // it by 20 %: a move it could have made.
  EXPECT_EQ(run(1.0, 0.005, y_late + 1.2 * max_speed() * longest_between_s(0.005)), FaultCause::kSensorJump);
  EXPECT_EQ(run(1.0, 0.005, y_late + 0.8 * max_speed() * longest_between_s(0.005)), FaultCause::kNone);
  // On time, as before: a jump of more than max_speed over a period is caught.
  EXPECT_EQ(run(1.0, 0.0, y_late + 1.2 * max_speed() * kPeriod), FaultCause::kSensorJump);
}

TEST_F(SupervisorChecks, APressureFrozenBitForBitIsAFaultAfterFrozenAfterS) {
  Supervisor s = make();
  ASSERT_EQ(run_good(s, 0.0, 0.5), c::FaultCause::kNone);
  const double frozen = config_.controller.supervisor.frozen_after_s;
  double raised_at = -1.0;
  for (double t = 0.5; t < 1.5; t += kPeriod) {
    hal::SensorFrame f = good(t);
    f.p_n_pa = 3.5e5;  // frozen
    if (tick(s, t, f) == c::FaultCause::kSensorFrozen) {
      raised_at = t;
      break;
    }
  }
  ASSERT_GT(raised_at, 0.0) << "never raised";
  EXPECT_NEAR(raised_at - 0.5, frozen, 2 * kPeriod);
  EXPECT_TRUE(s.cause_present()) << "still frozen: a reset must not clear it";
  EXPECT_EQ(s.present_cause(), c::FaultCause::kSensorFrozen);
  hal::SensorFrame thawed = good(raised_at + kPeriod);
  thawed.p_n_pa = 3.5e5 + 30.0;
  EXPECT_EQ(tick(s, raised_at + kPeriod, thawed), c::FaultCause::kNone) << "flickering again";
  EXPECT_FALSE(s.cause_present());
}

// A module sampling at the loop's rate but not in phase with it: now and then a tick finds no new
// sample and sees the last one again. The fault still latches on the first tick past the limit,
// repeated sample or not.
TEST_F(SupervisorChecks, AFrozenPressureLatchesOnTheFirstTickPastTheLimitEvenOnARepeatedSample) {
  // Between two ticks (no rounding question), and 202 ticks: not a multiple of the repetition.
  config_.controller.supervisor.frozen_after_s = 0.2015;
  const double frozen = config_.controller.supervisor.frozen_after_s;
  for (const int offset : {0, 1, 2}) {
    Supervisor s = make();
    double last_change = -1.0, last_p_n = NAN;
    hal::SensorFrame f = good(0.0);
    for (int k = 0; k < 1500; ++k) {
      const double t = k * kPeriod;
      if (k == 0 || k % 3 != offset) {  // a new sample; every third tick after the first repeats the last
        f = good(t);
        if (t >= 0.5) f.p_n_pa = 3.5e5;  // frozen from 0.5 s on
        if (f.p_n_pa != last_p_n) last_change = t, last_p_n = f.p_n_pa;
        f.fresh = true;
      } else {
        f.fresh = false;
      }
      const FaultCause cause = tick(s, t, f);
      if (t - last_change < frozen) {
        ASSERT_EQ(cause, c::FaultCause::kNone) << "offset " << offset << ", t = " << t;
      } else {
        EXPECT_EQ(cause, c::FaultCause::kSensorFrozen) << "offset " << offset << ": the first tick past the limit, t = " << t
                                                << (f.fresh ? " (a new sample)" : " (a repeated sample)");
        break;
      }
    }
  }
}

TEST_F(SupervisorChecks, FrozenDetectionIsOffAtZero) {
  config_.controller.supervisor.frozen_after_s = 0.0;
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  for (double t = 0.0; t < 2.0; t += kPeriod) {
    f.t_s = t;
    ASSERT_EQ(tick(s, t, f), c::FaultCause::kNone);
  }
}

TEST_F(SupervisorChecks, StaleSamplesBecomeACommsFaultOnlyAfterCommsFaultAfterS) {
  Supervisor s = make();
  ASSERT_EQ(run_good(s, 0.0, 0.1), c::FaultCause::kNone);
  const double limit = config_.controller.comms_fault_after_s;
  double raised_at = -1.0;
  for (double t = 0.1; t < 1.0; t += kPeriod) {
    hal::SensorFrame f = good(t);
    f.validity = hal::kSampleStale;
    const FaultCause cause = tick(s, t, f, hal::Status::kStale);
    EXPECT_FALSE(s.sample_good());
    if (cause != c::FaultCause::kNone) {
      EXPECT_EQ(cause, c::FaultCause::kComms);
      raised_at = t;
      break;
    }
  }
  ASSERT_GT(raised_at, 0.0);
  EXPECT_NEAR(raised_at - 0.1, limit, 1.5 * kPeriod);
}

TEST_F(SupervisorChecks, AShortRunOfStaleSamplesIsForgivenByTheNextGoodOne) {
  Supervisor s = make();
  for (int round = 0; round < 10; ++round) {
    const double t0 = round * 0.1;
    ASSERT_EQ(run_good(s, t0, t0 + 0.07), c::FaultCause::kNone);
    for (double t = t0 + 0.07; t < t0 + 0.1 - 1e-9; t += kPeriod) {
      hal::SensorFrame f = good(t);
      f.validity = hal::kSampleStale;
      ASSERT_EQ(tick(s, t, f, hal::Status::kStale), c::FaultCause::kNone) << "30 ms of stale samples < 50 ms";
    }
  }
}

TEST_F(SupervisorChecks, ThePositionBeyondTheSoftLimitsByMoreThanTheOvertravelIsAFaultWhenArmed) {
  const double limit = config_.controller.soft_limit_max_m + config_.controller.supervisor.overtravel_m;
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  f.y_m = limit - 1e-4;
  EXPECT_EQ(tick(s, 0.0, f), c::FaultCause::kNone) << "an overshoot within the overtravel";
  f.y_m = limit + 1e-4;
  f.t_s = 0.1;
  EXPECT_EQ(tick(s, 0.1, f), c::FaultCause::kSoftLimit);
  Supervisor d = make();
  EXPECT_EQ(tick(d, 0.0, f, hal::Status::kOk, /*armed=*/false), c::FaultCause::kNone) << "disarmed: not driven there";
}

TEST_F(SupervisorChecks, AFollowingErrorLastingLongerThanItsLimitIsAFault) {
  Supervisor s = make();
  const auto& v = config_.controller.supervisor;
  double raised_at = -1.0;
  for (double t = 0.0; t < 2 * v.following_error_s; t += kPeriod) {
    const hal::SensorFrame f = good(t);
    if (tick(s, t, f, hal::Status::kOk, true, f.y_m + 2 * v.following_error_m) != c::FaultCause::kNone) {
      raised_at = t;
      break;
    }
  }
  EXPECT_NEAR(raised_at, v.following_error_s, 2 * kPeriod);
}

TEST_F(SupervisorChecks, AMoveThatReachesTheWindowInTimeIsNoFollowingError) {
  Supervisor s = make();
  const auto& v = config_.controller.supervisor;
  // Five moves, each outside the window for 80 % of the time limit, then within it.
  const double move_s = 1.25 * v.following_error_s;
  for (double t = 0.0; t < 5 * move_s; t += kPeriod) {
    const hal::SensorFrame f = good(t);
    const bool moving = std::fmod(t, move_s) < 0.8 * v.following_error_s;
    ASSERT_EQ(tick(s, t, f, hal::Status::kOk, true, moving ? f.y_m + 0.1 : f.y_m), c::FaultCause::kNone) << t;
  }
}

TEST_F(SupervisorChecks, OverrunsInARowAndOneLongTickIntervalAreFaults) {
  const auto& v = config_.controller.supervisor;
  Supervisor s = make();
  for (std::uint32_t k = 0; k + 1 < v.overruns_in_a_row; ++k) s.note_overrun(true);
  s.note_overrun(false);  // the run is broken: counting starts again
  for (std::uint32_t k = 0; k + 1 < v.overruns_in_a_row; ++k) s.note_overrun(true);
  EXPECT_EQ(tick(s, 0.0, good(0.0)), c::FaultCause::kNone);
  s.note_overrun(true);
  EXPECT_EQ(tick(s, kPeriod, good(kPeriod)), c::FaultCause::kOverrun);
  EXPECT_STREQ(s.decided_by(), "controller.supervisor.overruns_in_a_row");

  Supervisor t = make();
  EXPECT_EQ(tick(t, 0.0, good(0.0)), c::FaultCause::kNone);
  EXPECT_EQ(tick(t, 0.5 * v.max_tick_interval_s, good(0.5 * v.max_tick_interval_s)), c::FaultCause::kNone);
  const double late = 0.5 * v.max_tick_interval_s + 1.1 * v.max_tick_interval_s;
  EXPECT_EQ(tick(t, late, good(late)), c::FaultCause::kOverrun);
  EXPECT_STREQ(t.decided_by(), "controller.supervisor.max_tick_interval_s");
}

// A fault names the key that decided it, and what raising that key would cost: the operator of a
// PC without a real-time kernel learns which timing key to relax for a supervised run.
TEST_F(SupervisorChecks, EachFaultNamesTheConfigKeyThatDecidedItAndWhatRelaxingItCosts) {
  Supervisor s = make();
  EXPECT_EQ(tick(s, 0.0, good(0.0)), c::FaultCause::kNone);
  EXPECT_EQ(s.decided_by(), nullptr) << "no fault, no key";
  hal::SensorFrame high = good(kPeriod);
  high.p_p_pa = config_.controller.supervisor.pressure_max_pa + 1.0;
  EXPECT_EQ(tick(s, kPeriod, high), c::FaultCause::kSensorRange);
  EXPECT_STREQ(s.decided_by(), "controller.supervisor.pressure_min_pa/pressure_max_pa")
      << "a sample's fault keeps its key although the motion checks ran after it";
  Supervisor u = make();
  hal::SensorFrame nan = good(0.0);
  nan.y_m = std::nan("");
  EXPECT_EQ(tick(u, 0.0, nan), c::FaultCause::kSensorNonFinite);
  EXPECT_EQ(u.decided_by(), nullptr) << "no key relaxes a reading that is not a number";

  const std::string interval = c::relaxing_costs("controller.supervisor.max_tick_interval_s");
  const std::string in_a_row = c::relaxing_costs("controller.supervisor.overruns_in_a_row");
  EXPECT_NE(interval, in_a_row);
  EXPECT_NE(interval.find("keep their last command"), std::string::npos) << interval;
  EXPECT_NE(in_a_row.find("real-time kernel"), std::string::npos) << in_a_row;
  EXPECT_NE(std::string(c::relaxing_costs(nullptr)).find("no key"), std::string::npos);
}

TEST_F(SupervisorChecks, ASilentSetPointStreamIsAFaultWhenOneIsConfigured) {
  config_.commands.setpoint_stream_timeout_s = 0.25;
  config_.controller.supervisor.max_tick_interval_s = 0.0;  // ticks are sampled sparsely here
  Supervisor s = make();
  EXPECT_EQ(tick(s, 0.2, good(0.2), hal::Status::kOk, true, std::nan(""), 0.0), c::FaultCause::kNone);
  EXPECT_EQ(tick(s, 0.3, good(0.3), hal::Status::kOk, true, std::nan(""), 0.1), c::FaultCause::kNone) << "a set point at 0.1 s";
  EXPECT_EQ(tick(s, 0.36, good(0.36), hal::Status::kOk, true, std::nan(""), 0.1), c::FaultCause::kCommandTimeout);
  Supervisor d = make();
  EXPECT_EQ(tick(d, 5.0, good(5.0), hal::Status::kOk, /*armed=*/false, std::nan(""), 0.0), c::FaultCause::kNone)
      << "disarmed, no stream is expected";
}

// The settling rules (oscillation, settle time), each on its own: the other motion checks off.
class SettlingChecks : public SupervisorChecks {
 protected:
  SettlingChecks() {
    auto& v = config_.controller.supervisor;
    v.following_error_s = 0.0;
    v.max_speed_m_per_s = 0.0;
  }
  // One armed tick (unless told otherwise) with the carriage at y, the set point y_d, and the
  // stop detector's state.
  FaultCause at(Supervisor& s, double t, double y, double y_d, bool at_rest, bool armed = true) {
    hal::SensorFrame f = good(t);
    f.y_m = y;
    c::SupervisedTick st;
    st.t_s = t;
    st.frame = &f;
    st.armed = armed;
    st.y_d_m = y_d;
    st.at_rest = at_rest;
    return s.check(st);
  }
  const pneu::config::SupervisorConfig& v() const { return config_.controller.supervisor; }
};

constexpr double kTwoPi = 6.283185307179586;

TEST_F(SettlingChecks, AnErrorSwingingBeyondTheBandIsAnOscillationAtTheNthSignChange) {
  config_.controller.supervisor.settle_time_s = 0.0;
  Supervisor s = make();
  // The paper's gains at mid-stroke: +-30 mm about the set point, a half-swing every 0.2 s.
  const double amplitude_m = 3 * v().oscillation_amplitude_m, frequency_hz = 2.5, y_d = 0.05;
  // The error y_d - y = amplitude sin(2 pi f t) leaves the band on one side, then on the other:
  // its k-th sign change is where it passes -band (k odd) or +band (k even) after the k-th zero.
  const double past_band_s = std::asin(v().oscillation_amplitude_m / amplitude_m) / (kTwoPi * frequency_hz);
  const double nth_change_s = v().oscillation_sign_changes * 0.5 / frequency_hz + past_band_s;
  double raised_at = -1.0;
  for (double t = 0.0; t < 3.0 && raised_at < 0.0; t += kPeriod)
    if (at(s, t, y_d - amplitude_m * std::sin(kTwoPi * frequency_hz * t), y_d, false) == FaultCause::kOscillation)
      raised_at = t;
  EXPECT_NEAR(raised_at, nth_change_s, 1.5 * kPeriod);
  EXPECT_FALSE(s.cause_present()) << "an event: a reset clears it";
}

TEST_F(SettlingChecks, ANormalApproachOvershootingTwiceIsNoOscillation) {
  Supervisor s = make();
  // A 100 mm step answered by a damped swing: beyond the set point by 45 mm, back short of it by
  // 20 mm (two sign changes of the error beyond the band), a third swing of 9 mm inside the band,
  // then rest at 0.8 s.
  const double y0 = -0.05, y_d = 0.05;
  for (double t = 0.0; t < 10.0; t += kPeriod) {
    const double y = y_d - (y_d - y0) * std::exp(-t / 0.25) * std::cos(kTwoPi * 2.5 * t);
    ASSERT_EQ(at(s, t, t < 0.8 ? y : y_d, y_d, t >= 0.805), FaultCause::kNone) << t;
  }
}

TEST_F(SettlingChecks, NoiseAroundTheSetPointChangesNoSign) {
  Supervisor s = make();
  const double y_d = 0.0;
  // Noise up to 95 % of the band on each side, flipping every tick: hysteresis, no sign change.
  for (double t = 0.0; t < 5.0; t += kPeriod) {
    const double noise_m = (static_cast<long>(std::llround(t / kPeriod)) % 2 ? 0.95 : -0.95) * v().oscillation_amplitude_m;
    ASSERT_EQ(at(s, t, y_d + noise_m, y_d, true), FaultCause::kNone) << t;
  }
}

TEST_F(SettlingChecks, SwingsSlowerThanTheWindowAllowsAreNoOscillation) {
  config_.controller.supervisor.settle_time_s = 0.0;
  Supervisor s = make();
  // The sign changes 0.8 window apart: never oscillation_sign_changes of them within one window.
  const double half_period_s = 0.8 * v().oscillation_window_s, y_d = 0.0;
  for (double t = 0.0; t < 10 * half_period_s; t += kPeriod)
    ASSERT_EQ(at(s, t, y_d - 0.05 * std::sin(kTwoPi * t / (2 * half_period_s)), y_d, false), FaultCause::kNone) << t;
}

TEST_F(SettlingChecks, AStepOfTheSetPointStartsTheCountAfresh) {
  config_.controller.supervisor.settle_time_s = 0.0;
  Supervisor s = make();
  // An operator stepping back and forth between two set points 100 mm apart every 0.25 s, each
  // step overshot once by 15 mm: a sign change per step, and no oscillation.
  for (double t = 0.0; t < 5.0; t += kPeriod) {
    const int move = static_cast<int>(t / 0.25);
    const double y_d = move % 2 ? 0.05 : -0.05;
    const double since_s = t - move * 0.25;
    const double from = -y_d;
    const double y = since_s < 0.1 ? from + (y_d + (y_d - from) * 0.15 - from) * since_s / 0.1 : y_d;
    ASSERT_EQ(at(s, t, y, y_d, false), FaultCause::kNone) << t;
  }
}

TEST_F(SettlingChecks, NoRestWithinTheSettleTimeOfASetPointChangeIsAFault) {
  config_.controller.supervisor.oscillation_sign_changes = 0;
  Supervisor s = make();
  // At rest at 0 until the set point steps to 50 mm at 1 s; the carriage creeps towards it and
  // never rests.
  double raised_at = -1.0;
  for (double t = 0.0; t < 10.0 && raised_at < 0.0; t += kPeriod) {
    const double y_d = t < 1.0 ? 0.0 : 0.05;
    const double y = t < 1.0 ? 0.0 : 0.045 * (1.0 - std::exp(-(t - 1.0) / 0.2));
    if (at(s, t, y, y_d, t < 1.001) == FaultCause::kNotSettled) raised_at = t;
  }
  EXPECT_NEAR(raised_at, 1.0 + v().settle_time_s, 1.5 * kPeriod);
  EXPECT_FALSE(s.cause_present()) << "an event: a reset clears it";
}

TEST_F(SettlingChecks, ARestWithinTheSettleTimeSatisfiesItUntilTheNextChange) {
  config_.controller.supervisor.oscillation_sign_changes = 0;
  Supervisor s = make();
  // The step at 1 s, a rest from 1.5 s to 2 s, then a restart and creeping on: settled once, the
  // rule has nothing more to say until the set point changes again at 6 s.
  const double t_change = 6.0;
  double raised_at = -1.0;
  for (double t = 0.0; t < 12.0 && raised_at < 0.0; t += kPeriod) {
    const double y_d = t < 1.0 ? 0.0 : t < t_change ? 0.05 : 0.1;
    const bool at_rest = t < 1.001 || (t >= 1.5 && t < 2.0);
    if (at(s, t, 0.04, y_d, at_rest) == FaultCause::kNotSettled) raised_at = t;
  }
  EXPECT_NEAR(raised_at, t_change + v().settle_time_s, 1.5 * kPeriod) << "only the change at 6 s goes unsettled";
}

TEST_F(SettlingChecks, AStepTooSmallToMoveTheCarriageHasSettled) {
  Supervisor s = make();
  for (double t = 0.0; t < 10.0; t += kPeriod)
    ASSERT_EQ(at(s, t, 0.0, t < 1.0 ? 0.0 : 0.004, true), FaultCause::kNone) << t;
}

TEST_F(SettlingChecks, AreOffAtZeroAndWhileDisarmed) {
  const auto swing = [](double t) { return -0.05 * std::sin(kTwoPi * 2.5 * t); };
  config_.controller.supervisor.oscillation_sign_changes = 0;
  config_.controller.supervisor.settle_time_s = 0.0;
  Supervisor off = make();
  for (double t = 0.0; t < 10.0; t += kPeriod) ASSERT_EQ(at(off, t, swing(t), 0.0, false), FaultCause::kNone) << t;
  config_.controller.supervisor = pneu::config::SupervisorConfig{};
  config_.controller.supervisor.following_error_s = 0.0;
  Supervisor disarmed = make();
  for (double t = 0.0; t < 10.0; t += kPeriod)
    ASSERT_EQ(at(disarmed, t, swing(t), 0.0, false, /*armed=*/false), FaultCause::kNone) << t;
}

TEST_F(SettlingChecks, ArmingStartsBothRulesAfresh) {
  Supervisor s = make();
  const auto y = [](double t) { return -0.05 * std::sin(kTwoPi * 2.5 * t); };
  // Three sign changes (one short of the fault), then re-armed: three more are still one short.
  double t = 0.0;
  for (; t < 0.5; t += kPeriod) ASSERT_EQ(at(s, t, y(t), 0.0, false), FaultCause::kNone) << t;
  ASSERT_EQ(v().oscillation_sign_changes, 4u);
  s.on_arm();
  for (; t < 1.0; t += kPeriod) ASSERT_EQ(at(s, t, y(t), 0.0, false), FaultCause::kNone) << t;
  // ... and the settle time runs from the arming.
  const double armed_at = t;
  s.on_arm();
  double raised_at = -1.0;
  for (; t < 10.0 && raised_at < 0.0; t += kPeriod)
    if (at(s, t, 0.001 * t, 0.0, false) == FaultCause::kNotSettled) raised_at = t;
  EXPECT_NEAR(raised_at, armed_at + v().settle_time_s, 1.5 * kPeriod);
}

TEST_F(SupervisorChecks, TheEStopIsAFaultAndACausePresentWhilePressed) {
  Supervisor s = make();
  hal::SensorFrame f = good(0.0);
  f.estop = true;
  EXPECT_EQ(tick(s, 0.0, f), c::FaultCause::kEStop);
  EXPECT_TRUE(s.cause_present());
  f.estop = false;
  f.t_s = kPeriod;
  EXPECT_EQ(tick(s, kPeriod, f), c::FaultCause::kNone);
  EXPECT_FALSE(s.cause_present());
}

TEST(FaultCauses, EveryCauseHasANameAndAText) {
  for (std::size_t k = 1; k < c::kFaultCauseCount; ++k) {
    const auto cause = static_cast<FaultCause>(k);
    EXPECT_STRNE(c::fault_name(cause), "unknown") << k;
    EXPECT_STRNE(c::fault_text(cause), "fault") << k;
  }
}

TEST(FaultCauses, KeepTheirNumbersOnTheWire) {
  // event_t and health_t carry these numbers: a renumbering breaks every log and every client.
  EXPECT_EQ(c::fault_number(FaultCause::kNone), 0);
  EXPECT_EQ(c::fault_number(FaultCause::kEStop), 1);
  EXPECT_EQ(c::fault_number(FaultCause::kComms), 2);
  EXPECT_EQ(c::fault_number(FaultCause::kSoftLimit), 7);
  EXPECT_EQ(c::fault_number(FaultCause::kCommandTimeout), 10);
  EXPECT_EQ(c::fault_number(FaultCause::kOscillation), 11);
  EXPECT_EQ(c::fault_number(FaultCause::kNotSettled), 12);
  EXPECT_EQ(c::fault_number(FaultCause::kAnotherController), 13);
  EXPECT_EQ(c::fault_number(FaultCause::kMovementTest), 14);
  EXPECT_EQ(c::fault_number(FaultCause::kMovementTest), c::kFaultCauseCount - 1);
  EXPECT_STREQ(c::fault_name(static_cast<FaultCause>(c::kFaultCauseCount)), "unknown");
}

}  // namespace

namespace {

// systemd's watchdog is petted only while the loop ticks.
TEST(WatchdogGate, PetsOncePerIntervalWhileTheHeartbeatAdvances) {
  pneu::controller::WatchdogGate gate(0.5);
  EXPECT_FALSE(gate.due(0, 0.0)) << "not before the first tick";
  EXPECT_TRUE(gate.due(10, 0.1)) << "the loop runs";
  EXPECT_FALSE(gate.due(20, 0.3)) << "within the interval";
  EXPECT_TRUE(gate.due(600, 0.6));
  EXPECT_TRUE(gate.due(1100, 1.1));
}

TEST(WatchdogGate, StopsPettingWhenTheLoopStopsTicking) {
  pneu::controller::WatchdogGate gate(0.5);
  EXPECT_TRUE(gate.due(100, 0.0));
  EXPECT_FALSE(gate.due(100, 0.6)) << "a hung loop: no petting, systemd restarts the daemon";
  EXPECT_FALSE(gate.due(100, 1.2));
  EXPECT_TRUE(gate.due(101, 1.8)) << "ticking again";
}

TEST(WatchdogGate, IsOffWithoutAWatchdog) {
  pneu::controller::WatchdogGate gate(0.0);
  EXPECT_FALSE(gate.due(1, 0.0));
  EXPECT_FALSE(gate.due(1000, 10.0));
}

}  // namespace
