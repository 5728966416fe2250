// libFuzzer target: pneu::config::load_string on untrusted YAML text and --set overrides.
//
// Input layout: the YAML text, then optionally overrides, each after a NUL byte (a --set string
// comes from argv and cannot hold a NUL, so NUL is a natural separator):
//
//   <yaml> [ \0 <key=value> [ \0 <key=value> ... ] ]
//
// When there is at least one override and the YAML part is empty, the base is the embedded
// config/sim.yaml, so that the overrides reach a whole, valid configuration and its validation.
//
// The contract held: load_string returns, or throws pneu::config::ConfigError. Only ConfigError
// is caught; any other exception escapes (std::terminate: a crash for libFuzzer), like a crash, a
// sanitizer report, a leak or a timeout. When it returns, to_yaml's output must load again (its
// documented contract) and print the same text again.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/config/config.hpp"

namespace {
constexpr std::size_t kMaxOverrides = 4;

[[noreturn]] void fail(const char* what, const std::string& detail) {
  std::fprintf(stderr, "pneu_fuzz_config: %s\n%s\n", what, detail.c_str());
  std::abort();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::string_view yaml = input;
  std::vector<std::string> overrides;
  if (const auto nul = input.find('\0'); nul != std::string_view::npos) {
    yaml = input.substr(0, nul);
    std::string_view rest = input.substr(nul + 1);
    while (overrides.size() < kMaxOverrides) {
      const auto next = rest.find('\0');
      overrides.emplace_back(rest.substr(0, next));
      if (next == std::string_view::npos) break;
      rest = rest.substr(next + 1);
    }
    if (yaml.empty()) yaml = pneu::config::default_config_yaml();
  }

  pneu::config::Config config;
  try {
    config = pneu::config::load_string(yaml, overrides, "<fuzz>");
  } catch (const pneu::config::ConfigError&) {
    return 0;  // refused with a key and a reason: the contract
  }

  // Accepted: the effective configuration must print as YAML that loads again, to itself.
  const std::string printed = pneu::config::to_yaml(config);
  std::string reprinted;
  try {
    reprinted = pneu::config::to_yaml(pneu::config::load_string(printed, {}, "<to_yaml>"));
  } catch (const pneu::config::ConfigError& e) {
    fail("to_yaml() of an accepted configuration does not load again:", std::string(e.what()) + "\n--- to_yaml:\n" + printed);
  }
  if (reprinted != printed)
    fail("to_yaml() is not a fixed point of load_string():", "--- first:\n" + printed + "--- second:\n" + reprinted);
  return 0;
}
