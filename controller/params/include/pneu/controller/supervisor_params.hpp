// The supervisor's fault checks and the safe output (controller.supervisor).
#pragma once

#include <cstdint>
#include "pneu/config/describe.hpp"
#include "pneu/model/params.hpp"

namespace pneu::controller {

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

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::SafeOutput;
using controller::SupervisorConfig;

inline constexpr Choice<SafeOutput> kSafeOutputs[] = {{"neutral", SafeOutput::kNeutral},
                                                      {"exhaust", SafeOutput::kExhaust}};

/// `period_s`: the loop's.
void describe(auto& a, Like<SupervisorConfig> auto& s, const model::PlantParams& plant, double period_s) {
  const double half = plant.geometry.half_stroke_m();
  constexpr const char* kMustContainTheStroke =
      " m (the range must contain the stroke: a carriage at an end stop is not a fault)";
  a.field(PNEU_NVP(s, position_min_m), Range::any(), "position readings below are out of range [m]");
  a.field(PNEU_NVP(s, position_max_m), Range::any(), "position readings above are out of range [m]");
  a.check("position_max_m", s.position_max_m > s.position_min_m, "must exceed position_min_m");
  a.check("position_min_m", s.position_min_m <= -half,
          [&] { return "must not exceed the stroke's lower end " + fmt(-half) + kMustContainTheStroke; });
  a.check("position_max_m", s.position_max_m >= half,
          [&] { return "must not lie below the stroke's upper end " + fmt(half) + kMustContainTheStroke; });
  a.field(PNEU_NVP(s, pressure_min_pa), Range::non_negative(), "pressure readings below are out of range [Pa]");
  a.field(PNEU_NVP(s, pressure_max_pa), Range::positive(), "pressure readings above are out of range [Pa]");
  a.check("pressure_max_pa", s.pressure_max_pa > s.pressure_min_pa, "must exceed pressure_min_pa");
  a.check("pressure_max_pa", s.pressure_max_pa > plant.gas.supply_pressure_pa, [&] {
    return "must exceed the supply pressure (" + fmt(plant.gas.supply_pressure_pa) + " Pa): a chamber may reach it";
  });
  a.check("pressure_min_pa", s.pressure_min_pa < plant.gas.exhaust_pressure_pa, [&] {
    return "must lie below the exhaust pressure (" + fmt(plant.gas.exhaust_pressure_pa) +
           " Pa): a chamber may reach it";
  });
  a.field(PNEU_NVP(s, max_speed_m_per_s), Range::non_negative(), "the position sensor jumped [m/s]; 0 = off");
  a.field(PNEU_NVP(s, frozen_after_s), Range::closed(0.0, 60.0), "a pressure reading frozen this long [s]");
  a.field(PNEU_NVP(s, overtravel_m), Range::non_negative(), "armed: overshoot allowed past the soft limits [m]");
  a.field(PNEU_NVP(s, following_error_m), Range::positive(), "|y_d - y| above this ... [m]");
  a.field(PNEU_NVP(s, following_error_s), Range::closed(0.0, 600.0), "... this long is a fault [s]; 0 = off");
  a.field(optional(PNEU_NVP(s, oscillation_amplitude_m)), Range::positive(),
          "armed: each half-swing of y_d - y beyond +- this ... [m]");
  a.field(optional(PNEU_NVP(s, oscillation_sign_changes)),
          IntRange::in(0, SupervisorConfig::kMaxOscillationSignChanges),
          "... this many sign changes of the error ...; 0 = off");
  a.field(optional(PNEU_NVP(s, oscillation_window_s)), Range::positive(), "... within this long is a fault [s]");
  a.field(optional(PNEU_NVP(s, settle_time_s)), Range::closed(0.0, 600.0),
          "armed: no rest this long after a set-point change is a fault [s]; 0 = off");
  a.field(PNEU_NVP(s, overruns_in_a_row), IntRange::in(0, 1000000).says("must be in [0, 1000000] (0 = off)"),
          "this many overruns in a row are a fault; 0 = off");
  a.field(PNEU_NVP(s, max_tick_interval_s), Range::closed(0.0, 10.0),
          "a longer tick interval is a fault [s]; 0 = off");
  a.check("max_tick_interval_s", s.max_tick_interval_s == 0.0 || s.max_tick_interval_s > period_s,
          [&] { return "must exceed the loop period (" + fmt(period_s) + " s), or be 0 (off)"; });
  a.field(PNEU_NVP(s, safe_output), one_of(kSafeOutputs), "the valves' output while a fault is latched");
}

}  // namespace pneu::config::schema
