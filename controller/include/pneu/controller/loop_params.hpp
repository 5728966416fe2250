// What the loop and its supervisor know of the configuration, held by value: built once from the
// Config off the loop thread, so that the loop keeps no reference into it (it may be moved, and
// the Config may go).
#pragma once

#include <stdexcept>

#include "pneu/config/config.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/model/params.hpp"

namespace pneu::controller {

/// Whether the loop runs the movement test (controller.movement_test) at the first ARM of the run:
/// on hal.backend modbus (a bench, or pneu-plant serve) with the test enabled, when the run starts
/// disarmed. (Starting armed, it runs before the loop's time starts instead: movement_test_runs(),
/// session.hpp. The in-process plant cannot be miswired: never there.)
[[nodiscard]] inline bool movement_test_at_first_arm(const config::Config& config) noexcept {
  return config.hal.backend == config::BackendKind::kModbus && config.controller.movement_test.enabled &&
         !config.controller.start_armed;
}

struct LoopParams {
  config::ControllerConfig controller;     ///< controller.*; law.offset_v must hold u_0 (resolve_offset())
  double setpoint_stream_timeout_s = 0.0;  ///< commands.setpoint_stream_timeout_s
  model::Geometry geometry;                ///< plant.geometry: the areas of Eq. 14 and the end stops
  double exhaust_pressure_pa = 0.0;        ///< plant.gas.exhaust_pressure_pa: p_E of Eq. 14
  model::FrictionParams friction;          ///< plant.friction: the stiction band the hold aims into
  /// The law of Eq. 4 the loop runs, its gain table designed already when scheduled
  /// (make_control_law(), session.hpp).
  ControlLaw law{controller.law};
  /// The first ARM runs the movement test before the law drives (movement_test_at_first_arm()).
  bool movement_test_at_arm = false;

  /// The loop's parameters in `config`, running `law`.
  [[nodiscard]] static LoopParams from(const config::Config& config, const ControlLaw& law) {
    return {config.controller, config.commands.setpoint_stream_timeout_s, config.plant.geometry,
            config.plant.gas.exhaust_pressure_pa, config.plant.friction, law, movement_test_at_first_arm(config)};
  }
  /// ... with the fixed gains of controller.law; a scheduled law needs its table (the overload
  /// above): refused (std::invalid_argument).
  [[nodiscard]] static LoopParams from(const config::Config& config) {
    if (config.controller.law.gains != config::GainsKind::kFixed)
      throw std::invalid_argument("LoopParams::from: a scheduled law needs its designed table (make_control_law)");
    return from(config, ControlLaw(config.controller.law));
  }
};

}  // namespace pneu::controller
