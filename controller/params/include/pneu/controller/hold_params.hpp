// The parameters of the in-position hold (controller.hold).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

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

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::HoldConfig;

void describe(auto& a, Like<HoldConfig> auto& h) {
  a.field(PNEU_NVP(h, enabled), "true: hold the carriage at rest within the window by its pressure force");
  a.field(PNEU_NVP(h, window_m), Range::positive(), "at rest this close to the set point: hold [m]");
  a.field(PNEU_NVP(h, force_gain_v_per_n), Range::non_negative(), "u = u* + this * (F_ref - F) + ... [V/N]");
  a.field(PNEU_NVP(h, integral_gain_v_per_n_s), Range::non_negative(),
          "... + this * integral of (F_ref - F) [V/(N s)]");
  a.field(PNEU_NVP(h, ramp_s), Range::non_negative(),
          "F_ref from the force at the hold's start to the stiction band's middle over this long [s]");
  a.field(optional(PNEU_NVP(h, reach_m)), Range::non_negative(),
          "at rest outside the window but this close: break away towards the set point [m]; 0 = off");
  a.field(optional(PNEU_NVP(h, reach_rate_n_per_s)), Range::positive(), "... the force ramped this fast [N/s]");
  a.field(optional(PNEU_NVP(h, reach_preload)), Range::closed(0.0, 0.95),
          "... from this share of the stiction bound it must cross (or the force, if past it) [-]");
}

}  // namespace pneu::config::schema
