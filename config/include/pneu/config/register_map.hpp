// The register map of an analog I/O module on Modbus: which 16-bit register holds which channel,
// and the linear scaling raw counts <-> volts. Volts <-> SI goes through the sensor calibration
// (sensors.*). Shared by the modbus backend and the HIL plant server, so both read the same map.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

namespace pneu::config {

/// One analog channel in one 16-bit register.
struct RegisterChannel {
  int address = 0;          ///< register address (0-based, as on the wire), in [0, 65535]
  bool is_signed = false;   ///< the register holds a two's complement int16
  double raw_min = 0.0;     ///< raw count at volts_min
  double raw_max = 65535.0; ///< raw count at volts_max (> raw_min)
  double volts_min = 0.0;   ///< [V]
  double volts_max = 10.0;  ///< [V] (> volts_min)

  /// Register word -> volts (linear; outside the raw range extrapolates, the caller checks range).
  [[nodiscard]] double to_volts(std::uint16_t word) const noexcept {
    const double raw = is_signed ? static_cast<double>(static_cast<std::int16_t>(word)) : static_cast<double>(word);
    return volts_min + (raw - raw_min) * (volts_max - volts_min) / (raw_max - raw_min);
  }
  /// Volts -> register word, rounded and clamped to [raw_min, raw_max].
  [[nodiscard]] std::uint16_t to_word(double volts) const noexcept {
    double raw = raw_min + (volts - volts_min) * (raw_max - raw_min) / (volts_max - volts_min);
    raw = std::round(raw);
    if (!(raw >= raw_min)) raw = raw_min;  // NaN lands here too
    if (raw > raw_max) raw = raw_max;
    return is_signed ? static_cast<std::uint16_t>(static_cast<std::int16_t>(raw)) : static_cast<std::uint16_t>(raw);
  }
  /// Whether a word lies inside the configured raw range (a rail or a broken wire lies outside).
  [[nodiscard]] bool in_range(std::uint16_t word) const noexcept {
    const double raw = is_signed ? static_cast<double>(static_cast<std::int16_t>(word)) : static_cast<double>(word);
    return raw >= raw_min && raw <= raw_max;
  }
};

enum class ModbusTransport { kTcp, kRtu };
enum class SensorTable { kHolding, kInput };  ///< where the sensor registers sit

/// The modbus backend and the HIL server (hal.modbus.*).
struct ModbusConfig {
  ModbusTransport transport = ModbusTransport::kTcp;
  std::string host = "127.0.0.1";        ///< TCP: module address (the HIL server listens on it)
  int port = 1502;                       ///< TCP port
  std::string device = "/dev/ttyUSB0";   ///< RTU: serial device
  int baud = 115200;                     ///< RTU
  char parity = 'N';                     ///< RTU: 'N', 'E' or 'O'
  int data_bits = 8;                     ///< RTU
  int stop_bits = 1;                     ///< RTU
  int unit_id = 1;                       ///< slave / unit identifier, 1..247
  double response_timeout_s = 0.02;      ///< a transaction not answered by then is a comms error
  double max_sample_age_s = 0.02;        ///< the loop flags a sample older than this as stale
  double min_exchange_period_s = 0.001;  ///< the I/O thread exchanges at most this often
  bool read_write_multiple = true;       ///< one FC23 transaction per cycle (sensors in holding registers)
  SensorTable sensor_table = SensorTable::kHolding;  ///< FC3/FC23 (holding) or FC4 (input)
  double reconnect_min_s = 0.05;         ///< back-off after a failure, doubling up to ...
  double reconnect_max_s = 2.0;          ///< ... this
  RegisterChannel position, pressure_p, pressure_n;  ///< sensors
  RegisterChannel valve_p, valve_n;                  ///< outputs (holding registers, FC16/FC23)
};

}  // namespace pneu::config
