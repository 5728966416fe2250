// The air in a chamber with heat exchange through its walls, and the valve spool's lag (docs/model.md
// section 2, "Heat exchange and the spool's lag"): the equations written once, for the simulated
// bench, the controller's forecasts, its estimate of the chamber temperatures and the
// identification. Pure functions and value types; real-time safe.
#pragma once

#include <cmath>

#include "pneu/model/params.hpp"

namespace pneu::model {

/// What a valve passes into a chamber, each of its two orifices at its upstream temperature (ISO
/// 6358: m = C rho_0 p_up sqrt(T_0 / T_up) phi): the supply's or the exhaust's (gas.temperature_k)
/// for air coming in, the chamber's for air going out.
struct ChamberInflow {
  double mass_kg_per_s = 0.0;        ///< net mass flow into the chamber [kg/s]
  /// The sum over the orifices of each one's flow into the chamber times its upstream temperature
  /// [K kg/s]; c_p times it is the enthalpy carried in.
  double enthalpy_k_kg_per_s = 0.0;
};

/// d/dt of a chamber's pressure and temperature.
struct ChamberRates {
  double dp_dt_pa_per_s = 0.0;
  double dtemperature_dt_k_per_s = 0.0;
};

/// Chamber P's wetted wall at position y: the bore's circumference times the chamber's length (its
/// dead volume counted as extra length) and both ends [m^2].
[[nodiscard]] double wall_area_p_m2(const Geometry& g, double y_m) noexcept;
/// Chamber N's: the bore's and the rod's circumferences times its length, and both (annular) ends [m^2].
[[nodiscard]] double wall_area_n_m2(const Geometry& g, double y_m) noexcept;

/// The energy balance of one chamber of volume V (Richer and Hurmuzlu 2000), with the adiabatic
/// index gamma, the gas constant r and the wall at T_w, heat flow Q = h A (T_w - T):
///   dp/dt = ( gamma r H - gamma p dV/dt + (gamma - 1) Q ) / V
///   dT/dt = T / (p V) ( gamma r H - r T M - (gamma - 1) p dV/dt + (gamma - 1) Q )
/// with M and H the chamber's ChamberInflow (from m = p V / (r T) and the first law). h = 0: p V^gamma
/// and T V^(gamma - 1) stay constant in a closed chamber; h large: T stays at T_w, p V constant.
class ThermalChamber {
 public:
  explicit ThermalChamber(const PlantParams& plant) noexcept
      : gamma_(plant.thermal.adiabatic_index),
        r_(plant.gas.gas_constant_j_per_kg_k),
        h_(plant.thermal.heat_transfer_w_per_m2_k),
        wall_k_(plant.wall_temperature_k()) {}

  [[nodiscard]] ChamberRates rates(const ChamberInflow& in, double p_pa, double t_k, double volume_m3,
                                   double dvolume_dt_m3_per_s, double wall_m2) const noexcept {
    const double heat_w = h_ * wall_m2 * (wall_k_ - t_k);
    const double shared = gamma_ * r_ * in.enthalpy_k_kg_per_s + (gamma_ - 1.0) * heat_w;
    return {(shared - gamma_ * p_pa * dvolume_dt_m3_per_s) / volume_m3,
            t_k / (p_pa * volume_m3) *
                (shared - r_ * t_k * in.mass_kg_per_s - (gamma_ - 1.0) * p_pa * dvolume_dt_m3_per_s)};
  }
  /// m c_v / (h A): how fast a closed chamber of this mass and wall relaxes to T_w [s] (at p, T, V).
  [[nodiscard]] double time_constant_s(double p_pa, double t_k, double volume_m3, double wall_m2) const noexcept {
    return p_pa * volume_m3 / ((gamma_ - 1.0) * t_k * h_ * wall_m2);
  }
  [[nodiscard]] double wall_temperature_k() const noexcept { return wall_k_; }
  [[nodiscard]] double adiabatic_index() const noexcept { return gamma_; }

 private:
  double gamma_, r_, h_, wall_k_;
};

/// The thermal time constant m c_v / (h A) of chamber P at mid-stroke, its air at the mean of the
/// supply and exhaust pressures and at the wall temperature [s]: the figure benches are quoted by
/// (the 32 mm bench: 1 s at h = 25.9 W/(m^2 K)).
[[nodiscard]] double thermal_time_constant_s(const PlantParams& plant) noexcept;
/// The h [W/(m^2 K)] that gives `plant` the thermal time constant `tau_s` (thermal_time_constant_s).
[[nodiscard]] double heat_transfer_for_time_constant(const PlantParams& plant, double tau_s) noexcept;

/// A spool that follows its command with a first-order lag (valve.spool_time_constant_s), as the
/// voltage its opening corresponds to. 0: no lag.
struct SpoolLag {
  double time_constant_s = 0.0;

  /// What the spool follows when commanded `w_v`: the command within the valve's travel, from
  /// fully open one way to fully open the other (w_0 -+ u_max); beyond it the spool is at its stop.
  [[nodiscard]] static double target_v(const ValveParams& v, double w_v) noexcept {
    return std::fmin(std::fmax(w_v, v.null_offset_v - v.max_voltage_v), v.null_offset_v + v.max_voltage_v);
  }

  /// Where a spool at `from_v` is `dt_s` later, commanded `target_v` all along (exact).
  [[nodiscard]] double after(double from_v, double target_v, double dt_s) const noexcept {
    if (!(time_constant_s > 0.0)) return target_v;
    return target_v + (from_v - target_v) * std::exp(-dt_s / time_constant_s);
  }
};

}  // namespace pneu::model
