// The loop's modes (docs/architecture.md, "Faults and the safe state"): armed, the law drives the
// valves with power on; disarmed, the outputs sit at the neutral voltage u_0 with power off; a fault
// latches the safe output until a reset received once its cause is gone, and the reset disarms.
// Set points from commands are clamped to the soft limits. Specified on a real ControlLoop over a
// fake backend whose sensors the test sets and whose last command it reads: no plant, no GPIO.
// (The e-stop and valve power through the GPIO lines: tests/test_gpio.cpp.)
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>
#include <memory>
#include <optional>
#include <ostream>
#include <utility>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/modes.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/hal/backend.hpp"

namespace pneu::hal {
// How gtest prints a command.
void PrintTo(const ActuatorCommand& c, std::ostream* os) {
  *os << "{u_P " << c.u_p_v << " V, u_N " << c.u_n_v << " V, valve power " << (c.valve_power ? "on" : "off") << "}";
}
}  // namespace pneu::hal

namespace {

using namespace pneu;
using controller::LoopCommand;
using controller::LoopEvent;
using controller::Mode;

// The bench as the loop sees it: a sample the test sets (the carriage held still, plausible
// pressures), and the commands the loop wrote.
class FakeBackend final : public hal::Backend {
 public:
  void open(double) override {}
  void close() noexcept override {}
  hal::Status read(double t_s, hal::SensorFrame& frame) noexcept override {
    frame = sample;
    frame.t_s = t_s;
    return hal::Status::kOk;
  }
  hal::Status write(const hal::ActuatorCommand& command) noexcept override {
    written = command;
    ++writes;
    return hal::Status::kOk;
  }

  hal::SensorFrame sample{0.0, 0.2145, 3.4e5, 4.9e5, 0.0, false, true, hal::kSensorsValid};
  hal::ActuatorCommand written{};
  int writes = 0;
};

constexpr double kU0V = 0.25;  // u_0, set rather than derived from the valve model: any value does

class LoopModes : public ::testing::Test {
 protected:
  LoopModes() {
    // The modes do not depend on the law: the paper's fixed gains keep each expected output a
    // line of arithmetic (and are the unstable ones the oscillation tests need).
    config_.controller.law.gains = config::GainsKind::kFixed;
    config_.controller.law.offset_v = kU0V;
    config_.controller.schedule.clear();  // the set point stays at initial_m (219.5 mm) until told
  }

  // Builds the loop from config_ (tests edit it first) and starts it at t = 0.
  void start() {
    loop_ = std::make_unique<controller::ControlLoop>(controller::LoopParams::from(config_), backend_, *outputs_);
    loop_->start(0.0);
  }
  // `n` ticks at the configured period, continuing from the last one.
  void run_ticks(int n) {
    for (int i = 0; i < n; ++i) loop_->tick(static_cast<double>(k_++) * config_.controller.period_s());
  }
  void send(LoopCommand::Kind kind, double value_m = 0.0) {
    ASSERT_TRUE(outputs_->commands.try_push(LoopCommand{kind, value_m, ++seq_}));
  }
  // Sends and runs the one tick that applies it.
  void command(LoopCommand::Kind kind, double value_m = 0.0) {
    send(kind, value_m);
    run_ticks(1);
  }
  [[nodiscard]] Mode mode() const { return loop_->mode(); }
  [[nodiscard]] double setpoint_m() const { return outputs_->setpoint_m.load(); }
  [[nodiscard]] double now_s() const { return static_cast<double>(k_ - 1) * config_.controller.period_s(); }
  // The events queued since the last call.
  std::vector<LoopEvent> events() {
    std::vector<LoopEvent> v;
    LoopEvent e;
    while (outputs_->events.try_pop(e)) v.push_back(e);
    return v;
  }
  // Latches an e-stop fault, armed, 0.1 s into the run.
  void latch_estop_fault() {
    start();
    run_ticks(100);
    ASSERT_EQ(mode(), Mode::kArmed);
    backend_.sample.estop = true;
    run_ticks(1);
    ASSERT_EQ(mode(), Mode::kFault);
  }

  config::Config config_ = config::load_string(config::default_config_yaml());
  FakeBackend backend_;
  std::unique_ptr<controller::LoopOutputs> outputs_ = std::make_unique<controller::LoopOutputs>();  // large queues
  std::unique_ptr<controller::ControlLoop> loop_;
  std::int64_t k_ = 0;
  std::uint64_t seq_ = 0;
};

const hal::ActuatorCommand kNeutralPowerOff = hal::ActuatorCommand::from_control(kU0V, false);

// u_0 and the safe voltages are copied, not computed: compared exactly.
MATCHER_P(IsCommand, expected, "is " + ::testing::PrintToString(expected)) {
  return arg.u_p_v == expected.u_p_v && arg.u_n_v == expected.u_n_v && arg.valve_power == expected.valve_power;
}

// ---------------------------------------------------------------------------------------------
// The modes as one state machine (modes.hpp): the table of every change, as the specification.
// The tests below show each change on a running loop with what it does on the way.

using controller::ModeEvent;

const char* mode_name(Mode m) {
  switch (m) {
    case Mode::kDisarmed: return "disarmed";
    case Mode::kArmed: return "armed";
    case Mode::kFault: return "fault";
    case Mode::kHold: return "hold";
    case Mode::kMovementTest: return "movement test";
  }
  return "?";
}
constexpr const char* kEventNames[] = {"ARM",         "ARM (test due)", "DISARM",   "fault",    "reset",
                                       "reset refused", "test passed",  "hold start", "hold end", "run stops"};
static_assert(std::size(kEventNames) == controller::kModeEventCount);

TEST(LoopModesStateMachine, EachModeAndEventLeadsToTheModeThisTableSays) {
  constexpr std::optional<Mode> none = std::nullopt;  // the event changes nothing and does nothing there
  constexpr Mode disarmed = Mode::kDisarmed, armed = Mode::kArmed, fault = Mode::kFault, hold = Mode::kHold,
                 test = Mode::kMovementTest;
  struct Row {
    Mode from;
    std::array<std::optional<Mode>, controller::kModeEventCount> to;  // by ModeEvent, in its order
  };
  const Row spec[] = {
      // in mode   ARM     ARM,    DISARM    fault  reset     reset    test    hold   hold   run
      //                   test                             refused  passed  start  end    stops
      //                   due
      {disarmed,  {armed,  test,   none,     fault, none,     none,    none,   none,  none,  none}},
      {armed,     {none,   none,   disarmed, fault, none,     none,    none,   hold,  none,  none}},
      {hold,      {none,   none,   disarmed, fault, none,     none,    none,   none,  armed, none}},
      {test,      {none,   none,   disarmed, fault, none,     none,    armed,  none,  none,  disarmed}},
      {fault,     {none,   none,   none,     none,  disarmed, fault,   none,   none,  none,  none}},
  };
  ASSERT_EQ(std::size(spec), controller::kModeCount);
  for (const Row& row : spec) {
    for (std::size_t e = 0; e < controller::kModeEventCount; ++e) {
      const std::optional<Mode> next = controller::next_mode(row.from, static_cast<ModeEvent>(e));
      EXPECT_EQ(next, row.to[e]) << "in mode " << mode_name(row.from) << ", " << kEventNames[e] << " leads to "
                                 << (next ? mode_name(*next) : "no change") << ", the specification says "
                                 << (row.to[e] ? mode_name(*row.to[e]) : "no change");
    }
  }
}

TEST(LoopModesStateMachine, ListsEachModeAndEventAtMostOnce) {
  const auto& table = controller::kModeTransitions;
  for (std::size_t i = 0; i < table.size(); ++i)
    for (std::size_t j = i + 1; j < table.size(); ++j)
      EXPECT_FALSE(table[i].from == table[j].from && table[i].event == table[j].event)
          << "rows " << i << " and " << j << ": " << mode_name(table[i].from) << ", "
          << kEventNames[static_cast<std::size_t>(table[i].event)];
}

// ---------------------------------------------------------------------------------------------
// Armed and disarmed

TEST_F(LoopModes, StartsArmedWithTheLawDrivingTheValvesAndPowerOn) {
  start();
  run_ticks(10);
  EXPECT_EQ(mode(), Mode::kArmed);
  // The carriage still, 5 mm short of the set point: u = K_y (y_d - y) + u_0 (no velocity).
  const double u = loop_->law().control_v(0.2195, 0.2145, 0.0, 0.0);
  ASSERT_GT(u, kU0V + 0.1) << "the law must ask for motion";
  EXPECT_THAT(backend_.written, IsCommand(hal::ActuatorCommand::from_control(u, true)));
}

TEST_F(LoopModes, StartsDisarmedWhenConfiguredWithPowerOffAtTheNeutralVoltage) {
  config_.controller.start_armed = false;
  start();
  run_ticks(10);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

TEST_F(LoopModes, DisarmCutsValvePowerAndHoldsTheNeutralVoltage) {
  start();
  run_ticks(10);
  command(LoopCommand::Kind::kDisarm);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  run_ticks(100);  // and stays so
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

TEST_F(LoopModes, ArmHoldsWhereTheCarriageIsWithPowerOn) {
  config_.controller.start_armed = false;
  backend_.sample.y_m = 0.1;  // away from the initial set point, 219.5 mm
  start();
  run_ticks(10);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_EQ(setpoint_m(), 0.1) << "bumpless: the set point is where the carriage is";
  EXPECT_THAT(backend_.written, IsCommand(hal::ActuatorCommand::from_control(kU0V, true)))
      << "at the set point, still: the law asks for u_0";
}

TEST_F(LoopModes, ArmBeyondASoftLimitHoldsAtTheLimit) {
  config_.controller.start_armed = false;
  start();
  backend_.sample.y_m = config_.controller.soft_limit_max_m + 0.005;  // within the overtravel
  run_ticks(10);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_EQ(setpoint_m(), config_.controller.soft_limit_max_m);
}

TEST_F(LoopModes, ArmWhileArmedKeepsTheSetPoint) {
  start();
  run_ticks(10);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_EQ(setpoint_m(), config_.controller.initial_setpoint_m) << "not moved to the carriage";
}

// ---------------------------------------------------------------------------------------------
// Faults, resets

TEST_F(LoopModes, AnEStopLatchesTheFaultWithinOneTickAndDrivesTheNeutralSafeOutput) {
  latch_estop_fault();
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kEStop);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

TEST_F(LoopModes, TheExhaustSafeOutputVentsBothChambersWithPowerOff) {
  config_.controller.supervisor.safe_output = config::SafeOutput::kExhaust;
  latch_estop_fault();
  const double u_max = config_.controller.law.max_voltage_v;
  EXPECT_THAT(backend_.written, IsCommand(hal::ActuatorCommand{-u_max, -u_max, false}));
}

TEST_F(LoopModes, TheFaultIsReportedOnceAsAnEventWithItsCause) {
  start();
  run_ticks(100);
  (void)events();
  backend_.sample.estop = true;
  run_ticks(1);
  const double t_fault_s = now_s();
  run_ticks(49);  // held for 50 ms: one fault, not one per tick
  const auto seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kFault);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kEStop);
  EXPECT_DOUBLE_EQ(seen[0].t_s, t_fault_s) << "dated at the tick that saw the e-stop";
  EXPECT_EQ(loop_->faults(), 1u);
  EXPECT_THAT(controller::fault_text(controller::FaultCause::kEStop), ::testing::HasSubstr("e-stop"));
}

TEST_F(LoopModes, TheFaultStaysLatchedAfterTheCauseIsGone) {
  latch_estop_fault();
  backend_.sample.estop = false;
  run_ticks(500);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kEStop);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

TEST_F(LoopModes, AResetWhileTheCauseStaysIsRefusedNamingTheCause) {
  latch_estop_fault();
  run_ticks(10);
  (void)events();
  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kFault);
  const auto seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kResetRefused);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kEStop);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

// Another controller on the channels: only the service thread hears it, and asks through
// LoopOutputs::external_fault, which the loop latches at its next tick and which refuses a reset
// for as long as it stays set.
TEST_F(LoopModes, AFaultTheServiceSideSeesLatchesAtTheNextTickAndRefusesResetsWhileItLasts) {
  start();
  run_ticks(100);
  ASSERT_EQ(mode(), Mode::kArmed);
  (void)events();
  outputs_->external_fault.store(controller::FaultCause::kAnotherController);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kAnotherController);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  auto seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kFault);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kAnotherController);
  run_ticks(100);
  EXPECT_TRUE(events().empty()) << "latched once, not every tick";

  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kFault) << "the other controller is still heard";
  seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kResetRefused);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kAnotherController);

  outputs_->external_fault.store(controller::FaultCause::kNone);  // no longer heard
  run_ticks(1);
  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kDisarmed);
}

TEST_F(LoopModes, AnEStopWhileDisarmedLatchesTheFaultToo) {
  config_.controller.start_armed = false;
  start();
  run_ticks(10);
  (void)events();
  backend_.sample.estop = true;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  const auto seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kFault);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kEStop);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  backend_.sample.estop = false;
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kFault) << "latched: only a reset clears it";
}

TEST_F(LoopModes, AResetWithoutAFaultChangesNothingAndSaysNothing) {
  start();
  run_ticks(10);
  (void)events();
  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(events().empty());
  EXPECT_TRUE(backend_.written.valve_power);
}

TEST_F(LoopModes, NeitherArmNorDisarmLeavesAFault) {
  latch_estop_fault();
  backend_.sample.estop = false;  // the cause gone: still only a reset clears the fault
  run_ticks(10);
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kFault);
  command(LoopCommand::Kind::kDisarm);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

TEST_F(LoopModes, AResetOnceTheCauseIsGoneDisarmsThenArmAndDisarmWorkAgain) {
  latch_estop_fault();
  backend_.sample.estop = false;
  run_ticks(10);
  (void)events();

  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kNone);
  const auto seen = events();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].kind, LoopEvent::Kind::kFaultReset);
  EXPECT_EQ(seen[0].fault_cause, controller::FaultCause::kEStop) << "the cause it cleared";
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));

  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(backend_.written.valve_power);
  command(LoopCommand::Kind::kDisarm);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  command(LoopCommand::Kind::kArm);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(backend_.written.valve_power);
}

// Any latched fault, not the e-stop only: here the supervisor's overrun check (10 overrunning
// ticks in a row). An overrun is an event, not a standing condition: a reset clears it at once.
TEST_F(LoopModes, AnyOtherFaultAlsoDrivesTheSafeOutputAndAResetClearsIt) {
  start();
  run_ticks(100);
  for (std::uint32_t i = 0; i < config_.controller.supervisor.overruns_in_a_row; ++i) loop_->note_overrun(true);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kOverrun);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kDisarmed);
}

// A loop that does not settle (the supervisor's settling rules, on the loop's own stop detector):
// the carriage swinging +-30 mm about the set point, a half-swing every 0.2 s, latches the
// oscillation fault at the 4th sign change of the error (0.2 s + the time to pass the 10 mm band
// after each zero: at 0.6 s + 0.0216 s), with the safe output; an event, so a reset clears it.
TEST_F(LoopModes, ACarriageSwingingAboutTheSetPointLatchesAnOscillationFaultThatAResetClears) {
  config_.controller.supervisor.following_error_s = 0.0;
  config_.controller.initial_setpoint_m = 0.0;  // mid-stroke, well inside the soft limits
  backend_.sample.y_m = 0.0;
  start();
  const double y_d = config_.controller.initial_setpoint_m;
  const auto& v = config_.controller.supervisor;
  for (int i = 0; i < 3000 && mode() == Mode::kArmed; ++i) {
    backend_.sample.y_m = y_d - 0.03 * std::sin(6.283185307179586 * 2.5 * static_cast<double>(k_) * 1e-3);
    run_ticks(1);
  }
  ASSERT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kOscillation);
  const double past_band_s = std::asin(v.oscillation_amplitude_m / 0.03) / (6.283185307179586 * 2.5);
  EXPECT_NEAR(now_s(), v.oscillation_sign_changes * 0.2 + past_band_s, 1.5e-3);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
  command(LoopCommand::Kind::kFaultReset);
  EXPECT_EQ(mode(), Mode::kDisarmed) << "a reset clears it: the swing is over once the valves are off";
}

// No rest within the settle time of a set point: the carriage creeps on, its stop detector never
// confirms a stop.
TEST_F(LoopModes, NoRestWithinTheSettleTimeOfASetPointLatchesANotSettledFault) {
  config_.controller.supervisor.following_error_s = 0.0;
  start();
  run_ticks(100);
  command(LoopCommand::Kind::kSetPoint, 0.15);
  const double sent_s = now_s();
  for (int i = 0; i < 5000 && mode() == Mode::kArmed; ++i) {
    backend_.sample.y_m -= 1e-5;  // 10 mm/s, far from the set point's band, never still
    run_ticks(1);
  }
  ASSERT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_->fault_cause(), controller::FaultCause::kNotSettled);
  EXPECT_NEAR(now_s() - sent_s, config_.controller.supervisor.settle_time_s, 1.5e-3);
}

// ---------------------------------------------------------------------------------------------
// Set points from commands

TEST_F(LoopModes, SetPointsAreClampedToTheSoftLimits) {
  start();
  run_ticks(10);
  const double lo = config_.controller.soft_limit_min_m, hi = config_.controller.soft_limit_max_m;
  command(LoopCommand::Kind::kSetPoint, 0.1);
  EXPECT_EQ(setpoint_m(), 0.1);
  command(LoopCommand::Kind::kSetPoint, hi + 0.05);
  EXPECT_EQ(setpoint_m(), hi);
  command(LoopCommand::Kind::kSetPoint, lo - 0.05);
  EXPECT_EQ(setpoint_m(), lo);
  EXPECT_EQ(mode(), Mode::kArmed);
}

TEST_F(LoopModes, SetPointStepsAreClampedToTheSoftLimits) {
  start();
  run_ticks(10);
  const double lo = config_.controller.soft_limit_min_m, hi = config_.controller.soft_limit_max_m;
  command(LoopCommand::Kind::kSetPointStep, -0.1195);
  EXPECT_DOUBLE_EQ(setpoint_m(), 0.1);
  command(LoopCommand::Kind::kSetPointStep, 1.0);  // steps the validator could not foresee
  EXPECT_EQ(setpoint_m(), hi);
  command(LoopCommand::Kind::kSetPointStep, -1.0);
  EXPECT_EQ(setpoint_m(), lo);
}

TEST_F(LoopModes, SetPointsQueuedInAFaultAreDropped) {
  latch_estop_fault();
  const double before = setpoint_m();
  command(LoopCommand::Kind::kSetPoint, 0.1);
  command(LoopCommand::Kind::kSetPointStep, -0.05);
  EXPECT_EQ(setpoint_m(), before);
}

// ---------------------------------------------------------------------------------------------
// The loop's parameters

TEST_F(LoopModes, KeepsItsOwnParametersWhateverBecomesOfTheConfigAndWhenMoved) {
  config_.controller.schedule = {{0.05, 0.170}};
  start();
  // The configuration it was built from changes (or goes): the loop goes on with what it was given.
  config_.controller.schedule = {{0.05, -0.1}};
  config_.controller.soft_limit_max_m = 0.0;
  config_.controller.law.offset_v = -1.0;
  controller::ControlLoop moved(std::move(*loop_));
  loop_.reset();
  for (int i = 0; i < 60; ++i) moved.tick(static_cast<double>(k_++) * config_.controller.period_s());
  EXPECT_EQ(setpoint_m(), 0.170) << "the schedule it was built with";
  send(LoopCommand::Kind::kSetPoint, 0.2);
  moved.tick(static_cast<double>(k_++) * config_.controller.period_s());
  EXPECT_EQ(setpoint_m(), 0.2) << "the soft limits it was built with";
  send(LoopCommand::Kind::kDisarm);
  moved.tick(static_cast<double>(k_++) * config_.controller.period_s());
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff)) << "the u_0 it was built with";
}

TEST_F(LoopModes, ASetPointCommandEndsTheConfiguredSchedule) {
  config_.controller.schedule = {{0.05, 0.170}};
  start();
  run_ticks(10);
  command(LoopCommand::Kind::kSetPoint, 0.1);
  run_ticks(100);  // past the schedule's step at 50 ms
  EXPECT_EQ(setpoint_m(), 0.1);
}

}  // namespace

// The in-position hold (controller.hold): at rest within the window of the set point, the loop
// drives the pressure force, not Eq. 4; it hands back on a set-point change, a reading outside the
// window, a fault or a disarm, each the tick it comes, saying why.
class LoopHold : public LoopModes {
 protected:
  LoopHold() {
    config_.controller.hold.enabled = true;
    backend_.sample.y_m = config_.controller.initial_setpoint_m + 1e-4;  // 0.1 mm off: inside 0.5 mm
  }
  // Starts, holds from the first tick on (the detector starts at rest), drops the hold's start.
  void start_holding() {
    start();
    run_ticks(1);
    ASSERT_EQ(mode(), Mode::kHold);
    const auto e = events();
    ASSERT_EQ(e.size(), 1u);
    ASSERT_EQ(e[0].kind, LoopEvent::Kind::kHoldStart);
  }
  // The hold's end among this tick's events (a jump beyond the window is also a start, which the
  // stop detector reports first).
  void expect_hold_end(controller::HoldEnd why) {
    const auto e = events();
    const auto end = std::find_if(e.begin(), e.end(), [](const LoopEvent& x) { return x.kind == LoopEvent::Kind::kHoldEnd; });
    ASSERT_NE(end, e.end());
    EXPECT_EQ(std::count_if(e.begin(), e.end(), [](const LoopEvent& x) { return x.kind == LoopEvent::Kind::kHoldEnd; }), 1);
    EXPECT_EQ(end->hold_end, why) << controller::hold_end_name(end->hold_end);
    EXPECT_DOUBLE_EQ(end->t_s, now_s());
  }
};

TEST_F(LoopHold, IsOffUnlessEnabled) {
  config_.controller.hold.enabled = false;
  start();
  run_ticks(100);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(events().empty());
}

// Issue 31: hold on / hold off from a command (the dashboard's), for the rest of the run.
TEST_F(LoopHold, AHoldOffCommandEndsItThatTickSayingOffAndItIsNotTakenAgainUntilAHoldOn) {
  start_holding();
  run_ticks(10);
  command(LoopCommand::Kind::kHoldOff);
  EXPECT_EQ(mode(), Mode::kArmed);
  expect_hold_end(controller::HoldEnd::kOff);
  EXPECT_STREQ(controller::hold_end_name(controller::HoldEnd::kOff), "off");
  run_ticks(100);
  EXPECT_EQ(mode(), Mode::kArmed) << "still at rest within the window, but not allowed";
  EXPECT_TRUE(events().empty());
  command(LoopCommand::Kind::kHoldOn);
  EXPECT_EQ(mode(), Mode::kHold) << "allowed again: taken the tick the command is applied";
}

TEST_F(LoopHold, AHoldOnCommandAllowsItWhenTheConfigurationHasItOff) {
  config_.controller.hold.enabled = false;
  start();
  run_ticks(10);
  EXPECT_EQ(mode(), Mode::kArmed);
  command(LoopCommand::Kind::kHoldOn);
  EXPECT_EQ(mode(), Mode::kHold);
}

TEST_F(LoopHold, NotWithinTheWindowTheLawKeepsDriving) {
  backend_.sample.y_m = config_.controller.initial_setpoint_m + 1e-3;  // 1 mm off
  start();
  run_ticks(100);
  EXPECT_EQ(mode(), Mode::kArmed);
}

TEST_F(LoopHold, DrivesTheMeasuredForceTowardsTheMiddleOfTheStictionBandWithPowerOn) {
  start_holding();
  // The sample's pressures hold F = 1.8 N, above the band's middle (45 - 50) / 2 = -2.5 N: the
  // integral term lowers u tick after tick, the law's u* notwithstanding.
  const double u_first = backend_.written.u_p_v;
  run_ticks(200);
  EXPECT_EQ(mode(), Mode::kHold);
  EXPECT_TRUE(backend_.written.valve_power);
  EXPECT_LT(backend_.written.u_p_v, u_first - 0.01);
  EXPECT_EQ(backend_.written.u_n_v, -backend_.written.u_p_v);
}

TEST_F(LoopHold, ASetPointCommandEndsItTheTickItIsApplied) {
  start_holding();
  run_ticks(10);
  command(LoopCommand::Kind::kSetPoint, 0.2);
  EXPECT_EQ(mode(), Mode::kArmed);
  expect_hold_end(controller::HoldEnd::kSetPoint);
}

TEST_F(LoopHold, AReadingOutsideTheWindowEndsItThatTick) {
  start_holding();
  run_ticks(10);
  backend_.sample.y_m = config_.controller.initial_setpoint_m + 6e-4;  // pushed beyond 0.5 mm
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kArmed);
  expect_hold_end(controller::HoldEnd::kLeftWindow);
}

TEST_F(LoopHold, AtTheWindowsEdgeReadingsWithinTheRestBandBeyondItDoNotEndIt) {
  // hil.yaml's sensors: a rest band of 20 um spans the noise and the ADC's steps at rest. Held at
  // 0.495 mm, readings flicker to 0.505 and 0.51 mm: the same rest, still held; a reading 0.525 mm
  // off (beyond the band) has left the window.
  config_.controller.stop_detector.rest_band_m = 2.0e-5;
  config_.controller.stop_detector.motion_band_m = 4.0e-5;
  const double y_d = config_.controller.initial_setpoint_m;
  backend_.sample.y_m = y_d + 4.95e-4;
  start_holding();
  for (const double off : {5.05e-4, 4.95e-4, 5.1e-4, 4.95e-4, 5.05e-4}) {
    backend_.sample.y_m = y_d + off;
    run_ticks(1);
    EXPECT_EQ(mode(), Mode::kHold) << off;
    EXPECT_TRUE(events().empty()) << off;
  }
  backend_.sample.y_m = y_d + 5.25e-4;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kArmed);
  expect_hold_end(controller::HoldEnd::kLeftWindow);
}

TEST_F(LoopHold, AFaultEndsItBeforeTheFaultLatches) {
  start_holding();
  backend_.sample.estop = true;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  const auto e = events();
  ASSERT_EQ(e.size(), 2u);
  EXPECT_EQ(e[0].kind, LoopEvent::Kind::kHoldEnd);
  EXPECT_EQ(e[0].hold_end, controller::HoldEnd::kFault);
  EXPECT_EQ(e[1].kind, LoopEvent::Kind::kFault);
  EXPECT_FALSE(backend_.written.valve_power);
}

TEST_F(LoopHold, ADisarmEndsItAndDisarms) {
  start_holding();
  command(LoopCommand::Kind::kDisarm);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  expect_hold_end(controller::HoldEnd::kDisarmed);
  EXPECT_THAT(backend_.written, IsCommand(kNeutralPowerOff));
}

// Reaching the window (controller.hold.reach_m): stuck outside the window but within reach, the
// loop ramps the measured force towards the set point until the carriage moves, then Eq. 4 again.
TEST_F(LoopHold, StuckOutsideTheWindowButWithinReachItRampsTheForceTowardsTheSetPointUntilItMoves) {
  config_.controller.hold.reach_m = 0.005;
  backend_.sample.y_m = config_.controller.initial_setpoint_m + 2e-3;  // 2 mm beyond: reach towards -
  start();
  run_ticks(1);
  ASSERT_EQ(mode(), Mode::kHold);
  auto e = events();
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].kind, LoopEvent::Kind::kHoldStart);
  EXPECT_EQ(e[0].direction, -1);
  // The force read does not follow (a fake bench): the reference running away below it pulls u
  // down, tick after tick.
  const double u_first = backend_.written.u_p_v;
  run_ticks(50);
  EXPECT_LT(backend_.written.u_p_v, u_first - 0.05);
  EXPECT_EQ(mode(), Mode::kHold);
  // It moves (beyond the stop detector's motion band): Eq. 4 drives again.
  backend_.sample.y_m -= 1e-4;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kArmed);
  expect_hold_end(controller::HoldEnd::kMoved);
}

TEST_F(LoopHold, BeyondReachTheLawKeepsDriving) {
  config_.controller.hold.reach_m = 0.005;
  backend_.sample.y_m = config_.controller.initial_setpoint_m + 6e-3;
  start();
  run_ticks(100);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(events().empty());
}
