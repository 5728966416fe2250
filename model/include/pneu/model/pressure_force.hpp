// The pressure force on the piston, Eq. 14 (docs/model.md section 2): the one place it is written,
// for the plant, the loop, the predictors and the tools.
#pragma once

#include "pneu/model/params.hpp"

namespace pneu::model {

/// F = S_P p_P - S_N p_N - S_r p_E [N], Eq. 14: both chamber pressures on the piston and the
/// exhaust pressure on the rod's outside, the force friction must oppose. The areas and p_E are
/// taken once, at construction. A value type; every method is real-time safe.
class PressureForce {
 public:
  PressureForce(const Geometry& geometry, double exhaust_pressure_pa) noexcept
      : area_p_m2_(geometry.area_p_m2()),
        area_n_m2_(geometry.area_n_m2()),
        area_rod_m2_(geometry.area_rod_m2()),
        exhaust_pressure_pa_(exhaust_pressure_pa) {}

  /// F for absolute chamber pressures p_P and p_N [Pa] (Eq. 14) [N].
  [[nodiscard]] double force_n(double p_p_pa, double p_n_pa) const noexcept {
    return area_p_m2_ * p_p_pa - area_n_m2_ * p_n_pa - area_rod_m2_ * exhaust_pressure_pa_;
  }

  /// The pressure-force plane of Fig. 7 (docs/model.md section 5), where F = x - y: the pushing
  /// side x = S_P p_P ...
  [[nodiscard]] double plane_x_n(double p_p_pa) const noexcept { return area_p_m2_ * p_p_pa; }
  /// ... and the opposing side y = S_N p_N + S_r p_E [N].
  [[nodiscard]] double plane_y_n(double p_n_pa) const noexcept {
    return area_n_m2_ * p_n_pa + area_rod_m2_ * exhaust_pressure_pa_;
  }

  [[nodiscard]] double area_p_m2() const noexcept { return area_p_m2_; }  ///< S_P
  [[nodiscard]] double area_n_m2() const noexcept { return area_n_m2_; }  ///< S_N
  [[nodiscard]] double area_rod_m2() const noexcept { return area_rod_m2_; }  ///< S_r
  [[nodiscard]] double exhaust_pressure_pa() const noexcept { return exhaust_pressure_pa_; }  ///< p_E

 private:
  double area_p_m2_, area_n_m2_, area_rod_m2_, exhaust_pressure_pa_;
};

}  // namespace pneu::model
