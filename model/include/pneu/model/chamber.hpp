// The air in the two chambers (docs/model.md section 2): the polytropic process of Eq. 2, or the
// energy balance with heat exchange through the walls, and the valves' spools with their lag. The
// equations are written here once, for the simulated bench, the controller's forecasts, its estimate
// of the chamber temperatures and the identification. Value types and pure functions; real-time
// safe.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>

#include "pneu/model/dual.hpp"
#include "pneu/model/params.hpp"

namespace pneu::model {

class ValveCharacteristic;

/// What a valve passes into a chamber, each of its two orifices at its upstream temperature (ISO
/// 6358: m = C rho_0 p_up sqrt(T_0 / T_up) phi): the supply's or the exhaust's (gas.temperature_k)
/// for air coming in, the chamber's for air going out. (S: double, or a Dual with derivatives.)
template <class S>
struct BasicChamberInflow {
  S mass_kg_per_s = S(0.0);        ///< net mass flow into the chamber [kg/s]
  /// The sum over the orifices of each one's flow into the chamber times its upstream temperature
  /// [K kg/s]; c_p times it is the enthalpy carried in.
  S enthalpy_k_kg_per_s = S(0.0);
};
using ChamberInflow = BasicChamberInflow<double>;

/// Where a chamber at rest settles, its valve held.
struct ChamberRest {
  double p_pa = 0.0;  ///< the null-flow pressure (Fig. 6) [Pa]
  double t_k = 0.0;   ///< the temperature [K]
};

/// d/dt of a chamber's pressure and temperature.
template <class S>
struct BasicChamberRates {
  S dp_dt_pa_per_s = S(0.0);
  S dtemperature_dt_k_per_s = S(0.0);
};
using ChamberRates = BasicChamberRates<double>;

/// Chamber P's wetted wall at position y: the bore's circumference times the chamber's length (its
/// dead volume counted as extra length) and both ends [m^2].
[[nodiscard]] double wall_area_p_m2(const Geometry& g, double y_m) noexcept;
/// Chamber N's: the bore's and the rod's circumferences times its length, and both (annular) ends [m^2].
[[nodiscard]] double wall_area_n_m2(const Geometry& g, double y_m) noexcept;
/// The same from the chamber's volume (S: double, or a Dual with derivatives).
template <class S>
[[nodiscard]] S wall_area_of_volume_p_m2(const Geometry& g, const S& volume_p_m3) noexcept {
  const S length = volume_p_m3 / g.area_p_m2();
  return std::numbers::pi * g.bore_diameter_m * length + 2.0 * g.area_p_m2();
}
template <class S>
[[nodiscard]] S wall_area_of_volume_n_m2(const Geometry& g, const S& volume_n_m3) noexcept {
  const S length = volume_n_m3 / g.area_n_m2();
  return std::numbers::pi * (g.bore_diameter_m + g.rod_diameter_m) * length + 2.0 * g.area_n_m2();
}

/// The energy balance of one chamber of volume V (Richer and Hurmuzlu 2000), with the adiabatic
/// index gamma, the gas constant r and the wall at T_w, heat flow Q = h A (T_w - T):
///   dp/dt = ( gamma r H - gamma p dV/dt + (gamma - 1) Q ) / V
///   dT/dt = T / (p V) ( gamma r H - r T M - (gamma - 1) p dV/dt + (gamma - 1) Q )
/// with M and H the chamber's ChamberInflow (from m = p V / (r T) and the first law). h = 0: p V^gamma
/// and T V^(gamma - 1) stay constant in a closed chamber; h large: T stays at T_w, p V constant.
/// (S: double, or a Dual with the derivatives by h among others.)
template <class S>
class BasicThermalChamber {
 public:
  BasicThermalChamber(const Gas& gas, const ThermalParams& thermal) noexcept
      : BasicThermalChamber(gas, thermal, S(thermal.heat_transfer_w_per_m2_k)) {}
  /// With the heat transfer `h` in place of thermal's.
  BasicThermalChamber(const Gas& gas, const ThermalParams& thermal, const S& h) noexcept
      : gamma_(thermal.adiabatic_index),
        r_(gas.gas_constant_j_per_kg_k),
        h_(h),
        wall_k_(thermal.wall_temperature_auto ? gas.temperature_k : thermal.wall_temperature_k) {}
  explicit BasicThermalChamber(const PlantParams& plant) noexcept : BasicThermalChamber(plant.gas, plant.thermal) {}

  [[nodiscard]] BasicChamberRates<S> rates(const BasicChamberInflow<S>& in, const S& p_pa, const S& t_k,
                                           const S& volume_m3, double dvolume_dt_m3_per_s,
                                           const S& wall_m2) const noexcept {
    const S heat_w = h_ * wall_m2 * (wall_k_ - t_k);
    const S shared = gamma_ * r_ * in.enthalpy_k_kg_per_s + (gamma_ - 1.0) * heat_w;
    return {(shared - gamma_ * p_pa * dvolume_dt_m3_per_s) / volume_m3,
            t_k / (p_pa * volume_m3) *
                (shared - r_ * t_k * in.mass_kg_per_s - (gamma_ - 1.0) * p_pa * dvolume_dt_m3_per_s)};
  }
  /// m c_v / (h A): how fast a closed chamber of this mass and wall relaxes to T_w [s] (at p, T, V;
  /// at the values).
  [[nodiscard]] double time_constant_s(double p_pa, double t_k, double volume_m3, double wall_m2) const noexcept {
    return p_pa * volume_m3 / ((gamma_ - 1.0) * t_k * value(h_) * wall_m2);
  }
  [[nodiscard]] double wall_temperature_k() const noexcept { return wall_k_; }
  [[nodiscard]] double adiabatic_index() const noexcept { return gamma_; }
  [[nodiscard]] const S& heat_transfer_w_per_m2_k() const noexcept { return h_; }

 private:
  double gamma_, r_;
  S h_;
  double wall_k_;
};
using ThermalChamber = BasicThermalChamber<double>;

/// The thermal time constant m c_v / (h A) of chamber P at mid-stroke, its air at the mean of the
/// supply and exhaust pressures and at the wall temperature [s]: the figure benches are quoted by
/// (the 32 mm bench: 1 s at h = 25.9 W/(m^2 K)).
[[nodiscard]] double thermal_time_constant_s(const PlantParams& plant) noexcept;
/// The h [W/(m^2 K)] that gives `plant` the thermal time constant `tau_s` (thermal_time_constant_s).
[[nodiscard]] double heat_transfer_for_time_constant(const PlantParams& plant, double tau_s) noexcept;

/// A spool that follows its command with a first-order lag (valve.spool_time_constant_s), as the
/// voltage its opening corresponds to. 0: no lag. (S: double, or a Dual with derivatives.)
template <class S>
struct BasicSpoolLag {
  S time_constant_s = S(0.0);

  [[nodiscard]] bool lags() const noexcept { return time_constant_s > 0.0; }
  /// What the spool follows when commanded `w_v`: the command within the valve's travel, from
  /// fully open one way to fully open the other (ValveCharacteristic::spool_min_v, spool_max_v);
  /// beyond it the spool is at its stop.
  template <class Valve>
  [[nodiscard]] static S target_v(const Valve& valve, double w_v) noexcept {
    using std::fmax;
    using std::fmin;
    return fmin(fmax(S(w_v), S(valve.spool_min_v())), S(valve.spool_max_v()));
  }
  /// Where a spool at `from_v` is `dt_s` later, commanded `target_v` all along (exact).
  template <class T = double>
  [[nodiscard]] S after(const S& from_v, const S& target_v, const T& dt_s) const noexcept {
    using std::exp;
    if (!lags()) return target_v;
    return target_v + (from_v - target_v) * exp(-dt_s / time_constant_s);
  }
};
using SpoolLag = BasicSpoolLag<double>;

/// Which chamber.
enum class Side : std::uint8_t { kP, kN };

/// Both chambers and the spools as a model sees them at an instant.
template <class S>
struct BasicChamberState {
  S p_p_pa = S(0.0), p_n_pa = S(0.0);  ///< pressures [Pa abs]
  S t_p_k = S(0.0), t_n_k = S(0.0);    ///< temperatures [K]
  S w_p_v = S(0.0), w_n_v = S(0.0);    ///< the spools, as the voltages their openings correspond to [V]
};
using ChamberState = BasicChamberState<double>;

/// The gas process of a plant model's two chambers, each fed by its valve (`valve`, the model or a
/// measured table): polytropic at the supply temperature (Eq. 2: dp/dt = k r T / V (q - p dV/dt /
/// (r T))), or with plant.thermal the energy balance of ThermalChamber. S: double (ChamberProcess),
/// or a Dual carrying the derivatives by the dead volumes and the heat transfer (the identification's).
template <class S>
class BasicChamberProcess {
 public:
  /// `thermal`: the energy balance's parameters, or null for the polytropic process.
  BasicChamberProcess(const Geometry& geometry, const Gas& gas, const ThermalParams* thermal) noexcept
      : BasicChamberProcess(geometry, gas, thermal, S(geometry.dead_volume_p_m3), S(geometry.dead_volume_n_m3),
                            S((thermal != nullptr ? *thermal : ThermalParams{}).heat_transfer_w_per_m2_k)) {}
  /// With the dead volumes and the heat transfer given in place of geometry's and thermal's.
  BasicChamberProcess(const Geometry& geometry, const Gas& gas, const ThermalParams* thermal, const S& dead_volume_p_m3,
                      const S& dead_volume_n_m3, const S& heat_transfer_w_per_m2_k) noexcept
      : geometry_(geometry),
        thermal_(thermal != nullptr),
        chamber_(gas, thermal != nullptr ? *thermal : ThermalParams{}, heat_transfer_w_per_m2_k),
        dead_p_m3_(dead_volume_p_m3),
        dead_n_m3_(dead_volume_n_m3),
        area_p_m2_(geometry.area_p_m2()),
        area_n_m2_(geometry.area_n_m2()),
        half_stroke_m_(geometry.half_stroke_m()),
        k_r_t_(gas.k_r_t()),
        r_t_(gas.gas_constant_j_per_kg_k * gas.temperature_k),
        supply_k_(gas.temperature_k),
        exhaust_pa_(gas.exhaust_pressure_pa),
        gamma_r_((thermal != nullptr ? thermal->adiabatic_index : gas.polytropic_index) * gas.gas_constant_j_per_kg_k) {}
  explicit BasicChamberProcess(const PlantParams& plant) noexcept
      : BasicChamberProcess(plant.geometry, plant.gas, plant.has_thermal ? &plant.thermal : nullptr) {}

  /// dp/dt and dT/dt (0 for the polytropic process) of chamber `side` at pressure p and
  /// temperature T, its valve at voltage w, the carriage at y moving at v.
  template <class Valve>
  [[nodiscard]] BasicChamberRates<S> rates(const Valve& valve, Side side, const S& p_pa, const S& t_k, const S& w_v,
                                           double y_m, double v_m_per_s) const noexcept {
    return rates(valve, place(side, y_m, v_m_per_s), p_pa, t_k, w_v);
  }
  /// What rates() needs of chamber `side`'s geometry with the carriage at y moving at v: its volume,
  /// the volume's rate and (with the energy balance) the wall's area. An integration that holds y
  /// and v computes it once, and rates() from it is the same, bit for bit.
  struct Place {
    Side side;
    S volume_m3 = S(0.0);
    double v_m_per_s = 0.0;
    double dvolume_dt_m3_per_s = 0.0;
    S wall_m2 = S(0.0);  ///< the energy balance's only
  };
  [[nodiscard]] Place place(Side side, double y, double v) const noexcept {
    const bool p_side = side == Side::kP;
    const S volume = volume_m3(side, y);
    return {side, volume, v, p_side ? area_p_m2_ * v : -area_n_m2_ * v,
            !thermal_ ? S(0.0) : p_side ? wall_area_of_volume_p_m2(geometry_, volume) : wall_area_of_volume_n_m2(geometry_, volume)};
  }
  // Eq. 2's pressure equation, or the energy balance (docs/model.md section 2). The polytropic form is
  // the plant's own, term for term (the simulated bench is bit for bit what it was).
  template <class Valve>
  [[nodiscard]] BasicChamberRates<S> rates(const Valve& valve, const Place& at, const S& p, const S& t_k,
                                           const S& w) const noexcept {
    const S& volume = at.volume_m3;
    if (!thermal_)
      return {polytropic_dp_dt(at.side, k_r_t_ / volume, valve.mass_flow_kg_per_s(w, p), p, at.v_m_per_s),
              S(0.0)};
    return chamber_.rates(valve.chamber_inflow(w, p, t_k, supply_k_), p, t_k, volume, at.dvolume_dt_m3_per_s, at.wall_m2);
  }
  /// A polytropic chamber held at its place with its valve (the model's equations) held at an
  /// opening, as an integration over a stuck carriage's step without a spool lag holds them: what
  /// rates() would work out again at each call, once. dp_dt() from it is rates()'s, bit for bit.
  template <class Valve>
  struct Held {
    Side side;
    double v_m_per_s;
    S k_r_t_over_volume;
    typename Valve::Opening opening;
  };
  template <class Valve>
  [[nodiscard]] Held<Valve> held(const Valve& valve, const Place& at, const S& w) const noexcept {
    return {at.side, at.v_m_per_s, k_r_t_ / at.volume_m3, valve.opening(w)};
  }
  template <class Valve>
  [[nodiscard]] S dp_dt(const Valve& valve, const Held<Valve>& h, const S& p) const noexcept {
    return polytropic_dp_dt(h.side, h.k_r_t_over_volume, valve.mass_flow_kg_per_s(h.opening, p), p, h.v_m_per_s);
  }
  /// The rate at which chamber `side` at rest at y forgets a disturbance of its state (the
  /// largest of its local valve and thermal rates) [1/s]: for step sizes (at the values).
  template <class Valve>
  [[nodiscard]] double fastest_rate_1_per_s(const Valve& valve, Side side, double p, double t_k, double w,
                                            double y) const noexcept {
    const double volume = value(volume_m3(side, y));
    if (!thermal_) return k_r_t_ / volume * -valve.dq_dp(w, p);
    // The valve's: gamma r T / V (-dq/dp) (the flow's temperature factor aside); the wall's: 1 / (m c_v / (h A)).
    const double wall = value(side == Side::kP ? wall_area_of_volume_p_m2(geometry_, volume_m3(side, y))
                                               : wall_area_of_volume_n_m2(geometry_, volume_m3(side, y)));
    return std::max(gamma_r_ * t_k / volume * -valve.dq_dp(w, p), 1.0 / chamber_.time_constant_s(p, t_k, volume, wall));
  }

  [[nodiscard]] bool thermal() const noexcept { return thermal_; }
  [[nodiscard]] const BasicThermalChamber<S>& thermal_chamber() const noexcept { return chamber_; }
  [[nodiscard]] double supply_temperature_k() const noexcept { return supply_k_; }
  [[nodiscard]] double exhaust_pressure_pa() const noexcept { return exhaust_pa_; }
  /// Where chamber `side` at rest at y settles, its valve held at w: the pressure at which the
  /// valve passes no net flow and, with the energy balance, the temperature at which the wall's
  /// heat balances what the valve's through-flow (the supply's air in, the chamber's out) carries:
  /// the wall's when the supply is at the wall's temperature, between the two otherwise (then
  /// depending a little on y, the wall's area). Polytropic: p_null(w) at the supply's temperature.
  /// (ChamberProcess's only.)
  [[nodiscard]] ChamberRest rest(const ValveCharacteristic& valve, Side side, double w_v, double y_m) const noexcept;
  [[nodiscard]] const Geometry& geometry() const noexcept { return geometry_; }
  [[nodiscard]] S volume_m3(Side side, double y_m) const noexcept {
    return side == Side::kP ? dead_p_m3_ + area_p_m2_ * (half_stroke_m_ + y_m)
                            : dead_n_m3_ + area_n_m2_ * (half_stroke_m_ - y_m);
  }

 private:
  Geometry geometry_;
  bool thermal_;
  BasicThermalChamber<S> chamber_;
  S dead_p_m3_, dead_n_m3_;
  double area_p_m2_, area_n_m2_, half_stroke_m_;
  double k_r_t_, r_t_, supply_k_, exhaust_pa_, gamma_r_;

  // Eq. 2's pressure equation, dp/dt = k r T / V (q -+ S p v / (r T)), from k r T / V.
  [[nodiscard]] S polytropic_dp_dt(Side side, const S& k_r_t_over_volume, const S& q, const S& p,
                                   double v) const noexcept {
    return side == Side::kP ? k_r_t_over_volume * (q - area_p_m2_ * p * v / r_t_)
                            : k_r_t_over_volume * (q + area_n_m2_ * p * v / r_t_);
  }
};
using ChamberProcess = BasicChamberProcess<double>;
template <>
ChamberRest BasicChamberProcess<double>::rest(const ValveCharacteristic& valve, Side side, double w_v,
                                              double y_m) const noexcept;

/// The chambers' temperatures and the spools' positions, which no sensor gives, estimated from what
/// is measured (the position, both pressures) and commanded (each valve's voltage): each chamber's
/// temperature equation of the energy balance integrated along the measured pressures and volumes,
/// the spools' lag along the commands (docs/model.md section 6, "The chambers' state at a stop").
/// A value type; advance() and command() are real-time safe. Borrows `valve`, which must outlive it.
/// S, Valve: double and ValveCharacteristic (ChamberObserver), or a Dual and the valve's equations
/// with it (the identification's derivatives of the estimate by the model's parameters).
template <class S, class Valve>
class BasicChamberObserver {
 public:
  BasicChamberObserver(const BasicChamberProcess<S>& process, const Valve& valve, BasicSpoolLag<S> spool) noexcept
      : process_(process), valve_(&valve), spool_(spool) {}

  /// At rest at `t_s`: the chambers at their rest temperature, the spools at the commands.
  void reset(double t_s, double y_m, double p_p_pa, double p_n_pa, double u_p_v, double u_n_v) noexcept {
    start(t_s, y_m,
          {p_p_pa, p_n_pa, process_.rest(*valve_, Side::kP, u_p_v, y_m).t_k, process_.rest(*valve_, Side::kN, u_n_v, y_m).t_k,
           BasicSpoolLag<S>::target_v(*valve_, u_p_v), BasicSpoolLag<S>::target_v(*valve_, u_n_v)},
          u_p_v, u_n_v);
  }
  /// At `t_s` in `state`, commanded u_p, u_n.
  void start(double t_s, double y_m, const BasicChamberState<S>& state, double u_p_v, double u_n_v) noexcept {
    t_s_ = t_s;
    y_m_ = y_m;
    state_ = state;
    command(u_p_v, u_n_v);
  }
  /// Goes on from another estimate's state, time, position and commands (a model replaced).
  void resume(const BasicChamberObserver& other) noexcept {
    state_ = other.state_;
    t_s_ = other.t_s_;
    y_m_ = other.y_m_;
    u_p_v_ = other.u_p_v_;
    u_n_v_ = other.u_n_v_;
  }
  /// To `t_s` with the measurements then, the commands held since the last ones (from the last
  /// measurements, linearly in between). An earlier or equal time only takes the measurements.
  ///
  /// Each chamber's temperature equation, its pressure and volume taken from the measurements (linear
  /// in between: the volume term integrates to -(gamma - 1) ln(V1 / V0) whatever the path), its valve
  /// at the spool's position, in RK4 steps short against the chamber's fastest rate. A spool lagging
  /// by less than a step moves a long way within it: each stage takes the spool's exact mean over the
  /// part of the step its RK4 weight stands for ([0, 1/6], [1/6, 5/6], [5/6, 1] of it), which the
  /// flow, linear in the opening, integrates exactly where the stage's own value would not (a 0.2 ms
  /// lag sampled at the stages of a 1 ms step misses a fifth of each command change's transient).
  void advance(double t_s, double y_m, double p_p_pa, double p_n_pa) noexcept {
    const double h = t_s - t_s_;
    const Valve& valve = *valve_;
    const S target_p = BasicSpoolLag<S>::target_v(valve, u_p_v_);
    const S target_n = BasicSpoolLag<S>::target_v(valve, u_n_v_);
    if (h > 0.0 && process_.thermal()) {
      const double v = (y_m - y_m_) / h;
      const auto integrate = [&](Side side, S t_k, double p0, double p1, const S& w0, const S& target) {
        // The spool's mean over [a, b] of the interval.
        const auto spool_mean = [&](double a, double b) -> S {
          using std::exp;
          if (!spool_.lags()) return target;
          const S& tau = spool_.time_constant_s;
          return target + (w0 - target) * tau * (exp(-a / tau) - exp(-b / tau)) / (b - a);
        };
        const auto rate = [&](double tau, const S& w, const S& temperature) {
          return process_.rates(valve, side, S(p0 + (p1 - p0) * tau / h), temperature, w, y_m_ + v * tau, v)
              .dtemperature_dt_k_per_s;
        };
        // The temperature equation's own rate, T d(dT/dt)/dT, is of the order of the chamber's fastest.
        const double fastest =
            process_.fastest_rate_1_per_s(valve, side, std::max(p0, p1), value(t_k), value(w0), y_m_);
        const int steps = std::clamp(static_cast<int>(std::ceil(h * fastest / 0.5)), 1, 1000);
        const double dt = h / steps;
        for (int i = 0; i < steps; ++i) {
          const double tau = i * dt;
          const S w_start = spool_mean(tau, tau + dt / 6.0), w_middle = spool_mean(tau + dt / 6.0, tau + 5.0 * dt / 6.0),
                  w_end = spool_mean(tau + 5.0 * dt / 6.0, tau + dt);
          const S k1 = rate(tau, w_start, t_k);
          const S k2 = rate(tau + 0.5 * dt, w_middle, t_k + 0.5 * dt * k1);
          const S k3 = rate(tau + 0.5 * dt, w_middle, t_k + 0.5 * dt * k2);
          const S k4 = rate(tau + dt, w_end, t_k + dt * k3);
          t_k += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        return t_k;
      };
      state_.t_p_k = integrate(Side::kP, state_.t_p_k, value(state_.p_p_pa), p_p_pa, state_.w_p_v, target_p);
      state_.t_n_k = integrate(Side::kN, state_.t_n_k, value(state_.p_n_pa), p_n_pa, state_.w_n_v, target_n);
    }
    if (h > 0.0) {
      state_.w_p_v = spool_.after(state_.w_p_v, target_p, h);
      state_.w_n_v = spool_.after(state_.w_n_v, target_n, h);
      t_s_ = t_s;
    }
    y_m_ = y_m;
    state_.p_p_pa = p_p_pa;
    state_.p_n_pa = p_n_pa;
  }
  /// The commands from now on: valve P at u_p, valve N at u_n [V].
  void command(double u_p_v, double u_n_v) noexcept {
    u_p_v_ = u_p_v;
    u_n_v_ = u_n_v;
  }
  /// The estimate at the last advance(), its pressures the measured ones.
  [[nodiscard]] const BasicChamberState<S>& state() const noexcept { return state_; }
  [[nodiscard]] double t_s() const noexcept { return t_s_; }
  [[nodiscard]] const BasicChamberProcess<S>& process() const noexcept { return process_; }

 private:
  BasicChamberProcess<S> process_;
  const Valve* valve_;
  BasicSpoolLag<S> spool_;
  BasicChamberState<S> state_{};
  double t_s_ = 0.0, y_m_ = 0.0;
  double u_p_v_ = 0.0, u_n_v_ = 0.0;
};
using ChamberObserver = BasicChamberObserver<double, ValveCharacteristic>;

}  // namespace pneu::model
