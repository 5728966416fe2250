// Hardware in the loop: pneud's modbus backend against `pneu-plant serve` on a free loopback port,
// and both against Modbus implementations not written here (mbpoll).
#include <arpa/inet.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <sched.h>
#include <sys/socket.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/config.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"

namespace {

using pneu::test::bin;
using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::test::Child;
using pneu::test::free_port;
using pneu::test::slurp;
using ::testing::HasSubstr;



// A TCP connection to `port` on loopback, or -1.
int connect_loopback(int port) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(static_cast<uint16_t>(port));
  if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) return fd;
  close(fd);
  return -1;
}

bool wait_listening(int port) {
  for (int i = 0; i < 200; ++i) {
    const int fd = connect_loopback(port);
    if (fd >= 0) {
      close(fd);  // the server sees a client that leaves at once
      return true;
    }
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

bool has_mbpoll() { return system("command -v mbpoll > /dev/null") == 0; }

// mbpoll's exit code for one poll (-1) of `what` (e.g. "-t 4 -r 1 -c 3"), writing `values` if any,
// with its output (both streams) in `out`.
int mbpoll(int port, const std::string& what, const fs::path& out, const std::string& values = "") {
  const int status = system(("mbpoll -m tcp -p " + std::to_string(port) + " -a 1 " + what + " -1 127.0.0.1 " + values +
                             " > " + out.string() + " 2>&1")
                                .c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The registers in mbpoll's output, by mbpoll's numbers (from 1).
std::map<int, long> mbpoll_words(const std::string& output) {
  std::map<int, long> words;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    int reg = 0;
    long value = 0;
    if (std::sscanf(line.c_str(), "[%d]: %ld", &reg, &value) == 2) words[reg] = value;
  }
  return words;
}

// A Modbus TCP request to read `count` registers from 0 (function 3), transaction `id`: bytes to
// send as a misbehaving client would, which libmodbus does not.
std::vector<std::uint8_t> read_request(std::uint16_t id, std::uint16_t count) {
  return {static_cast<std::uint8_t>(id >> 8), static_cast<std::uint8_t>(id), 0, 0, 0, 6, 1, 3, 0, 0,
          static_cast<std::uint8_t>(count >> 8), static_cast<std::uint8_t>(count)};
}

// A Modbus TCP request writing hil.yaml's valve registers 16 and 17 (function 16).
std::vector<std::uint8_t> write_valves_request(std::uint16_t id, std::uint16_t p, std::uint16_t n) {
  return {static_cast<std::uint8_t>(id >> 8), static_cast<std::uint8_t>(id), 0, 0, 0, 11, 1, 16, 0, 16, 0, 2, 4,
          static_cast<std::uint8_t>(p >> 8), static_cast<std::uint8_t>(p), static_cast<std::uint8_t>(n >> 8),
          static_cast<std::uint8_t>(n)};
}

// What arrives on `fd` within `limit`, up to `n` bytes.
std::vector<std::uint8_t> receive(int fd, std::size_t n, std::chrono::milliseconds limit) {
  std::vector<std::uint8_t> got;
  const auto until = std::chrono::steady_clock::now() + limit;
  while (got.size() < n && std::chrono::steady_clock::now() < until) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 10) <= 0) continue;
    std::uint8_t buf[300];
    const ssize_t k = recv(fd, buf, std::min(sizeof buf, n - got.size()), 0);
    if (k <= 0) break;
    got.insert(got.end(), buf, buf + k);
  }
  return got;
}

// A number field of one JSON line ("null" -> NaN).
double field(const std::string& line, const std::string& key) {
  const auto p = line.find("\"" + key + "\":");
  if (p == std::string::npos) return NAN;
  const std::string rest = line.substr(p + key.size() + 3);
  if (rest.rfind("null", 0) == 0) return NAN;
  return std::stod(rest);
}

// pneud's events file, by stop: when it was called, the nonlinear forecast made at it, and the
// restart start pneud dated after it (NaN where there is none).
using StopRecord = std::array<double, 3>;
std::map<int, StopRecord> stops_of(const std::string& events) {
  std::map<int, StopRecord> stops;
  std::istringstream lines(events);
  for (std::string line; std::getline(lines, line);) {
    auto& s = stops.try_emplace(static_cast<int>(field(line, "stop")), StopRecord{NAN, NAN, NAN}).first->second;
    if (line.find("\"event\":\"stop\"") != std::string::npos) s[0] = field(line, "t");
    if (line.find("\"event\":\"prediction\"") != std::string::npos && line.find("\"method\":\"nonlinear\"") != std::string::npos)
      s[1] = field(line, "t_restart");
    if (line.find("\"event\":\"start\"") != std::string::npos && line.find("\"restart\":true") != std::string::npos)
      s[2] = field(line, "t");
  }
  return stops;
}

// serve's record of the plant's motion (pneu-plant serve --events): its sticks and breakaways on
// pneud's loop time (`epoch`: the loop's time 0 on CLOCK_MONOTONIC), each as (t, stuck from then on).
using Motion = std::vector<std::pair<double, bool>>;
Motion plant_motion(const std::string& record, double epoch) {
  Motion motion;
  std::istringstream lines(record);
  for (std::string line; std::getline(lines, line);) {
    const bool breakaway = line.find("\"event\":\"breakaway\"") != std::string::npos;
    if (breakaway || line.find("\"event\":\"stick\"") != std::string::npos)
      motion.emplace_back(field(line, "monotonic_s") - epoch, !breakaway);
  }
  return motion;
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
    Child c = Child::spawn(answering_on_time(std::move(args)), dir_ / "serve.out", dir_ / "serve.err");
    EXPECT_TRUE(wait_listening(port_)) << slurp(dir_ / "serve.err");
    return c;
  }
  // The link's timing is hil.yaml's only for the tests of the link (`bench_link`); see
  // link_stalls_tolerated.
  std::vector<std::string> pneud_args(const std::vector<std::string>& extra, bool bench_link = false) const {
    std::vector<std::string> args{bin("pneud"), "--config", hil_yaml(), "--set", "hal.modbus.port=" + std::to_string(port_),
                                  "--set", "telemetry.enabled=false"};
    if (!bench_link) args = pneu::test::link_stalls_tolerated(std::move(args));
    if (on_time_) args.insert(args.end(), {"--set", "controller.realtime.priority=40"});
    args.insert(args.end(), extra.begin(), extra.end());
    return pneu::test::loop_timing_faults_off(std::move(args));
  }
  // The paper's step from the plant as serve starts it, at rest at 219.5 mm in complete equilibrium,
  // and the runs that time a fault from serve's start-up: without the movement test, whose pulses
  // (HilMovementTest) leave the carriage millimetres away with other pressures and take a second.
  static std::vector<std::string> no_movement_test() { return {"--set", "controller.movement_test.enabled=false"}; }
  static std::vector<std::string> with(std::vector<std::string> a, const std::vector<std::string>& b) {
    a.insert(a.end(), b.begin(), b.end());
    return a;
  }
  // pneud's figures (--summary-json), read once it has ended.
  [[nodiscard]] std::string summary_json() const { return (dir_ / "summary.json").string(); }
  // `args` run at real-time priority above pneud's, when the test asks for its loop on time: the
  // module's side (serve, the serial line) answers as hardware does, whatever else the host runs.
  [[nodiscard]] std::vector<std::string> answering_on_time(std::vector<std::string> args) const {
    if (on_time_) args.insert(args.begin(), {"chrt", "-f", "41"});
    return args;
  }
  pneu::test::TestDir dir_{"pneu_hil_"};
  int port_ = 0;
  bool on_time_ = false;  // HilOnTime
};

// The tests that judge figures that need pneud's loop on time (and serve's answers): where
// SCHED_FIFO is permitted, pneud's loop and its I/O thread (controller.realtime) and serve run at
// real-time priority, so that the tests beside them (ctest -j) cannot delay them, as a bench runs
// pneud; else they run alone (tests/CMakeLists.txt decides which at configure time, and a build
// that counted on SCHED_FIFO skips them, saying why, without it).
class HilOnTime : public Hil {
 protected:
  void SetUp() override {
    Hil::SetUp();
    on_time_ = std::system("chrt -f 1 true 2>/dev/null") == 0;
#ifdef PNEU_TESTS_AT_REALTIME_PRIORITY
    if (!on_time_)
      GTEST_SKIP() << "configured to run beside other tests at SCHED_FIFO, which this user may not use: "
                      "configure the build as this user (these tests then run alone), or run them on an idle machine";
#endif
  }
};

// The movement test before closed loop (controller.movement_test) over Modbus: pneu-plant serve
// plays a miswired bench (--fault tubes:swapped, pressure_sensors:swapped, a dead transmitter that
// reads its chamber's pressure at start-up with its noise, which the supervisor's frozen check cannot
// tell), and pneud refuses to start closed loop, naming the finding on stderr, before any tick (no
// events file is left); on the bench as it should be it says that the test passed, then runs.
class HilMovementTest : public Hil {
 protected:
  struct Start {
    int exit_code = -1;
    std::string err;
    bool ticked = false;  // the run's events file is there: the loop ran
  };
  Start start(const std::vector<std::string>& serve_faults, const std::vector<std::string>& pneud_extra = {}) {
    Child plant = serve(30.0, serve_faults);
    std::vector<std::string> extra{"--duration", "2", "--events", (dir_ / "events.jsonl").string()};
    extra.insert(extra.end(), pneud_extra.begin(), pneud_extra.end());
    Child pneud = Child::spawn(pneud_args(extra), dir_ / "pneud.out", dir_ / "pneud.err");
    Start s;
    s.exit_code = pneud.wait();
    s.err = slurp(dir_ / "pneud.err");
    s.ticked = fs::exists(dir_ / "events.jsonl");
    kill(plant.pid, SIGINT);
    EXPECT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
    return s;
  }
};

TEST_F(HilMovementTest, SwappedTubesStopTheStartBeforeClosedLoopNamingThem) {
  const Start s = start({"--fault", "tubes:swapped@0"});
  EXPECT_NE(s.exit_code, 0) << s.err;
  EXPECT_THAT(s.err, HasSubstr("movement test before closed loop: tubes swapped"));
  EXPECT_THAT(s.err, HasSubstr("closed loop not started"));
  EXPECT_FALSE(s.ticked) << "no tick of closed loop ran";
}

TEST_F(HilMovementTest, ADeadPressureSensorStopsTheStartBeforeClosedLoopNamingIt) {
  const Start s = start({"--fault", "pressure_p:dead@0"});
  EXPECT_NE(s.exit_code, 0) << s.err;
  EXPECT_THAT(s.err, HasSubstr("movement test before closed loop: p_P sensor dead"));
  EXPECT_FALSE(s.ticked) << "no tick of closed loop ran";
}

TEST_F(HilMovementTest, SwappedPressureChannelsStopTheStartNamingThem) {
  const Start s = start({"--fault", "pressure_sensors:swapped@0"});
  EXPECT_NE(s.exit_code, 0) << s.err;
  EXPECT_THAT(s.err, HasSubstr("movement test before closed loop: pressure sensors swapped"));
  EXPECT_FALSE(s.ticked);
}

TEST_F(HilMovementTest, ACorrectBenchPassesAndTheStartUpLineSaysSoThenClosedLoopRuns) {
  const Start s = start({}, {"--summary-json", summary_json()});
  EXPECT_EQ(s.exit_code, 0) << s.err;
  EXPECT_THAT(s.err, HasSubstr("pneud: movement test passed in "));
  EXPECT_TRUE(s.ticked);
  // The movement test's exchanges, made before the run's time starts, count among the link's
  // transactions, not in its exchanges per second of the run (about one a tick at 1 kHz).
  const auto summary = pneu::test::PneudSummary::read(summary_json());
  ASSERT_TRUE(summary.has_modbus);
  std::printf("%llu transactions for %llu ticks, %.0f per second of the run\n", summary.transactions, summary.ticks,
              summary.rate_per_s);
  EXPECT_GT(summary.transactions, summary.ticks + 500) << "the movement test's exchanges are counted";
  EXPECT_LT(summary.rate_per_s, 1200.0) << "but not as the run's";
}

TEST_F(HilMovementTest, SkippedOnlyByItsKeyWhichTheStartUpLineReports) {
  const Start s = start({}, {"--set", "controller.movement_test.enabled=false"});
  EXPECT_EQ(s.exit_code, 0) << s.err;
  EXPECT_THAT(s.err, HasSubstr("pneud: movement test: skipped (controller.movement_test.enabled: false)"));
  EXPECT_THAT(s.err, ::testing::Not(HasSubstr("movement test passed")));
  EXPECT_TRUE(s.ticked);
}

TEST_F(Hil, PaperScenarioOverModbusSticksRestartsAndTheNonlinearForecastHoldsWithin2Percent) {
  // Over Modbus the stop lands a little elsewhere each run (I/O timing, noise, the machine's
  // stalls), and how long the pressures take to break stiction depends steeply on where: 0.7 to
  // 4.6 s over our runs, or never when the equilibrium force lies inside the stiction band (both
  // methods then forecast no restart). Every run's restarts are judged; the phenomenon, a stop of
  // half a second or more under constant control then a restart, must show in one of 3 runs.
  // The paper's step with the paper's gains (config/paper.yaml's law on hil.yaml): hil.yaml's
  // designed law stops this step with the equilibrium force a newton inside the stiction band,
  // where the time to break it varies most from run to run (no restart in process; over Modbus,
  // one run restarted after 5.8 s, forecast 2.7 % off the start the detector dated).
  // hil.yaml's in-position hold off: the phenomenon is what it prevents.
  int long_restarts = 0, runs = 0;
  for (; runs < 3 && long_restarts == 0; ++runs) {
    const std::string events = "events" + std::to_string(runs) + ".jsonl";
    Child plant = serve(15.0);
    Child pneud = Child::spawn(pneud_args(with({"--events", (dir_ / events).string(), "--summary-json", summary_json(),
                                                "--set", "controller.law.gains=fixed", "--set", "controller.hold.enabled=false"},
                                               no_movement_test())),
                               dir_ / "pneud.out", dir_ / "pneud.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
    EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("last valve voltages: u_P ="));
    const auto summary = pneu::test::PneudSummary::read(summary_json());
    ASSERT_TRUE(summary.has_modbus);
    EXPECT_EQ(summary.errors, 0u);
    EXPECT_EQ(summary.reconnects, 0u);

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

// The in-position hold over Modbus: the paper's step with the paper's gains, which stops short of
// the set point and restarts seconds later; reaching from 5 mm brings the carriage into the 0.5 mm
// window, and once held there it never starts again: judged on serve's own record of the plant's
// motion (--events: no breakaway after the hold, on CLOCK_MONOTONIC), not on pneud's dating, which
// a loaded machine blurs; the forecasts under the hold's commands say no restart.
// The loop on time (HilOnTime): the hold keeps the force inside the stiction band only while its
// loop runs on time. With two busy loops beside the suite (bench/ctest_under_load.sh), at ordinary
// scheduling, it failed once in six: the forecasts under the hold said restart three times, and
// the plant broke away at the bound (-50 N) after the hold began: most likely the pressures
// drifting under a late loop's commands, the phenomenon itself. A bench's pneud runs with
// controller.realtime on a PREEMPT_RT kernel.
TEST_F(HilOnTime, PaperScenarioWithTheHoldOverModbusNeverRestartsOnceHeldWithinTheWindowWithTheLoopOnTime) {
  const fs::path plant_events = dir_ / "plant.jsonl";
  Child plant = serve(15.0, {"--events", plant_events.string()});
  // The hold and reach as measured here (hil.yaml ships them on, with a 0.2 mm window).
  Child pneud = Child::spawn(pneud_args(with({"--events", (dir_ / "events.jsonl").string(), "--summary-json", summary_json(),
                                              "--set", "controller.law.gains=fixed", "--set", "controller.hold.enabled=true",
                                              "--set", "controller.hold.window_m=0.0005", "--set", "controller.hold.reach_m=0.005"},
                                             no_movement_test())),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  // The plant's truth: its sticks and breakaways (serve's record, on CLOCK_MONOTONIC), on pneud's
  // loop time.
  const double epoch = pneu::test::PneudSummary::read(summary_json()).epoch_monotonic_s;
  ASSERT_TRUE(std::isfinite(epoch));
  const std::string plant_record = slurp(plant_events);
  const Motion motion = plant_motion(plant_record, epoch);
  ASSERT_TRUE(std::any_of(motion.begin(), motion.end(), [](const auto& m) { return !m.second; }))
      << "not vacuous: serve's record holds the plant's motion\n" << plant_record;
  // Stuck at `t`, by the plant's record: its last stick or breakaway before `t` was a stick.
  const auto plant_stuck_at = [&](double t) {
    const auto after = std::find_if(motion.begin(), motion.end(), [&](const auto& m) { return m.first > t; });
    return after != motion.begin() && std::prev(after)->second;
  };
  // Held: the first hold within the window (not reaching) that began on a carriage the plant's
  // record has stuck (a stop pneud confirms follows the stick by the stop detector's hold time and
  // the sample's age). Over Modbus pneud may call a stop over the last micrometres of a slide (a
  // stale sample reads as no motion, or a slide slower than the rest band) and begin a hold there,
  // on pressures still moving: it may end "moved" milliseconds later, or the carriage sticks under
  // it with a force that then leaves the stiction band; the forecasts made under it rightly say
  // restart. Such holds are not this test's claim, and not judged (they are printed).
  double t_held = NAN, y_held = NAN, y_d = NAN;
  int held_forecasts = 0, held_restart_forecasts = 0;
  std::istringstream lines(slurp(dir_ / "events.jsonl"));
  for (std::string line; std::getline(lines, line);) {
    const double t = field(line, "t");
    if (std::isnan(t_held)) {
      if (line.find("\"event\":\"hold_start\"") != std::string::npos && field(line, "reach") == 0.0 && t > 1.0) {
        if (plant_stuck_at(t))
          t_held = t, y_held = field(line, "y"), y_d = field(line, "y_d");
        else
          std::printf("hold from %.3f s on a carriage the plant's record has sliding: not judged\n", t);
      }
      continue;
    }
    if (line.find("\"method\":\"held\"") != std::string::npos) {
      ++held_forecasts;
      if (line.find("\"will_restart\":true") != std::string::npos) ++held_restart_forecasts;
    }
  }
  ASSERT_FALSE(std::isnan(t_held)) << "never held within the window\n" << slurp(dir_ / "pneud.out");
  std::printf("held within the window from %.3f s, %.3f mm from the set point\n", t_held, (y_held - y_d) * 1e3);
  EXPECT_LE(std::abs(y_held - y_d), 0.0005 + 1e-9);
  EXPECT_GT(held_forecasts, 10);
  EXPECT_EQ(held_restart_forecasts, 0);

  // Once held, the plant never broke away again.
  int breakaways_after = 0;
  for (const auto& [t, stuck] : motion)
    if (!stuck && t > t_held) ++breakaways_after;
  EXPECT_EQ(breakaways_after, 0) << "the plant started again after the hold:\n" << plant_record;
}

// Issue 15 over Modbus: pneu-plant serve plays a bench that is not pneud's model (stiction 20 %
// high, the exhaust leak 22 % low, a valve null offset of 50 mV); pneud --identify identifies it
// over the link (refused without --armed), and the paper's step on the identified configuration
// forecasts its long sticking phases within 5 %, where the model as configured was tens of % off.
// The loop on time (HilOnTime): deadlines the loop skips shift when its commands reach the valves,
// which the fit over the link cannot tell from the valves' physics (beside four builds, at ordinary
// scheduling, 1672 skipped in the fitted phases: a misfit of 181 Pa rms and no null offset found).
TEST_F(HilOnTime, IdentifiedOverModbusThePaperStepsLongStickingPhaseIsForecastWithin5PercentWithTheLoopOnTime) {
  const std::vector<std::string> bench{"--set", "hal.sim.plant.friction.static_positive_n=54",
                                       "--set", "hal.sim.plant.friction.static_negative_n=-60",
                                       "--set", "hal.sim.plant.valve.leak_conductance_out_m3_per_s_pa=9.98e-10",
                                       "--set", "hal.sim.plant.valve.null_offset_v=0.05"};
  const fs::path identified = dir_ / "identified.yaml";
  {
    Child refused = Child::spawn(pneud_args({"--identify", identified.string()}), dir_ / "refused.out", dir_ / "refused.err");
    EXPECT_EQ(refused.wait(), 2);
    EXPECT_THAT(slurp(dir_ / "refused.err"), HasSubstr("--armed"));
    EXPECT_FALSE(fs::exists(identified));
  }
  {
    Child plant = serve(90.0, bench);
    Child pneud = Child::spawn(pneud_args({"--identify", identified.string(), "--armed"}), dir_ / "identify.out",
                               dir_ / "identify.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "identify.err") << slurp(dir_ / "identify.out");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  }
  const std::string report = slurp(dir_ / "identify.out");
  std::printf("%s", report.substr(report.find("identified from")).c_str());
  ASSERT_TRUE(fs::exists(identified));
  const pneu::config::Config id = pneu::config::load_file(identified);
  EXPECT_NEAR(id.plant.friction.static_positive_n, 54.0, 0.05 * 54.0);
  EXPECT_NEAR(id.plant.friction.static_negative_n, -60.0, 0.05 * 60.0);
  EXPECT_NEAR(id.plant.valve.null_offset_v, 0.05, 0.015);
  EXPECT_EQ(id.hal.backend, pneu::config::BackendKind::kModbus) << "the rest of the configuration as it was";

  // The paper's step (its gains) on the identified configuration, the hold off (the phase judged
  // is the one it prevents); every restart after 0.5 s or more of sticking, as pneud dated it.
  int long_restarts = 0, runs = 0;
  for (; runs < 3 && long_restarts == 0; ++runs) {
    const std::string events = "paper" + std::to_string(runs) + ".jsonl";
    Child plant = serve(15.0, bench);
    std::vector<std::string> args =
        pneud_args(with({"--events", (dir_ / events).string(), "--set", "controller.law.gains=fixed", "--set",
                         "controller.hold.enabled=false"},
                        no_movement_test()));
    args[2] = identified.string();  // --config
    Child pneud = Child::spawn(args, dir_ / "paper.out", dir_ / "paper.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "paper.err");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
    const std::map<int, StopRecord> stops = stops_of(slurp(dir_ / events));
    for (const auto& [idx, s] : stops) {
      if (std::isnan(s[2]) || s[2] - s[0] < 0.5) continue;
      ++long_restarts;
      const double sticking = s[2] - s[0];
      std::printf("run %d, stop %d: stuck %.3f s, forecast %.2f %% off\n", runs, idx, sticking,
                  100 * std::abs(s[1] - s[2]) / sticking);
      EXPECT_LE(std::abs(s[1] - s[2]), 0.05 * sticking) << "run " << runs << ", stop " << idx;
    }
  }
  EXPECT_GE(long_restarts, 1) << "a sticking phase of 0.5 s or more ending in a restart, in " << runs << " runs";
}

// Issue 28 over Modbus: pneu-plant serve plays a bench with the physics every real cylinder has,
// wall heat exchange (a thermal time constant of 1 s at mid-stroke) and a 3 ms spool lag, on top of
// stiction and a valve unlike the model's; pneud's model has both terms, at other values (2 s, 1
// ms). pneud --identify --armed identifies it over the link, and the paper's step on the identified
// configuration forecasts its long sticking phases within 5 % of the breakaway that serve's own
// record (--events) dates, on serve's clock.
TEST_F(HilOnTime, AThermalBenchWithASpoolLagIdentifiedOverModbusForecastsTheLongStickingPhaseWithin5PercentOfServesRecordWithTheLoopOnTime) {
  const std::vector<std::string> bench{"--set", "hal.sim.plant.thermal.heat_transfer_w_per_m2_k=25.72",
                                       "--set", "hal.sim.plant.valve.spool_time_constant_s=0.003",
                                       "--set", "hal.sim.plant.friction.static_positive_n=50",
                                       "--set", "hal.sim.plant.valve.null_offset_v=0.03"};
  const std::vector<std::string> model{"--set", "plant.thermal.heat_transfer_w_per_m2_k=12.86",
                                       "--set", "plant.valve.spool_time_constant_s=0.001"};
  const fs::path identified = dir_ / "identified.yaml";
  {
    Child plant = serve(90.0, bench);
    std::vector<std::string> args = pneud_args({"--identify", identified.string(), "--armed"});
    args.insert(args.end(), model.begin(), model.end());
    Child pneud = Child::spawn(args, dir_ / "identify.out", dir_ / "identify.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "identify.err") << slurp(dir_ / "identify.out");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  }
  const std::string report = slurp(dir_ / "identify.out");
  std::printf("%s", report.substr(report.find("identified from")).c_str());
  const pneu::config::Config id = pneu::config::load_file(identified);
  ASSERT_TRUE(id.plant.has_thermal);
  // Over the link the model fits within twice the noise when the loop keeps its deadlines (25.9 Pa
  // for 18.5 explained on an idle machine, 35.7 Pa with one of its two cores busy, at ordinary
  // scheduling; 24 to 28 Pa with both busy at SCHED_FIFO); with both busy at ordinary scheduling
  // the loop skips deadlines within the stuck phases, each shifting when a command reached the
  // valves, and the fit reached 57 Pa: then it must say so, name the timing as a suspect, and every
  // forecast made on what it identified must say it is uncertain.
  const bool fits = report.find("the model fits the stuck phases' pressures") != std::string::npos;
  if (!fits) {
    EXPECT_THAT(report, HasSubstr("THE MODEL DOES NOT FIT"));
    EXPECT_THAT(report, HasSubstr("Or the commands' timing: the loop skipped"))
        << "a misfit while the loop kept every deadline is the model's";
    std::printf("the model does not fit over this link (the loop skipped deadlines): forecasts judged, flagged uncertain\n");
  }

  // The paper's step (its gains) on the identified configuration, judged against serve's record;
  // the hold off (the phase judged is the one it prevents).
  int long_restarts = 0, runs = 0;
  for (; runs < 3 && long_restarts == 0; ++runs) {
    const std::string events = "paper" + std::to_string(runs) + ".jsonl";
    const fs::path plant_events = dir_ / ("plant" + std::to_string(runs) + ".jsonl");
    std::vector<std::string> served = bench;
    served.insert(served.end(), {"--events", plant_events.string()});
    Child plant = serve(15.0, served);
    std::vector<std::string> args = pneud_args(with({"--events", (dir_ / events).string(), "--summary-json", summary_json(),
                                                     "--set", "controller.law.gains=fixed", "--set",
                                                     "controller.hold.enabled=false"},
                                                    no_movement_test()));
    args[2] = identified.string();  // --config
    Child pneud = Child::spawn(args, dir_ / "paper.out", dir_ / "paper.err");
    ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "paper.err");
    kill(plant.pid, SIGINT);
    ASSERT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
    const double epoch = pneu::test::PneudSummary::read(summary_json()).epoch_monotonic_s;
    ASSERT_TRUE(std::isfinite(epoch));
    // The plant's own record of its motion, on pneud's loop time.
    const Motion motion = plant_motion(slurp(plant_events), epoch);
    ASSERT_FALSE(motion.empty()) << slurp(plant_events);
    const std::string events_text = slurp(dir_ / events);
    EXPECT_EQ(events_text.find("\"model_fits\":false") == std::string::npos, fits)
        << "the forecasts carry the identification's verdict";
    const std::map<int, StopRecord> stops = stops_of(events_text);
    for (const auto& [idx, st] : stops) {
      if (std::isnan(st[2])) continue;
      // Judged where the plant had stuck by 50 ms after pneud called the stop (pneud calls it
      // over the last micrometres of the motion; a slow slide along the stiction bound can read as
      // a stop for a few ticks): the plant's first breakaway after.
      const auto after = std::find_if(motion.begin(), motion.end(), [&](const auto& m) { return m.first > st[0] + 0.05; });
      if (after == motion.begin() || !std::prev(after)->second) {
        std::printf("run %d, stop %d at %.3f s: the plant was sliding, not judged\n", runs, idx, st[0]);
        continue;
      }
      ASSERT_NE(after, motion.end()) << "stop " << idx << ": pneud saw a restart the plant's record does not hold";
      const double breakaway = after->first;
      const double sticking = breakaway - st[0];
      if (sticking < 0.5) continue;
      ++long_restarts;
      std::printf("run %d, stop %d: stuck %.3f s by serve's record (pneud dated the start %+.1f ms from it), forecast %.2f %% off\n",
                  runs, idx, sticking, 1e3 * (st[2] - breakaway), 100 * std::abs(st[1] - breakaway) / sticking);
      EXPECT_LE(std::abs(st[1] - breakaway), 0.05 * sticking) << "run " << runs << ", stop " << idx;
    }
  }
  EXPECT_GE(long_restarts, 1) << "a sticking phase of 0.5 s or more ending in a restart, in " << runs << " runs";
}

TEST_F(Hil, ServesUpToMaxClientsAtOnceAndClosesOneMoreWithALineOnStderr) {
  // By default four clients, as many I/O modules; --max-clients sets another number. Each client
  // is served before the next connects: accepted in that order.
  using Connection = std::unique_ptr<modbus_t, void (*)(modbus_t*)>;
  const auto connect = [&] {
    modbus_t* c = modbus_new_tcp("127.0.0.1", port_);
    modbus_set_slave(c, 1);
    EXPECT_EQ(modbus_connect(c), 0);
    return Connection(c, [](modbus_t* p) {
      modbus_close(p);
      modbus_free(p);
    });
  };
  for (const auto& [extra, limit] : std::vector<std::pair<std::vector<std::string>, int>>{{{}, 4}, {{"--max-clients", "2"}, 2}}) {
    SCOPED_TRACE("up to " + std::to_string(limit) + " clients");
    Child plant = serve(5.0, extra);
    uint16_t regs[3] = {};
    std::vector<Connection> served;
    for (int i = 0; i < limit; ++i) {
      served.push_back(connect());
      EXPECT_EQ(modbus_read_registers(served.back().get(), 0, 3, regs), 3) << "client " << i + 1;
    }
    Connection one_more = connect();  // accepted, then closed
    modbus_set_response_timeout(one_more.get(), 0, 200000);
    EXPECT_EQ(modbus_read_registers(one_more.get(), 0, 3, regs), -1) << "one more client gets no answer";
    for (auto& c : served) EXPECT_EQ(modbus_read_registers(c.get(), 0, 3, regs), 3) << "the others are still served";
    served.clear();
    one_more.reset();
    kill(plant.pid, SIGTERM);
    EXPECT_EQ(plant.wait(), 0);
    EXPECT_THAT(slurp(dir_ / "serve.err"), HasSubstr("refused a client from 127.0.0.1:"));
    EXPECT_THAT(slurp(dir_ / "serve.err"), HasSubstr("already serving " + std::to_string(limit)));
    EXPECT_THAT(slurp(dir_ / "serve.out"),
                HasSubstr("(at most " + std::to_string(limit) + " at once, 1 refused beyond --max-clients)"));
  }
}

TEST_F(Hil, MbpollReadsBesidePneudWhichSeesNoErrorAndMbpollMayNotWriteTheValves) {
  if (!has_mbpoll()) GTEST_SKIP() << "mbpoll (Debian package mbpoll) is not installed";
  Child plant = serve(10.0);
  Child pneud = Child::spawn(pneud_args({"--duration", "3", "--summary-json", summary_json()}), dir_ / "pneud.out",
                             dir_ / "pneud.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "writes the valve registers", 5s)) << slurp(dir_ / "pneud.err");
  // While pneud drives the valves, mbpoll polls the sensor registers, one connection a poll, and
  // once tries to write the valve registers.
  int polls = 0, write_rc = 0;
  std::string failed;
  while (!fs::exists(summary_json())) {  // it appears at the end of pneud's run
    if (polls == 5 && write_rc == 0) write_rc = mbpoll(port_, "-t 4 -r 17", dir_ / "mbpoll_write.out", "0 0");
    const fs::path out = dir_ / "mbpoll.out";
    if (mbpoll(port_, "-t 4 -r 1 -c 3", out) != 0 || mbpoll_words(slurp(out)).size() != 3) failed += slurp(out);
    ++polls;
  }
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  EXPECT_GE(polls, 6) << "mbpoll polled while pneud ran";
  EXPECT_EQ(failed, "") << "every poll read the three registers";
  EXPECT_NE(write_rc, 0);
  EXPECT_THAT(slurp(dir_ / "mbpoll_write.out"), HasSubstr("Slave device or server is busy")) << "exception 06";
  const auto summary = pneu::test::PneudSummary::read(summary_json());
  ASSERT_TRUE(summary.has_loop && summary.has_modbus) << slurp(dir_ / "pneud.out");
  EXPECT_EQ(summary.errors, 0u) << "pneud's exchanges all answered beside mbpoll's";
  EXPECT_EQ(summary.reconnects, 0u);
  EXPECT_EQ(summary.ticks + summary.skipped, 3001u);
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("1 valve writes refused as another client's"));
}

TEST_F(Hil, AClientThatDribblesItsRequestOrSendsBadOnesHoldsUpNotPneudBesideIt) {
  // pneud's response timeout is 0.5 s here (link_stalls_tolerated): a server that waited in
  // modbus_receive for the rest of the dribbled request (1.2 s) would time pneud out.
  Child plant = serve(10.0);
  Child pneud = Child::spawn(pneud_args({"--duration", "3", "--summary-json", summary_json()}), dir_ / "pneud.out",
                             dir_ / "pneud.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "writes the valve registers", 5s)) << slurp(dir_ / "pneud.err");

  // A request one byte every 100 ms: answered once whole.
  const int slow = connect_loopback(port_);
  ASSERT_GE(slow, 0);
  bool sent = true;
  for (const std::uint8_t byte : read_request(0x1234, 3)) {
    sent = sent && send(slow, &byte, 1, MSG_NOSIGNAL) == 1;
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(sent) << "the server dropped the slow client";
  const auto reply = receive(slow, 15, 3s);
  close(slow);
  EXPECT_EQ(reply.size(), 15u) << "MBAP, function 3, byte count, 3 registers";
  if (reply.size() == 15u) {
    EXPECT_EQ(reply[0] << 8 | reply[1], 0x1234) << "its transaction";
    EXPECT_EQ(reply[7], 3);
    EXPECT_EQ(reply[8], 6);
  }

  // Requests for more registers than a read carries, from three clients at once: libmodbus
  // answers each with exception 03 after sleeping its response timeout (0.5 s by default).
  std::vector<int> bad;
  for (std::uint16_t id = 1; id <= 3; ++id) {
    bad.push_back(connect_loopback(port_));
    ASSERT_GE(bad.back(), 0);
    const auto request = read_request(id, 200);
    EXPECT_EQ(send(bad.back(), request.data(), request.size(), MSG_NOSIGNAL), static_cast<ssize_t>(request.size()));
  }
  for (const int fd : bad) {
    const auto exception = receive(fd, 9, 3s);
    close(fd);
    EXPECT_EQ(exception.size(), 9u);
    if (exception.size() == 9u) {
      EXPECT_EQ(exception[7], 0x83);
      EXPECT_EQ(exception[8], MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE);
    }
  }
  // Half a request, and gone.
  const int half = connect_loopback(port_);
  ASSERT_GE(half, 0);
  ASSERT_EQ(send(half, read_request(7, 3).data(), 5, MSG_NOSIGNAL), 5);
  close(half);

  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  const auto summary = pneu::test::PneudSummary::read(summary_json());
  ASSERT_TRUE(summary.has_modbus) << slurp(dir_ / "pneud.out");
  EXPECT_EQ(summary.errors, 0u) << "no exchange of pneud's waited on the other clients";
  EXPECT_EQ(summary.reconnects, 0u);
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
}

TEST_F(Hil, AClientMayWriteTheValvesOnceTheOwnerLeftEvenWhenTheServerLearnsBothAtOnce) {
  // As pneud does after a timeout: it gives up its connection, a request unanswered, and writes
  // on a new one. Here the plant is stopped meanwhile (a stall of the machine): on waking it finds
  // the old connection's request and end, and the new connection's write, in one select. The new
  // connection was accepted first, so that it comes first in the plant's table.
  Child plant = serve(10.0);
  const int next = connect_loopback(port_);
  ASSERT_GE(next, 0);
  const auto send_all = [](int fd, const std::vector<std::uint8_t>& bytes) {
    return send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(bytes.size());
  };
  ASSERT_TRUE(send_all(next, read_request(1, 3)));
  ASSERT_EQ(receive(next, 15, 3s).size(), 15u) << "accepted and served";
  const int first = connect_loopback(port_);
  ASSERT_GE(first, 0);
  ASSERT_TRUE(send_all(first, write_valves_request(2, 1000, 2000)));
  ASSERT_EQ(receive(first, 12, 3s).size(), 12u) << "the first writer owns the valves";

  kill(plant.pid, SIGSTOP);
  ASSERT_TRUE(send_all(first, write_valves_request(3, 1000, 2000)));
  close(first);
  ASSERT_TRUE(send_all(next, write_valves_request(4, 3000, 4000)));
  kill(plant.pid, SIGCONT);
  const auto reply = receive(next, 12, 3s);
  close(next);
  ASSERT_GE(reply.size(), 9u);
  EXPECT_EQ(reply[7], MODBUS_FC_WRITE_MULTIPLE_REGISTERS) << "not exception 06 (0x90): the owner had left";
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("0 valve writes refused"));
}

TEST_F(Hil, MbpollReadsThePlantsRegisters) {
  if (!has_mbpoll()) GTEST_SKIP() << "mbpoll (Debian package mbpoll) is not installed";
  Child plant = serve(5.0);
  // Holding registers 0..2 (mbpoll counts from 1 unless -0): position, p_P, p_N as 16-bit words.
  const fs::path out = dir_ / "mbpoll.out";
  ASSERT_EQ(mbpoll(port_, "-t 4 -r 1 -c 3", out), 0) << slurp(out);
  std::map<int, long> words = mbpoll_words(slurp(out));
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

TEST_F(Hil, APushOfTheConfigurationMovesTheServedCarriageOnServesOwnTime) {
  // hal.sim.pushes on pneu-plant serve: -300 N for 0.3 s from 1.5 s after it starts, the valves at
  // their neutral voltages (no client writes them).
  Child plant = serve(6.0, {"--set", "hal.sim.pushes=[{t_s: 1.5, force_n: -300, duration_s: 0.3}]"});
  const auto position_m = [&]() -> double {
    const int fd = connect_loopback(port_);
    EXPECT_GE(fd, 0);
    const auto request = read_request(1, 1);
    EXPECT_EQ(send(fd, request.data(), request.size(), MSG_NOSIGNAL), static_cast<ssize_t>(request.size()));
    const auto reply = receive(fd, 11, 3s);
    close(fd);
    if (reply.size() != 11u) return NAN;
    const double word = reply[9] * 256.0 + reply[10];
    return (word * 10.0 / 65535.0 - 5.0) / 20.0;  // hil.yaml: 20 V/m, 5 V at mid-stroke
  };
  const double before = position_m();
  EXPECT_NEAR(before, 0.2195, 1e-4) << "at rest at the configured 219.5 mm before the push";
  std::this_thread::sleep_for(3s);
  const double after = position_m();
  EXPECT_LT(after, before - 1e-3) << "pushed towards -: measured " << after;
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
  Child pneud = Child::spawn(pneud_args(with({"--duration", "3", "--summary-json", summary_json()}, no_movement_test()),
                                        /*bench_link=*/true),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  // The safe output not confirmed (below), and the comms fault latched: exit code 4, said first.
  ASSERT_EQ(pneud.wait(), 4) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  const std::string out = slurp(dir_ / "pneud.out");
  EXPECT_THAT(out, ::testing::StartsWith("SAFE OUTPUT NOT CONFIRMED: the module did not confirm the safe output on "
                                         "closing (3 attempts): it may still hold the last command, and the run "
                                         "ended with a fault latched (comms, since "));
  const auto summary = pneu::test::PneudSummary::read(summary_json());
  ASSERT_TRUE(summary.has_loop && summary.has_modbus) << out;
  EXPECT_GE(summary.errors, 5u) << "each late reply is a counted comms error";
  EXPECT_GE(summary.reconnects, 5u) << "and the I/O thread closes and reconnects (libmodbus issue #255)";
  // Each stale read is a tick: over 1000 of them in the 2 s of late replies, where a loop waiting
  // on the module would tick once per 20 ms timeout (100 times).
  EXPECT_GT(summary.stale, 1000u) << "the loop saw the samples go stale: flagged, not waited for";
  EXPECT_EQ(summary.ticks + summary.skipped, 3001u) << "every deadline of the 3 s run was met or accounted for";
  // The safe output is tried three times on closing, each on a fresh connection; none is answered
  // in time, and pneud says so, on stderr too (the journal's).
  EXPECT_FALSE(summary.safe_output_delivered);
  EXPECT_EQ(summary.safe_output_attempts, 3u);
  EXPECT_THAT(out, HasSubstr("safe output on closing: NOT confirmed by the module after 3 attempts"));
  EXPECT_THAT(slurp(dir_ / "pneud.err"),
              HasSubstr("the module did not confirm the safe output on closing (3 attempts, last error: "));
}

// controller.realtime on the modbus backend: the loop thread and the I/O thread that carries each
// tick's reading and command both run SCHED_FIFO at the configured priority (the I/O thread
// inherits it: on a busy machine an I/O thread of ordinary scheduling delays the exchanges and the
// loop reads stale samples); the service thread (telemetry, the runtime's drain) keeps the
// ordinary scheduling. Read from /proc/PID/task/TID/stat (rt_priority, policy).
TEST_F(Hil, WithARealtimePriorityTheModbusIoThreadRunsAtTheLoopsPriority) {
  if (std::system("chrt -f 1 true 2>/dev/null") != 0) GTEST_SKIP() << "SCHED_FIFO is not permitted here (RLIMIT_RTPRIO, CAP_SYS_NICE)";
  Child plant = serve(10.0);
  Child pneud = Child::spawn(pneud_args(with({"--duration", "1.5", "--set", "controller.realtime.priority=7"}, no_movement_test())),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  std::this_thread::sleep_for(800ms);
  int fifo_at_7 = 0, other = 0;
  for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(pneud.pid) + "/task")) {
    const std::string stat = slurp(task.path() / "stat");
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));  // from field 3 (the name may hold spaces)
    std::vector<std::string> f{std::istream_iterator<std::string>(fields), {}};
    ASSERT_GT(f.size(), 38u) << stat;
    const int rt_priority = std::stoi(f[37]), policy = std::stoi(f[38]);  // fields 40 and 41
    if (policy == SCHED_FIFO && rt_priority == 7) ++fifo_at_7;
    else if (policy == SCHED_OTHER) ++other;
  }
  EXPECT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  EXPECT_EQ(fifo_at_7, 2) << "the loop thread and the Modbus I/O thread";
  EXPECT_GE(other, 1) << "the service thread keeps the ordinary scheduling";
}

TEST_F(HilOnTime, RtuOverAPtyPairAt115200BaudKeepsTheLoopRateAndFreshSamplesWithTheLoopOnTime) {
  if (system("command -v socat > /dev/null") != 0) GTEST_SKIP() << "socat (Debian package socat) is not installed";
  const fs::path a = dir_ / "ttyA", b = dir_ / "ttyB";
  Child pty = Child::spawn(answering_on_time({"socat", "pty,raw,echo=0,link=" + a.string(), "pty,raw,echo=0,link=" + b.string()}),
                           dir_ / "socat.out", dir_ / "socat.err");
  ASSERT_TRUE(pneu::test::eventually([&] { return fs::exists(a) && fs::exists(b); }, 2s)) << slurp(dir_ / "socat.err");
  // The server holds each reply for the time it takes on a real 115200 baud line (a pty has no
  // speed of its own): a function-23 exchange of 28 bytes plus silences takes about 3 ms.
  Child plant = Child::spawn(answering_on_time({bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set", "hal.modbus.transport=rtu",
                                                 "--set", "hal.modbus.device=" + a.string(), "--duration", "6"}),
                             dir_ / "serve.out", dir_ / "serve.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "serving", 3s)) << slurp(dir_ / "serve.err");
  // The sample age limit is hil.yaml's 20 ms, this test's subject; a stall of the plant or of
  // socat shorter than the tolerant response timeout is no comms error (see link_stalls_tolerated).
  Child pneud = Child::spawn(pneud_args({"--duration", "3", "--set", "hal.modbus.transport=rtu", "--set",
                                         "hal.modbus.device=" + b.string(), "--set", "hal.modbus.max_sample_age_s=0.02",
                                         "--summary-json", summary_json()}),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0);
  const std::string out = slurp(dir_ / "pneud.out");
  const auto summary = pneu::test::PneudSummary::read(summary_json());
  ASSERT_TRUE(summary.has_loop && summary.has_modbus) << out;
  std::printf("%.0f exchanges/s, %llu stale reads of %llu ticks, oldest %.1f ms\n", summary.rate_per_s, summary.stale,
              summary.ticks, summary.oldest_ms);
  EXPECT_EQ(summary.ticks + summary.skipped, 3001u) << "the loop kept its 1 kHz deadlines";
  EXPECT_EQ(summary.errors, 0u);
  EXPECT_GT(summary.rate_per_s, 100.0) << "exchanges as often as the line allows";
  EXPECT_LT(summary.rate_per_s, 400.0) << "and no more often than a 115200 baud line allows";
  EXPECT_LE(summary.stale, summary.ticks / 100) << "samples stay within the 20 ms age limit (oldest " << summary.oldest_ms << " ms)";
}

}  // namespace
