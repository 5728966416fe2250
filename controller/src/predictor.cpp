#include "pneu/controller/predictor.hpp"

#include <algorithm>
#include <cmath>

#include "pneu/model/pressure_force.hpp"

namespace pneu::controller {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kTimeTolerance_s = 1.0e-7;
// The nonlinear method's smallest margin is exact to this [N].
constexpr double kMarginTolerance_n = 1.0e-3;

struct Bounds {
  double upper_n;   // F_S+, or +inf when the + direction is blocked by an end stop
  double lower_n;   // F_S-, or -inf
};

Bounds bounds_of(const PredictorModel& m, const StopSnapshot& s) noexcept {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {s.blocked_direction > 0 ? inf : m.friction.static_positive_n,
          s.blocked_direction < 0 ? -inf : m.friction.static_negative_n};
}

// > 0 once F is outside the band it may leave.
double excess(const Bounds& b, double force) noexcept {
  return std::max(force - b.upper_n, b.lower_n - force);
}

// Distance to the nearer bound the carriage can cross (an end stop blocks one of them).
double margin(const Bounds& b, double force) noexcept {
  return std::min(b.upper_n - force, force - b.lower_n);
}

struct Common {
  model::PressureForce pressure_force;  // Eq. 14
  double k_r_t, v_p, v_n;
  double force(double p_p, double p_n) const noexcept { return pressure_force.force_n(p_p, p_n); }
};

Common common_of(const PredictorModel& m, const StopSnapshot& s) noexcept {
  return {model::PressureForce(m.geometry, m.gas.exhaust_pressure_pa), m.gas.k_r_t(),
          m.geometry.volume_p_m3(s.y_m), m.geometry.volume_n_m3(s.y_m)};
}

// Root of a function on [a, b] with f(a) <= 0 < f(b) (Illinois); returns the right end of the
// final bracket, where the event condition holds.
template <typename F>
double bracketed_root(F&& f, double a, double b, double fa, double fb, double tol) noexcept {
  int side = 0;
  for (int i = 0; i < 200 && b - a > tol; ++i) {
    double x = (a * fb - b * fa) / (fb - fa);
    if (!(x > a && x < b)) x = 0.5 * (a + b);
    const double fx = f(x);
    if (fx > 0.0) {
      b = x;
      fb = fx;
      if (side == +1) fa *= 0.5;
      side = +1;
    } else {
      a = x;
      fa = fx;
      if (side == -1) fb *= 0.5;
      side = -1;
    }
  }
  return b;
}

// C_p of Eq. 23 for one chamber, valve voltage w, from its stop pressure to its null-flow one.
double flow_slope(const PredictorModel& m, double w, double p_stop_pa, double p_null_pa) noexcept {
  // Below this the chord is 0/0: the chamber is at its null already and the tangent is the chord.
  constexpr double kChordMin_pa = 1.0;
  switch (m.linearized_slope) {
    case LinearizedSlope::kChord:
      if (std::abs(p_null_pa - p_stop_pa) >= kChordMin_pa)
        return m.valve->mass_flow_kg_per_s(w, p_stop_pa) / (p_null_pa - p_stop_pa);
      break;
    case LinearizedSlope::kEquilibriumTangent:
      return -m.valve->dq_dp(w, p_null_pa);
    case LinearizedSlope::kStopTangent:
      break;
  }
  return -m.valve->dq_dp(w, p_stop_pa);
}

// Fills the fields every method shares: equilibrium pressures and force, Eq. 23 time constants.
Prediction base(PredictionMethod method, const PredictorModel& m, const StopSnapshot& s,
                const Common& c) noexcept {
  Prediction p;
  p.method = method;
  p.p_p_equilibrium_pa = m.valve->null_pressure_pa(s.u_v);
  p.p_n_equilibrium_pa = m.valve->null_pressure_pa(-s.u_v);
  p.equilibrium_force_n = c.force(p.p_p_equilibrium_pa, p.p_n_equilibrium_pa);
  const double c_pp = flow_slope(m, s.u_v, s.p_p_pa, p.p_p_equilibrium_pa);
  const double c_pn = flow_slope(m, -s.u_v, s.p_n_pa, p.p_n_equilibrium_pa);
  p.tau_p_s = c_pp > 0.0 ? c.v_p / (c.k_r_t * c_pp) : std::numeric_limits<double>::infinity();
  p.tau_n_s = c_pn > 0.0 ? c.v_n / (c.k_r_t * c_pn) : std::numeric_limits<double>::infinity();
  return p;
}

struct P2 {
  double pp, pn;
};

// The two pressure equations of Eq. 19 (Eq. 2 with v = 0) under the held control u*: each
// chamber relaxes on its own towards its null-flow pressure.
struct PressureOde {
  const Common& c;
  const model::ValveCharacteristic& valve;
  double u;

  P2 rhs(const P2& x) const noexcept {
    return {c.k_r_t / c.v_p * valve.mass_flow_kg_per_s(u, x.pp), c.k_r_t / c.v_n * valve.mass_flow_kg_per_s(-u, x.pn)};
  }
  P2 rk4(const P2& x, double h) const noexcept {
    const P2 k1 = rhs(x);
    const P2 k2 = rhs({x.pp + 0.5 * h * k1.pp, x.pn + 0.5 * h * k1.pn});
    const P2 k3 = rhs({x.pp + 0.5 * h * k2.pp, x.pn + 0.5 * h * k2.pn});
    const P2 k4 = rhs({x.pp + h * k3.pp, x.pn + h * k3.pn});
    return {x.pp + h / 6.0 * (k1.pp + 2 * k2.pp + 2 * k3.pp + k4.pp),
            x.pn + h / 6.0 * (k1.pn + 2 * k2.pn + 2 * k3.pn + k4.pn)};
  }
  // A tenth of the faster chamber's local time constant (RK4 error << 1e-6 relative), <= 10 ms.
  double step_s(const P2& x) const noexcept {
    constexpr double kStepFraction = 0.1;
    constexpr double kMaxStep_s = 0.01;
    const double slope = std::max(c.k_r_t / c.v_p * -valve.dq_dp(u, x.pp), c.k_r_t / c.v_n * -valve.dq_dp(-u, x.pn));
    return std::min(kMaxStep_s, slope > 0.0 ? kStepFraction / slope : kMaxStep_s);
  }
};

void mark_restart(Prediction& p, const StopSnapshot& s, double dt, double force,
                  const Bounds& b) noexcept {
  p.will_restart = true;
  p.t_restart_s = s.t_s + dt;
  p.direction = (force - b.upper_n >= b.lower_n - force) ? +1 : -1;
  p.min_margin_n = 0.0;
}


// Eq. 17: F(x) = A e^{-x/tau_P} + B e^{-x/tau_N} + C, x = t - s.t_s, with p's time constants:
// whether and when it leaves the band b, checked exactly over all x >= 0 (F is monotone on both
// sides of its one possible extremum). Fills p's restart fields and smallest margin.
void two_exponential_crossing(Prediction& p, const StopSnapshot& s, const Bounds& b, double a, double bb,
                              double cc) noexcept {
  const double tp = p.tau_p_s, tn = p.tau_n_s;
  const auto force = [&](double x) {
    const double ep = std::isinf(tp) ? 1.0 : std::exp(-x / tp);
    const double en = std::isinf(tn) ? 1.0 : std::exp(-x / tn);
    return a * ep + bb * en + cc;
  };
  const double f0 = force(0.0);
  if (excess(b, f0) > 0.0) {
    mark_restart(p, s, 0.0, f0, b);
    return;
  }
  // F' = 0 at most once: -A/tau_P e^{-x/tau_P} = B/tau_N e^{-x/tau_N}.
  double x_ext = -1.0;
  if (std::isfinite(tp) && std::isfinite(tn) && tp != tn && a != 0.0 && bb != 0.0) {
    const double ratio = -(bb * tp) / (a * tn);
    if (ratio > 0.0) x_ext = -std::log(ratio) / (1.0 / tp - 1.0 / tn);
  }
  // Monotone segments [0, x_ext] and [x_ext, inf) (or [0, inf)). The limit at infinity is C unless
  // a time constant is infinite, in which case that term stays.
  const double f_inf = (std::isinf(tp) ? a : 0.0) + (std::isinf(tn) ? bb : 0.0) + cc;
  double seg_start = 0.0, f_start = f0;
  double min_margin = margin(b, f0);
  const double ends[2] = {x_ext > 0.0 ? x_ext : -1.0, std::numeric_limits<double>::infinity()};
  for (double seg_end : ends) {
    if (seg_end < 0.0) continue;
    const double f_end = std::isinf(seg_end) ? f_inf : force(seg_end);
    if (excess(b, f_end) > 0.0) {
      // Bracket a finite end on the way to infinity.
      double hi = seg_end;
      if (std::isinf(hi)) {
        const double tmax = std::max(std::isfinite(tp) ? tp : 0.0, std::isfinite(tn) ? tn : 0.0);
        hi = seg_start + std::max(tmax, 1e-3);
        while (excess(b, force(hi)) <= 0.0 && hi < 1e9) hi = seg_start + 2.0 * (hi - seg_start);
      }
      const auto g = [&](double x) { return excess(b, force(x)); };
      const double x = bracketed_root(g, seg_start, hi, excess(b, f_start), g(hi), kTimeTolerance_s);
      mark_restart(p, s, x, force(x), b);
      return;
    }
    min_margin = std::min(min_margin, margin(b, f_end));
    seg_start = seg_end;
    f_start = f_end;
  }
  p.min_margin_n = min_margin;
}

// The least-squares fit of a + b e^{-x/tau} to one chamber's history for a given tau (x from the
// first sample; the pressures centred on their mean, which the caller gives): a, b and the sum of
// squared residuals.
struct LinearPart {
  double a = 0.0, b = 0.0, sse = std::numeric_limits<double>::infinity();
};

LinearPart fit_linear_part(const PhaseHistory& h, int chamber, double mean_pa, double tau_s) noexcept {
  const std::size_t n = h.size();
  const double t0 = h.t_s(0);
  double se = 0.0, see = 0.0, sp = 0.0, sep = 0.0, spp = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = std::exp(-(h.t_s(i) - t0) / tau_s);
    const double q = h.p_pa(chamber, i) - mean_pa;
    se += e, see += e * e, sp += q, sep += e * q, spp += q * q;
  }
  const double dn = static_cast<double>(n);
  const double det = dn * see - se * se;
  LinearPart r;
  if (!(det > 1e-12 * dn * dn)) return r;  // e^{-x/tau} is flat over the history: no fit at this tau
  r.b = (dn * sep - se * sp) / det;
  r.a = (sp - r.b * se) / dn;
  r.sse = std::max(0.0, spp - r.a * sp - r.b * sep);
  return r;
}
}  // namespace

const char* to_string(PredictionMethod m) noexcept {
  switch (m) {
    case PredictionMethod::kLinearized: return "linearized";
    case PredictionMethod::kNonlinear: return "nonlinear";
    case PredictionMethod::kRelaxation: return "relaxation";
    case PredictionMethod::kHeld: return "held";
  }
  return "?";
}

Prediction predict_linearized(const PredictorModel& m, const StopSnapshot& s) noexcept {
  const Common c = common_of(m, s);
  Prediction p = base(PredictionMethod::kLinearized, m, s, c);
  // Eq. 17: each chamber relaxes from its stop pressure to p_null(+-u*) with its Eq. 23 tau.
  two_exponential_crossing(p, s, bounds_of(m, s), c.pressure_force.area_p_m2() * (s.p_p_pa - p.p_p_equilibrium_pa),
                           -c.pressure_force.area_n_m2() * (s.p_n_pa - p.p_n_equilibrium_pa), p.equilibrium_force_n);
  return p;
}

Prediction predict_nonlinear(const PredictorModel& m, const StopSnapshot& s) noexcept {
  const Common c = common_of(m, s);
  Prediction p = base(PredictionMethod::kNonlinear, m, s, c);
  const Bounds b = bounds_of(m, s);
  const PressureOde ode{c, *m.valve, s.u_v};
  const auto force = [&](const P2& x) { return c.force(x.pp, x.pn); };

  P2 x{s.p_p_pa, s.p_n_pa};
  double f = force(x);
  if (excess(b, f) > 0.0) {
    mark_restart(p, s, 0.0, f, b);
    return p;
  }
  const double pe_p = p.p_p_equilibrium_pa, pe_n = p.p_n_equilibrium_pa;
  double min_margin = margin(b, f);
  double t = 0.0;
  while (t < m.horizon_s) {
    // Each pressure relaxes monotonically towards its null-flow value (a scalar autonomous ODE
    // with q decreasing in p), so F stays inside the box spanned by the present and equilibrium
    // pressures: when that box lies inside the band, no restart can ever come.
    const double f_lo = c.force(std::min(x.pp, pe_p), std::max(x.pn, pe_n));
    const double f_hi = c.force(std::max(x.pp, pe_p), std::min(x.pn, pe_n));
    // Once no restart is possible, go on only while the box could still hold a smaller margin
    // than the one already met (after an overshoot the box corner lingers near a bound).
    if (f_lo > b.lower_n && f_hi < b.upper_n) {
      const double box_margin = std::min(margin(b, f_lo), margin(b, f_hi));
      if (box_margin >= min_margin - kMarginTolerance_n) {
        p.min_margin_n = std::min(min_margin, box_margin);
        return p;
      }
    }
    const double h = ode.step_s(x);
    const P2 x1 = ode.rk4(x, h);
    const double f1 = force(x1);
    if (excess(b, f1) > 0.0) {
      const auto g = [&](double th) { return excess(b, force(ode.rk4(x, th * h))); };
      const double th = bracketed_root(g, 0.0, 1.0, excess(b, f), excess(b, f1), kTimeTolerance_s / h);
      mark_restart(p, s, t + th * h, force(ode.rk4(x, th * h)), b);
      return p;
    }
    min_margin = std::min(min_margin, margin(b, f1));
    x = x1;
    f = f1;
    t += h;
  }
  p.horizon_reached = true;
  p.min_margin_n = min_margin;
  return p;
}

Prediction predict_held(const PredictorModel& m, const HoldLaw& law, HoldState state, const StopSnapshot& now) noexcept {
  // Settled: the force this close to its reference, the command moving less than this per tick.
  constexpr double kSettledForce_n = 0.01;
  constexpr double kSettledCommand_v = 1.0e-7;
  const Common c = common_of(m, now);
  Prediction p = base(PredictionMethod::kHeld, m, now, c);
  const Bounds b = bounds_of(m, now);
  const auto force = [&](const P2& x) { return c.force(x.pp, x.pn); };
  const double period = law.period_s();
  const double horizon = std::min(m.horizon_s, kHeldHorizon_s);

  P2 x{now.p_p_pa, now.p_n_pa};
  double f = force(x);
  if (excess(b, f) > 0.0) {
    mark_restart(p, now, 0.0, f, b);
    return p;
  }
  double min_margin = margin(b, f);
  double u = now.u_v;  // sent at now.t_s; the law's next command comes a period later
  for (double t = 0.0; t < horizon;) {
    // One period under u: RK4 in steps of at most the nonlinear method's.
    const PressureOde ode{c, *m.valve, u};
    for (double left = period; left > 0.0;) {
      const double h = std::min(left, ode.step_s(x));
      const P2 x1 = ode.rk4(x, h);
      const double f1 = force(x1);
      if (excess(b, f1) > 0.0) {
        const auto g = [&](double th) { return excess(b, force(ode.rk4(x, th * h))); };
        const double th = bracketed_root(g, 0.0, 1.0, excess(b, f), excess(b, f1), kTimeTolerance_s / h);
        const double f_cross = force(ode.rk4(x, th * h));
        mark_restart(p, now, t + th * h, f_cross, b);
        p.equilibrium_force_n = f_cross;
        return p;
      }
      min_margin = std::min(min_margin, margin(b, f1));
      x = x1;
      f = f1;
      t += h;
      left -= h;
    }
    const double t_abs = now.t_s + t;
    const double u_next = law.command_v(state, t_abs, f, true);
    const bool settled = law.ramp_done(state, t_abs) && std::abs(f - law.reference_n(state, t_abs)) < kSettledForce_n &&
                         std::abs(u_next - u) < kSettledCommand_v;
    u = u_next;
    if (settled) {
      p.min_margin_n = std::min(min_margin, margin(b, f));
      p.equilibrium_force_n = law.reference_n(state, t_abs);
      return p;
    }
  }
  p.horizon_reached = true;
  p.min_margin_n = min_margin;
  p.equilibrium_force_n = f;
  return p;
}

Prediction predict(PredictionMethod method, const PredictorModel& model, const StopSnapshot& stop) noexcept {
  switch (method) {
    case PredictionMethod::kLinearized: return predict_linearized(model, stop);
    case PredictionMethod::kNonlinear: return predict_nonlinear(model, stop);
    case PredictionMethod::kRelaxation:  // needs the phase's history
    case PredictionMethod::kHeld:        // needs the hold's state
      break;
  }
  Prediction none;  // no forecast
  none.method = method;
  none.horizon_reached = true;
  return none;
}

void PhaseHistory::add(double t_s, double p_p_pa, double p_n_pa) noexcept {
  if (skipped_ + 1 < stride_) {
    ++skipped_;
    return;
  }
  skipped_ = 0;
  if (n_ == kCapacity) {  // keep every other sample, and take every other one from now on
    for (std::size_t i = 0; i < kCapacity / 2; ++i) t_[i] = t_[2 * i], p_p_[i] = p_p_[2 * i], p_n_[i] = p_n_[2 * i];
    n_ = kCapacity / 2;
    stride_ *= 2;
  }
  t_[n_] = t_s, p_p_[n_] = p_p_pa, p_n_[n_] = p_n_pa;
  ++n_;
}

RelaxationFit fit_relaxation(const PhaseHistory& h, int chamber, double t_now_s) noexcept {
  RelaxationFit fit;
  const std::size_t n = h.size();
  if (n == 0) return fit;
  double mean = 0.0;
  for (std::size_t i = 0; i < n; ++i) mean += h.p_pa(chamber, i);
  mean /= static_cast<double>(n);
  const double span = h.span_s();
  const auto constant = [&] {  // no time constant can be told: the mean, held
    fit.p_now_pa = fit.p_inf_pa = mean;
    fit.tau_s = std::numeric_limits<double>::infinity();
    double sse = 0.0;
    for (std::size_t i = 0; i < n; ++i) sse += (h.p_pa(chamber, i) - mean) * (h.p_pa(chamber, i) - mean);
    fit.rms_pa = std::sqrt(sse / static_cast<double>(n));
    return fit;
  };
  if (n < 3 || !(span > 0.0)) return constant();
  // tau on a log grid from a few sample intervals to the cap, then golden section around the best.
  const double lo = std::log(std::max(1e-4, 2.0 * span / static_cast<double>(n)));
  const double hi = std::log(kRelaxationMaxTauSpans * span);
  constexpr int kGrid = 33;
  double best_x = hi;
  LinearPart best;
  double xs[kGrid];
  for (int k = 0; k < kGrid; ++k) {
    xs[k] = lo + (hi - lo) * k / (kGrid - 1);
    const LinearPart r = fit_linear_part(h, chamber, mean, std::exp(xs[k]));
    if (r.sse < best.sse) best = r, best_x = xs[k];
  }
  if (!std::isfinite(best.sse)) return constant();
  int k_best = 0;
  while (xs[k_best] != best_x) ++k_best;
  double a = xs[std::max(k_best - 1, 0)], b = xs[std::min(k_best + 1, kGrid - 1)];
  constexpr double kGolden = 0.6180339887498949;
  double x1 = b - kGolden * (b - a), x2 = a + kGolden * (b - a);
  LinearPart f1 = fit_linear_part(h, chamber, mean, std::exp(x1)), f2 = fit_linear_part(h, chamber, mean, std::exp(x2));
  for (int i = 0; i < 40 && b - a > 1e-6; ++i) {
    if (f1.sse < f2.sse) {
      b = x2, x2 = x1, f2 = f1;
      x1 = b - kGolden * (b - a);
      f1 = fit_linear_part(h, chamber, mean, std::exp(x1));
    } else {
      a = x1, x1 = x2, f1 = f2;
      x2 = a + kGolden * (b - a);
      f2 = fit_linear_part(h, chamber, mean, std::exp(x2));
    }
  }
  if (f1.sse < best.sse) best = f1, best_x = x1;
  if (f2.sse < best.sse) best = f2, best_x = x2;
  fit.tau_s = std::exp(best_x);
  fit.tau_at_cap = best_x >= hi - 1e-3;
  fit.p_inf_pa = mean + best.a;
  fit.p_now_pa = fit.p_inf_pa + best.b * std::exp(-(t_now_s - h.t_s(0)) / fit.tau_s);
  fit.rms_pa = std::sqrt(best.sse / static_cast<double>(n));
  return fit;
}

std::optional<Prediction> predict_relaxation(const PredictorModel& m, const StopSnapshot& now,
                                             const PhaseHistory& history) noexcept {
  if (history.size() < kRelaxationMinSamples || history.span_s() < kRelaxationMinSpan_s) return std::nullopt;
  const RelaxationFit fp = fit_relaxation(history, 0, now.t_s), fn = fit_relaxation(history, 1, now.t_s);
  const Common c = common_of(m, now);
  Prediction p;
  p.method = PredictionMethod::kRelaxation;
  p.p_p_equilibrium_pa = fp.p_inf_pa;
  p.p_n_equilibrium_pa = fn.p_inf_pa;
  p.equilibrium_force_n = c.force(fp.p_inf_pa, fn.p_inf_pa);
  p.tau_p_s = fp.tau_s;
  p.tau_n_s = fn.tau_s;
  // The fitted curves from now on, the form of Eq. 17.
  StopSnapshot from = now;
  from.p_p_pa = fp.p_now_pa;
  from.p_n_pa = fn.p_now_pa;
  two_exponential_crossing(p, from, bounds_of(m, now), c.pressure_force.area_p_m2() * (fp.p_now_pa - fp.p_inf_pa),
                           -c.pressure_force.area_n_m2() * (fn.p_now_pa - fn.p_inf_pa), p.equilibrium_force_n);
  return p;
}

ForecastTrack::ForecastTrack(PredictionMethod method, const PredictorModel& model, const StopSnapshot& stop) noexcept
    : method_(method),
      model_(model),
      stop_(stop),
      t_asked_s_(stop.t_s),
      p_p_pa_(stop.p_p_pa),
      p_n_pa_(stop.p_n_pa),
      step_start_s_(stop.t_s),
      step_end_s_(stop.t_s),
      start_{stop.p_p_pa, stop.p_n_pa},
      end_{stop.p_p_pa, stop.p_n_pa} {
  const Common c = common_of(model, stop);
  const Prediction p = base(method, model, stop, c);
  p_p_equilibrium_pa_ = p.p_p_equilibrium_pa;
  p_n_equilibrium_pa_ = p.p_n_equilibrium_pa;
  tau_p_s_ = p.tau_p_s;
  tau_n_s_ = p.tau_n_s;
  if (method == PredictionMethod::kNonlinear) {
    const P2 dx = PressureOde{c, *model.valve, stop.u_v}.rhs({stop.p_p_pa, stop.p_n_pa});
    start_slope_ = end_slope_ = {dx.pp, dx.pn};
  }
}

ForecastPoint ForecastTrack::at(double t_s) noexcept {
  const Common c = common_of(model_, stop_);
  if (method_ == PredictionMethod::kLinearized) {
    // Eq. 24: each pressure relaxes exponentially from its stop value to its equilibrium.
    const double x = std::max(0.0, t_s - stop_.t_s);
    const auto relax = [x](double p0, double pe, double tau) {
      return std::isinf(tau) ? p0 : pe + (p0 - pe) * std::exp(-x / tau);
    };
    const double pp = relax(stop_.p_p_pa, p_p_equilibrium_pa_, tau_p_s_);
    const double pn = relax(stop_.p_n_pa, p_n_equilibrium_pa_, tau_n_s_);
    return {pp, pn, c.force(pp, pn)};
  }
  if (!std::isfinite(t_s) || t_s < t_asked_s_) return {p_p_pa_, p_n_pa_, c.force(p_p_pa_, p_n_pa_)};
  t_asked_s_ = t_s;
  // The steps of predict_nonlinear from the snapshot; between their ends, the cubic Hermite
  // interpolant (from the values and slopes there: as accurate as the RK4 step, far cheaper than
  // a step per tick).
  const PressureOde ode{c, *model_.valve, stop_.u_v};
  while (t_s > step_end_s_) {
    step_start_s_ = step_end_s_;
    start_ = end_;
    start_slope_ = end_slope_;
    const double h = ode.step_s({start_[0], start_[1]});
    const P2 x = ode.rk4({start_[0], start_[1]}, h);
    const P2 dx = ode.rhs(x);
    step_end_s_ = step_start_s_ + h;
    end_ = {x.pp, x.pn};
    end_slope_ = {dx.pp, dx.pn};
  }
  const double h = step_end_s_ - step_start_s_;
  const double u = h > 0.0 ? (t_s - step_start_s_) / h : 1.0;
  const double h00 = (1.0 + 2.0 * u) * (1.0 - u) * (1.0 - u), h10 = u * (1.0 - u) * (1.0 - u);
  const double h01 = u * u * (3.0 - 2.0 * u), h11 = u * u * (u - 1.0);
  p_p_pa_ = h00 * start_[0] + h10 * h * start_slope_[0] + h01 * end_[0] + h11 * h * end_slope_[0];
  p_n_pa_ = h00 * start_[1] + h10 * h * start_slope_[1] + h01 * end_[1] + h11 * h * end_slope_[1];
  return {p_p_pa_, p_n_pa_, c.force(p_p_pa_, p_n_pa_)};
}

bool snapshot_is_finite(const StopSnapshot& s) noexcept {
  return std::isfinite(s.t_s) && std::isfinite(s.y_m) && std::isfinite(s.p_p_pa) && std::isfinite(s.p_n_pa) &&
         std::isfinite(s.u_v);
}

}  // namespace pneu::controller
