#include "pneu/telemetry/lcm_bridge.hpp"

#include <cmath>
#include <limits>

#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/event_t.hpp"
#include "pneu_lcm/health_t.hpp"
#include "pneu_lcm/prediction_t.hpp"
#include "pneu_lcm/state_t.hpp"

namespace pneu::telemetry {

using controller::LoopEvent;

namespace {
std::int64_t unix_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}
}  // namespace

LcmBridge::LcmBridge(const config::Config& config, controller::LoopOutputs& loop, bool accept_commands)
    : lcm_(std::make_unique<lcm::LCM>(config.telemetry.lcm_url)),
      prefix_(config.telemetry.channel_prefix),
      loop_(loop),
      validator_(config),
      epoch_utime_(unix_now_us()),
      started_(std::chrono::steady_clock::now()) {
  if (!lcm_->good())
    throw LcmError("LCM could not start on '" + config.telemetry.lcm_url +
                   "' (no multicast route? e.g. `ip route add 224.0.0.0/4 dev lo` keeps it on this "
                   "host; or set telemetry.enabled=false)");
  if (accept_commands) lcm_->subscribe(prefix_ + "COMMAND", &LcmBridge::on_command, this);
}

LcmBridge::~LcmBridge() = default;

bool LcmBridge::handle(int timeout_ms) { return lcm_->handleTimeout(timeout_ms) >= 0; }

std::int64_t LcmBridge::utime_of(double t_s) const noexcept {
  return epoch_utime_ + static_cast<std::int64_t>(std::llround(t_s * 1e6));
}

template <typename T>
void LcmBridge::publish(const char* suffix, const T& msg) {
  if (lcm_->publish(prefix_ + suffix, &msg) != 0) ++publish_errors_;
}

void LcmBridge::on_tick(const controller::TickRecord& r) {
  last_t_s_ = r.t_s;
  pneu_lcm::state_t m;
  m.utime = utime_of(r.t_s);
  m.seq = static_cast<std::int64_t>(r.seq);
  m.t = r.t_s;
  m.y_d = r.y_d_m;
  m.y = r.y_m;
  m.v_hat = r.v_hat_m_per_s;
  m.a_hat = r.a_hat_m_per_s2;
  m.p_p = r.p_p_pa;
  m.p_n = r.p_n_pa;
  m.force = r.force_n;
  m.u = r.u_v;
  m.stuck = r.stuck;
  m.mode = static_cast<std::int8_t>(r.mode);
  m.validity = static_cast<std::int32_t>(r.sensor_validity);
  publish("STATE", m);
}

void LcmBridge::on_event(const LoopEvent& e) {
  pneu_lcm::event_t m;
  m.utime = utime_of(e.t_s);
  m.t = e.t_s;
  m.stop = static_cast<std::int64_t>(e.stop_index);
  m.y = e.y_m;
  m.force = e.force_n;
  m.y_d = e.y_d_m;
  m.direction = static_cast<std::int8_t>(e.direction);
  if (e.kind == LoopEvent::Kind::kStop) {
    m.kind = pneu_lcm::event_t::KIND_STOP;
    m.text = "stop";
  } else if (e.kind == LoopEvent::Kind::kFault) {
    m.kind = pneu_lcm::event_t::KIND_FAULT;
    m.text = controller::fault_text(e.fault_cause);
  } else if (e.restart) {
    m.kind = pneu_lcm::event_t::KIND_RESTART;
    m.text = "restart after a stop, set point unchanged";
  } else {
    m.kind = pneu_lcm::event_t::KIND_START;
    m.text = "start";
  }
  publish("EVENT", m);
}

void LcmBridge::on_prediction(const controller::StopOutcome& s, const controller::Prediction& p) {
  pneu_lcm::prediction_t m;
  m.utime = utime_of(s.snapshot.t_s);
  m.t = s.snapshot.t_s;
  m.stop = static_cast<std::int64_t>(s.index);
  m.t_stop = s.t_stop_s;
  m.method = p.method == controller::PredictionMethod::kLinearized ? pneu_lcm::prediction_t::METHOD_LINEARIZED
                                                                    : pneu_lcm::prediction_t::METHOD_NONLINEAR;
  m.will_restart = p.will_restart;
  m.direction = static_cast<std::int8_t>(p.direction);
  m.t_restart = p.t_restart_s;
  m.u_star = s.snapshot.u_v;
  m.equilibrium_force = p.equilibrium_force_n;
  m.p_p_equilibrium = p.p_p_equilibrium_pa;
  m.p_n_equilibrium = p.p_n_equilibrium_pa;
  m.tau_p = p.tau_p_s;
  m.tau_n = p.tau_n_s;
  m.min_margin = p.min_margin_n;
  m.horizon_reached = p.horizon_reached;
  publish("PREDICTION", m);
}

void LcmBridge::on_health(const controller::HealthRecord& h) {
  const CommandCounters& c = validator_.counters();
  pneu_lcm::health_t m;
  m.utime = utime_of(h.t_s);
  m.t = h.t_s;
  m.mode = static_cast<std::int8_t>(h.mode);
  m.ticks = static_cast<std::int64_t>(h.ticks);
  m.overruns = static_cast<std::int64_t>(h.overruns);
  for (int i = 0; i < 4; ++i) {
    m.wake_latency_us[i] = h.wake_latency_s[i] * 1e6;
    m.compute_us[i] = h.compute_s[i] * 1e6;
  }
  m.comms_errors = static_cast<std::int64_t>(h.comms_errors);
  m.telemetry_dropped = static_cast<std::int64_t>(h.ticks_dropped + h.events_dropped + publish_errors_);
  m.commands_received = static_cast<std::int64_t>(c.received);
  m.commands_accepted = static_cast<std::int64_t>(c.accepted);
  m.commands_rejected = static_cast<std::int64_t>(c.rejected);
  m.rejected_malformed = static_cast<std::int64_t>(c.malformed);
  m.rejected_invalid = static_cast<std::int64_t>(c.invalid);
  m.rejected_rate = static_cast<std::int64_t>(c.rate);
  m.rejected_mode = static_cast<std::int64_t>(c.mode);
  m.rejected_sequence = static_cast<std::int64_t>(c.sequence);
  publish("HEALTH", m);
}

void LcmBridge::on_end(double t_end_s) {
  last_t_s_ = t_end_s;
  publish_text_event(pneu_lcm::event_t::KIND_END, "end of run");
}

void LcmBridge::publish_text_event(std::int8_t kind, const std::string& text) {
  pneu_lcm::event_t m;
  m.utime = unix_now_us();
  m.kind = kind;
  m.t = last_t_s_;
  m.stop = 0;
  m.y = m.force = m.y_d = std::numeric_limits<double>::quiet_NaN();
  m.direction = 0;
  m.text = text;
  publish("EVENT", m);
}

// Decoding happens here, on the service thread, inside a guard: command_t is fixed-size, so a
// hostile packet can at worst fail to decode; nothing it says reaches the loop unvalidated.
void LcmBridge::on_command(const lcm::ReceiveBuffer* buffer, const std::string&) {
  Verdict v;
  try {
    pneu_lcm::command_t c;
    const int used = c.decode(buffer->data, 0, static_cast<int>(buffer->data_size));
    if (used < 0) {
      v = validator_.malformed("not a pneu_lcm.command_t (" + std::to_string(buffer->data_size) + " bytes)");
    } else if (static_cast<std::uint32_t>(used) != buffer->data_size) {
      v = validator_.malformed("trailing bytes after a command_t");
    } else {
      const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count();
      v = validator_.validate({c.utime, c.seq, c.kind, c.value}, now_s,
                              loop_.setpoint_m.load(std::memory_order_relaxed),
                              static_cast<controller::Mode>(loop_.mode.load(std::memory_order_relaxed)));
    }
  } catch (const std::exception& e) {
    v = validator_.malformed(e.what());
  }
  if (v.accepted && !loop_.commands.try_push(v.command)) {
    ++commands_dropped_;
    v.accepted = false;
    v.text = "command queue to the loop is full: " + v.text + " dropped";
  }
  publish_text_event(v.accepted ? pneu_lcm::event_t::KIND_COMMAND_ACCEPTED : pneu_lcm::event_t::KIND_COMMAND_REJECTED,
                     v.accepted ? "accepted: " + v.text : "rejected (" + std::string(to_string(v.rejection)) + "): " + v.text);
}

}  // namespace pneu::telemetry
