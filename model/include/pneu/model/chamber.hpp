// The air in the two chambers (docs/model.md section 2): the polytropic process of Eq. 2, or the
// energy balance with heat exchange through the walls, and the valves' spools with their lag. The
// equations are written here once, for the simulated bench, the controller's forecasts, its estimate
// of the chamber temperatures and the identification. Value types and pure functions; real-time
// safe.
#pragma once

#include <cmath>
#include <cstdint>

#include "pneu/model/params.hpp"

namespace pneu::model {

class ValveCharacteristic;

/// What a valve passes into a chamber, each of its two orifices at its upstream temperature (ISO
/// 6358: m = C rho_0 p_up sqrt(T_0 / T_up) phi): the supply's or the exhaust's (gas.temperature_k)
/// for air coming in, the chamber's for air going out.
struct ChamberInflow {
  double mass_kg_per_s = 0.0;        ///< net mass flow into the chamber [kg/s]
  /// The sum over the orifices of each one's flow into the chamber times its upstream temperature
  /// [K kg/s]; c_p times it is the enthalpy carried in.
  double enthalpy_k_kg_per_s = 0.0;
};

/// Where a chamber at rest settles, its valve held.
struct ChamberRest {
  double p_pa = 0.0;  ///< the null-flow pressure (Fig. 6) [Pa]
  double t_k = 0.0;   ///< the temperature [K]
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
  ThermalChamber(const Gas& gas, const ThermalParams& thermal) noexcept
      : gamma_(thermal.adiabatic_index),
        r_(gas.gas_constant_j_per_kg_k),
        h_(thermal.heat_transfer_w_per_m2_k),
        wall_k_(thermal.wall_temperature_auto ? gas.temperature_k : thermal.wall_temperature_k) {}
  explicit ThermalChamber(const PlantParams& plant) noexcept : ThermalChamber(plant.gas, plant.thermal) {}

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
  [[nodiscard]] double heat_transfer_w_per_m2_k() const noexcept { return h_; }

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

  [[nodiscard]] bool lags() const noexcept { return time_constant_s > 0.0; }
  /// What the spool follows when commanded `w_v`: the command within the valve's travel, from
  /// fully open one way to fully open the other (ValveCharacteristic::spool_min_v, spool_max_v);
  /// beyond it the spool is at its stop.
  [[nodiscard]] static double target_v(const ValveCharacteristic& valve, double w_v) noexcept;
  /// Where a spool at `from_v` is `dt_s` later, commanded `target_v` all along (exact).
  [[nodiscard]] double after(double from_v, double target_v, double dt_s) const noexcept {
    if (!lags()) return target_v;
    return target_v + (from_v - target_v) * std::exp(-dt_s / time_constant_s);
  }
};

/// Which chamber.
enum class Side : std::uint8_t { kP, kN };

/// Both chambers and the spools as a model sees them at an instant.
struct ChamberState {
  double p_p_pa = 0.0, p_n_pa = 0.0;  ///< pressures [Pa abs]
  double t_p_k = 0.0, t_n_k = 0.0;    ///< temperatures [K]
  double w_p_v = 0.0, w_n_v = 0.0;    ///< the spools, as the voltages their openings correspond to [V]
};

/// The gas process of a plant model's two chambers, each fed by its valve (`valve`, the model or a
/// measured table): polytropic at the supply temperature (Eq. 2: dp/dt = k r T / V (q - p dV/dt /
/// (r T))), or with plant.thermal the energy balance of ThermalChamber.
class ChamberProcess {
 public:
  /// `thermal`: the energy balance's parameters, or null for the polytropic process.
  ChamberProcess(const Geometry& geometry, const Gas& gas, const ThermalParams* thermal) noexcept;
  explicit ChamberProcess(const PlantParams& plant) noexcept
      : ChamberProcess(plant.geometry, plant.gas, plant.has_thermal ? &plant.thermal : nullptr) {}

  /// dp/dt and dT/dt (0 for the polytropic process) of chamber `side` at pressure p and
  /// temperature T, its valve at voltage w, the carriage at y moving at v.
  [[nodiscard]] ChamberRates rates(const ValveCharacteristic& valve, Side side, double p_pa, double t_k, double w_v,
                                   double y_m, double v_m_per_s) const noexcept {
    return rates(valve, place(side, y_m, v_m_per_s), p_pa, t_k, w_v);
  }
  /// What rates() needs of chamber `side`'s geometry with the carriage at y moving at v: its volume,
  /// the volume's rate and (with the energy balance) the wall's area. An integration that holds y
  /// and v computes it once, and rates() from it is the same, bit for bit.
  struct Place {
    Side side;
    double volume_m3 = 0.0;
    double v_m_per_s = 0.0;
    double dvolume_dt_m3_per_s = 0.0;
    double wall_m2 = 0.0;  ///< the energy balance's only
  };
  [[nodiscard]] Place place(Side side, double y_m, double v_m_per_s) const noexcept;
  [[nodiscard]] ChamberRates rates(const ValveCharacteristic& valve, const Place& at, double p_pa, double t_k,
                                   double w_v) const noexcept;
  /// The rate at which chamber `side` at rest at y forgets a disturbance of its state (the
  /// largest of its local valve and thermal rates) [1/s]: for step sizes.
  [[nodiscard]] double fastest_rate_1_per_s(const ValveCharacteristic& valve, Side side, double p_pa, double t_k,
                                            double w_v, double y_m) const noexcept;

  [[nodiscard]] bool thermal() const noexcept { return thermal_; }
  [[nodiscard]] const ThermalChamber& thermal_chamber() const noexcept { return chamber_; }
  [[nodiscard]] double supply_temperature_k() const noexcept { return supply_k_; }
  [[nodiscard]] double exhaust_pressure_pa() const noexcept { return exhaust_pa_; }
  /// Where chamber `side` at rest at y settles, its valve held at w: the pressure at which the
  /// valve passes no net flow and, with the energy balance, the temperature at which the wall's
  /// heat balances what the valve's through-flow (the supply's air in, the chamber's out) carries:
  /// the wall's when the supply is at the wall's temperature, between the two otherwise (then
  /// depending a little on y, the wall's area). Polytropic: p_null(w) at the supply's temperature.
  [[nodiscard]] ChamberRest rest(const ValveCharacteristic& valve, Side side, double w_v, double y_m) const noexcept;
  [[nodiscard]] const Geometry& geometry() const noexcept { return geometry_; }
  [[nodiscard]] double volume_m3(Side side, double y_m) const noexcept {
    return side == Side::kP ? geometry_.dead_volume_p_m3 + area_p_m2_ * (half_stroke_m_ + y_m)
                            : geometry_.dead_volume_n_m3 + area_n_m2_ * (half_stroke_m_ - y_m);
  }

 private:
  Geometry geometry_;
  bool thermal_;
  ThermalChamber chamber_;
  double area_p_m2_, area_n_m2_, half_stroke_m_;
  double k_r_t_, r_t_, supply_k_, exhaust_pa_, gamma_r_;
};

/// The chambers' temperatures and the spools' positions, which no sensor gives, estimated from what
/// is measured (the position, both pressures) and commanded (each valve's voltage): each chamber's
/// temperature equation of the energy balance integrated along the measured pressures and volumes,
/// the spools' lag along the commands (docs/model.md section 6, "The chambers' state at a stop").
/// A value type; advance() and command() are real-time safe. Borrows `valve`, which must outlive it.
class ChamberObserver {
 public:
  ChamberObserver(const ChamberProcess& process, const ValveCharacteristic& valve, SpoolLag spool) noexcept
      : process_(process), valve_(&valve), spool_(spool) {}

  /// At rest at `t_s`: the chambers at their rest temperature, the spools at the commands.
  void reset(double t_s, double y_m, double p_p_pa, double p_n_pa, double u_p_v, double u_n_v) noexcept;
  /// Goes on from another estimate's state, time, position and commands (a model replaced).
  void resume(const ChamberObserver& other) noexcept {
    state_ = other.state_;
    t_s_ = other.t_s_;
    y_m_ = other.y_m_;
    u_p_v_ = other.u_p_v_;
    u_n_v_ = other.u_n_v_;
  }
  /// To `t_s` with the measurements then, the commands held since the last ones (from the last
  /// measurements, linearly in between). An earlier or equal time only takes the measurements.
  void advance(double t_s, double y_m, double p_p_pa, double p_n_pa) noexcept;
  /// The commands from now on: valve P at u_p, valve N at u_n [V].
  void command(double u_p_v, double u_n_v) noexcept {
    u_p_v_ = u_p_v;
    u_n_v_ = u_n_v;
  }
  /// The estimate at the last advance(), its pressures the measured ones.
  [[nodiscard]] const ChamberState& state() const noexcept { return state_; }
  [[nodiscard]] double t_s() const noexcept { return t_s_; }
  [[nodiscard]] const ChamberProcess& process() const noexcept { return process_; }

 private:
  ChamberProcess process_;
  const ValveCharacteristic* valve_;
  SpoolLag spool_;
  ChamberState state_{};
  double t_s_ = 0.0, y_m_ = 0.0;
  double u_p_v_ = 0.0, u_n_v_ = 0.0;
};

}  // namespace pneu::model
