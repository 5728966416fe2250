#include "pneu/model/chamber.hpp"

#include <algorithm>
#include <numbers>

#include "pneu/model/valve.hpp"
#include "roots.hpp"

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

double SpoolLag::target_v(const ValveCharacteristic& valve, double w_v) noexcept {
  return std::fmin(std::fmax(w_v, valve.spool_min_v()), valve.spool_max_v());
}

ChamberProcess::ChamberProcess(const Geometry& geometry, const Gas& gas, const ThermalParams* thermal) noexcept
    : geometry_(geometry),
      thermal_(thermal != nullptr),
      chamber_(gas, thermal != nullptr ? *thermal : ThermalParams{}),
      area_p_m2_(geometry.area_p_m2()),
      area_n_m2_(geometry.area_n_m2()),
      half_stroke_m_(geometry.half_stroke_m()),
      k_r_t_(gas.k_r_t()),
      r_t_(gas.gas_constant_j_per_kg_k * gas.temperature_k),
      supply_k_(gas.temperature_k),
      exhaust_pa_(gas.exhaust_pressure_pa),
      gamma_r_((thermal != nullptr ? thermal->adiabatic_index : gas.polytropic_index) * gas.gas_constant_j_per_kg_k) {}

ChamberProcess::Place ChamberProcess::place(Side side, double y, double v) const noexcept {
  const bool p_side = side == Side::kP;
  return {side, volume_m3(side, y), v, p_side ? area_p_m2_ * v : -area_n_m2_ * v,
          !thermal_ ? 0.0 : p_side ? wall_area_p_m2(geometry_, y) : wall_area_n_m2(geometry_, y)};
}

// Eq. 2's pressure equation, or the energy balance (docs/model.md section 2). The polytropic form is
// the plant's own, term for term (the simulated bench is bit for bit what it was).
ChamberRates ChamberProcess::rates(const ValveCharacteristic& valve, const Place& at, double p, double t_k,
                                   double w) const noexcept {
  const double volume = at.volume_m3;
  if (!thermal_) {
    const double q = valve.mass_flow_kg_per_s(w, p);
    const double v = at.v_m_per_s;
    return {at.side == Side::kP ? k_r_t_ / volume * (q - area_p_m2_ * p * v / r_t_)
                                : k_r_t_ / volume * (q + area_n_m2_ * p * v / r_t_),
            0.0};
  }
  return chamber_.rates(valve.chamber_inflow(w, p, t_k, supply_k_), p, t_k, volume, at.dvolume_dt_m3_per_s, at.wall_m2);
}

double ChamberProcess::fastest_rate_1_per_s(const ValveCharacteristic& valve, Side side, double p, double t_k,
                                            double w, double y) const noexcept {
  const double volume = volume_m3(side, y);
  if (!thermal_) return k_r_t_ / volume * -valve.dq_dp(w, p);
  // The valve's: gamma r T / V (-dq/dp) (the flow's temperature factor aside); the wall's: 1 / (m c_v / (h A)).
  const double wall = side == Side::kP ? wall_area_p_m2(geometry_, y) : wall_area_n_m2(geometry_, y);
  return std::max(gamma_r_ * t_k / volume * -valve.dq_dp(w, p), 1.0 / chamber_.time_constant_s(p, t_k, volume, wall));
}

ChamberRest ChamberProcess::rest(const ValveCharacteristic& valve, Side side, double w_v, double y_m) const noexcept {
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

void ChamberObserver::reset(double t_s, double y_m, double p_p_pa, double p_n_pa, double u_p_v, double u_n_v) noexcept {
  t_s_ = t_s;
  y_m_ = y_m;
  state_.p_p_pa = p_p_pa;
  state_.p_n_pa = p_n_pa;
  state_.t_p_k = process_.rest(*valve_, Side::kP, u_p_v, y_m).t_k;
  state_.t_n_k = process_.rest(*valve_, Side::kN, u_n_v, y_m).t_k;
  command(u_p_v, u_n_v);
  state_.w_p_v = SpoolLag::target_v(*valve_, u_p_v);
  state_.w_n_v = SpoolLag::target_v(*valve_, u_n_v);
}

// Each chamber's temperature equation, its pressure and volume taken from the measurements (linear
// in between: the volume term integrates to -(gamma - 1) ln(V1 / V0) whatever the path), its valve
// at the spool's position, in RK4 steps short against the chamber's fastest rate. A spool lagging
// by less than a step moves a long way within it: each stage takes the spool's exact mean over the
// part of the step its RK4 weight stands for ([0, 1/6], [1/6, 5/6], [5/6, 1] of it), which the
// flow, linear in the opening, integrates exactly where the stage's own value would not (a 0.2 ms
// lag sampled at the stages of a 1 ms step misses a fifth of each command change's transient).
void ChamberObserver::advance(double t_s, double y_m, double p_p_pa, double p_n_pa) noexcept {
  const double h = t_s - t_s_;
  const ValveCharacteristic& valve = *valve_;
  const double target_p = SpoolLag::target_v(valve, u_p_v_);
  const double target_n = SpoolLag::target_v(valve, u_n_v_);
  if (h > 0.0 && process_.thermal()) {
    const double v = (y_m - y_m_) / h;
    const auto integrate = [&](Side side, double t_k, double p0, double p1, double w0, double target) {
      // The spool's mean over [a, b] of the interval.
      const auto spool_mean = [&](double a, double b) {
        if (!spool_.lags()) return target;
        const double tau = spool_.time_constant_s;
        return target + (w0 - target) * tau * (std::exp(-a / tau) - std::exp(-b / tau)) / (b - a);
      };
      const auto rate = [&](double tau, double w, double temperature) {
        return process_.rates(valve, side, p0 + (p1 - p0) * tau / h, temperature, w, y_m_ + v * tau, v)
            .dtemperature_dt_k_per_s;
      };
      // The temperature equation's own rate, T d(dT/dt)/dT, is of the order of the chamber's fastest.
      const double fastest = process_.fastest_rate_1_per_s(valve, side, std::max(p0, p1), t_k, w0, y_m_);
      const int steps = std::clamp(static_cast<int>(std::ceil(h * fastest / 0.5)), 1, 1000);
      const double dt = h / steps;
      for (int i = 0; i < steps; ++i) {
        const double tau = i * dt;
        const double w_start = spool_mean(tau, tau + dt / 6.0), w_middle = spool_mean(tau + dt / 6.0, tau + 5.0 * dt / 6.0),
                     w_end = spool_mean(tau + 5.0 * dt / 6.0, tau + dt);
        const double k1 = rate(tau, w_start, t_k);
        const double k2 = rate(tau + 0.5 * dt, w_middle, t_k + 0.5 * dt * k1);
        const double k3 = rate(tau + 0.5 * dt, w_middle, t_k + 0.5 * dt * k2);
        const double k4 = rate(tau + dt, w_end, t_k + dt * k3);
        t_k += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      }
      return t_k;
    };
    state_.t_p_k = integrate(Side::kP, state_.t_p_k, state_.p_p_pa, p_p_pa, state_.w_p_v, target_p);
    state_.t_n_k = integrate(Side::kN, state_.t_n_k, state_.p_n_pa, p_n_pa, state_.w_n_v, target_n);
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

}  // namespace pneu::model
