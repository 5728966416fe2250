// The one configuration of a pneu program: YAML loaded once into typed, validated structs, SI units
// in the key names. A bad file is refused with the key path and the reason (ConfigError). Each key
// (its member here, its range, the rules between keys) is described once, in schema.hpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/config/register_map.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/sensors.hpp"

namespace pneu::config {

/// Bad user configuration: `what()` reads "<key.path>: <reason>".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string key_path, const std::string& reason)
      : std::runtime_error(key_path.empty() ? reason : key_path + ": " + reason),
        key_path_(std::move(key_path)) {}
  [[nodiscard]] const std::string& key_path() const noexcept { return key_path_; }

 private:
  std::string key_path_;
};

/// How the open-loop simulator starts (pneu-plant simulate).
struct SimulationConfig {
  double initial_position_m = 0.2195;  ///< simulation.initial_position_m: rest position at t = 0 [m], inside the stroke
};

struct DifferentiatorParams {
  /// Smoothing gain alpha of each first-order low-pass, x += alpha (raw - x) per sample, in (0, 1].
  /// alpha = 1 is the bare backward difference. Pole at z = 1 - alpha: time constant
  /// -T / ln(1 - alpha) (2.8 ms at alpha = 0.3, T = 1 ms), -3 dB bandwidth about
  /// acos(1 - alpha^2 / (2 (1 - alpha))) / (2 pi T) (57 Hz at alpha = 0.3, T = 1 ms).
  double smoothing = 0.3;
};

/// Where the gains of Eq. 4 come from (controller.law.gains).
enum class GainsKind : std::uint8_t {
  kFixed,      ///< "fixed": the three gains of controller.law, the same over the whole stroke
  kScheduled,  ///< "scheduled": designed at start-up at nodes over the stroke (pole placement on
               ///< the tangent-linear model, controller.law.design) and interpolated in position
};

/// What a design does where the requested dynamics cannot be had (controller.law.design.infeasible).
enum class InfeasibleDesign : std::uint8_t {
  kFallBack,  ///< "fall_back": node by node, the nearest feasible dynamics the sampled loop is stable with, reported
  kRefuse,    ///< "refuse": the whole design refused, pneud does not start
};

/// The design of scheduled gains (controller.law.design; pneu-plant tune designs with it too):
/// the requested closed-loop dynamics, the table's node spacing and the largest gains accepted.
struct GainDesignParams {
  double real_pole_1_per_s = 10.0;             ///< alpha: real pole at s = -alpha [1/s], > 0
  double natural_frequency_rad_per_s = 45.0;   ///< omega of the damped pair [rad/s], > 0
  double damping = 0.7;                        ///< zeta of the damped pair [-], > 0
  double node_spacing_m = 0.01;                ///< the table's nodes over the stroke, about this far apart [m]
  double max_position_gain_v_per_m = 1000.0;          ///< a design beyond this K_y is refused [V/m]
  double max_velocity_gain_v_s_per_m = 200.0;         ///< ... K_v [V/(m/s)]
  double max_acceleration_gain_v_s2_per_m = 5.0;      ///< ... K_a [V/(m/s^2)]
  InfeasibleDesign infeasible = InfeasibleDesign::kFallBack;  ///< where the requested dynamics cannot be had
};

struct ControlLawParams {
  GainsKind gains = GainsKind::kFixed;             ///< fixed gains, or scheduled by position
  double position_gain_v_per_m = 80.0;             ///< K_y [V/m]
  double velocity_gain_v_s_per_m = 1.5;            ///< K_v [V/(m/s)]
  double acceleration_gain_v_s2_per_m = 0.002;     ///< K_a [V/(m/s^2)]
  double offset_v = 0.0;                           ///< u_0 [V]: u_e of Eq. 7 unless configured
  double max_voltage_v = 10.0;                     ///< u_max: saturation [V], > 0
  GainDesignParams design;                         ///< controller.law.design (optional section)
};

/// The key's value: "fixed" or "scheduled".
[[nodiscard]] const char* to_string(GainsKind g) noexcept;

struct StopDetectorParams {
  /// Positions within this band of the first still sample count as "not moving" [m], >= 0.
  /// 0 suits ideal sensors (a stuck carriage reads the same position bit for bit); with noise or
  /// quantisation use a few standard deviations / one LSB.
  double rest_band_m = 0.0;
  /// Leaving rest: the position must move more than this from the stop position [m], > rest band.
  double motion_band_m = 1.0e-6;
  /// A stop is confirmed once the position stays within the rest band this long [s], > 0.
  double hold_s = 0.005;
};

/// Where the linearized restart predictor takes each chamber's flow slope C_p of Eq. 23 (its time
/// constant tau = V(y*) / (k r T C_p)), controller.predictor.linearized_slope. Every choice relaxes
/// each pressure exponentially from its stop value to p_null(+-u*) (Eq. 24) and keeps Eq.
/// 16/17/25; only tau differs.
enum class LinearizedSlope : std::uint8_t {
  kStopTangent,         ///< "stop": -dq/dp at the stop pressure, the paper's Eq. 23 (default)
  kChord,               ///< "chord": q(p_stop) / (p_null - p_stop), the secant from the stop
                        ///< pressure to the null-flow pressure: the forecast starts at the model's
                        ///< own rate dp/dt and ends where the model does
  kEquilibriumTangent,  ///< "equilibrium": -dq/dp at the null-flow pressure p_null(+-u*)
};

/// The key's value: "stop", "chord" or "equilibrium".
[[nodiscard]] const char* to_string(LinearizedSlope s) noexcept;

/// Which predictors run at each stop, and with which valve characteristic.
struct PredictorConfig {
  bool linearized = true;           ///< controller.predictor.methods holds "linearized"
  bool nonlinear = true;            ///< controller.predictor.methods holds "nonlinear"
  /// controller.predictor.methods holds "relaxation": while stuck, forecasts also from each
  /// chamber's relaxation fitted to the phase's own pressures (no valve model; needs
  /// update_period_s > 0)
  bool relaxation = false;
  std::string valve_table;          ///< table from `pneu-plant characterize-valve`; empty: the model
  double horizon_s = 600.0;         ///< the nonlinear method stops looking this long after a stop [s]
  LinearizedSlope linearized_slope = LinearizedSlope::kStopTangent;  ///< optional key
  /// While stuck, the forecasts are made again from the pressures of the moment this often
  /// (0: only at the stop) [s].
  double update_period_s = 0.1;
  /// Online identification: at each stop after a breakaway, the bench identified again from the
  /// last minute of the run's own signals, and the forecasts made on the running estimate
  /// (stiction, the valves' conductances and null offset, the dead volumes).
  bool learn_online = false;
  /// controller.predictor.model_fit (optional section, written by pneud --identify): how well
  /// plant: fitted the bench's stuck-phase pressures when it was identified. A residual beyond
  /// twice what the sensors' noise explains marks every forecast made on it uncertain.
  bool has_model_fit = false;
  struct ModelFit {
    double pressure_residual_pa = 0.0;   ///< the fit's residual, both chambers, rms [Pa]
    double pressure_explained_pa = 10.0; ///< what the sensors' noise explains of it [Pa]
    /// The residual is within twice what the noise explains.
    [[nodiscard]] bool fits() const noexcept { return pressure_residual_pa <= 2.0 * pressure_explained_pa; }
  } model_fit;
};

/// controller.hold: the in-position hold. Once the carriage is at rest within `window_m` of its
/// set point, pneud stops driving Eq. 4 and drives the pressure force, measured, to the middle of
/// the stiction band (plant.friction), so that the stuck carriage cannot break away; a set-point
/// change, the carriage leaving the window or moving at all, a fault or a disarm hand back.
struct HoldConfig {
  bool enabled = false;
  double window_m = 5.0e-4;                ///< at rest this close to the set point: hold [m]
  /// u = u* + force_gain (F_ref - F) + integral_gain * integral of (F_ref - F) [V/N], [V/(N s)]
  double force_gain_v_per_n = 0.01;
  double integral_gain_v_per_n_s = 0.1;
  /// F_ref goes from the force at the hold's start to the band's middle over this long [s]
  double ramp_s = 0.3;
  /// Reaching the window: a carriage at rest outside the window but within this of its set point
  /// is made to break away towards it, the force ramped (reach_rate_n_per_s) until it moves, then
  /// Eq. 4 again; 0: off [m]
  double reach_m = 0.0;
  double reach_rate_n_per_s = 2000.0;  ///< [N/s]
  /// The reach's ramp starts at this share of the stiction bound it must cross (plant.friction),
  /// or at the force if that is past it already: the band crossed at once, the ramp's slow part
  /// spent near the breakaway [-]
  double reach_preload = 0.7;
};

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

/// One step of the set-point schedule.
struct SetpointStep {
  double t_s = 0.0;                 ///< from this time on [s], increasing
  double position_m = 0.0;          ///< the set point y_d [m], inside the stroke
};

enum class ClockKind { kSimulated, kReal };

/// What the valves are driven to while a fault is latched (controller.supervisor.safe_output).
enum class SafeOutput {
  kNeutral,  ///< "neutral": both valves at the neutral voltage u_0 (u_P = u_0, u_N = -u_0): the
             ///< chambers hold their pressures and the carriage its position
  kExhaust,  ///< "exhaust": both valves at -u_max: both chambers vent, the cylinder goes limp
};

/// The supervisor's fault checks (controller.supervisor.*). A check set to 0 is off.
struct SupervisorConfig {
  /// The most sign changes the oscillation check can count (its history is fixed-size).
  static constexpr std::uint32_t kMaxOscillationSignChanges = 64;

  double position_min_m = -0.255;   ///< a position reading below is out of range [m]
  double position_max_m = 0.255;    ///< ... above [m]
  double pressure_min_pa = 2.0e4;   ///< a pressure reading below is out of range [Pa abs]
  double pressure_max_pa = 9.9e5;   ///< ... above [Pa abs]
  /// Two successive samples further apart than this speed allows: the position sensor jumped
  /// (a broken wiper, a rail) [m/s]; 0 = off.
  double max_speed_m_per_s = 5.0;
  /// A pressure reading unchanged bit for bit this long: the sensor or its converter is frozen
  /// [s]; 0 = off (ideal noiseless sensors legitimately repeat themselves).
  double frozen_after_s = 0.0;
  /// Armed, the position may pass the soft limits (which bound the set points) by this much, an
  /// overshoot, before it is a fault [m].
  double overtravel_m = 0.008;
  double following_error_m = 0.01;  ///< |y_d - y| above this ... [m]
  double following_error_s = 2.0;   ///< ... for longer than this while armed latches a fault [s]; 0 = off
  /// Oscillation: armed, the position error y_d - y swings from beyond +oscillation_amplitude_m
  /// to beyond -oscillation_amplitude_m (or back) oscillation_sign_changes times within
  /// oscillation_window_s. The band is the hysteresis: noise around zero error changes no sign.
  double oscillation_amplitude_m = 0.01;  ///< each half-swing exceeds this |y_d - y| [m]
  std::uint32_t oscillation_sign_changes = 4;  ///< this many sign changes ... ; 0 = off
  double oscillation_window_s = 2.0;      ///< ... within this long latch a fault [s]
  /// Armed, no rest (the stop detector holding the carriage) within this long after a change of
  /// the set point latches a fault [s]; 0 = off.
  double settle_time_s = 3.0;
  std::uint32_t overruns_in_a_row = 10;  ///< this many overrunning ticks in a row latch a fault; 0 = off
  double max_tick_interval_s = 0.05;     ///< one tick interval longer than this latches a fault [s]; 0 = off
  SafeOutput safe_output = SafeOutput::kNeutral;
};

/// Real-time set-up of the loop thread (controller.realtime.*), real clock only.
struct RealtimeConfig {
  int priority = 0;           ///< SCHED_FIFO priority of the loop thread, 1..99; 0 = normal scheduling
  int cpu = -1;               ///< pin the loop thread to this CPU; -1 = no pinning
  bool lock_memory = false;   ///< mlockall(MCL_CURRENT | MCL_FUTURE) and a pre-faulted stack
};

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

/// LCM telemetry (state, events, predictions, health).
struct TelemetryConfig {
  bool enabled = true;
  std::string lcm_url = "udpm://239.255.76.67:7667?ttl=0";  ///< ttl=0: nothing leaves the host
  std::string channel_prefix = "PNEU_";   ///< channels: <prefix>STATE, EVENT, PREDICTION, HEALTH
  double health_period_s = 1.0;           ///< health message period [s]
  /// Publish also when the loop runs on the simulated clock (a 12 s run then floods the network
  /// with 12,000 states in a few tens of milliseconds and runs 5x slower).
  bool in_simulated_time = false;
};

/// Inbound commands on <prefix>COMMAND (real clock only).
struct CommandsConfig {
  bool enabled = true;
  double max_rate_hz = 20.0;   ///< sustained command rate accepted [1/s]; above it: rejected
  double burst = 5.0;          ///< commands accepted back to back before the rate applies
  /// A command stamped (utime) further than this from this host's clock, past or future, is
  /// refused as stale or replayed [s].
  double max_age_s = 0.5;
  /// Largest set-point change one command may make [m] (rate of change of the set point).
  double max_setpoint_step_m = 0.5;
  /// With a set-point stream configured (> 0): armed, no set point for this long latches a
  /// fault [s]; 0 = set points come when they come.
  double setpoint_stream_timeout_s = 0.0;
};

/// Digital lines beside either backend (hal.gpio.*, libgpiod).
struct GpioConfig {
  bool enabled = false;
  std::string chip = "gpiochip0";       ///< name, /dev path, label or number
  unsigned estop_line = 0;              ///< e-stop input line offset
  bool estop_active_low = true;         ///< pressed = electrically low (a broken wire reads pressed)
  unsigned valve_power_line = 1;        ///< valve power-enable output line offset
  bool valve_power_active_low = false;  ///< power on = electrically low
  std::string consumer = "pneud";       ///< consumer name shown by gpioinfo
};

enum class BackendKind { kSim, kModbus };

/// hal.sim: the simulated bench (in process, and pneu-plant serve and simulate).
struct SimBenchConfig {
  /// hal.sim.plant present: the simulated bench is not the controller's model. Any subset of
  /// plant:'s keys, each over plant:'s value.
  bool has_plant = false;
  model::PlantParams plant;  ///< the bench: plant: with hal.sim.plant's keys over it
  /// hal.sim.pushes: external forces on the carriage (the simulated bench's disturbance input), on
  /// the loop's time in process, on pneu-plant serve's own (from its start) over Modbus.
  std::vector<model::Push> pushes;
};

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
