// The register map of an analog I/O module on Modbus: which register(s) hold which channel (a
// 16-bit count, or a float32 in two registers), and the linear scaling raw value <-> volts
// (hal.modbus.channels.*, described below). Volts <-> SI goes through the sensor calibration
// (sensors.*). Shared by the modbus backend and the HIL plant server, so both read the same map.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include "pneu/config/describe.hpp"

namespace pneu::hal {

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

}  // namespace pneu::hal

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using hal::RegisterChannel;
using hal::RegisterFormat;

inline constexpr Choice<RegisterFormat> kRegisterFormats[] = {{"int16", RegisterFormat::kInt16},
                                                              {"float32", RegisterFormat::kFloat32}};

/// One channel of hal.modbus.channels; `sensor`: an input (may be float32), else a valve output.
void describe(auto& a, Like<RegisterChannel> auto& c, bool sensor) {
  a.field(Field("register", c.address), IntRange::in(0, 65535), "register address (0-based, as on the wire)");
  a.field(optional(PNEU_NVP(c, format)), one_of(kRegisterFormats),
          "int16: one register; float32: two, high word first");
  a.check("format", sensor || c.format == RegisterFormat::kInt16,
          "float32 is for sensor channels only: a valve output is one 16-bit register");
  a.check("register", c.format != RegisterFormat::kFloat32 || c.address <= 65534,
          "must be in [0, 65534] (a float32 spans this register and the next)");
  a.field(meaningful_when(c.format == RegisterFormat::kInt16, Field("signed", c.is_signed)),
          "int16: the register holds a two's complement value");
  a.field(PNEU_NVP(c, raw_min), Range::any(), "raw value at volts_min");
  a.field(PNEU_NVP(c, raw_max), Range::any(), "raw value at volts_max");
  if (c.format == RegisterFormat::kFloat32) {
    constexpr double kFloatMax = 3.4028234663852886e38;
    a.check("raw_min", std::abs(c.raw_min) <= kFloatMax, "must fit a float32 (|raw_min| <= 3.4028235e38)");
    a.check("raw_max", std::abs(c.raw_max) <= kFloatMax, "must fit a float32 (|raw_max| <= 3.4028235e38)");
  } else {
    const double lo = c.is_signed ? -32768.0 : 0.0, hi = c.is_signed ? 32767.0 : 65535.0;
    const auto must_fit = [&] {
      return "must fit a " + std::string(c.is_signed ? "signed" : "unsigned") + " 16-bit register [" + fmt(lo) +
             ", " + fmt(hi) + "]";
    };
    a.check("raw_min", c.raw_min >= lo && c.raw_min <= hi, must_fit);
    a.check("raw_max", c.raw_max >= lo && c.raw_max <= hi, must_fit);
  }
  a.check("raw_max", c.raw_max > c.raw_min, [&] {
    return "the raw range is empty (raw_max " + fmt(c.raw_max) + " <= raw_min " + fmt(c.raw_min) + ")";
  });
  a.field(PNEU_NVP(c, volts_min), Range::any(), "[V]");
  a.field(PNEU_NVP(c, volts_max), Range::any(), "[V]");
  a.check("volts_max", c.volts_max > c.volts_min, [&] {
    return "the volts range is empty (volts_max " + fmt(c.volts_max) + " <= volts_min " + fmt(c.volts_min) + ")";
  });
}

}  // namespace pneu::config::schema
