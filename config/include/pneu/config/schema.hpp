// The configuration schema: every key of the YAML described once, in the struct it fills: its
// name, the member, the values it accepts and one line of documentation, with the rules between
// keys. Everything else is derived from these descriptions by walking them with an archive, as
// Drake's Serialize(Archive*) visitors do:
//   - reading and validating (load_string, config.cpp): unknown, repeated, missing keys, wrong
//     types, ranges, the rules below, each refused with the key path and the reason;
//   - writing back (to_yaml, `--check-config`), in the order of the descriptions;
//   - comparing (values_of: every value by its key path);
//   - the key catalogue behind "unknown key; did you mean ...?" and the keys of a configuration
//     (keys_of: the hostile-input matrix of tests/test_config_hostile.cpp).
//
// A component owns its parameters: its struct and its describe() live beside it, in its params
// header, with the vocabulary of pneu/config/describe.hpp:
//   controller/params/include/pneu/controller/*_params.hpp   the law, differentiator, stop
//       detector, predictor, hold, movement test, supervisor, real-time set-up, clock, set points
//   hal/params/include/pneu/hal/   hal.modbus (modbus_params.hpp, its channels in register_map.hpp),
//       hal.gpio (gpio_params.hpp), hal.sim and simulation (sim_params.hpp)
//   controller/telemetry/params/include/pneu/telemetry/   telemetry, commands
// The root configuration (config.hpp) aggregates them, and this file describes what is left
// (plant:, sensors:, the controller: and hal: sections' own keys) and the rules across sections.
//
// Adding a key: its member, with its default, in its struct; one line in that struct's describe()
// (here or in the component's params header); its documented line in the shipped configurations
// (config/*.yaml: the comment is the documentation users read, and docs/configuration.md is
// generated from it).
//
// A description is a function template `describe(a, object, context...)` run by every archive
// `a` over a const (writing, listing) or mutable (reading) object, top to bottom: a rule (check)
// may use any key described above it, which the reader has read by then. Its vocabulary:
//   a.field(PNEU_NVP(s, member), range, doc)     a number (Range), an integer (IntRange), an enum
//                                                (Choices), a bool or a string (no range)
//   a.number_or_auto(PNEU_NVP(s, member), is_auto, doc)   a number, or the word `auto`
//   a.flags("key", s, flags, doc)                a list of names, each setting a bool of s
//   a.section(PNEU_NVP(s, member), context...)   a mapping: describe(a, s.member, context...)
//   a.optional_section(PNEU_NVP(s, member), present)      ... that may be left out
//   a.group("key", [&](auto& a) { ... })         a mapping of the YAML with no struct of its own
//   a.list(PNEU_NVP(s, member), context...)      a list of mappings, each described by describe()
//   a.check("relative.path", ok, reason)         a rule: refused at the path unless `ok`
// PNEU_NVP names the key after its member, so that a key is spelled once; a key is required
// unless wrapped: optional(...), required_when(condition, ..., why), meaningful_when(condition,
// ...) (otherwise accepted and type-checked but neither kept nor written); flow(...) writes a
// mapping on one line.
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <concepts>
#include <cstdio>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/config/describe.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/sensors.hpp"
#include "pneu/model/tangent_linear.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::config::schema {

// ---------------------------------------------------------------------------------------------
// The names of enum-valued keys

inline constexpr Choice<BackendKind> kBackends[] = {{"sim", BackendKind::kSim}, {"modbus", BackendKind::kModbus}};

// ---------------------------------------------------------------------------------------------
// plant.*: the bench as the controller models it (docs/model.md)

void describe(auto& a, Like<model::Geometry> auto& g) {
  a.field(PNEU_NVP(g, stroke_m), Range::positive(), "L: full stroke [m]; y runs over [-L/2, +L/2]");
  a.field(PNEU_NVP(g, bore_diameter_m), Range::positive(), "piston diameter [m]");
  a.field(PNEU_NVP(g, rod_diameter_m), Range::positive(), "rod diameter [m], < bore");
  a.check("rod_diameter_m", g.rod_diameter_m < g.bore_diameter_m, [&] {
    return "must be smaller than geometry.bore_diameter_m (" + fmt(g.rod_diameter_m) + " >= " +
           fmt(g.bore_diameter_m) + ")";
  });
  a.field(PNEU_NVP(g, dead_volume_p_m3), Range::positive(), "V_P0: chamber P volume at y = -L/2 [m^3]");
  a.field(PNEU_NVP(g, dead_volume_n_m3), Range::positive(), "V_N0: chamber N volume at y = +L/2 [m^3]");
}

void describe(auto& a, Like<model::Gas> auto& g) {
  a.field(PNEU_NVP(g, supply_pressure_pa), Range::positive(), "p_S: supply pressure [Pa abs], > p_E");
  a.field(PNEU_NVP(g, exhaust_pressure_pa), Range::positive(), "p_E: exhaust pressure [Pa abs]");
  a.check("supply_pressure_pa", g.supply_pressure_pa > g.exhaust_pressure_pa, [&] {
    return "must exceed gas.exhaust_pressure_pa (" + fmt(g.supply_pressure_pa) + " <= " +
           fmt(g.exhaust_pressure_pa) + ")";
  });
  a.field(PNEU_NVP(g, polytropic_index), Range::closed(1.0, 1.4), "k: polytropic index [-]");
  a.field(PNEU_NVP(g, gas_constant_j_per_kg_k), Range::positive(), "r: gas constant [J/(kg K)]");
  a.field(PNEU_NVP(g, temperature_k), Range::positive(), "T: supply and chamber temperature [K]");
}

void describe(auto& a, Like<model::ValveParams> auto& v) {
  a.field(PNEU_NVP(v, max_conductance_m3_per_s_pa), Range::positive(),
          "C_max: sonic conductance fully open [m^3/(s Pa)]");
  a.field(PNEU_NVP(v, critical_pressure_ratio), Range::open(0.0, model::kLaminarPressureRatio),
          "b: ISO 6358 critical pressure ratio [-]");
  a.field(PNEU_NVP(v, leak_conductance_in_m3_per_s_pa), Range::non_negative(),
          "C_leak_in: supply -> chamber leak [m^3/(s Pa)]");
  a.field(PNEU_NVP(v, leak_conductance_out_m3_per_s_pa), Range::non_negative(),
          "C_leak_out: chamber -> exhaust leak [m^3/(s Pa)]");
  a.field(PNEU_NVP(v, max_voltage_v), Range::positive(), "u_max: the voltage that opens a valve fully [V]");
  a.field(optional(PNEU_NVP(v, null_offset_v)), Range::open(-v.max_voltage_v, v.max_voltage_v),
          "w_0: the voltage at which a valve is closed, its null offset [V]");
  a.field(optional(PNEU_NVP(v, reference_density_kg_per_m3)), Range::positive(),
          "rho_0 of ISO 6358 [kg/m^3]");
  a.field(optional(PNEU_NVP(v, reference_temperature_k)), Range::positive(), "T_0 of ISO 6358 [K]");
  a.field(optional(PNEU_NVP(v, spool_time_constant_s)), Range::closed(0.0, 1.0),
          "the spool follows its command with a first-order lag of this time constant [s]; 0 = none");
}

void describe(auto& a, Like<model::FrictionParams> auto& f) {
  a.field(PNEU_NVP(f, static_positive_n), Range::positive(), "F_S+: stiction, positive motion [N]");
  a.field(PNEU_NVP(f, coulomb_positive_n), Range::positive(), "F_C+: Coulomb friction, positive motion [N]");
  a.check("coulomb_positive_n", f.coulomb_positive_n <= f.static_positive_n, [&] {
    return "must not exceed friction.static_positive_n (" + fmt(f.coulomb_positive_n) + " > " +
           fmt(f.static_positive_n) + ")";
  });
  a.field(PNEU_NVP(f, static_negative_n), Range::negative(), "F_S-: stiction, negative motion [N]");
  a.field(PNEU_NVP(f, coulomb_negative_n), Range::negative(), "F_C-: Coulomb friction, negative motion [N]");
  a.check("coulomb_negative_n", f.coulomb_negative_n >= f.static_negative_n, [&] {
    return "must not be below friction.static_negative_n (" + fmt(f.coulomb_negative_n) + " < " +
           fmt(f.static_negative_n) + ")";
  });
  a.field(PNEU_NVP(f, viscous_n_s_per_m), Range::non_negative(), "sigma: viscous coefficient [N s/m]");
  a.field(PNEU_NVP(f, stribeck_velocity_m_per_s), Range::positive(), "v_s: Stribeck velocity [m/s]");
  a.field(PNEU_NVP(f, stick_velocity_m_per_s), Range::non_negative(),
          "|v| below which a decelerating carriage sticks [m/s]");
}

void describe(auto& a, Like<model::ThermalParams> auto& t) {
  a.field(PNEU_NVP(t, heat_transfer_w_per_m2_k), Range::positive(), "h: wall heat transfer coefficient [W/(m^2 K)]");
  a.field(optional(PNEU_NVP(t, adiabatic_index)), Range::left_open(1.0, 1.67), "gamma = c_p / c_v of the air [-]");
  a.number_or_auto(optional(PNEU_NVP(t, wall_temperature_k)), t.wall_temperature_auto,
                   "T_w: the walls' temperature [K]; auto = the supply's, gas.temperature_k");
  a.check("wall_temperature_k", t.wall_temperature_auto || t.wall_temperature_k > 0.0,
          [&] { return "must be > 0 or auto (got " + fmt(t.wall_temperature_k) + ")"; });
}

void describe(auto& a, Like<model::PlantParams> auto& p) {
  a.field(PNEU_NVP(p, mass_kg), Range::positive(), "M: moving mass (piston, rod, carriage, load) [kg]");
  a.section(PNEU_NVP(p, geometry));
  a.section(PNEU_NVP(p, gas));
  a.section(PNEU_NVP(p, valve));
  a.section(PNEU_NVP(p, friction));
  a.optional_section(optional(PNEU_NVP(p, thermal)), p.has_thermal);
  a.field(PNEU_NVP(p, max_step_s), Range::closed(1.0e-7, 1.0e-2), "largest RK4 step while the carriage slides [s]");
  a.field(optional(PNEU_NVP(p, max_stuck_step_s)), Range::closed(1.0e-7, 1.0e-2),
          "largest RK4 step while it is stuck [s]");
}

// ---------------------------------------------------------------------------------------------
// sensors.*

/// One channel; `gain_key` names its sensitivity with its unit (gain_v_per_m, gain_v_per_pa).
void describe(auto& a, Like<model::SensorChannelParams> auto& c, const char* gain_key) {
  a.field(Field(gain_key, c.gain_v_per_unit), Range::non_zero(), "sensitivity [V per SI unit]");
  a.field(PNEU_NVP(c, offset_v), Range::any(), "output at a zero value [V]");
  a.field(PNEU_NVP(c, noise_std_v), Range::non_negative(), "additive Gaussian noise, standard deviation [V]");
  a.field(PNEU_NVP(c, adc_bits), IntRange::in(0, 24).says("must be 0 (no quantisation) or 1..24 (got {})"),
          "ADC resolution [bits], 0 = no quantisation");
  a.field(PNEU_NVP(c, range_min_v), Range::any(), "electrical range: readings are clamped to it [V]");
  a.field(PNEU_NVP(c, range_max_v), Range::any(), "[V], > range_min_v");
  a.check("range_max_v", c.range_max_v > c.range_min_v,
          [&] { return "must exceed range_min_v (" + fmt(c.range_max_v) + " <= " + fmt(c.range_min_v) + ")"; });
}

void describe(auto& a, Like<model::SensorParams> auto& s) {
  a.field(PNEU_NVP(s, seed), IntRange::at_least(0), "seed of the noise generator");
  a.section(PNEU_NVP(s, position), "gain_v_per_m");
  a.section(PNEU_NVP(s, pressure_p), "gain_v_per_pa");
  a.section(PNEU_NVP(s, pressure_n), "gain_v_per_pa");
}

// ---------------------------------------------------------------------------------------------
// controller.*

void describe(auto& a, Like<ControllerConfig> auto& c, const model::PlantParams& plant) {
  const double half = plant.geometry.half_stroke_m();
  a.field(PNEU_NVP(c, rate_hz), Range::closed(1.0, 20000.0), "loop rate [Hz]");
  a.field(PNEU_NVP(c, clock), one_of(kClocks),
          "simulated: lockstep with the in-process plant; real: CLOCK_MONOTONIC");
  a.field(PNEU_NVP(c, duration_s), Range::non_negative(), "run length [s]; 0 = until SIGINT/SIGTERM");
  a.section(PNEU_NVP(c, law), c.offset_auto, plant.geometry);
  a.section(PNEU_NVP(c, differentiator));
  a.section(PNEU_NVP(c, stop_detector));
  a.section(PNEU_NVP(c, predictor));
  a.section(optional(PNEU_NVP(c, hold)));
  a.section(optional(PNEU_NVP(c, movement_test)));
  a.group("setpoints", [&](auto& s) {
    s.field(Field("initial_m", c.initial_setpoint_m), Range::any(), "set point before the first step [m]");
    s.check("initial_m", std::abs(c.initial_setpoint_m) <= half,
            [&] { return outside_the_stroke(half, c.initial_setpoint_m); });
    s.list(optional(PNEU_NVP(c, schedule)), half);
    s.check("schedule", c.schedule.size() <= controller::kMaxScheduleSteps, [&] {
      return "has " + std::to_string(c.schedule.size()) + " steps, more than the loop holds (" +
             std::to_string(controller::kMaxScheduleSteps) + "): stream set points as commands instead";
    });
    for (std::size_t i = 1; i < c.schedule.size(); ++i)
      s.check("schedule[" + std::to_string(i) + "].t_s", c.schedule[i].t_s > c.schedule[i - 1].t_s,
              "times must increase");
  });
  a.field(PNEU_NVP(c, soft_limit_min_m), Range::any(), "set points below are refused [m]");
  a.field(PNEU_NVP(c, soft_limit_max_m), Range::any(), "set points above are refused [m]");
  a.check("soft_limit_min_m", c.soft_limit_min_m >= -half, [&] {
    return "must lie inside the stroke (>= " + fmt(-half) + " m, got " + fmt(c.soft_limit_min_m) + ")";
  });
  a.check("soft_limit_max_m", c.soft_limit_max_m <= half, [&] {
    return "must lie inside the stroke (<= " + fmt(half) + " m, got " + fmt(c.soft_limit_max_m) + ")";
  });
  a.check("soft_limit_max_m", c.soft_limit_max_m > c.soft_limit_min_m, "must exceed soft_limit_min_m");
  a.check("setpoints.initial_m",
          c.initial_setpoint_m >= c.soft_limit_min_m && c.initial_setpoint_m <= c.soft_limit_max_m,
          "must lie within the soft limits");
  for (std::size_t i = 0; i < c.schedule.size(); ++i)
    a.check("setpoints.schedule[" + std::to_string(i) + "].position_m",
            c.schedule[i].position_m >= c.soft_limit_min_m && c.schedule[i].position_m <= c.soft_limit_max_m, [&] {
              return "must lie within the soft limits [" + fmt(c.soft_limit_min_m) + ", " +
                     fmt(c.soft_limit_max_m) + "] m";
            });
  a.check("movement_test.pulse_v", c.movement_test.pulse_v < c.law.max_voltage_v,
          "must lie below controller.law.max_voltage_v");
  a.check("movement_test.travel_m", c.movement_test.travel_m < 0.5 * (c.soft_limit_max_m - c.soft_limit_min_m),
          "must lie well within the soft limits (below half their span)");
  a.field(PNEU_NVP(c, start_armed), "armed at start-up");
  a.field(PNEU_NVP(c, comms_fault_after_s), Range::closed(0.0, 10.0),
          "reads not ok this long in a row are a fault [s]");
  a.section(PNEU_NVP(c, supervisor), plant, c.period_s());
  a.section(PNEU_NVP(c, realtime));
}

// ---------------------------------------------------------------------------------------------
// hal.*: its own key, and its sections (hal/params: modbus, gpio, sim)

void describe(auto& a, Like<HalConfig> auto& h) {
  a.field(PNEU_NVP(h, backend), one_of(kBackends).unknown("backend"), "sim: the plant in-process | modbus");
  a.optional_section(
      required_when(h.backend == BackendKind::kModbus, PNEU_NVP(h, modbus), "the modbus backend needs its section"),
      h.has_modbus);
  a.section(optional(PNEU_NVP(h, gpio)));
  a.optional_section(optional(PNEU_NVP(h, sim)), h.has_sim);
}

// ---------------------------------------------------------------------------------------------
// The whole configuration, and the rules across its sections

void describe(auto& a, Like<Config> auto& c) {
  a.section(PNEU_NVP(c, plant));
  a.section(PNEU_NVP(c, sensors));
  a.section(PNEU_NVP(c, simulation), c.plant.geometry);
  a.section(PNEU_NVP(c, controller), c.plant);
  a.section(PNEU_NVP(c, hal));
  a.section(PNEU_NVP(c, telemetry));
  a.section(PNEU_NVP(c, commands));
  const bool real_clock = c.controller.clock == ClockKind::kReal;
  a.check("controller.duration_s", c.controller.duration_s != 0.0 || real_clock,
          "0 (run until stopped) needs the real clock; give a duration");
  a.check("controller.clock", c.hal.backend != BackendKind::kModbus || real_clock,
          "the modbus backend runs on the real clock (--clock real)");
  a.check("hal.gpio.enabled", !c.hal.gpio.enabled || real_clock,
          "real lines (e-stop, valve power) need the real clock (--clock real)");
  // The simulated carriage starts where the supervisor lets it be: outside the soft limits it would
  // fault at t = 0 and the safe output would take the carriage wherever the plant goes.
  const ControllerConfig& ctl = c.controller;
  a.check("simulation.initial_position_m",
          c.hal.backend != BackendKind::kSim || (c.simulation.initial_position_m >= ctl.soft_limit_min_m &&
                                                 c.simulation.initial_position_m <= ctl.soft_limit_max_m),
          [&] {
            return "the simulated carriage would start outside the soft limits (controller.soft_limit_min_m, "
                   "soft_limit_max_m: [" + fmt(ctl.soft_limit_min_m) + ", " + fmt(ctl.soft_limit_max_m) + "] m, got " +
                   fmt(c.simulation.initial_position_m) + " m): the supervisor would fault at t = 0";
          });
}

// ---------------------------------------------------------------------------------------------
// Derived from the descriptions (schema.cpp)

/// What a key holds.
enum class KeyKind : std::uint8_t {
  kNumber,        ///< a finite number
  kInteger,       ///< an integer
  kBoolean,       ///< true or false
  kText,          ///< a string
  kChoice,        ///< one of the names of an enum
  kNumberOrAuto,  ///< a number, or the word auto
  kNames,         ///< a list of names
  kList,          ///< a list of mappings
  kSection,       ///< a mapping
};

/// One key: its path ("controller.setpoints.schedule[0].t_s"), what it holds, whether it may be
/// left out, and what the schema says of it (rules between keys aside).
struct KeyInfo {
  std::string path;
  KeyKind kind = KeyKind::kNumber;
  Presence presence = Presence::kRequired;
  std::string range;  ///< the values it accepts, as the schema states them ("> 0", "in [1, 247]", "tcp | rtu")
  std::string doc;    ///< its documentation line (empty for a mapping or a list of them: the struct's)
};

/// Every key of the schema, list entries as "list[]", each optional section's keys included; the
/// presence of a conditionally required key as the default configuration makes it.
[[nodiscard]] std::vector<KeyInfo> all_keys();

/// The keys of `config` as to_yaml() writes them, in that order (list entries by index, optional
/// sections only when present), with their presence as `config` makes it (a key required when
/// another key says so, required or not).
[[nodiscard]] std::vector<KeyInfo> keys_of(const Config& config);

/// The key paths the rules (checks) of the schema refuse at, for `config`.
[[nodiscard]] std::vector<std::string> rule_paths_of(const Config& config);

/// Every value of `config` by its key path, in the order of keys_of(), as a text that tells any
/// two different values apart (numbers as their shortest exact decimal text): two configurations
/// are the same when these are equal. `offset_v: auto` is "auto" (the number is only computed
/// later); an optional section also gives "<path>" -> "present" or "absent"; the values of a
/// section left out (their defaults) and a key ignored by the schema are given too.
[[nodiscard]] std::vector<std::pair<std::string, std::string>> values_of(const Config& config);

}  // namespace pneu::config::schema
