#include "pneu/telemetry/lcm_bridge.hpp"

#include <arpa/inet.h>
#include <poll.h>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <limits>
#include <thread>
#include <utility>

#include "pneu/controller/journal.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/telemetry/command_datagram.hpp"

#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/identification_t_members.hpp"
#include "pneu_lcm/state_t.hpp"
#include "pneu_lcm/event_t_members.hpp"
#include "pneu_lcm/health_t_members.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
#include "pneu_lcm/state_t_members.hpp"

namespace pneu::telemetry {

using controller::LoopEvent;

namespace {
constexpr int kRejectionEventsPerSecond = 20;
// The largest datagram read off the group: any command (longer ones are refused as oversized) and
// any health message (a host name of up to 255 bytes).
constexpr std::size_t kMaxDatagramBytes = 2048;

std::int64_t unix_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}
}  // namespace

LcmBridge::LcmBridge(const TelemetryConfig& telemetry, CommandValidator validator, controller::LoopOutputs& loop,
                     bool accept_commands)
    : lcm_(std::make_unique<lcm::LCM>(telemetry.lcm_url)),
      url_(telemetry.lcm_url),
      prefix_(telemetry.channel_prefix),
      state_channel_(prefix_ + "STATE"),
      event_channel_(prefix_ + "EVENT"),
      prediction_channel_(prefix_ + "PREDICTION"),
      health_channel_(prefix_ + "HEALTH"),
      command_channel_(prefix_ + "COMMAND"),
      identification_channel_(prefix_ + "IDENTIFICATION"),
      loop_(loop),
      accept_commands_(accept_commands),
      watch_(InstanceId::of_this_process(), telemetry.health_period_s),
      health_period_s_(telemetry.health_period_s),
      validator_(std::move(validator)),
      epoch_utime_(unix_now_us()),
      started_(std::chrono::steady_clock::now()) {
  if (!lcm_->good())
    throw LcmError("LCM could not start on '" + telemetry.lcm_url +
                   "' (no multicast route? e.g. `ip route add 224.0.0.0/4 dev lo` keeps it on this "
                   "host; or set telemetry.enabled=false)");
  const bool udpm = telemetry.lcm_url.rfind("udpm://", 0) == 0;
  if (accept_commands || udpm) {
    try {
      socket_ = std::make_unique<CommandSocket>(telemetry.lcm_url);
    } catch (const std::exception& e) {
      if (accept_commands) throw LcmError(std::string("commands: ") + e.what());
      watch_off_ = std::string("no socket on the LCM group: ") + e.what();
    }
  } else {
    watch_off_ = "telemetry.lcm_url '" + telemetry.lcm_url + "' is not udpm://: nothing is heard on it";
  }
}

LcmBridge::~LcmBridge() = default;

bool LcmBridge::handle(int timeout_ms) {
  if (!socket_) {
    std::this_thread::sleep_for(std::chrono::milliseconds(timeout_ms));
    return true;
  }
  pollfd p{socket_->fd(), POLLIN, 0};
  const int ready = ::poll(&p, 1, timeout_ms);
  if (ready < 0) return errno == EINTR;
  if (ready > 0) {
    std::array<std::uint8_t, kMaxDatagramBytes> buffer{};
    CommandSocket::Datagram d;
    for (int k = 0; k < 256 && socket_->receive(buffer, d); ++k)
      dispatch(std::span<const std::uint8_t>(buffer.data(), d.stored), d);
  }
  update_watch();
  return true;
}

double LcmBridge::watch_time_s() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
}

void LcmBridge::dispatch(std::span<const std::uint8_t> bytes, const CommandSocket::Datagram& d) {
  // One byte more than any command: a longer datagram is seen as oversized (MSG_TRUNC gives its
  // real length), whatever the buffer held.
  const auto command_bytes = bytes.first(std::min(bytes.size(), kMaxCommandDatagramBytes + 1));
  if (decode_command_datagram(command_bytes, command_channel_).kind != DatagramKind::kOtherChannel) {
    if (accept_commands_) on_datagram(command_bytes, d);
    return;
  }
  if (d.bytes > bytes.size()) return;  // longer than any health message
  if (const auto heard = decode_health_datagram(bytes, health_channel_)) watch_.heard(*heard, watch_time_s());
}

void LcmBridge::update_watch() {
  const std::optional<InstanceId> other = watch_.other(watch_time_s());
  if (other && !other_said_) {
    other_said_ = true;
    loop_.external_fault.store(controller::FaultCause::kAnotherController, std::memory_order_relaxed);
    controller::journal_line(stderr, controller::Priority::kErr,
                             "another controller on the channels " + prefix_ + "*: " + describe(*other) +
                                 " (this one: pid " + std::to_string(instance().pid) +
                                 "): both latch a fault (another-controller); stop one, then reset the other");
  } else if (!other && other_said_) {
    other_said_ = false;
    loop_.external_fault.store(controller::FaultCause::kNone, std::memory_order_relaxed);
    controller::journal_line(stderr, controller::Priority::kNotice,
                             "the other controller on " + prefix_ + "* is no longer heard: a fault reset is accepted again");
  }
}

std::optional<std::string> LcmBridge::listen_for_another(double listen_s) {
  if (!socket_) return std::nullopt;
  const double until_s = watch_time_s() + listen_s;
  std::array<std::uint8_t, kMaxDatagramBytes> buffer{};
  CommandSocket::Datagram d;
  std::optional<in_addr> state_from;  // <prefix>STATE heard: this pneud publishes none yet
  // Once its state is heard, a while longer for its health, to name it.
  const auto left = [&] { return (state_from ? until_s + 2.0 * listen_s : until_s) - watch_time_s(); };
  for (double left_s = listen_s; left_s > 0.0; left_s = left()) {
    pollfd p{socket_->fd(), POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(std::ceil(left_s * 1e3))) <= 0) continue;
    while (socket_->receive(buffer, d)) {
      if (d.bytes > d.stored) continue;
      const std::span<const std::uint8_t> bytes(buffer.data(), d.stored);
      if (!state_from && lcm_channel_of(bytes) == std::string_view(state_channel_)) state_from = d.source;
      if (const auto heard = decode_health_datagram(bytes, health_channel_)) watch_.heard(*heard, watch_time_s());
    }
    if (const auto other = watch_.other(watch_time_s())) return describe(*other);
  }
  if (!state_from) return std::nullopt;
  char source[INET_ADDRSTRLEN] = "?";
  inet_ntop(AF_INET, &*state_from, source, sizeof source);
  char within[32];
  std::snprintf(within, sizeof within, "%.2f s", 3.0 * listen_s);
  return "a publisher of " + state_channel_ + " (from " + source + "; no health of it heard within " + within +
         " to name it)";
}

std::int64_t LcmBridge::utime_of(double t_s) const noexcept {
  return epoch_utime_ + static_cast<std::int64_t>(std::llround(t_s * 1e6));
}

template <typename T>
void LcmBridge::publish(const std::string& channel, const T& msg) {
  if (lcm_->publish(channel, &msg) != 0) ++publish_errors_;
}

void LcmBridge::on_tick(const controller::TickRecord& r, const controller::ExpectedAtTick& /*expected*/) {
  last_t_s_ = r.t_s;
  pneu_lcm::state_t m;
  m.utime = utime_of(r.t_s);
  records::to_lcm(r, m);
  publish(state_channel_, m);
}

void LcmBridge::on_event(const LoopEvent& e) {
  pneu_lcm::event_t m;
  m.utime = utime_of(e.t_s);
  records::to_lcm(controller::event_message(e), m);
  publish(event_channel_, m);
}

void LcmBridge::on_forecast(const controller::ForecastRecord& f) {
  pneu_lcm::prediction_t m;
  m.utime = utime_of(f.t_s);
  records::to_lcm(f, m);
  publish(prediction_channel_, m);
}

void LcmBridge::on_identification(const controller::IdentificationRecord& r) {
  pneu_lcm::identification_t m{};
  m.utime = utime_of(r.t_s);
  records::to_lcm(r, m);
  publish(identification_channel_, m);
}

void LcmBridge::on_health(const controller::HealthRecord& h) {
  const CommandCounters& c = validator_.counters();
  controller::HealthMessage r;
  r.t_s = h.t_s;
  r.mode = static_cast<std::int8_t>(h.mode);
  r.ticks = static_cast<std::int64_t>(h.ticks);
  r.overruns = static_cast<std::int64_t>(h.overruns);
  r.wake_latency_us = {h.wake_latency_s[0] * 1e6, h.wake_latency_s[1] * 1e6, h.wake_latency_s[2] * 1e6,
                       h.wake_latency_s[3] * 1e6};
  r.compute_us = {h.compute_s[0] * 1e6, h.compute_s[1] * 1e6, h.compute_s[2] * 1e6, h.compute_s[3] * 1e6};
  r.comms_errors = static_cast<std::int64_t>(h.comms_errors);
  r.telemetry_dropped = static_cast<std::int64_t>(h.ticks_dropped + h.events_dropped + publish_errors_);
  r.commands_received = static_cast<std::int64_t>(c.received);
  r.commands_accepted = static_cast<std::int64_t>(c.accepted);
  r.commands_rejected = static_cast<std::int64_t>(c.rejected);
  r.rejected_malformed = static_cast<std::int64_t>(c.malformed);
  r.rejected_invalid = static_cast<std::int64_t>(c.invalid);
  r.rejected_rate = static_cast<std::int64_t>(c.rate);
  r.rejected_mode = static_cast<std::int64_t>(c.mode);
  r.rejected_sequence = static_cast<std::int64_t>(c.sequence);
  r.rejected_stale = static_cast<std::int64_t>(c.stale);
  r.rejected_foreign = static_cast<std::int64_t>(c.foreign);
  r.rejected_oversized = static_cast<std::int64_t>(c.oversized);
  r.deadlines_skipped = static_cast<std::int64_t>(h.deadlines_skipped);
  r.fault_cause = static_cast<std::int8_t>(controller::fault_number(h.fault_cause));
  r.faults = static_cast<std::int64_t>(h.faults);
  r.is_final = h.is_final;
  const InstanceId& self = instance();
  r.host = self.host;
  r.pid = self.pid;
  r.start_utime = self.start_utime;
  r.nonce = self.nonce;
  r.period_s = health_period_s_;
  pneu_lcm::health_t m;
  m.utime = utime_of(h.t_s);
  records::to_lcm(r, m);
  publish(health_channel_, m);
}

void LcmBridge::on_end(double t_end_s) {
  last_t_s_ = t_end_s;
  publish_text_event(controller::event_kind::kEnd, "end of run");
}

controller::TelemetryFigures LcmBridge::figures() const {
  controller::TelemetryFigures f;
  f.lcm_url = url_;
  f.channel_prefix = prefix_;
  f.publish_errors = publish_errors_;
  f.commands = validator_.counters();
  f.commands_dropped = commands_dropped_;
  return f;
}

void LcmBridge::publish_text_event(std::int8_t kind, const std::string& text, std::int64_t seq, std::string origin,
                                   std::int64_t session) {
  controller::EventMessage e;
  e.kind = kind;
  e.t_s = last_t_s_;
  e.seq = seq;
  e.origin = std::move(origin);
  e.session = session;
  e.text = text;
  pneu_lcm::event_t m;
  m.utime = unix_now_us();
  records::to_lcm(e, m);
  publish(event_channel_, m);
}

// Decoding happens here, on the service thread, in a total decoder (decode_command_datagram):
// command_t is fixed-size, so a hostile datagram can at worst fail to decode, and nothing it says
// reaches the loop unvalidated.
void LcmBridge::on_datagram(std::span<const std::uint8_t> bytes, const CommandSocket::Datagram& d) {
  DecodedDatagram decoded = decode_command_datagram(bytes, command_channel_);
  if (d.bytes > bytes.size() && decoded.kind != DatagramKind::kOtherChannel) {
    decoded.kind = DatagramKind::kOversized;  // cut by the buffer: longer than any command
    decoded.why = "longer than any command_t datagram";
  }
  if (decoded.kind == DatagramKind::kOtherChannel) return;  // our own telemetry, another axis
  const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
  Verdict v;
  char source[INET_ADDRSTRLEN] = "?";
  inet_ntop(AF_INET, &d.source, source, sizeof source);
  if (!d.from_this_host) {
    v = validator_.refuse(Rejection::kForeign, std::string("a datagram from ") + source +
                                                   ", another host: commands are accepted from this host only");
  } else if (decoded.kind == DatagramKind::kOversized) {
    v = validator_.refuse(Rejection::kOversized, "a datagram of " + std::to_string(d.bytes) + " bytes: " + decoded.why);
  } else if (decoded.kind == DatagramKind::kMalformed) {
    v = validator_.malformed(decoded.why);
  } else {
    v = validator_.validate(decoded.fields, now_s, unix_now_us(), loop_.setpoint_m.load(std::memory_order_relaxed),
                            loop_.mode.load(std::memory_order_relaxed));
  }
  const char* reason = to_string(v.rejection);
  if (v.accepted && !loop_.commands.try_push(v.command)) {
    ++commands_dropped_;
    v.accepted = false;
    reason = "queue_full";
    v.text = "command queue to the loop is full: " + v.text + " dropped";
  }
  if (!v.accepted) {
    if (now_s - rejection_window_s_ >= 1.0) {
      rejection_window_s_ = now_s;
      rejection_events_in_window_ = 0;
    }
    if (++rejection_events_in_window_ > kRejectionEventsPerSecond) {
      ++rejection_events_suppressed_;
      return;
    }
  }
  // The verdict names the command by its sequence number, so that its sender can tell its own, and
  // says who sent it and from which session (as the command said: its origin, made printable).
  const bool is_command = decoded.kind == DatagramKind::kCommand;
  const CommandFields& c = decoded.fields;
  const std::string origin = is_command ? printable_origin(c.origin) : std::string();
  const std::int64_t session = is_command ? c.session : 0;
  publish_text_event(v.accepted ? controller::event_kind::kCommandAccepted : controller::event_kind::kCommandRejected,
                     v.accepted ? "accepted: " + v.text : "rejected (" + std::string(reason) + "): " + v.text,
                     is_command ? c.seq : 0, origin, session);
  if (command_log_) {
    controller::CommandRecord r;
    r.accepted = v.accepted;
    if (!v.accepted) r.reason = reason;
    r.decoded = is_command;
    r.kind = wire_kind_name(c.kind);
    r.seq = c.seq;
    r.value = c.value;
    r.origin = origin;
    r.session = session;
    r.text = v.text;
    command_log_->record_command(r);
  }
}

}  // namespace pneu::telemetry
