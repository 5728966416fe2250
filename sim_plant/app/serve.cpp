// pneu-plant serve: the plant model stepped in real time behind a Modbus server exposing the
// register map of hal.modbus, as the bench's analog I/O module would (hardware in the loop). The
// server is pneu_plant_server's PlantServer; this is the command line around it: the options, the
// configuration turned into the server's parameters, the record files, the signals.
#include "serve.hpp"

#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/plant_server/plant_server.hpp"

namespace pneu::plant_app {

namespace {

using plant_server::kMaxClientsLimit;

// SIGINT and SIGTERM ask the server that runs to stop.
std::atomic<plant_server::PlantServer*> g_server{nullptr};
static_assert(std::atomic<plant_server::PlantServer*>::is_always_lock_free);
extern "C" void on_stop_signal(int) {
  if (plant_server::PlantServer* server = g_server.load()) server->request_stop();
}

/// The server's parameters that the configuration gives: the simulated bench (hal.sim.plant over
/// plant), its sensors and pushes, the initial position, the register map and the module's
/// watchdog.
plant_server::ServerParams server_params(const config::Config& cfg) {
  plant_server::ServerParams p;
  p.plant = config::simulated_bench(cfg);
  p.sensors = cfg.sensors;
  p.pushes = cfg.hal.sim.pushes;
  p.initial_position_m = cfg.simulation.initial_position_m;
  p.modbus = cfg.hal.modbus;
  p.watchdog_s = cfg.hal.modbus.module_watchdog_s;
  return p;
}

/// The options' part of the parameters, over `p` (--watchdog-outputs is read later, as before:
/// once the records are open). Throws UsageError.
void apply_options(const cli::Args& args, plant_server::ServerParams& p) {
  p.duration_s = args.number("duration", 0.0);
  if (p.duration_s < 0.0) throw cli::UsageError("--duration must be >= 0");
  p.reply_delay_s = args.number("reply-delay-s", 0.0);
  p.delay_after_s = args.number("delay-after-s", 0.0);
  if (p.reply_delay_s < 0.0 || p.delay_after_s < 0.0)
    throw cli::UsageError("--reply-delay-s and --delay-after-s must be >= 0");
  const double max_clients = args.number("max-clients", 4);
  if (!(max_clients >= 1 && max_clients <= kMaxClientsLimit && max_clients == std::floor(max_clients)))
    throw cli::UsageError("--max-clients must be a whole number from 1 to " + std::to_string(kMaxClientsLimit));
  p.max_clients = static_cast<int>(max_clients);
  p.watchdog_s = args.number("watchdog-s", p.watchdog_s);
  if (!(p.watchdog_s >= 0.0 && std::isfinite(p.watchdog_s))) throw cli::UsageError("--watchdog-s must be >= 0 (0: none)");
  for (const auto& spec : args.all("fault")) {
    try {
      p.faults.push_back(plant_server::parse_fault(spec, p.modbus, p.plant.valve.max_voltage_v));
    } catch (const plant_server::SpecError& e) {
      throw cli::UsageError(std::string("--fault ") + e.what());
    }
  }
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
  plant_server::ServerParams params = server_params(cfg);
  apply_options(args, params);

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
  plant_server::Sinks sinks;
  sinks.outputs = open_record(outputs_file, "outputs");
  sinks.events = open_record(events_file, "events");
  try {
    params.watchdog_outputs = plant_server::parse_watchdog_outputs(args.value("watchdog-outputs").value_or("neutral"),
                                                                   cfg.controller.law.max_voltage_v);
  } catch (const plant_server::SpecError& e) {
    throw cli::UsageError(std::string("--watchdog-outputs ") + e.what());
  }

  const int server_max_clients = params.max_clients;
  plant_server::PlantServer server(std::move(params), sinks);
  struct Handlers {  // the signals reach this server while it lives
    explicit Handlers(plant_server::PlantServer& s) {
      g_server.store(&s);
      std::signal(SIGINT, on_stop_signal);
      std::signal(SIGTERM, on_stop_signal);
    }
    ~Handlers() { g_server.store(nullptr); }
    Handlers(const Handlers&) = delete;
    Handlers& operator=(const Handlers&) = delete;
  } handlers(server);
  const config::ModbusConfig& mb = cfg.hal.modbus;
  if (!args.flag("quiet")) {
    if (mb.transport == config::ModbusTransport::kTcp)
      std::printf("pneu-plant serve: listening on %s:%d (unit %d, up to %d clients)\n", mb.host.c_str(), server.port(),
                  mb.unit_id, server_max_clients);
    else std::printf("pneu-plant serve: serving %s at %d baud (unit %d)\n", mb.device.c_str(), mb.baud, mb.unit_id);
    std::fflush(stdout);
  }
  server.run();
  if (outputs_file) outputs_file->commit();  // a record that could not be written fails the run
  if (events_file) events_file->commit();
  return cli::kExitOk;
}

}  // namespace pneu::plant_app
