#include "pneu/telemetry/command_datagram.hpp"

#include <cstring>

#include "pneu_lcm/command_t.hpp"

namespace pneu::telemetry {

static_assert(sizeof(pneu_lcm::command_t::origin) == kOriginBytes, "command_t.origin is kOriginBytes long");

namespace {
constexpr std::uint32_t kShortMagic = 0x4c433032;     // "LC02": a whole message in one datagram
constexpr std::uint32_t kFragmentMagic = 0x4c433033;  // "LC03": one fragment of a large message

std::uint32_t be32(const std::uint8_t* p) noexcept {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

DecodedDatagram reject(DatagramKind kind, const char* why) noexcept {
  DecodedDatagram d;
  d.kind = kind;
  d.why = why;
  return d;
}
}  // namespace

DecodedDatagram decode_command_datagram(std::span<const std::uint8_t> datagram,
                                        std::string_view command_channel) noexcept {
  const std::size_t n = datagram.size();
  if (n < 8) return reject(DatagramKind::kMalformed, "shorter than an LCM header");
  const std::uint32_t magic = be32(datagram.data());
  if (magic == kFragmentMagic) {
    // Telemetry never fragments on this host's channels either (state_t is small); a fragment
    // cannot be a command.
    return reject(DatagramKind::kMalformed, "a fragment of a large LCM message: commands are never fragmented");
  }
  if (magic != kShortMagic) return reject(DatagramKind::kMalformed, "not an LCM datagram (bad magic)");
  // The channel name: NUL-terminated within the datagram, at most 255 characters (LCM's limit).
  const auto* name = reinterpret_cast<const char*>(datagram.data() + 8);
  const std::size_t room = n - 8;
  const void* nul = std::memchr(name, '\0', room < 256 ? room : 256);
  if (!nul) return reject(DatagramKind::kMalformed, "channel name not terminated within 255 bytes");
  const std::string_view channel(name, static_cast<std::size_t>(static_cast<const char*>(nul) - name));
  if (channel != command_channel) return reject(DatagramKind::kOtherChannel, "another channel");
  if (n > kMaxCommandDatagramBytes) return reject(DatagramKind::kOversized, "longer than any command_t datagram");
  const std::size_t payload_at = 8 + channel.size() + 1;
  const int payload_bytes = static_cast<int>(n - payload_at);
  pneu_lcm::command_t c;
  // command_t is fixed-size: decode reads at most its kCommandPayloadBytes and cannot allocate. The guard
  // is the length check inside decode, and the exact-size check after it.
  const int used = c.decode(datagram.data() + payload_at, 0, payload_bytes);
  if (used < 0) return reject(DatagramKind::kMalformed, "not a pneu_lcm.command_t (wrong fingerprint or too short)");
  if (used != payload_bytes) return reject(DatagramKind::kMalformed, "trailing bytes after a command_t");
  DecodedDatagram d;
  d.kind = DatagramKind::kCommand;
  d.fields.utime = c.utime;
  d.fields.seq = c.seq;
  d.fields.kind = c.kind;
  d.fields.value = c.value;
  for (std::size_t i = 0; i < kOriginBytes; ++i) d.fields.origin[i] = static_cast<char>(c.origin[i]);
  d.fields.session = c.session;
  d.why = "";
  return d;
}

std::size_t encode_command_datagram(const CommandFields& f, std::string_view channel, std::uint32_t sequence,
                                    std::span<std::uint8_t> out) noexcept {
  pneu_lcm::command_t c;
  c.utime = f.utime;
  c.seq = f.seq;
  c.kind = f.kind;
  c.value = f.value;
  for (std::size_t i = 0; i < kOriginBytes; ++i) c.origin[i] = static_cast<std::int8_t>(f.origin[i]);
  c.session = f.session;
  const int payload = c.getEncodedSize();
  if (channel.size() > 255 || channel.find('\0') != std::string_view::npos) return 0;
  const std::size_t total = 8 + channel.size() + 1 + static_cast<std::size_t>(payload);
  if (out.size() < total) return 0;
  std::uint8_t* p = out.data();
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(kShortMagic >> (24 - 8 * i));
  for (int i = 0; i < 4; ++i) p[4 + i] = static_cast<std::uint8_t>(sequence >> (24 - 8 * i));
  std::memcpy(p + 8, channel.data(), channel.size());
  p[8 + channel.size()] = 0;
  if (c.encode(p + 8 + channel.size() + 1, 0, payload) != payload) return 0;
  return total;
}

}  // namespace pneu::telemetry
