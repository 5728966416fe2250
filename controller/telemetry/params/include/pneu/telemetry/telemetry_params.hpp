// The parameters of pneud's LCM telemetry (telemetry): where it publishes, how often health goes
// out, and whether a run on the simulated clock publishes too (lcm_bridge.hpp).
#pragma once

#include <cctype>
#include <string>

#include "pneu/config/describe.hpp"

namespace pneu::telemetry {

/// LCM telemetry (state, events, predictions, health).
struct TelemetryConfig {
  bool enabled = true;
  std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0";  ///< ttl=0: nothing leaves the host
  std::string channel_prefix = "PNEU_";   ///< channels: <prefix>STATE, EVENT, PREDICTION, HEALTH
  double health_period_s = 1.0;           ///< health message period [s]
  /// Publish also when the loop runs on the simulated clock (a 12 s run then floods the network
  /// with 12,000 states in a few tens of milliseconds and runs 5x slower).
  bool in_simulated_time = false;
};

/// A channel's name as an LCM subscription's regular expression matching it literally (LCM
/// subscribes by regular expression; a prefix may hold '.' and '-').
inline std::string regex_literal(const std::string& s) {
  std::string out;
  for (const char c : s) {
    const bool plain = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
    if (!plain) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace pneu::telemetry

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using telemetry::TelemetryConfig;

void describe(auto& a, Like<TelemetryConfig> auto& t) {
  a.field(PNEU_NVP(t, enabled), "publish (real clock; simulated clock with in_simulated_time)");
  a.field(PNEU_NVP(t, lcm_url), "LCM provider URL");
  a.check("lcm_url", !t.lcm_url.empty(), "must not be empty");
  a.field(PNEU_NVP(t, channel_prefix), "channels: <prefix>STATE, EVENT, PREDICTION, HEALTH");
  bool plain = true;
  for (char ch : t.channel_prefix)
    plain = plain && (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.');
  a.check("channel_prefix", plain, "may hold letters, digits, '_', '-' and '.' only");
  a.field(PNEU_NVP(t, health_period_s), Range::closed(0.01, 60.0), "health message period [s]");
  a.field(PNEU_NVP(t, in_simulated_time), "publish on the simulated clock too");
}

}  // namespace pneu::config::schema
