// The simulated bench behind a Modbus server, as the bench's analog I/O module would serve it
// (hardware in the loop): the plant model stepped in real time, its sensors scaled into the
// registers of a register map, the valve registers driving the valves, several TCP clients with
// one writer of the valves, the module's fieldbus watchdog, and a fault schedule. `pneu-plant
// serve` is a program around it; a test can run it in-process, on a thread, on 127.0.0.1 port 0.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <vector>

#include "pneu/hal/modbus_params.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/sensors.hpp"
#include "pneu/plant_server/faults.hpp"

namespace pneu::plant_server {

/// TCP: the most clients served at once (select's fd_set has room for them).
inline constexpr int kMaxClientsLimit = 64;

/// What the server is built from.
struct ServerParams {
  model::PlantParams plant;          ///< the simulated bench
  model::SensorParams sensors;       ///< its sensors: noise, clamp, converters
  std::vector<model::Push> pushes;   ///< external forces on the carriage, on the server's time
  double initial_position_m = 0.2195;  ///< at rest there at start-up, the valves at its neutral voltage u_e
  /// The register map, the transport (TCP host:port, port 0: one the kernel picks; RTU device,
  /// baud...) and the unit id. module_watchdog_s is not read: watchdog_s is the watchdog.
  hal::ModbusConfig modbus;
  int max_clients = 4;               ///< TCP: clients served at once, 1 to kMaxClientsLimit
  double duration_s = 0.0;           ///< run() returns after this long; 0: when request_stop() is called
  double reply_delay_s = 0.0;        ///< fault injection: every reply this late ...
  double delay_after_s = 0.0;        ///< ... from this time on
  double watchdog_s = 0.0;           ///< the module's fieldbus watchdog; 0: none
  std::optional<ValveVoltages> watchdog_outputs;  ///< what it sets; nullopt: the neutral voltages (u_e, -u_e)
  std::vector<Fault> faults;         ///< the schedule, in any order (ties act in the order given)
};

/// Where the server writes what it does. Each file is written and flushed line by line: a record
/// read while the server runs, kept whole up to a SIGKILL. The caller owns the files.
struct Sinks {
  std::FILE* events = nullptr;   ///< JSON lines: the plant's and the module's record (docs/serve.md); nullptr: none
  std::FILE* outputs = nullptr;  ///< CSV t_s,u_p_v,u_n_v: every change of the valve outputs written; nullptr: none
  std::FILE* messages = stdout;  ///< lines as things happen (a fault active, the valves' owner, a watchdog trip) and the closing summary
  std::FILE* warnings = stderr;  ///< clients refused or dropped, a valve write refused (once per client)
};

/// The server's counts, and the valve outputs it holds.
struct Stats {
  double t_s = 0.0;                 ///< the server's time: since run() started (at its end: how long it ran)
  std::uint64_t requests = 0;       ///< requests served for its unit
  std::uint64_t clients = 0;        ///< clients accepted (RTU: 1, the line)
  int most_connected = 0;           ///< the most served at once
  std::uint64_t refused = 0;        ///< connections refused beyond max_clients
  std::uint64_t busy = 0;           ///< valve writes refused as another client's (exception 06)
  std::uint64_t foreign = 0;        ///< requests for other units, ignored
  std::uint64_t watchdog_trips = 0;
  double u_p_v = 0.0, u_n_v = 0.0;  ///< the valve outputs held: the registers' voltages
};

/// The Modbus plant server. Construction builds the plant at rest and opens the transport (TCP:
/// listening on return; RTU: the device open); run() serves until request_stop() or the duration.
/// Throws std::invalid_argument for bad parameters, std::runtime_error when the transport cannot
/// be opened or fails.
class PlantServer {
 public:
  explicit PlantServer(ServerParams params, Sinks sinks = {});
  ~PlantServer();
  PlantServer(const PlantServer&) = delete;
  PlantServer& operator=(const PlantServer&) = delete;

  /// TCP: the port it listens on (the kernel's pick for port 0); RTU: 0.
  [[nodiscard]] int port() const noexcept;
  /// The neutral voltage u_e of the initial position (the valves' first outputs: u_P = u_e, u_N = -u_e).
  [[nodiscard]] double neutral_voltage_v() const noexcept;

  /// Serves: the server's time starts (its "start" record), the plant follows CLOCK_MONOTONIC,
  /// faults act at their times; returns on request_stop() (within 0.5 ms) or after the duration,
  /// having written its "stop" record and summary and closed its connections. Once only.
  void run();
  /// Asks run() to return. From any thread, or a signal handler (one lock-free atomic store).
  void request_stop() noexcept;
  /// The counts so far: from the thread that runs it, or once run() has returned.
  [[nodiscard]] Stats stats() const noexcept;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pneu::plant_server
