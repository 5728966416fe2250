// The state feedback of Eq. 4, without integral action.
#pragma once

#include "pneu/config/config.hpp"

#include <algorithm>

namespace pneu::controller {

using config::ControlLawParams;


/// u = K_y (y_d - y) - K_v v_hat - K_a a_hat + u_0, saturated to [-u_max, u_max]. Real-time safe.
class ControlLaw {
 public:
  explicit ControlLaw(const ControlLawParams& p) noexcept : p_(p) {}
  [[nodiscard]] double control_v(double y_d_m, double y_m, double v_hat, double a_hat) const noexcept {
    const double u = p_.position_gain_v_per_m * (y_d_m - y_m) - p_.velocity_gain_v_s_per_m * v_hat -
                     p_.acceleration_gain_v_s2_per_m * a_hat + p_.offset_v;
    return std::clamp(u, -p_.max_voltage_v, p_.max_voltage_v);
  }
  /// u* of Eq. 11: the constant control once the carriage is at rest at y* (v_hat = a_hat = 0).
  [[nodiscard]] double resting_control_v(double y_d_m, double y_star_m) const noexcept {
    return control_v(y_d_m, y_star_m, 0.0, 0.0);
  }
  [[nodiscard]] const ControlLawParams& params() const noexcept { return p_; }

 private:
  ControlLawParams p_;
};

}  // namespace pneu::controller
