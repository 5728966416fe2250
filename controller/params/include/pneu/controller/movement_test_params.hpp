// The parameters of the movement test (controller.movement_test).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

/// controller.movement_test: before closed loop on a real backend (hal.backend modbus), small
/// open-loop pulses around u_0 check that +u moves the carriage towards +y and raises p_P (and
/// lowers p_N), and that each sensor responds; swapped tubes, swapped pressure channels, a reversed
/// or dead position sensor or a dead pressure sensor stop the start with the finding.
struct MovementTestConfig {
  bool enabled = true;                 ///< run it before closed loop on hal.backend modbus
  double pulse_v = 1.5;                ///< each pulse drives u = u_0 +- this [V]
  double travel_m = 0.002;             ///< a pulse ends once the carriage moved this far [m]
  double pulse_s = 0.2;                ///< ... or after this long [s]
  double rest_s = 0.3;                 ///< u_0 after each pulse, the carriage coming to rest [s]
  double min_pressure_change_pa = 5000.0;  ///< a chamber's reading must change this much in a pulse [Pa]
};

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::MovementTestConfig;

void describe(auto& a, Like<MovementTestConfig> auto& m) {
  a.field(optional(PNEU_NVP(m, enabled)), "true: the movement test before closed loop on hal.backend modbus");
  a.field(optional(PNEU_NVP(m, pulse_v)), Range::positive(), "each pulse drives u = u_0 +- this [V]");
  a.field(optional(PNEU_NVP(m, travel_m)), Range::positive(), "a pulse ends once the carriage moved this far [m]");
  a.field(optional(PNEU_NVP(m, pulse_s)), Range::positive(), "... or after this long [s]");
  a.field(optional(PNEU_NVP(m, rest_s)), Range::non_negative(), "u_0 after each pulse [s]");
  a.field(optional(PNEU_NVP(m, min_pressure_change_pa)), Range::positive(),
          "a chamber's reading must change this much in a pulse [Pa]");
}

}  // namespace pneu::config::schema
