// The state feedback of Eq. 4, without integral action, with fixed gains or gains scheduled by
// position.
#pragma once

#include "pneu/controller/law_params.hpp"
#include "pneu/model/tangent_linear.hpp"

#include <algorithm>

namespace pneu::controller {



/// u = K_y (y_d - y) - K_v v_hat - K_a a_hat + u_0, saturated to [-u_max, u_max], with the gains
/// of controller.law (fixed) or those of a table designed at start-up, interpolated at the measured
/// position y (scheduled, controller.law.gains). The table is held by value in fixed storage:
/// copying the law never allocates. Real-time safe.
class ControlLaw {
 public:
  /// Fixed gains: those of `p`.
  explicit ControlLaw(const ControlLawParams& p) noexcept : p_(p) {}
  /// Gains scheduled by position: those of `schedule` (u_0 and u_max from `p`).
  ControlLaw(const ControlLawParams& p, const model::GainSchedule& schedule) noexcept
      : p_(p), schedule_(schedule) {}

  /// The gains in force at position y [m].
  [[nodiscard]] model::LawGains gains_at(double y_m) const noexcept {
    if (!schedule_.empty()) return schedule_.gains_at(y_m);
    return {p_.position_gain_v_per_m, p_.velocity_gain_v_s_per_m, p_.acceleration_gain_v_s2_per_m};
  }
  [[nodiscard]] double control_v(double y_d_m, double y_m, double v_hat, double a_hat) const noexcept {
    const model::LawGains g = gains_at(y_m);
    const double u = g.position_gain_v_per_m * (y_d_m - y_m) - g.velocity_gain_v_s_per_m * v_hat -
                     g.acceleration_gain_v_s2_per_m * a_hat + p_.offset_v;
    return std::clamp(u, -p_.max_voltage_v, p_.max_voltage_v);
  }
  /// u* of Eq. 11: the constant control once the carriage is at rest at y* (v_hat = a_hat = 0),
  /// with the gains at y*.
  [[nodiscard]] double resting_control_v(double y_d_m, double y_star_m) const noexcept {
    return control_v(y_d_m, y_star_m, 0.0, 0.0);
  }
  [[nodiscard]] const ControlLawParams& params() const noexcept { return p_; }
  /// The same law with every gain, fixed or scheduled, multiplied by `factor` (u_0 and u_max kept).
  [[nodiscard]] ControlLaw scaled(double factor) const noexcept {
    ControlLaw law = *this;
    law.p_.position_gain_v_per_m *= factor;
    law.p_.velocity_gain_v_s_per_m *= factor;
    law.p_.acceleration_gain_v_s2_per_m *= factor;
    law.schedule_ = schedule_.scaled(factor);
    return law;
  }
  /// The table of scheduled gains; empty with fixed gains.
  [[nodiscard]] const model::GainSchedule& schedule() const noexcept { return schedule_; }

 private:
  ControlLawParams p_;
  model::GainSchedule schedule_;
};

}  // namespace pneu::controller
