// The fault schedule's vocabulary (CHANNEL:MODE@T) and the watchdog's outputs, parsed and checked
// against the register map.
#include "pneu/plant_server/faults.hpp"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace pneu::plant_server {

namespace {

// A whole-string number (strtod: also "inf", "nan"), or nullopt.
std::optional<double> parse_number(const std::string& text) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size() || errno == ERANGE) return std::nullopt;
  return v;
}

const hal::RegisterChannel& channel_of(const hal::ModbusConfig& mb, FaultChannel c) {
  switch (c) {
    case FaultChannel::kPosition: return mb.position;
    case FaultChannel::kPressureP: return mb.pressure_p;
    case FaultChannel::kPressureN: return mb.pressure_n;
    case FaultChannel::kValveP: return mb.valve_p;
    case FaultChannel::kValveN: return mb.valve_n;
    case FaultChannel::kTubes:
    case FaultChannel::kPressureSensors: break;  // no one register: a miswiring
  }
  return mb.position;
}

}  // namespace

bool is_valve(FaultChannel c) noexcept { return c == FaultChannel::kValveP || c == FaultChannel::kValveN; }
bool is_wiring(FaultChannel c) noexcept { return c == FaultChannel::kTubes || c == FaultChannel::kPressureSensors; }

Fault parse_fault(const std::string& spec, const hal::ModbusConfig& mb, double u_max_v) {
  const auto bad = [&](const std::string& why) { return SpecError(spec, why); };
  const auto colon = spec.find(':');
  if (colon == std::string::npos) throw bad("expected CHANNEL:MODE@T, e.g. pressure_p:rail-high@2.5");
  const std::string channel = spec.substr(0, colon);
  const std::string rest = spec.substr(colon + 1);
  const auto at = rest.rfind('@');
  if (at == std::string::npos) throw bad("missing @T: the time from which the fault acts, in seconds after start-up");
  const std::string mode_text = rest.substr(0, at);
  const std::string t_text = rest.substr(at + 1);

  Fault f;
  f.spec = spec;
  if (channel == "position") f.channel = FaultChannel::kPosition;
  else if (channel == "pressure_p") f.channel = FaultChannel::kPressureP;
  else if (channel == "pressure_n") f.channel = FaultChannel::kPressureN;
  else if (channel == "valve_p") f.channel = FaultChannel::kValveP;
  else if (channel == "valve_n") f.channel = FaultChannel::kValveN;
  else if (channel == "tubes") f.channel = FaultChannel::kTubes;
  else if (channel == "pressure_sensors") f.channel = FaultChannel::kPressureSensors;
  else throw bad("unknown channel '" + channel + "' (position, pressure_p, pressure_n, valve_p, valve_n, tubes, pressure_sensors)");

  const auto t = parse_number(t_text);
  if (!t || !std::isfinite(*t)) throw bad("T must be a number of seconds (got '" + t_text + "')");
  if (*t < 0.0) throw bad("T must be >= 0 (got " + t_text + ")");
  f.t_s = *t;

  const auto eq = mode_text.find('=');
  const std::string mode = mode_text.substr(0, eq);
  const std::optional<std::string> arg =
      eq == std::string::npos ? std::nullopt : std::optional<std::string>(mode_text.substr(eq + 1));
  if (mode == "rail-low") f.mode = FaultMode::kRailLow;
  else if (mode == "rail-high") f.mode = FaultMode::kRailHigh;
  else if (mode == "raw") f.mode = FaultMode::kRaw;
  else if (mode == "volts") f.mode = FaultMode::kVolts;
  else if (mode == "freeze") f.mode = FaultMode::kFreeze;
  else if (mode == "nan") f.mode = FaultMode::kNan;
  else if (mode == "stuck") f.mode = FaultMode::kStuck;
  else if (mode == "dead") f.mode = FaultMode::kDead;
  else if (mode == "swapped") f.mode = FaultMode::kSwapped;
  else throw bad("unknown mode '" + mode + "' (sensors: rail-low, rail-high, raw=N, volts=V, freeze, nan, dead; valves: "
                 "stuck=V; tubes, pressure_sensors: swapped)");
  const bool takes_value = f.mode == FaultMode::kRaw || f.mode == FaultMode::kVolts || f.mode == FaultMode::kStuck;
  if (takes_value && (!arg || arg->empty())) throw bad(mode + " needs a value: " + mode + (f.mode == FaultMode::kRaw ? "=N" : "=V"));
  if (!takes_value && arg) throw bad(mode + " takes no value");
  if (is_wiring(f.channel) != (f.mode == FaultMode::kSwapped))
    throw bad(is_wiring(f.channel) ? channel + " takes swapped only" : "swapped is for tubes and pressure_sensors only");
  if (is_valve(f.channel) && f.mode != FaultMode::kStuck)
    throw bad(mode + " is a sensor mode: a valve channel takes stuck=V only");
  if (!is_valve(f.channel) && f.mode == FaultMode::kStuck)
    throw bad("stuck=V is a valve mode: a sensor channel takes rail-low, rail-high, raw=N, volts=V, freeze, nan or dead");
  if (is_wiring(f.channel)) return f;

  const hal::RegisterChannel& c = channel_of(mb, f.channel);
  const bool is_float = c.format == hal::RegisterFormat::kFloat32;
  const std::string type = is_float ? "float32" : c.is_signed ? "signed 16-bit" : "unsigned 16-bit";
  switch (f.mode) {
    case FaultMode::kRailLow: (void)c.raw_to_words(c.raw_min, f.words.data()); break;
    case FaultMode::kRailHigh: (void)c.raw_to_words(c.raw_max, f.words.data()); break;
    case FaultMode::kRaw: {
      const auto n = parse_number(*arg);
      if (!n || std::isnan(*n)) throw bad("raw=" + *arg + ": not a number" + (is_float ? " (for NaN use the mode nan)" : ""));
      if (!c.raw_to_words(*n, f.words.data()))
        throw bad("raw=" + *arg + " does not fit the channel's " + type + " register" +
                  (is_float ? "" : c.is_signed ? " (an integer in [-32768, 32767])" : " (an integer in [0, 65535])"));
      break;
    }
    case FaultMode::kVolts: {
      const auto v = parse_number(*arg);
      if (!v || !std::isfinite(*v)) throw bad("volts=" + *arg + ": not a finite number of volts");
      (void)c.raw_to_words(c.volts_to_raw(*v), f.words.data());  // saturates at the register type's limits
      break;
    }
    case FaultMode::kNan:
      if (!is_float)
        throw bad("nan needs a float32 channel (hal.modbus.channels." + channel +
                  ".format: float32): an int16 register cannot hold NaN");
      (void)c.raw_to_words(std::nan(""), f.words.data());  // 0x7FC0 0x0000, a quiet NaN
      break;
    case FaultMode::kStuck: {
      const auto v = parse_number(*arg);
      if (!v || !std::isfinite(*v)) throw bad("stuck=" + *arg + ": not a finite number of volts");
      if (std::abs(*v) > u_max_v) {
        char range[64];
        std::snprintf(range, sizeof range, "[%g, %g] V", -u_max_v, u_max_v);
        throw bad("stuck=" + *arg + " is outside the valve's range " + range +
                  " (plant.valve.max_voltage_v of the simulated bench)");
      }
      f.stuck_v = *v;
      break;
    }
    case FaultMode::kFreeze:
    case FaultMode::kDead:
    case FaultMode::kSwapped: break;
  }
  return f;
}

std::optional<ValveVoltages> parse_watchdog_outputs(const std::string& text, double exhaust_v) {
  if (text == "neutral") return std::nullopt;
  if (text == "exhaust") return ValveVoltages{-exhaust_v, -exhaust_v};
  const auto comma = text.find(',');
  const auto p = comma == std::string::npos ? std::nullopt : parse_number(text.substr(0, comma));
  const auto n = comma == std::string::npos ? std::nullopt : parse_number(text.substr(comma + 1));
  if (!p || !n || !std::isfinite(*p) || !std::isfinite(*n))
    throw SpecError(text, "expected neutral, exhaust or U_P,U_N in volts (e.g. -10,-10)");
  return ValveVoltages{*p, *n};
}

}  // namespace pneu::plant_server
