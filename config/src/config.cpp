#include "pneu/config/config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <type_traits>
#include <fstream>
#include <iterator>
#include <sstream>

#include "pneu/config/spelling.hpp"
#include "yaml_reader.hpp"

namespace pneu::config {

using detail::check;
using detail::fmt;
using detail::KeyCatalogue;
using detail::MapReader;

const char* to_string(LinearizedSlope s) noexcept {
  switch (s) {
    case LinearizedSlope::kChord: return "chord";
    case LinearizedSlope::kEquilibriumTangent: return "equilibrium";
    case LinearizedSlope::kStopTangent: break;
  }
  return "stop";
}

namespace {

constexpr LinearizedSlope kLinearizedSlopes[] = {LinearizedSlope::kStopTangent, LinearizedSlope::kChord,
                                                 LinearizedSlope::kEquilibriumTangent};

double positive(MapReader& r, const std::string& key) {
  const double v = r.number(key);
  check(v > 0.0, r.child_path(key), "must be > 0 (got " + fmt(v) + ")");
  return v;
}

double positive_or(MapReader& r, const std::string& key, double fallback) {
  return r.has(key) ? positive(r, key) : r.number_or(key, fallback);
}

double non_negative(MapReader& r, const std::string& key) {
  const double v = r.number(key);
  check(v >= 0.0, r.child_path(key), "must be >= 0 (got " + fmt(v) + ")");
  return v;
}

double in_range(MapReader& r, const std::string& key, double lo, double hi) {
  const double v = r.number(key);
  check(v >= lo && v <= hi, r.child_path(key),
        "must be in [" + fmt(lo) + ", " + fmt(hi) + "] (got " + fmt(v) + ")");
  return v;
}

plant::Geometry read_geometry(MapReader r) {
  plant::Geometry g;
  g.stroke_m = positive(r, "stroke_m");
  g.bore_diameter_m = positive(r, "bore_diameter_m");
  g.rod_diameter_m = positive(r, "rod_diameter_m");
  check(g.rod_diameter_m < g.bore_diameter_m, r.child_path("rod_diameter_m"),
        "must be smaller than geometry.bore_diameter_m (" + fmt(g.rod_diameter_m) +
            " >= " + fmt(g.bore_diameter_m) + ")");
  g.dead_volume_p_m3 = positive(r, "dead_volume_p_m3");
  g.dead_volume_n_m3 = positive(r, "dead_volume_n_m3");
  r.finish();
  return g;
}

plant::Gas read_gas(MapReader r) {
  plant::Gas g;
  g.supply_pressure_pa = positive(r, "supply_pressure_pa");
  g.exhaust_pressure_pa = positive(r, "exhaust_pressure_pa");
  check(g.supply_pressure_pa > g.exhaust_pressure_pa, r.child_path("supply_pressure_pa"),
        "must exceed gas.exhaust_pressure_pa (" + fmt(g.supply_pressure_pa) + " <= " +
            fmt(g.exhaust_pressure_pa) + ")");
  g.polytropic_index = in_range(r, "polytropic_index", 1.0, 1.4);
  g.gas_constant_j_per_kg_k = positive(r, "gas_constant_j_per_kg_k");
  g.temperature_k = positive(r, "temperature_k");
  r.finish();
  return g;
}

plant::ValveParams read_valve(MapReader r) {
  plant::ValveParams v;
  v.max_conductance_m3_per_s_pa = positive(r, "max_conductance_m3_per_s_pa");
  v.critical_pressure_ratio = r.number("critical_pressure_ratio");
  check(v.critical_pressure_ratio > 0.0 && v.critical_pressure_ratio < plant::kLaminarPressureRatio,
        r.child_path("critical_pressure_ratio"),
        "must be in (0, " + fmt(plant::kLaminarPressureRatio) + ") (got " +
            fmt(v.critical_pressure_ratio) + ")");
  v.leak_conductance_in_m3_per_s_pa = non_negative(r, "leak_conductance_in_m3_per_s_pa");
  v.leak_conductance_out_m3_per_s_pa = non_negative(r, "leak_conductance_out_m3_per_s_pa");
  v.max_voltage_v = positive(r, "max_voltage_v");
  // Optional: the ISO 6358 reference atmosphere.
  v.reference_density_kg_per_m3 = positive_or(r, "reference_density_kg_per_m3", 1.185);
  v.reference_temperature_k = positive_or(r, "reference_temperature_k", 293.15);
  r.finish();
  return v;
}

plant::FrictionParams read_friction(MapReader r) {
  plant::FrictionParams f;
  f.static_positive_n = positive(r, "static_positive_n");
  f.coulomb_positive_n = positive(r, "coulomb_positive_n");
  check(f.coulomb_positive_n <= f.static_positive_n, r.child_path("coulomb_positive_n"),
        "must not exceed friction.static_positive_n (" + fmt(f.coulomb_positive_n) + " > " +
            fmt(f.static_positive_n) + ")");
  f.static_negative_n = r.number("static_negative_n");
  check(f.static_negative_n < 0.0, r.child_path("static_negative_n"),
        "must be < 0 (got " + fmt(f.static_negative_n) + ")");
  f.coulomb_negative_n = r.number("coulomb_negative_n");
  check(f.coulomb_negative_n < 0.0, r.child_path("coulomb_negative_n"),
        "must be < 0 (got " + fmt(f.coulomb_negative_n) + ")");
  check(f.coulomb_negative_n >= f.static_negative_n, r.child_path("coulomb_negative_n"),
        "must not be below friction.static_negative_n (" + fmt(f.coulomb_negative_n) + " < " +
            fmt(f.static_negative_n) + ")");
  f.viscous_n_s_per_m = non_negative(r, "viscous_n_s_per_m");
  f.stribeck_velocity_m_per_s = positive(r, "stribeck_velocity_m_per_s");
  f.stick_velocity_m_per_s = non_negative(r, "stick_velocity_m_per_s");
  r.finish();
  return f;
}

plant::PlantParams read_plant(MapReader r) {
  plant::PlantParams p;
  p.mass_kg = positive(r, "mass_kg");
  p.geometry = read_geometry(r.map("geometry"));
  p.gas = read_gas(r.map("gas"));
  p.valve = read_valve(r.map("valve"));
  p.friction = read_friction(r.map("friction"));
  p.max_step_s = in_range(r, "max_step_s", 1.0e-7, 1.0e-2);
  r.finish();
  return p;
}

plant::SensorChannelParams read_channel(MapReader r, const char* gain_key) {
  plant::SensorChannelParams c;
  c.gain_v_per_unit = r.number(gain_key);
  check(c.gain_v_per_unit != 0.0, r.child_path(gain_key), "must not be 0");
  c.offset_v = r.number("offset_v");
  c.noise_std_v = non_negative(r, "noise_std_v");
  const long long bits = r.integer("adc_bits");
  check(bits >= 0 && bits <= 24, r.child_path("adc_bits"),
        "must be 0 (no quantisation) or 1..24 (got " + std::to_string(bits) + ")");
  c.adc_bits = static_cast<int>(bits);
  c.range_min_v = r.number("range_min_v");
  c.range_max_v = r.number("range_max_v");
  check(c.range_max_v > c.range_min_v, r.child_path("range_max_v"),
        "must exceed range_min_v (" + fmt(c.range_max_v) + " <= " + fmt(c.range_min_v) + ")");
  r.finish();
  return c;
}

plant::SensorParams read_sensors(MapReader r) {
  plant::SensorParams s;
  const long long seed = r.integer("seed");
  check(seed >= 0, r.child_path("seed"), "must be >= 0");
  s.seed = static_cast<std::uint64_t>(seed);
  s.position = read_channel(r.map("position"), "gain_v_per_m");
  s.pressure_p = read_channel(r.map("pressure_p"), "gain_v_per_pa");
  s.pressure_n = read_channel(r.map("pressure_n"), "gain_v_per_pa");
  r.finish();
  return s;
}

SimulationConfig read_simulation(MapReader r, const plant::Geometry& g) {
  SimulationConfig s;
  s.initial_position_m = r.number("initial_position_m");
  check(std::abs(s.initial_position_m) <= g.half_stroke_m(), r.child_path("initial_position_m"),
        "must lie inside the stroke [" + fmt(-g.half_stroke_m()) + ", " + fmt(g.half_stroke_m()) +
            "] m (got " + fmt(s.initial_position_m) + ")");
  r.finish();
  return s;
}

ControllerConfig read_controller(MapReader r, const plant::PlantParams& plant) {
  ControllerConfig c;
  const double half = plant.geometry.half_stroke_m();
  c.rate_hz = in_range(r, "rate_hz", 1.0, 20000.0);
  const std::string clock = r.string("clock");
  if (clock == "simulated") c.clock = ClockKind::kSimulated;
  else if (clock == "real") c.clock = ClockKind::kReal;
  else throw ConfigError(r.child_path("clock"), "must be 'simulated' or 'real' (got '" + clock + "')");
  c.duration_s = non_negative(r, "duration_s");
  {
    MapReader law = r.map("law");
    c.law.position_gain_v_per_m = non_negative(law, "position_gain_v_per_m");
    c.law.velocity_gain_v_s_per_m = non_negative(law, "velocity_gain_v_s_per_m");
    c.law.acceleration_gain_v_s2_per_m = non_negative(law, "acceleration_gain_v_s2_per_m");
    const YAML::Node offset = law.node("offset_v");
    if (offset.IsScalar() && offset.Scalar() == "auto") {
      c.offset_auto = true;
    } else {
      c.offset_auto = false;
      c.law.offset_v = MapReader::to_number(offset, law.child_path("offset_v"));
    }
    c.law.max_voltage_v = positive(law, "max_voltage_v");
    law.finish();
  }
  {
    MapReader d = r.map("differentiator");
    c.differentiator.smoothing = d.number("smoothing");
    check(c.differentiator.smoothing > 0.0 && c.differentiator.smoothing <= 1.0,
          d.child_path("smoothing"), "must be in (0, 1] (got " + fmt(c.differentiator.smoothing) + ")");
    d.finish();
  }
  {
    MapReader d = r.map("stop_detector");
    c.stop_detector.rest_band_m = non_negative(d, "rest_band_m");
    c.stop_detector.motion_band_m = positive(d, "motion_band_m");
    check(c.stop_detector.motion_band_m > c.stop_detector.rest_band_m, d.child_path("motion_band_m"),
          "must exceed rest_band_m");
    c.stop_detector.hold_s = positive(d, "hold_s");
    d.finish();
  }
  {
    MapReader pr = r.map("predictor");
    const YAML::Node methods = pr.node("methods");
    const std::string mpath = pr.child_path("methods");
    if (!methods.IsSequence()) throw ConfigError(mpath, "expected a list, e.g. [linearized, nonlinear]");
    c.predictor.linearized = c.predictor.nonlinear = false;
    for (std::size_t i = 0; i < methods.size(); ++i) {
      const std::string m = methods[i].IsScalar() ? methods[i].Scalar() : "";
      if (m == "linearized") c.predictor.linearized = true;
      else if (m == "nonlinear") c.predictor.nonlinear = true;
      else throw ConfigError(mpath + "[" + std::to_string(i) + "]",
                             "unknown method '" + m + "' (linearized, nonlinear)");
    }
    c.predictor.valve_table = pr.string_or("valve_table", "");
    c.predictor.horizon_s = positive(pr, "horizon_s");
    const std::string slope = pr.string_or("linearized_slope", to_string(LinearizedSlope::kStopTangent));
    const auto known = std::find_if(std::begin(kLinearizedSlopes), std::end(kLinearizedSlopes),
                                    [&](LinearizedSlope s) { return slope == to_string(s); });
    if (known == std::end(kLinearizedSlopes))
      throw ConfigError(pr.child_path("linearized_slope"),
                        "must be 'stop', 'chord' or 'equilibrium' (got '" + slope + "')");
    c.predictor.linearized_slope = *known;
    c.predictor.update_period_s = pr.has("update_period_s") ? non_negative(pr, "update_period_s")
                                                            : c.predictor.update_period_s;
    pr.finish();
  }
  {
    MapReader sp = r.map("setpoints");
    c.initial_setpoint_m = sp.number("initial_m");
    check(std::abs(c.initial_setpoint_m) <= half, sp.child_path("initial_m"),
          "must lie inside the stroke [" + fmt(-half) + ", " + fmt(half) + "] m (got " +
              fmt(c.initial_setpoint_m) + ")");
    const YAML::Node steps = sp.sequence_or_empty("schedule");
    const std::string spath = sp.child_path("schedule");
    for (std::size_t i = 0; i < steps.size(); ++i) {
      MapReader step = sp.child(steps[i], spath + "[" + std::to_string(i) + "]");
      SetpointStep s;
      s.t_s = non_negative(step, "t_s");
      s.position_m = step.number("position_m");
      check(std::abs(s.position_m) <= half, step.child_path("position_m"),
            "must lie inside the stroke [" + fmt(-half) + ", " + fmt(half) + "] m (got " +
                fmt(s.position_m) + ")");
      if (!c.schedule.empty())
        check(s.t_s > c.schedule.back().t_s, step.child_path("t_s"), "times must increase");
      step.finish();
      c.schedule.push_back(s);
    }
    sp.finish();
  }
  c.soft_limit_min_m = r.number("soft_limit_min_m");
  c.soft_limit_max_m = r.number("soft_limit_max_m");
  check(c.soft_limit_min_m >= -half, r.child_path("soft_limit_min_m"),
        "must lie inside the stroke (>= " + fmt(-half) + " m, got " + fmt(c.soft_limit_min_m) + ")");
  check(c.soft_limit_max_m <= half, r.child_path("soft_limit_max_m"),
        "must lie inside the stroke (<= " + fmt(half) + " m, got " + fmt(c.soft_limit_max_m) + ")");
  check(c.soft_limit_max_m > c.soft_limit_min_m, r.child_path("soft_limit_max_m"),
        "must exceed soft_limit_min_m");
  check(c.initial_setpoint_m >= c.soft_limit_min_m && c.initial_setpoint_m <= c.soft_limit_max_m,
        r.child_path("setpoints.initial_m"), "must lie within the soft limits");
  for (std::size_t i = 0; i < c.schedule.size(); ++i)
    check(c.schedule[i].position_m >= c.soft_limit_min_m && c.schedule[i].position_m <= c.soft_limit_max_m,
          r.child_path("setpoints.schedule[" + std::to_string(i) + "].position_m"),
          "must lie within the soft limits [" + fmt(c.soft_limit_min_m) + ", " + fmt(c.soft_limit_max_m) + "] m");
  c.start_armed = r.boolean("start_armed");
  c.comms_fault_after_s = in_range(r, "comms_fault_after_s", 0.0, 10.0);
  {
    MapReader s = r.map("supervisor");
    auto& v = c.supervisor;
    v.position_min_m = s.number("position_min_m");
    v.position_max_m = s.number("position_max_m");
    check(v.position_max_m > v.position_min_m, s.child_path("position_max_m"), "must exceed position_min_m");
    check(v.position_min_m <= -half, s.child_path("position_min_m"),
          "must not exceed the stroke's lower end " + fmt(-half) + " m (the range must contain the stroke: a carriage at an end stop is not a fault)");
    check(v.position_max_m >= half, s.child_path("position_max_m"),
          "must not lie below the stroke's upper end " + fmt(half) + " m (the range must contain the stroke: a carriage at an end stop is not a fault)");
    v.pressure_min_pa = non_negative(s, "pressure_min_pa");
    v.pressure_max_pa = positive(s, "pressure_max_pa");
    check(v.pressure_max_pa > v.pressure_min_pa, s.child_path("pressure_max_pa"), "must exceed pressure_min_pa");
    check(v.pressure_max_pa > plant.gas.supply_pressure_pa, s.child_path("pressure_max_pa"),
          "must exceed the supply pressure (" + fmt(plant.gas.supply_pressure_pa) + " Pa): a chamber may reach it");
    check(v.pressure_min_pa < plant.gas.exhaust_pressure_pa, s.child_path("pressure_min_pa"),
          "must lie below the exhaust pressure (" + fmt(plant.gas.exhaust_pressure_pa) + " Pa): a chamber may reach it");
    v.max_speed_m_per_s = non_negative(s, "max_speed_m_per_s");
    v.frozen_after_s = in_range(s, "frozen_after_s", 0.0, 60.0);
    v.overtravel_m = non_negative(s, "overtravel_m");
    v.following_error_m = positive(s, "following_error_m");
    v.following_error_s = in_range(s, "following_error_s", 0.0, 600.0);
    const long long k = s.integer("overruns_in_a_row");
    check(k >= 0 && k <= 1000000, s.child_path("overruns_in_a_row"), "must be in [0, 1000000] (0 = off)");
    v.overruns_in_a_row = static_cast<std::uint32_t>(k);
    v.max_tick_interval_s = in_range(s, "max_tick_interval_s", 0.0, 10.0);
    check(v.max_tick_interval_s == 0.0 || v.max_tick_interval_s > 1.0 / c.rate_hz, s.child_path("max_tick_interval_s"),
          "must exceed the loop period (" + fmt(1.0 / c.rate_hz) + " s), or be 0 (off)");
    const std::string safe = s.string("safe_output");
    if (safe == "neutral") v.safe_output = SafeOutput::kNeutral;
    else if (safe == "exhaust") v.safe_output = SafeOutput::kExhaust;
    else throw ConfigError(s.child_path("safe_output"), "must be 'neutral' or 'exhaust' (got '" + safe + "')");
    s.finish();
  }
  {
    MapReader rt = r.map("realtime");
    const long long prio = rt.integer("priority");
    check(prio >= 0 && prio <= 99, rt.child_path("priority"), "must be in [0, 99] (0 = normal scheduling)");
    c.realtime.priority = static_cast<int>(prio);
    const long long cpu = rt.integer("cpu");
    check(cpu >= -1 && cpu < 1024, rt.child_path("cpu"), "must be a CPU number, or -1 (no pinning)");
    c.realtime.cpu = static_cast<int>(cpu);
    c.realtime.lock_memory = rt.boolean("lock_memory");
    rt.finish();
  }
  r.finish();
  return c;
}

TelemetryConfig read_telemetry(MapReader r) {
  TelemetryConfig t;
  t.enabled = r.boolean("enabled");
  t.lcm_url = r.string("lcm_url");
  check(!t.lcm_url.empty(), r.child_path("lcm_url"), "must not be empty");
  t.channel_prefix = r.string("channel_prefix");
  for (char ch : t.channel_prefix)
    check(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-' || ch == '.',
          r.child_path("channel_prefix"), "may hold letters, digits, '_', '-' and '.' only");
  t.health_period_s = in_range(r, "health_period_s", 0.01, 60.0);
  t.in_simulated_time = r.boolean("in_simulated_time");
  r.finish();
  return t;
}

CommandsConfig read_commands(MapReader r) {
  CommandsConfig c;
  c.enabled = r.boolean("enabled");
  c.max_rate_hz = in_range(r, "max_rate_hz", 0.01, 1000.0);
  c.burst = in_range(r, "burst", 1.0, 1000.0);
  c.max_age_s = in_range(r, "max_age_s", 0.001, 3600.0);
  c.max_setpoint_step_m = positive(r, "max_setpoint_step_m");
  c.setpoint_stream_timeout_s = in_range(r, "setpoint_stream_timeout_s", 0.0, 3600.0);
  r.finish();
  return c;
}

// One channel of hal.modbus.channels. `sensor`: a sensor channel (may be float32), else a valve
// output (int16 only).
RegisterChannel read_register(MapReader r, bool sensor) {
  RegisterChannel c;
  const std::string format = r.string_or("format", "int16");
  if (format == "int16") c.format = RegisterFormat::kInt16;
  else if (format == "float32") c.format = RegisterFormat::kFloat32;
  else throw ConfigError(r.child_path("format"), "must be 'int16' or 'float32' (got '" + format + "')");
  check(sensor || c.format == RegisterFormat::kInt16, r.child_path("format"),
        "float32 is for sensor channels only: a valve output is one 16-bit register");
  const bool is_float = c.format == RegisterFormat::kFloat32;
  const long long address = r.integer("register");
  if (is_float)
    check(address >= 0 && address <= 65534, r.child_path("register"),
          "must be in [0, 65534] (a float32 spans this register and the next)");
  else
    check(address >= 0 && address <= 65535, r.child_path("register"), "must be in [0, 65535]");
  c.address = static_cast<int>(address);
  // float32: `signed` is accepted (and type-checked) but means nothing; it is not kept.
  if (is_float) (void)r.boolean_or("signed", false);
  else c.is_signed = r.boolean("signed");
  c.raw_min = r.number("raw_min");
  c.raw_max = r.number("raw_max");
  if (is_float) {
    constexpr double kFloatMax = 3.4028234663852886e38;
    check(std::abs(c.raw_min) <= kFloatMax, r.child_path("raw_min"), "must fit a float32 (|raw_min| <= 3.4028235e38)");
    check(std::abs(c.raw_max) <= kFloatMax, r.child_path("raw_max"), "must fit a float32 (|raw_max| <= 3.4028235e38)");
  } else {
    const double lo = c.is_signed ? -32768.0 : 0.0, hi = c.is_signed ? 32767.0 : 65535.0;
    check(c.raw_min >= lo && c.raw_min <= hi, r.child_path("raw_min"),
          "must fit a " + std::string(c.is_signed ? "signed" : "unsigned") + " 16-bit register [" + fmt(lo) + ", " + fmt(hi) + "]");
    check(c.raw_max >= lo && c.raw_max <= hi, r.child_path("raw_max"),
          "must fit a " + std::string(c.is_signed ? "signed" : "unsigned") + " 16-bit register [" + fmt(lo) + ", " + fmt(hi) + "]");
  }
  check(c.raw_max > c.raw_min, r.child_path("raw_max"),
        "the raw range is empty (raw_max " + fmt(c.raw_max) + " <= raw_min " + fmt(c.raw_min) + ")");
  c.volts_min = r.number("volts_min");
  c.volts_max = r.number("volts_max");
  check(c.volts_max > c.volts_min, r.child_path("volts_max"),
        "the volts range is empty (volts_max " + fmt(c.volts_max) + " <= volts_min " + fmt(c.volts_min) + ")");
  r.finish();
  return c;
}

ModbusConfig read_modbus(MapReader r) {
  ModbusConfig m;
  const std::string transport = r.string("transport");
  if (transport == "tcp") m.transport = ModbusTransport::kTcp;
  else if (transport == "rtu") m.transport = ModbusTransport::kRtu;
  else throw ConfigError(r.child_path("transport"), "must be 'tcp' or 'rtu' (got '" + transport + "')");
  m.host = r.string_or("host", m.host);
  const long long port = r.integer_or("port", m.port);
  check(port >= 1 && port <= 65535, r.child_path("port"), "must be in [1, 65535]");
  m.port = static_cast<int>(port);
  m.device = r.string_or("device", m.device);
  const long long baud = r.integer_or("baud", m.baud);
  check(baud >= 300 && baud <= 4000000, r.child_path("baud"), "must be in [300, 4000000]");
  m.baud = static_cast<int>(baud);
  const std::string parity = r.string_or("parity", "none");
  if (parity == "none") m.parity = 'N';
  else if (parity == "even") m.parity = 'E';
  else if (parity == "odd") m.parity = 'O';
  else throw ConfigError(r.child_path("parity"), "must be none, even or odd (got '" + parity + "')");
  const long long data_bits = r.integer_or("data_bits", 8);
  check(data_bits >= 5 && data_bits <= 8, r.child_path("data_bits"), "must be in [5, 8]");
  m.data_bits = static_cast<int>(data_bits);
  const long long stop_bits = r.integer_or("stop_bits", 1);
  check(stop_bits == 1 || stop_bits == 2, r.child_path("stop_bits"), "must be 1 or 2");
  m.stop_bits = static_cast<int>(stop_bits);
  const long long unit = r.integer("unit_id");
  check(unit >= 1 && unit <= 247, r.child_path("unit_id"), "must be in [1, 247]");
  m.unit_id = static_cast<int>(unit);
  m.response_timeout_s = in_range(r, "response_timeout_s", 1e-4, 10.0);
  m.max_sample_age_s = in_range(r, "max_sample_age_s", 1e-4, 10.0);
  m.min_exchange_period_s = in_range(r, "min_exchange_period_s", 0.0, 1.0);
  m.read_write_multiple = r.boolean("read_write_multiple");
  const std::string table = r.string("sensor_table");
  if (table == "holding") m.sensor_table = SensorTable::kHolding;
  else if (table == "input") m.sensor_table = SensorTable::kInput;
  else throw ConfigError(r.child_path("sensor_table"), "must be 'holding' or 'input' (got '" + table + "')");
  check(!(m.read_write_multiple && m.sensor_table == SensorTable::kInput), r.child_path("read_write_multiple"),
        "function 23 reads holding registers: with sensor_table input, set read_write_multiple false");
  m.reconnect_min_s = in_range(r, "reconnect_min_s", 1e-3, 60.0);
  m.reconnect_max_s = in_range(r, "reconnect_max_s", m.reconnect_min_s, 600.0);
  {
    MapReader ch = r.map("channels");
    m.position = read_register(ch.map("position"), true);
    m.pressure_p = read_register(ch.map("pressure_p"), true);
    m.pressure_n = read_register(ch.map("pressure_n"), true);
    m.valve_p = read_register(ch.map("valve_p"), false);
    m.valve_n = read_register(ch.map("valve_n"), false);
    // One register holds one channel: refuse overlaps within a table (the valves are holding
    // registers; the sensors are too unless sensor_table is input). A float32 channel holds two.
    struct Named { const char* name; const RegisterChannel* c; bool holding; };
    const bool sensors_holding = m.sensor_table == SensorTable::kHolding;
    const Named all[] = {{"position", &m.position, sensors_holding}, {"pressure_p", &m.pressure_p, sensors_holding},
                         {"pressure_n", &m.pressure_n, sensors_holding}, {"valve_p", &m.valve_p, true},
                         {"valve_n", &m.valve_n, true}};
    for (std::size_t i = 0; i < 5; ++i)
      for (std::size_t j = i + 1; j < 5; ++j) {
        const RegisterChannel &a = *all[i].c, &b = *all[j].c;
        const int shared = std::max(a.address, b.address);  // the first register both hold, if any
        check(!(all[i].holding == all[j].holding && shared <= std::min(a.last_address(), b.last_address())),
              ch.child_path(all[j].name) + ".register",
              "overlaps " + std::string(all[i].name) + " (both at register " + std::to_string(shared) + ")");
      }
    if (m.read_write_multiple)
      check(std::abs(m.valve_p.address - m.valve_n.address) == 1, ch.child_path("valve_n") + ".register",
            "function 23 writes one block: valve_p and valve_n must be adjacent registers");
    const int lo = std::min({m.position.address, m.pressure_p.address, m.pressure_n.address});
    const int hi = std::max({m.position.last_address(), m.pressure_p.last_address(), m.pressure_n.last_address()});
    check(hi - lo < 121, ch.child_path("pressure_n") + ".register",
          "the sensor registers must lie within 121 consecutive registers (one read transaction)");
    ch.finish();
  }
  r.finish();
  return m;
}

HalConfig read_hal(MapReader r) {
  HalConfig h;
  const std::string backend = r.string("backend");
  if (backend == "sim") h.backend = BackendKind::kSim;
  else if (backend == "modbus") h.backend = BackendKind::kModbus;
  else throw ConfigError(r.child_path("backend"), "unknown backend '" + backend + "' (sim, modbus)");
  h.has_modbus = r.has("modbus");
  if (h.has_modbus) h.modbus = read_modbus(r.map("modbus"));
  else (void)r.string_or("modbus", "");
  if (r.has("gpio")) {
    MapReader g = r.map("gpio");
    h.gpio.enabled = g.boolean("enabled");
    h.gpio.chip = g.string_or("chip", h.gpio.chip);
    check(!h.gpio.chip.empty(), g.child_path("chip"), "must not be empty");
    const long long estop = g.integer_or("estop_line", h.gpio.estop_line);
    const long long power = g.integer_or("valve_power_line", h.gpio.valve_power_line);
    check(estop >= 0 && estop < 65536, g.child_path("estop_line"), "must be a line offset >= 0");
    check(power >= 0 && power < 65536, g.child_path("valve_power_line"), "must be a line offset >= 0");
    check(estop != power, g.child_path("valve_power_line"), "must differ from estop_line");
    h.gpio.estop_line = static_cast<unsigned>(estop);
    h.gpio.valve_power_line = static_cast<unsigned>(power);
    h.gpio.estop_active_low = g.boolean_or("estop_active_low", h.gpio.estop_active_low);
    h.gpio.valve_power_active_low = g.boolean_or("valve_power_active_low", h.gpio.valve_power_active_low);
    h.gpio.consumer = g.string_or("consumer", h.gpio.consumer);
    g.finish();
  } else {
    (void)r.string_or("gpio", "");
  }
  if (h.backend == BackendKind::kModbus && !h.has_modbus)
    r.refuse_missing("modbus", "missing: the modbus backend needs its section");
  r.finish();
  return h;
}

// "unknown key", and the override's path as the schema spells it when each of its keys is known
// or plausibly a typo of a known one ("did you mean controller.law.position_gain_v_per_m?"); a
// last key that is as plausibly a typo of several gives each.
std::string unknown_override_key(const std::vector<std::string>& keys) {
  const KeyCatalogue& schema = detail::schema_keys();
  std::string meant;
  bool corrected = false;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto known = schema.find(meant);
    if (known == schema.end()) return "unknown key";
    if (known->second.count(keys[i])) {
      meant += (meant.empty() ? "" : ".") + keys[i];
      continue;
    }
    const std::vector<std::string> closest = closest_known(keys[i], {known->second.begin(), known->second.end()});
    if (closest.empty() || (closest.size() > 1 && i + 1 < keys.size())) return "unknown key";
    if (i + 1 == keys.size()) {
      std::vector<std::string> paths;
      for (const std::string& k : closest) paths.push_back((meant.empty() ? "" : meant + ".") + k);
      return detail::unknown_key_meaning(paths);
    }
    meant += (meant.empty() ? "" : ".") + closest.front();
    corrected = true;
  }
  return corrected ? detail::unknown_key_meaning({meant}) : "unknown key";
}

// "a.b.c=value": sets the node at a.b.c to the YAML value, creating missing keys; the schema
// decoder then rejects any key it does not know.
void apply_override(YAML::Node& root, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("", "override '" + assignment + "' is not KEY=VALUE");
  std::string path = assignment.substr(0, eq);
  while (!path.empty() && std::isspace(static_cast<unsigned char>(path.back()))) path.pop_back();
  while (!path.empty() && std::isspace(static_cast<unsigned char>(path.front()))) path.erase(0, 1);
  const std::string text = assignment.substr(eq + 1);
  YAML::Node value;
  try {
    value = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, "cannot parse override value '" + text + "': " + e.msg);
  }
  std::vector<std::string> keys;
  std::stringstream ss(path);
  for (std::string key; std::getline(ss, key, '.');) {
    if (key.empty()) throw ConfigError(path, "override key has an empty component");
    keys.push_back(key);
  }
  if (keys.empty()) throw ConfigError("", "override '" + assignment + "' has no key");
  // yaml-cpp nodes are handles: walk with copies of the handles, assign through the last one.
  std::vector<YAML::Node> chain{root};
  std::string walked;
  for (std::size_t i = 0; i + 1 < keys.size(); ++i) {
    walked += (walked.empty() ? "" : ".") + keys[i];
    YAML::Node next = chain.back()[keys[i]];
    if (next.IsDefined() && !next.IsNull() && !next.IsMap())
      throw ConfigError(walked, "is a value, not a section: cannot override '" + path + "'");
    if (!next.IsDefined() || next.IsNull()) throw ConfigError(path, unknown_override_key(keys));
    chain.push_back(next);
  }
  // A key absent from the file may still be an optional key of the schema: create it and let
  // the decoder reject it when it is unknown.
  YAML::Node leaf = chain.back()[keys.back()];
  if (leaf.IsDefined() && leaf.IsMap())
    throw ConfigError(path, "is a section; override its keys one by one");
  chain.back()[keys.back()] = value;
}

// `record`: surveying the schema (detail::schema_keys).
Config decode(const YAML::Node& root, KeyCatalogue* record = nullptr) {
  MapReader r(root, "", record);
  Config c;
  c.plant = read_plant(r.map("plant"));
  c.sensors = read_sensors(r.map("sensors"));
  c.simulation = read_simulation(r.map("simulation"), c.plant.geometry);
  c.controller = read_controller(r.map("controller"), c.plant);
  c.hal = read_hal(r.map("hal"));
  c.telemetry = read_telemetry(r.map("telemetry"));
  c.commands = read_commands(r.map("commands"));
  r.finish();
  return c;
}

}  // namespace

namespace detail {

const KeyCatalogue& schema_keys() {
  // Every mapping of the schema is read when decoding the embedded sim.yaml with a Modbus section
  // added (the defaults of ModbusConfig, each channel at a register of its own): each reader
  // files the keys it read. The first decode records into a catalogue thrown away, so that no
  // message of it could ask for the catalogue being built.
  static const KeyCatalogue keys = [] {
    KeyCatalogue thrown_away, catalogue;
    try {
      Config c = decode(YAML::Load(std::string(default_config_yaml())), &thrown_away);
      c.hal.has_modbus = true;
      int address = 0;
      for (RegisterChannel* ch : {&c.hal.modbus.position, &c.hal.modbus.pressure_p, &c.hal.modbus.pressure_n,
                                  &c.hal.modbus.valve_p, &c.hal.modbus.valve_n})
        ch->address = address++;
      (void)decode(YAML::Load(to_yaml(c)), &catalogue);
    } catch (const ConfigError&) {
      return KeyCatalogue{};  // a broken embedded default: messages without suggestions (its tests fail)
    }
    return catalogue;
  }();
  return keys;
}

}  // namespace detail

namespace {

// Hostile text is refused before yaml-cpp sees it. yaml-cpp 0.7 spends about 2 s and 250 MB per
// MiB of a long flat list (20 MiB: 30 s and 4.9 GB), for configurations of about 12 KiB. Its
// parser does refuse nesting beyond 500 levels by itself (no stack overflow), but only as "bad
// file": the scan below says what is wrong, long before that.
constexpr std::size_t kMaxDocumentBytes = std::size_t{1} << 20;  // 1 MiB
constexpr std::size_t kMaxNesting = 64;

// The first line of a YAML text nested deeper than `limit` levels, or 0, without parsing it:
// block collections by their columns ("- " and "? " open a level at their own column, and a
// block sequence may sit at its parent key's column), flow collections by their brackets,
// outside comments, quoted scalars, plain scalars and block scalars. It errs towards counting
// more (each line's own key or scalar is a level).
std::size_t line_nested_deeper_than(std::string_view text, std::size_t limit) {
  constexpr auto npos = std::string_view::npos;
  struct Level {
    std::size_t column;
    bool sequence;
  };
  std::vector<Level> block;
  std::size_t flow = 0;
  char quote = 0;                 // inside a quoted scalar (which may span lines): its quote
  long block_scalar_parent = -2;  // inside a block scalar: the column its lines are deeper than
  bool node_start = true;         // the next character may start a node (not inside a plain scalar)
  bool after_json_node = false;   // flow: just after a quoted scalar or a collection (":" follows)
  long scalar_owner = -1;         // a plain scalar ending a line continues on lines deeper than this
  std::size_t line_no = 0;
  for (std::size_t begin = 0; begin < text.size();) {
    std::size_t end = text.find('\n', begin);
    if (end == npos) end = text.size();
    std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::size_t indent = line.find_first_not_of(' ');
    if (block_scalar_parent > -2) {
      if (indent == npos || static_cast<long>(indent) > block_scalar_parent) continue;
      block_scalar_parent = -2;
    }
    std::size_t pos = 0;
    std::size_t last_level = npos;  // the column of the last level this line opened
    if (quote == 0 && flow == 0) {
      if (indent == npos || line[indent] == '#' || (indent == 0 && line[0] == '%')) continue;
      pos = indent;
      // A line deeper than the node owning the plain scalar that ended the last one continues it.
      if (node_start || static_cast<long>(indent) <= scalar_owner) {
        node_start = true;
        if (indent == 0 && (line.starts_with("---") || line.starts_with("...")) &&
            (line.size() == 3 || line[3] == ' ' || line[3] == '\t')) {
          block.clear();  // the next document
          pos = line.find_first_not_of(" \t", 3);
          if (pos == npos || line[pos] == '#') continue;
        }
        for (;;) {
          const char c = line[pos];
          const bool indicator = (c == '-' || c == '?' || c == ':') &&
                                 (pos + 1 == line.size() || line[pos + 1] == ' ' || line[pos + 1] == '\t');
          const bool sequence = indicator && c == '-';
          while (!block.empty() && (block.back().column > pos ||
                                    (block.back().column == pos && block.back().sequence && !sequence)))
            block.pop_back();
          if (block.empty() || block.back().column < pos || block.back().sequence != sequence)
            block.push_back({pos, sequence});
          last_level = pos;
          if (block.size() > limit) return line_no;
          if (!indicator) break;
          pos = line.find_first_not_of(" \t", pos + 1);
          if (pos == npos || line[pos] == '#') break;
        }
        if (pos == npos) continue;
        // The owner of a scalar on this line: the key before it, else the level holding it.
        scalar_owner = block.size() < 2 ? -1 : static_cast<long>(block[block.size() - 2].column);
      }
    }
    for (std::size_t i = pos; i < line.size(); ++i) {
      const char c = line[i];
      if (quote != 0) {
        if (quote == '"' && c == '\\') ++i;
        else if (quote == '\'' && c == '\'' && i + 1 < line.size() && line[i + 1] == '\'') ++i;
        else if (c == quote) quote = 0, node_start = false, after_json_node = true;
        continue;
      }
      if (c == ' ' || c == '\t') continue;
      if (c == '#' && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t')) break;
      const bool space_next = i + 1 == line.size() || line[i + 1] == ' ' || line[i + 1] == '\t';
      const bool flow_indicator_next = i + 1 < line.size() && std::string_view(",[]{}").find(line[i + 1]) != npos;
      if (node_start) {
        if (c == '"' || c == '\'') {
          quote = c;
          continue;
        }
        if (c == '&' || c == '!') {  // an anchor or a tag: the node follows
          while (i + 1 < line.size() && line[i + 1] != ' ' && line[i + 1] != '\t' &&
                 (flow == 0 || std::string_view(",[]{}").find(line[i + 1]) == npos))
            ++i;
          continue;
        }
        if (c == '[' || c == '{') {
          if (block.size() + ++flow > limit) return line_no;
          continue;
        }
        if ((c == '-' || c == '?') && space_next) continue;
        if ((c == '|' || c == '>') && flow == 0) {
          // A block scalar's header holds only indicators and a comment after the '|' or '>'.
          const std::size_t rest = line.find_first_not_of("-+0123456789", i + 1);
          const std::size_t more = rest == npos ? rest : line.find_first_not_of(" \t", rest);
          if ((rest == npos || line[rest] == ' ' || line[rest] == '\t') && (more == npos || line[more] == '#')) {
            // Its lines are deeper than the node holding it: the key before it, or the "- " entry.
            const std::size_t owner = i == last_level ? block.size() - 1 : block.size();
            block_scalar_parent = owner == 0 ? -1 : static_cast<long>(block[owner - 1].column);
            break;
          }
        }
      }
      if (flow > 0) {
        if (c == '[' || c == '{') {  // no plain scalar holds these in a flow collection
          if (block.size() + ++flow > limit) return line_no;
          node_start = true;
          continue;
        }
        if (c == ']' || c == '}') {
          --flow;
          node_start = false;
          after_json_node = true;
          continue;
        }
        if (c == ',' || (c == ':' && (space_next || flow_indicator_next || after_json_node))) {
          node_start = true;
          after_json_node = false;
          continue;
        }
      } else if (c == ':' && space_next) {
        if (last_level != npos) scalar_owner = static_cast<long>(last_level);
        node_start = true;
        continue;
      }
      node_start = false;  // inside a plain scalar or an alias
      after_json_node = false;
    }
  }
  return 0;
}

// Refuses `text` (named `origin`) when it is too large or too deeply nested to hand to yaml-cpp.
void refuse_hostile_text(std::string_view text, const std::string& origin) {
  if (text.size() > kMaxDocumentBytes)
    throw ConfigError(origin, "too large: " + std::to_string(text.size()) + " bytes, at most " +
                                  std::to_string(kMaxDocumentBytes) + " (1 MiB)");
  if (const std::size_t line = line_nested_deeper_than(text, kMaxNesting))
    throw ConfigError(origin, "nested too deeply: more than " + std::to_string(kMaxNesting) +
                                  " levels at line " + std::to_string(line));
}

}  // namespace

Config load_string(std::string_view yaml, const std::vector<std::string>& overrides,
                   std::string_view origin) {
  refuse_hostile_text(yaml, std::string(origin));
  for (const auto& o : overrides)
    if (const auto eq = o.find('='); eq != std::string::npos)
      refuse_hostile_text(std::string_view(o).substr(eq + 1), o.substr(0, eq));
  YAML::Node root;
  try {
    root = YAML::Load(std::string(yaml));
  } catch (const YAML::Exception& e) {
    throw ConfigError(std::string(origin),
                      "not valid YAML (line " + std::to_string(e.mark.line + 1) + "): " + e.msg);
  }
  if (!root.IsMap()) throw ConfigError(std::string(origin), "expected a YAML mapping at the top");
  for (const auto& o : overrides) apply_override(root, o);
  return decode(root);
}

Config load_file(const std::filesystem::path& path, const std::vector<std::string>& overrides) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw ConfigError(path.string(), "cannot open the file (no such file)");
  if (const auto size = std::filesystem::file_size(path, ec); !ec && size > kMaxDocumentBytes)
    throw ConfigError(path.string(), "too large: " + std::to_string(size) + " bytes, at most " +
                                         std::to_string(kMaxDocumentBytes) + " (1 MiB)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path.string(), "cannot open the file");
  // At most one byte beyond the limit: a file growing meanwhile is still refused, not read whole.
  std::string text(kMaxDocumentBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return load_string(text, overrides, path.string());
}

Config load_file_or_default(const std::filesystem::path& path,
                            const std::vector<std::string>& overrides) {
  if (path.empty()) return load_string(default_config_yaml(), overrides, "<embedded sim.yaml>");
  return load_file(path, overrides);
}

namespace {
// A double as the shortest text that reads back as the same double: 0.032, where yaml-cpp writes
// 0.032000000000000001; without an exponent from 1e-4 to 1e9 (700000, not 7e+05). The dump is
// for people, and reads back exactly. (Non-finite values keep yaml-cpp's .inf/.nan.)
struct Shortest {
  double v;
};
YAML::Emitter& operator<<(YAML::Emitter& e, Shortest s) {
  if (!std::isfinite(s.v)) return e << s.v;
  char buf[64];
  const double a = std::fabs(s.v);
  const auto r = a == 0.0 || (a >= 1e-4 && a < 1e9) ? std::to_chars(buf, buf + sizeof buf, s.v, std::chars_format::fixed)
                                                     : std::to_chars(buf, buf + sizeof buf, s.v);
  return e << std::string(buf, r.ptr);
}

void emit_channel(YAML::Emitter& e, const char* name, const char* gain_key,
                  const plant::SensorChannelParams& c) {
  e << YAML::Key << name << YAML::Value << YAML::BeginMap;
  e << YAML::Key << gain_key << YAML::Value << Shortest{c.gain_v_per_unit};
  e << YAML::Key << "offset_v" << YAML::Value << Shortest{c.offset_v};
  e << YAML::Key << "noise_std_v" << YAML::Value << Shortest{c.noise_std_v};
  e << YAML::Key << "adc_bits" << YAML::Value << c.adc_bits;
  e << YAML::Key << "range_min_v" << YAML::Value << Shortest{c.range_min_v};
  e << YAML::Key << "range_max_v" << YAML::Value << Shortest{c.range_max_v};
  e << YAML::EndMap;
}
}  // namespace

std::string to_yaml(const Config& c) {
  YAML::Emitter e;
  e.SetDoublePrecision(17);
  const auto kv = [&](const char* k, auto v) {
    if constexpr (std::is_floating_point_v<decltype(v)>)
      e << YAML::Key << k << YAML::Value << Shortest{static_cast<double>(v)};
    else
      e << YAML::Key << k << YAML::Value << v;
  };
  e << YAML::BeginMap;
  e << YAML::Key << "plant" << YAML::Value << YAML::BeginMap;
  kv("mass_kg", c.plant.mass_kg);
  e << YAML::Key << "geometry" << YAML::Value << YAML::BeginMap;
  kv("stroke_m", c.plant.geometry.stroke_m);
  kv("bore_diameter_m", c.plant.geometry.bore_diameter_m);
  kv("rod_diameter_m", c.plant.geometry.rod_diameter_m);
  kv("dead_volume_p_m3", c.plant.geometry.dead_volume_p_m3);
  kv("dead_volume_n_m3", c.plant.geometry.dead_volume_n_m3);
  e << YAML::EndMap;
  e << YAML::Key << "gas" << YAML::Value << YAML::BeginMap;
  kv("supply_pressure_pa", c.plant.gas.supply_pressure_pa);
  kv("exhaust_pressure_pa", c.plant.gas.exhaust_pressure_pa);
  kv("polytropic_index", c.plant.gas.polytropic_index);
  kv("gas_constant_j_per_kg_k", c.plant.gas.gas_constant_j_per_kg_k);
  kv("temperature_k", c.plant.gas.temperature_k);
  e << YAML::EndMap;
  e << YAML::Key << "valve" << YAML::Value << YAML::BeginMap;
  kv("max_conductance_m3_per_s_pa", c.plant.valve.max_conductance_m3_per_s_pa);
  kv("critical_pressure_ratio", c.plant.valve.critical_pressure_ratio);
  kv("leak_conductance_in_m3_per_s_pa", c.plant.valve.leak_conductance_in_m3_per_s_pa);
  kv("leak_conductance_out_m3_per_s_pa", c.plant.valve.leak_conductance_out_m3_per_s_pa);
  kv("max_voltage_v", c.plant.valve.max_voltage_v);
  kv("reference_density_kg_per_m3", c.plant.valve.reference_density_kg_per_m3);
  kv("reference_temperature_k", c.plant.valve.reference_temperature_k);
  e << YAML::EndMap;
  e << YAML::Key << "friction" << YAML::Value << YAML::BeginMap;
  kv("static_positive_n", c.plant.friction.static_positive_n);
  kv("coulomb_positive_n", c.plant.friction.coulomb_positive_n);
  kv("static_negative_n", c.plant.friction.static_negative_n);
  kv("coulomb_negative_n", c.plant.friction.coulomb_negative_n);
  kv("viscous_n_s_per_m", c.plant.friction.viscous_n_s_per_m);
  kv("stribeck_velocity_m_per_s", c.plant.friction.stribeck_velocity_m_per_s);
  kv("stick_velocity_m_per_s", c.plant.friction.stick_velocity_m_per_s);
  e << YAML::EndMap;
  kv("max_step_s", c.plant.max_step_s);
  e << YAML::EndMap;
  e << YAML::Key << "sensors" << YAML::Value << YAML::BeginMap;
  kv("seed", static_cast<unsigned long long>(c.sensors.seed));
  emit_channel(e, "position", "gain_v_per_m", c.sensors.position);
  emit_channel(e, "pressure_p", "gain_v_per_pa", c.sensors.pressure_p);
  emit_channel(e, "pressure_n", "gain_v_per_pa", c.sensors.pressure_n);
  e << YAML::EndMap;
  e << YAML::Key << "simulation" << YAML::Value << YAML::BeginMap;
  kv("initial_position_m", c.simulation.initial_position_m);
  e << YAML::EndMap;
  const auto& k = c.controller;
  e << YAML::Key << "controller" << YAML::Value << YAML::BeginMap;
  kv("rate_hz", k.rate_hz);
  kv("clock", k.clock == ClockKind::kReal ? "real" : "simulated");
  kv("duration_s", k.duration_s);
  e << YAML::Key << "law" << YAML::Value << YAML::BeginMap;
  kv("position_gain_v_per_m", k.law.position_gain_v_per_m);
  kv("velocity_gain_v_s_per_m", k.law.velocity_gain_v_s_per_m);
  kv("acceleration_gain_v_s2_per_m", k.law.acceleration_gain_v_s2_per_m);
  if (k.offset_auto) kv("offset_v", "auto");
  else kv("offset_v", k.law.offset_v);
  kv("max_voltage_v", k.law.max_voltage_v);
  e << YAML::EndMap;
  e << YAML::Key << "differentiator" << YAML::Value << YAML::BeginMap;
  kv("smoothing", k.differentiator.smoothing);
  e << YAML::EndMap;
  e << YAML::Key << "stop_detector" << YAML::Value << YAML::BeginMap;
  kv("rest_band_m", k.stop_detector.rest_band_m);
  kv("motion_band_m", k.stop_detector.motion_band_m);
  kv("hold_s", k.stop_detector.hold_s);
  e << YAML::EndMap;
  e << YAML::Key << "predictor" << YAML::Value << YAML::BeginMap;
  e << YAML::Key << "methods" << YAML::Value << YAML::Flow << YAML::BeginSeq;
  if (k.predictor.linearized) e << "linearized";
  if (k.predictor.nonlinear) e << "nonlinear";
  e << YAML::EndSeq;
  kv("valve_table", k.predictor.valve_table);
  kv("horizon_s", k.predictor.horizon_s);
  kv("linearized_slope", to_string(k.predictor.linearized_slope));
  kv("update_period_s", k.predictor.update_period_s);
  e << YAML::EndMap;
  e << YAML::Key << "setpoints" << YAML::Value << YAML::BeginMap;
  kv("initial_m", k.initial_setpoint_m);
  e << YAML::Key << "schedule" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : k.schedule) {
    e << YAML::Flow << YAML::BeginMap;
    kv("t_s", s.t_s);
    kv("position_m", s.position_m);
    e << YAML::EndMap;
  }
  e << YAML::EndSeq;
  e << YAML::EndMap;
  kv("soft_limit_min_m", k.soft_limit_min_m);
  kv("soft_limit_max_m", k.soft_limit_max_m);
  kv("start_armed", k.start_armed);
  kv("comms_fault_after_s", k.comms_fault_after_s);
  {
    const auto& v = k.supervisor;
    e << YAML::Key << "supervisor" << YAML::Value << YAML::BeginMap;
    kv("position_min_m", v.position_min_m);
    kv("position_max_m", v.position_max_m);
    kv("pressure_min_pa", v.pressure_min_pa);
    kv("pressure_max_pa", v.pressure_max_pa);
    kv("max_speed_m_per_s", v.max_speed_m_per_s);
    kv("frozen_after_s", v.frozen_after_s);
    kv("overtravel_m", v.overtravel_m);
    kv("following_error_m", v.following_error_m);
    kv("following_error_s", v.following_error_s);
    kv("overruns_in_a_row", v.overruns_in_a_row);
    kv("max_tick_interval_s", v.max_tick_interval_s);
    kv("safe_output", v.safe_output == SafeOutput::kExhaust ? "exhaust" : "neutral");
    e << YAML::EndMap;
  }
  e << YAML::Key << "realtime" << YAML::Value << YAML::BeginMap;
  kv("priority", k.realtime.priority);
  kv("cpu", k.realtime.cpu);
  kv("lock_memory", k.realtime.lock_memory);
  e << YAML::EndMap;
  e << YAML::EndMap;
  e << YAML::Key << "hal" << YAML::Value << YAML::BeginMap;
  kv("backend", c.hal.backend == BackendKind::kModbus ? "modbus" : "sim");
  if (c.hal.has_modbus) {
    const auto& m = c.hal.modbus;
    e << YAML::Key << "modbus" << YAML::Value << YAML::BeginMap;
    kv("transport", m.transport == ModbusTransport::kRtu ? "rtu" : "tcp");
    kv("host", m.host);
    kv("port", m.port);
    kv("device", m.device);
    kv("baud", m.baud);
    kv("parity", m.parity == 'E' ? "even" : (m.parity == 'O' ? "odd" : "none"));
    kv("data_bits", m.data_bits);
    kv("stop_bits", m.stop_bits);
    kv("unit_id", m.unit_id);
    kv("response_timeout_s", m.response_timeout_s);
    kv("max_sample_age_s", m.max_sample_age_s);
    kv("min_exchange_period_s", m.min_exchange_period_s);
    kv("read_write_multiple", m.read_write_multiple);
    kv("sensor_table", m.sensor_table == SensorTable::kInput ? "input" : "holding");
    kv("reconnect_min_s", m.reconnect_min_s);
    kv("reconnect_max_s", m.reconnect_max_s);
    e << YAML::Key << "channels" << YAML::Value << YAML::BeginMap;
    const std::pair<const char*, const RegisterChannel*> chans[] = {
        {"position", &m.position}, {"pressure_p", &m.pressure_p}, {"pressure_n", &m.pressure_n},
        {"valve_p", &m.valve_p}, {"valve_n", &m.valve_n}};
    for (const auto& [name, ch] : chans) {
      e << YAML::Key << name << YAML::Value << YAML::Flow << YAML::BeginMap;
      kv("register", ch->address);
      kv("format", ch->format == RegisterFormat::kFloat32 ? "float32" : "int16");
      if (ch->format == RegisterFormat::kInt16) kv("signed", ch->is_signed);
      kv("raw_min", ch->raw_min);
      kv("raw_max", ch->raw_max);
      kv("volts_min", ch->volts_min);
      kv("volts_max", ch->volts_max);
      e << YAML::EndMap;
    }
    e << YAML::EndMap;
    e << YAML::EndMap;
  }
  {
    const auto& g = c.hal.gpio;
    e << YAML::Key << "gpio" << YAML::Value << YAML::BeginMap;
    kv("enabled", g.enabled);
    kv("chip", g.chip);
    kv("estop_line", g.estop_line);
    kv("estop_active_low", g.estop_active_low);
    kv("valve_power_line", g.valve_power_line);
    kv("valve_power_active_low", g.valve_power_active_low);
    kv("consumer", g.consumer);
    e << YAML::EndMap;
  }
  e << YAML::EndMap;
  e << YAML::Key << "telemetry" << YAML::Value << YAML::BeginMap;
  kv("enabled", c.telemetry.enabled);
  kv("lcm_url", c.telemetry.lcm_url);
  kv("channel_prefix", c.telemetry.channel_prefix);
  kv("health_period_s", c.telemetry.health_period_s);
  kv("in_simulated_time", c.telemetry.in_simulated_time);
  e << YAML::EndMap;
  e << YAML::Key << "commands" << YAML::Value << YAML::BeginMap;
  kv("enabled", c.commands.enabled);
  kv("max_rate_hz", c.commands.max_rate_hz);
  kv("burst", c.commands.burst);
  kv("max_age_s", c.commands.max_age_s);
  kv("max_setpoint_step_m", c.commands.max_setpoint_step_m);
  kv("setpoint_stream_timeout_s", c.commands.setpoint_stream_timeout_s);
  e << YAML::EndMap;
  e << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

}  // namespace pneu::config
