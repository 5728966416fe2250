// The register map of an analog I/O module on Modbus: which register(s) hold which channel (a
// 16-bit count, or a float32 in two registers), and the linear scaling raw value <-> volts.
// Volts <-> SI goes through the sensor calibration (sensors.*). Shared by the modbus backend and
// the HIL plant server, so both read the same map.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

namespace pneu::config {

/// How a channel's raw value sits in the registers (hal.modbus.channels.*.format).
enum class RegisterFormat : std::uint8_t {
  kInt16,    ///< one 16-bit register: an unsigned count, or two's complement with `signed`
  kFloat32,  ///< two registers: an IEEE-754 single, high word at `address`, low word at
             ///< `address + 1` (big-endian word order "ABCD", each word big-endian on the wire as
             ///< every Modbus register). Sensor channels only.
};

/// One analog channel: its register(s) and the linear scaling raw value <-> volts. The raw value
/// is the register's count (int16) or the float it holds (float32).
struct RegisterChannel {
  int address = 0;          ///< register address (0-based, as on the wire), in [0, 65535]; float32: the high word
  bool is_signed = false;   ///< int16: the register holds a two's complement int16 (ignored for float32)
  double raw_min = 0.0;     ///< raw value at volts_min
  double raw_max = 65535.0; ///< raw value at volts_max (> raw_min)
  double volts_min = 0.0;   ///< [V]
  double volts_max = 10.0;  ///< [V] (> volts_min)
  RegisterFormat format = RegisterFormat::kInt16;  ///< last, so {address, signed, ...} initialisers still hold

  /// Registers the channel occupies: 1 (int16) or 2 (float32).
  [[nodiscard]] int register_count() const noexcept { return format == RegisterFormat::kFloat32 ? 2 : 1; }
  /// The last register it occupies.
  [[nodiscard]] int last_address() const noexcept { return address + register_count() - 1; }

  /// The raw value held by the channel's words (`words[0]` at `address`, `words[1]` at
  /// `address + 1` for float32). NaN and infinities of a float32 pass through.
  [[nodiscard]] double raw_of(const std::uint16_t* words) const noexcept {
    if (format == RegisterFormat::kFloat32) return static_cast<double>(float_of(words[0], words[1]));
    return int16_raw(words[0]);
  }
  /// Raw value -> volts (linear; outside the raw range extrapolates, NaN stays NaN).
  [[nodiscard]] double raw_to_volts(double raw) const noexcept {
    return volts_min + (raw - raw_min) * (volts_max - volts_min) / (raw_max - raw_min);
  }
  /// Volts -> raw value (linear, neither rounded nor clamped).
  [[nodiscard]] double volts_to_raw(double volts) const noexcept {
    return raw_min + (volts - volts_min) * (raw_max - raw_min) / (volts_max - volts_min);
  }
  /// The channel's words -> volts.
  [[nodiscard]] double to_volts(const std::uint16_t* words) const noexcept { return raw_to_volts(raw_of(words)); }
  /// Whether the words hold a raw value inside [raw_min, raw_max] (a rail or a broken wire lies
  /// outside; a float32 NaN or infinity is never in range).
  [[nodiscard]] bool in_range(const std::uint16_t* words) const noexcept {
    const double raw = raw_of(words);
    return raw >= raw_min && raw <= raw_max;  // false for NaN
  }
  /// Volts -> the channel's words, clamped to [raw_min, raw_max] (int16: rounded to a count; NaN
  /// lands on raw_min).
  void to_words(double volts, std::uint16_t* words) const noexcept {
    double raw = volts_to_raw(volts);
    if (format == RegisterFormat::kInt16) raw = std::round(raw);
    if (!(raw >= raw_min)) raw = raw_min;  // NaN lands here too
    if (raw > raw_max) raw = raw_max;
    if (format == RegisterFormat::kFloat32) {
      (void)raw_to_words(raw, words);
    } else {
      words[0] = is_signed ? static_cast<std::uint16_t>(static_cast<std::int16_t>(raw)) : static_cast<std::uint16_t>(raw);
    }
  }
  /// A raw value -> the channel's words, unclamped except by the register type: int16 rounds and
  /// saturates at the type's limits, float32 rounds to single precision and saturates at
  /// +-FLT_MAX (NaN and infinities pass). Returns whether the value fitted the type as given
  /// (int16: an integer within its limits; float32: not beyond +-FLT_MAX unless infinite).
  bool raw_to_words(double raw, std::uint16_t* words) const noexcept {
    if (format == RegisterFormat::kFloat32) {
      constexpr double kMax = 3.4028234663852886e38;  // FLT_MAX
      const bool fits = !(std::isfinite(raw) && std::abs(raw) > kMax);
      const double r = std::isfinite(raw) ? std::clamp(raw, -kMax, kMax) : raw;
      std::uint32_t bits = 0;
      const float f = static_cast<float>(r);
      std::memcpy(&bits, &f, sizeof bits);
      words[0] = static_cast<std::uint16_t>(bits >> 16);
      words[1] = static_cast<std::uint16_t>(bits & 0xFFFFu);
      return fits;
    }
    const double lo = is_signed ? -32768.0 : 0.0, hi = is_signed ? 32767.0 : 65535.0;
    const bool fits = raw == std::round(raw) && raw >= lo && raw <= hi;  // false for NaN
    double r = std::round(raw);
    if (!(r >= lo)) r = lo;  // NaN lands here too
    if (r > hi) r = hi;
    words[0] = is_signed ? static_cast<std::uint16_t>(static_cast<std::int16_t>(r)) : static_cast<std::uint16_t>(r);
    return fits;
  }

  // One-register shorthands for int16 channels (the valves; a float32 channel needs both words).
  /// An int16 channel's count.
  [[nodiscard]] double int16_raw(std::uint16_t word) const noexcept {
    return is_signed ? static_cast<double>(static_cast<std::int16_t>(word)) : static_cast<double>(word);
  }
  /// Register word -> volts (linear; outside the raw range extrapolates, the caller checks range).
  [[nodiscard]] double to_volts(std::uint16_t word) const noexcept { return raw_to_volts(int16_raw(word)); }
  /// Volts -> register word, rounded and clamped to [raw_min, raw_max].
  [[nodiscard]] std::uint16_t to_word(double volts) const noexcept {
    std::uint16_t words[2] = {};
    to_words(volts, words);
    return words[0];
  }
  /// Whether a word lies inside the configured raw range (a rail or a broken wire lies outside).
  [[nodiscard]] bool in_range(std::uint16_t word) const noexcept {
    const double raw = int16_raw(word);
    return raw >= raw_min && raw <= raw_max;
  }

  /// The float of two words in "ABCD" order.
  [[nodiscard]] static float float_of(std::uint16_t high, std::uint16_t low) noexcept {
    const std::uint32_t bits = static_cast<std::uint32_t>(high) << 16 | low;
    float f = 0.0f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
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
  /// The module's fieldbus watchdog that the controller expects [s]: the bench's coupler must set
  /// its outputs to their safe values when no request came for this long (pneu-plant serve's
  /// default --watchdog-s). 0: none stated.
  double module_watchdog_s = 0.0;
  RegisterChannel position, pressure_p, pressure_n;  ///< sensors
  RegisterChannel valve_p, valve_n;                  ///< outputs (holding registers, FC16/FC23)
};

}  // namespace pneu::config
