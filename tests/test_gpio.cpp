// Specification of the digital lines (pneu_hal_gpio): the libgpiod adapter, the GpioBackend
// decorator, and the e-stop and valve power seen through a real ControlLoop on the simulated bench.
//
// The adapter needs a GPIO chip. Lines of a real chip are never driven from a test (they may be
// wired to something); the adapter is exercised on a simulated chip (gpio-sim or gpio-mockup) when
// one exists, and skipped, saying why, otherwise. Everything above the adapter runs everywhere
// through FakeLines, a GpioLines test double.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/hal/gpio_backend.hpp"
#include "pneu/hal/gpio_lines.hpp"
#include "pneu/hal/sim_backend.hpp"

namespace {

using namespace pneu;
using controller::LoopCommand;
using controller::Mode;
using hal::Status;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// The libgpiod adapter

// Lines on the real loop thread can't throw, so these fail the build, not the run.
static_assert(noexcept(std::declval<hal::GpioLines&>().read_estop(std::declval<bool&>())));
static_assert(noexcept(std::declval<hal::GpioLines&>().set_valve_power(true)));

bool any_gpio_chip() {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/dev", ec))
    if (e.path().filename().string().starts_with("gpiochip")) return true;
  return false;
}

std::string message_of_construction(const hal::GpioConfig& params) {
  try {
    hal::LibgpiodLines lines(params);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(constructed without error)";
}

TEST(LibgpiodLines, ConstructingOnAMissingChipThrowsNamingTheChipAndItsKey) {
  hal::GpioConfig params;
  params.chip = "pneu-test-no-such-chip";
  const std::string message = message_of_construction(params);
  EXPECT_THAT(message, HasSubstr("'pneu-test-no-such-chip'"));
  EXPECT_THAT(message, HasSubstr("hal.gpio.chip"));
  EXPECT_THAT(message, HasSubstr("gpiodetect"));
}

TEST(LibgpiodLines, RefusesOneLineForBothTheEStopAndValvePowerBeforeTouchingTheChip) {
  hal::GpioConfig params;
  // Refused before the chip is looked up: the same message on any machine.
  params.chip = "pneu-test-no-such-chip";
  params.estop_line = 3;
  params.valve_power_line = 3;
  const std::string message = message_of_construction(params);
  EXPECT_THAT(message, HasSubstr("line 3"));
  EXPECT_THAT(message, HasSubstr("hal.gpio.valve_power_line"));
}

TEST(LibgpiodLines, RefusesAnEmptyChipName) {
  hal::GpioConfig params;
  params.chip.clear();
  EXPECT_THAT(message_of_construction(params), HasSubstr("no GPIO chip given (hal.gpio.chip)"));
}

// A simulated chip whose lines the test pulls and observes from outside: gpio-sim (sysfs
// .../gpio-sim.N/gpiochipM/sim_gpioK/{pull,value}) or gpio-mockup (debugfs .../gpiochipM/K).
struct SimulatedChip {
  std::string name;  // gpiochipM
  fs::path dir;
  bool gpio_sim = true;

  void pull(unsigned line, bool high) const {
    std::ofstream f(gpio_sim ? dir / ("sim_gpio" + std::to_string(line)) / "pull"
                             : dir / std::to_string(line));
    f << (gpio_sim ? (high ? "pull-up" : "pull-down") : (high ? "1" : "0"));
    f.close();
    if (!f) throw std::runtime_error("cannot pull line " + std::to_string(line) + " of " + name);
  }
  [[nodiscard]] bool level(unsigned line) const {
    std::ifstream f(gpio_sim ? dir / ("sim_gpio" + std::to_string(line)) / "value"
                             : dir / std::to_string(line));
    int v = -1;
    f >> v;
    if (v != 0 && v != 1)
      throw std::runtime_error("cannot read line " + std::to_string(line) + " of " + name);
    return v == 1;
  }
};

// The first simulated chip with at least two lines.
std::optional<SimulatedChip> find_simulated_chip() {
  std::error_code ec;
  for (const auto& dev : fs::directory_iterator("/sys/devices/platform", ec)) {
    if (!dev.path().filename().string().starts_with("gpio-sim.")) continue;
    for (const auto& chip : fs::directory_iterator(dev.path(), ec))
      if (chip.path().filename().string().starts_with("gpiochip") &&
          fs::exists(chip.path() / "sim_gpio1" / "pull"))
        return SimulatedChip{chip.path().filename().string(), chip.path(), true};
  }
  for (const auto& chip : fs::directory_iterator("/sys/kernel/debug/gpio-mockup", ec))
    if (fs::exists(chip.path() / "1"))
      return SimulatedChip{chip.path().filename().string(), chip.path(), false};
  return std::nullopt;
}

class LibgpiodLinesOnASimulatedChip : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!any_gpio_chip())
      GTEST_SKIP() << "no GPIO chip on this machine (/dev/gpiochip* absent): the libgpiod adapter "
                      "is not exercised; the logic above it is tested through GpioLines";
    chip_ = find_simulated_chip();
    if (!chip_)
      GTEST_SKIP() << "GPIO chips exist but none is simulated (gpio-sim, gpio-mockup): a test "
                      "does not drive the lines of a real chip; the adapter is not exercised";
  }
  [[nodiscard]] hal::GpioConfig params(bool active_low) const {
    return {true, chip_->name, 0, active_low, 1, active_low, "pneu-test"};
  }
  std::optional<SimulatedChip> chip_;
};

TEST_F(LibgpiodLinesOnASimulatedChip, ReadsTheEStopLevelAndDrivesValvePowerActiveHigh) {
  hal::LibgpiodLines lines(params(false));
  EXPECT_FALSE(chip_->level(1)) << "valve power must start off";
  bool active = false;
  chip_->pull(0, true);
  ASSERT_EQ(lines.read_estop(active), Status::kOk);
  EXPECT_TRUE(active);
  chip_->pull(0, false);
  ASSERT_EQ(lines.read_estop(active), Status::kOk);
  EXPECT_FALSE(active);
  ASSERT_EQ(lines.set_valve_power(true), Status::kOk);
  EXPECT_TRUE(chip_->level(1));
  ASSERT_EQ(lines.set_valve_power(false), Status::kOk);
  EXPECT_FALSE(chip_->level(1));
}

TEST_F(LibgpiodLinesOnASimulatedChip, ActiveLowLinesInvertTheElectricalLevel) {
  hal::LibgpiodLines lines(params(true));
  EXPECT_TRUE(chip_->level(1)) << "valve power off is a high level on an active-low line";
  bool active = false;
  chip_->pull(0, false);
  ASSERT_EQ(lines.read_estop(active), Status::kOk);
  EXPECT_TRUE(active);
  chip_->pull(0, true);
  ASSERT_EQ(lines.read_estop(active), Status::kOk);
  EXPECT_FALSE(active);
  ASSERT_EQ(lines.set_valve_power(true), Status::kOk);
  EXPECT_FALSE(chip_->level(1));
}

TEST_F(LibgpiodLinesOnASimulatedChip, ALineHeldByAnotherConsumerIsRefusedNamingIt) {
  hal::LibgpiodLines first(params(false));
  const std::string message = message_of_construction(params(false));
  EXPECT_THAT(message, HasSubstr("line 0 of GPIO chip '" + chip_->name + "'"));
  EXPECT_THAT(message, HasSubstr("hal.gpio.estop_line"));
}

TEST_F(LibgpiodLinesOnASimulatedChip, DestructionSwitchesValvePowerOffBeforeReleasing) {
  {
    hal::LibgpiodLines lines(params(false));
    ASSERT_EQ(lines.set_valve_power(true), Status::kOk);
    ASSERT_TRUE(chip_->level(1));
  }
  EXPECT_FALSE(chip_->level(1));
}

// ---------------------------------------------------------------------------------------------
// GpioBackend through the interface

// The e-stop switch and the valve power relay, as a test sets and sees them.
class FakeLines final : public hal::GpioLines {
 public:
  bool estop_pressed = false;
  bool reads_fail = false;  ///< read_estop fails and, misbehaving, leaves `active` false
  bool valve_power = true;  ///< starts on, so that switching it off is observable
  int power_writes = 0;

  Status read_estop(bool& active) noexcept override {
    if (reads_fail) {
      active = false;  // GpioBackend must not trust the flag of a failed read
      return Status::kDeviceError;
    }
    active = estop_pressed;
    return Status::kOk;
  }
  Status set_valve_power(bool on) noexcept override {
    valve_power = on;
    ++power_writes;
    return Status::kOk;
  }
};

// The default bench (embedded config/sim.yaml) with u_0 resolved.
struct Bench {
  assembly::RunSpec spec = assembly::RunSpec::of(config::load_string(config::default_config_yaml()));
  const config::Config& config = spec.config();
  [[nodiscard]] double u_0() const { return spec.u_0_v(); }
};

// The in-process plant at rest at the configured start, at equilibrium for u_0.
std::unique_ptr<hal::SimBackend> make_sim(const Bench& b) {
  return std::make_unique<hal::SimBackend>(b.config.plant, b.config.sensors,
                                           b.config.simulation.initial_position_m, b.u_0());
}

// The decorator around the simulated bench, with fake lines, opened.
class GpioBackend : public ::testing::Test {
 protected:
  GpioBackend() { backend.open(0.0); }

  Bench b;
  std::unique_ptr<hal::SimBackend> sim = make_sim(b);
  FakeLines lines;
  hal::GpioBackend backend{*sim, lines};
};

TEST_F(GpioBackend, OpenSwitchesValvePowerOff) {
  EXPECT_FALSE(lines.valve_power);
}

TEST_F(GpioBackend, AddsTheEStopLineToTheInnerFrame) {
  hal::SensorFrame frame;
  ASSERT_EQ(backend.read(0.001, frame), Status::kOk);
  EXPECT_FALSE(frame.estop);
  EXPECT_DOUBLE_EQ(frame.y_m, b.config.simulation.initial_position_m);  // the inner frame, kept

  lines.estop_pressed = true;
  ASSERT_EQ(backend.read(0.002, frame), Status::kOk);
  EXPECT_TRUE(frame.estop);
  EXPECT_DOUBLE_EQ(frame.y_m, b.config.simulation.initial_position_m);
}

TEST_F(GpioBackend, AFailedEStopReadCountsAsPressedAndReportsADeviceError) {
  lines.reads_fail = true;
  hal::SensorFrame frame;
  EXPECT_EQ(backend.read(0.001, frame), Status::kDeviceError);
  EXPECT_TRUE(frame.estop);
}

TEST_F(GpioBackend, DrivesValvePowerFromTheCommandAndForwardsTheVoltages) {
  hal::SensorFrame frame;
  ASSERT_EQ(backend.read(0.001, frame), Status::kOk);

  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(1.25, true)), Status::kOk);
  EXPECT_TRUE(lines.valve_power);
  EXPECT_EQ(sim->held_command().u_p_v, 1.25);
  EXPECT_EQ(sim->held_command().u_n_v, -1.25);
  EXPECT_TRUE(sim->held_command().valve_power);

  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(-0.5, false)), Status::kOk);
  EXPECT_FALSE(lines.valve_power);
  EXPECT_EQ(sim->held_command().u_p_v, -0.5);
  EXPECT_FALSE(sim->held_command().valve_power);
}

TEST_F(GpioBackend, ForcesValvePowerOffWhileTheEStopReadsPressed) {
  hal::SensorFrame frame;
  lines.estop_pressed = true;
  ASSERT_EQ(backend.read(0.001, frame), Status::kOk);
  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(1.0, true)), Status::kOk);
  EXPECT_FALSE(lines.valve_power);
  EXPECT_FALSE(sim->held_command().valve_power);  // the inner backend sees the power as driven

  lines.estop_pressed = false;  // released: the next read lifts the force
  ASSERT_EQ(backend.read(0.002, frame), Status::kOk);
  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(1.0, true)), Status::kOk);
  EXPECT_TRUE(lines.valve_power);
}

TEST_F(GpioBackend, KeepsValvePowerOffUntilTheFirstEStopReadAfterOpen) {
  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(1.0, true)), Status::kOk);
  EXPECT_FALSE(lines.valve_power);
}

TEST_F(GpioBackend, CloseSwitchesValvePowerOff) {
  hal::SensorFrame frame;
  ASSERT_EQ(backend.read(0.001, frame), Status::kOk);
  ASSERT_EQ(backend.write(hal::ActuatorCommand::from_control(1.0, true)), Status::kOk);
  ASSERT_TRUE(lines.valve_power);
  backend.close();
  EXPECT_FALSE(lines.valve_power);
}

TEST_F(GpioBackend, ReportsNoLinkAroundTheInProcessPlant) { EXPECT_FALSE(backend.link_report()); }

// A backend with a link to a device, as the modbus backend has, for what the decorator passes on.
class LinkedBackend final : public hal::Backend {
 public:
  void open(double) override {}
  void close() noexcept override {}
  [[nodiscard]] Status read(double t_s, hal::SensorFrame& frame) noexcept override {
    frame = hal::SensorFrame{};
    frame.t_s = t_s;
    return Status::kOk;
  }
  [[nodiscard]] Status write(const hal::ActuatorCommand&) noexcept override { return Status::kOk; }
  [[nodiscard]] std::optional<hal::LinkReport> link_report() const override {
    hal::LinkReport r;
    r.transactions = 42;
    r.last_error = "timeout";
    r.safe_output_attempts = 1;
    r.safe_output_delivered = true;
    return r;
  }
};

TEST(GpioBackendAroundADevice, ReportsTheDevicesLink) {
  LinkedBackend device;
  FakeLines lines;
  const hal::GpioBackend backend(device, lines);
  const std::optional<hal::LinkReport> link = backend.link_report();
  ASSERT_TRUE(link) << "the summary's modbus figures come through the decorator";
  EXPECT_EQ(link->transactions, 42u);
  EXPECT_EQ(link->last_error, "timeout");
  EXPECT_TRUE(link->safe_output_delivered);
}

// ---------------------------------------------------------------------------------------------
// The e-stop and valve power lines through a real ControlLoop: the default paper run (set point
// 219.5 mm -> 170 mm at t = 1 s), armed at start, on the simulated bench wrapped by GpioBackend
// with FakeLines. The loop's modes themselves (the fault latched and reported once, resets refused
// while the cause stays, arm and disarm) are specified without GPIO in tests/test_loop_modes.cpp.

class EStopLoop : public ::testing::Test {
 protected:
  EStopLoop()
      : sim_(make_sim(bench_)),
        backend_(*sim_, lines_),
        outputs_(std::make_unique<controller::LoopOutputs>()),
        loop_(controller::LoopParams::from(bench_.config, bench_.spec.law()),
              backend_, *outputs_) {
    loop_.start(0.0);
  }

  // `n` ticks at the configured period, continuing from the last one.
  void run_ticks(int n) {
    for (int i = 0; i < n; ++i) {
      loop_.tick(static_cast<double>(k_++) * bench_.config.controller.period_s());
      controller::TickRecord r;
      while (outputs_->ticks.try_pop(r)) last_u_v_ = r.u_v;
    }
  }
  void send(LoopCommand::Kind kind) {
    ASSERT_TRUE(outputs_->commands.try_push(LoopCommand{kind, 0.0, ++seq_}));
  }
  [[nodiscard]] Mode mode() const { return loop_.mode(); }
  // Mid-run: 1.2 s, 0.2 s after the set-point step, the carriage on its way to 170 mm, armed.
  void run_to_mid_run() {
    run_ticks(1200);
    ASSERT_EQ(mode(), Mode::kArmed);
    ASSERT_TRUE(lines_.valve_power);
    ASSERT_NE(last_u_v_, bench_.u_0()) << "the law must be driving, not holding u_0";
  }

  Bench bench_;
  std::unique_ptr<hal::SimBackend> sim_;
  FakeLines lines_;
  hal::GpioBackend backend_;
  std::unique_ptr<controller::LoopOutputs> outputs_;  // large queues: on the heap
  controller::ControlLoop loop_;
  std::int64_t k_ = 0;
  std::uint64_t seq_ = 0;
  double last_u_v_ = 0.0;
};

TEST_F(EStopLoop, PressingTheEStopFaultsWithinOneTickCutsValvePowerAndHoldsNeutral) {
  run_to_mid_run();
  lines_.estop_pressed = true;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_FALSE(lines_.valve_power);
  EXPECT_EQ(sim_->held_command().u_p_v, bench_.u_0());  // u_0 is copied, not computed: exact
  EXPECT_EQ(sim_->held_command().u_n_v, -bench_.u_0());
  EXPECT_EQ(last_u_v_, bench_.u_0());
}

TEST_F(EStopLoop, AfterReleaseAResetDisarmsAndValvePowerFollowsTheArmedState) {
  run_to_mid_run();
  lines_.estop_pressed = true;
  run_ticks(10);
  lines_.estop_pressed = false;
  run_ticks(10);
  ASSERT_EQ(mode(), Mode::kFault);

  send(LoopCommand::Kind::kFaultReset);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_FALSE(lines_.valve_power);
  EXPECT_EQ(sim_->held_command().u_p_v, bench_.u_0());

  send(LoopCommand::Kind::kArm);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(lines_.valve_power);

  send(LoopCommand::Kind::kDisarm);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kDisarmed);
  EXPECT_FALSE(lines_.valve_power);

  send(LoopCommand::Kind::kArm);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kArmed);
  EXPECT_TRUE(lines_.valve_power);
}

// Any latched fault, not the e-stop only: here the supervisor's overrun check (10 overrunning
// ticks in a row) cuts valve power through the line and holds the neutral safe output.
TEST_F(EStopLoop, AnyOtherFaultAlsoCutsValvePowerThroughTheLine) {
  run_to_mid_run();
  for (int i = 0; i < 10; ++i) loop_.note_overrun(true);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_EQ(loop_.fault_cause(), controller::FaultCause::kOverrun);
  EXPECT_FALSE(lines_.valve_power);
  EXPECT_EQ(last_u_v_, bench_.u_0()) << "safe_output: neutral";
}

TEST_F(EStopLoop, AFailedEStopReadLatchesTheFault) {
  run_to_mid_run();
  lines_.reads_fail = true;
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kFault);
  EXPECT_FALSE(lines_.valve_power);
  EXPECT_EQ(sim_->held_command().u_p_v, bench_.u_0());

  lines_.reads_fail = false;  // the line reads again, released: still latched until a reset
  run_ticks(10);
  EXPECT_EQ(mode(), Mode::kFault);
  send(LoopCommand::Kind::kFaultReset);
  run_ticks(1);
  EXPECT_EQ(mode(), Mode::kDisarmed);
}

}  // namespace
