// Hardware in the loop: pneud's modbus backend against `pneu-plant serve` on a free loopback port,
// and both against Modbus implementations not written here (mbpoll).
#include <arpa/inet.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <chrono>
#include <cmath>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "support/child_process.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::test::Child;
using pneu::test::free_port;
using pneu::test::slurp;
using ::testing::HasSubstr;

std::string bin(const std::string& name) { return std::string(PNEU_BINARY_DIR) + "/bin/" + name; }
std::string hil_yaml() { return std::string(PNEU_SOURCE_DIR) + "/config/hil.yaml"; }


bool wait_listening(int port) {
  for (int i = 0; i < 200; ++i) {
    const int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(static_cast<uint16_t>(port));
    const bool ok = connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
    close(fd);  // the server sees a client that leaves at once, and serves the next
    if (ok) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

// A number field of one JSON line ("null" -> NaN).
double field(const std::string& line, const std::string& key) {
  const auto p = line.find("\"" + key + "\":");
  if (p == std::string::npos) return NAN;
  const std::string rest = line.substr(p + key.size() + 3);
  if (rest.rfind("null", 0) == 0) return NAN;
  return std::stod(rest);
}

class Hil : public ::testing::Test {
 protected:
  void SetUp() override {
    port_ = free_port();
  }
  Child serve(double duration_s, const std::vector<std::string>& extra = {}) {
    std::vector<std::string> args{bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set",
                                  "hal.modbus.port=" + std::to_string(port_), "--duration", std::to_string(duration_s)};
    args.insert(args.end(), extra.begin(), extra.end());
    Child c = Child::spawn(args, dir_ / "serve.out", dir_ / "serve.err");
    EXPECT_TRUE(wait_listening(port_)) << slurp(dir_ / "serve.err");
    return c;
  }
  // The link's timing is hil.yaml's only for the tests of the link (`bench_link`); see
  // link_stalls_tolerated.
  std::vector<std::string> pneud_args(const std::vector<std::string>& extra, bool bench_link = false) const {
    std::vector<std::string> args{bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                                  "--set", "telemetry.enabled=false"};
    if (!bench_link) args = pneu::test::link_stalls_tolerated(std::move(args));
    args.insert(args.end(), extra.begin(), extra.end());
    return pneu::test::loop_timing_faults_off(std::move(args));
  }
  pneu::test::TestDir dir_{"pneu_hil_"};
  int port_ = 0;
};

TEST_F(Hil, PaperScenarioOverModbusSticksRestartsAndTheNonlinearForecastHoldsWithin2Percent) {
  // Over Modbus the stop lands a little elsewhere each run (I/O timing, noise, the machine's
  // stalls), and how long the pressures take to break stiction depends steeply on where: 0.7 to
  // 4.6 s over our runs, or never when the equilibrium force lies inside the stiction band (both
  // methods then forecast no restart). Every run's restarts are judged; the phenomenon, a stop of
  // half a second or more under constant control then a restart, must show in one of 3 runs.
  int long_restarts = 0, runs = 0;
  for (; runs < 3 && long_restarts == 0; ++runs) {
    const std::string events = "events" + std::to_string(runs) + ".jsonl";
    Child plant = serve(15.0);
    Child pneud = Child::spawn(pneud_args({"--events", (dir_ / events).string()}), dir_ / "pneud.out",
                               dir_ / "pneud.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
    EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("last valve voltages: u_P ="));
    EXPECT_THAT(slurp(dir_ / "pneud.out"), HasSubstr("0 errors, 0 reconnects"));

    struct Stop {
      double t = NAN, nonlinear = NAN, restart = NAN;
    };
    std::map<int, Stop> stops;
    std::istringstream lines(slurp(dir_ / events));
    for (std::string line; std::getline(lines, line);) {
      const int idx = static_cast<int>(field(line, "stop"));
      if (line.find("\"event\":\"stop\"") != std::string::npos) stops[idx].t = field(line, "t");
      if (line.find("\"event\":\"prediction\"") != std::string::npos && line.find("\"method\":\"nonlinear\"") != std::string::npos)
        stops[idx].nonlinear = field(line, "t_restart");  // made at the stop, not made again later
      if (line.find("\"event\":\"start\"") != std::string::npos && line.find("\"restart\":true") != std::string::npos)
        stops[idx].restart = field(line, "t");
    }
    for (const auto& [idx, s] : stops) {
      if (std::isnan(s.restart)) continue;
      const double sticking = s.restart - s.t;
      if (sticking < 0.5) continue;  // the 2 % bound is for the sticking phases of the phenomenon
      ++long_restarts;
      ASSERT_FALSE(std::isnan(s.nonlinear)) << "run " << runs << ", stop " << idx << ": no restart forecast";
      EXPECT_LE(std::abs(s.nonlinear - s.restart), 0.02 * sticking)
          << "run " << runs << ", stop " << idx << " at " << s.t << " s: forecast " << s.nonlinear << " s, restart "
          << s.restart << " s";
    }
    if (long_restarts == 0) std::printf("run %d: no sticking phase of 0.5 s or more ended in a restart\n%s", runs,
                                        slurp(dir_ / "pneud.out").c_str());
  }
  EXPECT_GE(long_restarts, 1) << "a sticking phase of 0.5 s or more ending in a restart, in " << runs << " runs";
}

TEST_F(Hil, ServesOneClientAtATimeAndRefusesASecondCleanly) {
  Child plant = serve(5.0);
  modbus_t* first = modbus_new_tcp("127.0.0.1", port_);
  ASSERT_EQ(modbus_connect(first), 0);
  modbus_set_slave(first, 1);
  uint16_t regs[3] = {};
  ASSERT_EQ(modbus_read_registers(first, 0, 3, regs), 3);
  modbus_t* second = modbus_new_tcp("127.0.0.1", port_);
  modbus_set_response_timeout(second, 0, 200000);
  ASSERT_EQ(modbus_connect(second), 0) << "accepted, then closed";
  modbus_set_slave(second, 1);
  EXPECT_EQ(modbus_read_registers(second, 0, 3, regs), -1) << "the second client gets no answer";
  EXPECT_EQ(modbus_read_registers(first, 0, 3, regs), 3) << "the first one is still served";
  modbus_close(second);
  modbus_free(second);
  modbus_close(first);
  modbus_free(first);
  kill(plant.pid, SIGTERM);
  EXPECT_EQ(plant.wait(), 0);
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("1 refused"));
}

TEST_F(Hil, MbpollReadsThePlantsRegisters) {
  if (system("command -v mbpoll > /dev/null") != 0) GTEST_SKIP() << "mbpoll (Debian package mbpoll) is not installed";
  Child plant = serve(5.0);
  // Holding registers 0..2 (mbpoll counts from 1 unless -0): position, p_P, p_N as 16-bit words.
  const std::string out = (dir_ / "mbpoll.out").string();
  ASSERT_EQ(system(("mbpoll -m tcp -p " + std::to_string(port_) + " -a 1 -t 4 -r 1 -c 3 -1 127.0.0.1 > " + out +
                    " 2>&1").c_str()),
            0)
      << slurp(out);
  std::map<int, long> words;
  std::istringstream in(slurp(out));
  for (std::string line; std::getline(in, line);) {
    int reg = 0;
    long value = 0;
    if (std::sscanf(line.c_str(), "[%d]: %ld", &reg, &value) == 2) words[reg] = value;
  }
  ASSERT_EQ(words.size(), 3u) << slurp(out);
  // 0..65535 over 0..10 V; 20 V/m with 5 V at mid-stroke; 1e-5 V/Pa.
  const double y = (words[1] * 10.0 / 65535.0 - 5.0) / 20.0;
  const double p_p = words[2] * 10.0 / 65535.0 / 1e-5, p_n = words[3] * 10.0 / 65535.0 / 1e-5;
  EXPECT_NEAR(y, 0.2195, 1e-4) << "at rest at the configured 219.5 mm (noise 2.5 um, steps 7.6 um)";
  EXPECT_GT(p_p, 1.0e5);
  EXPECT_LT(p_p, 7.0e5);
  EXPECT_GT(p_n, p_p) << "at rest at u_e the rod side holds more pressure (S_N < S_P)";
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
}

TEST_F(Hil, UnreachableHostWrongUnitAndBadMapFailAtStartUpWithClearErrors) {
  // Nobody listens.
  Child none = Child::spawn(pneud_args({"--duration", "1"}), dir_ / "a.out", dir_ / "a.err");
  EXPECT_EQ(none.wait(), 1);
  EXPECT_THAT(slurp(dir_ / "a.err"), HasSubstr("cannot connect"));

  Child plant = serve(10.0);
  Child wrong_unit = Child::spawn(pneud_args({"--duration", "1", "--set", "hal.modbus.unit_id=7"}), dir_ / "b.out",
                                  dir_ / "b.err");
  EXPECT_EQ(wrong_unit.wait(), 1);
  EXPECT_THAT(slurp(dir_ / "b.err"), HasSubstr("unit 7: the first exchange failed"));

  Child overlap = Child::spawn(pneud_args({"--duration", "1", "--set", "hal.modbus.channels.pressure_p.register=0"}),
                               dir_ / "c.out", dir_ / "c.err");
  EXPECT_EQ(overlap.wait(), 2);
  EXPECT_THAT(slurp(dir_ / "c.err"), HasSubstr("hal.modbus.channels.pressure_p.register: overlaps position"));

  // A register the module does not have: it answers with an exception, named at start-up.
  Child beyond = Child::spawn(pneud_args({"--duration", "1", "--set", "hal.modbus.channels.pressure_n.register=100"}),
                              dir_ / "e.out", dir_ / "e.err");
  EXPECT_EQ(beyond.wait(), 1);
  EXPECT_THAT(slurp(dir_ / "e.err"), HasSubstr("Illegal data address"));

  Child empty = Child::spawn(pneud_args({"--duration", "1", "--set", "hal.modbus.channels.position.raw_max=0"}),
                             dir_ / "d.out", dir_ / "d.err");
  EXPECT_EQ(empty.wait(), 2);
  EXPECT_THAT(slurp(dir_ / "d.err"), HasSubstr("the raw range is empty"));
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
}

TEST_F(Hil, AModuleThatAnswersLateIsACountedCommsFaultAndTheLoopNeverWaits) {
  // From 1 s on every reply comes 50 ms late, beyond the 20 ms response timeout.
  Child plant = serve(6.0, {"--reply-delay-s", "0.05", "--delay-after-s", "1"});
  Child pneud = Child::spawn(pneud_args({"--duration", "3"}, /*bench_link=*/true), dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  const std::string out = slurp(dir_ / "pneud.out");
  const auto summary = pneu::test::PneudSummary::parse(out);
  ASSERT_TRUE(summary.has_loop && summary.has_modbus) << out;
  EXPECT_GE(summary.errors, 5u) << "each late reply is a counted comms error";
  EXPECT_GE(summary.reconnects, 5u) << "and the I/O thread closes and reconnects (libmodbus issue #255)";
  // Each stale read is a tick: over 1000 of them in the 2 s of late replies, where a loop waiting
  // on the module would tick once per 20 ms timeout (100 times).
  EXPECT_GT(summary.stale, 1000u) << "the loop saw the samples go stale: flagged, not waited for";
  EXPECT_EQ(summary.ticks + summary.skipped, 3001u) << "every deadline of the 3 s run was met or accounted for";
  // The safe output is tried three times on closing, each on a fresh connection; none is answered
  // in time, and pneud says so, on stderr too (the journal's).
  EXPECT_THAT(out, HasSubstr("safe output on closing: NOT confirmed by the module after 3 attempts"));
  EXPECT_THAT(slurp(dir_ / "pneud.err"),
              HasSubstr("the module did not confirm the safe output on closing (3 attempts, last error: "));
}

TEST_F(Hil, RtuOverAPtyPairAt115200BaudKeepsTheLoopRateAndFreshSamples) {
  if (system("command -v socat > /dev/null") != 0) GTEST_SKIP() << "socat (Debian package socat) is not installed";
  const fs::path a = dir_ / "ttyA", b = dir_ / "ttyB";
  Child pty = Child::spawn({"socat", "pty,raw,echo=0,link=" + a.string(), "pty,raw,echo=0,link=" + b.string()},
                           dir_ / "socat.out", dir_ / "socat.err");
  ASSERT_TRUE(pneu::test::eventually([&] { return fs::exists(a) && fs::exists(b); }, 2s)) << slurp(dir_ / "socat.err");
  // The server holds each reply for the time it takes on a real 115200 baud line (a pty has no
  // speed of its own): a function-23 exchange of 28 bytes plus silences takes about 3 ms.
  Child plant = Child::spawn({bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set", "hal.modbus.transport=rtu",
                              "--set", "hal.modbus.device=" + a.string(), "--duration", "6"},
                             dir_ / "serve.out", dir_ / "serve.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "serving", 3s)) << slurp(dir_ / "serve.err");
  // The sample age limit is hil.yaml's 20 ms, this test's subject; a stall of the plant or of
  // socat shorter than the tolerant response timeout is no comms error (see link_stalls_tolerated).
  Child pneud = Child::spawn(pneud_args({"--duration", "3", "--set", "hal.modbus.transport=rtu", "--set",
                                         "hal.modbus.device=" + b.string(), "--set", "hal.modbus.max_sample_age_s=0.02"}),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  const std::string out = slurp(dir_ / "pneud.out");
  const auto summary = pneu::test::PneudSummary::parse(out);
  ASSERT_TRUE(summary.has_loop && summary.has_modbus) << out;
  EXPECT_EQ(summary.ticks + summary.skipped, 3001u) << "the loop kept its 1 kHz deadlines";
  EXPECT_EQ(summary.errors, 0u);
  EXPECT_GT(summary.rate_per_s, 100.0) << "exchanges as often as the line allows";
  EXPECT_LT(summary.rate_per_s, 400.0) << "and no more often than a 115200 baud line allows";
  EXPECT_LE(summary.stale, summary.ticks / 100) << "samples stay within the 20 ms age limit (oldest " << summary.oldest_ms << " ms)";
}

}  // namespace
