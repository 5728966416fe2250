// The safe output on closing counts as delivered only when the module's valve registers, read back,
// hold it (issue 29). RTU frames carry no transaction id: a late reply to an earlier request looks
// like the reply to the safe write. pneud's modbus backend on a pty, against a module the test
// plays (one that answers a write with a stale reply and does not apply it), and against
// `pneu-plant serve` answering late, with a wire the test relays between two ptys. Real time:
// about 10 s.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <termios.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/hal/modbus_backend.hpp"
#include "pneu/hal/monotonic.hpp"
#include "support/child_process.hpp"
#include "support/paths.hpp"
#include "support/json.hpp"

namespace {

using pneu::test::bin;
using pneu::test::hil_yaml;

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using pneu::test::Child;
using pneu::test::Json;
using pneu::test::slurp;


// hil.yaml's registers: position 0, pressure_p 1, pressure_n 2, valve_p 16, valve_n 17 (signed,
// -32767..32767 for -10..10 V).
constexpr int kValveP = 16;
std::uint16_t valve_word(double volts) {
  return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(volts / 10.0 * 32767.0)));
}

// A pseudo-terminal: the test holds the master and one descriptor of the slave, set raw, so that
// the line stays up (no EIO on the master) while the backend closes and reopens the slave, and
// bytes sent meanwhile wait in the line, as on a serial line.
class Pty {
 public:
  Pty() {
    master_ = posix_openpt(O_RDWR | O_NOCTTY);
    if (master_ < 0 || grantpt(master_) != 0 || unlockpt(master_) != 0) return;
    path_ = ptsname(master_);
    slave_ = open(path_.c_str(), O_RDWR | O_NOCTTY);
    termios t{};
    tcgetattr(slave_, &t);
    cfmakeraw(&t);
    tcsetattr(slave_, TCSANOW, &t);
    fcntl(master_, F_SETFL, fcntl(master_, F_GETFL) | O_NONBLOCK);
  }
  ~Pty() {
    if (slave_ >= 0) close(slave_);
    if (master_ >= 0) close(master_);
  }
  Pty(const Pty&) = delete;
  Pty& operator=(const Pty&) = delete;
  [[nodiscard]] bool good() const { return master_ >= 0 && slave_ >= 0; }
  [[nodiscard]] int master() const { return master_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  int master_ = -1, slave_ = -1;
  std::string path_;
};

std::uint16_t crc16(const std::uint8_t* p, std::size_t n) {  // Modbus RTU: poly 0xA001, init 0xFFFF
  std::uint16_t crc = 0xFFFF;
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001) : static_cast<std::uint16_t>(crc >> 1);
  }
  return crc;
}
std::vector<std::uint8_t> with_crc(std::vector<std::uint8_t> frame) {
  const std::uint16_t crc = crc16(frame.data(), frame.size());
  frame.push_back(static_cast<std::uint8_t>(crc & 0xFF));  // low byte first
  frame.push_back(static_cast<std::uint8_t>(crc >> 8));
  return frame;
}

// The I/O module, played by the test on a pty's master as unit 1 (functions 3, 6, 16, 23 on 32
// holding registers, answered at once). In stale mode it answers every write with the reply it
// sent to the previous write of the same function, as a late reply on the line would look, and
// does not apply the write.
class FakeModule {
 public:
  explicit FakeModule(int fd) : fd_(fd) {
    regs_[0] = 30000;  // position, p_P, p_N: readings inside their ranges
    regs_[1] = 20000;
    regs_[2] = 25000;
    thread_ = std::thread([this] { run(); });
  }
  ~FakeModule() {
    done_ = true;
    thread_.join();
  }
  void set_stale(bool on) { stale_ = on; }
  [[nodiscard]] std::array<std::uint16_t, 2> valves() {
    std::lock_guard<std::mutex> l(m_);
    return {regs_[kValveP], regs_[kValveP + 1]};
  }
  [[nodiscard]] int stale_replies() const { return stale_replies_.load(); }
  [[nodiscard]] int reads_of_the_valves() const { return reads_of_the_valves_.load(); }
  [[nodiscard]] int writes() const { return writes_.load(); }

 private:
  void run() {
    std::vector<std::uint8_t> in;
    while (!done_) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 5) <= 0) continue;
      std::uint8_t buf[256];
      const ssize_t n = read(fd_, buf, sizeof buf);
      if (n <= 0) {
        std::this_thread::sleep_for(1ms);
        continue;
      }
      in.insert(in.end(), buf, buf + n);
      for (std::size_t len = frame_length(in); len > 0 && in.size() >= len; len = frame_length(in)) {
        const std::vector<std::uint8_t> frame(in.begin(), in.begin() + static_cast<long>(len));
        in.erase(in.begin(), in.begin() + static_cast<long>(len));
        if (crc16(frame.data(), len) != 0) {  // a frame with its CRC sums to 0
          in.clear();
          break;
        }
        answer(frame);
      }
    }
  }
  static std::size_t frame_length(const std::vector<std::uint8_t>& in) {
    if (in.size() < 2) return 0;
    switch (in[1]) {
      case 3: case 6: return 8;
      case 16: return in.size() < 7 ? 0 : 9u + in[6];
      case 23: return in.size() < 11 ? 0 : 13u + in[10];
      default: return in.size();  // not ours: dropped whole
    }
  }
  static int word(const std::vector<std::uint8_t>& f, int at) { return f[at] << 8 | f[at + 1]; }
  void answer(const std::vector<std::uint8_t>& q) {
    const std::uint8_t fc = q[1];
    std::vector<std::uint8_t> reply{q[0], fc};
    const bool writes = fc == 6 || fc == 16 || fc == 23;
    if (writes && stale_ && last_write_reply_.count(fc)) {
      ++stale_replies_;
      send(last_write_reply_[fc]);
      return;
    }
    std::lock_guard<std::mutex> l(m_);
    const auto read_block = [&](int start, int count) {
      reply.push_back(static_cast<std::uint8_t>(2 * count));
      for (int i = 0; i < count; ++i) {
        reply.push_back(static_cast<std::uint8_t>(regs_[start + i] >> 8));
        reply.push_back(static_cast<std::uint8_t>(regs_[start + i]));
      }
      if (start <= kValveP && start + count > kValveP) ++reads_of_the_valves_;
    };
    switch (fc) {
      case 3: read_block(word(q, 2), word(q, 4)); break;
      case 6:
        regs_[word(q, 2)] = static_cast<std::uint16_t>(word(q, 4));
        reply.assign(q.begin(), q.begin() + 6);
        break;
      case 16:
        for (int i = 0; i < word(q, 4); ++i) regs_[word(q, 2) + i] = static_cast<std::uint16_t>(word(q, 7 + 2 * i));
        reply.assign(q.begin(), q.begin() + 6);
        break;
      case 23:
        for (int i = 0; i < word(q, 8); ++i) regs_[word(q, 6) + i] = static_cast<std::uint16_t>(word(q, 11 + 2 * i));
        read_block(word(q, 2), word(q, 4));
        break;
      default: return;
    }
    if (writes) ++writes_;
    const auto frame = with_crc(reply);
    if (writes) last_write_reply_[fc] = frame;
    send(frame);
  }
  void send(const std::vector<std::uint8_t>& frame) { (void)!write(fd_, frame.data(), frame.size()); }

  int fd_;
  std::mutex m_;
  std::array<std::uint16_t, 32> regs_{};
  std::map<std::uint8_t, std::vector<std::uint8_t>> last_write_reply_;  // the I/O thread's only
  std::atomic<bool> stale_{false}, done_{false};
  std::atomic<int> stale_replies_{0}, reads_of_the_valves_{0}, writes_{0};
  std::thread thread_;
};

// A wire between two ptys' masters: what one slave's user sends, the other's receives.
class Wire {
 public:
  Wire(int a, int b) : a_(a), b_(b) {
    thread_ = std::thread([this] {
      while (!done_) {
        pollfd p[2] = {{a_, POLLIN, 0}, {b_, POLLIN, 0}};
        if (poll(p, 2, 5) <= 0) continue;
        for (int i = 0; i < 2; ++i) {
          if (!(p[i].revents & POLLIN)) continue;
          std::uint8_t buf[512];
          const ssize_t n = read(p[i].fd, buf, sizeof buf);
          for (ssize_t done = 0; n > 0 && done < n && !done_;) {
            const ssize_t w = write(p[1 - i].fd, buf + done, static_cast<std::size_t>(n - done));
            if (w > 0) done += w;
            else std::this_thread::sleep_for(1ms);
          }
        }
      }
    });
  }
  ~Wire() {
    done_ = true;
    thread_.join();
  }

 private:
  int a_, b_;
  std::atomic<bool> done_{false};
  std::thread thread_;
};

pneu::config::Config rtu_config(const std::string& device) {
  return pneu::config::load_file(hil_yaml(), {"hal.modbus.transport=rtu", "hal.modbus.device=" + device});
}

pneu::hal::ActuatorCommand command(double u_p, double u_n) {
  pneu::hal::ActuatorCommand c{};
  c.u_p_v = u_p;
  c.u_n_v = u_n;
  return c;
}

class SafeOutputOnClosing : public ::testing::Test {
 protected:
  pneu::test::TestDir dir_{"pneu_safe_output_"};
};

TEST_F(SafeOutputOnClosing, AModuleThatAppliesTheSafeWriteReadsItBackAndItIsDelivered) {
  Pty line;
  ASSERT_TRUE(line.good());
  FakeModule module(line.master());
  const auto cfg = rtu_config(line.path());
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  ASSERT_NO_THROW(backend.open(0.0));
  ASSERT_EQ(backend.write(command(2.0, -2.0)), pneu::hal::Status::kOk);
  ASSERT_TRUE(pneu::test::eventually([&] { return module.valves()[0] == valve_word(2.0); }, 2s));
  ASSERT_EQ(backend.write(command(-10.0, -10.0)), pneu::hal::Status::kOk);
  backend.close();
  const auto link = backend.link_report();
  ASSERT_TRUE(link);
  EXPECT_TRUE(link->safe_output_delivered) << link->last_error;
  EXPECT_EQ(link->safe_output_attempts, 1);
  EXPECT_EQ(module.valves(), (std::array<std::uint16_t, 2>{valve_word(-10.0), valve_word(-10.0)}));
  EXPECT_GE(module.reads_of_the_valves(), 1) << "the valve registers were read back";
  EXPECT_NEAR(link->safe_output_read_back_u_p_v, -10.0, 1e-3);
  EXPECT_NEAR(link->safe_output_read_back_u_n_v, -10.0, 1e-3);
}

TEST_F(SafeOutputOnClosing, AStaleRtuReplyToTheSafeWriteIsNotTakenForDelivery) {
  Pty line;
  ASSERT_TRUE(line.good());
  FakeModule module(line.master());
  const auto cfg = rtu_config(line.path());
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  ASSERT_NO_THROW(backend.open(0.0));
  ASSERT_EQ(backend.write(command(2.0, -2.0)), pneu::hal::Status::kOk);
  ASSERT_TRUE(pneu::test::eventually([&] { return module.valves()[0] == valve_word(2.0); }, 2s));
  // From now on each write is answered by the reply to the write before it, and not applied.
  module.set_stale(true);
  ASSERT_EQ(backend.write(command(-10.0, -10.0)), pneu::hal::Status::kOk);
  backend.close();
  const auto link = backend.link_report();
  ASSERT_TRUE(link);
  EXPECT_GE(module.stale_replies(), 1) << "not vacuous: the safe write was answered by a stale reply";
  EXPECT_EQ(module.valves(), (std::array<std::uint16_t, 2>{valve_word(2.0), valve_word(-2.0)}))
      << "not vacuous: the module still holds the drive command";
  EXPECT_FALSE(link->safe_output_delivered) << "a reply to an earlier write is no delivery";
  EXPECT_EQ(link->safe_output_attempts, pneu::hal::ModbusBackend::kSafeOutputAttempts);
  EXPECT_NEAR(link->safe_output_read_back_u_p_v, 2.0, 1e-3) << "what the module holds, read back";
  EXPECT_NEAR(link->safe_output_read_back_u_n_v, -2.0, 1e-3);
  EXPECT_THAT(link->last_error, ::testing::HasSubstr("not the safe output's"));
}

TEST_F(SafeOutputOnClosing, ALateReplyLeftOnTheRtuLineIsFlushedOnConnecting) {
  // The reply to a read of the valve registers (function 3, 2 registers) that came after its
  // request was given up, waiting on the line when a new connection opens it: taken for the
  // reply to the first exchange, it fails it.
  Pty line;
  ASSERT_TRUE(line.good());
  const auto late = with_crc({1, 3, 4, 0x7F, 0xFF, 0x80, 0x01});
  ASSERT_EQ(write(line.master(), late.data(), late.size()), static_cast<ssize_t>(late.size()));
  std::this_thread::sleep_for(50ms);
  FakeModule module(line.master());
  const auto cfg = rtu_config(line.path());
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  EXPECT_NO_THROW(backend.open(0.0));
  backend.close();
}

// pneu-plant serve over RTU, answering every request 30 ms late (beyond the 20 ms response
// timeout) from 1 s on: the backend's exchanges take the reply to the request before theirs
// (serve reads the line one request at a time, so the requests queue up on it). The safe output
// written on closing reaches serve's registers only after the queue; pneud may say "delivered"
// only if serve's own record shows it held the safe output before close() returned.
TEST_F(SafeOutputOnClosing, OverRtuAReplyThatBelongsToAnEarlierRequestOfALateModuleIsNotTakenForDelivery) {
  Pty plant_side, pneud_side;
  ASSERT_TRUE(plant_side.good() && pneud_side.good());
  Wire wire(plant_side.master(), pneud_side.master());
  const fs::path events = dir_ / "serve.jsonl";
  Child plant = Child::spawn({bin("pneu-plant"), "serve", "--config", hil_yaml(), "--set", "hal.modbus.transport=rtu",
                              "--set", "hal.modbus.device=" + plant_side.path(), "--duration", "20", "--reply-delay-s",
                              "0.03", "--delay-after-s", "1", "--events", events.string()},
                             dir_ / "serve.out", dir_ / "serve.err");
  ASSERT_TRUE(pneu::test::wait_for_text(dir_ / "serve.out", "serving", 3s)) << slurp(dir_ / "serve.err");
  const auto cfg = rtu_config(pneud_side.path());
  pneu::hal::ModbusBackend backend(cfg.hal.modbus, cfg.sensors);
  ASSERT_NO_THROW(backend.open(0.0));
  ASSERT_EQ(backend.write(command(2.0, -2.0)), pneu::hal::Status::kOk);
  const double start_s = Json::parse(slurp(events).substr(0, slurp(events).find('\n')))["monotonic_s"].number();
  // Late replies from serve's 1 s on; the queue of requests grows for 0.5 s.
  while (pneu::hal::monotonic_s() < start_s + 1.5) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(backend.write(command(-10.0, -10.0)), pneu::hal::Status::kOk);
  backend.close();
  const double closed_s = pneu::hal::monotonic_s();
  const auto link = backend.link_report();
  ASSERT_TRUE(link);
  std::this_thread::sleep_for(1500ms);  // serve works off its queue: the safe output reaches it
  kill(plant.pid, SIGINT);
  EXPECT_EQ(plant.wait(), 0) << slurp(dir_ / "serve.err");
  EXPECT_GT(link->errors, 5u) << "not vacuous: the replies came late";

  // When serve's registers first held the safe output (its record), on CLOCK_MONOTONIC.
  double held_s = NAN;
  std::istringstream lines(slurp(events));
  for (std::string line; std::getline(lines, line) && std::isnan(held_s);) {
    const Json e = Json::parse(line);
    if (e["event"].text() == "outputs" && std::abs(e["u_p"].number() + 10.0) < 1e-3 && std::abs(e["u_n"].number() + 10.0) < 1e-3)
      held_s = e["monotonic_s"].number();
  }
  ASSERT_FALSE(std::isnan(held_s)) << "serve received the safe output in the end\n" << slurp(events).substr(0, 4000);
  std::printf("serve held the safe output %.1f ms after close() returned; pneud said %s\n", (held_s - closed_s) * 1e3,
              link->safe_output_delivered ? "delivered" : "not confirmed");
  if (link->safe_output_delivered) {
    EXPECT_LE(held_s, closed_s) << "said delivered " << (held_s - closed_s) * 1e3
                                << " ms before the module held it: a reply to an earlier request";
  }
  EXPECT_FALSE(link->safe_output_delivered) << "serve's queue was behind the safe write when pneud gave up";
}

}  // namespace
