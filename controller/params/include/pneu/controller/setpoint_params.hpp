// The set points a run follows by itself (controller.setpoints.schedule): each step a time and a
// position. The loop holds at most kMaxScheduleSteps of them (its parameters are fixed-size).
#pragma once

#include <cmath>
#include <cstddef>

#include "pneu/config/describe.hpp"

namespace pneu::controller {

/// One step of the set-point schedule.
struct SetpointStep {
  double t_s = 0.0;                 ///< from this time on [s], increasing
  double position_m = 0.0;          ///< the set point y_d [m], inside the stroke
};

/// The most steps a schedule may have (the loop holds them in a fixed-size table).
inline constexpr std::size_t kMaxScheduleSteps = 8192;

}  // namespace pneu::controller

namespace pneu::config::schema {

using controller::SetpointStep;

/// One step of controller.setpoints.schedule.
void describe(auto& a, Like<SetpointStep> auto& s, double half_stroke_m) {
  a.field(PNEU_NVP(s, t_s), Range::non_negative(), "from this time on [s]");
  a.field(PNEU_NVP(s, position_m), Range::any(), "the set point [m]");
  a.check("position_m", std::abs(s.position_m) <= half_stroke_m,
          [&] { return outside_the_stroke(half_stroke_m, s.position_m); });
}

}  // namespace pneu::config::schema
