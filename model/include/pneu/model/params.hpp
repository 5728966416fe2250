// Parameters of the bench model (docs/model.md sections 1-4 and 7): what the simulated plant
// integrates and the controller's predictors assume. Plain aggregates in SI units; user input is
// validated by pneu::config before it gets here, the users only assert invariants.
#pragma once

#include <numbers>

namespace pneu::model {

/// Cylinder geometry. Position y is measured from mid-stroke, y in [-L/2, +L/2]; positive y grows
/// chamber P (bore side).
struct Geometry {
  double stroke_m = 0.500;           ///< L, full stroke [m], > 0
  double bore_diameter_m = 0.032;    ///< piston diameter [m], > rod diameter
  double rod_diameter_m = 0.020;     ///< rod diameter [m], in (0, bore)
  double dead_volume_p_m3 = 1.0e-5;  ///< V_P0, chamber P volume at y = -L/2, tubes included [m^3], > 0
  double dead_volume_n_m3 = 1.0e-5;  ///< V_N0, chamber N volume at y = +L/2, tubes included [m^3], > 0

  [[nodiscard]] double area_p_m2() const noexcept {  ///< S_P
    return std::numbers::pi / 4.0 * bore_diameter_m * bore_diameter_m;
  }
  [[nodiscard]] double area_rod_m2() const noexcept {  ///< S_r
    return std::numbers::pi / 4.0 * rod_diameter_m * rod_diameter_m;
  }
  [[nodiscard]] double area_n_m2() const noexcept { return area_p_m2() - area_rod_m2(); }  ///< S_N
  [[nodiscard]] double half_stroke_m() const noexcept { return 0.5 * stroke_m; }
  /// V_P(y) = V_P0 + S_P (L/2 + y)  [m^3]
  [[nodiscard]] double volume_p_m3(double y_m) const noexcept {
    return dead_volume_p_m3 + area_p_m2() * (half_stroke_m() + y_m);
  }
  /// V_N(y) = V_N0 + S_N (L/2 - y)  [m^3]
  [[nodiscard]] double volume_n_m3(double y_m) const noexcept {
    return dead_volume_n_m3 + area_n_m2() * (half_stroke_m() - y_m);
  }
};

/// Air and the pressure sources. Pressures are absolute.
struct Gas {
  double supply_pressure_pa = 7.0e5;            ///< p_S [Pa], > p_E
  double exhaust_pressure_pa = 1.0e5;           ///< p_E, also the pressure on the rod's outside [Pa], > 0
  double polytropic_index = 1.2;                ///< k [-], in [1, 1.4]
  double gas_constant_j_per_kg_k = 287.0;       ///< r [J/(kg K)], > 0
  double temperature_k = 293.15;                ///< T, supply and chamber temperature [K], > 0

  [[nodiscard]] double k_r_t() const noexcept {  ///< k r T [J/kg]
    return polytropic_index * gas_constant_j_per_kg_k * temperature_k;
  }
};

/// 3-way servo-distributor: two ISO 6358 orifices (supply -> chamber, chamber -> exhaust) whose
/// sonic conductances follow the voltage w (docs/model.md section 3).
struct ValveParams {
  double max_conductance_m3_per_s_pa = 1.6e-8;    ///< C_max [m^3/(s Pa)], > 0
  double critical_pressure_ratio = 0.3;           ///< b [-], in (0, 1)
  double leak_conductance_in_m3_per_s_pa = 8.0e-10;    ///< C_leak_in [m^3/(s Pa)], >= 0
  double leak_conductance_out_m3_per_s_pa = 1.28e-9;   ///< C_leak_out [m^3/(s Pa)], >= 0
  double max_voltage_v = 10.0;                    ///< u_max: full opening [V], > 0
  /// The voltage at which a valve is closed (both orifices at their leaks): a real servo-valve's
  /// null offset [V], |w_0| < u_max; the opening is w - w_0.
  double null_offset_v = 0.0;
  double reference_density_kg_per_m3 = 1.185;     ///< rho_0 of ISO 6358 [kg/m^3]
  double reference_temperature_k = 293.15;        ///< T_0 of ISO 6358 [K]
  /// The spool follows its command with a first-order lag of this time constant [s], >= 0; 0: it
  /// opens the instant it is commanded (docs/model.md section 3).
  double spool_time_constant_s = 0.0;
};

/// The chambers' energy balance with heat exchange through their walls (docs/model.md section 2,
/// "With heat exchange"): in place of the polytropic process at constant temperature, each chamber
/// has a temperature of its own; the air enters at its upstream temperature, leaves at the
/// chamber's, and exchanges h A(y) (T_w - T) with the wall.
struct ThermalParams {
  double heat_transfer_w_per_m2_k = 25.9;  ///< h: wall heat transfer coefficient [W/(m^2 K)], > 0
  double adiabatic_index = 1.4;            ///< gamma = c_p / c_v of the air [-], in (1, 1.67]
  /// T_w: the walls' temperature [K], > 0, unless `wall_temperature_auto`: the supply's, gas.temperature_k.
  double wall_temperature_k = 293.15;
  bool wall_temperature_auto = true;
};

/// Karnopp friction with Stribeck effect, asymmetric (docs/model.md section 4).
struct FrictionParams {
  double static_positive_n = 45.0;       ///< F_S+ [N], > 0, >= F_C+
  double coulomb_positive_n = 35.0;      ///< F_C+ [N], > 0
  double static_negative_n = -50.0;      ///< F_S- [N], < 0, <= F_C-
  double coulomb_negative_n = -38.0;     ///< F_C- [N], < 0
  double viscous_n_s_per_m = 60.0;       ///< sigma [N s/m], >= 0
  double stribeck_velocity_m_per_s = 0.01;  ///< v_s [m/s], > 0
  /// Sliding -> stuck also when |v| falls below this band while decelerating with F inside the
  /// stiction band, so that an asymptotic approach to v = 0 sticks too [m/s], >= 0.
  double stick_velocity_m_per_s = 1.0e-4;
};

/// Everything the plant model needs.
struct PlantParams {
  Geometry geometry;
  double mass_kg = 17.0;  ///< M, moving mass (piston, rod, carriage, load) [kg], > 0
  Gas gas;
  ValveParams valve;
  FrictionParams friction;
  /// With `has_thermal`, the chambers' process is `thermal`'s energy balance; without, polytropic at
  /// gas.temperature_k with gas.polytropic_index (Eq. 2).
  bool has_thermal = false;
  ThermalParams thermal;
  /// Largest integration step while the carriage slides [s], and while it is stuck. The plant
  /// further limits them to keep explicit RK4 stable on the step's fastest pressure mode (see
  /// Plant::step_size_s()).
  double max_step_s = 3.4e-4;
  double max_stuck_step_s = 1.0e-3;

  /// T_w [K]: thermal.wall_temperature_k, or the supply's (gas.temperature_k) when auto.
  [[nodiscard]] double wall_temperature_k() const noexcept {
    return thermal.wall_temperature_auto ? gas.temperature_k : thermal.wall_temperature_k;
  }
};

/// An external force on the carriage, a step from `t_s` for `duration_s` (a push by hand, a
/// collision): the simulated bench's disturbance input, not a parameter of the plant's model.
struct Push {
  double t_s = 0.0;         ///< it starts [s]
  double force_n = 0.0;     ///< towards +y while it lasts [N]
  double duration_s = 0.0;  ///< [s], > 0
};

}  // namespace pneu::model
