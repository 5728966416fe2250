// The HIL plant server (pneu_plant_server's PlantServer) in-process: run on a thread on 127.0.0.1
// at a port the kernel picks, talked to with libmodbus and with pneud's modbus backend, asked to
// stop, its counts and records read back. What `pneu-plant serve`'s child-process tests establish
// (test_serve_faults, test_serve_watchdog), here on the class itself. Real time: about 4 s in all.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/hal/modbus_backend.hpp"
#include "pneu/plant_server/plant_server.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/hil_modbus_client.hpp"
#include "support/json.hpp"

namespace {

using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::plant_server::Fault;
using pneu::plant_server::PlantServer;
using pneu::plant_server::ServerParams;
using pneu::plant_server::SpecError;
using pneu::test::Json;
using pneu::test::slurp;
using ::testing::HasSubstr;
using Clock = std::chrono::steady_clock;


// hil.yaml's registers: position 0, pressure_p 1, pressure_n 2 (unsigned, 0..65535 for 0..10 V),
// valve_p 16, valve_n 17 (signed, -32767..32767 for -10..10 V).
constexpr int kPosition = 0, kPressureP = 1, kValveP = 16, kValveN = 17;
using pneu::test::hil_valve_volts;
using pneu::test::hil_valve_word;

pneu::config::Config hil_config() { return pneu::config::load_file(hil_yaml(), {}); }

// The bench of hil.yaml behind its register map, on 127.0.0.1 at a port the kernel picks.
ServerParams hil_params(const pneu::config::Config& cfg) {
  ServerParams p;
  p.plant = pneu::config::simulated_bench(cfg);
  p.sensors = cfg.sensors;
  p.pushes = cfg.hal.sim.pushes;
  p.initial_position_m = cfg.simulation.initial_position_m;
  p.modbus = cfg.hal.modbus;
  p.modbus.host = "127.0.0.1";
  p.modbus.port = 0;
  return p;
}

Fault fault(const std::string& spec, const ServerParams& p) {
  return pneu::plant_server::parse_fault(spec, p.modbus, p.plant.valve.max_voltage_v);
}

// A server run on a thread of the test, its records in files of the test's directory.
class Running {
 public:
  Running(ServerParams params, const fs::path& dir)
      : dir_(dir),
        events_(std::fopen((dir / "events.jsonl").c_str(), "w")),
        outputs_(std::fopen((dir / "outputs.csv").c_str(), "w")),
        messages_(std::fopen((dir / "messages.txt").c_str(), "w")),
        warnings_(std::fopen((dir / "warnings.txt").c_str(), "w")),
        server_(std::move(params), {events_, outputs_, messages_, warnings_}),
        thread_([this] {
          try {
            server_.run();
          } catch (...) {
            error_ = std::current_exception();
          }
        }) {}
  ~Running() { halt(); }
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

  // Asks the server to stop, and waits until it has; then the records are whole. What run()
  // threw is thrown here.
  void stop() {
    halt();
    if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  }
  [[nodiscard]] PlantServer& server() { return server_; }
  [[nodiscard]] int port() const { return server_.port(); }
  [[nodiscard]] std::string messages() const { return slurp(dir_ / "messages.txt"); }
  [[nodiscard]] std::string warnings() const { return slurp(dir_ / "warnings.txt"); }
  [[nodiscard]] std::vector<Json> events() const {
    std::vector<Json> lines;
    std::istringstream in(slurp(dir_ / "events.jsonl"));
    for (std::string line; std::getline(in, line);) lines.push_back(Json::parse(line));
    return lines;
  }

 private:
  void halt() {
    if (!thread_.joinable()) return;
    server_.request_stop();
    thread_.join();
    for (std::FILE* f : {events_, outputs_, messages_, warnings_}) std::fclose(f);
  }

  fs::path dir_;
  std::FILE *events_, *outputs_, *messages_, *warnings_;
  PlantServer server_;
  std::exception_ptr error_;
  std::thread thread_;  // last: started once the rest is built
};

std::vector<Json> of_kind(const std::vector<Json>& events, const std::string& kind) {
  std::vector<Json> found;
  for (const Json& e : events)
    if (e["event"].text() == kind) found.push_back(e);
  return found;
}

using Client = pneu::test::HilModbusClient;

class PlantServerTest : public ::testing::Test {
 protected:
  pneu::test::TestDir dir_{"pneu_plant_server_"};
  const pneu::config::Config cfg_ = hil_config();
};

TEST_F(PlantServerTest, ServesOnAPortTheKernelPicksAndStopsWhenAskedClosingItsConnections) {
  Running r(hil_params(cfg_), dir_);
  ASSERT_GT(r.port(), 0) << "port 0 asks the kernel for one";
  {
    Client c(r.port());
    ASSERT_TRUE(c.connected());
    EXPECT_GT(c.read(kPosition, 3)[kPosition], 60000) << "at rest at 219.5 mm: about 9.39 V";
    const auto valves = c.read(kValveP, 2);
    EXPECT_NEAR(hil_valve_volts(valves[0]), r.server().neutral_voltage_v(), 10.0 / 32767.0) << "u_P = u_e";
    EXPECT_NEAR(hil_valve_volts(valves[1]), -r.server().neutral_voltage_v(), 10.0 / 32767.0) << "u_N = -u_e";
  }
  const auto asked = Clock::now();
  r.stop();
  EXPECT_LT(Clock::now() - asked, 1s) << "run() looks at the request at least every 0.5 ms";
  Client late(r.port());
  EXPECT_FALSE(late.connected()) << "no longer listening";

  const pneu::plant_server::Stats s = r.server().stats();
  EXPECT_EQ(s.requests, 2u);
  EXPECT_EQ(s.clients, 1u);
  EXPECT_EQ(s.busy, 0u);
  const auto events = r.events();
  ASSERT_GE(events.size(), 3u);  // start, connect, stop (a disconnect the stop may come before)
  EXPECT_EQ(events.front()["event"].text(), "start");
  EXPECT_EQ(events.back()["event"].text(), "stop");
  EXPECT_EQ(events.back()["requests"].count(), 2u);
  EXPECT_EQ(of_kind(events, "connect").size(), 1u);
  EXPECT_THAT(r.messages(), HasSubstr("stopped after"));
  EXPECT_THAT(r.messages(), HasSubstr("; 2 requests from 1 clients"));
}

TEST_F(PlantServerTest, ValveVoltagesWrittenByPneudsBackendDriveThePlantWhosePositionTheBackendReads) {
  Running r(hil_params(cfg_), dir_);
  pneu::config::ModbusConfig link = cfg_.hal.modbus;
  link.port = r.port();
  pneu::hal::ModbusBackend backend(link, cfg_.sensors);
  const double u_e = r.server().neutral_voltage_v();
  ASSERT_EQ(backend.write({u_e, -u_e, true}), pneu::hal::Status::kOk);  // the carriage held where it rests
  ASSERT_NO_THROW(backend.open(0.0));
  pneu::hal::SensorFrame at_rest;
  ASSERT_TRUE(pneu::test::eventually([&] { return backend.read(0.0, at_rest) == pneu::hal::Status::kOk; }, 2s));
  EXPECT_NEAR(at_rest.y_m, cfg_.simulation.initial_position_m, 0.5e-3) << "in metres, through the register map";

  ASSERT_EQ(backend.write(pneu::hal::ActuatorCommand::from_control(3.0, true)), pneu::hal::Status::kOk);
  std::this_thread::sleep_for(400ms);
  pneu::hal::SensorFrame moved;
  EXPECT_TRUE(pneu::test::eventually([&] { return backend.read(0.0, moved) == pneu::hal::Status::kOk; }, 2s));
  backend.close();
  r.stop();

  EXPECT_GT(moved.y_m, at_rest.y_m + 5e-3) << "u = +3 V fills chamber P: the carriage runs forward";
  const pneu::plant_server::Stats s = r.server().stats();
  EXPECT_GT(s.requests, 50u) << "the backend's I/O thread exchanges every millisecond or so";
  const auto events = r.events();
  ASSERT_EQ(of_kind(events, "owner").size(), 1u) << "the backend took the valve registers";
  const auto breakaways = of_kind(events, "breakaway");
  ASSERT_FALSE(breakaways.empty()) << "the plant left rest";
  EXPECT_EQ(breakaways.back()["direction"].number(), 1.0);
}

TEST_F(PlantServerTest, TheFaultScheduleActsAtEachFaultsTimeInTimeOrderAndNotBefore) {
  ServerParams p = hil_params(cfg_);
  // Given out of order: the later one first.
  p.faults = {fault("pressure_p:rail-high@1", p), fault("position:rail-low@0", p)};
  const auto started = Clock::now();  // before the server's t = 0
  Running r(std::move(p), dir_);
  Client c(r.port());
  ASSERT_TRUE(c.connected());
  const auto before = c.read(kPosition, 2);
  ASSERT_LT(Clock::now() - started, 1s) << "read before pressure_p's fault acts";
  EXPECT_EQ(before[kPosition], 0) << "position:rail-low@0 acts from the start: raw_min";
  EXPECT_LT(before[kPressureP], 40000) << "about 3.4 bar: 3.4 V";

  std::this_thread::sleep_until(started + 1s);
  EXPECT_TRUE(pneu::test::eventually([&] { return c.read1(kPressureP) == 65535; }, 2s)) << "raw_max from 1 s on";
  r.stop();
  const auto faults = of_kind(r.events(), "fault");
  ASSERT_EQ(faults.size(), 2u);
  EXPECT_EQ(faults[0]["spec"].text(), "position:rail-low@0");
  EXPECT_EQ(faults[0]["t"].number(), 0.0);
  EXPECT_EQ(faults[1]["spec"].text(), "pressure_p:rail-high@1");
  EXPECT_EQ(faults[1]["t"].number(), 1.0) << "recorded at its own time, inside the plant's catch-up";
  EXPECT_THAT(r.messages(), HasSubstr("fault pressure_p:rail-high@1 active at t = "));
}

TEST_F(PlantServerTest, TheFirstWriterOwnsTheValvesAndASecondWriterGetsException06UntilTheOwnerLeaves) {
  Running r(hil_params(cfg_), dir_);
  auto owner = std::make_unique<Client>(r.port());
  Client other(r.port());
  ASSERT_TRUE(owner->connected() && other.connected());
  EXPECT_EQ(owner->write_valves(1.0, -1.0), 0);
  EXPECT_EQ(other.write_valves(5.0, 5.0), EMBXSBUSY) << "server device busy";
  EXPECT_EQ(other.write_valves(5.0, 5.0), EMBXSBUSY);
  EXPECT_EQ(other.read(kValveP, 2), (std::vector<std::uint16_t>{hil_valve_word(1.0), hil_valve_word(-1.0)})) << "the owner's";
  owner.reset();  // disconnects: the valve registers are free
  EXPECT_EQ(other.write_valves(3.0, -3.0), 0);
  r.stop();

  const pneu::plant_server::Stats s = r.server().stats();
  EXPECT_EQ(s.busy, 2u);
  EXPECT_NEAR(s.u_p_v, 3.0, 1e-3);
  EXPECT_NEAR(s.u_n_v, -3.0, 1e-3);
  const auto owners = of_kind(r.events(), "owner");
  ASSERT_EQ(owners.size(), 2u);
  EXPECT_EQ(owners[0]["client"].count(), 1u);
  EXPECT_EQ(owners[1]["client"].count(), 2u);
  ASSERT_EQ(of_kind(r.events(), "released").size(), 1u);
  EXPECT_EQ(of_kind(r.events(), "released")[0]["cause"].text(), "disconnect");
  const std::string warnings = r.warnings();
  EXPECT_THAT(warnings, HasSubstr("client 2 (127.0.0.1:"));
  EXPECT_THAT(warnings, HasSubstr("may not write the valve registers: client 1 owns them"));
  EXPECT_EQ(warnings.find("may not write"), warnings.rfind("may not write")) << "told once per client";
  EXPECT_THAT(r.messages(), HasSubstr("client 1 left: the valve registers are free"));
  EXPECT_THAT(r.messages(), HasSubstr("2 valve writes refused as another client's"));
}

TEST_F(PlantServerTest, TheWatchdogSetsItsOutputsAndFreesTheValvesWhenTheOwnerFallsSilent) {
  ServerParams p = hil_params(cfg_);
  p.watchdog_s = 0.1;
  p.watchdog_outputs = pneu::plant_server::ValveVoltages{-10.0, -10.0};
  Running r(std::move(p), dir_);
  Client owner(r.port()), other(r.port());
  ASSERT_TRUE(owner.connected() && other.connected());
  EXPECT_EQ(owner.write_valves(1.0, -1.0), 0);
  EXPECT_TRUE(pneu::test::eventually(
      [&] { return other.read(kValveP, 2) == std::vector<std::uint16_t>{hil_valve_word(-10.0), hil_valve_word(-10.0)}; }, 2s))
      << "the owner silent (connected) past 0.1 s: the watchdog's outputs";
  EXPECT_EQ(other.write_valves(2.0, -2.0), 0) << "the valve registers are free for the next writer";
  r.stop();

  EXPECT_GE(r.server().stats().watchdog_trips, 1u);
  const auto trips = of_kind(r.events(), "watchdog");  // a second: client 2 silent past 0.1 s before the stop
  ASSERT_GE(trips.size(), 1u);
  EXPECT_EQ(trips[0]["client"].count(), 1u);
  EXPECT_GE(trips[0]["t"].number() - trips[0]["last_request_t"].number(), 0.1);
  EXPECT_EQ(of_kind(r.events(), "released").at(0)["cause"].text(), "watchdog");
  EXPECT_THAT(r.messages(), HasSubstr("watchdog: no request from client 1 for "));
}

TEST(PlantServerParams, BadFaultsWatchdogOutputsAndParametersAreRefusedSayingWhy) {
  const ServerParams p = hil_params(hil_config());
  const auto refusal = [&](const std::string& spec) {
    try {
      (void)fault(spec, p);
    } catch (const SpecError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(refusal("position:stuck=1@0"), "'position:stuck=1@0': stuck=V is a valve mode: a sensor channel takes "
                                           "rail-low, rail-high, raw=N, volts=V, freeze, nan or dead");
  EXPECT_THAT(refusal("pressure_p:nan@0"), HasSubstr("nan needs a float32 channel"));
  EXPECT_THAT(refusal("valve_p:stuck=11@0"), HasSubstr("outside the valve's range [-10, 10] V"));
  EXPECT_THAT(refusal("pressure_p:rail-high"), HasSubstr("missing @T"));
  EXPECT_EQ(refusal("tubes:swapped@2.5"), "accepted");

  EXPECT_FALSE(pneu::plant_server::parse_watchdog_outputs("neutral", 10.0).has_value()) << "the neutral voltages";
  EXPECT_EQ(pneu::plant_server::parse_watchdog_outputs("exhaust", 10.0)->u_n_v, -10.0);
  EXPECT_THROW((void)pneu::plant_server::parse_watchdog_outputs("-10", 10.0), SpecError);

  ServerParams none = p;
  none.max_clients = 0;
  EXPECT_THROW({ PlantServer refused(none, {}); }, std::invalid_argument);
}

}  // namespace
