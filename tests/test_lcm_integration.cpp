// pneud among real LCM tools, inside a private network namespace (tests/in_private_netns.sh):
// recorded by the real lcm-logger, and steered by a real LCM publisher.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <pwd.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/event_t.hpp"
#include "pneu_lcm/health_t.hpp"
#include "pneu_lcm/identification_t.hpp"
#include "pneu_lcm/prediction_t.hpp"
#include "pneu_lcm/state_t.hpp"

#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/lcm_sniffer.hpp"

namespace {

using pneu::test::bin;

namespace fs = std::filesystem;
using pneu::test::Child;
using pneu::test::Csv;
using pneu::test::loop_timing_faults_off;
using pneu::test::slurp;
using ::testing::HasSubstr;
using ::testing::Not;
using namespace std::chrono_literals;

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";


class LcmIntegration : public ::testing::Test {
 protected:
  // pneud on the real clock until SIGTERM, with no schedule (armed, holding 219.5 mm until
  // commanded) and `args` added; returned once its state is heard (its loop ticking).
  Child start_commanded_pneud(const std::vector<std::string>& args) {
    pneu::test::LcmSniffer sniffer;
    EXPECT_TRUE(sniffer.good());
    std::vector<std::string> command = {bin("pneud"), "--clock", "real", "--duration", "0", "--require-telemetry",
                                        "--set", "controller.setpoints.schedule=[]"};
    command.insert(command.end(), args.begin(), args.end());
    Child pneud = Child::spawn(loop_timing_faults_off(command), dir_ / "pneud.out", dir_ / "pneud.err");
    std::string channel;
    std::vector<std::uint8_t> payload;
    EXPECT_TRUE(pneu::test::eventually(
        [&] { return sniffer.receive(channel, payload, 100) && channel == "PNEU_STATE"; }, 10s, 1ms))
        << "pneud up, its loop ticking";
    return pneud;
  }

  pneu::test::TestDir dir_{"pneu_lcm_"};
};

// How many events on `channel` an LCM log holds so far (0 while it does not exist yet).
int events_in_log(const fs::path& log, const std::string& channel) {
  lcm::LogFile file(log.string(), "r");
  if (!file.good()) return 0;
  int n = 0;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) n += e->channel == channel;
  return n;
}

// Waits, up to 10 s, until the logger has received what pneud published: until `log` holds a state
// of each of the `ticks` ticks, or its count of states has not grown for half a second. lcm-logger
// writes the last few messages it received only when it stops (measured: 2982 of 2995 states in
// the file for 10 s after pneud ended, all 2995 once it stopped), so a file that stopped growing
// means that all the datagrams are in; the rest is written on SIGINT.
void wait_for_logger(const fs::path& log, std::size_t ticks) {
  int last = -1;
  auto since = std::chrono::steady_clock::now();
  (void)pneu::test::eventually(
      [&] {
        const int n = events_in_log(log, "PNEU_STATE");
        if (n != last) last = n, since = std::chrono::steady_clock::now();
        return n >= static_cast<int>(ticks) || std::chrono::steady_clock::now() - since >= 500ms;
      },
      10s, 100ms);  // judged by the caller, from the log once the logger stopped
}

// lcm-logger recording PNEU_.* into `log`, subscribed (a probe of its own is in the log) before
// it returns.
Child start_logger(const fs::path& log, const fs::path& dir) {
  Child logger = Child::spawn({"lcm-logger", "-q", "-f", std::string("--lcm-url=") + kUrl, "-c", "PNEU_.*", log.string()},
                              dir / "logger.out", dir / "logger.err");
  EXPECT_GT(logger.pid, 0) << "lcm-logger (package liblcm-bin) did not start";
  lcm::LCM probe(kUrl);
  EXPECT_TRUE(probe.good());
  const char probe_data[1] = {0};
  for (int i = 0; i < 100 && events_in_log(log, "PNEU_PROBE") == 0; ++i) {
    probe.publish("PNEU_PROBE", probe_data, sizeof probe_data);
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_GT(events_in_log(log, "PNEU_PROBE"), 0) << "lcm-logger did not subscribe within 10 s";
  return logger;
}

TEST_F(LcmIntegration, LcmLoggerRecordsEveryTickInOrderWithEventsAndPredictions) {
  const fs::path log = dir_ / "run.lcm";
  Child logger = start_logger(log, dir_);
  ASSERT_FALSE(::testing::Test::HasFailure());

  Child pneud = Child::spawn(loop_timing_faults_off({bin("pneud"), "--clock", "real", "--duration", "3",
                                                     "--require-telemetry", "--trajectory", (dir_ / "traj.csv").string(),
                                                     "--events", (dir_ / "events.jsonl").string(), "--summary-json",
                                                     (dir_ / "summary.json").string()}),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  // Until the logger has received every tick's state it will get, then stop it.
  wait_for_logger(log, Csv::read(dir_ / "traj.csv").rows.size());
  kill(logger.pid, SIGINT);
  ASSERT_EQ(logger.wait(), 0) << slurp(dir_ / "logger.err");

  // Read the log itself.
  lcm::LogFile file(log.string(), "r");
  ASSERT_TRUE(file.good());
  std::vector<pneu_lcm::state_t> states;
  std::map<std::string, int> counts;
  std::vector<pneu_lcm::event_t> events;
  int predictions = 0, at_stops = 0, made_again = 0;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) {
    ++counts[e->channel];
    if (e->channel == "PNEU_STATE") {
      pneu_lcm::state_t s;
      ASSERT_EQ(s.decode(e->data, 0, e->datalen), e->datalen);
      states.push_back(s);
    } else if (e->channel == "PNEU_EVENT") {
      pneu_lcm::event_t ev;
      ASSERT_GT(ev.decode(e->data, 0, e->datalen), 0);
      events.push_back(ev);
    } else if (e->channel == "PNEU_PREDICTION") {
      pneu_lcm::prediction_t p;
      ASSERT_GT(p.decode(e->data, 0, e->datalen), 0);
      ++predictions;
      if (p.update == 0) {
        ++at_stops;
        EXPECT_GE(p.t, p.t_stop) << "made when the stop is confirmed";
      } else {
        // The live predictor, while stuck: from the pressures of the moment, against the
        // forecast made at the stop.
        ++made_again;
        EXPECT_GE(p.t, p.t_stop + p.update * 0.1 - 1e-9) << "every 0.1 s while stuck";
        EXPECT_TRUE(std::isfinite(p.force) && std::isfinite(p.stop_forecast_force));
      }
    }
  }
  const Csv traj = Csv::read(dir_ / "traj.csv");
  ASSERT_EQ(states.size(), traj.rows.size()) << "every tick's state arrives";
  for (std::size_t i = 0; i < states.size(); ++i) ASSERT_EQ(states[i].seq, static_cast<int64_t>(i)) << "in order, no gap";
  // Every deadline of the 3 s run was ticked, or skipped after an overrun the shared machine
  // caused (pneud counts those; timing is not this test's business).
  const auto summary = pneu::test::PneudSummary::read(dir_ / "summary.json");
  ASSERT_TRUE(summary.has_loop);
  const auto ticks = summary.ticks, skipped = summary.skipped;
  EXPECT_EQ(states.size(), ticks);
  EXPECT_EQ(ticks + skipped, 3001u);
  // The events and forecasts in the log are those pneud wrote to its events file: how many stops
  // and restarts the run had is the bench's business (on a loaded machine, with deadlines skipped,
  // the short first sticking phase may not come), that each is published is this test's.
  std::map<std::string, int> written;
  {
    std::ifstream in(dir_ / "events.jsonl");
    for (std::string line; std::getline(in, line);) {
      for (const char* kind : {"stop", "prediction", "reforecast"})
        if (line.find(std::string("{\"event\":\"") + kind + "\"") == 0) ++written[kind];
      if (line.find("{\"event\":\"start\"") == 0 && line.find("\"restart\":true") != std::string::npos)
        ++written["restart"];
    }
  }
  const auto logged = [&](std::int8_t kind) {
    return static_cast<int>(std::count_if(events.begin(), events.end(), [&](const auto& e) { return e.kind == kind; }));
  };
  ASSERT_GE(written["stop"], 1) << "the default bench sticks near its set point within 3 s: " << slurp(dir_ / "events.jsonl");
  EXPECT_EQ(logged(pneu_lcm::event_t::KIND_STOP), written["stop"]);
  EXPECT_EQ(logged(pneu_lcm::event_t::KIND_RESTART), written["restart"]);
  EXPECT_EQ(at_stops, written["prediction"]) << "each stop's forecasts, both methods";
  EXPECT_EQ(at_stops, 2 * written["stop"]);
  EXPECT_EQ(made_again, written["reforecast"]);
  EXPECT_GT(made_again, 0) << "the last sticking phase lasts past 0.1 s: re-forecast while stuck";
  EXPECT_GE(counts["PNEU_HEALTH"], 2);

  // The converter's CSV holds the same.
  const fs::path csv_dir = dir_ / "csv";
  ASSERT_EQ(std::system((bin("pneu-log2csv") + " " + log.string() + " " + csv_dir.string() + " > " +
                         (dir_ / "conv.out").string() + " 2>&1").c_str()),
            0)
      << slurp(dir_ / "conv.out");
  const Csv st = Csv::read(csv_dir / "PNEU_STATE.csv");
  ASSERT_EQ(st.rows.size(), states.size());
  const std::size_t c_seq = st.col("seq"), c_y = st.col("y"), c_u = st.col("u"), c_pp = st.col("p_p");
  for (std::size_t i = 0; i < states.size(); ++i) {
    ASSERT_EQ(std::stoll(st.rows[i][c_seq]), states[i].seq);
    ASSERT_EQ(std::stod(st.rows[i][c_y]), states[i].y) << "row " << i;  // %.17g round-trips
    ASSERT_EQ(std::stod(st.rows[i][c_u]), states[i].u) << "row " << i;
    ASSERT_EQ(std::stod(st.rows[i][c_pp]), states[i].p_p) << "row " << i;
    // ... and pneud's own trajectory, printed with 9 to 12 significant digits.
    ASSERT_NEAR(std::stod(traj.rows[i][3]), states[i].y, 1e-11) << "row " << i;
  }
  EXPECT_EQ(Csv::read(csv_dir / "PNEU_EVENT.csv").rows.size(), events.size());
  EXPECT_EQ(Csv::read(csv_dir / "PNEU_PREDICTION.csv").rows.size(), static_cast<std::size_t>(predictions));
}

// Collects what pneud publishes about commands, read off the group (see LcmSniffer).
struct Listener {
  std::mutex m;
  std::vector<pneu_lcm::event_t> events;
  pneu_lcm::health_t last_health{};
  int health_count = 0;
  pneu::test::LcmSniffer sniffer;
  // One datagram, if one comes within `timeout_ms`.
  void poll(int timeout_ms) {
    std::string channel;
    std::vector<std::uint8_t> payload;
    if (!sniffer.receive(channel, payload, timeout_ms)) return;
    const int size = static_cast<int>(payload.size());
    std::lock_guard<std::mutex> l(m);
    if (channel == "PNEU_EVENT") {
      pneu_lcm::event_t e;
      if (e.decode(payload.data(), 0, size) == size) events.push_back(e);
    } else if (channel == "PNEU_HEALTH") {
      pneu_lcm::health_t h;
      if (h.decode(payload.data(), 0, size) == size) {
        last_health = h;
        ++health_count;
      }
    }
  }
  // Whether `seen` (called under the lock) holds within `limit`, while another thread polls.
  bool wait_for(const std::function<bool()>& seen, std::chrono::milliseconds limit) {
    return pneu::test::eventually(
        [&] {
          std::lock_guard<std::mutex> l(m);
          return seen();
        },
        limit, 5ms);
  }
};

pneu_lcm::command_t command(int64_t seq, int8_t kind, double value) {
  pneu_lcm::command_t c{};
  // Stamped now: pneud refuses commands stamped further than commands.max_age_s from its clock.
  c.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                std::chrono::system_clock::now().time_since_epoch())
                .count();
  c.seq = seq;
  c.kind = kind;
  c.value = value;
  return c;
}

// Issue 15, online: pneud learning online (controller.predictor.learn_online) on a bench whose
// stiction is not the model's publishes its running estimate on PNEU_IDENTIFICATION, and
// pneu-identify, offline from the LCM log of the same run, gives the same estimates within their
// uncertainty. F_S- is bounded from beyond by the first restart after a stuck phase: in 4 s of the
// real clock that was the run's second and last update. On a machine loaded enough to skip
// deadlines (a fresh-machine check beside a CI run) the test failed once with F_S- not identified,
// most likely because that update had not come; 6 s leave room.
TEST_F(LcmIntegration, OnlineIdentificationIsPublishedAndTheLogIdentifiesTheSameOffline) {
  const fs::path log = dir_ / "run.lcm";
  Child logger = start_logger(log, dir_);
  ASSERT_FALSE(::testing::Test::HasFailure());
  Child pneud = Child::spawn(
      loop_timing_faults_off({bin("pneud"), "--clock", "real", "--duration", "6", "--require-telemetry", "--set",
                              "controller.predictor.learn_online=true", "--set",
                              "hal.sim.plant.friction.static_negative_n=-53", "--trajectory", (dir_ / "traj.csv").string()}),
      dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  wait_for_logger(log, Csv::read(dir_ / "traj.csv").rows.size());
  kill(logger.pid, SIGINT);
  ASSERT_EQ(logger.wait(), 0) << slurp(dir_ / "logger.err");
  EXPECT_THAT(slurp(dir_ / "pneud.out"), HasSubstr("online identification: "));

  lcm::LogFile file(log.string(), "r");
  ASSERT_TRUE(file.good());
  std::vector<pneu_lcm::identification_t> updates;
  for (const lcm::LogEvent* e = file.readNextEvent(); e; e = file.readNextEvent()) {
    if (e->channel != "PNEU_IDENTIFICATION") continue;
    pneu_lcm::identification_t m{};
    ASSERT_EQ(m.decode(e->data, 0, e->datalen), e->datalen);
    updates.push_back(m);
  }
  ASSERT_FALSE(updates.empty()) << "an update at each stop after a breakaway";
  const auto& online = updates.back();
  EXPECT_EQ(online.updates, static_cast<int32_t>(updates.size()));
  const int fs_neg = pneu_lcm::identification_t::STATIC_NEGATIVE_N;
  ASSERT_EQ(online.identified[fs_neg], 1) << "the restarts of the paper's step are negative";
  EXPECT_NEAR(online.value[fs_neg], -53.0, 0.02 * 53.0);

  // Offline, from the log.
  const fs::path identified = dir_ / "identified.yaml";
  Child offline = Child::spawn({bin("pneu-identify"), "--lcm-log", log.string(), "--out", identified.string()},
                               dir_ / "identify.out", dir_ / "identify.err");
  ASSERT_EQ(offline.wait(), 0) << slurp(dir_ / "identify.err");
  // The written F_S- against the online one, within their uncertainties (3 sigma of both).
  const std::string yaml = slurp(identified);
  const auto at = yaml.find("\n    static_negative_n: ");
  ASSERT_NE(at, std::string::npos) << yaml;
  const double offline_fs_neg = std::stod(yaml.substr(at + 24));
  // Its line carries the note "# identified DATE: VALUE +- SIGMA (was ...)".
  const std::string line = yaml.substr(at + 1, yaml.find('\n', at + 1) - at - 1);
  const auto note = line.find("# identified ");
  ASSERT_NE(note, std::string::npos) << line;
  const auto pm = line.find(" +- ", note);
  ASSERT_NE(pm, std::string::npos) << line;
  const double offline_sigma = std::stod(line.substr(pm + 4));
  std::printf("F_S-: online %.4f +- %.4f (%d updates), offline %.4f +- %.4f\n", online.value[fs_neg],
              online.sigma[fs_neg], online.updates, offline_fs_neg, offline_sigma);
  EXPECT_LE(std::abs(online.value[fs_neg] - offline_fs_neg), 3 * (online.sigma[fs_neg] + offline_sigma));
}

TEST_F(LcmIntegration, CommandsAreValidatedAndOnlyValidOnesReachTheLoop) {
  lcm::LCM lcm(kUrl);
  ASSERT_TRUE(lcm.good());
  Listener listener;
  ASSERT_TRUE(listener.sniffer.good());
  std::atomic<bool> done{false};
  std::thread handler([&] {
    while (!done) listener.poll(20);
  });

  // No schedule: the carriage holds 219.5 mm until commanded.
  Child pneud = Child::spawn(loop_timing_faults_off({bin("pneud"), "--clock", "real", "--duration", "4",
                                                     "--require-telemetry", "--set", "controller.setpoints.schedule=[]",
                                                     "--set", "telemetry.health_period_s=0.5", "--set",
                                                     "commands.max_rate_hz=100", "--set", "commands.burst=5",
                                                     "--trajectory", (dir_ / "traj.csv").string(), "--summary-json",
                                                     (dir_ / "summary.json").string()}),
                             dir_ / "pneud.out", dir_ / "pneud.err");
  ASSERT_TRUE(listener.wait_for([&] { return listener.health_count > 0; }, 10s)) << "pneud up, its loop ticking";
  using C = pneu_lcm::command_t;
  // One at a time: each is judged (one event, accepted or rejected) before the next is sent, and
  // 20 ms later, so that a stall of the machine cannot bunch them over the rate limit (100 per
  // second here); and UDP has no flow control.
  const auto send = [&](const C& c) {
    std::size_t before = 0;
    {
      std::lock_guard<std::mutex> l(listener.m);
      before = listener.events.size();
    }
    ASSERT_EQ(lcm.publish("PNEU_COMMAND", &c), 0);
    ASSERT_TRUE(listener.wait_for([&] { return listener.events.size() > before; }, 5s)) << "command " << c.seq;
    std::this_thread::sleep_for(20ms);
  };
  send(command(10, C::KIND_SET_POINT, 0.170));          // valid (the paper's step: settled within 1 s)
  send(command(11, C::KIND_SET_POINT, 0.900));          // outside the soft limits
  send(command(12, C::KIND_SET_POINT, std::nan("")));   // not finite
  send(command(5, C::KIND_SET_POINT, 0.120));           // sequence going back
  send(command(13, 42, 0.0));                           // unknown kind
  send(command(14, C::KIND_ARM, 0.0));                  // already armed
  pneu_lcm::state_t wrong{};                            // wrongly typed message
  ASSERT_EQ(lcm.publish("PNEU_COMMAND", &wrong), 0);
  const char garbage[3] = {1, 2, 3};
  for (int i = 0; i < 200; ++i) {  // a stream of garbage at 1 kHz
    ASSERT_EQ(lcm.publish("PNEU_COMMAND", garbage, sizeof garbage), 0);
    std::this_thread::sleep_for(1ms);
  }
  // Let the bucket refill before the burst, and the one-second window of rejection events pass
  // (pneud publishes at most 20 rejection events a second; it counts every rejection in health).
  std::this_thread::sleep_for(1100ms);
  for (int i = 0; i < 12; ++i) {  // back to back: over the rate limit (burst 5, 100 per second)
    const C c = command(100 + i, C::KIND_SET_POINT_STEP, 0.0001);
    ASSERT_EQ(lcm.publish("PNEU_COMMAND", &c), 0);
  }
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  EXPECT_TRUE(listener.wait_for([&] { return listener.last_health.is_final; }, 2s)) << "the final health message";
  done = true;
  handler.join();

  std::lock_guard<std::mutex> l(listener.m);
  std::vector<std::string> rejected, accepted;
  for (const auto& e : listener.events) {
    if (e.kind == pneu_lcm::event_t::KIND_COMMAND_REJECTED) rejected.push_back(e.text);
    if (e.kind == pneu_lcm::event_t::KIND_COMMAND_ACCEPTED) accepted.push_back(e.text);
  }
  const auto any = [](const std::vector<std::string>& v, const std::string& s) {
    return std::any_of(v.begin(), v.end(), [&](const std::string& t) { return t.find(s) != std::string::npos; });
  };
  EXPECT_TRUE(any(accepted, "set point 170.000 mm"));
  EXPECT_TRUE(any(rejected, "outside the soft limits"));
  EXPECT_TRUE(any(rejected, "not a finite number"));
  EXPECT_TRUE(any(rejected, "is not above the last accepted"));
  EXPECT_TRUE(any(rejected, "unknown command kind 42"));
  EXPECT_TRUE(any(rejected, "already armed"));
  EXPECT_TRUE(any(rejected, "not a pneu_lcm.command_t"));
  EXPECT_TRUE(any(rejected, "rate limit"));
  // Each verdict names its command by sequence number; a datagram that is no command has none (0).
  for (const auto& e : listener.events) {
    if (e.kind != pneu_lcm::event_t::KIND_COMMAND_ACCEPTED && e.kind != pneu_lcm::event_t::KIND_COMMAND_REJECTED)
      continue;
    const std::pair<const char*, int64_t> seq_of[] = {
        {"set point 170.000 mm", 10}, {"not a finite number", 12}, {"already armed", 14}, {"malformed", 0}};
    for (const auto& [text, seq] : seq_of)
      if (e.text.find(text) != std::string::npos) {
        EXPECT_EQ(e.seq, seq) << e.text;
      }
  }

  // Counted and published in health (the last health message counts everything sent above).
  ASSERT_GE(listener.health_count, 2);
  const auto& h = listener.last_health;
  EXPECT_EQ(h.commands_received, 1 + 5 + 1 + 200 + 12);
  EXPECT_EQ(h.commands_accepted, static_cast<int64_t>(accepted.size()));
  EXPECT_EQ(h.commands_rejected, h.commands_received - h.commands_accepted);
  EXPECT_LT(static_cast<int64_t>(rejected.size()), h.commands_rejected)
      << "the garbage stream's rejections are counted, not each published as an event";
  EXPECT_EQ(h.commands_rejected, h.rejected_malformed + h.rejected_invalid + h.rejected_sequence + h.rejected_mode +
                                     h.rejected_rate + h.rejected_stale + h.rejected_foreign + h.rejected_oversized);
  EXPECT_EQ(h.rejected_stale + h.rejected_foreign + h.rejected_oversized, 0);
  EXPECT_EQ(h.rejected_malformed, 201);
  EXPECT_EQ(h.rejected_invalid, 3);
  EXPECT_EQ(h.rejected_sequence, 1);
  EXPECT_EQ(h.rejected_mode, 1);
  EXPECT_GE(h.rejected_rate, 1);
  EXPECT_EQ(h.telemetry_dropped, 0);

  // The valid set point moved the simulated piston; the loop ticked on throughout: every
  // deadline of the 4 s run is accounted for (ticked, or skipped after an overrun the machine
  // caused), and the recorded ticks have no gap.
  const Csv traj = Csv::read(dir_ / "traj.csv");
  ASSERT_FALSE(traj.rows.empty());
  const double y_d_end = std::stod(traj.rows.back()[2]), y_end = std::stod(traj.rows.back()[3]);
  EXPECT_NEAR(y_d_end, 0.170 + 0.0001 * static_cast<double>(accepted.size() - 1), 1e-9);
  EXPECT_NEAR(y_end, y_d_end, 0.005) << "the carriage went from 219.5 mm to the commanded set point";
  for (std::size_t i = 0; i < traj.rows.size(); ++i) ASSERT_EQ(std::stoull(traj.rows[i][0]), i);
  const auto summary = pneu::test::PneudSummary::read(dir_ / "summary.json");
  ASSERT_TRUE(summary.has_loop);
  const auto ticks = summary.ticks, skipped = summary.skipped;
  EXPECT_EQ(ticks + skipped, 4001u);
  EXPECT_EQ(ticks, traj.rows.size());
}

// One controller per bench (issue 29). Health messages off the group, by the pid that sent them.
class Healths {
 public:
  Healths() {
    thread_ = std::thread([this] {
      std::string channel;
      std::vector<std::uint8_t> payload;
      while (!done_) {
        if (!sniffer_.receive(channel, payload, 20) || channel != "PNEU_HEALTH") continue;
        pneu_lcm::health_t h;
        if (h.decode(payload.data(), 0, static_cast<int>(payload.size())) != static_cast<int>(payload.size())) continue;
        std::lock_guard<std::mutex> l(m_);
        last_[h.pid] = h;
      }
    });
  }
  ~Healths() {
    done_ = true;
    thread_.join();
  }
  bool good() const { return sniffer_.good(); }
  // Whether the last health of `pid` satisfies `pred` within `limit`.
  bool wait(pid_t pid, const std::function<bool(const pneu_lcm::health_t&)>& pred, std::chrono::milliseconds limit) {
    return pneu::test::eventually(
        [&] {
          std::lock_guard<std::mutex> l(m_);
          const auto it = last_.find(pid);
          return it != last_.end() && pred(it->second);
        },
        limit, 5ms);
  }

 private:
  pneu::test::LcmSniffer sniffer_;
  std::mutex m_;
  std::map<std::int32_t, pneu_lcm::health_t> last_;
  std::atomic<bool> done_{false};
  std::thread thread_;
};

std::vector<std::string> pneud_until_sigterm(const pneu::test::TestDir& dir, const std::string& name,
                                             double health_period_s) {
  return loop_timing_faults_off({bin("pneud"), "--clock", "real", "--duration", "0", "--require-telemetry", "--set",
                                 "controller.setpoints.schedule=[]", "--set",
                                 "telemetry.health_period_s=" + std::to_string(health_period_s), "--events",
                                 (dir / (name + ".events.jsonl")).string(), "--trajectory",
                                 (dir / (name + ".traj.csv")).string()});
}

TEST_F(LcmIntegration, ASecondControllerOnTheChannelsRefusesToStartNamingTheFirst) {
  Healths healths;
  ASSERT_TRUE(healths.good());
  Child first = Child::spawn(pneud_until_sigterm(dir_, "first", 0.2), dir_ / "first.out", dir_ / "first.err");
  ASSERT_TRUE(healths.wait(first.pid, [](const auto& h) { return h.mode == 1; }, 10s)) << slurp(dir_ / "first.err");
  ASSERT_TRUE(healths.wait(first.pid, [](const auto& h) {
    char host[256] = "";
    gethostname(host, sizeof host - 1);
    return h.host == host && h.start_utime > 0;
  }, 1s)) << "its health names it";

  Child second = Child::spawn(pneud_until_sigterm(dir_, "second", 0.2), dir_ / "second.out", dir_ / "second.err");
  EXPECT_EQ(second.wait(), 1) << slurp(dir_ / "second.err");
  const std::string err = slurp(dir_ / "second.err");
  EXPECT_THAT(err, HasSubstr("pneud: another controller is running on the channels PNEU_*: pneud pid " +
                             std::to_string(first.pid) + " on host "));
  EXPECT_THAT(err, HasSubstr("one controller per bench"));
  EXPECT_FALSE(fs::exists(dir_ / "second.traj.csv")) << "nothing ran: no file left";
  EXPECT_FALSE(fs::exists(dir_ / "second.events.jsonl"));

  EXPECT_TRUE(healths.wait(first.pid, [](const auto& h) { return h.mode == 1 && h.faults == 0 && !h.is_final; }, 2s))
      << "the first drives on";
  kill(first.pid, SIGTERM);
  EXPECT_EQ(first.wait(), 0) << slurp(dir_ / "first.err");
  EXPECT_EQ(slurp(dir_ / "first.err"), "") << "it heard no other";
}

// A controller that cannot be heard when another starts (stalled here by SIGSTOP, as a frozen
// machine or a network partition would hide it) and then speaks again: the two hear each other while
// running. Both latch the another-controller fault, say so on stderr, and refuse a reset while the
// other is heard. Once the second has stopped (its last health forgets it at once), the first's
// reset is accepted.
TEST_F(LcmIntegration, TwoControllersThatHearEachOtherWhileRunningBothLatchAFault) {
  Healths healths;
  ASSERT_TRUE(healths.good());
  Child first = Child::spawn(pneud_until_sigterm(dir_, "first", 0.2), dir_ / "first.out", dir_ / "first.err");
  ASSERT_TRUE(healths.wait(first.pid, [](const auto& h) { return h.mode == 1; }, 10s)) << slurp(dir_ / "first.err");
  kill(first.pid, SIGSTOP);
  std::this_thread::sleep_for(200ms);  // what it sent last is delivered, or dropped
  Child second = Child::spawn(pneud_until_sigterm(dir_, "second", 0.2), dir_ / "second.out", dir_ / "second.err");
  ASSERT_TRUE(healths.wait(second.pid, [](const auto& h) { return h.mode == 1; }, 10s))
      << "the second heard no other as it started: " << slurp(dir_ / "second.err");
  kill(first.pid, SIGCONT);
  const auto faulted = [](const auto& h) { return h.mode == 2 && h.fault_cause == 13; };
  EXPECT_TRUE(healths.wait(first.pid, faulted, 10s)) << slurp(dir_ / "first.err");
  EXPECT_TRUE(healths.wait(second.pid, faulted, 10s)) << slurp(dir_ / "second.err");
  EXPECT_THAT(slurp(dir_ / "first.err"), HasSubstr("<3>pneud: another controller on the channels PNEU_*: pneud pid " +
                                                   std::to_string(second.pid) + " on host "));
  EXPECT_THAT(slurp(dir_ / "second.err"), HasSubstr("<3>pneud: another controller on the channels PNEU_*: pneud pid " +
                                                    std::to_string(first.pid) + " on host "));
  EXPECT_THAT(slurp(dir_ / "first.err"), HasSubstr("<3>pneud: FAULT at "));
  EXPECT_THAT(slurp(dir_ / "second.err"), Not(HasSubstr("no longer heard"))) << "not forgotten between messages";

  lcm::LCM lcm(kUrl);
  ASSERT_TRUE(lcm.good());
  const pneu_lcm::command_t refused = command(1, pneu_lcm::command_t::KIND_FAULT_RESET, 0.0);
  ASSERT_EQ(lcm.publish("PNEU_COMMAND", &refused), 0);
  EXPECT_TRUE(pneu::test::eventually(
      [&] {
        return slurp(dir_ / "first.err")
                   .find("<4>pneud: fault reset refused at ") != std::string::npos;
      },
      5s))
      << "refused while the other is heard: " << slurp(dir_ / "first.err");

  kill(second.pid, SIGTERM);
  EXPECT_EQ(second.wait(), 3) << "it ended with the fault latched: " << slurp(dir_ / "second.err");
  EXPECT_TRUE(pneu::test::eventually([&] {
    return slurp(dir_ / "first.err").find("no longer heard") != std::string::npos;
  }, 5s)) << slurp(dir_ / "first.err");
  const pneu_lcm::command_t reset = command(2, pneu_lcm::command_t::KIND_FAULT_RESET, 0.0);
  ASSERT_EQ(lcm.publish("PNEU_COMMAND", &reset), 0);
  EXPECT_TRUE(healths.wait(first.pid, [](const auto& h) { return h.mode == 0; }, 8s)) << "reset: disarmed";
  kill(first.pid, SIGTERM);
  EXPECT_EQ(first.wait(), 0) << slurp(dir_ / "first.err");
}

// The user running this test, as pneu-command names it in its origin.
std::string user_name() {
  const passwd* pw = ::getpwuid(::geteuid());
  return pw != nullptr ? pw->pw_name : std::to_string(::geteuid());
}

// pneu-command run to its end: exit code, stdout, stderr.
struct CommandRun {
  int exit_code = -1;
  pid_t pid = 0;
  std::string out, err;
  std::chrono::duration<double> took{};
};
CommandRun pneu_command(const pneu::test::TestDir& dir, const std::vector<std::string>& args) {
  static int n = 0;
  const std::string tag = "command" + std::to_string(++n);
  std::vector<std::string> argv = {bin("pneu-command")};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto t0 = std::chrono::steady_clock::now();
  Child c = Child::spawn(argv, dir / (tag + ".out"), dir / (tag + ".err"));
  CommandRun r;
  r.pid = c.pid;
  r.exit_code = c.wait();
  r.took = std::chrono::steady_clock::now() - t0;
  r.out = slurp(dir / (tag + ".out"));
  r.err = slurp(dir / (tag + ".err"));
  return r;
}

// The "command" lines of a pneud events file.
std::vector<std::string> command_events(const fs::path& events) {
  std::vector<std::string> lines;
  std::istringstream in(slurp(events));
  for (std::string line; std::getline(in, line);)
    if (line.starts_with("{\"event\":\"command\",")) lines.push_back(line);
  return lines;
}

// The verdict comes back to the command's sender (a generous limit: the test is about the answer,
// not its delay, and a shared machine stalls processes now and then).
TEST_F(LcmIntegration, PneuCommandPrintsTheDaemonsVerdictAndExitsNonZeroOnARejection) {
  const fs::path events = dir_ / "events.jsonl";
  Child pneud = start_commanded_pneud({"--events", events.string()});
  ASSERT_FALSE(HasFailure());

  const CommandRun accepted = pneu_command(dir_, {"--seq", "10", "--timeout-s", "10", "set-point", "0.17"});
  EXPECT_EQ(accepted.exit_code, 0) << accepted.err;
  EXPECT_EQ(accepted.out, "pneud accepted: set point 170.000 mm\n");
  EXPECT_EQ(accepted.err, "");

  const CommandRun outside = pneu_command(dir_, {"--seq", "11", "--timeout-s", "10", "set-point", "0.9"});
  EXPECT_EQ(outside.exit_code, 3);
  EXPECT_EQ(outside.out, "");
  EXPECT_THAT(outside.err, HasSubstr("pneud rejected (invalid): set point 900.000 mm is outside the soft limits"));

  const CommandRun armed = pneu_command(dir_, {"--seq", "12", "--timeout-s", "10", "arm"});
  EXPECT_EQ(armed.exit_code, 3);
  EXPECT_THAT(armed.err, HasSubstr("pneud rejected (mode): arm refused: already armed"));

  kill(pneud.pid, SIGTERM);
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  // The events file holds each verdict, in the order given, each attributed to its sender.
  const std::vector<std::string> lines = command_events(events);
  ASSERT_EQ(lines.size(), 3u) << slurp(events);
  const auto by = [](const CommandRun& r) {
    return ",\"origin\":\"pneu-command " + user_name() + "\",\"session\":" + std::to_string(r.pid) + ",";
  };
  EXPECT_THAT(lines[0], HasSubstr(",\"verdict\":\"accepted\",\"reason\":null,\"kind\":\"set_point\",\"seq\":10,"
                                  "\"value\":0.17" + by(accepted) + "\"text\":\"set point 170.000 mm\"}"));
  EXPECT_THAT(lines[1], HasSubstr(",\"verdict\":\"rejected\",\"reason\":\"invalid\",\"kind\":\"set_point\",\"seq\":11,"
                                  "\"value\":0.9" + by(outside) + "\"text\":\"set point 900.000 mm is outside the soft limits"));
  EXPECT_THAT(lines[2], HasSubstr(",\"verdict\":\"rejected\",\"reason\":\"mode\",\"kind\":\"arm\",\"seq\":12,"
                                  "\"value\":0" + by(armed) + "\"text\":\"arm refused: already armed\"}"));
}

// Issue 31: every command's verdict says who sent it and from which session, in the events file
// and in the event on <prefix>EVENT, whatever the verdict; a sender names itself (--origin).
TEST_F(LcmIntegration, EveryVerdictIsAttributedToItsSendersOriginAndSessionInTheEventsAndOnTheChannel) {
  Listener listener;
  ASSERT_TRUE(listener.sniffer.good());
  std::atomic<bool> done{false};
  std::thread handler([&] {
    while (!done) listener.poll(20);
  });
  const fs::path events = dir_ / "events.jsonl";
  Child pneud = start_commanded_pneud({"--events", events.string()});
  ASSERT_FALSE(HasFailure());
  const CommandRun named = pneu_command(dir_, {"--seq", "20", "--timeout-s", "10", "--origin", "line \"3\" rig",
                                               "set-point", "0.17"});
  EXPECT_EQ(named.exit_code, 0) << named.err;
  const CommandRun refused = pneu_command(dir_, {"--seq", "21", "--timeout-s", "10", "arm"});
  EXPECT_EQ(refused.exit_code, 3) << refused.err;
  kill(pneud.pid, SIGTERM);
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  done = true;
  handler.join();

  const std::vector<std::string> lines = command_events(events);
  ASSERT_EQ(lines.size(), 2u) << slurp(events);
  EXPECT_THAT(lines[0], HasSubstr("\"verdict\":\"accepted\""));
  EXPECT_THAT(lines[0], HasSubstr(",\"origin\":\"line \\\"3\\\" rig\",\"session\":" + std::to_string(named.pid) + ","));
  EXPECT_THAT(lines[1], HasSubstr("\"verdict\":\"rejected\""));
  EXPECT_THAT(lines[1], HasSubstr(",\"origin\":\"pneu-command " + user_name() + "\",\"session\":" +
                                  std::to_string(refused.pid) + ","));
  std::lock_guard<std::mutex> l(listener.m);
  int verdicts = 0;
  for (const pneu_lcm::event_t& e : listener.events) {
    if (e.kind == pneu_lcm::event_t::KIND_COMMAND_ACCEPTED) {
      ++verdicts;
      EXPECT_EQ(e.seq, 20);
      EXPECT_EQ(e.origin, "line \"3\" rig");
      EXPECT_EQ(e.session, named.pid);
    } else if (e.kind == pneu_lcm::event_t::KIND_COMMAND_REJECTED) {
      ++verdicts;
      EXPECT_EQ(e.seq, 21);
      EXPECT_EQ(e.origin, "pneu-command " + user_name());
      EXPECT_EQ(e.session, refused.pid);
    } else {
      EXPECT_EQ(e.origin, "") << "only verdicts are attributed";
      EXPECT_EQ(e.session, 0);
    }
  }
  EXPECT_EQ(verdicts, 2);
}

// Issue 29: a set point sent while disarmed used to be "accepted: set point ..." and then not the
// one in force: arming holds where the carriage is. It is refused now, and its verdict says what
// arming does; arming then does exactly that.
TEST_F(LcmIntegration, ASetPointWhileDisarmedIsRefusedSayingWhatArmingDoesAndArmingDoesIt) {
  const fs::path traj = dir_ / "traj.csv";
  Child pneud = start_commanded_pneud({"--trajectory", traj.string()});
  ASSERT_FALSE(HasFailure());

  const CommandRun disarm = pneu_command(dir_, {"--seq", "10", "--timeout-s", "10", "disarm"});
  EXPECT_EQ(disarm.exit_code, 0) << disarm.err;
  const CommandRun step = pneu_command(dir_, {"--seq", "11", "--timeout-s", "10", "step", "-0.005"});
  EXPECT_EQ(step.exit_code, 3) << step.out;
  EXPECT_EQ(step.err, "pneu-command: pneud rejected (mode): set point refused: disarmed: arm first; on arm the "
                      "carriage holds where it is\n");
  const CommandRun arm = pneu_command(dir_, {"--seq", "12", "--timeout-s", "10", "arm"});
  EXPECT_EQ(arm.exit_code, 0) << arm.err;
  std::this_thread::sleep_for(300ms);
  kill(pneud.pid, SIGTERM);
  ASSERT_EQ(pneud.wait(), 0) << slurp(dir_ / "pneud.err");
  EXPECT_THAT(slurp(dir_ / "pneud.err"), HasSubstr("<5>pneud: disarmed at "));
  EXPECT_THAT(slurp(dir_ / "pneud.err"), HasSubstr("<5>pneud: armed at "));

  // The trajectory: armed, disarmed, armed again holding where the carriage was; the refused step
  // never in force.
  const Csv t = Csv::read(traj);
  const std::size_t c_y_d = t.col("y_d"), c_y = t.col("y"), c_mode = t.col("mode");
  std::string modes;
  for (const auto& row : t.rows) {
    if (modes.empty() || modes.back() != row[c_mode][0]) {
      modes += row[c_mode][0];
      if (modes == "101") {
        EXPECT_EQ(row[c_y_d], row[c_y]) << "armed where the carriage is";
      }
    }
    ASSERT_NEAR(std::stod(row[c_y_d]), 0.2195, 0.001) << "the step to 214.5 mm never in force";
  }
  EXPECT_EQ(modes, "101") << "armed, disarmed, armed";
}

TEST_F(LcmIntegration, PneuCommandWithoutADaemonExitsWithNoAnswerAfterItsTimeout) {
  const CommandRun r = pneu_command(dir_, {"--timeout-s", "1", "arm"});
  EXPECT_EQ(r.exit_code, 4);
  EXPECT_GE(r.took.count(), 1.0) << "it waited for the verdict";
  EXPECT_LT(r.took.count(), 10.0) << "and not much longer";  // generous: a loaded machine
  EXPECT_EQ(r.out, "");
  EXPECT_THAT(r.err, HasSubstr("no answer from pneud within 1 s"));
  EXPECT_THAT(r.err, HasSubstr("whether it was applied is unknown"));
  EXPECT_THAT(r.err, HasSubstr("not running"));
  EXPECT_THAT(r.err, HasSubstr("another LCM URL or channel prefix"));
  EXPECT_THAT(r.err, HasSubstr("at most 20 rejection events a second"));
}

// The test plays pneud: to each command it answers first with a verdict on another sequence
// number and a non-verdict event carrying this one, then with the verdict on this command.
TEST_F(LcmIntegration, PneuCommandTakesOnlyTheVerdictOnItsOwnSequenceNumber) {
  pneu::test::LcmSniffer sniffer;
  ASSERT_TRUE(sniffer.good());
  lcm::LCM lcm(kUrl);
  ASSERT_TRUE(lcm.good());
  std::atomic<bool> done{false};
  std::atomic<int> answered{0};
  std::thread daemon([&] {
    std::string channel;
    std::vector<std::uint8_t> payload;
    while (!done) {
      if (!sniffer.receive(channel, payload, 20) || channel != "PNEU_COMMAND") continue;
      pneu_lcm::command_t c;
      if (c.decode(payload.data(), 0, static_cast<int>(payload.size())) < 0) continue;
      using E = pneu_lcm::event_t;
      const auto event = [&](std::int8_t kind, std::int64_t seq, const std::string& text) {
        E e{};
        e.utime = c.utime;
        e.kind = kind;
        e.seq = seq;
        e.text = text;
        lcm.publish("PNEU_EVENT", &e);
      };
      event(E::KIND_COMMAND_ACCEPTED, c.seq + 1, "accepted: another command");
      event(E::KIND_STOP, c.seq, "stop");
      event(E::KIND_COMMAND_REJECTED, c.seq, "rejected (mode): the test says no");
      ++answered;
    }
  });
  const CommandRun r = pneu_command(dir_, {"--seq", "100", "--timeout-s", "10", "disarm"});
  done = true;
  daemon.join();
  EXPECT_EQ(answered, 1);
  EXPECT_EQ(r.exit_code, 3) << r.out << r.err;
  EXPECT_EQ(r.err, "pneu-command: pneud rejected (mode): the test says no\n");
}

}  // namespace
