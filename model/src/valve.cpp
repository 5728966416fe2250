#include "pneu/model/valve.hpp"

#include <algorithm>
#include <cmath>

#include "pneu/model/pressure_force.hpp"
#include "roots.hpp"

namespace pneu::model {

using detail::phi;

double flow_function(double x, double b) noexcept { return phi(x, b); }

double flow_function_slope(double x, double b) noexcept { return detail::phi_slope(std::clamp(x, 0.0, 1.0), b); }


// With m = K p_up phi(p_down / p_up), K = C rho_0 sqrt(T0/T):
//   dm/dp_down = K phi'(x)                      dm/dp_up = K (phi(x) - x phi'(x))
double Orifice::d_mass_flow_d_pb(double c, double p_a, double p_b) const noexcept {
  const double k = c * reference_density_kg_per_m3 * temperature_factor;
  if (p_a >= p_b) return k * flow_function_slope(p_b / p_a, critical_ratio);
  // Reversed: m = -K p_b phi(p_a / p_b); p_b is upstream.
  const double x = p_a / p_b;
  return -k * (flow_function(x, critical_ratio) - x * flow_function_slope(x, critical_ratio));
}

double Orifice::d_mass_flow_d_pa(double c, double p_a, double p_b) const noexcept {
  const double k = c * reference_density_kg_per_m3 * temperature_factor;
  if (p_a >= p_b) {
    const double x = p_b / p_a;
    return k * (flow_function(x, critical_ratio) - x * flow_function_slope(x, critical_ratio));
  }
  return -k * flow_function_slope(p_a / p_b, critical_ratio);
}

double ValveCharacteristic::null_pressure_pa(double w_v) const noexcept {
  return decreasing_root([&](double p) { return mass_flow_kg_per_s(w_v, p); }, min_pressure_pa(),
                         max_pressure_pa(), 1.0e-7);
}

ChamberInflow ValveCharacteristic::chamber_inflow(double w_v, double p_pa, double chamber_k,
                                                  double supply_k) const noexcept {
  const double q = mass_flow_kg_per_s(w_v, p_pa);
  if (q >= 0.0) return {q, q * supply_k};
  const double out = q * std::sqrt(supply_k / chamber_k);
  return {out, out * chamber_k};
}

double ValveCharacteristic::null_pressure_pa(double w_v, double chamber_k, double supply_k) const noexcept {
  return decreasing_root([&](double p) { return chamber_inflow(w_v, p, chamber_k, supply_k).mass_kg_per_s; },
                         min_pressure_pa(), max_pressure_pa(), 1.0e-7);
}

ValveModel::ValveModel(const ValveParams& valve, const Gas& gas) noexcept : valve_(valve), eq_(valve, gas) {}

double equilibrium_force_n(const ValveCharacteristic& valve, const Geometry& g, double p_e,
                           double u) noexcept {
  return PressureForce(g, p_e).force_n(valve.null_pressure_pa(u), valve.null_pressure_pa(-u));
}

double equilibrium_voltage_v(const ValveCharacteristic& valve, const Geometry& g,
                             double p_e) noexcept {
  // F_e(u) increases with u; the root of -F_e is found by the decreasing-root solver.
  const double u_lim = std::min(valve.max_voltage_v(), -valve.min_voltage_v());
  return decreasing_root([&](double u) { return -equilibrium_force_n(valve, g, p_e, u); }, -u_lim,
                         u_lim, 1.0e-12);
}

double equilibrium_force_n(const ValveCharacteristic& valve, const ChamberProcess& process, double u, double y) noexcept {
  return PressureForce(process.geometry(), process.exhaust_pressure_pa())
      .force_n(process.rest(valve, Side::kP, u, y).p_pa, process.rest(valve, Side::kN, -u, y).p_pa);
}

double equilibrium_voltage_v(const ValveCharacteristic& valve, const ChamberProcess& process, double y) noexcept {
  const double u_lim = std::min(valve.max_voltage_v(), -valve.min_voltage_v());
  return decreasing_root([&](double u) { return -equilibrium_force_n(valve, process, u, y); }, -u_lim, u_lim, 1.0e-12);
}

}  // namespace pneu::model
