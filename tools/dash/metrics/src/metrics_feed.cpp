#include "pneu/dash/metrics_feed.hpp"

#include <optional>
#include <string_view>

#include "pneu/records/lcm.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/prediction_t_members.hpp"

namespace pneu::dash {
namespace {

// The record an LCM message of type Message carries; nothing when the bytes do not decode whole.
template <class Message, class Record>
std::optional<Record> decode(const void* data, std::size_t size) {
  if (size < 8 || size > 0x7fffffff) return std::nullopt;
  Message m{};
  if (m.decode(data, 0, static_cast<int>(size)) != static_cast<int>(size)) return std::nullopt;
  Record r{};
  records::from_lcm(m, r);
  return r;
}

}  // namespace

bool MetricsFeed::forward(const std::string& lcm_channel, const void* data, std::size_t size) {
  if (!lcm_channel.starts_with(prefix_)) return false;
  const std::string_view suffix = std::string_view(lcm_channel).substr(prefix_.size());
  const auto hand = [&](auto&& record, auto&& to) {
    if (!record) {
      ++undecodable_;
      return false;
    }
    to(*record);
    return true;
  };
  if (suffix == "HEALTH")
    return hand(decode<pneu_lcm::health_t, controller::HealthMessage>(data, size),
                [&](const auto& r) { metrics_.on_health(r); });
  if (suffix == "EVENT")
    return hand(decode<pneu_lcm::event_t, controller::EventMessage>(data, size),
                [&](const auto& r) { metrics_.on_event(r); });
  if (suffix == "PREDICTION")
    return hand(decode<pneu_lcm::prediction_t, controller::ForecastRecord>(data, size),
                [&](const auto& r) { metrics_.on_forecast(r); });
  if (suffix == "IDENTIFICATION")
    return hand(decode<pneu_lcm::identification_t, controller::IdentificationRecord>(data, size),
                [&](const auto& r) { metrics_.on_identification(r); });
  return false;
}

}  // namespace pneu::dash
