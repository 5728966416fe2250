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
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <stdexcept>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/sim_plant/plant.hpp"
#include "pneu/sim_plant/sensors.hpp"

namespace pneu::plant_app {

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop.store(true); }

double mono_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

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

}  // namespace

const char* const kServeHelpText = R"(pneu-plant serve: the simulated bench behind a Modbus server (hardware in the loop)

  --config FILE        YAML configuration with a hal.modbus section (default: the embedded
                       config/sim.yaml, which has none: use config/hil.yaml)
  --set KEY=VALUE      override a config key (repeatable), e.g. --set hal.modbus.port=1502
  --duration S         stop after S seconds (default: run until SIGINT/SIGTERM)
  --reply-delay-s D    fault injection: answer every request D seconds late ...
  --delay-after-s T    ... from T seconds after start-up on (default 0)
  --quiet              no start-up line

The plant of plant.* runs in real time from rest at simulation.initial_position_m. Each request
is answered from the sensor models of sensors.* (noise, clamp, ADC) scaled into the registers of
hal.modbus.channels; the valve registers written by the client drive the valves (valve_p; u_N is
assumed -u_P, as Eq. 1). TCP listens on hal.modbus.host:port (loopback by default) and serves one
client at a time: a second one is accepted and closed at once. RTU serves hal.modbus.device as
unit hal.modbus.unit_id. On exit it prints the last valve voltages it was sent.
)";

int serve(int argc, char** argv) {
  const cli::Args args(argc, argv, 2, {"config", "duration", "reply-delay-s", "delay-after-s"}, {"help", "quiet"}, {"set"});
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
  const auto& mb = cfg.hal.modbus;

  plant::Plant plant(cfg.plant);
  plant::SensorSuite sensors(cfg.sensors);
  const double u_e = plant::equilibrium_voltage_v(plant.valve(), cfg.plant.geometry, cfg.plant.gas.exhaust_pressure_pa);
  plant.reset_at_rest(cfg.simulation.initial_position_m, u_e);
  double u_p = u_e, u_n = -u_e;

  ModbusContext m;
  const bool tcp = mb.transport == config::ModbusTransport::kTcp;
  m.ctx = tcp ? modbus_new_tcp(mb.host.c_str(), mb.port)
              : modbus_new_rtu(mb.device.c_str(), mb.baud, mb.parity, mb.data_bits, mb.stop_bits);
  if (!m.ctx) throw std::runtime_error(std::string("cannot create the Modbus server: ") + modbus_strerror(errno));
  modbus_set_slave(m.ctx, mb.unit_id);
  const int top = std::max({mb.position.address, mb.pressure_p.address, mb.pressure_n.address, mb.valve_p.address,
                            mb.valve_n.address}) + 1;
  m.map = modbus_mapping_new(0, 0, top, top);
  if (!m.map) throw std::runtime_error(std::string("cannot allocate the register map: ") + modbus_strerror(errno));
  uint16_t* sensor_regs = mb.sensor_table == config::SensorTable::kInput ? m.map->tab_input_registers : m.map->tab_registers;
  m.map->tab_registers[mb.valve_p.address] = mb.valve_p.to_word(u_p);
  m.map->tab_registers[mb.valve_n.address] = mb.valve_n.to_word(u_n);

  int listen_fd = -1, client_fd = -1;
  if (tcp) {
    listen_fd = modbus_tcp_listen(m.ctx, 1);
    if (listen_fd < 0)
      throw std::runtime_error("cannot listen on " + mb.host + ":" + std::to_string(mb.port) + ": " + modbus_strerror(errno));
  } else {
    if (modbus_connect(m.ctx) == -1)
      throw std::runtime_error("cannot open " + mb.device + ": " + modbus_strerror(errno));
    client_fd = modbus_get_socket(m.ctx);
  }
  std::signal(SIGINT, on_stop_signal);
  std::signal(SIGTERM, on_stop_signal);
  if (!args.flag("quiet")) {
    if (tcp) std::printf("pneu-plant serve: listening on %s:%d (unit %d)\n", mb.host.c_str(), mb.port, mb.unit_id);
    else std::printf("pneu-plant serve: serving %s at %d baud (unit %d)\n", mb.device.c_str(), mb.baud, mb.unit_id);
    std::fflush(stdout);
  }

  const double t0 = mono_s();
  std::uint64_t requests = 0, refused = 0, clients = 0, foreign = 0;
  uint8_t query[MODBUS_RTU_MAX_ADU_LENGTH > MODBUS_TCP_MAX_ADU_LENGTH ? MODBUS_RTU_MAX_ADU_LENGTH : MODBUS_TCP_MAX_ADU_LENGTH];
  while (!g_stop.load()) {
    const double now = mono_s() - t0;
    if (duration > 0.0 && now >= duration) break;
    // Real time: the plant catches up with the wall clock, the valves held since the last write.
    if (now > plant.state().t_s) plant.step(now - plant.state().t_s, u_p);

    fd_set fds;
    FD_ZERO(&fds);
    int max_fd = -1;
    if (listen_fd >= 0) FD_SET(listen_fd, &fds), max_fd = std::max(max_fd, listen_fd);
    if (client_fd >= 0) FD_SET(client_fd, &fds), max_fd = std::max(max_fd, client_fd);
    timeval tv{0, 500};  // the plant advances at least every 0.5 ms while idle
    const int ready = select(max_fd + 1, &fds, nullptr, nullptr, &tv);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string("select: ") + std::strerror(errno));
    }
    // The present client first: a departed one is noticed before a newcomer is judged.
    if (client_fd >= 0 && FD_ISSET(client_fd, &fds)) {
      const int rc = modbus_receive(m.ctx, query);
      const int unit_at = modbus_get_header_length(m.ctx) - 1;
      if (rc > 0 && query[unit_at] != mb.unit_id && query[unit_at] != 0) {
        ++foreign;  // another unit's request: a real module stays silent, the client times out
      } else if (rc > 0) {
        ++requests;
        const double t = mono_s() - t0;
        if (t > plant.state().t_s) plant.step(t - plant.state().t_s, u_p);
        const auto& s = plant.state();
        const auto v = sensors.read_volts(s.y_m, s.p_p_pa, s.p_n_pa);
        sensor_regs[mb.position.address] = mb.position.to_word(v.y_m);
        sensor_regs[mb.pressure_p.address] = mb.pressure_p.to_word(v.p_p_pa);
        sensor_regs[mb.pressure_n.address] = mb.pressure_n.to_word(v.p_n_pa);
        if (!tcp) {
          // A pty carries bytes at any speed: hold the reply for the time the request and the
          // reply take on a real line at this baud rate (10 bits a byte, 3.5-character silences),
          // so the client meets the timing of the bench's serial link.
          const int fc = query[unit_at + 1];
          const int n_read = fc == 3 || fc == 4 ? (query[unit_at + 4] << 8 | query[unit_at + 5])
                             : fc == 23         ? (query[unit_at + 4] << 8 | query[unit_at + 5])
                                                : 0;
          const int reply_bytes = n_read > 0 ? 5 + 2 * n_read : 8;
          const double wire_s = (rc + reply_bytes + 7) * 10.0 / mb.baud;
          const double until = mono_s() + wire_s;
          while (mono_s() < until) {
            timespec ts{0, 50000};
            nanosleep(&ts, nullptr);
          }
        }
        if (reply_delay > 0.0 && t >= delay_after) {  // fault injection: a module that answers late
          const double until = mono_s() + reply_delay;
          while (mono_s() < until && !g_stop.load()) {
            timespec ts{0, 200000};
            nanosleep(&ts, nullptr);
          }
        }
        modbus_reply(m.ctx, query, rc, m.map);
        u_p = mb.valve_p.to_volts(m.map->tab_registers[mb.valve_p.address]);
        u_n = mb.valve_n.to_volts(m.map->tab_registers[mb.valve_n.address]);
      } else if (rc == -1) {
        if (tcp) {
          ::close(client_fd);
          client_fd = -1;
        }
      }
    }
    if (listen_fd >= 0 && FD_ISSET(listen_fd, &fds)) {
      if (client_fd < 0) {
        client_fd = modbus_tcp_accept(m.ctx, &listen_fd);
        if (client_fd >= 0) ++clients;
      } else {  // one client at a time: refuse cleanly
        const int extra = accept(listen_fd, nullptr, nullptr);
        if (extra >= 0) {
          ::close(extra);
          ++refused;
          std::fprintf(stderr, "pneu-plant serve: refused a second client (one at a time)\n");
        }
      }
    }
  }
  std::printf("pneu-plant serve: stopped after %.3f s; %llu requests from %llu clients, %llu refused, "
              "%llu for other units ignored; last valve voltages: u_P = %+.4f V, u_N = %+.4f V\n",
              mono_s() - t0, static_cast<unsigned long long>(requests), static_cast<unsigned long long>(clients),
              static_cast<unsigned long long>(refused), static_cast<unsigned long long>(foreign), u_p, u_n);
  if (listen_fd >= 0) ::close(listen_fd);
  return cli::kExitOk;
}

}  // namespace pneu::plant_app
