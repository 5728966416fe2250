#include "pneu/hal/modbus_backend.hpp"

#include <modbus.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "pneu/config/describe.hpp"
#include "pneu/hal/monotonic.hpp"

namespace pneu::hal {

namespace {

modbus_t* as_ctx(void* p) { return static_cast<modbus_t*>(p); }

}  // namespace

ModbusBackend::ModbusBackend(const ModbusConfig& modbus, const model::SensorParams& calibration)
    : cfg_(modbus),
      position_(calibration.position),
      pressure_p_(calibration.pressure_p),
      pressure_n_(calibration.pressure_n) {
  const int r0 = std::min({cfg_.position.address, cfg_.pressure_p.address, cfg_.pressure_n.address});
  const int r1 = std::max({cfg_.position.last_address(), cfg_.pressure_p.last_address(), cfg_.pressure_n.last_address()});
  read_start_ = r0;
  read_count_ = r1 - r0 + 1;
  write_start_ = std::min(cfg_.valve_p.address, cfg_.valve_n.address);
  write_count_ = std::abs(cfg_.valve_p.address - cfg_.valve_n.address) + 1;
  at_p_ = cfg_.valve_p.address == write_start_ ? 0 : 1;
  if (read_count_ > MODBUS_MAX_WR_READ_REGISTERS)
    throw std::runtime_error("hal.modbus.channels: the sensor registers span " + std::to_string(read_count_) +
                             " registers, more than one read transaction carries");
  // The module's watchdog must outlast one lost reply and its retry on a new connection, or a
  // single lost frame sets the outputs to the module's safe values while pneud drives on.
  const double one_loss_s = 2.0 * cfg_.response_timeout_s + cfg_.min_exchange_period_s;
  if (cfg_.module_watchdog_s != 0.0 && !(cfg_.module_watchdog_s > one_loss_s)) {
    char text[240];
    std::snprintf(text, sizeof text,
                  "must be 0 (none) or exceed a lost reply and its retry, 2 x response_timeout_s + "
                  "min_exchange_period_s = %g s (got %g): one lost reply would trip the module's watchdog",
                  one_loss_s, cfg_.module_watchdog_s);
    throw config::ConfigError("hal.modbus.module_watchdog_s", text);
  }
  if (cfg_.read_write_multiple && write_count_ != 2)
    throw std::runtime_error("hal.modbus.channels: function 23 writes one block: valve_p and valve_n must be adjacent registers");
}

ModbusBackend::~ModbusBackend() { close(); }

std::string ModbusBackend::last_error() const {
  const std::lock_guard<std::mutex> lock(error_mutex_);  // the I/O thread's, never the loop's
  return last_error_;
}

std::optional<LinkReport> ModbusBackend::link_report() const {
  LinkReport r;
  r.transactions = counters_.transactions.load();
  r.errors = counters_.errors.load();
  r.reconnects = counters_.reconnects.load();
  r.out_of_range = counters_.out_of_range.load();
  r.stale_reads = counters_.stale_reads.load();
  r.oldest_sample_s = counters_.max_age_s.load();
  r.last_error = last_error();
  r.safe_output_attempts = safe_output_.attempts;
  r.safe_output_max_attempts = kSafeOutputAttempts;
  r.safe_output_delivered = safe_output_.delivered;
  if (safe_output_.read_back) {
    r.safe_output_read_back_u_p_v = safe_output_.read_back_u_p_v;
    r.safe_output_read_back_u_n_v = safe_output_.read_back_u_n_v;
  }
  return r;
}

void ModbusBackend::set_error(const std::string& why) {
  const std::lock_guard<std::mutex> lock(error_mutex_);
  last_error_ = why;
}

bool ModbusBackend::connect_once(std::string* why) noexcept {
  disconnect();
  modbus_t* ctx = cfg_.transport == ModbusTransport::kTcp
                      ? modbus_new_tcp(cfg_.host.c_str(), cfg_.port)
                      : modbus_new_rtu(cfg_.device.c_str(), cfg_.baud, cfg_.parity, cfg_.data_bits, cfg_.stop_bits);
  if (!ctx) {
    *why = std::string("cannot create the libmodbus context: ") + modbus_strerror(errno);
    return false;
  }
  modbus_set_slave(ctx, cfg_.unit_id);
  const double to = cfg_.response_timeout_s;
  // The response timeout bounds the whole reply: libmodbus' byte timeout (500 ms by default)
  // would otherwise let a garbled reply stall the I/O thread far longer.
  if (modbus_set_response_timeout(ctx, static_cast<uint32_t>(to), static_cast<uint32_t>((to - std::floor(to)) * 1e6)) == -1 ||
      modbus_set_byte_timeout(ctx, 0, 0) == -1) {
    *why = std::string("cannot set the timeouts: ") + modbus_strerror(errno);
    modbus_free(ctx);
    return false;
  }
  if (modbus_connect(ctx) == -1) {
    *why = std::string("cannot connect: ") + modbus_strerror(errno);
    modbus_free(ctx);
    return false;
  }
  // RTU frames carry no transaction id: a reply that arrived after its request timed out would be
  // taken for the reply to the next request. Whatever the line holds now belongs to no request of
  // this connection. (TCP: a new connection carries nothing of the old one.)
  if (cfg_.transport == ModbusTransport::kRtu) (void)modbus_flush(ctx);
  ctx_ = ctx;
  return true;
}

void ModbusBackend::disconnect() noexcept {
  if (ctx_) {
    modbus_close(as_ctx(ctx_));
    modbus_free(as_ctx(ctx_));
    ctx_ = nullptr;
  }
}

void ModbusBackend::output_words(std::uint16_t out[2]) const noexcept {
  // The analog outputs carry the commanded voltages whatever the valve power: in fault and
  // disarmed the loop commands its safe voltages, and they must reach the module (the power-enable
  // line, where there is one, is the GPIO decorator's).
  out[at_p_] = cfg_.valve_p.to_word(io_command_.u_p_v);
  out[1 - at_p_] = cfg_.valve_n.to_word(io_command_.u_n_v);
}

bool ModbusBackend::read_back_outputs(std::string* why) noexcept {
  std::uint16_t want[2] = {}, got[2] = {};
  output_words(want);
  const int at_p = at_p_;
  modbus_t* ctx = as_ctx(ctx_);
  // Function 3 on the valve registers: adjacent, one transaction; else one each.
  const bool read = write_count_ == 2 ? modbus_read_registers(ctx, write_start_, 2, got) == 2
                                      : modbus_read_registers(ctx, cfg_.valve_p.address, 1, &got[at_p]) == 1 &&
                                            modbus_read_registers(ctx, cfg_.valve_n.address, 1, &got[1 - at_p]) == 1;
  if (!read) {
    *why = std::string("reading the valve registers back: ") + modbus_strerror(errno);
    counters_.last_errno.store(errno, std::memory_order_relaxed);
    return false;
  }
  safe_output_.read_back = true;
  safe_output_.read_back_u_p_v = cfg_.valve_p.to_volts(got[at_p]);
  safe_output_.read_back_u_n_v = cfg_.valve_n.to_volts(got[1 - at_p]);
  if (got[0] == want[0] && got[1] == want[1]) return true;
  char text[200];
  std::snprintf(text, sizeof text,
                "the valve registers read back u_P = %+.4f V, u_N = %+.4f V, not the safe output's %+.4f V, %+.4f V",
                safe_output_.read_back_u_p_v, safe_output_.read_back_u_n_v, cfg_.valve_p.to_volts(want[at_p]),
                cfg_.valve_n.to_volts(want[1 - at_p]));
  *why = text;
  return false;
}

bool ModbusBackend::exchange(std::string* why) noexcept {
  uint16_t out[2] = {};
  output_words(out);
  const int at_p = at_p_, at_n = 1 - at_p_;
  uint16_t in[MODBUS_MAX_WR_READ_REGISTERS] = {};
  modbus_t* ctx = as_ctx(ctx_);
  int rc = 0;
  // The sample is dated by its reply, but the module read the registers earlier, at an instant
  // no one on this side sees: after the request went out, before the reply was taken. A thread
  // stalled between the reply's arrival and its date (a loaded machine) dates it late by the
  // stall; the sample keeps both ends, so that the supervisor judges a jump over the longest
  // time the carriage may have moved between two readings, not the shortest.
  // On a link that reads, then writes by other requests, the reply to the read dates the sample,
  // not the end of the writes (a few milliseconds later on RTU).
  const double request_mono_s = monotonic_s();
  double reply_mono_s = 0.0;
  if (cfg_.read_write_multiple) {
    rc = modbus_write_and_read_registers(ctx, write_start_, write_count_, out, read_start_, read_count_, in);
    reply_mono_s = monotonic_s();
  } else {
    rc = cfg_.sensor_table == SensorTable::kInput ? modbus_read_input_registers(ctx, read_start_, read_count_, in)
                                                          : modbus_read_registers(ctx, read_start_, read_count_, in);
    reply_mono_s = monotonic_s();
    if (rc == read_count_) {
      const int w = write_count_ == 2 ? modbus_write_registers(ctx, write_start_, 2, out)
                                      : (modbus_write_register(ctx, cfg_.valve_p.address, out[at_p]) == 1 &&
                                                 modbus_write_register(ctx, cfg_.valve_n.address, out[at_n]) == 1
                                             ? 2
                                             : -1);
      if (w != write_count_ && w != 2) rc = -1;
    }
  }
  if (rc != read_count_) {
    *why = rc < 0 ? std::string(modbus_strerror(errno)) : "short reply (" + std::to_string(rc) + " registers)";
    counters_.last_errno.store(errno, std::memory_order_relaxed);
    return false;
  }
  Sample s;
  s.request_mono_s = request_mono_s;
  s.mono_s = reply_mono_s;
  // A channel's words (two for a float32: high word first). A NaN or infinite float32 reaches the
  // frame as a non-finite value, flagged invalid like any reading outside the raw range.
  const auto words = [&](const RegisterChannel& c) { return &in[c.address - read_start_]; };
  const auto take = [&](const RegisterChannel& c, const model::SensorChannelParams& cal, double& value,
                        std::uint32_t invalid_flag) {
    const uint16_t* w = words(c);
    value = cal.to_si(c.to_volts(w));
    if (!c.in_range(w)) s.validity |= invalid_flag;
  };
  take(cfg_.position, position_, s.y_m, kPositionInvalid);
  take(cfg_.pressure_p, pressure_p_, s.p_p_pa, kPressurePInvalid);
  take(cfg_.pressure_n, pressure_n_, s.p_n_pa, kPressureNInvalid);
  if (s.validity) counters_.out_of_range.fetch_add(1, std::memory_order_relaxed);
  sample_.store(s);
  return true;
}

void ModbusBackend::open(double) {
  std::string why;
  const std::string where = cfg_.transport == ModbusTransport::kTcp
                                ? cfg_.host + ":" + std::to_string(cfg_.port)
                                : cfg_.device + " at " + std::to_string(cfg_.baud) + " baud";
  if (!connect_once(&why)) throw std::runtime_error("modbus " + where + ": " + why);
  if (!exchange(&why)) {
    disconnect();
    throw std::runtime_error("modbus " + where + ", unit " + std::to_string(cfg_.unit_id) +
                             ": the first exchange failed: " + why);
  }
  link_up_.store(true);
  running_.store(true);
  thread_ = std::thread([this] { io_thread(); });
}

void ModbusBackend::close() noexcept {
  const bool was_running = running_.exchange(false);
  if (was_running && thread_.joinable()) thread_.join();
  // The caller wrote its safe state just before closing: deliver it, so that the module holds it
  // after we are gone. A request or reply can be lost (a CRC error on the line, a module busy past
  // the response timeout), and the link may be down at this moment: each failed attempt is made
  // again on a fresh connection, as the I/O thread does (libmodbus issue #255), up to
  // kSafeOutputAttempts, each bounded by the response timeout (twice: the write, the read back).
  // A reply is no proof: over RTU a late reply to an earlier request looks like the write's, and
  // a module may answer a write it never applies. Delivered means the valve registers, read back
  // after the write, hold the safe output's words.
  if (was_running) {
    (void)command_.load(io_command_);
    safe_output_ = SafeOutputDelivery{};
    SafeOutputDelivery& d = safe_output_;
    std::string why;
    while (!d.delivered && d.attempts < kSafeOutputAttempts) {
      ++d.attempts;
      if ((!ctx_ || !link_up_.load()) && !connect_once(&why)) {
        link_up_.store(false);
        continue;
      }
      link_up_.store(true);
      d.delivered = exchange(&why) && read_back_outputs(&why);
      if (!d.delivered) {
        counters_.errors.fetch_add(1, std::memory_order_relaxed);
        disconnect();
        link_up_.store(false);
      }
    }
    if (!d.delivered) set_error(why);
  }
  disconnect();
  link_up_.store(false);
}

void ModbusBackend::io_thread() noexcept {
  double backoff = cfg_.reconnect_min_s;
  double next = monotonic_s();
  std::string why;
  // Waits out the back-off in short slices, so that close() never waits for a long one, and
  // doubles it for the next failure.
  const auto back_off = [&] {
    const double until = monotonic_s() + backoff;
    while (running_.load(std::memory_order_relaxed) && monotonic_s() < until)
      sleep_until_monotonic_s(std::min(until, monotonic_s() + 0.01));
    backoff = std::min(2.0 * backoff, cfg_.reconnect_max_s);
  };
  int failures_in_a_row = 0;
  while (running_.load(std::memory_order_relaxed)) {
    if (!link_up_.load(std::memory_order_relaxed)) {
      // One failure is retried at once (a single lost reply need not cost a comms fault); from
      // the second in a row on, back off, after failed exchanges too: a frozen module still
      // completes TCP handshakes from its kernel's backlog, and reconnecting at once would only
      // pile connections up in it.
      if (failures_in_a_row >= 2) back_off();
      if (!running_.load(std::memory_order_relaxed)) break;
      counters_.reconnects.fetch_add(1, std::memory_order_relaxed);
      if (connect_once(&why)) {
        link_up_.store(true, std::memory_order_relaxed);
      } else {
        set_error(why);
        ++failures_in_a_row;
        continue;
      }
    }
    (void)command_.load(io_command_);
    if (exchange(&why)) {
      counters_.transactions.fetch_add(1, std::memory_order_relaxed);
      backoff = cfg_.reconnect_min_s;
      failures_in_a_row = 0;
    } else {
      // After a timeout or bad data libmodbus 3.1.6 may pair the next request with this late
      // reply (issue #255): close and reconnect rather than carry on desynchronised.
      counters_.errors.fetch_add(1, std::memory_order_relaxed);
      set_error(why);
      disconnect();
      link_up_.store(false, std::memory_order_relaxed);
      ++failures_in_a_row;
      continue;
    }
    next += cfg_.min_exchange_period_s;
    const double now = monotonic_s();
    if (now < next) sleep_until_monotonic_s(next);
    else next = now;
  }
}

Status ModbusBackend::read(double t_s, SensorFrame& frame) noexcept {
  Sample s;
  bool fresh = false;
  if (!sample_.load(s, &fresh)) {
    frame = SensorFrame{t_s, 0.0, 0.0, 0.0, 0.0, false, false, kSampleStale | kCommsError, 0.0};
    return Status::kCommsError;
  }
  const double age = monotonic_s() - s.mono_s;
  frame = SensorFrame{t_s - age, s.y_m, s.p_p_pa, s.p_n_pa, age, false, fresh, s.validity, s.mono_s - s.request_mono_s};
  if (age > counters_.max_age_s.load(std::memory_order_relaxed)) counters_.max_age_s.store(age, std::memory_order_relaxed);
  const bool up = link_up_.load(std::memory_order_relaxed);
  if (!up) frame.validity |= kCommsError;
  if (age > cfg_.max_sample_age_s) {
    counters_.stale_reads.fetch_add(1, std::memory_order_relaxed);
    frame.validity |= kSampleStale;
    return up ? Status::kStale : Status::kCommsError;
  }
  return up ? Status::kOk : Status::kCommsError;
}

Status ModbusBackend::write(const ActuatorCommand& command) noexcept {
  command_.store(command);
  return Status::kOk;
}

}  // namespace pneu::hal
