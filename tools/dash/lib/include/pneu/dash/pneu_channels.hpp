// pneud's LCM channels on the dashboard: one Foxglove channel per channel pneud publishes
// (<prefix>STATE, EVENT, PREDICTION, HEALTH, IDENTIFICATION; controller/telemetry/src/lcm_bridge.cpp),
// each message decoded with its generated LCM type into its record and sent as the record's JSON
// (pneu/records/json.hpp), advertised with the JSON Schema derived from the same description
// (pneu/records/schema.hpp).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "pneu/dash/server.hpp"

namespace pneu::dash {

/// The channels, by the suffix of their LCM channel's name.
enum class PneuChannel : std::uint8_t { kState, kEvent, kPrediction, kHealth, kIdentification };
inline constexpr std::size_t kPneuChannelCount = 5;

/// "STATE", "EVENT", ...
[[nodiscard]] const char* suffix_of(PneuChannel c);
/// The record's name (its schemaName): "tick", "event_message", "forecast", "health", "identification".
[[nodiscard]] const char* schema_name_of(PneuChannel c);
/// The JSON Schema of its messages, derived from the record's description.
[[nodiscard]] std::string schema_of(PneuChannel c);
/// Its field that counts messages without gaps ("" when the record has none).
[[nodiscard]] const char* sequence_field_of(PneuChannel c);
/// Whether each message supersedes the last (the tick records, 1 kHz): a subscription may ask for
/// them at most at a rate (ChannelSpec::latest_wins). The others (events, forecasts, health,
/// identification) are never decimated.
[[nodiscard]] bool latest_wins_of(PneuChannel c);
/// The record carried by an LCM message of the channel's type as JSON; nothing when the bytes do
/// not decode whole as that type (wrong fingerprint, short, or bytes left over).
[[nodiscard]] std::optional<std::string> record_json(PneuChannel c, const void* data, std::size_t size);

/// Adds the channels to a server (topics: prefix + suffix) and forwards LCM messages to them.
class PneuFeed {
 public:
  PneuFeed(Server& server, std::string prefix);

  /// Forwards one LCM message of `lcm_channel` received at `recv_utime` (us since the epoch):
  /// false when it is none of the channels, or does not decode (counted in undecodable()).
  bool forward(const std::string& lcm_channel, const void* data, std::size_t size, std::int64_t recv_utime);

  [[nodiscard]] const std::string& prefix() const noexcept { return prefix_; }
  [[nodiscard]] ChannelId id(PneuChannel c) const noexcept { return ids_[static_cast<std::size_t>(c)]; }
  [[nodiscard]] std::uint64_t undecodable() const noexcept { return undecodable_; }

 private:
  Server& server_;
  std::string prefix_;
  std::array<ChannelId, kPneuChannelCount> ids_{};
  std::atomic<std::uint64_t> undecodable_{0};
};

/// serverInfo's metadata for pneud's channels: "modes", the loop's modes by their number on the
/// wire ("0:DISARMED,1:ARMED,..." from the controller's table), for a client to name state_t's and
/// health_t's `mode`.
[[nodiscard]] std::vector<std::pair<std::string, std::string>> pneud_metadata();

}  // namespace pneu::dash
