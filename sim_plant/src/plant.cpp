#include "pneu/sim_plant/plant.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <utility>

namespace pneu::plant {

namespace {

constexpr int kPositive = +1;
constexpr int kNegative = -1;

int direction_of(Motion m) noexcept {
  return m == Motion::kSlidingPositive ? kPositive : (m == Motion::kSlidingNegative ? kNegative : 0);
}

Motion sliding(int direction) noexcept {
  return direction > 0 ? Motion::kSlidingPositive : Motion::kSlidingNegative;
}

// Event location on theta in [0, 1] for an event function g with g(0) <= 0 < g(1): Illinois
// regula falsi keeping a bracket, returning its right end (where g > 0, so the located state
// satisfies the event condition). `eval` maps theta to g. Stops when the bracket is narrower
// than `theta_tolerance`.
template <typename G>
double locate_event(G&& eval, double g0, double g1, double theta_tolerance) noexcept {
  double lo = 0.0, hi = 1.0, g_lo = g0, g_hi = g1;
  int side = 0;
  for (int i = 0; i < 100 && hi - lo > theta_tolerance; ++i) {
    double theta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
    if (!(theta > lo && theta < hi)) theta = 0.5 * (lo + hi);
    const double g = eval(theta);
    if (g > 0.0) {
      hi = theta;
      g_hi = g;
      if (side == +1) g_lo *= 0.5;
      side = +1;
    } else {
      lo = theta;
      g_lo = g;
      if (side == -1) g_hi *= 0.5;
      side = -1;
    }
  }
  return hi;
}

// RK4 is stable on the negative real axis for h |lambda| < 2.785; keep 10 % margin.
constexpr double kStabilityMargin = 2.5;

// Event time resolution [s].
constexpr double kEventTimeTolerance_s = 1.0e-11;
// A sub-step dt / n may come out this much (relative) above the step it was sized by: rounding,
// not a longer step (1e-3 / 5 is one ulp above 2e-4). step()'s count of sub-steps and advance()'s
// cap both allow it.
constexpr double kStepRounding = 1.0e-9;

}  // namespace

Plant::Plant(const model::PlantParams& params)
    : params_(params),
      valve_(params.valve, params.gas),
      force_(params.geometry, params.gas.exhaust_pressure_pa),
      process_(params),
      spool_{params.valve.spool_time_constant_s},
      area_p_m2_(force_.area_p_m2()),
      area_n_m2_(force_.area_n_m2()),
      half_stroke_m_(params.geometry.half_stroke_m()),
      k_r_t_(params.gas.k_r_t()),
      piston_index_(params.has_thermal ? params.thermal.adiabatic_index : params.gas.polytropic_index) {
  assert(params.mass_kg > 0.0 && params.max_step_s > 0.0 && params.max_stuck_step_s > 0.0 && area_n_m2_ > 0.0);
  // Fastest pressure mode: |dq/dp| is largest in the laminar region of a wide-open orifice,
  // |d m/d p| <= K (1 + |phi'|) per orifice; both orifices of one valve together open at most
  // C_max + C_leak_in + C_leak_out.
  const auto& v = params.valve;
  const double max_open = v.max_conductance_m3_per_s_pa + v.leak_conductance_in_m3_per_s_pa +
                          v.leak_conductance_out_m3_per_s_pa;
  // A chamber's pressure mode per unit of opening and of 1 / volume: k r T rho_0 sqrt(T_0 / T)
  // (1 + |phi'(1)|), with the energy balance the adiabatic index in place of k.
  pressure_rate_per_opening_ =
      k_r_t_ * v.reference_density_kg_per_m3 * valve_.orifice().temperature_factor *
      (1.0 + std::abs(model::flow_function_slope(1.0, v.critical_pressure_ratio))) *
      (piston_index_ / params.gas.polytropic_index);
  const double min_volume =
      std::min(params.geometry.dead_volume_p_m3, params.geometry.dead_volume_n_m3);
  if (params.has_thermal) {
    // The wall's heat, fastest in the least air per wall area: a chamber at its dead volume, at
    // the exhaust pressure.
    const auto& g = params.geometry;
    const double t_wall = params.wall_temperature_k();
    for (const auto& [volume, wall] : {std::pair{g.dead_volume_p_m3, model::wall_area_p_m2(g, -half_stroke_m_)},
                                       std::pair{g.dead_volume_n_m3, model::wall_area_n_m2(g, half_stroke_m_)}})
      wall_rate_per_s_ = std::max(wall_rate_per_s_, 1.0 / process_.thermal_chamber().time_constant_s(
                                                              params.gas.exhaust_pressure_pa, t_wall, volume, wall));
  }
  const double lambda_max = std::max(pressure_rate_per_opening_ * max_open / min_volume, wall_rate_per_s_);
  stable_step_s_ = kStabilityMargin / lambda_max;
  reset_at_rest(0.0, 0.0);
}

double Plant::sliding_friction_n(Motion motion, double v) const noexcept {
  const auto& f = params_.friction;
  const double s = v / f.stribeck_velocity_m_per_s;
  // Beyond 7 v_s the Stribeck term is below 1e-21 of (F_S - F_C): skip the exponential.
  const double stribeck = s * s < 49.0 ? std::exp(-s * s) : 0.0;
  if (motion == Motion::kSlidingNegative) {
    return f.coulomb_negative_n + (f.static_negative_n - f.coulomb_negative_n) * stribeck +
           f.viscous_n_s_per_m * v;
  }
  return f.coulomb_positive_n + (f.static_positive_n - f.coulomb_positive_n) * stribeck +
         f.viscous_n_s_per_m * v;
}

double Plant::force_of(const Vec& x) const noexcept {
  return force_.force_n(x[2], x[3]);
}

double Plant::pressure_force_n() const noexcept { return force_.force_n(state_.p_p_pa, state_.p_n_pa); }

Plant::Voltages Plant::voltages_at(const Drive& d, double dt_s) const noexcept {
  return {spool_.after(d.from_p_v, d.u_p_v, dt_s), spool_.after(d.from_n_v, d.u_n_v, dt_s)};
}

// Eq. 2, each valve at its own voltage (Eq. 1 is u_P = u, u_N = -u); with plant.thermal, each
// chamber's energy balance in place of the polytropic process (model::ChamberProcess).
Plant::Vec Plant::derivative(const Vec& x, Motion motion, Voltages w) const noexcept {
  ++rhs_evaluations_;
  const double y = x[0], v = x[1];
  const model::ChamberRates rp = process_.rates(valve_, model::Side::kP, x[2], x[4], w.w_p_v, y, v);
  const model::ChamberRates rn = process_.rates(valve_, model::Side::kN, x[3], x[5], w.w_n_v, y, v);
  Vec dx;
  dx[2] = rp.dp_dt_pa_per_s;
  dx[3] = rn.dp_dt_pa_per_s;
  dx[4] = rp.dtemperature_dt_k_per_s;
  dx[5] = rn.dtemperature_dt_k_per_s;
  if (motion == Motion::kStuck) {
    dx[0] = 0.0;
    dx[1] = 0.0;
  } else {
    dx[0] = v;
    dx[1] = (driving_force_of(x) - sliding_friction_n(motion, v)) / params_.mass_kg;
  }
  return dx;
}

Plant::Vec Plant::rk4(const Vec& x, double h, Motion motion, const Drive& u) const noexcept {
  const Voltages start = voltages_at(u, 0.0), middle = voltages_at(u, 0.5 * h), end = voltages_at(u, h);
  const bool valves_held = start.w_p_v == middle.w_p_v && start.w_p_v == end.w_p_v &&
                           start.w_n_v == middle.w_n_v && start.w_n_v == end.w_n_v;
  if (motion == Motion::kStuck && !params_.has_thermal && valves_held) return rk4_held(x, h, start);
  const Vec k1 = derivative(x, motion, start);
  const Vec k2 = derivative(x + 0.5 * h * k1, motion, middle);
  const Vec k3 = derivative(x + 0.5 * h * k2, motion, middle);
  const Vec k4 = derivative(x + h * k3, motion, end);
  Vec out = x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  if (motion == Motion::kStuck) {  // no creep: y and v are not integrated at all while stuck
    out[0] = x[0];
    out[1] = 0.0;
  }
  return out;
}

// rk4() over a stuck carriage, polytropic chambers and valves held: each chamber's pressure alone,
// its place, k r T / V and its valve's opening worked out once for the four stages. The same
// arithmetic, stage by stage and element by element, as rk4()'s on the whole state: bit for bit.
Plant::Vec Plant::rk4_held(const Vec& x, double h, Voltages w) const noexcept {
  rhs_evaluations_ += 4;
  const auto& eq = valve_.equations();
  const auto held_p = process_.held(eq, process_.place(model::Side::kP, x[0], x[1]), w.w_p_v);
  const auto held_n = process_.held(eq, process_.place(model::Side::kN, x[0], x[1]), w.w_n_v);
  // Both chambers stage by stage (two independent chains for the processor to overlap).
  const double p = x[2], n = x[3];
  const double k1p = process_.dp_dt(eq, held_p, p);
  const double k1n = process_.dp_dt(eq, held_n, n);
  const double k2p = process_.dp_dt(eq, held_p, p + 0.5 * h * k1p);
  const double k2n = process_.dp_dt(eq, held_n, n + 0.5 * h * k1n);
  const double k3p = process_.dp_dt(eq, held_p, p + 0.5 * h * k2p);
  const double k3n = process_.dp_dt(eq, held_n, n + 0.5 * h * k2n);
  const double k4p = process_.dp_dt(eq, held_p, p + h * k3p);
  const double k4n = process_.dp_dt(eq, held_n, n + h * k3n);
  Vec out = x;
  out[1] = 0.0;
  out[2] = p + (h / 6.0) * (k1p + 2.0 * k2p + 2.0 * k3p + k4p);
  out[3] = n + (h / 6.0) * (k1n + 2.0 * k2n + 2.0 * k3n + k4n);
  return out;
}

void Plant::record(PlantEvent::Kind kind, int direction) noexcept {
  if (event_count_ == events_.size()) {
    ++events_dropped_;
    return;
  }
  events_[event_count_++] = PlantEvent{kind, state_.t_s, state_.y_m, pressure_force_n(), direction};
}

void Plant::settle_mode_at_rest() noexcept {
  const auto& f = params_.friction;
  const double force = pressure_force_n() + external_n_;
  if (state_.v_m_per_s > 0.0) {
    state_.motion = Motion::kSlidingPositive;
  } else if (state_.v_m_per_s < 0.0) {
    state_.motion = Motion::kSlidingNegative;
  } else if (force > f.static_positive_n && state_.y_m < half_stroke_m_) {
    state_.motion = Motion::kSlidingPositive;
  } else if (force < f.static_negative_n && state_.y_m > -half_stroke_m_) {
    state_.motion = Motion::kSlidingNegative;
  } else {
    state_.motion = Motion::kStuck;
  }
}

void Plant::reset_at_rest(double y_m, double u_v, double t_s) noexcept {
  const double y = std::clamp(y_m, -half_stroke_m_, half_stroke_m_);
  const model::ChamberRest rest_p = process_.rest(valve_, model::Side::kP, u_v, y);
  const model::ChamberRest rest_n = process_.rest(valve_, model::Side::kN, -u_v, y);
  PlantState s{t_s, y_m, 0.0, rest_p.p_pa, rest_n.p_pa, Motion::kStuck, rest_p.t_k, rest_n.t_k};
  const bool lag = spool_.time_constant_s > 0.0;
  s.w_p_v = lag ? model::SpoolLag::target_v(valve_, u_v) : u_v;
  s.w_n_v = lag ? model::SpoolLag::target_v(valve_, -u_v) : -u_v;
  reset(s);
}

void Plant::reset(const PlantState& state) noexcept {
  state_ = state;
  state_.y_m = std::clamp(state_.y_m, -half_stroke_m_, half_stroke_m_);
  // Without plant.thermal the chambers stay at gas.temperature_k.
  const double t_rest = params_.has_thermal ? params_.wall_temperature_k() : params_.gas.temperature_k;
  if (!params_.has_thermal || std::isnan(state_.t_p_k)) state_.t_p_k = t_rest;
  if (!params_.has_thermal || std::isnan(state_.t_n_k)) state_.t_n_k = t_rest;
  if (std::isnan(state_.w_p_v)) state_.w_p_v = 0.0;
  if (std::isnan(state_.w_n_v)) state_.w_n_v = 0.0;
  settle_mode_at_rest();
  event_count_ = 0;
}

void Plant::step(double dt_s, double u_p_v, double u_n_v) noexcept {
  event_count_ = 0;
  if (!(dt_s > 0.0)) return;
  const double t_end = state_.t_s + dt_s;
  // With a spool lag the spools follow the commands within the valves' travel; without, the
  // valves see the commands themselves.
  const bool lag = spool_.time_constant_s > 0.0;
  const Drive u{lag ? model::SpoolLag::target_v(valve_, u_p_v) : u_p_v,
                lag ? model::SpoolLag::target_v(valve_, u_n_v) : u_n_v, 0.0, 0.0};
  const int n = static_cast<int>(std::ceil(dt_s / sub_step_s(dt_s, u.u_p_v, u.u_n_v) - kStepRounding));
  const double h = dt_s / std::max(n, 1);
  for (int i = 0; i < std::max(n, 1); ++i) advance(h, u);
  state_.t_s = t_end;
}

double Plant::sub_step_s(double dt_s, double w_p_v, double w_n_v) const noexcept {
  const double max_step_s = state_.motion == Motion::kStuck ? params_.max_stuck_step_s : params_.max_step_s;
  if (max_step_s <= stable_step_s_) return max_step_s;  // stable in any state
  // Each chamber's pressure mode over this step: its valve's opening, the larger of where the spool
  // stands and where it goes (both orifices together pass the leaks and |w - w_0| / u_max of C_max,
  // convex in w), over the smallest volume the chamber can reach within the step (the carriage going
  // on at its speed, and 1 mm more), and the piston's own term k S |v| / V.
  const auto& eq = valve_.equations();
  const auto opening = [&](double w) {
    const auto o = eq.opening(w);
    return o.inlet_m3_per_s_pa + o.outlet_m3_per_s_pa;
  };
  const double speed = std::abs(state_.v_m_per_s);
  const double travel_m = speed * dt_s + 1.0e-3;
  const auto rate = [&](model::Side side, double w_from, double w_to) {
    const bool p_side = side == model::Side::kP;
    const double y = std::clamp(state_.y_m + (p_side ? -travel_m : travel_m), -half_stroke_m_, half_stroke_m_);
    const double volume = process_.volume_m3(side, y);
    return (pressure_rate_per_opening_ * std::max(opening(w_from), opening(w_to)) +
            piston_index_ * (p_side ? area_p_m2_ : area_n_m2_) * speed) /
           volume;
  };
  const double lambda = std::max({rate(model::Side::kP, state_.w_p_v, w_p_v),
                                  rate(model::Side::kN, state_.w_n_v, w_n_v), wall_rate_per_s_});
  // Never below the stiffest state's step: that one is stable anywhere.
  return std::min(max_step_s, std::max(stable_step_s_, kStabilityMargin / lambda));
}

void Plant::advance(double h, Drive command) noexcept {
  const auto& f = params_.friction;
  Vec x;
  x << state_.y_m, state_.v_m_per_s, state_.p_p_pa, state_.p_n_pa, state_.t_p_k, state_.t_n_k;
  double remaining = h;
  Drive u = command;  // with the spools where this pass starts
  const auto commit = [&](const Vec& xn, double dt) {
    state_.y_m = xn[0];
    state_.v_m_per_s = xn[1];
    state_.p_p_pa = xn[2];
    state_.p_n_pa = xn[3];
    state_.t_p_k = xn[4];
    state_.t_n_k = xn[5];
    const Voltages w = voltages_at(u, dt);
    state_.w_p_v = w.w_p_v;
    state_.w_n_v = w.w_n_v;
    state_.t_s += dt;
    x = xn;
    remaining -= dt;
  };

  // Each pass integrates the rest of the sub-step or stops at the first located mode change. A
  // sub-step sized for a stuck carriage (up to max_stuck_step_s) that slides, after a breakaway in
  // it or in an earlier sub-step of the sample, goes on in steps of the sliding carriage's size
  // (sub_step_s()).
  for (int pass = 0; pass < 32 && remaining > 0.0; ++pass) {
    const Motion m = state_.motion;
    u.from_p_v = state_.w_p_v;
    u.from_n_v = state_.w_n_v;
    // (h is dt / n: kStepRounding.)
    const double span = m != Motion::kStuck && h > params_.max_step_s * (1.0 + kStepRounding)
                            ? std::min(remaining, sub_step_s(remaining, command.u_p_v, command.u_n_v))
                            : remaining;
    const Vec x0 = x;
    const Vec x1 = rk4(x0, span, m, u);
    const double theta_tolerance = kEventTimeTolerance_s / span;

    if (m == Motion::kStuck) {
      // Breakaway when F leaves [F_S-, F_S+]; an end stop blocks breakaway into itself.
      const bool may_go_up = x0[0] < half_stroke_m_;
      const bool may_go_down = x0[0] > -half_stroke_m_;
      const auto g = [&](const Vec& xs) {
        const double force = driving_force_of(xs);
        const double up = may_go_up ? force - f.static_positive_n : -1.0;
        const double down = may_go_down ? f.static_negative_n - force : -1.0;
        return std::max(up, down);
      };
      const double g1 = g(x1);
      if (g1 <= 0.0) {
        commit(x1, span);
        continue;
      }
      const double g0 = std::min(g(x0), 0.0);
      const double theta = locate_event(
          [&](double th) { return g(rk4(x0, th * span, m, u)); }, g0, g1, theta_tolerance);
      const Vec xe = rk4(x0, theta * span, m, u);
      commit(xe, theta * span);
      const double force = driving_force_of(xe);
      const int dir = (may_go_up && force > f.static_positive_n) ? kPositive : kNegative;
      state_.motion = sliding(dir);
      record(PlantEvent::Kind::kBreakaway, dir);
      continue;
    }

    const int s = direction_of(m);
    // Events while sliding: the velocity changes sign, or the carriage reaches its end stop.
    const auto g_velocity = [&](const Vec& xs) { return -s * xs[1]; };
    const auto g_stop = [&](const Vec& xs) { return s * xs[0] - half_stroke_m_; };
    const auto g = [&](const Vec& xs) { return std::max(g_velocity(xs), g_stop(xs)); };
    const double g1 = g(x1);
    if (g1 <= 0.0) {
      commit(x1, span);
      // Asymptotic approach to rest: inside the velocity band, decelerating, F inside the
      // stiction band -> stick.
      if (std::abs(x[1]) < f.stick_velocity_m_per_s && s * derivative(x, m, {state_.w_p_v, state_.w_n_v})[1] < 0.0 &&
          driving_force_of(x) >= f.static_negative_n && driving_force_of(x) <= f.static_positive_n) {
        state_.v_m_per_s = 0.0;
        state_.motion = Motion::kStuck;
        record(PlantEvent::Kind::kStick, s);
      }
      continue;
    }
    const double g0 = std::min(g(x0), 0.0);
    const double theta = locate_event([&](double th) { return g(rk4(x0, th * span, m, u)); },
                                      g0, g1, theta_tolerance);
    Vec xe = rk4(x0, theta * span, m, u);
    const bool hit_stop = g_stop(xe) >= g_velocity(xe);
    xe[1] = 0.0;
    if (hit_stop) xe[0] = s * half_stroke_m_;
    commit(xe, theta * span);
    const double force = driving_force_of(xe);
    if (hit_stop) {
      state_.motion = Motion::kStuck;
      record(PlantEvent::Kind::kEndStop, s);
    } else if (force >= f.static_negative_n && force <= f.static_positive_n) {
      state_.motion = Motion::kStuck;
      record(PlantEvent::Kind::kStick, s);
    } else {
      const int dir = force > f.static_positive_n ? kPositive : kNegative;
      state_.motion = sliding(dir);
      if (dir != s) record(PlantEvent::Kind::kReversal, dir);
    }
  }
  if (remaining > 0.0) {  // more than 32 mode changes in one sub-step: finish without events
    u.from_p_v = state_.w_p_v;
    u.from_n_v = state_.w_n_v;
    commit(rk4(x, remaining, state_.motion, u), remaining);
    ++events_dropped_;
  }
}

double push_force_n(std::span<const model::Push> pushes, double t_s) noexcept {
  double f = 0.0;
  for (const auto& p : pushes)
    if (t_s >= p.t_s && t_s < p.t_s + p.duration_s) f += p.force_n;
  return f;
}

double next_push_change_s(std::span<const model::Push> pushes, double t_s) noexcept {
  double next = std::numeric_limits<double>::infinity();
  for (const auto& p : pushes) {
    if (p.t_s > t_s) next = std::min(next, p.t_s);
    else if (p.t_s + p.duration_s > t_s) next = std::min(next, p.t_s + p.duration_s);
  }
  return next;
}

}  // namespace pneu::plant
