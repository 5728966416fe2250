// The in-position hold's law (docs/model.md section 11), written once for the loop that runs it
// and for the live predictor that forecasts under its commands (predict_held). A value type: no
// allocation, no exception; real-time safe.
#pragma once

#include <algorithm>

#include "pneu/controller/hold_params.hpp"

namespace pneu::controller {

/// Where a hold stands: fixed when it starts, but for its integral term.
struct HoldState {
  double t0_s = 0.0;       ///< when the hold started [s]
  /// Where the reference starts: the pressure force measured then (reaching: at least
  /// hold.reach_preload of the stiction bound it must cross) [N]
  double force0_n = 0.0;
  double u0_v = 0.0;       ///< u* then (Eq. 11): the law builds on it [V]
  double target_n = 0.0;   ///< where the reference ends: the stiction band's middle [N]
  /// +1 / -1: reaching the window, the reference ramped that way at reach_rate_n_per_s until the
  /// carriage moves; 0: holding within the window.
  int reach_direction = 0;
  double reach_rate_n_per_s = 0.0;  ///< the reach's ramp rate (halved after a reach went past) [N/s]
  double integral_v = 0.0;          ///< the PI's integral term [V]
};

/// u = u* + K_F (F_ref - F) + K_I * integral of (F_ref - F), saturated; F_ref from the force at the
/// hold's start to the band's middle over hold.ramp_s, or (reaching) ramped towards the set point.
class HoldLaw {
 public:
  HoldLaw(const HoldConfig& hold, double max_voltage_v, double period_s) noexcept
      : hold_(hold), u_max_v_(max_voltage_v), period_s_(period_s) {}

  /// F_ref at `t_s` [N].
  [[nodiscard]] double reference_n(const HoldState& s, double t_s) const noexcept {
    const double elapsed = t_s - s.t0_s;
    if (s.reach_direction != 0) return s.force0_n + s.reach_direction * s.reach_rate_n_per_s * elapsed;
    const double ramp = hold_.ramp_s > 0.0 ? std::clamp(elapsed / hold_.ramp_s, 0.0, 1.0) : 1.0;
    return s.force0_n + (s.target_n - s.force0_n) * ramp;
  }
  /// The reference has reached its target (holding within the window only).
  [[nodiscard]] bool ramp_done(const HoldState& s, double t_s) const noexcept {
    return s.reach_direction == 0 && t_s - s.t0_s >= hold_.ramp_s;
  }
  /// One tick's command from the force measured at `t_s`; advances the integral by the tick. A bad
  /// sample (`read_ok` false) adds nothing to it.
  [[nodiscard]] double command_v(HoldState& s, double t_s, double force_n, bool read_ok) const noexcept {
    const double error = read_ok ? reference_n(s, t_s) - force_n : 0.0;
    s.integral_v = std::clamp(s.integral_v + hold_.integral_gain_v_per_n_s * error * period_s_, -u_max_v_ - s.u0_v,
                              u_max_v_ - s.u0_v);
    return std::clamp(s.u0_v + hold_.force_gain_v_per_n * error + s.integral_v, -u_max_v_, u_max_v_);
  }
  [[nodiscard]] double period_s() const noexcept { return period_s_; }
  [[nodiscard]] const HoldConfig& config() const noexcept { return hold_; }

 private:
  HoldConfig hold_;
  double u_max_v_;
  double period_s_;
};

}  // namespace pneu::controller
