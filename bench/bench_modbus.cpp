// What a Modbus TCP exchange costs on loopback, and how old the sample is that the loop takes.
//
//   Fc23RoundTrip         the floor: one bare libmodbus read/write-multiple (function 23)
//                         request/response on one connection (per-iteration time; median and p99
//                         over repetitions)
//   Fc23RoundTripHistogram 10,000 round trips timed one by one: p50/p99/max as counters [us]
//   BackendExchangeRate   the ModbusBackend's I/O thread exchanging back to back
//                         (min_exchange_period_s = 0) for 1 s: exchanges/s, us per exchange
//   BackendSampleAge      the loop's view with min_exchange_period_s = 0.001 (config/hil.yaml):
//                         1000 read()s at 1 ms deadlines, the sample's age p50/p99/max [us]
//
// The module is an in-process libmodbus server thread with hil.yaml's register map (holding 0..2
// sensors, 16..17 valves), one client at a time on a free loopback port.
//
// Run pinned to one core (client, server and I/O thread then share it, as on a small controller),
// from the source directory:
//   taskset -c 1 build-mb/bin/bench_modbus --benchmark_repetitions=5
//     --benchmark_report_aggregates_only=true
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "pneu/hal/modbus_backend.hpp"
#include "pneu/hal/modbus_params.hpp"
#include "pneu/hal/monotonic.hpp"
#include "pneu/model/sensors.hpp"

namespace {

using namespace pneu;

// hil.yaml's register map and sensor calibration.
constexpr int kRegPosition = 0, kRegPressureP = 1, kRegPressureN = 2, kRegValveP = 16,
              kRegValveN = 17;
const hal::RegisterChannel kSensorChannel{0, false, 0.0, 65535.0, 0.0, 10.0};
const hal::RegisterChannel kValveChannel{0, true, -32767.0, 32767.0, -10.0, 10.0};

using pneu::hal::monotonic_s;
using pneu::hal::sleep_until_monotonic_s;

// The value at quantile q (0..1) of `v` (sorted in place).
double quantile(std::vector<double>& v, double q) {
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)));
  return v[i];
}

// A loopback port nobody listens on right now (libmodbus refuses to listen on port 0).
int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  close(fd);
  return ntohs(a.sin_port);
}

// The analog I/O module: a libmodbus TCP server on its own thread, serving clients one after
// another until destroyed. Sensors: y = 0.100 m (7 V), p_P = 3 bar (3 V), p_N = 4 bar (4 V).
class LoopbackModule {
 public:
  LoopbackModule() : port_(free_port()) {
    ctx_ = modbus_new_tcp("127.0.0.1", port_);
    mapping_ = modbus_mapping_new(0, 0, 32, 32);
    if (!ctx_ || !mapping_) throw std::runtime_error("libmodbus: cannot create the server context");
    mapping_->tab_registers[kRegPosition] = kSensorChannel.to_word(20.0 * 0.100 + 5.0);
    mapping_->tab_registers[kRegPressureP] = kSensorChannel.to_word(1e-5 * 3.0e5);
    mapping_->tab_registers[kRegPressureN] = kSensorChannel.to_word(1e-5 * 4.0e5);
    listen_fd_ = modbus_tcp_listen(ctx_, 1);
    if (listen_fd_ == -1)
      throw std::runtime_error("libmodbus: cannot listen on 127.0.0.1:" + std::to_string(port_) +
                               ": " + modbus_strerror(errno));
    thread_ = std::thread([this] { serve(); });
  }
  ~LoopbackModule() {
    stopping_.store(true);
    shutdown(listen_fd_, SHUT_RDWR);  // accept() returns at once
    thread_.join();
    close(listen_fd_);
    modbus_mapping_free(mapping_);
    modbus_free(ctx_);
  }
  LoopbackModule(const LoopbackModule&) = delete;
  LoopbackModule& operator=(const LoopbackModule&) = delete;

  [[nodiscard]] int port() const noexcept { return port_; }

 private:
  void serve() noexcept {
    std::vector<std::uint8_t> query(MODBUS_TCP_MAX_ADU_LENGTH);
    while (!stopping_.load()) {
      int fd = listen_fd_;
      if (modbus_tcp_accept(ctx_, &fd) == -1) break;
      for (;;) {
        const int rc = modbus_receive(ctx_, query.data());
        if (rc == -1) break;    // the client left
        if (rc == 0) continue;  // not for this unit
        if (modbus_reply(ctx_, query.data(), rc, mapping_) == -1) break;
      }
      modbus_close(ctx_);  // the client's socket; the listening one stays
    }
  }

  int port_;
  modbus_t* ctx_ = nullptr;
  modbus_mapping_t* mapping_ = nullptr;
  int listen_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

LoopbackModule& module() {
  static LoopbackModule m;
  return m;
}

// A bare libmodbus client on the module, as the backend configures one.
struct RawClient {
  modbus_t* ctx = nullptr;
  RawClient() {
    ctx = modbus_new_tcp("127.0.0.1", module().port());
    modbus_set_slave(ctx, 1);
    modbus_set_response_timeout(ctx, 0, 20000);
    if (modbus_connect(ctx) == -1)
      throw std::runtime_error(std::string("connect: ") + modbus_strerror(errno));
  }
  ~RawClient() {
    modbus_close(ctx);
    modbus_free(ctx);
  }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;
  // One function-23 exchange: write both valves, read the three sensors. True on success.
  bool exchange(std::uint16_t* in) noexcept {
    const std::uint16_t out[2] = {kValveChannel.to_word(-0.19), kValveChannel.to_word(0.19)};
    return modbus_write_and_read_registers(ctx, kRegValveP, 2, out, kRegPosition, 3, in) == 3;
  }
};

// hil.yaml's hal.modbus section and sensor calibration.
hal::ModbusConfig hil_modbus(double min_exchange_period_s) {
  hal::ModbusConfig c;
  c.host = "127.0.0.1";
  c.port = module().port();
  c.unit_id = 1;
  c.response_timeout_s = 0.02;
  c.max_sample_age_s = 0.02;
  c.min_exchange_period_s = min_exchange_period_s;
  c.read_write_multiple = true;
  c.position = c.pressure_p = c.pressure_n = kSensorChannel;
  c.position.address = kRegPosition;
  c.pressure_p.address = kRegPressureP;
  c.pressure_n.address = kRegPressureN;
  c.valve_p = c.valve_n = kValveChannel;
  c.valve_p.address = kRegValveP;
  c.valve_n.address = kRegValveN;
  return c;
}

model::SensorParams hil_calibration() {
  model::SensorParams p;
  p.position = {20.0, 5.0, 0.0, 16, 0.0, 10.0};
  p.pressure_p = {1e-5, 0.0, 0.0, 16, 0.0, 10.0};
  p.pressure_n = {1e-5, 0.0, 0.0, 16, 0.0, 10.0};
  return p;
}

void Fc23RoundTrip(benchmark::State& state) {
  RawClient client;
  std::uint16_t in[3] = {};
  for (auto _ : state) {
    if (!client.exchange(in)) {
      state.SkipWithError(
          (std::string("modbus_write_and_read_registers: ") + modbus_strerror(errno)).c_str());
      break;
    }
    benchmark::DoNotOptimize(in);
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(Fc23RoundTrip)->UseRealTime()->Unit(benchmark::kMicrosecond);

void Fc23RoundTripHistogram(benchmark::State& state) {
  constexpr int kRoundTrips = 10000;
  RawClient client;
  std::uint16_t in[3] = {};
  std::vector<double> us(kRoundTrips);
  for (auto _ : state) {
    for (int i = 0; i < kRoundTrips; ++i) {
      const double t0 = monotonic_s();
      if (!client.exchange(in)) {
        state.SkipWithError(
            (std::string("modbus_write_and_read_registers: ") + modbus_strerror(errno)).c_str());
        return;
      }
      us[static_cast<std::size_t>(i)] = 1e6 * (monotonic_s() - t0);
    }
  }
  state.counters["p50_us"] = quantile(us, 0.50);
  state.counters["p99_us"] = quantile(us, 0.99);
  state.counters["max_us"] = us.back();
  std::printf("  fc23 round trip, %d timed one by one: p50 %.1f us, p99 %.1f us, max %.1f us\n",
              kRoundTrips, quantile(us, 0.50), quantile(us, 0.99), us.back());
}
BENCHMARK(Fc23RoundTripHistogram)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);

void BackendExchangeRate(benchmark::State& state) {
  double per_s = 0.0, errors = 0.0;
  for (auto _ : state) {
    hal::ModbusBackend backend(hil_modbus(0.0), hil_calibration());
    backend.open(0.0);
    const std::uint64_t n0 = backend.counters().transactions.load();
    const double t0 = monotonic_s();
    sleep_until_monotonic_s(t0 + 1.0);
    const std::uint64_t n1 = backend.counters().transactions.load();
    const double t1 = monotonic_s();
    backend.close();
    per_s = static_cast<double>(n1 - n0) / (t1 - t0);
    errors = static_cast<double>(backend.counters().errors.load());
  }
  state.counters["exchanges_per_s"] = per_s;
  state.counters["us_per_exchange"] = 1e6 / per_s;
  state.counters["errors"] = errors;
  std::printf(
      "  backend back to back (min_exchange_period_s = 0): %.0f exchanges/s = %.1f us per "
      "exchange, %.0f errors\n",
      per_s, 1e6 / per_s, errors);
}
BENCHMARK(BackendExchangeRate)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);

void BackendSampleAge(benchmark::State& state) {
  constexpr int kReads = 1000;
  constexpr double kPeriodS = 0.001;
  std::vector<double> age_us(kReads);
  int not_ok = 0;
  double y_m = NAN, per_s = 0.0;
  for (auto _ : state) {
    hal::ModbusBackend backend(hil_modbus(0.001), hil_calibration());
    backend.open(0.0);
    const std::uint64_t n0 = backend.counters().transactions.load();
    const double t0 = monotonic_s();
    for (int i = 0; i < kReads; ++i) {
      sleep_until_monotonic_s(t0 + (i + 1) * kPeriodS);
      hal::SensorFrame frame;
      if (backend.read(monotonic_s() - t0, frame) != hal::Status::kOk) ++not_ok;
      age_us[static_cast<std::size_t>(i)] = 1e6 * frame.age_s;
      y_m = frame.y_m;
    }
    per_s = static_cast<double>(backend.counters().transactions.load() - n0) / (monotonic_s() - t0);
    backend.close();
  }
  if (std::abs(y_m - 0.100) > 1e-5)
    state.SkipWithError("the backend did not read the served position");
  state.counters["age_p50_us"] = quantile(age_us, 0.50);
  state.counters["age_p99_us"] = quantile(age_us, 0.99);
  state.counters["age_max_us"] = age_us.back();
  state.counters["not_ok_reads"] = not_ok;
  state.counters["exchanges_per_s"] = per_s;
  std::printf(
      "  sample age over %d reads at 1 ms (min_exchange_period_s = 0.001, %.0f exchanges/s): p50 "
      "%.1f us, "
      "p99 %.1f us, max %.1f us, %d reads not ok\n",
      kReads, per_s, quantile(age_us, 0.50), quantile(age_us, 0.99), age_us.back(), not_ok);
}
BENCHMARK(BackendSampleAge)->Iterations(1)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
