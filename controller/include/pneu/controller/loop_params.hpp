// What the loop and its supervisor know of the configuration, held by value and fixed-size (no
// string, no vector: the loop thread never allocates): built once off the loop thread, so that
// the loop keeps no reference into the configuration (it may be moved, and the configuration go).
#pragma once

#include <array>
#include <cstddef>
#include <span>

#include "pneu/controller/control_law.hpp"
#include "pneu/controller/differentiator_params.hpp"
#include "pneu/controller/hold_params.hpp"
#include "pneu/controller/law_params.hpp"
#include "pneu/controller/movement_test_params.hpp"
#include "pneu/controller/setpoint_params.hpp"
#include "pneu/controller/stop_detector_params.hpp"
#include "pneu/controller/supervisor_params.hpp"
#include "pneu/model/params.hpp"

namespace pneu::config {
struct Config;
}

namespace pneu::controller {

/// Whether the loop runs the movement test (controller.movement_test) at the first ARM of the run:
/// on hal.backend modbus (a bench, or pneu-plant serve) with the test enabled, when the run starts
/// disarmed. (Starting armed, it runs before the loop's time starts instead: movement_test_runs(),
/// session.hpp. The in-process plant cannot be miswired: never there.)
[[nodiscard]] bool movement_test_at_first_arm(const config::Config& config) noexcept;

/// The loop's part of controller.*, under the keys' names.
struct LoopSettings {
  double rate_hz = 1000.0;              ///< controller.rate_hz [Hz]
  ControlLawParams law;                 ///< controller.law; law.offset_v must hold u_0 (assembly::RunSpec)
  DifferentiatorParams differentiator;  ///< controller.differentiator
  StopDetectorParams stop_detector;     ///< controller.stop_detector
  HoldConfig hold;                      ///< controller.hold
  MovementTestConfig movement_test;     ///< controller.movement_test
  double initial_setpoint_m = 0.0;      ///< controller.setpoints.initial_m [m]
  std::array<SetpointStep, kMaxScheduleSteps> schedule_steps{};  ///< controller.setpoints.schedule ...
  std::size_t schedule_size = 0;                                  ///< ... its first schedule_size
  double soft_limit_min_m = -0.24;      ///< controller.soft_limit_min_m [m]
  double soft_limit_max_m = 0.24;       ///< controller.soft_limit_max_m [m]
  bool start_armed = true;              ///< controller.start_armed
  double comms_fault_after_s = 0.05;    ///< controller.comms_fault_after_s [s]
  SupervisorConfig supervisor;          ///< controller.supervisor

  [[nodiscard]] double period_s() const noexcept { return 1.0 / rate_hz; }
  [[nodiscard]] std::span<const SetpointStep> schedule() const noexcept { return {schedule_steps.data(), schedule_size}; }
};

struct LoopParams {
  LoopSettings controller;                 ///< controller.*, what the loop uses of it
  double setpoint_stream_timeout_s = 0.0;  ///< commands.setpoint_stream_timeout_s
  model::Geometry geometry;                ///< plant.geometry: the areas of Eq. 14 and the end stops
  double exhaust_pressure_pa = 0.0;        ///< plant.gas.exhaust_pressure_pa: p_E of Eq. 14
  model::FrictionParams friction;          ///< plant.friction: the stiction band the hold aims into
  /// The law of Eq. 4 the loop runs, its gain table designed already when scheduled
  /// (make_control_law(), session.hpp).
  ControlLaw law{controller.law};
  /// The first ARM runs the movement test before the law drives (movement_test_at_first_arm()).
  bool movement_test_at_arm = false;

  /// The loop's parameters in `config`, running `law` (session.cpp).
  [[nodiscard]] static LoopParams from(const config::Config& config, const ControlLaw& law);
  /// ... with the fixed gains of controller.law; a scheduled law needs its table (the overload
  /// above): refused (std::invalid_argument).
  [[nodiscard]] static LoopParams from(const config::Config& config);
};

}  // namespace pneu::controller
