// A libmodbus TCP client of unit 1 on loopback, for the tests that talk to the simulated bench's
// Modbus server (pneu-plant serve, or PlantServer in process) over config/hil.yaml's register map.
#pragma once

#include <gtest/gtest.h>
#include <modbus.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <vector>

namespace pneu::test {

/// hil.yaml: valve_p at 16, valve_n at 17, signed words, -32767..32767 for -10..10 V.
inline constexpr int kHilValveP = 16;
inline std::uint16_t hil_valve_word(double volts) {
  return static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(volts / 10.0 * 32767.0)));
}
inline double hil_valve_volts(std::uint16_t word) { return static_cast<std::int16_t>(word) * 10.0 / 32767.0; }

class HilModbusClient {
 public:
  explicit HilModbusClient(int port, double response_timeout_s = 0.5) : ctx_(modbus_new_tcp("127.0.0.1", port)) {
    modbus_set_slave(ctx_, 1);
    modbus_set_response_timeout(ctx_, static_cast<uint32_t>(response_timeout_s),
                                static_cast<uint32_t>(std::fmod(response_timeout_s, 1.0) * 1e6));
    connected_ = modbus_connect(ctx_) == 0;
  }
  ~HilModbusClient() {
    modbus_close(ctx_);
    modbus_free(ctx_);
  }
  HilModbusClient(const HilModbusClient&) = delete;
  HilModbusClient& operator=(const HilModbusClient&) = delete;
  [[nodiscard]] bool connected() const { return connected_; }
  [[nodiscard]] modbus_t* ctx() const { return ctx_; }

  std::vector<std::uint16_t> read(int address, int count) {
    std::vector<std::uint16_t> regs(static_cast<std::size_t>(count));
    EXPECT_EQ(modbus_read_registers(ctx_, address, count, regs.data()), count) << modbus_strerror(errno);
    return regs;
  }
  std::uint16_t read1(int address) { return read(address, 1)[0]; }
  /// Both valve registers written (function 16) as words: 0, or the errno of the refusal
  /// (EMBXSBUSY: another client owns the valves).
  int write_valve_words(std::uint16_t p, std::uint16_t n) {
    const std::uint16_t out[2] = {p, n};
    return modbus_write_registers(ctx_, kHilValveP, 2, out) == 2 ? 0 : errno;
  }
  /// ... as voltages.
  int write_valves(double u_p_v, double u_n_v) { return write_valve_words(hil_valve_word(u_p_v), hil_valve_word(u_n_v)); }

 private:
  modbus_t* ctx_;
  bool connected_ = false;
};

}  // namespace pneu::test
