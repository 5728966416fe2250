#include "pneu/model/chamber.hpp"

#include <numbers>

namespace pneu::model {

double wall_area_p_m2(const Geometry& g, double y_m) noexcept {
  const double length = g.volume_p_m3(y_m) / g.area_p_m2();
  return std::numbers::pi * g.bore_diameter_m * length + 2.0 * g.area_p_m2();
}

double wall_area_n_m2(const Geometry& g, double y_m) noexcept {
  const double length = g.volume_n_m3(y_m) / g.area_n_m2();
  return std::numbers::pi * (g.bore_diameter_m + g.rod_diameter_m) * length + 2.0 * g.area_n_m2();
}

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

}  // namespace pneu::model
