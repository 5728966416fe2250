#include "pneu/dash/pneu_channels.hpp"

#include "pneu/controller/records.hpp"
#include "pneu/records/json.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu/records/schema.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
#include "pneu_lcm/state_t_members.hpp"

namespace pneu::dash {
namespace {

using controller::EventMessage;
using controller::ForecastRecord;
using controller::HealthMessage;
using controller::IdentificationRecord;
using controller::TickRecord;

template <class Message, class Record>
std::optional<std::string> decode(const void* data, std::size_t size) {
  if (size < 8 || size > 0x7fffffff) return std::nullopt;
  Message m{};
  if (m.decode(data, 0, static_cast<int>(size)) != static_cast<int>(size)) return std::nullopt;
  Record r{};
  records::from_lcm(m, r);
  std::string out;
  records::write_json_object(out, r);
  return out;
}

template <class Record>
std::string schema() {
  return records::json_schema<Record>(std::string("https://pneu.invalid/schemas/") +
                                      records::Description<Record>::kName + ".schema.json");
}

// Calls f.template operator()<Message, Record>() for the channel's pair.
template <class F>
auto with_types(PneuChannel c, F&& f) {
  switch (c) {
    case PneuChannel::kState:
      return f.template operator()<pneu_lcm::state_t, TickRecord>();
    case PneuChannel::kEvent:
      return f.template operator()<pneu_lcm::event_t, EventMessage>();
    case PneuChannel::kPrediction:
      return f.template operator()<pneu_lcm::prediction_t, ForecastRecord>();
    case PneuChannel::kHealth:
      return f.template operator()<pneu_lcm::health_t, HealthMessage>();
    case PneuChannel::kIdentification:
      break;
  }
  return f.template operator()<pneu_lcm::identification_t, IdentificationRecord>();
}

constexpr PneuChannel kAll[] = {PneuChannel::kState, PneuChannel::kEvent, PneuChannel::kPrediction,
                                PneuChannel::kHealth, PneuChannel::kIdentification};

}  // namespace

const char* suffix_of(PneuChannel c) {
  switch (c) {
    case PneuChannel::kState:
      return "STATE";
    case PneuChannel::kEvent:
      return "EVENT";
    case PneuChannel::kPrediction:
      return "PREDICTION";
    case PneuChannel::kHealth:
      return "HEALTH";
    case PneuChannel::kIdentification:
      break;
  }
  return "IDENTIFICATION";
}

const char* schema_name_of(PneuChannel c) {
  return with_types(c, []<class M, class R>() { return records::Description<R>::kName; });
}

std::string schema_of(PneuChannel c) {
  return with_types(c, []<class M, class R>() { return schema<R>(); });
}

const char* sequence_field_of(PneuChannel c) {
  // The tick's seq counts every tick; identification's updates every message. The others have
  // none (health's ticks jump by a period's ticks, events and forecasts are numbered per stop).
  switch (c) {
    case PneuChannel::kState:
      return "seq";
    case PneuChannel::kIdentification:
      return "updates";
    default:
      return "";
  }
}

bool latest_wins_of(PneuChannel c) { return c == PneuChannel::kState; }

std::optional<std::string> record_json(PneuChannel c, const void* data, std::size_t size) {
  return with_types(c, [&]<class M, class R>() { return decode<M, R>(data, size); });
}

PneuFeed::PneuFeed(Server& server, std::string prefix) : server_(server), prefix_(std::move(prefix)) {
  for (const PneuChannel c : kAll) {
    ChannelSpec spec;
    spec.topic = prefix_ + suffix_of(c);
    spec.schema_name = schema_name_of(c);
    spec.schema = schema_of(c);
    spec.sequence_field = sequence_field_of(c);
    spec.latest_wins = latest_wins_of(c);
    ids_[static_cast<std::size_t>(c)] = server_.add_channel(std::move(spec));
  }
}

bool PneuFeed::forward(const std::string& lcm_channel, const void* data, std::size_t size, std::int64_t recv_utime) {
  if (lcm_channel.size() <= prefix_.size() || lcm_channel.compare(0, prefix_.size(), prefix_) != 0) return false;
  const std::string_view suffix = std::string_view(lcm_channel).substr(prefix_.size());
  for (const PneuChannel c : kAll) {
    if (suffix != suffix_of(c)) continue;
    auto text = record_json(c, data, size);
    if (!text) {
      ++undecodable_;
      return false;
    }
    server_.publish(id(c), recv_utime > 0 ? static_cast<std::uint64_t>(recv_utime) * 1000u : 0u, std::move(*text));
    return true;
  }
  return false;
}

std::vector<std::pair<std::string, std::string>> pneud_metadata() {
  std::string modes;
  for (const auto& [mode, name] : controller::kModeNames)
    modes += (modes.empty() ? "" : ",") + std::to_string(static_cast<int>(mode)) + ":" + name;
  return {{"modes", modes}};
}


}  // namespace pneu::dash
