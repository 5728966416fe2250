#include "pneu/telemetry/instance_watch.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <random>
#include <stdexcept>

#include "pneu_lcm/health_t.hpp"

namespace pneu::telemetry {

InstanceId InstanceId::of_this_process() {
  InstanceId id;
  char host[256] = "";
  if (::gethostname(host, sizeof host - 1) == 0) id.host = host;
  id.pid = static_cast<std::int32_t>(::getpid());
  id.start_utime =
      std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::random_device random;
  id.nonce = static_cast<std::int64_t>((std::uint64_t{random()} << 32) | random());
  return id;
}

std::string describe(const InstanceId& id) {
  const std::time_t started = static_cast<std::time_t>(id.start_utime / 1000000);
  std::tm utc{};
  char when[32] = "?";
  if (::gmtime_r(&started, &utc)) std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S UTC", &utc);
  return "pneud pid " + std::to_string(id.pid) + " on host " + (id.host.empty() ? "?" : id.host) + ", started " + when;
}

std::optional<std::string_view> lcm_channel_of(std::span<const std::uint8_t> datagram) {
  constexpr std::uint8_t kShortMagic[4] = {0x4c, 0x43, 0x30, 0x32};  // "LC02": a whole message in one datagram
  const std::size_t n = datagram.size();
  if (n < 8 || std::memcmp(datagram.data(), kShortMagic, 4) != 0) return std::nullopt;
  const auto* name = reinterpret_cast<const char*>(datagram.data() + 8);
  const void* nul = std::memchr(name, '\0', std::min<std::size_t>(n - 8, 256));
  if (!nul) return std::nullopt;
  return std::string_view(name, static_cast<std::size_t>(static_cast<const char*>(nul) - name));
}

std::optional<HealthHeard> decode_health_datagram(std::span<const std::uint8_t> datagram, std::string_view health_channel) {
  const std::optional<std::string_view> channel = lcm_channel_of(datagram);
  if (!channel || *channel != health_channel) return std::nullopt;
  const std::size_t at = 8 + channel->size() + 1;
  const int bytes = static_cast<int>(datagram.size() - at);
  pneu_lcm::health_t h;
  try {  // lcm-gen's string decoding trusts the length on the wire: a hostile one can throw
    if (h.decode(datagram.data() + at, 0, bytes) != bytes) return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
  HealthHeard heard;
  heard.from = {h.host, h.pid, h.start_utime, h.nonce};
  heard.is_final = h.is_final;
  heard.period_s = h.period;
  return heard;
}

InstanceWatch::InstanceWatch(InstanceId self, double period_s) : self_(std::move(self)), period_s_(period_s) {}

void InstanceWatch::heard(const HealthHeard& m, double now_s) {
  if (m.from == self_) return;
  const bool same = other_ && *other_ == m.from;
  if (m.is_final) {
    if (same) other_.reset();  // it stopped
    return;
  }
  interval_s_ = same ? now_s - last_heard_s_ : 0.0;
  other_period_s_ = std::isfinite(m.period_s) ? m.period_s : 0.0;
  other_ = m.from;
  last_heard_s_ = now_s;
}

std::optional<InstanceId> InstanceWatch::other(double now_s) const {
  if (other_ && now_s - last_heard_s_ <= 3.0 * std::max({period_s_, other_period_s_, interval_s_})) return other_;
  return std::nullopt;
}

}  // namespace pneu::telemetry
