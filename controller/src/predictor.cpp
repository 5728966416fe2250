#include "pneu/controller/predictor.hpp"

#include <Eigen/Dense>
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
  model::ChamberProcess process;  // the chambers' process: polytropic, or the energy balance
  double y_m;                     // y*
  // Eq. 23's c in tau = V / (c C_p): k r T, or gamma r T_w with the energy balance (a chamber's
  // pressure at its wall temperature responds to its flow as an adiabatic one does at first)
  double c_tau;
  bool plain;  // polytropic and no spool lag: Eq. 19 as it always was, the pressures alone
  model::SpoolLag spool;
  model::ChamberRest rest_p, rest_n;  // where each chamber settles under u* and -u*
  double force(double p_p, double p_n) const noexcept { return pressure_force.force_n(p_p, p_n); }
};

// Where chamber `side` settles under w; without a valve model (the relaxation fit, which finds
// the asymptotes itself) only the temperature is known: the supply's.
model::ChamberRest rest_of(const PredictorModel& m, const model::ChamberProcess& process, model::Side side, double w_v,
                           double y_m) noexcept {
  if (m.valve == nullptr) return {std::numeric_limits<double>::quiet_NaN(), m.gas.temperature_k};
  return process.rest(*m.valve, side, w_v, y_m);
}

Common common_of(const PredictorModel& m, const StopSnapshot& s) noexcept {
  const double c_tau = m.has_thermal ? m.thermal.adiabatic_index * m.gas.gas_constant_j_per_kg_k *
                                           (m.thermal.wall_temperature_auto ? m.gas.temperature_k
                                                                            : m.thermal.wall_temperature_k)
                                     : m.gas.k_r_t();
  const model::ChamberProcess process = m.process();
  return {model::PressureForce(m.geometry, m.gas.exhaust_pressure_pa),
          m.gas.k_r_t(),
          m.geometry.volume_p_m3(s.y_m),
          m.geometry.volume_n_m3(s.y_m),
          process,
          s.y_m,
          c_tau,
          !m.has_hidden_state(),
          model::SpoolLag{m.spool_time_constant_s},
          rest_of(m, process, model::Side::kP, s.u_v, s.y_m),
          rest_of(m, process, model::Side::kN, -s.u_v, s.y_m)};
}

// The chambers' state at the snapshot: its pressures, and its temperatures and spools as estimated
// (at rest where not given).
struct X {
  double pp, pn, tp, tn;
};
X start_of(const Common& c, const StopSnapshot& s) noexcept {
  return {s.p_p_pa, s.p_n_pa, std::isnan(s.t_p_k) ? c.rest_p.t_k : s.t_p_k, std::isnan(s.t_n_k) ? c.rest_n.t_k : s.t_n_k};
}
double spool_p_of(const StopSnapshot& s) noexcept { return std::isnan(s.w_p_v) ? s.u_v : s.w_p_v; }
double spool_n_of(const StopSnapshot& s) noexcept { return std::isnan(s.w_n_v) ? -s.u_v : s.w_n_v; }

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
  p.model_fits = m.fits;
  p.p_p_equilibrium_pa = c.rest_p.p_pa;
  p.p_n_equilibrium_pa = c.rest_n.p_pa;
  p.equilibrium_force_n = c.force(p.p_p_equilibrium_pa, p.p_n_equilibrium_pa);
  const double c_pp = flow_slope(m, s.u_v, s.p_p_pa, p.p_p_equilibrium_pa);
  const double c_pn = flow_slope(m, -s.u_v, s.p_n_pa, p.p_n_equilibrium_pa);
  p.tau_p_s = c_pp > 0.0 ? c.v_p / (c.c_tau * c_pp) : std::numeric_limits<double>::infinity();
  p.tau_n_s = c_pn > 0.0 ? c.v_n / (c.c_tau * c_pn) : std::numeric_limits<double>::infinity();
  return p;
}

// The two chambers at rest (Eq. 19: Eq. 2 with v = 0) under the held control u*: each relaxes on
// its own towards its equilibrium; with the energy balance, its temperature towards the wall's, and
// with a spool lag, its valve opening towards +-u* from where the spool was at the snapshot (t = 0).
struct ChamberOde {
  const Common& c;
  const model::ValveCharacteristic& valve;
  double u;
  double w_p0, w_n0;  // the spools at t = 0

  // A spool this many time constants after a change is where it was commanded (e^-8: 3e-4).
  static constexpr double kSpoolSettled = 8.0;

  double w_p(double t) const noexcept { return c.spool.after(w_p0, model::SpoolLag::target_v(valve, u), t); }
  double w_n(double t) const noexcept { return c.spool.after(w_n0, model::SpoolLag::target_v(valve, -u), t); }
  bool spools_settled(double t) const noexcept { return !c.spool.lags() || t >= kSpoolSettled * c.spool.time_constant_s; }

  X rhs(const X& x, double t) const noexcept {
    if (c.plain)
      return {c.k_r_t / c.v_p * valve.mass_flow_kg_per_s(u, x.pp), c.k_r_t / c.v_n * valve.mass_flow_kg_per_s(-u, x.pn),
              0.0, 0.0};
    const model::ChamberRates rp = c.process.rates(valve, model::Side::kP, x.pp, x.tp, w_p(t), c.y_m, 0.0);
    const model::ChamberRates rn = c.process.rates(valve, model::Side::kN, x.pn, x.tn, w_n(t), c.y_m, 0.0);
    return {rp.dp_dt_pa_per_s, rn.dp_dt_pa_per_s, rp.dtemperature_dt_k_per_s, rn.dtemperature_dt_k_per_s};
  }
  X rk4(const X& x, double t, double h) const noexcept {
    const X k1 = rhs(x, t);
    const X k2 = rhs({x.pp + 0.5 * h * k1.pp, x.pn + 0.5 * h * k1.pn, x.tp + 0.5 * h * k1.tp, x.tn + 0.5 * h * k1.tn},
                     t + 0.5 * h);
    const X k3 = rhs({x.pp + 0.5 * h * k2.pp, x.pn + 0.5 * h * k2.pn, x.tp + 0.5 * h * k2.tp, x.tn + 0.5 * h * k2.tn},
                     t + 0.5 * h);
    const X k4 = rhs({x.pp + h * k3.pp, x.pn + h * k3.pn, x.tp + h * k3.tp, x.tn + h * k3.tn}, t + h);
    return {x.pp + h / 6.0 * (k1.pp + 2 * k2.pp + 2 * k3.pp + k4.pp),
            x.pn + h / 6.0 * (k1.pn + 2 * k2.pn + 2 * k3.pn + k4.pn),
            x.tp + h / 6.0 * (k1.tp + 2 * k2.tp + 2 * k3.tp + k4.tp),
            x.tn + h / 6.0 * (k1.tn + 2 * k2.tn + 2 * k3.tn + k4.tn)};
  }
  // A tenth of the faster chamber's local time constant (RK4 error << 1e-6 relative), <= 10 ms;
  // while a spool still moves, a tenth of its lag.
  double step_s(const X& x, double t) const noexcept {
    constexpr double kStepFraction = 0.1;
    constexpr double kMaxStep_s = 0.01;
    double slope;
    if (c.plain) {
      slope = std::max(c.k_r_t / c.v_p * -valve.dq_dp(u, x.pp), c.k_r_t / c.v_n * -valve.dq_dp(-u, x.pn));
    } else {
      slope = std::max(c.process.fastest_rate_1_per_s(valve, model::Side::kP, x.pp, x.tp, w_p(t), c.y_m),
                       c.process.fastest_rate_1_per_s(valve, model::Side::kN, x.pn, x.tn, w_n(t), c.y_m));
      if (!spools_settled(t)) slope = std::max(slope, 1.0 / c.spool.time_constant_s);
    }
    return std::min(kMaxStep_s, slope > 0.0 ? kStepFraction / slope : kMaxStep_s);
  }
};

// The force range the chambers can still span from `x` on (each relaxing to its equilibrium p_e):
// the box of the present and equilibrium pressures (a scalar autonomous ODE with q decreasing in p
// moves monotonically). With the energy balance the present pressures are taken at the
// temperature each chamber settles at (its air cooled or warmed to it), and the box widened by
// twice the force that the temperatures' distance from it is worth. With a spool still moving,
// nothing.
struct ForceRange {
  double lo_n, hi_n;
  bool known;
};
ForceRange reachable_forces(const Common& c, const ChamberOde& ode, const X& x, double t, double pe_p,
                            double pe_n) noexcept {
  if (!ode.spools_settled(t)) return {0.0, 0.0, false};
  double pp = x.pp, pn = x.pn, slack = 0.0;
  if (c.process.thermal()) {
    pp = x.pp * c.rest_p.t_k / x.tp;
    pn = x.pn * c.rest_n.t_k / x.tn;
    slack = 2.0 * (c.pressure_force.area_p_m2() * std::abs(x.pp - pp) + c.pressure_force.area_n_m2() * std::abs(x.pn - pn));
  }
  return {c.force(std::min(pp, pe_p), std::max(pn, pe_n)) - slack, c.force(std::max(pp, pe_p), std::min(pn, pe_n)) + slack,
          true};
}

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

// One chamber's state (pressure, and temperature and spool where the model has them) linearised at
// the point Eq. 23's slope names (the stop's state, the equilibrium, or the stop's with the flow's
// chord), relaxing to its equilibrium (p_e, the wall temperature, the spool at `target`): the
// pressure's share of each mode of the linear system (docs/model.md section 6).
ChamberModes chamber_modes(const PredictorModel& m, const Common& c, model::Side side, double p0, double t0, double w0,
                           double target, double p_e) noexcept {
  const bool thermal = c.process.thermal(), lag = c.spool.lags();
  const int n = 1 + (thermal ? 1 : 0) + (lag ? 1 : 0);
  const int it = 1, iw = thermal ? 2 : 1;  // the temperature's and the spool's places
  const double rest = (side == model::Side::kP ? c.rest_p : c.rest_n).t_k;
  using Vec = Eigen::VectorXd;
  const auto rate = [&](const Vec& z) {
    const double t = thermal ? z[it] : rest, w = lag ? z[iw] : target;
    const model::ChamberRates r = c.process.rates(*m.valve, side, z[0], t, w, c.y_m, 0.0);
    Vec dz(n);
    dz[0] = r.dp_dt_pa_per_s;
    if (thermal) dz[it] = r.dtemperature_dt_k_per_s;
    if (lag) dz[iw] = (target - w) / c.spool.time_constant_s;
    return dz;
  };
  Vec z0(n), ze(n);
  z0[0] = p0;
  ze[0] = p_e;
  if (thermal) z0[it] = t0, ze[it] = rest;
  if (lag) z0[iw] = w0, ze[iw] = target;
  // The spool reaches its target within milliseconds, the pressure takes its time over seconds:
  // the slopes are taken with the spool at its target (at the stop's, a spool 0.4 V short of u* put
  // a 1 s restart 27 % early).
  Vec at = m.linearized_slope == LinearizedSlope::kEquilibriumTangent ? ze : z0;
  if (lag) at[iw] = target;
  Eigen::MatrixXd jacobian(n, n);
  const double steps[3] = {10.0, 0.01, 1.0e-4};  // [Pa], [K], [V]: central differences
  for (int j = 0; j < n; ++j) {
    const double h = steps[j == 0 ? 0 : (thermal && j == it ? 1 : 2)];
    Vec up = at, down = at;
    up[j] += h;
    down[j] -= h;
    jacobian.col(j) = (rate(up) - rate(down)) / (2.0 * h);
  }
  // The chord: the pressure's own slope from the stop to the equilibrium, at the wall temperature
  // with the spool at its target (the tangent when they are within 1 Pa).
  if (m.linearized_slope == LinearizedSlope::kChord && std::abs(p0 - p_e) >= 1.0) {
    Vec z = ze;
    z[0] = p0;
    jacobian(0, 0) = rate(z)[0] / (p0 - p_e);
  }
  ChamberModes modes;
  modes.p_equilibrium_pa = p_e;
  modes.count = n;
  const Eigen::EigenSolver<Eigen::MatrixXd> solver(jacobian);
  const Eigen::MatrixXcd vectors = solver.eigenvectors();
  const Eigen::VectorXcd weights = vectors.fullPivLu().solve((z0 - ze).cast<std::complex<double>>());
  for (int i = 0; i < n; ++i) {
    std::complex<double> rate_i = solver.eigenvalues()[i];
    // A mode that does not decay (no flow slope: C_p <= 0) stays where it is, as Eq. 23's infinite tau.
    if (!(rate_i.real() < 0.0)) rate_i = {0.0, 0.0};
    modes.amplitude_pa[static_cast<std::size_t>(i)] = vectors(0, i) * weights[i];
    modes.rate_1_per_s[static_cast<std::size_t>(i)] = rate_i;
  }
  return modes;
}

// Eq. 16/25 for forces that are sums of modes: whether and when F(x) = force(p_P(x), p_N(x)) leaves
// the band b, on a grid a fiftieth of the fastest mode's time constant at first, then a fiftieth
// of the time elapsed, out to forty of the slowest (after which F has settled at the equilibrium
// force, or stays where its non-decaying modes hold it), each crossing located by regula falsi.
void modes_crossing(Prediction& p, const StopSnapshot& s, const Bounds& b, const Common& c, const ChamberModes& mp,
                    const ChamberModes& mn, double horizon_s) noexcept {
  const auto force = [&](double x) { return c.force(mp.pressure_pa(x), mn.pressure_pa(x)); };
  double fastest = 0.0, slowest = std::numeric_limits<double>::infinity();
  bool lasting = false;  // a mode that does not decay
  for (const ChamberModes* modes : {&mp, &mn})
    for (int i = 0; i < modes->count; ++i) {
      const double r = -modes->rate_1_per_s[static_cast<std::size_t>(i)].real();
      if (std::abs(modes->amplitude_pa[static_cast<std::size_t>(i)]) == 0.0) continue;
      if (r > 0.0) {
        fastest = std::max(fastest, r);
        slowest = std::min(slowest, r);
      } else {
        lasting = true;
      }
    }
  double f = force(0.0);
  if (excess(b, f) > 0.0) {
    mark_restart(p, s, 0.0, f, b);
    return;
  }
  double min_margin = margin(b, f);
  if (fastest > 0.0) {
    const double end = std::min(horizon_s, 40.0 / slowest);
    for (double x = 0.0; x < end;) {
      const double h = std::min(end - x, 0.02 * std::max(1.0 / fastest, x));
      const double f1 = force(x + h);
      if (excess(b, f1) > 0.0) {
        const auto g = [&](double xx) { return excess(b, force(xx)); };
        const double at = bracketed_root(g, x, x + h, excess(b, f), excess(b, f1), kTimeTolerance_s);
        mark_restart(p, s, at, force(at), b);
        return;
      }
      min_margin = std::min(min_margin, margin(b, f1));
      x += h;
      f = f1;
    }
  }
  if (!lasting) min_margin = std::min(min_margin, margin(b, p.equilibrium_force_n));
  p.min_margin_n = min_margin;
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

double ChamberModes::main_time_constant_s() const noexcept {
  double largest = 0.0, tau = std::numeric_limits<double>::infinity();
  for (int i = 0; i < count; ++i) {
    const double a = std::abs(amplitude_pa[static_cast<std::size_t>(i)]);
    if (a <= largest) continue;
    largest = a;
    const double r = -rate_1_per_s[static_cast<std::size_t>(i)].real();
    tau = r > 0.0 ? 1.0 / r : std::numeric_limits<double>::infinity();
  }
  return tau;
}

Prediction predict_linearized(const PredictorModel& m, const StopSnapshot& s) noexcept {
  const Common c = common_of(m, s);
  Prediction p = base(PredictionMethod::kLinearized, m, s, c);
  if (c.plain) {
    // Eq. 17: each chamber relaxes from its stop pressure to p_null(+-u*) with its Eq. 23 tau.
    two_exponential_crossing(p, s, bounds_of(m, s), c.pressure_force.area_p_m2() * (s.p_p_pa - p.p_p_equilibrium_pa),
                             -c.pressure_force.area_n_m2() * (s.p_n_pa - p.p_n_equilibrium_pa), p.equilibrium_force_n);
    return p;
  }
  const X x0 = start_of(c, s);
  const ChamberModes mp = chamber_modes(m, c, model::Side::kP, x0.pp, x0.tp, spool_p_of(s), s.u_v, p.p_p_equilibrium_pa);
  const ChamberModes mn = chamber_modes(m, c, model::Side::kN, x0.pn, x0.tn, spool_n_of(s), -s.u_v, p.p_n_equilibrium_pa);
  p.tau_p_s = mp.main_time_constant_s();
  p.tau_n_s = mn.main_time_constant_s();
  modes_crossing(p, s, bounds_of(m, s), c, mp, mn, m.horizon_s);
  return p;
}

Prediction predict_nonlinear(const PredictorModel& m, const StopSnapshot& s) noexcept {
  const Common c = common_of(m, s);
  Prediction p = base(PredictionMethod::kNonlinear, m, s, c);
  const Bounds b = bounds_of(m, s);
  const ChamberOde ode{c, *m.valve, s.u_v, spool_p_of(s), spool_n_of(s)};
  const auto force = [&](const X& x) { return c.force(x.pp, x.pn); };

  X x = start_of(c, s);
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
    // Once no restart is possible, go on only while the box could still hold a smaller margin
    // than the one already met (after an overshoot the box corner lingers near a bound).
    if (const ForceRange range = reachable_forces(c, ode, x, t, pe_p, pe_n);
        range.known && range.lo_n > b.lower_n && range.hi_n < b.upper_n) {
      const double box_margin = std::min(margin(b, range.lo_n), margin(b, range.hi_n));
      if (box_margin >= min_margin - kMarginTolerance_n) {
        p.min_margin_n = std::min(min_margin, box_margin);
        return p;
      }
    }
    const double h = ode.step_s(x, t);
    const X x1 = ode.rk4(x, t, h);
    const double f1 = force(x1);
    if (excess(b, f1) > 0.0) {
      const auto g = [&](double th) { return excess(b, force(ode.rk4(x, t, th * h))); };
      const double th = bracketed_root(g, 0.0, 1.0, excess(b, f), excess(b, f1), kTimeTolerance_s / h);
      mark_restart(p, s, t + th * h, force(ode.rk4(x, t, th * h)), b);
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
  const auto force = [&](const X& x) { return c.force(x.pp, x.pn); };
  const double period = law.period_s();
  const double horizon = std::min(m.horizon_s, kHeldHorizon_s);

  X x = start_of(c, now);
  double spool_p = spool_p_of(now), spool_n = spool_n_of(now);
  double f = force(x);
  if (excess(b, f) > 0.0) {
    mark_restart(p, now, 0.0, f, b);
    return p;
  }
  double min_margin = margin(b, f);
  double u = now.u_v;  // sent at now.t_s; the law's next command comes a period later
  for (double t = 0.0; t < horizon;) {
    // One period under u: RK4 in steps of at most the nonlinear method's, the spools lagging
    // towards it from where the last period left them.
    const ChamberOde ode{c, *m.valve, u, spool_p, spool_n};
    for (double left = period, in_period = 0.0; left > 0.0;) {
      const double h = std::min(left, ode.step_s(x, in_period));
      const X x1 = ode.rk4(x, in_period, h);
      const double f1 = force(x1);
      if (excess(b, f1) > 0.0) {
        const auto g = [&](double th) { return excess(b, force(ode.rk4(x, in_period, th * h))); };
        const double th = bracketed_root(g, 0.0, 1.0, excess(b, f), excess(b, f1), kTimeTolerance_s / h);
        const double f_cross = force(ode.rk4(x, in_period, th * h));
        mark_restart(p, now, t + th * h, f_cross, b);
        p.equilibrium_force_n = f_cross;
        return p;
      }
      min_margin = std::min(min_margin, margin(b, f1));
      x = x1;
      f = f1;
      t += h;
      in_period += h;
      left -= h;
    }
    spool_p = ode.w_p(period);
    spool_n = ode.w_n(period);
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
  p.model_fits = m.fits;
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
  const X x0 = start_of(c, stop);
  end_temperature_ = {x0.tp, x0.tn};
  if (method == PredictionMethod::kLinearized && !c.plain) {
    modes_[0] = chamber_modes(model, c, model::Side::kP, x0.pp, x0.tp, spool_p_of(stop), stop.u_v, p_p_equilibrium_pa_);
    modes_[1] = chamber_modes(model, c, model::Side::kN, x0.pn, x0.tn, spool_n_of(stop), -stop.u_v, p_n_equilibrium_pa_);
  }
  if (method == PredictionMethod::kNonlinear) {
    const X dx = ChamberOde{c, *model.valve, stop.u_v, spool_p_of(stop), spool_n_of(stop)}.rhs(x0, 0.0);
    start_slope_ = end_slope_ = {dx.pp, dx.pn};
  }
}

ForecastPoint ForecastTrack::at(double t_s) noexcept {
  const Common c = common_of(model_, stop_);
  if (method_ == PredictionMethod::kLinearized && !c.plain) {
    const double x = std::max(0.0, t_s - stop_.t_s);
    const double pp = modes_[0].pressure_pa(x), pn = modes_[1].pressure_pa(x);
    return {pp, pn, c.force(pp, pn)};
  }
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
  const ChamberOde ode{c, *model_.valve, stop_.u_v, spool_p_of(stop_), spool_n_of(stop_)};
  while (t_s > step_end_s_) {
    step_start_s_ = step_end_s_;
    start_ = end_;
    start_slope_ = end_slope_;
    const X from{start_[0], start_[1], end_temperature_[0], end_temperature_[1]};
    const double since_stop = step_start_s_ - stop_.t_s;
    const double h = ode.step_s(from, since_stop);
    const X x = ode.rk4(from, since_stop, h);
    const X dx = ode.rhs(x, since_stop + h);
    step_end_s_ = step_start_s_ + h;
    end_ = {x.pp, x.pn};
    end_slope_ = {dx.pp, dx.pn};
    end_temperature_ = {x.tp, x.tn};
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
