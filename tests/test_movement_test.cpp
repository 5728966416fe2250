// The movement test before closed loop (controller.movement_test) on the in-process plant with
// hil.yaml's noisy, quantised sensors, in simulated time: a correct bench passes, and each
// miswiring a backend wrapper makes of it (the tubes or the pressure channels swapped, the position
// reversed, a sensor dead) is named; and the same test stepped by the loop at the first ARM of a run
// started disarmed (MovementTestAtArm). Over Modbus: test_hil.cpp (HilMovementTest*) and, commanded
// over LCM, test_hil_commanded.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/movement_test.hpp"
#include "pneu/controller/session.hpp"
#include "support/paths.hpp"

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
    if (estop) f.estop = true;
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
  bool estop = false;          // the e-stop pressed from now on
  double y0_ = 0.0, p0_ = 0.0, n0_ = 0.0;
};

struct Outcome {
  controller::MovementTestResult result;
  double y_true_end_m = 0.0;  // where the plant's carriage really is at the end
};

// The test on hil.yaml's bench, run in process from rest at `y0_m`, through `wiring`.
Outcome run_test(const Wiring& wiring, double y0_m = 0.2195) {
  const assembly::RunSpec spec = assembly::RunSpec::of(
      config::load_file(pneu::test::hil_yaml(),
                        {"hal.backend=sim", "controller.clock=simulated",
                         "simulation.initial_position_m=" + std::to_string(y0_m),
                         "controller.setpoints.initial_m=" + std::to_string(y0_m)}));
  const config::Config& cfg = spec.config();
  std::unique_ptr<hal::SimBackend> sim = assembly::simulated_bench(spec);
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
  config::Config cfg = config::load_file(pneu::test::hil_yaml());
  EXPECT_TRUE(controller::movement_test_runs(cfg));
  cfg.controller.movement_test.enabled = false;
  EXPECT_FALSE(controller::movement_test_runs(cfg));
  cfg.controller.movement_test.enabled = true;
  cfg.controller.start_armed = false;
  EXPECT_FALSE(controller::movement_test_runs(cfg)) << "not before an ARM command it would pre-empt";
  EXPECT_FALSE(controller::movement_test_runs(config::load_file_or_default("", {})));
}

TEST(MovementTest, RunsAtTheFirstArmOnAModbusBackendStartingDisarmedAndNeverInProcess) {
  config::Config cfg = config::load_file(pneu::test::hil_yaml());
  EXPECT_FALSE(controller::movement_test_at_first_arm(cfg)) << "starting armed it runs before the loop's time";
  cfg.controller.start_armed = false;
  EXPECT_TRUE(controller::movement_test_at_first_arm(cfg));
  cfg.controller.law.gains = config::GainsKind::kFixed;  // no table to design for this
  EXPECT_TRUE(controller::LoopParams::from(cfg, controller::ControlLaw(cfg.controller.law)).movement_test_at_arm);
  cfg.controller.movement_test.enabled = false;
  EXPECT_FALSE(controller::movement_test_at_first_arm(cfg));
  config::Config sim = config::load_file_or_default("", {"controller.start_armed=false"});
  EXPECT_FALSE(controller::movement_test_at_first_arm(sim));
}

// The loop at the first ARM of a run started disarmed (Mode::kMovementTest), on hil.yaml's bench
// in process, through a wiring: tick by tick in simulated time, commands pushed as the command
// thread pushes them. The in-process plant never runs it by itself (it cannot be miswired): the
// parameters say it does, as hal.backend modbus makes them. The in-position hold off (hil.yaml
// ships with it on): the modes at ARM are the subject; with it on, a carriage armed at rest at its
// set point goes on to hold (HilFaultInjection).
class MovementTestAtArm : public ::testing::Test {
 protected:
  void start(const Wiring& wiring) {
    const assembly::RunSpec spec = assembly::RunSpec::of(
        config::load_file(pneu::test::hil_yaml(),
                          {"hal.backend=sim", "controller.clock=simulated", "controller.start_armed=false",
                           "controller.setpoints.schedule=[]", "controller.setpoints.initial_m=0.2195",
                           "controller.hold.enabled=false"}));
    cfg_ = spec.config();
    auto sim = assembly::simulated_bench(spec);
    plant_ = sim.get();
    backend_ = std::make_unique<MiswiredBackend>(std::move(sim), wiring);
    controller::LoopParams params = controller::LoopParams::from(cfg_, spec.law());
    params.movement_test_at_arm = true;
    loop_ = std::make_unique<controller::ControlLoop>(params, *backend_, *outputs_);
    loop_->start(0.0);
    run_for(0.1);
  }
  // Ticks at the loop's period for `s` seconds, or until the mode leaves `until_not` when given.
  void run_for(double s, std::optional<controller::Mode> until_not = std::nullopt) {
    const double period = cfg_.controller.period_s();
    for (double end = t_ + s; t_ < end - 1e-9;) {
      t_ += period;
      loop_->tick(t_);
      controller::TickRecord r;
      while (outputs_->ticks.try_pop(r))
        if (modes_.empty() || modes_.back() != static_cast<char>('0' + static_cast<int>(r.mode)))
          modes_ += static_cast<char>('0' + static_cast<int>(r.mode));
      controller::LoopEvent e;
      while (outputs_->events.try_pop(e))
        if (e.kind == controller::LoopEvent::Kind::kMovementTest || e.kind == controller::LoopEvent::Kind::kFault)
          events_.push_back(e);
      if (until_not && loop_->mode() != *until_not) return;
    }
  }
  void command(controller::LoopCommand::Kind kind, double value_m = 0.0) {
    ASSERT_TRUE(outputs_->commands.try_push({kind, value_m, ++seq_}));
    run_for(cfg_.controller.period_s());
  }
  // ARM, then the ticks until the test ended (3 s at most).
  void arm_and_test() {
    command(controller::LoopCommand::Kind::kArm);
    ASSERT_EQ(loop_->mode(), controller::Mode::kMovementTest);
    run_for(3.0, controller::Mode::kMovementTest);
  }
  [[nodiscard]] double y_true_m() const { return plant_->plant().state().y_m; }

  config::Config cfg_;
  hal::SimBackend* plant_ = nullptr;
  std::unique_ptr<MiswiredBackend> backend_;
  std::unique_ptr<controller::LoopOutputs> outputs_ = std::make_unique<controller::LoopOutputs>();
  std::unique_ptr<controller::ControlLoop> loop_;
  double t_ = 0.0;
  std::uint64_t seq_ = 0;
  std::string modes_;  // each run of a mode once, by number: "0412" disarmed, test, armed, fault
  std::vector<controller::LoopEvent> events_;  // the movement test's ends and the faults
};

using controller::LoopCommand;
using controller::Mode;
using controller::MovementTestEnd;

TEST_F(MovementTestAtArm, ACorrectBenchPassesThenArmsHoldingWhereTheCarriageIsAndALaterArmDoesNotTestAgain) {
  start({});
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(outputs_->mode.load(), Mode::kMovementTest) << "visible to the command thread and health";
  EXPECT_TRUE(backend_->last_.valve_power) << "the test drives the valves";
  command(LoopCommand::Kind::kSetPoint, 0.17);  // refused by the validator; one that got through is dropped
  run_for(3.0, Mode::kMovementTest);
  ASSERT_EQ(loop_->mode(), Mode::kArmed) << modes_;
  ASSERT_EQ(events_.size(), 1u);
  const controller::LoopEvent& e = events_[0];
  EXPECT_EQ(e.movement_end, MovementTestEnd::kPassed);
  EXPECT_TRUE(e.movement_test.passed()) << controller::describe(e.movement_test);
  EXPECT_EQ(e.movement_test.pulses, 2);
  EXPECT_LT(e.movement_test.duration_s, 2.0);
  EXPECT_NEAR(outputs_->setpoint_m.load(), e.y_m, 1e-12) << "armed holding where the carriage is as it passed";
  EXPECT_EQ(e.y_d_m, outputs_->setpoint_m.load()) << "the event says the set point armed";
  EXPECT_NEAR(y_true_m(), 0.2195, 0.01);
  run_for(1.0);
  EXPECT_EQ(loop_->mode(), Mode::kArmed);
  EXPECT_NEAR(y_true_m(), e.y_m, 0.002) << "held";
  EXPECT_FALSE(loop_->movement_test_due());

  command(LoopCommand::Kind::kDisarm);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(loop_->mode(), Mode::kArmed) << "once passed, not again in this run";
  EXPECT_EQ(modes_, "04101");
}

TEST_F(MovementTestAtArm, SwappedTubesLatchTheMovementTestFaultNamingThemAndAResetDoesNotSkipTheNextTest) {
  start({.tubes_swapped = true});
  arm_and_test();
  ASSERT_EQ(loop_->mode(), Mode::kFault) << modes_;
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kMovementTest);
  EXPECT_EQ(outputs_->fault_cause.load(), controller::FaultCause::kMovementTest);
  EXPECT_EQ(modes_, "042") << "the law never drove";
  ASSERT_EQ(events_.size(), 2u);
  EXPECT_EQ(events_[0].movement_end, MovementTestEnd::kFinding);
  EXPECT_EQ(events_[0].movement_test.finding, MovementFinding::kTubesSwapped);
  EXPECT_EQ(events_[1].kind, controller::LoopEvent::Kind::kFault);
  EXPECT_EQ(events_[1].movement_test.finding, MovementFinding::kTubesSwapped) << "the fault carries the finding";
  EXPECT_STREQ(events_[1].fault_key, "controller.movement_test");
  const hal::ActuatorCommand safe = loop_->safe_command();
  EXPECT_FALSE(backend_->last_.valve_power);
  EXPECT_EQ(backend_->last_.u_p_v, safe.u_p_v);
  EXPECT_EQ(backend_->last_.u_n_v, safe.u_n_v);
  EXPECT_NEAR(y_true_m(), 0.2195, 0.015);

  command(LoopCommand::Kind::kFaultReset);
  ASSERT_EQ(loop_->mode(), Mode::kDisarmed);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(loop_->mode(), Mode::kMovementTest) << "the wiring may have been mended: tested again";
}

TEST_F(MovementTestAtArm, ADisarmAFaultOrTheRunsStopDuringTheTestAbortItSafelyAndTheNextArmTestsAgain) {
  start({});
  command(LoopCommand::Kind::kArm);
  run_for(0.1);
  command(LoopCommand::Kind::kDisarm);
  EXPECT_EQ(loop_->mode(), Mode::kDisarmed);
  EXPECT_FALSE(backend_->last_.valve_power);
  EXPECT_EQ(backend_->last_.u_p_v, cfg_.controller.law.offset_v) << "disarmed: u_0";
  ASSERT_EQ(events_.size(), 1u);
  EXPECT_EQ(events_[0].movement_end, MovementTestEnd::kDisarmed);
  EXPECT_EQ(events_[0].movement_test.finding, MovementFinding::kInterrupted);

  command(LoopCommand::Kind::kArm);
  ASSERT_EQ(loop_->mode(), Mode::kMovementTest) << "not passed: tested again";
  run_for(0.1);
  backend_->estop = true;
  run_for(cfg_.controller.period_s());
  EXPECT_EQ(loop_->mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kEStop);
  EXPECT_FALSE(backend_->last_.valve_power);
  ASSERT_EQ(events_.size(), 3u);
  EXPECT_EQ(events_[1].movement_end, MovementTestEnd::kFault);
  EXPECT_EQ(events_[1].fault_cause, controller::FaultCause::kEStop);

  backend_->estop = false;
  command(LoopCommand::Kind::kFaultReset);
  command(LoopCommand::Kind::kArm);
  ASSERT_EQ(loop_->mode(), Mode::kMovementTest);
  run_for(0.1);
  loop_->stop();
  EXPECT_EQ(loop_->mode(), Mode::kDisarmed);
  EXPECT_FALSE(backend_->last_.valve_power) << "the run's stop: the safe output";
  controller::LoopEvent e;
  ASSERT_TRUE(outputs_->events.try_pop(e));
  EXPECT_EQ(e.movement_end, MovementTestEnd::kStopped);
}

}  // namespace
