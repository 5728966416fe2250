#include "pneu/model/chamber.hpp"

#include <algorithm>
#include <numbers>

#include "pneu/model/valve.hpp"
#include "roots.hpp"

namespace pneu::model {

double wall_area_p_m2(const Geometry& g, double y_m) noexcept { return wall_area_of_volume_p_m2(g, g.volume_p_m3(y_m)); }

double wall_area_n_m2(const Geometry& g, double y_m) noexcept { return wall_area_of_volume_n_m2(g, g.volume_n_m3(y_m)); }

namespace {
// m c_v / A of chamber P at mid-stroke, at the mean pressure and the wall temperature [J/(K m^2)].
double heat_capacity_per_wall_area(const PlantParams& p) {
  const double pressure = 0.5 * (p.gas.supply_pressure_pa + p.gas.exhaust_pressure_pa);
  const double heat_capacity = pressure * p.geometry.volume_p_m3(0.0) /
                               ((p.thermal.adiabatic_index - 1.0) * p.wall_temperature_k());  // m c_v
  return heat_capacity / wall_area_p_m2(p.geometry, 0.0);
}
}  // namespace

double thermal_time_constant_s(const PlantParams& plant) noexcept {
  return heat_capacity_per_wall_area(plant) / plant.thermal.heat_transfer_w_per_m2_k;
}

double heat_transfer_for_time_constant(const PlantParams& plant, double tau_s) noexcept {
  return heat_capacity_per_wall_area(plant) / tau_s;
}

template <>
ChamberRest BasicChamberProcess<double>::rest(const ValveCharacteristic& valve, Side side, double w_v, double y_m) const noexcept {
  if (!thermal_) return {valve.null_pressure_pa(w_v), supply_k_};
  const double wall_k = chamber_.wall_temperature_k();
  if (wall_k == supply_k_) return {valve.null_pressure_pa(w_v, wall_k, supply_k_), wall_k};
  // With no net flow, dp/dt = 0 and dT/dt = 0 both ask gamma r H + (gamma - 1) h A (T_w - T) = 0,
  // H = m_in (T_s - T): decreasing in T, of one sign at T_s and of the other at T_w.
  const double wall_m2 = side == Side::kP ? wall_area_p_m2(geometry_, y_m) : wall_area_n_m2(geometry_, y_m);
  const double gamma = chamber_.adiabatic_index(), r = gamma_r_ / gamma;
  const double h = chamber_.heat_transfer_w_per_m2_k();
  const auto balance = [&](double t_k) {
    const double p = valve.null_pressure_pa(w_v, t_k, supply_k_);
    return gamma * r * valve.chamber_inflow(w_v, p, t_k, supply_k_).enthalpy_k_kg_per_s +
           (gamma - 1.0) * h * wall_m2 * (wall_k - t_k);
  };
  const double lo = std::min(wall_k, supply_k_), hi = std::max(wall_k, supply_k_);
  const double t_k = decreasing_root(balance, lo, hi, 1e-9);
  return {valve.null_pressure_pa(w_v, t_k, supply_k_), t_k};
}

}  // namespace pneu::model
