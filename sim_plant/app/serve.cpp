// pneu-plant serve: the plant model stepped in real time behind a Modbus server exposing the
// register map of hal.modbus, as the bench's analog I/O module would (hardware in the loop).
#include "serve.hpp"

#include <arpa/inet.h>
#include <modbus.h>
#include <sys/select.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/config/text.hpp"
#include "pneu/config/config.hpp"
#include "pneu/hal/monotonic.hpp"
#include "pneu/sim_plant/plant.hpp"
#include "pneu/sim_plant/sensors.hpp"

namespace pneu::plant_app {

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop.store(true); }

using hal::monotonic_s;

struct ModbusContext {
  modbus_t* ctx = nullptr;
  modbus_mapping_t* map = nullptr;
  ~ModbusContext() {
    if (map) modbus_mapping_free(map);
    if (ctx) {
      modbus_close(ctx);
      modbus_free(ctx);
    }
  }
};

// --- Fault injection (--fault CHANNEL:MODE@T) ---------------------------------------------------

enum class FaultChannel { kPosition, kPressureP, kPressureN, kValveP, kValveN, kTubes, kPressureSensors };
enum class FaultMode { kRailLow, kRailHigh, kRaw, kVolts, kFreeze, kNan, kStuck, kDead, kSwapped };

/// One --fault, parsed and validated against the register map before serving.
struct Fault {
  std::string spec;
  FaultChannel channel = FaultChannel::kPosition;
  FaultMode mode = FaultMode::kFreeze;
  double t_s = 0.0;                    ///< acts from this time after start-up on
  double stuck_v = 0.0;                ///< valve faults: the voltage the stuck spool drives
  std::array<std::uint16_t, 2> words{};  ///< sensor faults: what the register(s) read (freeze: set on activation)
};

bool is_valve(FaultChannel c) { return c == FaultChannel::kValveP || c == FaultChannel::kValveN; }
/// A miswiring of the bench (the tubes, the pressure transmitters' channels) rather than one channel.
bool is_wiring(FaultChannel c) { return c == FaultChannel::kTubes || c == FaultChannel::kPressureSensors; }

const config::RegisterChannel& channel_of(const config::ModbusConfig& mb, FaultChannel c) {
  switch (c) {
    case FaultChannel::kPosition: return mb.position;
    case FaultChannel::kPressureP: return mb.pressure_p;
    case FaultChannel::kPressureN: return mb.pressure_n;
    case FaultChannel::kValveP: return mb.valve_p;
    case FaultChannel::kValveN: return mb.valve_n;
    case FaultChannel::kTubes:
    case FaultChannel::kPressureSensors: break;  // no one register: a miswiring
  }
  return mb.position;
}

// A whole-string number (strtod: also "inf", "nan"), or nullopt.
std::optional<double> parse_number(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE) return std::nullopt;
  return v;
}

/// `u_max_v`: the simulated valve's largest voltage (plant.valve.max_voltage_v), the bound of stuck=V.
Fault parse_fault(const std::string& spec, const config::ModbusConfig& mb, double u_max_v) {
  const auto bad = [&](const std::string& why) { return cli::UsageError("--fault '" + spec + "': " + why); };
  const auto colon = spec.find(':');
  if (colon == std::string::npos) throw bad("expected CHANNEL:MODE@T, e.g. pressure_p:rail-high@2.5");
  const std::string channel = spec.substr(0, colon);
  const std::string rest = spec.substr(colon + 1);
  const auto at = rest.rfind('@');
  if (at == std::string::npos) throw bad("missing @T: the time from which the fault acts, in seconds after start-up");
  const std::string mode_text = rest.substr(0, at);
  const std::string t_text = rest.substr(at + 1);

  Fault f;
  f.spec = spec;
  if (channel == "position") f.channel = FaultChannel::kPosition;
  else if (channel == "pressure_p") f.channel = FaultChannel::kPressureP;
  else if (channel == "pressure_n") f.channel = FaultChannel::kPressureN;
  else if (channel == "valve_p") f.channel = FaultChannel::kValveP;
  else if (channel == "valve_n") f.channel = FaultChannel::kValveN;
  else if (channel == "tubes") f.channel = FaultChannel::kTubes;
  else if (channel == "pressure_sensors") f.channel = FaultChannel::kPressureSensors;
  else throw bad("unknown channel '" + channel + "' (position, pressure_p, pressure_n, valve_p, valve_n, tubes, pressure_sensors)");

  const auto t = parse_number(t_text);
  if (!t || !std::isfinite(*t)) throw bad("T must be a number of seconds (got '" + t_text + "')");
  if (*t < 0.0) throw bad("T must be >= 0 (got " + t_text + ")");
  f.t_s = *t;

  const auto eq = mode_text.find('=');
  const std::string mode = mode_text.substr(0, eq);
  const std::optional<std::string> arg =
      eq == std::string::npos ? std::nullopt : std::optional<std::string>(mode_text.substr(eq + 1));
  if (mode == "rail-low") f.mode = FaultMode::kRailLow;
  else if (mode == "rail-high") f.mode = FaultMode::kRailHigh;
  else if (mode == "raw") f.mode = FaultMode::kRaw;
  else if (mode == "volts") f.mode = FaultMode::kVolts;
  else if (mode == "freeze") f.mode = FaultMode::kFreeze;
  else if (mode == "nan") f.mode = FaultMode::kNan;
  else if (mode == "stuck") f.mode = FaultMode::kStuck;
  else if (mode == "dead") f.mode = FaultMode::kDead;
  else if (mode == "swapped") f.mode = FaultMode::kSwapped;
  else throw bad("unknown mode '" + mode + "' (sensors: rail-low, rail-high, raw=N, volts=V, freeze, nan, dead; valves: "
                 "stuck=V; tubes, pressure_sensors: swapped)");
  const bool takes_value = f.mode == FaultMode::kRaw || f.mode == FaultMode::kVolts || f.mode == FaultMode::kStuck;
  if (takes_value && (!arg || arg->empty())) throw bad(mode + " needs a value: " + mode + (f.mode == FaultMode::kRaw ? "=N" : "=V"));
  if (!takes_value && arg) throw bad(mode + " takes no value");
  if (is_wiring(f.channel) != (f.mode == FaultMode::kSwapped))
    throw bad(is_wiring(f.channel) ? channel + " takes swapped only" : "swapped is for tubes and pressure_sensors only");
  if (is_valve(f.channel) && f.mode != FaultMode::kStuck)
    throw bad(mode + " is a sensor mode: a valve channel takes stuck=V only");
  if (!is_valve(f.channel) && f.mode == FaultMode::kStuck)
    throw bad("stuck=V is a valve mode: a sensor channel takes rail-low, rail-high, raw=N, volts=V, freeze, nan or dead");
  if (is_wiring(f.channel)) return f;

  const config::RegisterChannel& c = channel_of(mb, f.channel);
  const bool is_float = c.format == config::RegisterFormat::kFloat32;
  const std::string type = is_float ? "float32" : c.is_signed ? "signed 16-bit" : "unsigned 16-bit";
  switch (f.mode) {
    case FaultMode::kRailLow: (void)c.raw_to_words(c.raw_min, f.words.data()); break;
    case FaultMode::kRailHigh: (void)c.raw_to_words(c.raw_max, f.words.data()); break;
    case FaultMode::kRaw: {
      const auto n = parse_number(*arg);
      if (!n || std::isnan(*n)) throw bad("raw=" + *arg + ": not a number" + (is_float ? " (for NaN use the mode nan)" : ""));
      if (!c.raw_to_words(*n, f.words.data()))
        throw bad("raw=" + *arg + " does not fit the channel's " + type + " register" +
                  (is_float ? "" : c.is_signed ? " (an integer in [-32768, 32767])" : " (an integer in [0, 65535])"));
      break;
    }
    case FaultMode::kVolts: {
      const auto v = parse_number(*arg);
      if (!v || !std::isfinite(*v)) throw bad("volts=" + *arg + ": not a finite number of volts");
      (void)c.raw_to_words(c.volts_to_raw(*v), f.words.data());  // saturates at the register type's limits
      break;
    }
    case FaultMode::kNan:
      if (!is_float)
        throw bad("nan needs a float32 channel (hal.modbus.channels." + channel +
                  ".format: float32): an int16 register cannot hold NaN");
      (void)c.raw_to_words(std::nan(""), f.words.data());  // 0x7FC0 0x0000, a quiet NaN
      break;
    case FaultMode::kStuck: {
      const auto v = parse_number(*arg);
      if (!v || !std::isfinite(*v)) throw bad("stuck=" + *arg + ": not a finite number of volts");
      if (std::abs(*v) > u_max_v) {
        char range[64];
        std::snprintf(range, sizeof range, "[%g, %g] V", -u_max_v, u_max_v);
        throw bad("stuck=" + *arg + " is outside the valve's range " + range +
                  " (plant.valve.max_voltage_v of the simulated bench)");
      }
      f.stuck_v = *v;
      break;
    }
    case FaultMode::kFreeze:
    case FaultMode::kDead:
    case FaultMode::kSwapped: break;
  }
  return f;
}

// --- Several TCP clients, one writer of the valves ------------------------------------------------

constexpr int kMaxClientsLimit = 64;   ///< --max-clients' upper bound (select's fd_set has room)
constexpr int kMbapBytes = 7;          ///< transaction id, protocol id, length, unit id

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
  bool told_busy = false;        ///< its first refused valve write was reported on stderr
  bool reply_pending = false;    ///< --reply-delay-s holds the reply back (the socket is not read meanwhile)
  double reply_at_s = 0.0;       ///< when it falls due, since start-up
  int query_length = 0;
  std::array<std::uint8_t, std::max(MODBUS_RTU_MAX_ADU_LENGTH, MODBUS_TCP_MAX_ADU_LENGTH)> query{};
  std::array<std::uint16_t, 6> sensor_words{};  ///< the sensor registers when the held request came
};

/// `text` as a JSON string, quotes included (a device path or a --fault spec may hold any byte).
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

/// The fields of an --events line, as printf would print them.
using text::format;

/// The valve outputs a module's watchdog sets (--watchdog-outputs): neutral, exhaust or U_P,U_N.
struct WatchdogOutputs {
  double u_p_v = 0.0, u_n_v = 0.0;
};

WatchdogOutputs parse_watchdog_outputs(const std::string& text, double u_e_v, double u_max_v) {
  if (text == "neutral") return {u_e_v, -u_e_v};
  if (text == "exhaust") return {-u_max_v, -u_max_v};
  const auto comma = text.find(',');
  const auto p = comma == std::string::npos ? std::nullopt : parse_number(text.substr(0, comma));
  const auto n = comma == std::string::npos ? std::nullopt : parse_number(text.substr(comma + 1));
  if (!p || !n || !std::isfinite(*p) || !std::isfinite(*n))
    throw cli::UsageError("--watchdog-outputs '" + text + "': expected neutral, exhaust or U_P,U_N in volts (e.g. -10,-10)");
  return {*p, *n};
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

}  // namespace

const char* const kServeHelpText = R"(pneu-plant serve: the simulated bench behind a Modbus server (hardware in the loop)

  --config FILE        YAML configuration with a hal.modbus section (default: the embedded
                       config/sim.yaml, which has none: use config/hil.yaml)
  --set KEY=VALUE      override a config key (repeatable), e.g. --set hal.modbus.port=1502
  --duration S         stop after S seconds (default: run until SIGINT/SIGTERM)
  --outputs FILE       record the valve voltages the clients write: CSV with the header
                       t_s,u_p_v,u_n_v, one line at start-up (the registers' initial values) and
                       one each time either received voltage changes (not per request); t_s in
                       seconds since start-up, 6 decimals. Each line is flushed at once, so the
                       file holds the last outputs received even after a SIGKILL. (Like
                       --events, a live record: written into the file itself, not beside it;
                       a symbolic link is followed, a device or FIFO written directly.)
  --events FILE        the plant's and the module's own record of what they did, one JSON object
                       per line, flushed at once, each with "event", "t" (serve's seconds since
                       start-up) and "monotonic_s" (CLOCK_MONOTONIC: another process's record on
                       that clock lines up): "start"; the plant's "breakaway" (stuck -> sliding;
                       "direction" +1 / -1), "stick" (sliding -> stuck) and "end_stop", located
                       inside the integration step, with "y" [m] and "force" [N, Eq. 14]; the
                       valve outputs it holds, "outputs" ("u_p", "u_n" [V], "client", "cause"
                       write | watchdog; at most one line written per 10 ms, "skipped": the
                       changes superseded before their line was due; never the last);
                       "connect", "disconnect", "refused",
                       "owner" and "released" (the valve registers' writer); "watchdog" (a trip:
                       "client", "last_request_t", "last_request_monotonic_s", the outputs set);
                       "fault" (a --fault becoming active); "stop". The truth a test judges
                       pneud's forecasts, dates and safe outputs against (format: docs/serve.md).
  --fault SPEC         fault injection (repeatable): SPEC is CHANNEL:MODE@T, acting from T seconds
                       after start-up on. Sensor channels position, pressure_p, pressure_n:
                         rail-low | rail-high  the register reads the channel's raw_min | raw_max
                         raw=N                 the register reads the raw value N (may lie outside
                                               [raw_min, raw_max]; must fit the register type)
                         volts=V               the register reads V volts through the channel's
                                               scaling, clamped only by the register type
                         freeze                the register keeps the value it had at T
                         nan                   the register reads NaN (float32 channels only)
                         dead                  the sensor reads the value its quantity had at T,
                                               with its noise: a dead transmitter (not frozen bit
                                               for bit, so only a movement test tells)
                       valve channels valve_p, valve_n:
                         stuck=V               the plant's valve is driven at V volts whatever the
                                               client writes (--outputs still records the writes);
                                               |V| at most the valve's plant.valve.max_voltage_v
                       miswirings:
                         tubes:swapped         valve P's tube feeds chamber N and valve N's
                                               chamber P
                         pressure_sensors:swapped  the pressure_p register reads chamber N, the
                                               pressure_n register chamber P
                       A later fault on the same channel replaces an earlier one. Each prints one
                       line when it becomes active.
  --reply-delay-s D    fault injection: answer every request D seconds late, with the readings of
                       its time (each client's own: a held reply holds up no other client) ...
  --delay-after-s T    ... from T seconds after start-up on (default 0)
  --max-clients N      TCP: serve up to N clients at once, 1 to 64 (default 4)
  --watchdog-s S       the module's fieldbus watchdog, as an I/O coupler's: when the owner of the
                       valve registers has sent no request for S seconds, the valve outputs go to
                       --watchdog-outputs and the registers are free for the next writer
                       (default: hal.modbus.module_watchdog_s; 0: none)
  --watchdog-outputs W what the watchdog sets: neutral (the voltages serve starts with, u_e of
                       the initial position: the carriage held), exhaust (both valves at
                       -controller.law.max_voltage_v) or U_P,U_N in volts (default neutral)
  --quiet              no start-up line

The plant of plant.* runs in real time from rest at simulation.initial_position_m. Each request
is answered from the sensor models of sensors.* (noise, clamp, ADC) scaled into the registers of
hal.modbus.channels (a float32 channel: two registers, high word first); the valve registers
written by the client drive the valves, each its own: valve_p -> u_P, valve_n -> u_N.

TCP listens on hal.modbus.host:port (loopback by default) and serves up to --max-clients clients
at once, as an I/O module does (a controller, and a monitoring tool beside it); one more is
accepted and closed at once, with a line on stderr. Each request is read only once it has arrived
whole, so a slow or stalled client holds up no other; one that stops taking its replies is
dropped. Reading is free for all. The valve registers have one writer: the first client that
sends a write to valve_p or valve_n (functions 6, 16, 22, 23) owns them until it disconnects; a
write by another client that touches them is answered with exception 06 (server device busy) and
changes nothing (reported on stderr once per client), and the owner's leaving frees them for the
next writer (stdout says who owns them, and when they are free). With a watchdog, an owner that
falls silent loses them too (stdout says so), and the outputs go to the watchdog's.
RTU serves hal.modbus.device as unit hal.modbus.unit_id, one line, one client.

On exit it prints the requests served, the clients (at most how many at once, how many refused),
the valve writes refused, and the last valve voltages it was sent. Bad --fault specs, an
--outputs or --events file that cannot be opened, and both naming one file are refused before
serving, with exit code 2.
)";

int serve(int argc, char** argv) {
  const cli::Args args(argc, argv, 2,
                       {"config", "duration", "reply-delay-s", "delay-after-s", "outputs", "events", "max-clients",
                        "watchdog-s", "watchdog-outputs"},
                       {"help", "quiet"}, {"set", "fault"});
  if (args.flag("help")) {
    std::cout << kServeHelpText;
    return cli::kExitOk;
  }
  const config::Config cfg = config::load_file_or_default(args.value("config").value_or(""), args.all("set"));
  if (!cfg.hal.has_modbus) throw config::ConfigError("hal.modbus", "missing: serve needs the register map (see config/hil.yaml)");
  const double duration = args.number("duration", 0.0);
  if (duration < 0.0) throw cli::UsageError("--duration must be >= 0");
  const double reply_delay = args.number("reply-delay-s", 0.0);
  const double delay_after = args.number("delay-after-s", 0.0);
  if (reply_delay < 0.0 || delay_after < 0.0) throw cli::UsageError("--reply-delay-s and --delay-after-s must be >= 0");
  const double max_clients_d = args.number("max-clients", 4);
  if (!(max_clients_d >= 1 && max_clients_d <= kMaxClientsLimit && max_clients_d == std::floor(max_clients_d)))
    throw cli::UsageError("--max-clients must be a whole number from 1 to " + std::to_string(kMaxClientsLimit));
  const int max_clients = static_cast<int>(max_clients_d);
  const auto& mb = cfg.hal.modbus;
  const double watchdog_s = args.number("watchdog-s", mb.module_watchdog_s);
  if (!(watchdog_s >= 0.0 && std::isfinite(watchdog_s))) throw cli::UsageError("--watchdog-s must be >= 0 (0: none)");

  // Faults in the order they become active (ties: command-line order).
  std::vector<Fault> faults;
  for (const auto& spec : args.all("fault"))
    faults.push_back(parse_fault(spec, mb, config::simulated_bench(cfg).valve.max_voltage_v));
  std::stable_sort(faults.begin(), faults.end(), [](const Fault& a, const Fault& b) { return a.t_s < b.t_s; });

  // Live records (flushed line by line, read while serve runs, kept after a SIGKILL), opened as
  // every output is (cli::OutputFile): links followed, a device or FIFO written directly.
  std::vector<std::pair<std::string, std::string>> given;
  for (const char* option : {"outputs", "events"})
    if (const auto path = args.value(option)) given.emplace_back(std::string("--") + option, *path);
  cli::refuse_same_file(given);
  std::optional<cli::OutputFile> outputs_file, events_file;
  const auto open_record = [&](std::optional<cli::OutputFile>& file, const char* option) -> std::FILE* {
    const auto path = args.value(option);
    if (!path) return nullptr;
    try {
      return file.emplace(*path, std::string("--") + option, cli::OutputKind::kLive).c_file();
    } catch (const std::runtime_error& e) {
      throw cli::UsageError(e.what());
    }
  };
  std::FILE* const outputs = open_record(outputs_file, "outputs");
  std::FILE* const events = open_record(events_file, "events");

  const model::PlantParams& bench = config::simulated_bench(cfg);  // hal.sim.plant over plant:
  plant::Plant plant(bench);
  plant::SensorSuite sensors(cfg.sensors);
  const double u_e =
      model::equilibrium_voltage_v(plant.valve(), model::ChamberProcess(bench), cfg.simulation.initial_position_m);
  plant.reset_at_rest(cfg.simulation.initial_position_m, u_e);
  double u_p = u_e, u_n = -u_e;  // what the client wrote (at first: the neutral voltages)
  const WatchdogOutputs watchdog_outputs =
      parse_watchdog_outputs(args.value("watchdog-outputs").value_or("neutral"), u_e, cfg.controller.law.max_voltage_v);
  const std::uint16_t watchdog_word_p = mb.valve_p.to_word(watchdog_outputs.u_p_v);
  const std::uint16_t watchdog_word_n = mb.valve_n.to_word(watchdog_outputs.u_n_v);
  std::optional<double> stuck_p, stuck_n;  // a stuck spool drives its valve instead

  ModbusContext m;
  const bool tcp = mb.transport == config::ModbusTransport::kTcp;
  m.ctx = tcp ? modbus_new_tcp(mb.host.c_str(), mb.port)
              : modbus_new_rtu(mb.device.c_str(), mb.baud, mb.parity, mb.data_bits, mb.stop_bits);
  if (!m.ctx) throw std::runtime_error(std::string("cannot create the Modbus server: ") + modbus_strerror(errno));
  modbus_set_slave(m.ctx, mb.unit_id);
  const int top = std::max({mb.position.last_address(), mb.pressure_p.last_address(), mb.pressure_n.last_address(),
                            mb.valve_p.last_address(), mb.valve_n.last_address()}) + 1;
  m.map = modbus_mapping_new(0, 0, top, top);
  if (!m.map) throw std::runtime_error(std::string("cannot allocate the register map: ") + modbus_strerror(errno));
  uint16_t* sensor_regs = mb.sensor_table == config::SensorTable::kInput ? m.map->tab_input_registers : m.map->tab_registers;
  m.map->tab_registers[mb.valve_p.address] = mb.valve_p.to_word(u_p);
  m.map->tab_registers[mb.valve_n.address] = mb.valve_n.to_word(u_n);
  std::uint16_t word_p = m.map->tab_registers[mb.valve_p.address], word_n = m.map->tab_registers[mb.valve_n.address];

  // The sensor registers: from the sensor models, or what an active fault makes them read.
  const Fault* sensor_fault[3] = {nullptr, nullptr, nullptr};  // position, pressure_p, pressure_n
  const config::RegisterChannel* sensor_channel[3] = {&mb.position, &mb.pressure_p, &mb.pressure_n};
  // Miswirings and dead sensors (--fault tubes:swapped, pressure_sensors:swapped, CHANNEL:dead).
  bool tubes_swapped = false, pressure_sensors_swapped = false;
  std::optional<double> dead_value[3];  // what a dead sensor reads (before its noise)
  // What each sensor measures: its quantity, through the wiring.
  const auto measured = [&](int i) {
    const auto& s = plant.state();
    return i == 0 ? s.y_m : (i == 1) != pressure_sensors_swapped ? s.p_p_pa : s.p_n_pa;
  };
  const auto update_sensor_registers = [&] {
    double q[3];
    for (int i = 0; i < 3; ++i) q[i] = dead_value[i].value_or(measured(i));
    const auto v = sensors.read_volts(q[0], q[1], q[2]);
    const double volts[3] = {v.y_m, v.p_p_pa, v.p_n_pa};
    for (int i = 0; i < 3; ++i) {
      const config::RegisterChannel& c = *sensor_channel[i];
      std::uint16_t* w = &sensor_regs[c.address];
      if (!sensor_fault[i]) c.to_words(volts[i], w);
      else std::copy_n(sensor_fault[i]->words.begin(), c.register_count(), w);
    }
  };
  update_sensor_registers();  // so that a fault frozen before the first request has a value to keep

  // TCP: up to max_clients connections, each its slot; RTU: the line, in slot 0.
  std::vector<Connection> connections(tcp ? static_cast<std::size_t>(max_clients) : 1);
  int listen_fd = -1;
  if (tcp) {
    // A burst of connections waits in the kernel to be accepted (or refused), not retried later.
    listen_fd = modbus_tcp_listen(m.ctx, kMaxClientsLimit);
    if (listen_fd < 0)
      throw std::runtime_error("cannot listen on " + mb.host + ":" + std::to_string(mb.port) + ": " + modbus_strerror(errno));
    // A request reaches modbus_receive whole (frame_ready): a byte timeout only ends a frame whose
    // function needs more bytes than its MBAP length announced, and 1 ms of it holds no one up.
    // libmodbus answers a request with an illegal count after sleeping its response timeout and
    // flushing (to skip the rest of a garbled RTU frame): 1 us, so that one client's bad request
    // does not stall the others for 0.5 s.
    modbus_set_byte_timeout(m.ctx, 0, 1000);
    modbus_set_response_timeout(m.ctx, 0, 1);
  } else {
    if (modbus_connect(m.ctx) == -1)
      throw std::runtime_error("cannot open " + mb.device + ": " + modbus_strerror(errno));
    connections[0].fd = modbus_get_socket(m.ctx);
    connections[0].number = 1;
    connections[0].peer = mb.device;
  }
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  if (!args.flag("quiet")) {
    if (tcp)
      std::printf("pneu-plant serve: listening on %s:%d (unit %d, up to %d clients)\n", mb.host.c_str(), mb.port,
                  mb.unit_id, max_clients);
    else std::printf("pneu-plant serve: serving %s at %d baud (unit %d)\n", mb.device.c_str(), mb.baud, mb.unit_id);
    std::fflush(stdout);
  }

  const double t0 = monotonic_s();
  // One line of the record: its kind, its time and the rest of its fields (",\"key\":value...").
  const auto record = [&](const char* kind, double t, const std::string& rest) {
    if (!events) return;
    std::fprintf(events, "{\"event\":\"%s\",\"t\":%.9f,\"monotonic_s\":%.9f%s}\n", kind, t, t0 + t, rest.c_str());
    std::fflush(events);
  };
  if (events) {
    std::string what = format(",\"watchdog_s\":%.6f,\"watchdog_u_p\":%.6f,\"watchdog_u_n\":%.6f", watchdog_s,
                              mb.valve_p.to_volts(watchdog_word_p), mb.valve_n.to_volts(watchdog_word_n));
    if (watchdog_s == 0.0) what = ",\"watchdog_s\":0";
    record("start", 0.0, what + format(",\"u_p\":%.6f,\"u_n\":%.6f", mb.valve_p.to_volts(word_p), mb.valve_n.to_volts(word_n)));
  }
  // The plant's motion events (its time is serve's: both start at 0).
  const auto record_events = [&](std::span<const plant::PlantEvent> happened) {
    if (!events) return;
    for (const plant::PlantEvent& e : happened) {
      const char* kind = e.kind == plant::PlantEvent::Kind::kBreakaway ? "breakaway"
                         : e.kind == plant::PlantEvent::Kind::kStick   ? "stick"
                         : e.kind == plant::PlantEvent::Kind::kEndStop ? "end_stop"
                                                                        : nullptr;
      if (kind == nullptr) continue;  // a reversal slides on
      std::fprintf(events, "{\"event\":\"%s\",\"t\":%.9f,\"monotonic_s\":%.9f,\"direction\":%d,\"y\":%.9f,\"force\":%.6f}\n",
                   kind, e.t_s, t0 + e.t_s, e.direction, e.y_m, e.force_n);  // the plant's own time
    }
    if (!happened.empty()) std::fflush(events);
  };
  const auto record_outputs = [&](double t) {
    if (!outputs) return;
    std::fprintf(outputs, "%.6f,%.6f,%.6f\n", t, mb.valve_p.to_volts(word_p), mb.valve_n.to_volts(word_n));
    std::fflush(outputs);
  };
  if (outputs) {
    std::fputs("t_s,u_p_v,u_n_v\n", outputs);
    record_outputs(0.0);
  }
  // The outputs the module holds, in --events: each change with its time, at most one line
  // written per kOutputsRecordGapS; a change superseded before its line was due is counted
  // ("skipped") in the next line, and the last change waits at most that long (pending, written
  // by the loop).
  constexpr double kOutputsRecordGapS = 0.01;
  struct OutputsLine {
    double t = 0.0;
    std::uint64_t client = 0;
    const char* cause = "write";
  };
  std::optional<OutputsLine> pending_outputs;
  double last_outputs_line_t = -1.0;  // serve's time when the last line was written
  std::uint64_t outputs_skipped = 0;
  const auto write_outputs_line = [&](const OutputsLine& o) {
    record("outputs", o.t,
           format(",\"u_p\":%.6f,\"u_n\":%.6f,\"client\":%llu,\"cause\":\"%s\",\"skipped\":%llu",
                  mb.valve_p.to_volts(word_p), mb.valve_n.to_volts(word_n), static_cast<unsigned long long>(o.client),
                  o.cause, static_cast<unsigned long long>(outputs_skipped)));
    last_outputs_line_t = std::max(o.t, monotonic_s() - t0);  // when written: a pending line comes late
    outputs_skipped = 0;
    pending_outputs.reset();
  };
  // Called once word_p, word_n hold the new outputs; `now`: serve's time. A watchdog's line
  // is written at once.
  const auto outputs_changed = [&](const OutputsLine& o) {
    if (!events) return;
    if (pending_outputs) ++outputs_skipped;
    if (o.t - last_outputs_line_t >= kOutputsRecordGapS || std::string_view(o.cause) != "write") write_outputs_line(o);
    else pending_outputs = o;
  };
  const auto flush_pending_outputs = [&](double now) {
    if (pending_outputs && now - last_outputs_line_t >= kOutputsRecordGapS) write_outputs_line(*pending_outputs);
  };

  // Real time: the plant catches up with the wall clock, the valves held since the last write;
  // each fault takes effect at its own time inside the catch-up.
  std::size_t next_fault = 0;
  const auto drive_p = [&] { return stuck_p.value_or(u_p); };
  const auto drive_n = [&] { return stuck_n.value_or(u_n); };
  // The plant to `t`, each push of hal.sim.pushes (on serve's time) from its start to its end.
  const auto step_to = [&](double t) {
    plant::step_with_pushes(plant, t, tubes_swapped ? drive_n() : drive_p(), tubes_swapped ? drive_p() : drive_n(),
                            cfg.hal.sim.pushes, record_events);
  };
  const auto advance_to = [&](double t) {
    for (; next_fault < faults.size() && faults[next_fault].t_s <= t; ++next_fault) {
      Fault& f = faults[next_fault];
      if (f.t_s > plant.state().t_s) step_to(f.t_s);
      switch (f.channel) {
        case FaultChannel::kValveP: stuck_p = f.stuck_v; break;
        case FaultChannel::kValveN: stuck_n = f.stuck_v; break;
        case FaultChannel::kTubes: tubes_swapped = true; break;
        case FaultChannel::kPressureSensors: pressure_sensors_swapped = true; break;
        default: {
          const int i = static_cast<int>(f.channel);
          dead_value[i].reset();
          if (f.mode == FaultMode::kDead) {
            dead_value[i] = measured(i);
            sensor_fault[i] = nullptr;
            break;
          }
          if (f.mode == FaultMode::kFreeze)
            std::copy_n(&sensor_regs[sensor_channel[i]->address], sensor_channel[i]->register_count(), f.words.begin());
          sensor_fault[i] = &f;
        }
      }
      std::printf("pneu-plant serve: fault %s active at t = %.6f s\n", f.spec.c_str(), monotonic_s() - t0);
      std::fflush(stdout);
      record("fault", f.t_s, ",\"spec\":" + json_string(f.spec));
    }
    step_to(t);
  };
  // A held reply answers with the readings of its request's time, as a module that answers late.
  const auto sensor_words = [&](std::array<std::uint16_t, 6>& words, bool restore) {
    std::uint16_t* w = words.data();
    for (const config::RegisterChannel* c : sensor_channel) {
      std::uint16_t* reg = &sensor_regs[c->address];
      if (restore) std::copy_n(w, c->register_count(), reg);
      else std::copy_n(reg, c->register_count(), w);
      w += c->register_count();
    }
  };

  std::uint64_t requests = 0, refused = 0, clients = tcp ? 0 : 1, foreign = 0, busy = 0, owner = 0, trips = 0;
  int connected = 0, most_connected = tcp ? 0 : 1;
  if (!tcp) record("connect", 0.0, ",\"client\":1,\"peer\":" + json_string(mb.device));
  // The watchdog watches the client that took the valve registers last (the owner, or the owner
  // that left without another taking them): its requests feed it. 0: disarmed.
  std::uint64_t watched = 0;
  double watched_last_request_s = 0.0;
  const auto drop = [&](Connection& c, const char* why) {
    if (why) std::fprintf(stderr, "pneu-plant serve: client %llu (%s) %s: closed\n",
                          static_cast<unsigned long long>(c.number), c.peer.c_str(), why);
    ::close(c.fd);
    const double t = monotonic_s() - t0;
    record("disconnect", t, format(",\"client\":%llu", static_cast<unsigned long long>(c.number)) +
                                ",\"why\":" + json_string(why ? why : "left"));
    if (c.number == owner) {
      owner = 0;
      std::printf("pneu-plant serve: client %llu left: the valve registers are free\n",
                  static_cast<unsigned long long>(c.number));
      std::fflush(stdout);
      record("released", t, format(",\"client\":%llu,\"cause\":\"disconnect\"", static_cast<unsigned long long>(c.number)));
    }
    c = Connection{};
    --connected;
  };
  // Whether the owner of the valve registers has disconnected (then dropped), asked when another
  // client writes them: its end of the connection may not have been read yet.
  const auto owner_left = [&] {
    for (Connection& c : connections) {
      if (c.fd < 0 || c.number != owner) continue;
      std::uint8_t byte = 0;
      const ssize_t n = recv(c.fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT);
      if (n > 0 || (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR))) return false;
      drop(c, nullptr);
      return true;
    }
    return true;
  };
  const auto reply = [&](Connection& c) {
    if (c.reply_pending) sensor_words(c.sensor_words, /*restore=*/true);
    c.reply_pending = false;
    modbus_set_socket(m.ctx, c.fd);
    const WrittenRegisters written = written_registers(c.query.data() + modbus_get_header_length(m.ctx));
    if (written.include(mb.valve_p.address) || written.include(mb.valve_n.address)) {
      if (owner != 0 && owner != c.number && !owner_left()) {
        ++busy;
        if (!c.told_busy)
          std::fprintf(stderr, "pneu-plant serve: client %llu (%s) may not write the valve registers: client %llu "
                               "owns them until it disconnects (exception 06, server device busy; told once)\n",
                       static_cast<unsigned long long>(c.number), c.peer.c_str(), static_cast<unsigned long long>(owner));
        c.told_busy = true;
        if (modbus_reply_exception(m.ctx, c.query.data(), MODBUS_EXCEPTION_SLAVE_OR_SERVER_BUSY) == -1 && tcp)
          drop(c, "does not take its replies");
        return;
      }
      if (owner == 0) {
        owner = c.number;
        watched = c.number;
        watched_last_request_s = c.last_request_s;
        std::printf("pneu-plant serve: client %llu (%s) writes the valve registers: they are its until it disconnects%s\n",
                    static_cast<unsigned long long>(c.number), c.peer.c_str(),
                    watchdog_s > 0.0 ? " or falls silent past the watchdog" : "");
        std::fflush(stdout);
        record("owner", monotonic_s() - t0, format(",\"client\":%llu", static_cast<unsigned long long>(c.number)));
      }
    }
    // A client that stops taking its replies fills its socket: the send fails at once (the socket
    // does not block) and the client is dropped, never waited for.
    const int sent = modbus_reply(m.ctx, c.query.data(), c.query_length, m.map);
    const std::uint16_t wp = m.map->tab_registers[mb.valve_p.address];
    const std::uint16_t wn = m.map->tab_registers[mb.valve_n.address];
    if (wp != word_p || wn != word_n) {  // each valve drives its own chamber (not Eq. 1's u_N = -u_P)
      word_p = wp;
      word_n = wn;
      u_p = mb.valve_p.to_volts(wp);
      u_n = mb.valve_n.to_volts(wn);
      const double t = monotonic_s() - t0;
      record_outputs(t);
      outputs_changed({t, c.number, "write"});
    }
    if (sent == -1 && tcp) drop(c, "does not take its replies");
  };
  // A request from `c`: answered now, or held back by --reply-delay-s.
  const auto serve_request = [&](Connection& c) {
    modbus_set_socket(m.ctx, c.fd);
    const int rc = modbus_receive(m.ctx, c.query.data());
    if (rc == -1) {
      if (tcp) drop(c, (std::string("sent a request libmodbus cannot read (") + modbus_strerror(errno) + ")").c_str());
      return;
    }
    const int unit_at = modbus_get_header_length(m.ctx) - 1;
    if (rc == 0) return;  // RTU: another unit's request, filtered by libmodbus
    if (c.query[unit_at] != mb.unit_id && c.query[unit_at] != 0) {
      ++foreign;  // another unit's request: a real module stays silent, the client times out
      return;
    }
    ++requests;
    c.query_length = rc;
    const double t = monotonic_s() - t0;
    c.last_request_s = t;
    if (c.number == watched) watched_last_request_s = t;
    advance_to(t);
    update_sensor_registers();
    if (!tcp) {
      // A pty carries bytes at any speed: hold the reply for the time the request and the
      // reply take on a real line at this baud rate (10 bits a byte, 3.5-character silences),
      // so the client meets the timing of the bench's serial link.
      const int fc = c.query[unit_at + 1];
      const int n_read = fc == 3 || fc == 4 ? (c.query[unit_at + 4] << 8 | c.query[unit_at + 5])
                         : fc == 23         ? (c.query[unit_at + 4] << 8 | c.query[unit_at + 5])
                                            : 0;
      const int reply_bytes = n_read > 0 ? 5 + 2 * n_read : 8;
      const double wire_s = (rc + reply_bytes + 7) * 10.0 / mb.baud;
      hal::sleep_until_monotonic_s(monotonic_s() + wire_s);
    }
    if (reply_delay > 0.0 && t >= delay_after) {  // fault injection: a module that answers late
      sensor_words(c.sensor_words, /*restore=*/false);
      c.reply_pending = true;
      c.reply_at_s = monotonic_s() - t0 + reply_delay;  // written when it falls due, even if the client left
    } else {
      reply(c);
    }
  };
  const auto accept_client = [&] {
    sockaddr_in from{};
    socklen_t from_size = sizeof from;
    const int fd = accept4(listen_fd, reinterpret_cast<sockaddr*>(&from), &from_size, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return;
    char address[INET_ADDRSTRLEN] = "?";
    inet_ntop(AF_INET, &from.sin_addr, address, sizeof address);
    const std::string peer = std::string(address) + ":" + std::to_string(ntohs(from.sin_port));
    const auto slot = std::find_if(connections.begin(), connections.end(), [](const Connection& c) { return c.fd < 0; });
    if (slot == connections.end()) {
      ::close(fd);
      ++refused;
      record("refused", monotonic_s() - t0, ",\"peer\":" + json_string(peer));
      std::fprintf(stderr, "pneu-plant serve: refused a client from %s: already serving %d (--max-clients %d)\n",
                   peer.c_str(), max_clients, max_clients);
      return;
    }
    slot->fd = fd;
    slot->number = ++clients;
    slot->peer = peer;
    record("connect", monotonic_s() - t0,
           format(",\"client\":%llu", static_cast<unsigned long long>(slot->number)) + ",\"peer\":" + json_string(peer));
    most_connected = std::max(most_connected, ++connected);
  };

  // The watchdog's trip at serve's time `now`: the plant runs to it under the outputs held, then
  // under the watchdog's; the owner loses the valve registers.
  const auto trip = [&](double now) {
    advance_to(now);
    ++trips;
    const std::uint64_t client = watched;
    watched = 0;
    if (events && pending_outputs) write_outputs_line(*pending_outputs);
    m.map->tab_registers[mb.valve_p.address] = word_p = watchdog_word_p;
    m.map->tab_registers[mb.valve_n.address] = word_n = watchdog_word_n;
    u_p = mb.valve_p.to_volts(word_p);
    u_n = mb.valve_n.to_volts(word_n);
    record_outputs(now);
    record("watchdog", now,
           format(",\"client\":%llu,\"last_request_t\":%.9f,\"last_request_monotonic_s\":%.9f,\"u_p\":%.6f,\"u_n\":%.6f",
                  static_cast<unsigned long long>(client), watched_last_request_s, t0 + watched_last_request_s, u_p, u_n));
    outputs_changed({now, client, "watchdog"});
    std::printf("pneu-plant serve: watchdog: no request from client %llu for %.3f s: valve outputs u_P = %+.4f V, "
                "u_N = %+.4f V%s\n",
                static_cast<unsigned long long>(client), now - watched_last_request_s, u_p, u_n,
                owner == client ? "; the valve registers are free" : "");
    std::fflush(stdout);
    if (owner == client) {
      owner = 0;
      record("released", now, format(",\"client\":%llu,\"cause\":\"watchdog\"", static_cast<unsigned long long>(client)));
    }
  };

  while (!g_stop.load()) {
    double now = monotonic_s() - t0;
    if (duration > 0.0 && now >= duration) break;
    advance_to(now);
    // Held replies as they fall due, the earliest first.
    for (;;) {
      Connection* due = nullptr;
      for (Connection& c : connections)
        if (c.reply_pending && c.reply_at_s <= now && (!due || c.reply_at_s < due->reply_at_s)) due = &c;
      if (!due) break;
      reply(*due);
      now = monotonic_s() - t0;
    }

    fd_set fds;
    FD_ZERO(&fds);
    int max_fd = -1;
    double wait_s = 0.0005;  // the plant advances, and the watchdog looks, at least every 0.5 ms while idle
    if (listen_fd >= 0) FD_SET(listen_fd, &fds), max_fd = std::max(max_fd, listen_fd);
    for (const Connection& c : connections) {
      if (c.fd < 0) continue;
      if (c.reply_pending) wait_s = std::min(wait_s, std::max(0.0, c.reply_at_s - now));
      else FD_SET(c.fd, &fds), max_fd = std::max(max_fd, c.fd);
    }
    timeval tv{0, static_cast<suseconds_t>(wait_s * 1e6)};
    const int ready = select(max_fd + 1, &fds, nullptr, nullptr, &tv);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string("select: ") + std::strerror(errno));
    }
    // The clients before a newcomer, the owner of the valve registers first: a departed owner is
    // noticed before another client's write is judged.
    const auto first = std::find_if(connections.begin(), connections.end(),
                                    [&](const Connection& c) { return c.fd >= 0 && c.number == owner; });
    const std::size_t start = first == connections.end() ? 0 : static_cast<std::size_t>(first - connections.begin());
    for (std::size_t k = 0; k < connections.size(); ++k) {
      Connection& c = connections[(start + k) % connections.size()];
      if (c.fd < 0 || c.reply_pending || !FD_ISSET(c.fd, &fds)) continue;
      if (!tcp) {
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
    if (listen_fd >= 0 && FD_ISSET(listen_fd, &fds)) accept_client();
    // After the requests that were waiting: a stall of serve's own is no silence of the client's.
    now = monotonic_s() - t0;
    if (watchdog_s > 0.0 && watched != 0 && now - watched_last_request_s >= watchdog_s) trip(now);
    flush_pending_outputs(now);
  }
  if (events && pending_outputs) write_outputs_line(*pending_outputs);
  const double t_end = monotonic_s() - t0;
  record("stop", t_end,
         format(",\"requests\":%llu,\"watchdog_trips\":%llu,\"u_p\":%.6f,\"u_n\":%.6f",
                static_cast<unsigned long long>(requests), static_cast<unsigned long long>(trips), u_p, u_n));
  std::printf("pneu-plant serve: stopped after %.3f s; %llu requests from %llu clients (at most %d at once, %llu "
              "refused beyond --max-clients), %llu valve writes refused as another client's, %llu for other units "
              "ignored, %llu watchdog trips; last valve voltages: u_P = %+.4f V, u_N = %+.4f V\n",
              t_end, static_cast<unsigned long long>(requests), static_cast<unsigned long long>(clients),
              most_connected, static_cast<unsigned long long>(refused), static_cast<unsigned long long>(busy),
              static_cast<unsigned long long>(foreign), static_cast<unsigned long long>(trips), u_p, u_n);
  if (tcp) {
    for (Connection& c : connections)
      if (c.fd >= 0) ::close(c.fd);
    modbus_set_socket(m.ctx, -1);  // closed above: not for modbus_close to close again
    ::close(listen_fd);
  }
  if (outputs_file) outputs_file->commit();  // a record that could not be written fails the run
  if (events_file) events_file->commit();
  return cli::kExitOk;
}

}  // namespace pneu::plant_app
