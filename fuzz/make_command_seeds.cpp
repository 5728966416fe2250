// Writes the seeds of fuzz/corpus/command/ with encode_command_datagram (not a fuzzer):
//
//   build/fuzz/pneu_fuzz_command_seeds fuzz/corpus/command
//
// One valid datagram per command kind on PNEU_COMMAND, odd values (NaN with a payload, -0, inf,
// denormal, extreme integers, an unknown kind), the same command on another channel, an LC03
// fragment header, a bad magic, truncations at every field boundary and trailing bytes.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "pneu/telemetry/command_datagram.hpp"

namespace {
using pneu::telemetry::CommandFields;
using Bytes = std::vector<std::uint8_t>;

Bytes encode(const CommandFields& f, std::string_view channel = "PNEU_COMMAND", std::uint32_t sequence = 1) {
  Bytes out(pneu::telemetry::kMaxCommandDatagramBytes + 64);
  const std::size_t n = pneu::telemetry::encode_command_datagram(f, channel, sequence, out);
  if (n == 0) {
    std::fprintf(stderr, "encode_command_datagram failed\n");
    std::exit(1);
  }
  out.resize(n);
  return out;
}

// Who sent it (command_t.origin, .session), as pneu-dash and pneu-command say.
CommandFields attributed(CommandFields f, const std::string& origin, std::int64_t session) {
  pneu::telemetry::set_origin(f.origin, origin);
  f.session = session;
  return f;
}

double nan_with_payload() {
  const std::uint64_t bits = 0x7ff80000deadbeefULL;
  double v;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

bool write(const std::string& dir, const std::string& name, const Bytes& b) {
  const std::string path = dir + "/" + name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  const bool ok = std::fwrite(b.data(), 1, b.size(), f) == b.size();
  return std::fclose(f) == 0 && ok;
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  const std::int64_t t = 1'700'000'000'000'000;  // utime: microseconds since the epoch
  std::vector<std::pair<std::string, Bytes>> seeds = {
      {"set_point", encode({t, 1, 1, 0.17})},
      {"set_point_step", encode({t + 1000, 2, 2, -0.005})},
      {"arm", encode({t + 2000, 3, 3, 0.0})},
      {"disarm", encode({t + 3000, 4, 4, 0.0})},
      {"fault_reset", encode({t + 4000, 5, 5, 0.0})},
      {"unknown_kind", encode({t, 6, -128, 1.0})},
      {"nan_payload", encode({t, 7, 1, nan_with_payload()})},
      {"minus_inf", encode({0, 8, 2, -std::numeric_limits<double>::infinity()})},
      {"minus_zero", encode({-1, 8, 1, -0.0})},
      {"denormal_extremes", encode({std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max(), 1,
                                    std::numeric_limits<double>::denorm_min()}, "PNEU_COMMAND", 0xffffffffu)},
      {"other_channel_state", encode({t, 9, 1, 0.1}, "PNEU_STATE")},
      {"empty_channel", encode({t, 10, 1, 0.1}, "")},
      {"attributed_set_point", encode(attributed({t, 11, 1, 0.17}, "pneu-dash 127.0.0.1:8765", 4503599627370497))},
      {"origin_control_characters", encode(attributed({t, 12, 3, 0.0}, "pneu-dash \x1b[2J\r\n", -1))},
      {"origin_full_no_nul", encode(attributed({t, 13, 4, 0.0}, std::string(32, 'o'), 1))},
  };
  // Truncations at the field boundaries of the set-point datagram: header, channel, fingerprint,
  // utime, seq, kind, and one byte short of the value; then one trailing byte.
  const Bytes whole = seeds[0].second;
  for (const std::size_t keep : {4u, 8u, 12u, 21u, 29u, 37u, 45u, 46u, 53u}) {
    if (keep < whole.size()) seeds.push_back({"truncated_" + std::to_string(keep), Bytes(whole.begin(), whole.begin() + keep)});
  }
  // ... and one byte short of the session, the last field.
  seeds.push_back({"truncated_session", Bytes(whole.begin(), whole.end() - 1)});
  Bytes trailing = whole;
  trailing.push_back(0);
  seeds.push_back({"trailing_byte", trailing});
  // A fragment header: "LC03" magic, sequence, then fragment fields.
  Bytes fragment = whole;
  fragment[3] = '3';
  seeds.push_back({"fragment_lc03", fragment});
  seeds.push_back({"fragment_lc03_magic_only", Bytes{'L', 'C', '0', '3'}});
  Bytes bad_magic = whole;
  bad_magic[0] = 'X';
  seeds.push_back({"bad_magic", bad_magic});
  Bytes bad_fingerprint = whole;
  bad_fingerprint[8 + 13] ^= 0x01;
  seeds.push_back({"bad_fingerprint", bad_fingerprint});

  for (const auto& [name, bytes] : seeds) {
    if (!write(dir, name, bytes)) {
      std::fprintf(stderr, "cannot write %s/%s\n", dir.c_str(), name.c_str());
      return 1;
    }
  }
  std::printf("%zu seeds written to %s\n", seeds.size(), dir.c_str());
  return 0;
}
