// The movement test before closed loop (controller.movement_test) on the in-process plant with
// hil.yaml's noisy, quantised sensors, in simulated time: a correct bench passes, and each
// miswiring a backend wrapper makes of it (the tubes or the pressure channels swapped, the position
// reversed, a sensor dead) is named. Over Modbus: test_hil.cpp (MovementTest*).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <utility>

#include "pneu/backends/factory.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/movement_test.hpp"
#include "pneu/controller/session.hpp"

namespace {

using namespace pneu;
using controller::MovementFinding;

// What a miswired bench does to the signals between the loop and the plant.
struct Wiring {
  bool tubes_swapped = false;     // valve P feeds chamber N, valve N chamber P
  bool pressures_swapped = false; // the p_P channel reads chamber N, and back
  bool position_reversed = false; // the position reads -y
  bool p_p_dead = false, p_n_dead = false, position_dead = false;  // the reading stays where it was
};

class MiswiredBackend final : public hal::Backend {
 public:
  MiswiredBackend(std::unique_ptr<hal::Backend> inner, Wiring w) : inner_(std::move(inner)), w_(w) {}
  void open(double t0_s) override { inner_->open(t0_s); }
  void close() noexcept override { inner_->close(); }
  hal::Status read(double t_s, hal::SensorFrame& f) noexcept override {
    const hal::Status s = inner_->read(t_s, f);
    if (w_.pressures_swapped) std::swap(f.p_p_pa, f.p_n_pa);
    if (w_.position_reversed) f.y_m = -f.y_m;
    if (first_) {
      first_ = false;
      y0_ = f.y_m, p0_ = f.p_p_pa, n0_ = f.p_n_pa;
    }
    if (w_.position_dead) f.y_m = y0_;
    if (w_.p_p_dead) f.p_p_pa = p0_;
    if (w_.p_n_dead) f.p_n_pa = n0_;
    return s;
  }
  hal::Status write(const hal::ActuatorCommand& c) noexcept override {
    last_ = c;
    hal::ActuatorCommand to = c;
    if (w_.tubes_swapped) std::swap(to.u_p_v, to.u_n_v);
    return inner_->write(to);
  }

 private:
  std::unique_ptr<hal::Backend> inner_;
  Wiring w_;
  bool first_ = true;

 public:
  hal::ActuatorCommand last_;  // the last command written to the bench
  double y0_ = 0.0, p0_ = 0.0, n0_ = 0.0;
};

struct Outcome {
  controller::MovementTestResult result;
  double y_true_end_m = 0.0;  // where the plant's carriage really is at the end
};

// The test on hil.yaml's bench, run in process from rest at `y0_m`, through `wiring`.
Outcome run_test(const Wiring& wiring, double y0_m = 0.2195) {
  config::Config cfg = config::load_file(std::string(PNEU_SOURCE_DIR) + "/config/hil.yaml",
                                         {"hal.backend=sim", "controller.clock=simulated",
                                          "simulation.initial_position_m=" + std::to_string(y0_m),
                                          "controller.setpoints.initial_m=" + std::to_string(y0_m)});
  const auto valve = controller::make_valve_characteristic(cfg, {});
  controller::resolve_offset(cfg, *valve);
  std::unique_ptr<hal::SimBackend> sim = backends::make_sim_backend(cfg);
  const hal::SimBackend& plant = *sim;
  MiswiredBackend backend(std::move(sim), wiring);
  backend.open(0.0);
  const auto& c = cfg.controller;
  controller::MovementTest test(c.movement_test, controller::MovementTestBench::of(cfg));
  controller::SimulatedClock clock;
  const std::atomic<bool> stop{false};
  Outcome o;
  o.result = controller::run_movement_test(backend, clock, c.period_s(), test, stop);
  o.y_true_end_m = plant.plant().state().y_m;
  std::printf("%s\n", controller::describe(o.result).c_str());
  EXPECT_FALSE(backend.last_.valve_power) << "valve power off once done";
  EXPECT_NEAR(backend.last_.u_p_v, c.law.offset_v, 1e-12) << "u_0 once done";
  return o;
}

TEST(MovementTest, ACorrectBenchPassesWithinTwoSecondsAndEndsNearWhereItStarted) {
  const Outcome o = run_test({});
  const auto& r = o.result;
  ASSERT_TRUE(r.passed()) << controller::describe(r);
  EXPECT_EQ(r.pulses, 2);
  EXPECT_LT(r.pulse[0].du_v, 0.0) << "from 219.5 mm the first pulse heads for the side with more room";
  EXPECT_GT(r.pulse[1].du_v, 0.0);
  EXPECT_LT(r.duration_s, 2.0) << controller::describe(r);
  EXPECT_NEAR(o.y_true_end_m, 0.2195, 0.01) << "the carriage ends within 10 mm of its start";
  EXPECT_LT(o.y_true_end_m, 0.24) << "inside the soft limits";
}

TEST(MovementTest, FromTheOtherHalfOfTheStrokeTheFirstPulseIsPositive) {
  const Outcome o = run_test({}, -0.1);
  ASSERT_TRUE(o.result.passed()) << controller::describe(o.result);
  EXPECT_GT(o.result.pulse[0].du_v, 0.0);
}

TEST(MovementTest, SwappedTubesAreNamed) {
  const Outcome o = run_test({.tubes_swapped = true});
  EXPECT_EQ(o.result.finding, MovementFinding::kTubesSwapped) << controller::describe(o.result);
  EXPECT_EQ(o.result.pulses, 1) << "a carriage that went the wrong way is not driven again";
  EXPECT_NEAR(o.y_true_end_m, 0.2195, 0.015) << "the wrong way is limited too";
}

TEST(MovementTest, SwappedPressureChannelsAreNamed) {
  const Outcome o = run_test({.pressures_swapped = true});
  EXPECT_EQ(o.result.finding, MovementFinding::kPressureSensorsSwapped) << controller::describe(o.result);
}

TEST(MovementTest, AReversedPositionSensorIsNamed) {
  const Outcome o = run_test({.position_reversed = true});
  EXPECT_EQ(o.result.finding, MovementFinding::kPositionReversed) << controller::describe(o.result);
}

TEST(MovementTest, ADeadPressureSensorIsNamedByItsChamber) {
  EXPECT_EQ(run_test({.p_p_dead = true}).result.finding, MovementFinding::kPressurePDead);
  EXPECT_EQ(run_test({.p_n_dead = true}).result.finding, MovementFinding::kPressureNDead);
}

TEST(MovementTest, ADeadPositionSensorIsNamedAfterOnePulseEndedAtItsTimeLimit) {
  const Outcome o = run_test({.position_dead = true});
  EXPECT_EQ(o.result.finding, MovementFinding::kPositionNotResponding) << controller::describe(o.result);
  ASSERT_EQ(o.result.pulses, 1) << "a motion not seen is not driven again";
  config::MovementTestConfig defaults;
  EXPECT_NEAR(o.result.pulse[0].duration_s, defaults.pulse_s, 2e-3);
  EXPECT_LT(std::abs(o.y_true_end_m), 0.24) << "the carriage stays inside the soft limits: "
                                            << o.y_true_end_m;
}

TEST(MovementTest, BadSamplesEndItAsACommsFindingAndAStopRequestAsAnInterruption) {
  config::MovementTestConfig cfg;
  const controller::MovementTestBench bench;  // comms limit 0.05 s
  controller::MovementTest test(cfg, bench);
  hal::SensorFrame good;
  good.p_p_pa = good.p_n_pa = 3e5;
  (void)test.step(0.0, hal::Status::kOk, good);
  hal::SensorFrame stale = good;
  stale.validity = hal::kSampleStale;
  double t = 0.0;
  for (; !test.done() && t < 1.0; t += 1e-3) {
    const hal::ActuatorCommand c = test.step(t, hal::Status::kStale, stale);
    if (!test.done()) {
      EXPECT_TRUE(c.valve_power);
    }
  }
  EXPECT_EQ(test.result().finding, MovementFinding::kComms);
  EXPECT_NEAR(t, 0.05, 3e-3);
  EXPECT_FALSE(test.step(t, hal::Status::kOk, good).valve_power);

  controller::MovementTest other(cfg, bench);
  (void)other.step(0.0, hal::Status::kOk, good);
  other.interrupt();
  EXPECT_EQ(other.result().finding, MovementFinding::kInterrupted);
}

TEST(MovementTest, RunsOnAModbusBackendStartingArmedUnlessTheKeySaysNotAndNeverInProcess) {
  config::Config cfg = config::load_file(std::string(PNEU_SOURCE_DIR) + "/config/hil.yaml");
  EXPECT_TRUE(controller::movement_test_runs(cfg));
  cfg.controller.movement_test.enabled = false;
  EXPECT_FALSE(controller::movement_test_runs(cfg));
  cfg.controller.movement_test.enabled = true;
  cfg.controller.start_armed = false;
  EXPECT_FALSE(controller::movement_test_runs(cfg)) << "not before an ARM command it would pre-empt";
  EXPECT_FALSE(controller::movement_test_runs(config::load_file_or_default("", {})));
}

}  // namespace
