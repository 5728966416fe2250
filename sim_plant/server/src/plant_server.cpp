// The plant server: the plant model stepped in real time behind a libmodbus server exposing a
// register map, as the bench's analog I/O module would (hardware in the loop).
#include "pneu/plant_server/plant_server.hpp"

#include <arpa/inet.h>
#include <modbus.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

#include "pneu/config/text.hpp"
#include "pneu/hal/monotonic.hpp"
#include "pneu/sim_plant/plant.hpp"
#include "pneu/sim_plant/sensors.hpp"

namespace pneu::plant_server {

namespace {

using hal::monotonic_s;
using text::format;  // the fields of an events line, as printf would print them

static_assert(std::atomic<bool>::is_always_lock_free, "request_stop() must be safe in a signal handler");

struct ModbusContext {
  modbus_t* ctx = nullptr;
  modbus_mapping_t* map = nullptr;
  ModbusContext() = default;
  ModbusContext(const ModbusContext&) = delete;
  ModbusContext& operator=(const ModbusContext&) = delete;
  ~ModbusContext() {
    if (map) modbus_mapping_free(map);
    if (ctx) {
      modbus_close(ctx);
      modbus_free(ctx);
    }
  }
};

// --- Several TCP clients, one writer of the valves ------------------------------------------------

constexpr int kMbapBytes = 7;  ///< transaction id, protocol id, length, unit id

/// The holding registers a request writes, [first, first + count); count 0 when it writes none.
/// Functions 6, 16, 22 and 23 write registers (the map has no coils). `pdu` points at the function
/// code of a request as modbus_receive returned it (which read the bytes used here).
struct WrittenRegisters {
  int first = 0;
  int count = 0;
  [[nodiscard]] bool include(int address) const { return address >= first && address < first + count; }
};

WrittenRegisters written_registers(const std::uint8_t* pdu) {
  const auto word = [pdu](int at) { return pdu[at] << 8 | pdu[at + 1]; };
  switch (pdu[0]) {
    case MODBUS_FC_WRITE_SINGLE_REGISTER:
    case MODBUS_FC_MASK_WRITE_REGISTER: return {word(1), 1};
    case MODBUS_FC_WRITE_MULTIPLE_REGISTERS: return {word(1), word(3)};
    case MODBUS_FC_WRITE_AND_READ_REGISTERS: return {word(5), word(7)};
    default: return {};
  }
}

/// A client's connection (for RTU: the line), with the request it sent last.
struct Connection {
  int fd = -1;                   ///< -1: a free slot
  std::uint64_t number = 0;      ///< 1, 2, ... in the order they were accepted
  std::string peer;              ///< address:port
  int low_water_bytes = 1;       ///< the socket's SO_RCVLOWAT: the bytes of the frame awaited
  double last_request_s = 0.0;   ///< when its last request for this unit was read, since start-up
  bool told_busy = false;        ///< its first refused valve write was reported on the warnings
  bool reply_pending = false;    ///< reply_delay_s holds the reply back (the socket is not read meanwhile)
  double reply_at_s = 0.0;       ///< when it falls due, since start-up
  int query_length = 0;
  std::array<std::uint8_t, std::max(MODBUS_RTU_MAX_ADU_LENGTH, MODBUS_TCP_MAX_ADU_LENGTH)> query{};
  std::array<std::uint16_t, 6> sensor_words{};  ///< the sensor registers when the held request came
};

/// `text` as a JSON string, quotes included (a device path or a fault spec may hold any byte).
std::string json_string(const std::string& text) {
  std::string out = "\"";
  for (const char ch : text) {
    const auto u = static_cast<unsigned char>(ch);
    if (ch == '"' || ch == '\\') out += '\\', out += ch;
    else if (u < 0x20) {
      char esc[8];
      std::snprintf(esc, sizeof esc, "\\u%04x", u);
      out += esc;
    } else out += ch;
  }
  return out + "\"";
}

enum class Frame { kWhole, kPartial, kClosed, kTooLong };

/// Whether a client's socket holds a whole Modbus TCP request, by the length field of its MBAP
/// header, read without taking it from the socket: modbus_receive then never waits for the rest of
/// a frame (up to its byte timeout, 0.5 s, for a client that sent half of one), which would hold up
/// every other client. While a frame is partial the socket's SO_RCVLOWAT is the frame's size, so
/// that select wakes when it is complete, not for each byte; woken with less, the client has left.
Frame frame_ready(Connection& c) {
  std::uint8_t head[MODBUS_TCP_MAX_ADU_LENGTH];
  const ssize_t n = recv(c.fd, head, sizeof head, MSG_PEEK | MSG_DONTWAIT);
  if (n < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR ? Frame::kPartial : Frame::kClosed;
  if (n == 0 || n < c.low_water_bytes) return Frame::kClosed;
  int need = 6;  // up to the length field
  if (n >= 6) {
    need = 6 + (head[4] << 8 | head[5]);
    if (need > MODBUS_TCP_MAX_ADU_LENGTH) return Frame::kTooLong;
    need = std::max(need, kMbapBytes + 1);
  }
  const int low_water = n >= need ? 1 : need;
  if (low_water != c.low_water_bytes) {
    (void)setsockopt(c.fd, SOL_SOCKET, SO_RCVLOWAT, &low_water, sizeof low_water);
    c.low_water_bytes = low_water;
  }
  return n >= need ? Frame::kWhole : Frame::kPartial;
}

/// The valve outputs the module holds, as the events record writes them: each change with its
/// time, at most one line per kOutputsRecordGapS.
struct OutputsLine {
  double t = 0.0;
  std::uint64_t client = 0;
  const char* cause = "write";
};
constexpr double kOutputsRecordGapS = 0.01;

ServerParams checked(ServerParams p) {
  const auto bad = [](const std::string& why) { return std::invalid_argument("plant server: " + why); };
  if (!(p.max_clients >= 1 && p.max_clients <= kMaxClientsLimit))
    throw bad("max_clients must be from 1 to " + std::to_string(kMaxClientsLimit));
  if (!(p.duration_s >= 0.0)) throw bad("duration_s must be >= 0");
  if (!(p.reply_delay_s >= 0.0 && p.delay_after_s >= 0.0)) throw bad("reply_delay_s and delay_after_s must be >= 0");
  if (!(p.watchdog_s >= 0.0 && std::isfinite(p.watchdog_s))) throw bad("watchdog_s must be >= 0 (0: none)");
  // Faults in the order they become active (ties: the order given).
  std::stable_sort(p.faults.begin(), p.faults.end(), [](const Fault& a, const Fault& b) { return a.t_s < b.t_s; });
  return p;
}

}  // namespace

class PlantServer::Impl {
 public:
  Impl(ServerParams params, Sinks sinks);
  ~Impl();
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void run();
  void request_stop() noexcept { stop_.store(true); }
  [[nodiscard]] Stats stats() const noexcept;
  [[nodiscard]] int port() const noexcept { return port_; }
  [[nodiscard]] double neutral_voltage_v() const noexcept { return u_e_; }

 private:
  // The server's time: seconds since run() started.
  [[nodiscard]] double now_s() const noexcept { return monotonic_s() - t0_; }

  // Set-up.
  void open_transport();

  // The records.
  void record(const char* kind, double t, const std::string& rest);
  void record_plant_events(std::span<const plant::PlantEvent> happened);
  void record_outputs(double t);
  void write_outputs_line(const OutputsLine& o);
  void outputs_changed(const OutputsLine& o);
  void flush_pending_outputs(double now);

  // The plant, its sensors and the faults.
  [[nodiscard]] double measured(int i) const;
  void update_sensor_registers();
  void step_to(double t);
  void advance_to(double t);
  void activate(Fault& f);
  void save_sensor_words(std::array<std::uint16_t, 6>& words) const;
  void restore_sensor_words(const std::array<std::uint16_t, 6>& words);

  // The clients.
  void accept_client();
  void drop(Connection& c, const char* why);
  [[nodiscard]] bool owner_left();
  void serve_request(Connection& c);
  void reply(Connection& c);
  void hold_for_the_line(const Connection& c, int request_bytes) const;
  void trip(double now);
  [[nodiscard]] bool serve_once();
  void finish();

  const ServerParams p_;
  const hal::ModbusConfig& mb_ = p_.modbus;
  const Sinks sinks_;
  const bool tcp_ = p_.modbus.transport == hal::ModbusTransport::kTcp;
  std::atomic<bool> stop_{false};
  bool ran_ = false;

  plant::Plant plant_;
  plant::SensorSuite sensors_;
  double u_e_ = 0.0;
  double u_p_ = 0.0, u_n_ = 0.0;  // what the client wrote (at first: the neutral voltages)
  std::uint16_t watchdog_word_p_ = 0, watchdog_word_n_ = 0;
  std::optional<double> stuck_p_, stuck_n_;  // a stuck spool drives its valve instead

  ModbusContext m_;
  std::uint16_t* sensor_regs_ = nullptr;
  std::uint16_t word_p_ = 0, word_n_ = 0;  // the valve registers as last read back

  // The sensor registers: from the sensor models, or what an active fault makes them read.
  const Fault* sensor_fault_[3] = {nullptr, nullptr, nullptr};  // position, pressure_p, pressure_n
  const hal::RegisterChannel* sensor_channel_[3] = {&mb_.position, &mb_.pressure_p, &mb_.pressure_n};
  // Miswirings and dead sensors (tubes:swapped, pressure_sensors:swapped, CHANNEL:dead).
  bool tubes_swapped_ = false, pressure_sensors_swapped_ = false;
  std::optional<double> dead_value_[3];  // what a dead sensor reads (before its noise)
  std::vector<Fault> faults_;            // the schedule, in time order
  std::size_t next_fault_ = 0;

  // TCP: up to max_clients connections, each its slot; RTU: the line, in slot 0.
  std::vector<Connection> connections_;
  int listen_fd_ = -1;
  int port_ = 0;

  double t0_ = 0.0;       // CLOCK_MONOTONIC at the server's t = 0
  double t_end_s_ = 0.0;  // when run() ended (0: not yet)

  // The events record's outputs lines: a change superseded before its line was due is counted
  // ("skipped") in the next line, and the last change waits at most kOutputsRecordGapS (pending).
  std::optional<OutputsLine> pending_outputs_;
  double last_outputs_line_t_ = -1.0;  // the server's time when the last line was written
  std::uint64_t outputs_skipped_ = 0;

  std::uint64_t requests_ = 0, refused_ = 0, clients_ = 0, foreign_ = 0, busy_ = 0, owner_ = 0, trips_ = 0;
  int connected_ = 0, most_connected_ = 0;
  // The watchdog watches the client that took the valve registers last (the owner, or the owner
  // that left without another taking them): its requests feed it. 0: disarmed.
  std::uint64_t watched_ = 0;
  double watched_last_request_s_ = 0.0;
};

PlantServer::Impl::Impl(ServerParams params, Sinks sinks)
    : p_(checked(std::move(params))), sinks_(sinks), plant_(p_.plant), sensors_(p_.sensors), faults_(p_.faults) {
  u_e_ = model::equilibrium_voltage_v(plant_.valve(), model::ChamberProcess(p_.plant), p_.initial_position_m);
  plant_.reset_at_rest(p_.initial_position_m, u_e_);
  u_p_ = u_e_;
  u_n_ = -u_e_;
  const ValveVoltages watchdog = p_.watchdog_outputs.value_or(ValveVoltages{u_e_, -u_e_});
  watchdog_word_p_ = mb_.valve_p.to_word(watchdog.u_p_v);
  watchdog_word_n_ = mb_.valve_n.to_word(watchdog.u_n_v);

  m_.ctx = tcp_ ? modbus_new_tcp(mb_.host.c_str(), mb_.port)
                : modbus_new_rtu(mb_.device.c_str(), mb_.baud, mb_.parity, mb_.data_bits, mb_.stop_bits);
  if (!m_.ctx) throw std::runtime_error(std::string("cannot create the Modbus server: ") + modbus_strerror(errno));
  modbus_set_slave(m_.ctx, mb_.unit_id);
  const int top = std::max({mb_.position.last_address(), mb_.pressure_p.last_address(), mb_.pressure_n.last_address(),
                            mb_.valve_p.last_address(), mb_.valve_n.last_address()}) + 1;
  m_.map = modbus_mapping_new(0, 0, top, top);
  if (!m_.map) throw std::runtime_error(std::string("cannot allocate the register map: ") + modbus_strerror(errno));
  sensor_regs_ = mb_.sensor_table == hal::SensorTable::kInput ? m_.map->tab_input_registers : m_.map->tab_registers;
  m_.map->tab_registers[mb_.valve_p.address] = mb_.valve_p.to_word(u_p_);
  m_.map->tab_registers[mb_.valve_n.address] = mb_.valve_n.to_word(u_n_);
  word_p_ = m_.map->tab_registers[mb_.valve_p.address];
  word_n_ = m_.map->tab_registers[mb_.valve_n.address];
  update_sensor_registers();  // so that a fault frozen before the first request has a value to keep
  open_transport();
}

PlantServer::Impl::~Impl() {
  // run() closes its connections on return; a server never run (or left by an exception) here.
  for (Connection& c : connections_)
    if (tcp_ && c.fd >= 0) ::close(c.fd);
  if (listen_fd_ >= 0) {
    if (m_.ctx) modbus_set_socket(m_.ctx, -1);  // closed here: not for modbus_close to close again
    ::close(listen_fd_);
  }
}

void PlantServer::Impl::open_transport() {
  connections_.resize(tcp_ ? static_cast<std::size_t>(p_.max_clients) : 1);
  if (tcp_) {
    // A burst of connections waits in the kernel to be accepted (or refused), not retried later.
    listen_fd_ = modbus_tcp_listen(m_.ctx, kMaxClientsLimit);
    if (listen_fd_ < 0)
      throw std::runtime_error("cannot listen on " + mb_.host + ":" + std::to_string(mb_.port) + ": " + modbus_strerror(errno));
    sockaddr_in bound{};
    socklen_t bound_size = sizeof bound;
    port_ = getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &bound_size) == 0 ? ntohs(bound.sin_port) : mb_.port;
    // A request reaches modbus_receive whole (frame_ready): a byte timeout only ends a frame whose
    // function needs more bytes than its MBAP length announced, and 1 ms of it holds no one up.
    // libmodbus answers a request with an illegal count after sleeping its response timeout and
    // flushing (to skip the rest of a garbled RTU frame): 1 us, so that one client's bad request
    // does not stall the others for 0.5 s.
    modbus_set_byte_timeout(m_.ctx, 0, 1000);
    modbus_set_response_timeout(m_.ctx, 0, 1);
  } else {
    if (modbus_connect(m_.ctx) == -1)
      throw std::runtime_error("cannot open " + mb_.device + ": " + modbus_strerror(errno));
    connections_[0].fd = modbus_get_socket(m_.ctx);
    connections_[0].number = 1;
    connections_[0].peer = mb_.device;
    clients_ = 1;
    most_connected_ = 1;
  }
}

// --- The records ----------------------------------------------------------------------------------

// One line of the events record: its kind, its time and the rest of its fields (",\"key\":value...").
void PlantServer::Impl::record(const char* kind, double t, const std::string& rest) {
  if (!sinks_.events) return;
  std::fprintf(sinks_.events, "{\"event\":\"%s\",\"t\":%.9f,\"monotonic_s\":%.9f%s}\n", kind, t, t0_ + t, rest.c_str());
  std::fflush(sinks_.events);
}

// The plant's motion events (its time is the server's: both start at 0).
void PlantServer::Impl::record_plant_events(std::span<const plant::PlantEvent> happened) {
  if (!sinks_.events) return;
  for (const plant::PlantEvent& e : happened) {
    const char* kind = e.kind == plant::PlantEvent::Kind::kBreakaway ? "breakaway"
                       : e.kind == plant::PlantEvent::Kind::kStick   ? "stick"
                       : e.kind == plant::PlantEvent::Kind::kEndStop ? "end_stop"
                                                                      : nullptr;
    if (kind == nullptr) continue;  // a reversal slides on
    std::fprintf(sinks_.events, "{\"event\":\"%s\",\"t\":%.9f,\"monotonic_s\":%.9f,\"direction\":%d,\"y\":%.9f,\"force\":%.6f}\n",
                 kind, e.t_s, t0_ + e.t_s, e.direction, e.y_m, e.force_n);  // the plant's own time
  }
  if (!happened.empty()) std::fflush(sinks_.events);
}

void PlantServer::Impl::record_outputs(double t) {
  if (!sinks_.outputs) return;
  std::fprintf(sinks_.outputs, "%.6f,%.6f,%.6f\n", t, mb_.valve_p.to_volts(word_p_), mb_.valve_n.to_volts(word_n_));
  std::fflush(sinks_.outputs);
}

void PlantServer::Impl::write_outputs_line(const OutputsLine& o) {
  record("outputs", o.t,
         format(",\"u_p\":%.6f,\"u_n\":%.6f,\"client\":%llu,\"cause\":\"%s\",\"skipped\":%llu",
                mb_.valve_p.to_volts(word_p_), mb_.valve_n.to_volts(word_n_), static_cast<unsigned long long>(o.client),
                o.cause, static_cast<unsigned long long>(outputs_skipped_)));
  last_outputs_line_t_ = std::max(o.t, now_s());  // when written: a pending line comes late
  outputs_skipped_ = 0;
  pending_outputs_.reset();
}

// Called once word_p_, word_n_ hold the new outputs. A watchdog's line is written at once.
void PlantServer::Impl::outputs_changed(const OutputsLine& o) {
  if (!sinks_.events) return;
  if (pending_outputs_) ++outputs_skipped_;
  if (o.t - last_outputs_line_t_ >= kOutputsRecordGapS || std::string_view(o.cause) != "write") write_outputs_line(o);
  else pending_outputs_ = o;
}

void PlantServer::Impl::flush_pending_outputs(double now) {
  if (pending_outputs_ && now - last_outputs_line_t_ >= kOutputsRecordGapS) write_outputs_line(*pending_outputs_);
}

// --- The plant, its sensors and the faults ----------------------------------------------------------

// What sensor `i` (position, pressure_p, pressure_n) measures: its quantity, through the wiring.
double PlantServer::Impl::measured(int i) const {
  const auto& s = plant_.state();
  return i == 0 ? s.y_m : (i == 1) != pressure_sensors_swapped_ ? s.p_p_pa : s.p_n_pa;
}

void PlantServer::Impl::update_sensor_registers() {
  double q[3];
  for (int i = 0; i < 3; ++i) q[i] = dead_value_[i].value_or(measured(i));
  const auto v = sensors_.read_volts(q[0], q[1], q[2]);
  const double volts[3] = {v.y_m, v.p_p_pa, v.p_n_pa};
  for (int i = 0; i < 3; ++i) {
    const hal::RegisterChannel& c = *sensor_channel_[i];
    std::uint16_t* w = &sensor_regs_[c.address];
    if (!sensor_fault_[i]) c.to_words(volts[i], w);
    else std::copy_n(sensor_fault_[i]->words.begin(), c.register_count(), w);
  }
}

// The plant to `t` under the valves held since the last write (a stuck spool drives its valve
// instead; swapped tubes feed each chamber from the other valve), each push from its start to its
// end.
void PlantServer::Impl::step_to(double t) {
  const double drive_p = stuck_p_.value_or(u_p_), drive_n = stuck_n_.value_or(u_n_);
  plant::step_with_pushes(plant_, t, tubes_swapped_ ? drive_n : drive_p, tubes_swapped_ ? drive_p : drive_n, p_.pushes,
                          [this](std::span<const plant::PlantEvent> happened) { record_plant_events(happened); });
}

// Real time: the plant catches up with the wall clock; each fault takes effect at its own time
// inside the catch-up.
void PlantServer::Impl::advance_to(double t) {
  for (; next_fault_ < faults_.size() && faults_[next_fault_].t_s <= t; ++next_fault_) {
    Fault& f = faults_[next_fault_];
    if (f.t_s > plant_.state().t_s) step_to(f.t_s);
    activate(f);
  }
  step_to(t);
}

void PlantServer::Impl::activate(Fault& f) {
  switch (f.channel) {
    case FaultChannel::kValveP: stuck_p_ = f.stuck_v; break;
    case FaultChannel::kValveN: stuck_n_ = f.stuck_v; break;
    case FaultChannel::kTubes: tubes_swapped_ = true; break;
    case FaultChannel::kPressureSensors: pressure_sensors_swapped_ = true; break;
    default: {
      const int i = static_cast<int>(f.channel);
      dead_value_[i].reset();
      if (f.mode == FaultMode::kDead) {
        dead_value_[i] = measured(i);
        sensor_fault_[i] = nullptr;
        break;
      }
      if (f.mode == FaultMode::kFreeze)
        std::copy_n(&sensor_regs_[sensor_channel_[i]->address], sensor_channel_[i]->register_count(), f.words.begin());
      sensor_fault_[i] = &f;
    }
  }
  std::fprintf(sinks_.messages, "pneu-plant serve: fault %s active at t = %.6f s\n", f.spec.c_str(), now_s());
  std::fflush(sinks_.messages);
  record("fault", f.t_s, ",\"spec\":" + json_string(f.spec));
}

// A held reply answers with the readings of its request's time, as a module that answers late.
void PlantServer::Impl::save_sensor_words(std::array<std::uint16_t, 6>& words) const {
  std::uint16_t* w = words.data();
  for (const hal::RegisterChannel* c : sensor_channel_) {
    std::copy_n(&sensor_regs_[c->address], c->register_count(), w);
    w += c->register_count();
  }
}

void PlantServer::Impl::restore_sensor_words(const std::array<std::uint16_t, 6>& words) {
  const std::uint16_t* w = words.data();
  for (const hal::RegisterChannel* c : sensor_channel_) {
    std::copy_n(w, c->register_count(), &sensor_regs_[c->address]);
    w += c->register_count();
  }
}

// --- The clients ----------------------------------------------------------------------------------

void PlantServer::Impl::accept_client() {
  sockaddr_in from{};
  socklen_t from_size = sizeof from;
  const int fd = accept4(listen_fd_, reinterpret_cast<sockaddr*>(&from), &from_size, SOCK_NONBLOCK | SOCK_CLOEXEC);
  if (fd < 0) return;
  char address[INET_ADDRSTRLEN] = "?";
  inet_ntop(AF_INET, &from.sin_addr, address, sizeof address);
  const std::string peer = std::string(address) + ":" + std::to_string(ntohs(from.sin_port));
  const auto slot = std::find_if(connections_.begin(), connections_.end(), [](const Connection& c) { return c.fd < 0; });
  if (slot == connections_.end()) {
    ::close(fd);
    ++refused_;
    record("refused", now_s(), ",\"peer\":" + json_string(peer));
    std::fprintf(sinks_.warnings, "pneu-plant serve: refused a client from %s: already serving %d (--max-clients %d)\n",
                 peer.c_str(), p_.max_clients, p_.max_clients);
    return;
  }
  slot->fd = fd;
  slot->number = ++clients_;
  slot->peer = peer;
  record("connect", now_s(),
         format(",\"client\":%llu", static_cast<unsigned long long>(slot->number)) + ",\"peer\":" + json_string(peer));
  most_connected_ = std::max(most_connected_, ++connected_);
}

// Closes `c`'s connection; `why`: the reason it is dropped, on the warnings (nullptr: it left).
void PlantServer::Impl::drop(Connection& c, const char* why) {
  if (why) std::fprintf(sinks_.warnings, "pneu-plant serve: client %llu (%s) %s: closed\n",
                        static_cast<unsigned long long>(c.number), c.peer.c_str(), why);
  ::close(c.fd);
  const double t = now_s();
  record("disconnect", t, format(",\"client\":%llu", static_cast<unsigned long long>(c.number)) +
                              ",\"why\":" + json_string(why ? why : "left"));
  if (c.number == owner_) {
    owner_ = 0;
    std::fprintf(sinks_.messages, "pneu-plant serve: client %llu left: the valve registers are free\n",
                 static_cast<unsigned long long>(c.number));
    std::fflush(sinks_.messages);
    record("released", t, format(",\"client\":%llu,\"cause\":\"disconnect\"", static_cast<unsigned long long>(c.number)));
  }
  c = Connection{};
  --connected_;
}

// Whether the owner of the valve registers has disconnected (then dropped), asked when another
// client writes them: its end of the connection may not have been read yet.
bool PlantServer::Impl::owner_left() {
  for (Connection& c : connections_) {
    if (c.fd < 0 || c.number != owner_) continue;
    std::uint8_t byte = 0;
    const ssize_t n = recv(c.fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
    if (n > 0 || (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR))) return false;
    drop(c, nullptr);
    return true;
  }
  return true;
}

// A request from `c`: answered now, or held back by reply_delay_s.
void PlantServer::Impl::serve_request(Connection& c) {
  modbus_set_socket(m_.ctx, c.fd);
  const int rc = modbus_receive(m_.ctx, c.query.data());
  if (rc == -1) {
    if (tcp_) drop(c, (std::string("sent a request libmodbus cannot read (") + modbus_strerror(errno) + ")").c_str());
    return;
  }
  const int unit_at = modbus_get_header_length(m_.ctx) - 1;
  if (rc == 0) return;  // RTU: another unit's request, filtered by libmodbus
  if (c.query[unit_at] != mb_.unit_id && c.query[unit_at] != 0) {
    ++foreign_;  // another unit's request: a real module stays silent, the client times out
    return;
  }
  ++requests_;
  c.query_length = rc;
  const double t = now_s();
  c.last_request_s = t;
  if (c.number == watched_) watched_last_request_s_ = t;
  advance_to(t);
  update_sensor_registers();
  if (!tcp_) hold_for_the_line(c, rc);
  if (p_.reply_delay_s > 0.0 && t >= p_.delay_after_s) {  // fault injection: a module that answers late
    save_sensor_words(c.sensor_words);
    c.reply_pending = true;
    c.reply_at_s = now_s() + p_.reply_delay_s;  // written when it falls due, even if the client left
  } else {
    reply(c);
  }
}

// RTU: a pty carries bytes at any speed: hold the reply for the time the request and the reply
// take on a real line at this baud rate (10 bits a byte, 3.5-character silences), so the client
// meets the timing of the bench's serial link.
void PlantServer::Impl::hold_for_the_line(const Connection& c, int request_bytes) const {
  const int unit_at = modbus_get_header_length(m_.ctx) - 1;
  const int fc = c.query[unit_at + 1];
  const int n_read = fc == 3 || fc == 4 ? (c.query[unit_at + 4] << 8 | c.query[unit_at + 5])
                     : fc == 23         ? (c.query[unit_at + 4] << 8 | c.query[unit_at + 5])
                                        : 0;
  const int reply_bytes = n_read > 0 ? 5 + 2 * n_read : 8;
  const double wire_s = (request_bytes + reply_bytes + 7) * 10.0 / mb_.baud;
  hal::sleep_until_monotonic_s(monotonic_s() + wire_s);
}

// Answers `c`'s request; a write to the valve registers by another than their owner is refused
// with exception 06.
void PlantServer::Impl::reply(Connection& c) {
  if (c.reply_pending) restore_sensor_words(c.sensor_words);
  c.reply_pending = false;
  modbus_set_socket(m_.ctx, c.fd);
  const WrittenRegisters written = written_registers(c.query.data() + modbus_get_header_length(m_.ctx));
  if (written.include(mb_.valve_p.address) || written.include(mb_.valve_n.address)) {
    if (owner_ != 0 && owner_ != c.number && !owner_left()) {
      ++busy_;
      if (!c.told_busy)
        std::fprintf(sinks_.warnings,
                     "pneu-plant serve: client %llu (%s) may not write the valve registers: client %llu "
                     "owns them until it disconnects (exception 06, server device busy; told once)\n",
                     static_cast<unsigned long long>(c.number), c.peer.c_str(), static_cast<unsigned long long>(owner_));
      c.told_busy = true;
      if (modbus_reply_exception(m_.ctx, c.query.data(), MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY) == -1 && tcp_)
        drop(c, "does not take its replies");
      return;
    }
    if (owner_ == 0) {
      owner_ = c.number;
      watched_ = c.number;
      watched_last_request_s_ = c.last_request_s;
      std::fprintf(sinks_.messages,
                   "pneu-plant serve: client %llu (%s) writes the valve registers: they are its until it disconnects%s\n",
                   static_cast<unsigned long long>(c.number), c.peer.c_str(),
                   p_.watchdog_s > 0.0 ? " or falls silent past the watchdog" : "");
      std::fflush(sinks_.messages);
      record("owner", now_s(), format(",\"client\":%llu", static_cast<unsigned long long>(c.number)));
    }
  }
  // A client that stops taking its replies fills its socket: the send fails at once (the socket
  // does not block) and the client is dropped, never waited for.
  const int sent = modbus_reply(m_.ctx, c.query.data(), c.query_length, m_.map);
  const std::uint16_t wp = m_.map->tab_registers[mb_.valve_p.address];
  const std::uint16_t wn = m_.map->tab_registers[mb_.valve_n.address];
  if (wp != word_p_ || wn != word_n_) {  // each valve drives its own chamber (not Eq. 1's u_N = -u_P)
    word_p_ = wp;
    word_n_ = wn;
    u_p_ = mb_.valve_p.to_volts(wp);
    u_n_ = mb_.valve_n.to_volts(wn);
    const double t = now_s();
    record_outputs(t);
    outputs_changed({t, c.number, "write"});
  }
  if (sent == -1 && tcp_) drop(c, "does not take its replies");
}

// The watchdog's trip at the server's time `now`: the plant runs to it under the outputs held,
// then under the watchdog's; the owner loses the valve registers.
void PlantServer::Impl::trip(double now) {
  advance_to(now);
  ++trips_;
  const std::uint64_t client = watched_;
  watched_ = 0;
  if (sinks_.events && pending_outputs_) write_outputs_line(*pending_outputs_);
  m_.map->tab_registers[mb_.valve_p.address] = word_p_ = watchdog_word_p_;
  m_.map->tab_registers[mb_.valve_n.address] = word_n_ = watchdog_word_n_;
  u_p_ = mb_.valve_p.to_volts(word_p_);
  u_n_ = mb_.valve_n.to_volts(word_n_);
  record_outputs(now);
  record("watchdog", now,
         format(",\"client\":%llu,\"last_request_t\":%.9f,\"last_request_monotonic_s\":%.9f,\"u_p\":%.6f,\"u_n\":%.6f",
                static_cast<unsigned long long>(client), watched_last_request_s_, t0_ + watched_last_request_s_, u_p_, u_n_));
  outputs_changed({now, client, "watchdog"});
  std::fprintf(sinks_.messages,
               "pneu-plant serve: watchdog: no request from client %llu for %.3f s: valve outputs u_P = %+.4f V, "
               "u_N = %+.4f V%s\n",
               static_cast<unsigned long long>(client), now - watched_last_request_s_, u_p_, u_n_,
               owner_ == client ? "; the valve registers are free" : "");
  std::fflush(sinks_.messages);
  if (owner_ == client) {
    owner_ = 0;
    record("released", now, format(",\"client\":%llu,\"cause\":\"watchdog\"", static_cast<unsigned long long>(client)));
  }
}

// --- Serving ------------------------------------------------------------------------------------

void PlantServer::Impl::run() {
  if (ran_) throw std::logic_error("PlantServer::run: once only");
  ran_ = true;
  t0_ = monotonic_s();
  if (sinks_.events) {
    std::string what = format(",\"watchdog_s\":%.6f,\"watchdog_u_p\":%.6f,\"watchdog_u_n\":%.6f", p_.watchdog_s,
                              mb_.valve_p.to_volts(watchdog_word_p_), mb_.valve_n.to_volts(watchdog_word_n_));
    if (p_.watchdog_s == 0.0) what = ",\"watchdog_s\":0";
    record("start", 0.0,
           what + format(",\"u_p\":%.6f,\"u_n\":%.6f", mb_.valve_p.to_volts(word_p_), mb_.valve_n.to_volts(word_n_)));
  }
  if (sinks_.outputs) {
    std::fputs("t_s,u_p_v,u_n_v\n", sinks_.outputs);
    record_outputs(0.0);
  }
  if (!tcp_) record("connect", 0.0, ",\"client\":1,\"peer\":" + json_string(mb_.device));
  while (!stop_.load() && serve_once()) {
  }
  finish();
}

// One round: the plant to now, the held replies due, then the requests that arrived (select waits
// up to 0.5 ms), the newcomers, the watchdog. False once the duration is over.
bool PlantServer::Impl::serve_once() {
  double now = now_s();
  if (p_.duration_s > 0.0 && now >= p_.duration_s) return false;
  advance_to(now);
  // Held replies as they fall due, the earliest first.
  for (;;) {
    Connection* due = nullptr;
    for (Connection& c : connections_)
      if (c.reply_pending && c.reply_at_s <= now && (!due || c.reply_at_s < due->reply_at_s)) due = &c;
    if (!due) break;
    reply(*due);
    now = now_s();
  }

  fd_set fds;
  FD_ZERO(&fds);
  int max_fd = -1;
  double wait_s = 0.0005;  // the plant advances, and the watchdog looks, at least every 0.5 ms while idle
  if (listen_fd_ >= 0) FD_SET(listen_fd_, &fds), max_fd = std::max(max_fd, listen_fd_);
  for (const Connection& c : connections_) {
    if (c.fd < 0) continue;
    if (c.reply_pending) wait_s = std::min(wait_s, std::max(0.0, c.reply_at_s - now));
    else FD_SET(c.fd, &fds), max_fd = std::max(max_fd, c.fd);
  }
  timeval tv{0, static_cast<suseconds_t>(wait_s * 1e6)};
  const int ready = select(max_fd + 1, &fds, nullptr, nullptr, &tv);
  if (ready < 0) {
    if (errno == EINTR) return true;
    throw std::runtime_error(std::string("select: ") + std::strerror(errno));
  }
  // The clients before a newcomer, the owner of the valve registers first: a departed owner is
  // noticed before another client's write is judged.
  const auto first = std::find_if(connections_.begin(), connections_.end(),
                                  [&](const Connection& c) { return c.fd >= 0 && c.number == owner_; });
  const std::size_t start = first == connections_.end() ? 0 : static_cast<std::size_t>(first - connections_.begin());
  for (std::size_t k = 0; k < connections_.size(); ++k) {
    Connection& c = connections_[(start + k) % connections_.size()];
    if (c.fd < 0 || c.reply_pending || !FD_ISSET(c.fd, &fds)) continue;
    if (!tcp_) {
      serve_request(c);
      continue;
    }
    switch (frame_ready(c)) {
      case Frame::kWhole: serve_request(c); break;
      case Frame::kPartial: break;
      case Frame::kClosed: drop(c, nullptr); break;
      case Frame::kTooLong: drop(c, "sent a frame longer than Modbus TCP's 260 bytes"); break;
    }
  }
  if (listen_fd_ >= 0 && FD_ISSET(listen_fd_, &fds)) accept_client();
  // After the requests that were waiting: a stall of the server's own is no silence of the client's.
  now = now_s();
  if (p_.watchdog_s > 0.0 && watched_ != 0 && now - watched_last_request_s_ >= p_.watchdog_s) trip(now);
  flush_pending_outputs(now);
  return true;
}

// The last outputs line, the stop record and the summary; the connections closed.
void PlantServer::Impl::finish() {
  if (sinks_.events && pending_outputs_) write_outputs_line(*pending_outputs_);
  t_end_s_ = now_s();
  record("stop", t_end_s_,
         format(",\"requests\":%llu,\"watchdog_trips\":%llu,\"u_p\":%.6f,\"u_n\":%.6f",
                static_cast<unsigned long long>(requests_), static_cast<unsigned long long>(trips_), u_p_, u_n_));
  std::fprintf(sinks_.messages,
               "pneu-plant serve: stopped after %.3f s; %llu requests from %llu clients (at most %d at once, %llu "
               "refused beyond --max-clients), %llu valve writes refused as another client's, %llu for other units "
               "ignored, %llu watchdog trips; last valve voltages: u_P = %+.4f V, u_N = %+.4f V\n",
               t_end_s_, static_cast<unsigned long long>(requests_), static_cast<unsigned long long>(clients_),
               most_connected_, static_cast<unsigned long long>(refused_), static_cast<unsigned long long>(busy_),
               static_cast<unsigned long long>(foreign_), static_cast<unsigned long long>(trips_), u_p_, u_n_);
  std::fflush(sinks_.messages);
  if (tcp_) {
    for (Connection& c : connections_)
      if (c.fd >= 0) ::close(c.fd), c.fd = -1;
    modbus_set_socket(m_.ctx, -1);  // closed above: not for modbus_close to close again
    ::close(listen_fd_);
    listen_fd_ = -1;
  }
}

Stats PlantServer::Impl::stats() const noexcept {
  Stats s;
  s.t_s = t_end_s_ > 0.0 ? t_end_s_ : ran_ ? now_s() : 0.0;
  s.requests = requests_;
  s.clients = clients_;
  s.most_connected = most_connected_;
  s.refused = refused_;
  s.busy = busy_;
  s.foreign = foreign_;
  s.watchdog_trips = trips_;
  s.u_p_v = u_p_;
  s.u_n_v = u_n_;
  return s;
}

// --- PlantServer ------------------------------------------------------------------------------------

PlantServer::PlantServer(ServerParams params, Sinks sinks) : impl_(std::make_unique<Impl>(std::move(params), sinks)) {}
PlantServer::~PlantServer() = default;
int PlantServer::port() const noexcept { return impl_->port(); }
double PlantServer::neutral_voltage_v() const noexcept { return impl_->neutral_voltage_v(); }
void PlantServer::run() { impl_->run(); }
void PlantServer::request_stop() noexcept { impl_->request_stop(); }
Stats PlantServer::stats() const noexcept { return impl_->stats(); }

}  // namespace pneu::plant_server
