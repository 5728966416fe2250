// The one configuration of a pneu program: YAML loaded once into typed, validated structs, SI units
// in the key names. A bad file is refused with the key path and the reason (ConfigError). Each key
// (its member, its range, the rules between keys) is described once: in its component's params
// header, which this root aggregates, or in schema.hpp. Only programs and the assembly of a run
// include this header: no public header of a component does (tests/test_public_headers.py).
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/config/describe.hpp"
#include "pneu/controller/clock_params.hpp"
#include "pneu/controller/differentiator_params.hpp"
#include "pneu/controller/hold_params.hpp"
#include "pneu/controller/law_params.hpp"
#include "pneu/controller/movement_test_params.hpp"
#include "pneu/controller/predictor_params.hpp"
#include "pneu/controller/realtime_params.hpp"
#include "pneu/controller/setpoint_params.hpp"
#include "pneu/controller/stop_detector_params.hpp"
#include "pneu/controller/supervisor_params.hpp"
#include "pneu/hal/gpio_params.hpp"
#include "pneu/hal/modbus_params.hpp"
#include "pneu/hal/register_map.hpp"
#include "pneu/hal/sim_params.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/sensors.hpp"
#include "pneu/telemetry/commands_params.hpp"
#include "pneu/telemetry/telemetry_params.hpp"

namespace pneu::config {

// The components' parameters (each with its describe(), beside the component): the sections of
// controller: this configuration aggregates, under the names code written against it uses.
using controller::ClockKind;
using controller::ControlLawParams;
using controller::DifferentiatorParams;
using controller::GainDesignParams;
using controller::GainsKind;
using controller::HoldConfig;
using controller::InfeasibleDesign;
using controller::LinearizedSlope;
using controller::MovementTestConfig;
using controller::PredictorConfig;
using controller::RealtimeConfig;
using controller::SafeOutput;
using controller::SetpointStep;
using controller::StopDetectorParams;
using controller::SupervisorConfig;
using controller::to_string;

// The HAL's backends' parameters (hal/params: hal.modbus and its register map, hal.gpio, hal.sim,
// simulation) and telemetry's (controller/telemetry/params: telemetry, commands).
using hal::GpioConfig;
using hal::ModbusConfig;
using hal::ModbusTransport;
using hal::RegisterChannel;
using hal::RegisterFormat;
using hal::SensorTable;
using hal::SimBenchConfig;
using hal::SimulationConfig;
using telemetry::CommandsConfig;
using telemetry::TelemetryConfig;

/// pneud's loop and control.
struct ControllerConfig {
  double rate_hz = 1000.0;          ///< loop rate [Hz]
  ClockKind clock = ClockKind::kSimulated;  ///< simulated: lockstep with the in-process plant
  double duration_s = 12.0;         ///< run length [s]; 0 = until SIGINT/SIGTERM (real clock)
  bool offset_auto = true;          ///< u_0 = u_e of Eq. 7 (law.offset_v is then computed)
  ControlLawParams law;
  DifferentiatorParams differentiator;
  StopDetectorParams stop_detector;
  PredictorConfig predictor;
  HoldConfig hold;                      ///< controller.hold.* (optional section: absent, off)
  MovementTestConfig movement_test;     ///< controller.movement_test.* (optional section: absent, on)
  double initial_setpoint_m = 0.2195;   ///< set point before the first schedule step [m]
  std::vector<SetpointStep> schedule;   ///< set-point steps, time increasing
  double soft_limit_min_m = -0.24;      ///< set points (and, later, positions) below are refused [m]
  double soft_limit_max_m = 0.24;       ///< ... and above [m]
  bool start_armed = true;              ///< armed at start-up (else disarmed until an ARM command)
  /// Reads that are not ok (stale sample, lost link) for this long in a row latch a comms fault [s].
  double comms_fault_after_s = 0.05;
  SupervisorConfig supervisor;          ///< controller.supervisor.*
  RealtimeConfig realtime;              ///< controller.realtime.*

  [[nodiscard]] double period_s() const noexcept { return 1.0 / rate_hz; }
};

enum class BackendKind { kSim, kModbus };

/// The hardware abstraction layer: which backend pneud drives.
struct HalConfig {
  BackendKind backend = BackendKind::kSim;  ///< hal.backend: "sim" (in-process plant) or "modbus"
  bool has_modbus = false;                  ///< hal.modbus present (required by the modbus backend
                                            ///< and by pneu-plant serve)
  ModbusConfig modbus;
  GpioConfig gpio;                          ///< hal.gpio (optional section; absent: disabled)
  /// hal.sim present (code that gives a configuration a bench or pushes of its own sets it, so
  /// that the configuration is written with them)
  bool has_sim = false;
  SimBenchConfig sim;                       ///< hal.sim (optional section)
};

struct Config;
/// The simulated bench's parameters: hal.sim.plant when given, else plant: (the bench is its model).
[[nodiscard]] const model::PlantParams& simulated_bench(const Config& config) noexcept;

/// The whole configuration.
struct Config {
  model::PlantParams plant;          ///< plant.*
  model::SensorParams sensors;       ///< sensors.*
  SimulationConfig simulation;       ///< simulation.*
  ControllerConfig controller;       ///< controller.*
  HalConfig hal;                     ///< hal.*
  TelemetryConfig telemetry;         ///< telemetry.*
  CommandsConfig commands;           ///< commands.*
};

/// Loads and validates a YAML file. `overrides` are "dotted.key.path=value" strings applied
/// before validation; an override naming a key the schema does not know is an error.
/// Throws ConfigError.
[[nodiscard]] Config load_file(const std::filesystem::path& path,
                               const std::vector<std::string>& overrides = {});
/// Same, from YAML text (`origin` names it in messages).
[[nodiscard]] Config load_string(std::string_view yaml, const std::vector<std::string>& overrides = {},
                                 std::string_view origin = "<string>");
/// The default bench (config/sim.yaml), embedded at build time.
[[nodiscard]] std::string_view default_config_yaml() noexcept;
/// Loads `path`, or the embedded default when `path` is empty.
[[nodiscard]] Config load_file_or_default(const std::filesystem::path& path,
                                          const std::vector<std::string>& overrides = {});

/// The effective configuration as YAML, loadable by load_string().
[[nodiscard]] std::string to_yaml(const Config& config);

}  // namespace pneu::config
