// pneud's LCM messages into Metrics: each message of <prefix>EVENT, PREDICTION, HEALTH and
// IDENTIFICATION decoded with its generated LCM type into its record (pneu/records/lcm.hpp) and
// handed over; <prefix>STATE is not needed for the metrics (health_t sums the loop up).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <string>

#include "pneu/dash/metrics.hpp"

namespace pneu::dash {

class MetricsFeed {
 public:
  MetricsFeed(Metrics& metrics, std::string prefix)
      : metrics_(metrics), prefix_(std::move(prefix)) {}

  /// Hands one LCM message of `lcm_channel` to the metrics: false when it is none of their channels
  /// or does not decode whole (counted in undecodable()).
  bool forward(const std::string& lcm_channel, const void* data, std::size_t size);

  [[nodiscard]] std::uint64_t undecodable() const noexcept { return undecodable_; }

 private:
  Metrics& metrics_;
  std::string prefix_;
  std::atomic<std::uint64_t> undecodable_{0};
};

}  // namespace pneu::dash
