// The module watchdog of `pneu-plant serve` (issue 29), as an I/O coupler's fieldbus watchdog: when
// the owner of the valve registers falls silent, the outputs go to the configured safe values and
// the registers are free; and serve's own record (--events) of what it held, when. Judged on
// serve's record, on its own clock. Real time: about 10 s; one bound is real time by the issue's
// demand (150 ms from pneud's last request to the safe outputs, with a 100 ms watchdog).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/hil_modbus_client.hpp"
#include "support/json.hpp"

namespace {

using pneu::test::bin;
using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::test::Child;
using pneu::test::free_port;
using pneu::test::Json;
using pneu::test::slurp;
using ::testing::HasSubstr;


constexpr int kValveP = pneu::test::kHilValveP;
using pneu::test::hil_valve_word;

using Client = pneu::test::HilModbusClient;

class ServeWatchdog : public ::testing::Test {
 protected:
  void SetUp() override { port_ = free_port(); }
  Child serve(const std::vector<std::string>& extra) {
    std::vector<std::string> args{bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set",
                                  "hal.modbus.port=" + std::to_string(port_), "--duration", "30", "--events",
                                  events().string()};
    args.insert(args.end(), extra.begin(), extra.end());
    Child c = Child::spawn(args, dir_ / "serve.out", dir_ / "serve.err");
    EXPECT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "listening", 3s)) << slurp(dir_ / "serve.err");
    return c;
  }
  [[nodiscard]] fs::path events() const { return dir_ / "serve.jsonl"; }
  // serve's record, line by line (a line being written is left out).
  [[nodiscard]] std::vector<Json> record() const {
    std::vector<Json> lines;
    std::istringstream in(slurp(events()));
    for (std::string line; std::getline(in, line);) {
      try {
        lines.push_back(Json::parse(line));
      } catch (const std::exception&) {
      }
    }
    return lines;
  }
  [[nodiscard]] std::vector<Json> of_kind(const std::string& kind) const {
    std::vector<Json> out;
    for (auto& e : record())
      if (e["event"].text() == kind) out.push_back(e);
    return out;
  }
  pneu::test::TestDir dir_{"pneu_serve_watchdog_"};
  int port_ = 0;
};

TEST_F(ServeWatchdog, AfterASigkillOfPneudServesRecordShowsTheSafeOutputsWithin150MsOfItsLastRequest) {
  Child plant = serve({"--watchdog-s", "0.1", "--watchdog-outputs", "exhaust"});
  std::vector<std::string> args{bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                                "--set", "telemetry.enabled=false", "--duration", "0"};
  Child pneud = Child::spawn(pneu::test::loop_timing_faults_off(pneu::test::link_stalls_tolerated(std::move(args))),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "writes the valve registers", 5s)) << slurp(dir_ / "pneud.err");
  std::this_thread::sleep_for(1s);
  ASSERT_TRUE(of_kind("watchdog").empty()) << "pneud's requests keep the watchdog fed while it runs";
  kill(pneud.pid, SIGKILL);
  EXPECT_EQ(pneud.wait(), 128 + SIGKILL);
  ASSERT_TRUE(pneu::test::eventually([&] { return !of_kind("watchdog").empty(); }, 3s)) << slurp(events());

  const Json trip = of_kind("watchdog").front();
  const double silent_s = trip["monotonic_s"].number() - trip["last_request_monotonic_s"].number();
  std::printf("the watchdog tripped %.1f ms after pneud's last request\n", silent_s * 1e3);
  EXPECT_GE(silent_s, 0.1) << "not before the watchdog's time";
  EXPECT_LE(silent_s, 0.15) << "the safe outputs within 150 ms of pneud's last request (serve's clock)";
  EXPECT_NEAR(trip["u_p"].number(), -10.0, 1e-3);
  EXPECT_NEAR(trip["u_n"].number(), -10.0, 1e-3);
  // The outputs it holds from then on, in the same record: the watchdog's, at its time.
  bool held = false;
  for (const Json& o : of_kind("outputs"))
    if (o["cause"].text() == "watchdog") {
      held = true;
      EXPECT_EQ(o["t"].number(), trip["t"].number());
      EXPECT_NEAR(o["u_p"].number(), -10.0, 1e-3);
      EXPECT_NEAR(o["u_n"].number(), -10.0, 1e-3);
    }
  EXPECT_TRUE(held) << slurp(events());
  // pneud's drive before: other outputs than the watchdog's (not vacuous).
  bool drove = false;
  for (const Json& o : of_kind("outputs")) drove = drove || (o["cause"].text() == "write" && o["u_p"].number() > -9.0);
  EXPECT_TRUE(drove);
  const auto disconnects = of_kind("disconnect");
  ASSERT_FALSE(disconnects.empty()) << "the kernel closed the killed pneud's connection";
  EXPECT_LE(disconnects.back()["t"].number(), trip["t"].number());
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("watchdog: no request from client"));
}

TEST_F(ServeWatchdog, AClientThatVanishedWithoutClosingLosesTheValvesToTheWatchdogAndAnotherTakesThem) {
  Child plant = serve({"--watchdog-s", "1", "--outputs", (dir_ / "outputs.csv").string()});
  Client first(port_, 1.0), second(port_, 1.0);
  ASSERT_TRUE(first.connected() && second.connected());
  ASSERT_EQ(first.write_valves(2.0, -2.0), 0);
  EXPECT_EQ(second.write_valves(3.0, -3.0), EMBXSBUSY) << "the first writer owns the valves";
  // Its reads feed the watchdog: 2 s of a request every 0.2 s, no trip.
  for (int i = 0; i < 10; ++i) {
    (void)first.read(0, 3);
    std::this_thread::sleep_for(200ms);
  }
  EXPECT_TRUE(of_kind("watchdog").empty()) << slurp(events());
  EXPECT_EQ(second.write_valves(3.0, -3.0), EMBXSBUSY) << "still the first client's";
  // Then silent, its connection open: a client that hung.
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "watchdog: no request from client 1", 3s))
      << slurp(dir_ / "serve.out");
  const auto trips = of_kind("watchdog");
  ASSERT_EQ(trips.size(), 1u);
  EXPECT_EQ(trips[0]["client"].count(), 1u);
  const double silent_s = trips[0]["t"].number() - trips[0]["last_request_t"].number();
  EXPECT_GE(silent_s, 1.0);
  const auto released = of_kind("released");
  ASSERT_EQ(released.size(), 1u);
  EXPECT_EQ(released[0]["cause"].text(), "watchdog");
  EXPECT_EQ(of_kind("disconnect").size(), 0u) << "the hung client never closed";
  // The neutral outputs (serve's start-up voltages), then the second client's.
  const Json start = of_kind("start").front();
  EXPECT_NEAR(trips[0]["u_p"].number(), start["u_p"].number(), 1e-6);
  EXPECT_NEAR(trips[0]["u_n"].number(), start["u_n"].number(), 1e-6);
  EXPECT_EQ(second.write_valves(3.0, -3.0), 0) << "free once the watchdog tripped";
  EXPECT_EQ(second.read(kValveP, 2), (std::vector<std::uint16_t>{hil_valve_word(3.0), hil_valve_word(-3.0)}));
  const auto owners = of_kind("owner");
  ASSERT_EQ(owners.size(), 2u);
  EXPECT_EQ(owners[1]["client"].count(), 2u);
  kill(plant.pid, SIGTERM);
  EXPECT_EQ(plant.wait(), 0);
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("1 watchdog trips"));
  EXPECT_NEAR(of_kind("stop").front()["u_p"].number(), 3.0, 1e-3);
}

TEST_F(ServeWatchdog, TheRecordWritesTheHeldOutputsAtMostOnceEvery10MsCountingTheSkippedAndTheLastAlways) {
  Child plant = serve({});
  Client c(port_, 1.0);
  ASSERT_TRUE(c.connected());
  int changes = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 300; ++i, ++changes) ASSERT_EQ(c.write_valves(-5.0 + i * 0.02, 1.0), 0);
  const double took_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(pneu::test::eventually(
      [&] {
        const auto lines = of_kind("outputs");
        return !lines.empty() && std::abs(lines.back()["u_p"].number() - (-5.0 + 299 * 0.02)) < 1e-3;
      },
      2s))
      << "the last outputs held are on record within 10 ms\n" << slurp(events());
  const auto lines = of_kind("outputs");
  std::uint64_t counted = 0;
  double last_t = -1.0;
  for (const Json& o : lines) {
    counted += 1 + o["skipped"].count();
    EXPECT_EQ(o["client"].count(), 1u);
    EXPECT_GT(o["t"].number(), last_t) << "in order";
    last_t = o["t"].number();
  }
  EXPECT_EQ(counted, static_cast<std::uint64_t>(changes)) << "every change is on record, written or counted";
  EXPECT_LE(lines.size(), static_cast<std::size_t>(took_s / 0.01) + 2) << "bounded: " << lines.size() << " lines";
  EXPECT_LT(lines.size(), 300u) << "not one line per write: the writes came faster than 10 ms apart";
}

TEST_F(ServeWatchdog, PneudRefusesAStatedWatchdogThatOneLostReplyWouldTripAndWarnsWhenNoneIsStated) {
  // hil.yaml: 20 ms response timeout, 1 ms exchange period: one lost reply and its retry is 41 ms.
  Child p = Child::spawn({bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                          "--set", "telemetry.enabled=false", "--duration", "1", "--set", "hal.modbus.module_watchdog_s=0.04"},
                         dir_ / "pneud.out", dir_ / "pneud.err");
  EXPECT_EQ(p.wait(), 2) << "refused as a configuration error, before connecting";
  EXPECT_THAT(slurp(dir_ / "pneud.err"), HasSubstr("hal.modbus.module_watchdog_s"));
  EXPECT_THAT(slurp(dir_ / "pneud.err"), HasSubstr("one lost reply would trip the module's watchdog"));
  EXPECT_THAT(slurp(dir_ / "pneud.err"), ::testing::Not(HasSubstr("cannot connect")));
  // 0.1 s is accepted: it gets as far as connecting (no module listens here).
  Child ok = Child::spawn({bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                           "--set", "telemetry.enabled=false", "--duration", "1", "--set", "hal.modbus.module_watchdog_s=0.1"},
                          dir_ / "ok.out", dir_ / "ok.err");
  EXPECT_EQ(ok.wait(), 1);
  EXPECT_THAT(slurp(dir_ / "ok.err"), HasSubstr("cannot connect"));
  EXPECT_THAT(slurp(dir_ / "ok.err"), ::testing::Not(HasSubstr("no module watchdog stated")));
  // None stated (hil.yaml's 0): said at start-up, on stderr (the journal).
  Child none = Child::spawn({bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                             "--set", "telemetry.enabled=false", "--duration", "1"},
                            dir_ / "none.out", dir_ / "none.err");
  EXPECT_EQ(none.wait(), 1);
  EXPECT_THAT(slurp(dir_ / "none.err"), HasSubstr("warning: hal.modbus.module_watchdog_s is 0: no module watchdog stated"));
}

}  // namespace
