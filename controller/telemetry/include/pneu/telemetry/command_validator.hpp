// Validation of inbound commands, off the real-time path: decoded fields in, a LoopCommand or a
// reason out. Pure logic (no LCM), so it is tested on its own.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/run_figures.hpp"
#include "pneu/telemetry/commands_params.hpp"

namespace pneu::telemetry {

/// command_t.origin's size: who sends a command, NUL-padded.
inline constexpr std::size_t kOriginBytes = 32;

/// The fields of a command_t, as decoded.
struct CommandFields {
  std::int64_t utime = 0;
  std::int64_t seq = 0;
  std::int8_t kind = 0;  ///< command_t.KIND_*
  double value = 0.0;
  std::array<char, kOriginBytes> origin{};  ///< who sends it: printable ASCII, NUL-padded (as sent)
  std::int64_t session = 0;                 ///< the sender's session (0: none)
};

/// `origin` as text: up to its first NUL (all 32 bytes when there is none).
[[nodiscard]] inline std::string_view origin_text(const std::array<char, kOriginBytes>& origin) noexcept {
  std::size_t n = 0;
  while (n < origin.size() && origin[n] != '\0') ++n;
  return {origin.data(), n};
}
/// Whether `origin` is printable ASCII (0x20 to 0x7e) up to its first NUL and NUL after it: what
/// may be written into events, logs and pages as it is.
[[nodiscard]] inline bool origin_is_clean(const std::array<char, kOriginBytes>& origin) noexcept {
  const std::size_t n = origin_text(origin).size();
  for (std::size_t i = 0; i < origin.size(); ++i) {
    const auto c = static_cast<unsigned char>(origin[i]);
    if (i < n ? (c < 0x20 || c > 0x7e) : c != 0) return false;
  }
  return true;
}
/// `origin` as text that may be written anywhere: up to its first NUL, any byte that is not
/// printable ASCII as '?'.
[[nodiscard]] std::string printable_origin(const std::array<char, kOriginBytes>& origin);
/// Fills `origin` with `text`, cut at kOriginBytes, NUL-padded (for senders).
inline void set_origin(std::array<char, kOriginBytes>& origin, std::string_view text) noexcept {
  origin.fill('\0');
  for (std::size_t i = 0; i < text.size() && i < origin.size(); ++i) origin[i] = text[i];
}

/// Command kinds on the wire (command_t.KIND_*).
inline constexpr std::int8_t kWireSetPoint = 1, kWireSetPointStep = 2, kWireArm = 3,
                             kWireDisarm = 4, kWireFaultReset = 5, kWireHoldOn = 6, kWireHoldOff = 7;
/// set_point, set_point_step, arm, disarm, fault_reset, hold_on, hold_off; "unknown" for another
/// number.
[[nodiscard]] const char* wire_kind_name(std::int8_t kind) noexcept;

enum class Rejection : std::uint8_t {
  kNone,
  kMalformed,  ///< undecodable, wrong type or size
  kInvalid,    ///< non-finite value, unknown kind, set point outside the soft limits
  kRate,       ///< over the rate limit
  kMode,       ///< not allowed in the current mode
  kSequence,   ///< sequence number not above the last accepted one
  kStale,      ///< stamped further than commands.max_age_s from this host's clock: a replay, a stuck sender
  kForeign,    ///< sent from another host (commands are accepted from this host only)
  kOversized,  ///< a datagram on the command channel longer than any command
};

struct Verdict {
  bool accepted = false;
  controller::LoopCommand command;  ///< when accepted
  Rejection rejection = Rejection::kNone;
  std::string text;                 ///< what was done, or why not, for people
};

/// By verdict and reason (a figure of the run: it lives with the others in run_figures.hpp).
using controller::CommandCounters;

/// Checks, in order: rate (token bucket: `burst` back to back, `max_rate_hz` sustained), age
/// (utime within commands.max_age_s of this host's clock, past or future), sequence (strictly
/// increasing over accepted commands), origin (printable ASCII, NUL-padded: it is written into
/// the verdict's event as it is; an empty origin is taken, and recorded as empty), values (finite, known kind, resulting set point inside the
/// soft limits, a set-point change no larger than commands.max_setpoint_step_m), mode (set points:
/// armed or holding, refused disarmed: arming holds the carriage where it is, whatever set point came
/// before; arm: disarmed; disarm: armed or holding; fault reset: fault; hold on and hold off: any
/// mode, a setting for the rest of the run). Not thread-safe: one command thread owns it.
class CommandValidator {
 public:
  /// `commands`: the rate, age and step limits; set points outside [soft_limit_min_m,
  /// soft_limit_max_m] (controller.soft_limit_*) are refused.
  CommandValidator(const CommandsConfig& commands, double soft_limit_min_m, double soft_limit_max_m);

  /// `now_s` on any monotonic clock; `now_unix_us` this host's clock (Unix time, us) for the age
  /// check; `setpoint_m` and `mode` as the loop last published them.
  [[nodiscard]] Verdict validate(const CommandFields& command, double now_s, std::int64_t now_unix_us,
                                 double setpoint_m, controller::Mode mode);
  /// Counts an undecodable message.
  [[nodiscard]] Verdict malformed(const std::string& why);
  /// Counts a datagram refused before decoding (kForeign, kOversized, kMalformed).
  [[nodiscard]] Verdict refuse(Rejection why, const std::string& text);
  [[nodiscard]] const CommandCounters& counters() const noexcept { return counters_; }

 private:
  Verdict reject(Rejection why, std::string text);

  double min_m_, max_m_, rate_hz_, burst_, max_age_s_, max_step_m_;
  double tokens_;
  double last_refill_s_ = -1.0;
  bool have_seq_ = false;
  std::int64_t last_seq_ = 0;
  CommandCounters counters_;
};

[[nodiscard]] const char* to_string(Rejection r) noexcept;

}  // namespace pneu::telemetry
