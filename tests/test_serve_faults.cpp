// Fault injection in `pneu-plant serve` (issue 6), read back with libmodbus as a client: sensor
// registers at a rail, at a given raw value, frozen, NaN on a float32 channel; a stuck valve spool
// that moves the plant whatever the client writes; and the --outputs record of what the client
// wrote, which survives a SIGKILL; several clients: one writer of the valves, held replies each
// late by the delay. Real time: about 12 s in all.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <fstream>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/hal/modbus_backend.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/hil_modbus_client.hpp"

namespace {

using pneu::test::bin;
using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::test::Child;
using pneu::test::Csv;
using pneu::test::free_port;
using pneu::test::slurp;
using ::testing::HasSubstr;
using Clock = std::chrono::steady_clock;


// hil.yaml's registers: position 0, pressure_p 1, pressure_n 2 (unsigned, 0..65535 for 0..10 V),
// valve_p 16, valve_n 17 (signed, -32767..32767 for -10..10 V).
constexpr int kPosition = 0, kPressureP = 1, kPressureN = 2, kValveP = 16, kValveN = 17;

std::vector<std::string> float32_overrides() {
  std::ifstream in(std::string(PNEU_SOURCE_DIR) + "/tests/hil_float32_overrides.txt");
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) lines.push_back(line);
  return lines;
}

using pneu::test::hil_valve_volts;
using pneu::test::hil_valve_word;

using Client = pneu::test::HilModbusClient;

bool wait_listening(int port) {
  for (int i = 0; i < 200; ++i) {
    modbus_t* probe = modbus_new_tcp("127.0.0.1", port);
    const bool ok = modbus_connect(probe) == 0;
    modbus_close(probe);  // the server sees a client that leaves at once, and serves the next
    modbus_free(probe);
    if (ok) return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

class ServeFaults : public ::testing::Test {
 protected:
  void SetUp() override {
    port_ = free_port();
  }
  // Starts serve on hil.yaml at a free port with `extra` options; `started_` is taken before the
  // spawn, so serve's own start-up (its t = 0) is later: a fault at T is active by started_ + T.
  Child serve(const std::vector<std::string>& extra, double duration_s = 10.0) {
    std::vector<std::string> args{bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set",
                                  "hal.modbus.port=" + std::to_string(port_), "--duration", std::to_string(duration_s)};
    args.insert(args.end(), extra.begin(), extra.end());
    started_ = Clock::now();
    Child c = Child::spawn(args, dir_ / "serve.out", dir_ / "serve.err");
    EXPECT_TRUE(wait_listening(port_)) << slurp(dir_ / "serve.err");
    return c;
  }
  double since_start_s() const { return std::chrono::duration<double>(Clock::now() - started_).count(); }
  void sleep_until_s(double t) const {
    std::this_thread::sleep_until(started_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(t)));
  }
  // Until serve says the fault `spec` is active (its start-up may lag started_ on a loaded
  // machine), up to 5 s.
  bool wait_active(const std::string& spec) const {
    return pneu::test::wait_for_text(dir_ / "serve.out", "fault " + spec + " active at t = ", 5s);
  }
  std::vector<std::string> with_float32(std::vector<std::string> extra) const {
    for (const auto& o : float32_overrides()) extra.insert(extra.begin(), {"--set", o});
    return extra;
  }

  pneu::test::TestDir dir_{"pneu_serve_faults_"};
  int port_ = 0;
  Clock::time_point started_;
};

TEST_F(ServeFaults, RailFaultsReadTheChannelsRawLimitsFromTheirTimeOn) {
  Child plant = serve({"--fault", "pressure_p:rail-high@1", "--fault", "position:rail-low@1"});
  Client c(port_);
  ASSERT_TRUE(c.connected());
  const auto before = c.read(kPosition, 3);
  ASSERT_LT(since_start_s(), 1.0) << "read before the faults act";
  EXPECT_GT(before[kPosition], 60000) << "at rest at 219.5 mm: about 9.39 V";
  EXPECT_LT(before[kPressureP], 40000) << "about 3.4 bar: 3.4 V";

  sleep_until_s(1.2);
  ASSERT_TRUE(wait_active("pressure_p:rail-high@1") && wait_active("position:rail-low@1")) << slurp(dir_ / "serve.out");
  const auto after = c.read(kPosition, 3);
  EXPECT_EQ(after[kPressureP], 65535) << "raw_max";
  EXPECT_EQ(after[kPosition], 0) << "raw_min";
  EXPECT_NEAR(after[kPressureN], before[kPressureN], 100) << "the other channels read on";
  const std::string out = slurp(dir_ / "serve.out");
  EXPECT_THAT(out, HasSubstr("fault pressure_p:rail-high@1 active at t = "));
  EXPECT_THAT(out, HasSubstr("fault position:rail-low@1 active at t = "));
}

TEST_F(ServeFaults, RawAndVoltsFaultsReadTheGivenValueEvenOutsideTheRawRange) {
  // position's raw range narrowed to 60000: raw=65000 is a reading beyond it, as from a broken wire.
  Child plant = serve({"--set", "hal.modbus.channels.position.raw_max=60000", "--fault", "position:raw=65000@0",
                       "--fault", "pressure_n:volts=2.5@0", "--fault", "pressure_p:raw=12345@0"});
  Client c(port_);
  ASSERT_TRUE(c.connected());
  const auto regs = c.read(kPosition, 3);
  EXPECT_EQ(regs[kPosition], 65000);
  EXPECT_EQ(regs[kPressureP], 12345);
  EXPECT_EQ(regs[kPressureN], 16384) << "2.5 V of 0..10 V on 0..65535: 16383.75, rounded";
}

TEST_F(ServeFaults, FreezeKeepsTheValueTheRegisterHadAtItsTime) {
  Child plant = serve({"--fault", "pressure_n:freeze@1"});
  Client c(port_);
  ASSERT_TRUE(c.connected());
  std::set<std::uint16_t> live;
  while (since_start_s() < 0.9) {
    live.insert(c.read1(kPressureN));
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_GE(live.size(), 2u) << "not vacuous: 20 Pa of noise moves the live reading";

  sleep_until_s(1.2);
  ASSERT_TRUE(wait_active("pressure_n:freeze@1")) << slurp(dir_ / "serve.out");
  const std::uint16_t frozen = c.read1(kPressureN);
  std::set<std::uint16_t> later;
  for (int i = 0; i < 60; ++i) {
    later.insert(c.read1(kPressureN));
    std::this_thread::sleep_for(5ms);
  }
  EXPECT_EQ(later, std::set<std::uint16_t>{frozen});
  EXPECT_NEAR(frozen, *live.begin(), 50) << "frozen at a live value, not at some default";
}

TEST_F(ServeFaults, NanOnAFloat32ChannelReadsQuietNanBitsAndReachesTheFrameFlaggedInvalid) {
  Child plant = serve(with_float32({"--fault", "pressure_p:nan@0"}));
  {
    Client c(port_);
    ASSERT_TRUE(c.connected());
    const auto regs = c.read(0, 8);  // position 0, pressure_p 4-5, pressure_n 6-7
    EXPECT_EQ(regs[4], 0x7FC0);
    EXPECT_EQ(regs[5], 0x0000);
    const float p_n_volts = pneu::config::RegisterChannel::float_of(regs[6], regs[7]);
    EXPECT_GT(p_n_volts, 4.0f) << "p_N at rest is about 4.9 bar: 4.9 V, and the float is the raw value";
    EXPECT_LT(p_n_volts, 6.0f);
  }

  // pneud's modbus backend on the same map: a non-finite pressure with its invalid flag set.
  std::vector<std::string> overrides = float32_overrides();
  overrides.push_back("hal.modbus.port=" + std::to_string(port_));
  const pneu::config::Config cfg = pneu::config::load_file(hil_yaml(), overrides);
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  ASSERT_NO_THROW(backend.open(0.0));
  pneu::hal::SensorFrame frame;
  (void)backend.read(0.0, frame);
  backend.close();
  EXPECT_TRUE(std::isnan(frame.p_p_pa));
  EXPECT_TRUE(frame.validity & pneu::hal::kPressurePInvalid);
  EXPECT_NEAR(frame.p_n_pa, 4.9e5, 0.5e5) << "the healthy float32 channel decodes to SI";
  EXPECT_FALSE(frame.validity & pneu::hal::kPressureNInvalid);
  EXPECT_FALSE(frame.validity & pneu::hal::kPositionInvalid);
}

TEST_F(ServeFaults, AStuckValveMovesThePlantWhileOutputsRecordWhatTheClientWrote) {
  // The client holds the valves where serve started them (u_0 = u_e, the carriage at rest at
  // complete equilibrium), one count off so that its writes are a change --outputs records; from
  // 1 s valve P's spool is stuck at -3 V: chamber P vents and the carriage runs back.
  Child plant = serve({"--outputs", (dir_ / "outputs.csv").string(), "--fault", "valve_p:stuck=-3@1"});
  Client c(port_);
  ASSERT_TRUE(c.connected());
  const auto u0 = c.read(kValveP, 2);
  const std::uint16_t held_p = static_cast<std::uint16_t>(u0[0] + 1), held_n = static_cast<std::uint16_t>(u0[1] - 1);
  std::vector<std::uint16_t> positions_before, positions_after;
  while (since_start_s() < 2.5) {
    EXPECT_EQ(c.write_valve_words(held_p, held_n), 0) << modbus_strerror(errno);
    (since_start_s() < 0.9 ? positions_before : positions_after).push_back(c.read1(kPosition));
    std::this_thread::sleep_for(5ms);
  }
  ASSERT_GE(positions_before.size(), 10u);
  const auto [lo, hi] = std::minmax_element(positions_before.begin(), positions_before.end());
  EXPECT_LE(*hi - *lo, 2) << "at rest under the client's u_0: within the ADC's last count";
  // 1.5 s after the spool stuck: tens of millimetres back (20 V/m, 0.153 mV a count: 131 counts a mm).
  EXPECT_LT(positions_after.back() + 2000, positions_before.front()) << "the stuck valve moved the carriage";
  EXPECT_THAT(slurp(dir_ / "serve.out"), HasSubstr("fault valve_p:stuck=-3@1 active at t = "));

  // Read at once: serve writes a change's line before it serves the next request, and the client's
  // last request was a read, answered after its last write's line.
  const Csv out = Csv::read(dir_ / "outputs.csv");
  ASSERT_EQ(out.header, (std::vector<std::string>{"t_s", "u_p_v", "u_n_v"}));
  ASSERT_EQ(out.rows.size(), 2u) << "the initial values, then one change: hundreds of writes of the same words";
  EXPECT_EQ(std::stod(out.rows[0][out.col("t_s")]), 0.0);
  EXPECT_NEAR(std::stod(out.rows[0][out.col("u_p_v")]), hil_valve_volts(u0[0]), 1e-6);
  EXPECT_NEAR(std::stod(out.rows[0][out.col("u_n_v")]), hil_valve_volts(u0[1]), 1e-6);
  EXPECT_NEAR(std::stod(out.rows[1][out.col("u_p_v")]), hil_valve_volts(held_p), 1e-6) << "what the client wrote, not -3 V";
  EXPECT_NEAR(std::stod(out.rows[1][out.col("u_n_v")]), hil_valve_volts(held_n), 1e-6);
  EXPECT_GT(std::stod(out.rows[1][out.col("t_s")]), 0.0);
}

TEST_F(ServeFaults, TheOutputsFileHoldsTheLastWrittenVoltagesAfterASigkill) {
  Child plant = serve({"--outputs", (dir_ / "outputs.csv").string()});
  Client c(port_);
  ASSERT_TRUE(c.connected());
  // Three settings, each written ten times: three change lines, not thirty. serve writes a change's
  // line before it serves the next request, so each line is on file once the next write is
  // answered: before the SIGKILL, with no wait.
  const std::vector<std::pair<double, double>> settings{{1.0, -1.0}, {0.25, 2.5}, {-10.0, -10.0}};
  for (const auto& [p, n] : settings)
    for (int i = 0; i < 10; ++i) {
      EXPECT_EQ(c.write_valve_words(hil_valve_word(p), hil_valve_word(n)), 0) << modbus_strerror(errno);
      std::this_thread::sleep_for(2ms);
    }
  kill(plant.pid, SIGKILL);
  EXPECT_EQ(plant.wait(), 128 + SIGKILL);

  const Csv out = Csv::read(dir_ / "outputs.csv");
  ASSERT_EQ(out.rows.size(), 1u + settings.size()) << slurp(dir_ / "outputs.csv");
  double t_last = 0.0;
  for (std::size_t i = 0; i < settings.size(); ++i) {
    const auto& row = out.rows[i + 1];
    EXPECT_NEAR(std::stod(row[out.col("u_p_v")]), settings[i].first, 1e-3) << "line " << i + 2;
    EXPECT_NEAR(std::stod(row[out.col("u_n_v")]), settings[i].second, 1e-3) << "line " << i + 2;
    const double t = std::stod(row[out.col("t_s")]);
    EXPECT_GE(t, t_last) << "line " << i + 2;
    t_last = t;
  }
  EXPECT_EQ(out.rows.back()[out.col("u_p_v")], "-10.000000") << "the exhaust-both safe state, 6 decimals";
  EXPECT_EQ(out.rows.back()[out.col("u_n_v")], "-10.000000");
}

TEST_F(ServeFaults, TheFirstClientToWriteTheValvesOwnsThemUntilItDisconnectsAndTheOthersGetException06) {
  Child plant = serve({"--outputs", (dir_ / "outputs.csv").string()});
  auto owner = std::make_unique<Client>(port_);
  Client other(port_);
  ASSERT_TRUE(owner->connected() && other.connected());
  EXPECT_EQ(owner->write_valve_words(hil_valve_word(1.0), hil_valve_word(-1.0)), 0) << modbus_strerror(errno);

  // Every function that writes a register, touching a valve register, from another client:
  // refused with exception 06 (server device busy), and nothing written.
  modbus_t* c = other.ctx();
  const std::uint16_t words[2] = {hil_valve_word(5.0), hil_valve_word(5.0)};
  std::uint16_t in[3] = {};
  const auto refusal = [](int rc) { return rc == -1 ? errno : 0; };
  EXPECT_EQ(refusal(modbus_write_registers(c, kValveP, 2, words)), EMBXSBUSY) << "function 16";
  EXPECT_EQ(refusal(modbus_write_register(c, kValveN, words[1])), EMBXSBUSY) << "function 6";
  EXPECT_EQ(refusal(modbus_mask_write_register(c, kValveP, 0, words[0])), EMBXSBUSY) << "function 22";
  EXPECT_EQ(refusal(modbus_write_and_read_registers(c, kValveP, 2, words, kPosition, 3, in)), EMBXSBUSY)
      << "function 23, as a second pneud would send";
  EXPECT_EQ(refusal(modbus_write_registers(c, kValveN, 1, words)), EMBXSBUSY) << "valve_n alone";
  EXPECT_EQ(other.read(kValveP, 2), (std::vector<std::uint16_t>{hil_valve_word(1.0), hil_valve_word(-1.0)})) << "the owner's";
  EXPECT_EQ(other.read(kPosition, 3).size(), 3u) << "reading is free for all";
  EXPECT_EQ(modbus_write_register(c, 5, 1234), 1) << "a register beside the valves is no one's";

  EXPECT_EQ(owner->write_valve_words(hil_valve_word(2.0), hil_valve_word(-2.0)), 0) << modbus_strerror(errno);
  owner.reset();  // disconnects: the valve registers are free
  EXPECT_EQ(other.write_valve_words(hil_valve_word(3.0), hil_valve_word(-3.0)), 0) << modbus_strerror(errno);
  EXPECT_EQ(other.read(kValveP, 2), (std::vector<std::uint16_t>{hil_valve_word(3.0), hil_valve_word(-3.0)}));
  kill(plant.pid, SIGTERM);
  EXPECT_EQ(plant.wait(), 0);

  const Csv out = Csv::read(dir_ / "outputs.csv");
  ASSERT_EQ(out.rows.size(), 4u) << "the initial values, then the owners' three writes only\n" << slurp(dir_ / "outputs.csv");
  for (int i = 1; i <= 3; ++i) {
    EXPECT_NEAR(std::stod(out.rows[i][out.col("u_p_v")]), i, 1e-3) << "line " << i + 2;
    EXPECT_NEAR(std::stod(out.rows[i][out.col("u_n_v")]), -i, 1e-3) << "line " << i + 2;
  }
  const std::string stdout_text = slurp(dir_ / "serve.out");
  EXPECT_THAT(stdout_text, HasSubstr("left: the valve registers are free"));
  EXPECT_THAT(stdout_text, HasSubstr("5 valve writes refused as another client's"));
  const std::string err = slurp(dir_ / "serve.err");
  EXPECT_THAT(err, HasSubstr("may not write the valve registers"));
  EXPECT_EQ(err.find("may not write"), err.rfind("may not write")) << "told once per client";
}

TEST_F(ServeFaults, ASampleAnsweredLateCarriesTheSpanInWhichItWasReadNotJustItsReplyTime) {
  // serve reads the registers when the request comes and answers 50 ms later: to pneud's side the
  // same as an I/O thread that took a prompt reply 50 ms late. The backend dates the sample by its
  // reply, and its frame says the module read it up to the whole exchange earlier: the span
  // covers the delay (a loaded machine only widens it).
  Child plant = serve({"--reply-delay-s", "0.05"});
  const pneu::config::Config cfg = pneu::config::load_file(
      hil_yaml(), {"hal.modbus.port=" + std::to_string(port_), "hal.modbus.response_timeout_s=0.5",
                   "hal.modbus.max_sample_age_s=1"});
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  ASSERT_NO_THROW(backend.open(0.0));
  std::this_thread::sleep_for(200ms);
  pneu::hal::SensorFrame frame;
  const pneu::hal::Status status = backend.read(10.0, frame);
  backend.close();
  EXPECT_EQ(status, pneu::hal::Status::kOk);
  EXPECT_GE(frame.read_span_s, 0.05);
  EXPECT_LT(frame.read_span_s, 2.0) << "one exchange's span, not the time since open";
  EXPECT_LE(frame.t_s, 10.0) << "dated by its reply, before the loop read it";
}

TEST_F(ServeFaults, HeldRepliesAreLateByTheDelayForEachClientNotQueuedBehindAnothers) {
  // Two clients' requests at once, each answered 1 s late: both after 1 s, neither after 2 s as
  // if the server slept through one client's delay before reading the other's request. The
  // 0.8 s margin is for a stall of the machine.
  Child plant = serve({"--reply-delay-s", "1"});
  Client a(port_, 3.0), b(port_, 3.0);
  ASSERT_TRUE(a.connected() && b.connected());
  double took_s[2] = {};
  const auto timed_read = [](Client& c, double& took) {
    const auto start = Clock::now();
    (void)c.read(kPosition, 3);
    took = std::chrono::duration<double>(Clock::now() - start).count();
  };
  std::thread ta(timed_read, std::ref(a), std::ref(took_s[0]));
  std::thread tb(timed_read, std::ref(b), std::ref(took_s[1]));
  ta.join();
  tb.join();
  for (const double t : took_s) {
    EXPECT_GE(t, 1.0);
    EXPECT_LT(t, 1.8);
  }
}

}  // namespace
