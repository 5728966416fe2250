// The decoder of inbound command datagrams: one UDP payload in, a command_t's fields or a reason
// out. Pure and total (noexcept, no allocation): every byte string an attacker can send ends in a
// verdict, which is what the fuzz target holds it to.
//
// Wire format (LCM's UDP multicast protocol, "short message" form; commands are never
// fragmented):
//   uint32 magic 0x4c433032 ("LC02", big-endian) | uint32 sequence | channel name, NUL-terminated
//   | payload: pneu_lcm.command_t, LCM-encoded (8-byte fingerprint + fields, kCommandPayloadBytes)
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "pneu/telemetry/command_validator.hpp"

namespace pneu::telemetry {

/// A command_t's bytes: the fingerprint, utime, seq, kind, value, origin, session.
inline constexpr std::size_t kCommandPayloadBytes = 8 + 8 + 8 + 1 + 8 + kOriginBytes + 8;
/// The largest datagram a command can be: header, a 255-byte channel name and its NUL, payload.
inline constexpr std::size_t kMaxCommandDatagramBytes = 8 + 256 + kCommandPayloadBytes;

enum class DatagramKind : std::uint8_t {
  kCommand,       ///< a well-formed command_t on the command channel: `fields` holds it
  kOtherChannel,  ///< a well-formed LCM message on another channel (our own telemetry): ignore it
  kMalformed,     ///< not an LCM short message, fragmented, or not a command_t: reject and count
  kOversized,     ///< longer than any command can be: reject and count
};

struct DecodedDatagram {
  DatagramKind kind = DatagramKind::kMalformed;
  CommandFields fields;        ///< when kind == kCommand
  const char* why = "";        ///< when rejected: a static text, for people
};

/// Decodes `datagram` (the whole UDP payload) addressed to `command_channel`.
[[nodiscard]] DecodedDatagram decode_command_datagram(std::span<const std::uint8_t> datagram,
                                                      std::string_view command_channel) noexcept;

/// Encodes a command as the datagram above (for tools and tests). Returns the bytes written, or 0
/// when `out` is too small or the channel name is too long.
[[nodiscard]] std::size_t encode_command_datagram(const CommandFields& fields, std::string_view channel,
                                                  std::uint32_t sequence, std::span<std::uint8_t> out) noexcept;

}  // namespace pneu::telemetry
