// The movement test at the first ARM, over Modbus and LCM: pneu-plant serve plays the bench (as it
// should be, or with its tubes swapped), pneud starts disarmed on it as config/bench.yaml has it,
// and pneu-command arms it; inside a private network namespace (tests/in_private_netns.sh). The
// movement test at start-up (pneud starting armed): test_hil.cpp, HilMovementTest.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <cstdint>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/lcm_sniffer.hpp"

namespace {

using pneu::test::bin;
using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using pneu::test::Child;
using pneu::test::Csv;
using pneu::test::slurp;
using ::testing::HasSubstr;
using ::testing::Not;
using namespace std::chrono_literals;


class HilMovementTestAtArm : public ::testing::Test {
 protected:
  void SetUp() override { port_ = pneu::test::free_port(); }

  // pneu-plant serve on the port, with `faults` (serve --fault ...).
  Child serve(const std::vector<std::string>& faults) {
    std::vector<std::string> args{bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set",
                                  "hal.modbus.port=" + std::to_string(port_), "--duration", "60"};
    args.insert(args.end(), faults.begin(), faults.end());
    Child c = Child::spawn(args, dir_ / "serve.out", dir_ / "serve.err");
    EXPECT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "listening on", 10s)) << slurp(dir_ / "serve.err");
    return c;
  }
  // pneud on it until SIGTERM, started disarmed with no schedule; returned once its state is heard
  // (its loop ticking).
  Child start_disarmed_pneud() {
    pneu::test::LcmSniffer sniffer;
    EXPECT_TRUE(sniffer.good());
    std::vector<std::string> args{bin("pneud"), "--config", hil_yaml(), "--duration", "0", "--require-telemetry",
                                  "--set", "hal.modbus.port=" + std::to_string(port_), "--set",
                                  "controller.start_armed=false", "--set", "controller.setpoints.schedule=[]",
                                  // hil.yaml's in-position hold off: the modes judged are the ARM's
                                  // (the hold's own are its tests')
                                  "--set", "controller.hold.enabled=false",
                                  "--events", events().string(), "--trajectory", trajectory().string()};
    Child pneud = Child::spawn(pneu::test::loop_timing_faults_off(pneu::test::link_stalls_tolerated(args)),
                               dir_ / "pneud.out", dir_ / "pneud.err");
    std::string channel;
    std::vector<std::uint8_t> payload;
    EXPECT_TRUE(pneu::test::eventually(
        [&] { return sniffer.receive(channel, payload, 100) && channel == "PNEU_STATE"; }, 10s, 1ms))
        << "pneud up, its loop ticking: " << err();
    return pneud;
  }
  // pneu-command with `args`: its exit code, and what it printed on stdout then stderr.
  std::pair<int, std::string> command(const std::vector<std::string>& args) {
    const std::string tag = "command" + std::to_string(++commands_);
    std::vector<std::string> argv{bin("pneu-command"), "--seq", std::to_string(commands_ + 10), "--timeout-s", "10"};
    argv.insert(argv.end(), args.begin(), args.end());
    Child c = Child::spawn(argv, dir_ / (tag + ".out"), dir_ / (tag + ".err"));
    const int code = c.wait();
    return {code, slurp(dir_ / (tag + ".out")) + slurp(dir_ / (tag + ".err"))};
  }
  // Whether pneud's stderr holds `text` within `limit`.
  bool said(const std::string& text, std::chrono::milliseconds limit = 10s) {
    return pneu::test::wait_for_text(dir_ / "pneud.err", text, limit);
  }
  // The modes of the trajectory's ticks, each run of one mode once ("0412": disarmed, the movement
  // test, armed, fault).
  std::string modes() const {
    const Csv t = Csv::read(trajectory());
    const std::size_t c = t.col("mode");
    std::string m;
    for (const auto& row : t.rows)
      if (m.empty() || m.back() != row[c][0]) m += row[c][0];
    return m;
  }
  std::string err() const { return slurp(dir_ / "pneud.err"); }
  fs::path events() const { return dir_ / "events.jsonl"; }
  fs::path trajectory() const { return dir_ / "traj.csv"; }

  pneu::test::TestDir dir_{"pneu_hil_arm_"};
  int port_ = 0;
  int commands_ = 0;
};

TEST_F(HilMovementTestAtArm, SwappedTubesLatchAMovementTestFaultAtTheFirstArmNamingThemAndNoClosedLoopRuns) {
  Child plant = serve({"--fault", "tubes:swapped@0"});
  Child pneud = start_disarmed_pneud();
  ASSERT_FALSE(HasFailure());

  const auto arm = command({"arm"});
  EXPECT_EQ(arm.first, 0) << arm.second;
  ASSERT_TRUE(said("<3>pneud: FAULT at ")) << err();
  EXPECT_THAT(err(), HasSubstr("pneud: movement test: at the first ARM (controller.start_armed: false)"));
  EXPECT_THAT(err(), HasSubstr(": movement-test: "));
  EXPECT_THAT(err(), HasSubstr("tubes-swapped: tubes swapped: +u moved the carriage towards -y"));
  EXPECT_THAT(err(), Not(HasSubstr("movement test passed")));
  const auto set_point = command({"set-point", "0.2145"});
  EXPECT_EQ(set_point.first, 3) << "refused: " << set_point.second;
  EXPECT_THAT(set_point.second, HasSubstr("a fault is latched"));

  kill(pneud.pid, SIGTERM);
  EXPECT_EQ(pneud.wait(), 3) << "it ends with the fault latched: " << err();
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  EXPECT_EQ(modes(), "042") << "disarmed, the movement test, the fault: never armed in closed loop";
  EXPECT_THAT(slurp(events()), HasSubstr("\"cause\":\"movement-test\""));
  EXPECT_THAT(slurp(events()), HasSubstr("\"finding\":\"tubes-swapped\""));
}

TEST_F(HilMovementTestAtArm, ACorrectBenchPassesAtTheFirstArmThenHoldsAndTakesASetPointAndALaterArmSkipsIt) {
  Child plant = serve({});
  Child pneud = start_disarmed_pneud();
  ASSERT_FALSE(HasFailure());

  const auto arm = command({"arm"});
  EXPECT_EQ(arm.first, 0) << arm.second;
  ASSERT_TRUE(said("<5>pneud: movement test passed at ")) << err();
  EXPECT_THAT(err(), Not(HasSubstr("FAULT")));
  const auto set_point = command({"set-point", "0.2145"});
  EXPECT_EQ(set_point.first, 0) << set_point.second;
  std::this_thread::sleep_for(1500ms);  // the move
  // Once passed in this run, a later ARM arms at once: the wiring does not change while pneud runs.
  EXPECT_EQ(command({"disarm"}).first, 0);
  EXPECT_EQ(command({"arm"}).first, 0);
  std::this_thread::sleep_for(300ms);

  kill(pneud.pid, SIGTERM);
  EXPECT_EQ(pneud.wait(), 0) << err();
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  EXPECT_EQ(modes(), "04101") << "disarmed, the movement test, armed, disarmed, armed again without it";
  // The last tick armed before the disarm: the set point taken, and reached.
  const Csv t = Csv::read(trajectory());
  const std::size_t c_mode = t.col("mode");
  std::size_t last_armed = 0;
  for (std::size_t i = 1; i < t.rows.size() && !(t.rows[i][c_mode] == "0" && t.rows[i - 1][c_mode] == "1"); ++i)
    last_armed = i;
  EXPECT_NEAR(std::stod(t.rows[last_armed][t.col("y_d")]), 0.2145, 1e-9) << "the set point taken";
  EXPECT_NEAR(std::stod(t.rows[last_armed][t.col("y")]), 0.2145, 0.003) << "and reached";
  EXPECT_THAT(slurp(events()), HasSubstr("{\"event\":\"movement_test\","));
}

}  // namespace
