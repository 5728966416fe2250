// The parameters of the modbus backend and of the HIL plant server that plays its module
// (hal.modbus): the link (TCP or RTU), its timing, and the register map (register_map.hpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>

#include "pneu/config/describe.hpp"
#include "pneu/hal/register_map.hpp"

namespace pneu::hal {

enum class ModbusTransport { kTcp, kRtu };
enum class SensorTable { kHolding, kInput };  ///< where the sensor registers sit

/// The modbus backend and the HIL server (hal.modbus.*).
struct ModbusConfig {
  ModbusTransport transport = ModbusTransport::kTcp;
  std::string host = "127.0.0.1";        ///< TCP: module address (the HIL server listens on it)
  int port = 1502;                       ///< TCP port
  std::string device = "/dev/ttyUSB0";   ///< RTU: serial device
  int baud = 115200;                     ///< RTU
  char parity = 'N';                     ///< RTU: 'N', 'E' or 'O'
  int data_bits = 8;                     ///< RTU
  int stop_bits = 1;                     ///< RTU
  int unit_id = 1;                       ///< slave / unit identifier, 1..247
  double response_timeout_s = 0.02;      ///< a transaction not answered by then is a comms error
  double max_sample_age_s = 0.02;        ///< the loop flags a sample older than this as stale
  double min_exchange_period_s = 0.001;  ///< the I/O thread exchanges at most this often
  bool read_write_multiple = true;       ///< one FC23 transaction per cycle (sensors in holding registers)
  SensorTable sensor_table = SensorTable::kHolding;  ///< FC3/FC23 (holding) or FC4 (input)
  double reconnect_min_s = 0.05;         ///< back-off after a failure, doubling up to ...
  double reconnect_max_s = 2.0;          ///< ... this
  /// The module's fieldbus watchdog that the controller expects [s]: the bench's coupler must set
  /// its outputs to their safe values when no request came for this long (pneu-plant serve's
  /// default --watchdog-s). 0: none stated.
  double module_watchdog_s = 0.0;
  RegisterChannel position, pressure_p, pressure_n;  ///< sensors
  RegisterChannel valve_p, valve_n;                  ///< outputs (holding registers, FC16/FC23)
};

}  // namespace pneu::hal

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using hal::ModbusConfig;
using hal::ModbusTransport;
using hal::SensorTable;

inline constexpr Choice<ModbusTransport> kTransports[] = {{"tcp", ModbusTransport::kTcp},
                                                          {"rtu", ModbusTransport::kRtu}};
inline constexpr Choice<char> kParities[] = {{"none", 'N'}, {"even", 'E'}, {"odd", 'O'}};
inline constexpr Choice<SensorTable> kSensorTables[] = {{"holding", SensorTable::kHolding},
                                                        {"input", SensorTable::kInput}};

void describe(auto& a, Like<ModbusConfig> auto& m) {
  a.field(PNEU_NVP(m, transport), one_of(kTransports), "tcp | rtu");
  a.field(optional(PNEU_NVP(m, host)), "TCP: the module's address");
  a.field(optional(PNEU_NVP(m, port)), IntRange::in(1, 65535), "TCP port");
  a.field(optional(PNEU_NVP(m, device)), "RTU: serial device");
  a.field(optional(PNEU_NVP(m, baud)), IntRange::in(300, 4000000), "RTU: bits per second");
  a.field(optional(PNEU_NVP(m, parity)), one_of(kParities).unquoted(), "RTU: none | even | odd");
  a.field(optional(PNEU_NVP(m, data_bits)), IntRange::in(5, 8), "RTU");
  a.field(optional(PNEU_NVP(m, stop_bits)), IntRange::in(1, 2).says("must be 1 or 2"), "RTU");
  a.field(PNEU_NVP(m, unit_id), IntRange::in(1, 247), "Modbus unit (slave) identifier");
  a.field(PNEU_NVP(m, response_timeout_s), Range::closed(1e-4, 10.0), "a later answer is a comms error [s]");
  a.field(PNEU_NVP(m, max_sample_age_s), Range::closed(1e-4, 10.0), "older samples are stale [s]");
  a.field(PNEU_NVP(m, min_exchange_period_s), Range::closed(0.0, 1.0),
          "the I/O thread exchanges at most this often [s]");
  a.field(PNEU_NVP(m, read_write_multiple), "one function-23 transaction per cycle");
  a.field(PNEU_NVP(m, sensor_table), one_of(kSensorTables), "holding (FC3/FC23) | input (FC4)");
  a.check("read_write_multiple", !(m.read_write_multiple && m.sensor_table == SensorTable::kInput),
          "function 23 reads holding registers: with sensor_table input, set read_write_multiple false");
  a.field(PNEU_NVP(m, reconnect_min_s), Range::closed(1e-3, 60.0), "back-off after a failure [s]");
  a.field(PNEU_NVP(m, reconnect_max_s), Range::any(), "... doubling up to this [s]");
  a.check("reconnect_max_s", m.reconnect_max_s >= m.reconnect_min_s && m.reconnect_max_s <= 600.0, [&] {
    return "must be in [" + fmt(m.reconnect_min_s) + ", 600] (got " + fmt(m.reconnect_max_s) + ")";
  });
  a.field(optional(PNEU_NVP(m, module_watchdog_s)), Range::closed(0.0, 600.0),
          "the module's fieldbus watchdog the bench's coupler is set to [s]; 0: none");
  a.group("channels", [&](auto& ch) {
    ch.section(flow(PNEU_NVP(m, position)), true);
    ch.section(flow(PNEU_NVP(m, pressure_p)), true);
    ch.section(flow(PNEU_NVP(m, pressure_n)), true);
    ch.section(flow(PNEU_NVP(m, valve_p)), false);
    ch.section(flow(PNEU_NVP(m, valve_n)), false);
    // One register holds one channel: no overlaps within a table (the valves are holding
    // registers; the sensors are too unless sensor_table is input). A float32 channel holds two.
    struct Named {
      const char* name;
      const RegisterChannel* c;
      bool holding;
    };
    const bool sensors_holding = m.sensor_table == SensorTable::kHolding;
    const Named all[] = {{"position", &m.position, sensors_holding},
                         {"pressure_p", &m.pressure_p, sensors_holding},
                         {"pressure_n", &m.pressure_n, sensors_holding},
                         {"valve_p", &m.valve_p, true},
                         {"valve_n", &m.valve_n, true}};
    for (std::size_t i = 0; i < 5; ++i)
      for (std::size_t j = i + 1; j < 5; ++j) {
        const RegisterChannel &x = *all[i].c, &y = *all[j].c;
        const int shared = std::max(x.address, y.address);  // the first register both hold, if any
        ch.check(std::string(all[j].name) + ".register",
                 !(all[i].holding == all[j].holding && shared <= std::min(x.last_address(), y.last_address())),
                 [&] {
                   return "overlaps " + std::string(all[i].name) + " (both at register " +
                          std::to_string(shared) + ")";
                 });
      }
    ch.check("valve_n.register", !m.read_write_multiple || std::abs(m.valve_p.address - m.valve_n.address) == 1,
             "function 23 writes one block: valve_p and valve_n must be adjacent registers");
    const int lo = std::min({m.position.address, m.pressure_p.address, m.pressure_n.address});
    const int hi = std::max({m.position.last_address(), m.pressure_p.last_address(), m.pressure_n.last_address()});
    ch.check("pressure_n.register", hi - lo < 121,
             "the sensor registers must lie within 121 consecutive registers (one read transaction)");
  });
}

}  // namespace pneu::config::schema
