// One controller per bench: each pneud says who it is in its health messages (health_t's host,
// pid, start_utime, nonce), and listens on its health channel for another's. Before it starts, one
// heard is a refusal to start; while it runs, both latch a fault (FaultCause::kAnotherController)
// for as long as they hear each other. Pure logic here (InstanceWatch), and the decoder of a health
// datagram off the group (decode_health_datagram); LcmBridge does the listening.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace pneu::telemetry {

/// Who a pneud is on its channels.
struct InstanceId {
  std::string host;
  std::int32_t pid = 0;
  std::int64_t start_utime = 0;  ///< Unix time [us]
  std::int64_t nonce = 0;
  bool operator==(const InstanceId&) const = default;

  /// This process: its host name, pid, now, and a random nonce.
  [[nodiscard]] static InstanceId of_this_process();
};

/// "pneud pid 1234 on host bench-pc, started 2026-11-27 16:50:01 UTC", for people.
[[nodiscard]] std::string describe(const InstanceId& id);

/// A health message as heard: whose, whether it was its last (is_final), and its sender's health
/// period.
struct HealthHeard {
  InstanceId from;
  bool is_final = false;
  double period_s = 0.0;
};

/// The channel of `datagram` (a whole UDP payload off the LCM group) when it is one LCM short
/// message; nothing otherwise. The view points into `datagram`.
[[nodiscard]] std::optional<std::string_view> lcm_channel_of(std::span<const std::uint8_t> datagram);

/// Decodes `datagram` (a whole UDP payload off the LCM group) when it is one LCM short message on
/// `health_channel` holding a health_t; nothing otherwise (another channel, a fragment, garbage).
[[nodiscard]] std::optional<HealthHeard> decode_health_datagram(std::span<const std::uint8_t> datagram,
                                                                std::string_view health_channel);

/// Which other instance is heard now. Not thread-safe: the service thread owns it.
class InstanceWatch {
 public:
  /// `self`: this process (its own health, heard back off the group, is no other); `period_s`: its
  /// health period. Another instance counts as present until it said its last (is_final), or for 3
  /// of the longest of this period, its own and the interval between its messages after the last
  /// one heard.
  InstanceWatch(InstanceId self, double period_s);

  /// A health message heard at `now_s` (any monotonic clock).
  void heard(const HealthHeard& message, double now_s);
  /// The other instance heard, while it counts as present at `now_s`.
  [[nodiscard]] std::optional<InstanceId> other(double now_s) const;
  [[nodiscard]] const InstanceId& self() const noexcept { return self_; }

 private:
  InstanceId self_;
  double period_s_;
  std::optional<InstanceId> other_;
  double last_heard_s_ = 0.0;
  double interval_s_ = 0.0;  // between its last two messages (0: one heard so far)
  double other_period_s_ = 0.0;
};

}  // namespace pneu::telemetry
