// libFuzzer target: pneu::telemetry::decode_command_datagram, the decoder of inbound UDP command
// datagrams, on the channel pneud listens to ("PNEU_COMMAND" with the default prefix).
//
// Held, for every byte string: the decoder returns (it is noexcept: a throw would terminate)
// without a crash or sanitizer report, with a known kind and a reason when it rejects. When the
// datagram decodes as a command:
//   - it is exactly as long as a short message with a command_t on that channel;
//   - encode_command_datagram of the decoded fields (with the datagram's own sequence number)
//     reproduces the datagram byte for byte (LCM's encoding is canonical), and
//   - that datagram decodes to the same fields, bit for bit (NaN payloads compared by memcpy).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>
#include <string_view>

#include "pneu/telemetry/command_datagram.hpp"

namespace {
using pneu::telemetry::CommandFields;
using pneu::telemetry::DatagramKind;

constexpr std::string_view kChannel = "PNEU_COMMAND";
using pneu::telemetry::kCommandPayloadBytes;

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "pneu_fuzz_command: %s\n", what);
  std::abort();
}

bool same_fields(const CommandFields& a, const CommandFields& b) {
  std::uint64_t va = 0, vb = 0;
  std::memcpy(&va, &a.value, sizeof va);
  std::memcpy(&vb, &b.value, sizeof vb);
  return a.utime == b.utime && a.seq == b.seq && a.kind == b.kind && va == vb && a.origin == b.origin &&
         a.session == b.session;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> datagram(data, size);
  const auto d = pneu::telemetry::decode_command_datagram(datagram, kChannel);

  switch (d.kind) {
    case DatagramKind::kOtherChannel:
    case DatagramKind::kMalformed:
    case DatagramKind::kOversized:
      if (d.why == nullptr || d.why[0] == '\0') fail("a rejection without a reason");
      return 0;
    case DatagramKind::kCommand:
      break;
    default:
      fail("an unknown DatagramKind");
  }

  if (size != 8 + kChannel.size() + 1 + kCommandPayloadBytes) fail("a command datagram of the wrong length");
  const std::uint32_t sequence = (std::uint32_t{data[4]} << 24) | (std::uint32_t{data[5]} << 16) |
                                 (std::uint32_t{data[6]} << 8) | std::uint32_t{data[7]};
  std::uint8_t again[pneu::telemetry::kMaxCommandDatagramBytes];
  const std::size_t n = pneu::telemetry::encode_command_datagram(d.fields, kChannel, sequence, again);
  if (n == 0) fail("encode_command_datagram refused the fields of a decoded command");
  if (n != size || std::memcmp(again, data, size) != 0)
    fail("re-encoding a decoded command does not reproduce the datagram");
  const auto d2 = pneu::telemetry::decode_command_datagram(std::span<const std::uint8_t>(again, n), kChannel);
  if (d2.kind != DatagramKind::kCommand) fail("a re-encoded command does not decode as a command");
  if (!same_fields(d.fields, d2.fields)) fail("a re-encoded command decodes to other fields");
  return 0;
}
