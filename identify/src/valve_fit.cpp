#include "valve_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <type_traits>
#include <span>
#include <utility>
#include <vector>

#include "pneu/model/chamber.hpp"
#include "pneu/model/dual.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::identify::detail {

namespace {

// A phase as the fit sees it: where it starts, and the samples it is compared at.
struct FitPhase {
  std::size_t first = 0, last = 0;
  double y_m = 0.0;
  std::vector<std::size_t> observed;
};

// The null offset is not a scale: it is "not identified" beyond this standard deviation [V]
// (p_null moves about 3.3 kPa per 10 mV near u = 0).
constexpr double kMaxNullOffsetStd_v = 0.01;
// The pressure noise the uncertainty assumes at least: a 16-bit reading of a 10 bar transmitter
// steps by 15 Pa [Pa].
constexpr double kPressureNoiseFloor_pa = 20.0;
// What a model that fits leaves at least, even of an ideal sensor's readings (the integration, the
// samples' timing) [Pa]: twice it is the largest residual of a fit with ideal sensors.
constexpr double kResidualFloor_pa = 10.0;
// A fit whose residual exceeds this many times what the noise explains does not fit; a phase whose
// own residual exceeds kPhaseMisfit times it is named.
constexpr double kMisfit = 2.0;
constexpr double kPhaseMisfit = 3.0;
// The command delays tried [samples].
constexpr std::size_t kMaxCommandDelaySamples = 4;
// Leaks in the prior at 0 start the fit from this fraction of C_max (a logarithm needs > 0).
constexpr double kLeakFloorOfMax = 1.0e-3;

// The spool lag is "not identified" beyond this standard deviation [s].
constexpr double kMaxSpoolLagStd_s = 0.001;
// The spool lags the fit tries stay within [0, this] [s].
constexpr double kMaxSpoolLag_s = 0.05;
// The spool lag at which the derivatives at the bound 0 are taken (from above) [s].
constexpr double kSpoolLagAtBound_s = 1e-6;

// theta: ln C_max, ln C_leak_in, ln C_leak_out, w_0, ln V_P0, ln V_N0, ln h, tau_spool.
using Theta = Eigen::Matrix<double, kValveFitParams, 1>;

model::PlantParams applied(model::PlantParams p, const Theta& th) {
  for (std::size_t i = 0; i < kValveFitParams; ++i) {
    if (!has_parameter(p, i)) continue;
    const double t = th[static_cast<Eigen::Index>(i)];
    parameter(p, i) = logarithmic(i) ? std::exp(t) : t;
  }
  return p;
}

Theta theta_of(model::PlantParams p) {
  const double floor = kLeakFloorOfMax * p.valve.max_conductance_m3_per_s_pa;
  Theta th;
  for (std::size_t i = 0; i < kValveFitParams; ++i) {
    const double v = i == kLeakIn || i == kLeakOut ? std::max(parameter(p, i), floor) : parameter(p, i);
    th[static_cast<Eigen::Index>(i)] = logarithmic(i) ? std::log(v) : v;
  }
  return th;
}

// One chamber closed at volume v (Eq. 19): dp/dt = k r T / V q(w, p).
struct Chamber {
  const model::ValveModel* valve;
  double c_over_v;
  // Advances p by h at constant w, in RK4 steps short enough for the chamber's time constant (the
  // valve's opening at w computed once: the same arithmetic as q(w, p), bit for bit).
  [[nodiscard]] double advance(double w, double p, double h) const noexcept {
    const double slope = -c_over_v * valve->dq_dp(w, p);  // 1/tau
    const int steps = std::max(1, static_cast<int>(std::ceil(h * slope / 0.5)));
    const double dt = h / steps;
    const model::ValveEquations<double>& eq = valve->equations();
    const model::ValveEquations<double>::Opening opening = eq.opening(w);
    const auto rate = [&](double pp) { return c_over_v * eq.mass_flow_kg_per_s(opening, pp); };
    for (int i = 0; i < steps; ++i) {
      const double k1 = rate(p);
      const double k2 = rate(p + 0.5 * dt * k1);
      const double k3 = rate(p + 0.5 * dt * k2);
      const double k4 = rate(p + dt * k3);
      p += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    return p;
  }
};

// What the plain model's pressure of one chamber depends on, as the sensitivity integration carries
// them: ln C_max, ln C_leak_in, ln C_leak_out, w_0, the logarithm of its own dead volume, and its
// phase's start (z, in noise floors).
enum Direction : std::size_t { kDMax, kDLeakIn, kDLeakOut, kDNull, kDVolume, kDStart, kDirections };
using Directions = std::array<double, kDirections>;

// Chamber with the derivatives of its pressure: each RK4 step of Chamber::advance taken with the
// variational equation ds/dt = c/V (dq/dp s + dq/dtheta) + d(c/V)/dtheta q beside it, by the same
// stages. That is the exact derivative of Chamber::advance's own steps (an explicit Runge-Kutta
// step's derivative is the step applied to the variational equation), where central differences
// approximate it at twice the cost per parameter.
struct SensitiveChamber {
  const model::ValveModel* valve;
  const model::ValveParams* params;
  double c_over_v;
  double dead_volume_m3, volume_m3;
  double p_supply_pa, p_exhaust_pa;

  // d clamp(x, 0, 1) / dx: at a corner (a valve commanded exactly to its null offset, as an ideal
  // record's zero command is to a null offset of 0) the mean of its two sides, as a central
  // difference would take it.
  static double inside(double x) noexcept { return x > 0.0 && x < 1.0 ? 1.0 : x == 0.0 || x == 1.0 ? 0.5 : 0.0; }
  // What a rate at constant w needs of w: the conductances and dq/dtheta's factors of the unit flows.
  struct Held {
    double c_in, c_out;
    double max_in, max_out;  // dC_in / d ln C_max, dC_out / d ln C_max
    double null_in, null_out;  // -dC_in / dw_0, dC_out / dw_0 (the slope inside the travel)
  };
  [[nodiscard]] Held held(double w) const noexcept {
    const double c_in = valve->inlet_conductance_m3_per_s_pa(w), c_out = valve->outlet_conductance_m3_per_s_pa(w);
    const double opening = (w - params->null_offset_v) / params->max_voltage_v;
    const double slope = params->max_conductance_m3_per_s_pa / params->max_voltage_v;  // dC/dw inside the travel
    return {c_in, c_out, c_in - params->leak_conductance_in_m3_per_s_pa, c_out - params->leak_conductance_out_m3_per_s_pa,
            slope * inside(opening), slope * inside(-opening)};
  }
  // dp/dt at (w, p) and its derivatives given the state's (s).
  void rate(const Held& at, double p, const Directions& s, double& f, Directions& df) const noexcept {
    // The orifices' flows are linear in their conductances: q = C_in m_in - C_out m_out (docs/model.md
    // section 3), C_in = C_leak_in + C_max clamp((w - w_0) / u_max, 0, 1), C_out mirrored. The unit
    // flows m_in, m_out with their slopes by p, by the orifice's own equation.
    using Slope = model::Dual<1>;
    const model::Orifice& orifice = valve->orifice();
    const Slope pressure = Slope::variable(p, 0);
    const Slope unit_in = orifice.flow(Slope(1.0), p_supply_pa, pressure);
    const Slope unit_out = orifice.flow(Slope(1.0), pressure, p_exhaust_pa);
    const double q = at.c_in * unit_in.v - at.c_out * unit_out.v;
    const double q_p = at.c_in * unit_in.d[0] - at.c_out * unit_out.d[0];
    Directions q_theta{};
    q_theta[kDMax] = at.max_in * unit_in.v - at.max_out * unit_out.v;
    q_theta[kDLeakIn] = params->leak_conductance_in_m3_per_s_pa * unit_in.v;
    q_theta[kDLeakOut] = -params->leak_conductance_out_m3_per_s_pa * unit_out.v;
    q_theta[kDNull] = -(at.null_in * unit_in.v + at.null_out * unit_out.v);
    f = c_over_v * q;
    for (std::size_t d = 0; d < kDirections; ++d) df[d] = c_over_v * (q_p * s[d] + q_theta[d]);
    df[kDVolume] -= c_over_v * dead_volume_m3 / volume_m3 * q;  // d(c/V)/d ln V_0 = -c V_0 / V^2
  }
  // Advances p and its derivatives by h at constant w, in Chamber::advance's steps.
  void advance(double w, double& p, Directions& s, double h) const noexcept {
    const double decay = -c_over_v * valve->dq_dp(w, p);
    const int steps = std::max(1, static_cast<int>(std::ceil(h * decay / 0.5)));
    const double dt = h / steps;
    const Held at_w = held(w);
    Directions l1, l2, l3, l4, at;
    double k1, k2, k3, k4;
    const auto along = [&](const Directions& l, double f) {
      for (std::size_t d = 0; d < kDirections; ++d) at[d] = s[d] + f * l[d];
      return at;
    };
    for (int i = 0; i < steps; ++i) {
      rate(at_w, p, s, k1, l1);
      rate(at_w, p + 0.5 * dt * k1, along(l1, 0.5 * dt), k2, l2);
      rate(at_w, p + 0.5 * dt * k2, along(l2, 0.5 * dt), k3, l3);
      rate(at_w, p + dt * k3, along(l3, dt), k4, l4);
      p += dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
      for (std::size_t d = 0; d < kDirections; ++d) s[d] += dt / 6.0 * (l1[d] + 2.0 * l2[d] + 2.0 * l3[d] + l4[d]);
    }
  }
};

// The command acting on each valve over [t_k, t_k+1): the one recorded `delay` samples before
// (within `from`), valve N's as recorded (the safe outputs drive it apart from -u).
struct Commands {
  std::span<const Sample> s;
  std::size_t delay, from;
  [[nodiscard]] std::size_t source(std::size_t i) const noexcept { return i >= from + delay ? i - delay : from; }
  [[nodiscard]] double p(std::size_t i) const noexcept { return s[source(i)].u_v; }
  [[nodiscard]] double n(std::size_t i) const noexcept {
    const Sample& x = s[source(i)];
    return std::isnan(x.u_n_v) ? -x.u_v : x.u_n_v;
  }
};

// The model with hidden state differentiated: its derivatives carried by the directions of theta's
// parameters (in theta's order) and of the start of the chamber integrated (z, per unit of z).
constexpr int kStartDirection = kValveFitParams;
using Dual = model::Dual<kValveFitParams + 1>;

// One chamber at rest with the energy balance and the spool's lag: its pressure, temperature and
// spool advanced together (RK4 in steps short against the chamber's rates and, while the spool
// moves, against its lag). S, Valve: double and the model, or a Dual and the model's equations
// with it (the derivatives of these very steps).
template <class S, class Valve>
struct RestingChamber {
  const model::BasicChamberProcess<S>* process;
  const Valve* valve;
  model::BasicSpoolLag<S> spool;
  model::Side side;
  double y_m;

  // A spool this many lags after a change is where it was commanded (e^-8: 3e-4 of the change); until
  // then, steps of kSpoolStepOfLag lags. The spool's position at each stage is exact (its
  // exponential); against steps of 0.01 lag, over a 12-bench thermal sweep's fits, steps of one lag
  // leave 0.01 to 0.36 Pa rms per fit, at most 7.7 Pa at one sample (a step across the valve's null,
  // where the opening bends), against a fit's floor of 10 Pa. Steps of a quarter of a lag cost three
  // times as much and moved no identified parameter by more than 3e-4 of its value (six benches).
  static constexpr double kSpoolSettled = 8.0;
  static constexpr double kSpoolStepOfLag = 1.0;

  void advance(double command, double h, S& p, S& t_k, S& w) const noexcept {
    const S target = model::BasicSpoolLag<S>::target_v(*valve, command);
    S done(0.0);
    // (The steps' numbers are the values'. Their lengths move with the lag while it settles within
    // h: the derivatives are of these very steps.)
    const double lag_s = model::value(spool.time_constant_s);
    if (spool.lags() && std::abs(model::value(w - target)) > 1e-9) {
      const S moving = kSpoolSettled * lag_s < h ? S(kSpoolSettled * spool.time_constant_s) : S(h);  // std::min
      integrate(target, moving, static_cast<int>(std::ceil(model::value(moving) / (kSpoolStepOfLag * lag_s))), p, t_k, w);
      done = moving;
    }
    if (model::value(h - done) > 0.0) integrate(target, h - done, 0, p, t_k, w);
  }

 private:
  // `steps` RK4 steps over h, at least as many as the chamber's fastest rate asks.
  void integrate(const S& target, const S& h, int steps, S& p, S& t_k, S& w) const noexcept {
    const S w0 = w;
    // At rest: the volume and the wall's area are the same at every stage.
    const typename model::BasicChamberProcess<S>::Place at = process->place(side, y_m, 0.0);
    const auto rates = [&](const S& spool_w, const S& pp, const S& tt) { return process->rates(*valve, at, pp, tt, spool_w); };
    const double fastest =
        process->fastest_rate_1_per_s(*valve, side, model::value(p), model::value(t_k), model::value(w0), y_m);
    steps = std::clamp(std::max(steps, static_cast<int>(std::ceil(model::value(h) * fastest / 0.5))), 1, 10000);
    const S dt = h / static_cast<double>(steps);
    for (int i = 0; i < steps; ++i) {
      const S tau = static_cast<double>(i) * dt;
      const S w_middle = spool.after(w0, target, tau + 0.5 * dt);  // the second and third stages'
      const model::BasicChamberRates<S> k1 = rates(spool.after(w0, target, tau), p, t_k);
      const model::BasicChamberRates<S> k2 =
          rates(w_middle, p + 0.5 * dt * k1.dp_dt_pa_per_s, t_k + 0.5 * dt * k1.dtemperature_dt_k_per_s);
      const model::BasicChamberRates<S> k3 =
          rates(w_middle, p + 0.5 * dt * k2.dp_dt_pa_per_s, t_k + 0.5 * dt * k2.dtemperature_dt_k_per_s);
      const model::BasicChamberRates<S> k4 =
          rates(spool.after(w0, target, tau + dt), p + dt * k3.dp_dt_pa_per_s, t_k + dt * k3.dtemperature_dt_k_per_s);
      p += dt / 6.0 * (k1.dp_dt_pa_per_s + 2.0 * k2.dp_dt_pa_per_s + 2.0 * k3.dp_dt_pa_per_s + k4.dp_dt_pa_per_s);
      t_k += dt / 6.0 *
             (k1.dtemperature_dt_k_per_s + 2.0 * k2.dtemperature_dt_k_per_s + 2.0 * k3.dtemperature_dt_k_per_s +
              k4.dtemperature_dt_k_per_s);
    }
    w = spool.after(w0, target, h);
  }
};

// Each phase's integration starts from its first measured pressures, which carry the sensor's
// noise: with a chamber's time constant of seconds, an error there stays in every later sample of
// the phase, one error per phase and chamber that the valve parameters would otherwise absorb (with
// hil.yaml's sensors, C_max and both dead volumes 7 to 8 sigma off the bench). The fit estimates
// those starts too: z, one per phase and chamber (P, N), the start's correction in units of
// kPressureNoiseFloor_pa, with a prior of 0 +- 1. Not for an ideal sensor's readings (no rest
// band): they are the pressures.
// With the energy balance or a spool lag, what no sensor gives at a phase's start, the chambers'
// temperatures and the spools' positions, is the model's own estimate (model::ChamberObserver)
// along the record up to it: from the measured pressures and positions and the commands.
class Problem {
 public:
  // `delay`: the samples between a command's record and the valves acting on it (a bus's).
  Problem(std::span<const Sample> s, std::vector<FitPhase> phases, const model::PlantParams& prior, std::size_t delay,
          double rest_band_m)
      : s_(s), phases_(std::move(phases)), prior_(prior), delay_(delay), fit_starts_(rest_band_m > 0.0),
        plain_(!prior.has_thermal && !(prior.valve.spool_time_constant_s > 0.0)), still_band_m_(rest_band_m + 1e-12) {
    for (const auto& p : phases_) {
      rows_.push_back(size_);
      size_ += 2 * static_cast<Eigen::Index>(p.observed.size());
    }
    rows_.push_back(size_);
  }
  [[nodiscard]] Eigen::Index size() const noexcept { return size_; }
  /// The starts' corrections: two per phase (P, N).
  [[nodiscard]] Eigen::Index starts() const noexcept {
    return fit_starts_ ? 2 * static_cast<Eigen::Index>(phases_.size()) : 0;
  }
  /// The start a row depends on: phase j's rows alternate P (2j) and N (2j + 1).
  [[nodiscard]] Eigen::Index start_of_row(Eigen::Index row) const noexcept {
    const auto j = std::upper_bound(rows_.begin(), rows_.end(), row) - rows_.begin() - 1;
    return 2 * j + (row - rows_[static_cast<std::size_t>(j)]) % 2;
  }
  /// Polytropic and without a spool lag: the pressures are the model's whole state.
  [[nodiscard]] bool plain() const noexcept { return plain_; }
  /// Phase j's rows: [first, end).
  [[nodiscard]] std::pair<Eigen::Index, Eigen::Index> rows_of(std::size_t j) const noexcept { return {rows_[j], rows_[j + 1]}; }
  [[nodiscard]] const std::vector<FitPhase>& phases() const noexcept { return phases_; }

  // Measured minus Eq. 19's pressures at every observed sample, P then N [Pa].
  [[nodiscard]] Eigen::VectorXd residuals(const Theta& th, const Eigen::VectorXd& z) const {
    const model::PlantParams p = applied(prior_, th);
    const model::ValveModel valve(p.valve, p.gas);
    Eigen::VectorXd r(size_);
    if (plain_) {
      for (std::size_t j = 0; j < phases_.size(); ++j) plain_residuals(p, valve, j, z, r);
      return r;
    }
    const model::ChamberProcess process(p);
    const model::SpoolLag spool{p.valve.spool_time_constant_s};
    const Commands u{s_, delay_, 0};
    model::ChamberObserver at_rest(process, valve, spool);
    at_rest.reset(s_[0].t_s, s_[0].y_m, s_[0].p_p_pa, s_[0].p_n_pa, u.p(0), u.n(0));
    // On from there with the valve's equations themselves (ValveModel's, inlined: the same arithmetic).
    const model::ValveEquations<double>& equations = valve.equations();
    model::BasicChamberObserver<double, model::ValveEquations<double>> observer(process, equations, spool);
    observer.start(s_[0].t_s, s_[0].y_m, at_rest.state(), u.p(0), u.n(0));
    const std::vector<model::ChamberState> at = hidden_states(observer);
    for (std::size_t j = 0; j < phases_.size(); ++j)
      phase_pressures(process, equations, spool, at[j], j, start_pa(j, 0, z), start_pa(j, 1, z),
                      [&](Eigen::Index row, std::size_t obs, double pp, double pn) {
                        r[row] = s_[obs].p_p_pa - pp;
                        r[row + 1] = s_[obs].p_n_pa - pn;
                      });
    return r;
  }
  // The residuals' derivatives, exactly: by the parameters `free` (jt, m x free.size(), per unit of
  // theta) and each row's by its own start (jz, per unit of z, when the starts are fitted) [Pa].
  void derivatives(const Theta& th, const Eigen::VectorXd& z, std::span<const std::size_t> free, Eigen::MatrixXd& jt,
                   Eigen::VectorXd& jz) const {
    if (plain_)
      plain_derivatives(th, z, free, jt, jz);
    else
      hidden_derivatives(th, z, free, jt, jz);
  }

 private:
  // Phase j's start of chamber P (0) or N (1) [Pa]: its first reading, corrected by z.
  [[nodiscard]] double start_pa(std::size_t j, int chamber, const Eigen::VectorXd& z) const {
    const Sample& first = s_[phases_[j].first];
    const auto c = static_cast<Eigen::Index>(2 * j) + chamber;
    return (chamber == 0 ? first.p_p_pa : first.p_n_pa) + (fit_starts_ ? z[c] * kPressureNoiseFloor_pa : 0.0);
  }
  // The model with hidden state's derivatives, by one pass of Dual numbers through the same
  // equations and steps as residuals(): the hidden states along the record (ChamberObserver) and
  // each phase's integration (RestingChamber), every parameter and the start carried as a direction.
  // The rest temperatures the estimate starts from at the record's first sample are taken as given
  // (no derivatives): exact when the wall is at the supply's temperature (the rest temperature then
  // the wall's, whatever the parameters); with a wall at another temperature their share is left out.
  void hidden_derivatives(const Theta& th, const Eigen::VectorXd& z, std::span<const std::size_t> free,
                          Eigen::MatrixXd& jt, Eigen::VectorXd& jz) const {
    model::PlantParams p = applied(prior_, th);
    // A spool lag at its bound 0 is no lag, and its derivative there none; the fit's step asks the
    // limit from above, which a lag of kSpoolLagAtBound_s gives (the pressures are linear in a lag
    // that short).
    if (has_parameter(prior_, kSpoolLag) && !(p.valve.spool_time_constant_s > 0.0))
      p.valve.spool_time_constant_s = kSpoolLagAtBound_s;
    const model::ValveModel valve(p.valve, p.gas);
    // Parameter i's value with its derivative by theta_i (d e^t / dt = e^t for a logarithm).
    const auto seeded = [&](std::size_t i) {
      model::PlantParams q = p;
      const double x = parameter(q, i);
      return has_parameter(p, i) ? Dual::variable(x, static_cast<int>(i), logarithmic(i) ? x : 1.0) : Dual(x);
    };
    model::ValveEquations<Dual> dual_valve(p.valve, p.gas);
    dual_valve.max_conductance_m3_per_s_pa = seeded(kMaxConductance);
    dual_valve.leak_conductance_in_m3_per_s_pa = seeded(kLeakIn);
    dual_valve.leak_conductance_out_m3_per_s_pa = seeded(kLeakOut);
    dual_valve.null_offset_v = seeded(kNullOffset);
    const model::BasicChamberProcess<Dual> process(p.geometry, p.gas, p.has_thermal ? &p.thermal : nullptr,
                                                   seeded(kDeadVolumeP), seeded(kDeadVolumeN), seeded(kHeatTransfer));
    const model::BasicSpoolLag<Dual> spool{seeded(kSpoolLag)};
    const Commands u{s_, delay_, 0};
    model::ChamberObserver at_rest(model::ChamberProcess(p), valve, model::SpoolLag{p.valve.spool_time_constant_s});
    at_rest.reset(s_[0].t_s, s_[0].y_m, s_[0].p_p_pa, s_[0].p_n_pa, u.p(0), u.n(0));
    model::BasicChamberObserver<Dual, model::ValveEquations<Dual>> observer(process, dual_valve, spool);
    observer.start(s_[0].t_s, s_[0].y_m,
                   {s_[0].p_p_pa, s_[0].p_n_pa, at_rest.state().t_p_k, at_rest.state().t_n_k,
                    model::BasicSpoolLag<Dual>::target_v(dual_valve, u.p(0)),
                    model::BasicSpoolLag<Dual>::target_v(dual_valve, u.n(0))},
                   u.p(0), u.n(0));
    const std::vector<model::BasicChamberState<Dual>> at = hidden_states(observer);
    jt.resize(size_, static_cast<Eigen::Index>(free.size()));
    jz.resize(fit_starts_ ? size_ : 0);
    for (std::size_t j = 0; j < phases_.size(); ++j) {
      Dual pp(start_pa(j, 0, z)), pn(start_pa(j, 1, z));
      pp.d[kStartDirection] = pn.d[kStartDirection] = fit_starts_ ? kPressureNoiseFloor_pa : 0.0;
      phase_pressures(process, dual_valve, spool, at[j], j, pp, pn,
                      [&](Eigen::Index row, std::size_t, const Dual& mp, const Dual& mn) {
                        for (std::size_t col = 0; col < free.size(); ++col) {  // the residual is measured - model
                          jt(row, static_cast<Eigen::Index>(col)) = -mp.d[free[col]];
                          jt(row + 1, static_cast<Eigen::Index>(col)) = -mn.d[free[col]];
                        }
                        if (fit_starts_) {
                          jz[row] = -mp.d[kStartDirection];
                          jz[row + 1] = -mn.d[kStartDirection];
                        }
                      });
    }
  }
  // The plain model's residuals' derivatives, exactly (SensitiveChamber): by the parameters `free`
  // (jt, m x free.size(), per unit of theta) and each row's by its own start (jz, per unit of z,
  // when the starts are fitted) [Pa].
  void plain_derivatives(const Theta& th, const Eigen::VectorXd& z, std::span<const std::size_t> free, Eigen::MatrixXd& jt,
                         Eigen::VectorXd& jz) const {
    const model::PlantParams p = applied(prior_, th);
    const model::ValveModel valve(p.valve, p.gas);
    const double c = p.gas.k_r_t();
    jt.resize(size_, static_cast<Eigen::Index>(free.size()));
    jz.resize(fit_starts_ ? size_ : 0);
    // Column c's direction in chamber P's and chamber N's sensitivities (none: the other's volume).
    constexpr std::size_t kNone = kDirections;
    std::vector<std::array<std::size_t, 2>> direction;
    for (const std::size_t i : free) {
      switch (i) {
        case kMaxConductance: direction.push_back({kDMax, kDMax}); break;
        case kLeakIn: direction.push_back({kDLeakIn, kDLeakIn}); break;
        case kLeakOut: direction.push_back({kDLeakOut, kDLeakOut}); break;
        case kNullOffset: direction.push_back({kDNull, kDNull}); break;
        case kDeadVolumeP: direction.push_back({kDVolume, kNone}); break;
        default: direction.push_back({kNone, kDVolume}); break;  // kDeadVolumeN (plain: no others)
      }
    }
    for (std::size_t j = 0; j < phases_.size(); ++j) {
      const FitPhase& ph = phases_[j];
      const auto zj = static_cast<Eigen::Index>(2 * j);
      double pp = s_[ph.first].p_p_pa + (fit_starts_ ? z[zj] * kPressureNoiseFloor_pa : 0.0);
      double pn = s_[ph.first].p_n_pa + (fit_starts_ ? z[zj + 1] * kPressureNoiseFloor_pa : 0.0);
      Directions sp{}, sn{};
      sp[kDStart] = sn[kDStart] = kPressureNoiseFloor_pa;
      const double vp = p.geometry.volume_p_m3(ph.y_m), vn = p.geometry.volume_n_m3(ph.y_m);
      const SensitiveChamber cp{&valve, &p.valve, c / vp, p.geometry.dead_volume_p_m3, vp, p.gas.supply_pressure_pa,
                                p.gas.exhaust_pressure_pa};
      const SensitiveChamber cn{&valve, &p.valve, c / vn, p.geometry.dead_volume_n_m3, vn, p.gas.supply_pressure_pa,
                                p.gas.exhaust_pressure_pa};
      const auto u_at = [&](std::size_t i) { return s_[i >= ph.first + delay_ ? i - delay_ : ph.first].u_v; };
      std::size_t k = ph.first;
      Eigen::Index row = rows_[j];
      for (const std::size_t obs : ph.observed) {
        while (k < obs) {
          std::size_t next = k + 1;
          while (next < obs && u_at(next) == u_at(k)) ++next;
          const double h = s_[next].t_s - s_[k].t_s;
          cp.advance(u_at(k), pp, sp, h);
          cn.advance(-u_at(k), pn, sn, h);
          k = next;
        }
        for (const auto& [chamber, s] : {std::pair{0, &sp}, std::pair{1, &sn}}) {
          for (std::size_t col = 0; col < free.size(); ++col) {
            const std::size_t d = direction[col][static_cast<std::size_t>(chamber)];
            jt(row, static_cast<Eigen::Index>(col)) = d == kNone ? 0.0 : -(*s)[d];  // the residual is measured - model
          }
          if (fit_starts_) jz[row] = -(*s)[kDStart];
          ++row;
        }
      }
    }
  }
  // The chambers' temperatures and spools at each phase's first sample, as the model estimates
  // them along the record (`observer`, reset at the record's first sample).
  template <class Observer>
  [[nodiscard]] std::vector<std::decay_t<decltype(std::declval<Observer&>().state())>> hidden_states(
      Observer& observer) const {
    std::vector<std::decay_t<decltype(observer.state())>> at;
    const Commands u{s_, delay_, 0};
    // Where the carriage stands still under one command, up to kMaxStride samples are one step
    // (the pressures linear in between: a few pascals off over 10 ms, nothing to a temperature).
    constexpr std::size_t kMaxStride = 10;
    std::size_t k = 0;
    for (const FitPhase& ph : phases_) {
      while (k < ph.first) {
        std::size_t next = k + 1;
        while (next < ph.first && next - k < kMaxStride && u.p(next) == u.p(k) && u.n(next) == u.n(k) &&
               std::abs(s_[next + 1].y_m - s_[k].y_m) <= still_band_m_)
          ++next;
        observer.advance(s_[next].t_s, s_[next].y_m, s_[next].p_p_pa, s_[next].p_n_pa);
        observer.command(u.p(next), u.n(next));
        k = next;
      }
      at.push_back(observer.state());
    }
    return at;
  }

  // Phase j's pressures with the energy balance and the spool's lag, from the starts pp, pn and the
  // hidden state `at`: emit(row, sample, P's, N's) at each observed sample.
  template <class S, class Valve, class Emit>
  void phase_pressures(const model::BasicChamberProcess<S>& process, const Valve& valve,
                       const model::BasicSpoolLag<S>& spool, const model::BasicChamberState<S>& at, std::size_t j, S pp,
                       S pn, Emit&& emit) const {
    const FitPhase& ph = phases_[j];
    const RestingChamber<S, Valve> cp{&process, &valve, spool, model::Side::kP, ph.y_m};
    const RestingChamber<S, Valve> cn{&process, &valve, spool, model::Side::kN, ph.y_m};
    S tp = at.t_p_k, tn = at.t_n_k, wp = at.w_p_v, wn = at.w_n_v;
    // Each u holds from its sample to the next (the command of a tick until the next tick). The
    // valves act on the command recorded `delay_` samples before (within the phase).
    const Commands u{s_, delay_, ph.first};
    std::size_t k = ph.first;
    Eigen::Index row = rows_[j];
    for (const std::size_t obs : ph.observed) {
      while (k < obs) {
        std::size_t next = k + 1;
        while (next < obs && u.p(next) == u.p(k) && u.n(next) == u.n(k)) ++next;
        const double h = s_[next].t_s - s_[k].t_s;
        cp.advance(u.p(k), h, pp, tp, wp);
        cn.advance(u.n(k), h, pn, tn, wn);
        k = next;
      }
      emit(row, obs, pp, pn);
      row += 2;
    }
  }

  // The plain model's residuals of phase j (Eq. 19, Chamber).
  void plain_residuals(const model::PlantParams& p, const model::ValveModel& valve, std::size_t j,
                       const Eigen::VectorXd& z, Eigen::VectorXd& r) const {
    const FitPhase& ph = phases_[j];
    double pp = start_pa(j, 0, z), pn = start_pa(j, 1, z);
    std::size_t k = ph.first;
    Eigen::Index row = rows_[j];
    // Each u holds from its sample to the next (the command of a tick until the next tick).
    // The valves act on the command recorded `delay_` samples before (within the phase).
    const auto u_at = [&](std::size_t i) { return s_[i >= ph.first + delay_ ? i - delay_ : ph.first].u_v; };
    const double c = p.gas.k_r_t();
    const Chamber cp{&valve, c / p.geometry.volume_p_m3(ph.y_m)};
    const Chamber cn{&valve, c / p.geometry.volume_n_m3(ph.y_m)};
    for (const std::size_t obs : ph.observed) {
      while (k < obs) {
        std::size_t next = k + 1;
        while (next < obs && u_at(next) == u_at(k)) ++next;
        const double h = s_[next].t_s - s_[k].t_s;
        pp = cp.advance(u_at(k), pp, h);
        pn = cn.advance(-u_at(k), pn, h);
        k = next;
      }
      r[row++] = s_[obs].p_p_pa - pp;
      r[row++] = s_[obs].p_n_pa - pn;
    }
  }

  std::span<const Sample> s_;
  std::vector<FitPhase> phases_;
  model::PlantParams prior_;
  std::size_t delay_ = 0;
  bool fit_starts_ = true;
  bool plain_ = true;  // polytropic, no spool lag: the pressures are the whole state
  double still_band_m_;  // readings this close are a carriage standing still
  Eigen::Index size_ = 0;
  std::vector<Eigen::Index> rows_;  // each phase's first row, then size_
};

struct Solution {
  Eigen::VectorXd residual_pa;  // the data's, at the solution
  Theta theta;
  Eigen::Matrix<double, kValveFitParams, kValveFitParams> covariance;  // with the starts' uncertainty in it
  double rms_pa = 0.0;
  double cost = 0.0;  // the data's and the prior's, in their standard deviations (what is minimised)
};

// The prior's spread: how far the bench may be from the model before the data says otherwise
// (1 sigma): half the value for the conductances and volumes (theta is their logarithm), 0.1 V
// for the null offset. The fit is the posterior's mode: a combination the data sees is set by
// the data, one it does not see stays near the model's value.
constexpr double kPriorSpreadLog = 0.5;
constexpr double kPriorSpreadNullOffset_v = 0.1;
// The wall's heat transfer is known to a factor of e either way (benches' thermal time constants
// run from tenths of a second to seconds), the spool lag to 5 ms.
constexpr double kPriorSpreadHeatTransferLog = 1.0;
constexpr double kPriorSpreadSpoolLag_s = 0.005;

double prior_spread(std::size_t i) {
  switch (i) {
    case kNullOffset: return kPriorSpreadNullOffset_v;
    case kHeatTransfer: return kPriorSpreadHeatTransferLog;
    case kSpoolLag: return kPriorSpreadSpoolLag_s;
    default: return kPriorSpreadLog;
  }
}

// A step that lowers the cost (a chi-square) by less than this leaves the parameters within about
// a thousandth of their sigma of the optimum (sqrt of the decrease): the search has converged.
constexpr double kConvergedDecrease = 1e-6;

// Levenberg-Marquardt on the free parameters and the phases' starts (the Jacobian exact: the plain
// model's by the pressures' sensitivities, with the hidden state by Dual numbers) for the measured
// pressures, at kPressureNoiseFloor_pa, and the priors; the
// posterior covariance of the parameters (the starts' uncertainty marginalised), scaled up when
// the residual is noisier than the floor. Each row depends on one start alone, so the normal
// equations are formed without the starts' columns in full.
Solution levenberg_marquardt(const Problem& problem, Theta theta, const Theta& prior,
                             const std::array<bool, kValveFitParams>& free) {
  std::vector<std::size_t> idx;
  for (std::size_t i = 0; i < kValveFitParams; ++i)
    if (free[i]) idx.push_back(i);
  const auto nf = static_cast<Eigen::Index>(idx.size());
  const auto m = problem.size();
  const auto nz = problem.starts();
  const auto n = nf + nz;
  const double noise = kPressureNoiseFloor_pa;
  std::vector<Eigen::Index> start_of(nz > 0 ? static_cast<std::size_t>(m) : 0);
  for (Eigen::Index row = 0; nz > 0 && row < m; ++row)
    start_of[static_cast<std::size_t>(row)] = problem.start_of_row(row);
  Eigen::VectorXd z = Eigen::VectorXd::Zero(nz);
  // The data's residuals, weighted by the noise.
  const auto residuals = [&](const Theta& th, const Eigen::VectorXd& zz) {
    return Eigen::VectorXd(problem.residuals(th, zz) / noise);
  };
  const auto prior_cost = [&](const Theta& th, const Eigen::VectorXd& zz) {
    double c = zz.squaredNorm();
    for (const std::size_t i : idx) {
      const auto d = static_cast<Eigen::Index>(i);
      c += std::pow((th[d] - prior[d]) / prior_spread(i), 2);
    }
    return c;
  };
  // The normal equations' matrix (data only) and gradient at (th, zz), from the data's residuals r.
  struct Normal {
    Eigen::MatrixXd a;
    Eigen::VectorXd g;
  };
  // The data's residuals' derivatives: by the free parameters (m x nf), and each row's by its start.
  struct Jacobian {
    Eigen::MatrixXd jt;
    Eigen::VectorXd jz;
  };
  const auto jacobian = [&](const Theta& th, const Eigen::VectorXd& zz) {
    Jacobian j{Eigen::MatrixXd(m, nf), Eigen::VectorXd()};
    problem.derivatives(th, zz, idx, j.jt, j.jz);
    j.jt /= noise;
    j.jz /= noise;
    return j;
  };
  // The Jacobian of the last normal equations formed: at the solution, once the search ends.
  Jacobian j;
  const auto normal = [&](const Theta& th, const Eigen::VectorXd& zz, const Eigen::VectorXd& r) {
    j = jacobian(th, zz);
    const Eigen::MatrixXd& jt = j.jt;
    Normal out{Eigen::MatrixXd::Zero(n, n), Eigen::VectorXd::Zero(n)};
    out.a.topLeftCorner(nf, nf) = jt.transpose() * jt;
    out.g.head(nf) = jt.transpose() * r;
    if (nz == 0) return out;
    const Eigen::VectorXd& jz = j.jz;
    for (Eigen::Index row = 0; row < m; ++row) {
      const Eigen::Index c = nf + start_of[static_cast<std::size_t>(row)];
      out.a(c, c) += jz[row] * jz[row];
      out.g[c] += jz[row] * r[row];
      for (Eigen::Index q = 0; q < nf; ++q) out.a(q, c) += jt(row, q) * jz[row];
    }
    out.a.bottomLeftCorner(nz, nf) = out.a.topRightCorner(nf, nz).transpose();
    return out;
  };
  // The priors' share of the normal equations.
  const auto with_priors = [&](Normal nm, const Theta& th, const Eigen::VectorXd& zz) {
    for (Eigen::Index c = 0; c < nf; ++c) {
      const std::size_t i = idx[static_cast<std::size_t>(c)];
      const double w = 1.0 / (prior_spread(i) * prior_spread(i));
      nm.a(c, c) += w;
      nm.g[c] += w * (th[static_cast<Eigen::Index>(i)] - prior[static_cast<Eigen::Index>(i)]);
    }
    for (Eigen::Index c = 0; c < nz; ++c) {
      nm.a(nf + c, nf + c) += 1.0;
      nm.g[nf + c] += zz[c];
    }
    return nm;
  };
  Eigen::VectorXd r = residuals(theta, z);
  double cost = r.squaredNorm() + prior_cost(theta, z);
  double lambda = 1.0e-3;
  Normal nm = normal(theta, z, r);
  for (int iteration = 0; iteration < 100 && n > 0; ++iteration) {
    const Normal full = with_priors(nm, theta, z);
    bool improved = false;
    for (int tries = 0; tries < 12 && !improved; ++tries) {
      Eigen::MatrixXd damped = full.a;
      for (Eigen::Index d = 0; d < n; ++d) damped(d, d) += lambda * std::max(full.a(d, d), 1e-30);
      Eigen::VectorXd step = damped.ldlt().solve(-full.g);
      // A trust region: no parameter moves by more than its prior's spread in one step. A long
      // Gauss-Newton step can take the dead volumes far below the swept volume at once, where the
      // pressures no longer depend on them and the search stalls. (Not the starts: they act almost
      // linearly.)
      for (Eigen::Index c = 0; c < nf; ++c) {
        const double limit = prior_spread(idx[static_cast<std::size_t>(c)]);
        if (std::abs(step[c]) > limit) step *= limit / std::abs(step[c]);
      }
      Theta trial = theta;
      for (Eigen::Index c = 0; c < nf; ++c) trial[static_cast<Eigen::Index>(idx[static_cast<std::size_t>(c)])] += step[c];
      trial[kNullOffset] = std::clamp(trial[kNullOffset], -5.0, 5.0);
      trial[kSpoolLag] = std::clamp(trial[kSpoolLag], 0.0, kMaxSpoolLag_s);
      const Eigen::VectorXd trial_z = z + step.tail(nz);
      const Eigen::VectorXd rt = residuals(trial, trial_z);
      const double ct = rt.squaredNorm() + prior_cost(trial, trial_z);
      if (std::isfinite(ct) && ct < cost) {
        const double decrease = cost - ct;
        theta = trial;
        z = trial_z;
        r = rt;
        cost = ct;
        lambda = std::max(lambda / 3.0, 1e-12);
        improved = true;
        nm = normal(theta, z, r);
        if (decrease < std::max(kConvergedDecrease, 1e-12 * ct)) iteration = 1000;  // converged
      } else {
        lambda *= 4.0;
      }
    }
    if (!improved) break;
  }
  Solution sol;
  sol.residual_pa = r * noise;
  sol.theta = theta;
  sol.covariance.setZero();
  const double data_cost = r.squaredNorm() * noise * noise;
  sol.rms_pa = m > 0 ? std::sqrt(data_cost / static_cast<double>(m)) : 0.0;
  sol.cost = cost;
  if (nf > 0) {
    // Residuals noisier than the floor: the data's information is that much less.
    const double scale = std::max(1.0, (sol.rms_pa / noise) * (sol.rms_pa / noise));
    Normal info{nm.a / scale, Eigen::VectorXd::Zero(n)};
    info = with_priors(info, prior, Eigen::VectorXd::Zero(nz));  // (the gradient is not used)
    Eigen::MatrixXd cov = info.a.inverse();
    // What the residuals actually do, phase by phase (a sandwich clustered on the phases): a
    // residual that runs through each phase (small misfits of the model: its estimate of the hidden
    // state, the integration) moves the parameters by more than independent noise at the floor
    // would. Each parameter keeps the larger of the two variances.
    const Normal data_and_prior = with_priors(nm, prior, Eigen::VectorXd::Zero(nz));
    const Eigen::MatrixXd a_inverse = data_and_prior.a.inverse();
    Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(n, n);
    for (std::size_t ph = 0; ph < problem.phases().size(); ++ph) {
      const auto [from, to] = problem.rows_of(ph);
      Eigen::VectorXd score = Eigen::VectorXd::Zero(n);
      score.head(nf) = j.jt.middleRows(from, to - from).transpose() * r.segment(from, to - from);
      for (Eigen::Index row = from; nz > 0 && row < to; ++row)
        score[nf + start_of[static_cast<std::size_t>(row)]] += j.jz[row] * r[row];
      meat += score * score.transpose();
    }
    const Eigen::MatrixXd sandwich = a_inverse * meat * a_inverse;
    for (Eigen::Index d = 0; d < nf; ++d) {
      const double larger = std::max(cov(d, d), sandwich(d, d));
      if (cov(d, d) > 0.0) {  // the row and column scaled, so that the correlations stay
        const double f = std::sqrt(larger / cov(d, d));
        cov.row(d) *= f;
        cov.col(d) *= f;
      }
    }
    for (Eigen::Index a_ = 0; a_ < nf; ++a_)
      for (Eigen::Index b_ = 0; b_ < nf; ++b_)
        sol.covariance(static_cast<Eigen::Index>(idx[static_cast<std::size_t>(a_)]),
                       static_cast<Eigen::Index>(idx[static_cast<std::size_t>(b_)])) = cov(a_, b_);
  }
  return sol;
}

// The pressure sensors' noise, both chambers, from the fitted phases' readings: their second
// differences (a smooth drift's are nothing at a millisecond), robustly (the median absolute value;
// white noise of deviation s gives second differences of deviation s sqrt(6)) [Pa].
double pressure_noise_pa(std::span<const Sample> s, const std::vector<FitPhase>& phases) {
  std::vector<double> d;
  for (const FitPhase& ph : phases)
    for (std::size_t k = ph.first + 1; k < ph.last; ++k) {
      d.push_back(std::abs(s[k + 1].p_p_pa - 2.0 * s[k].p_p_pa + s[k - 1].p_p_pa));
      d.push_back(std::abs(s[k + 1].p_n_pa - 2.0 * s[k].p_n_pa + s[k - 1].p_n_pa));
    }
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2] / (0.6745 * std::sqrt(6.0));
}

// The stuck phases the fit compares, each with the samples it is compared at.
std::vector<FitPhase> fit_phases(std::span<const Sample> s, std::span<const StuckPhase> phases,
                                 const model::PlantParams& prior, const Options& o) {
  // A window of a running record: the estimate of the hidden state starts from a guess (at rest),
  // and is trusted once it has forgotten it.
  double warm_up_s = 0.0;
  if (!o.at_rest_at_start && prior.has_thermal) warm_up_s = 5.0 * model::thermal_time_constant_s(prior);
  if (!o.at_rest_at_start && prior.valve.spool_time_constant_s > 0.0)
    warm_up_s = std::max(warm_up_s, 10.0 * prior.valve.spool_time_constant_s);
  std::vector<FitPhase> fit;
  for (const StuckPhase& p : phases) {
    if (!p.driven || s[p.still_last].t_s - s[p.still_first].t_s < o.min_fit_phase_s) continue;
    if (s[p.still_first].t_s - s.front().t_s < warm_up_s) continue;
    FitPhase f{p.still_first, p.still_last, p.y_m, {}};
    double next_t = s[p.still_first].t_s + o.fit_sample_s;
    for (std::size_t k = p.still_first + 1; k <= p.still_last; ++k)
      if (s[k].t_s >= next_t - 1e-9) {
        f.observed.push_back(k);
        next_t = s[k].t_s + o.fit_sample_s;
      }
    if (!f.observed.empty()) fit.push_back(std::move(f));
  }
  return fit;
}

}  // namespace

FitCheck check_fit_model(std::span<const Sample> s, std::span<const StuckPhase> phases, const model::PlantParams& prior,
                         const Options& o, const model::PlantParams& at, std::span<const double> z, bool derivatives) {
  const std::size_t delay = o.command_delay_samples >= 0 ? static_cast<std::size_t>(o.command_delay_samples) : 0;
  const Problem problem(s, fit_phases(s, phases, prior, o), prior, delay, o.rest_band_m);
  Eigen::VectorXd zz = Eigen::VectorXd::Zero(problem.starts());
  for (Eigen::Index c = 0; c < zz.size() && static_cast<std::size_t>(c) < z.size(); ++c) zz[c] = z[static_cast<std::size_t>(c)];
  const Theta th = theta_of(at);
  FitCheck out;
  const Eigen::VectorXd r = problem.residuals(th, zz);
  out.residual_pa.assign(r.begin(), r.end());
  out.starts = static_cast<std::size_t>(problem.starts());
  for (Eigen::Index row = 0; out.starts > 0 && row < r.size(); ++row)
    out.start_of_row.push_back(static_cast<std::size_t>(problem.start_of_row(row)));
  if (!derivatives) return out;
  std::vector<std::size_t> present;
  for (std::size_t i = 0; i < kValveFitParams; ++i)
    if (has_parameter(prior, i)) present.push_back(i);
  Eigen::MatrixXd jt;
  Eigen::VectorXd jz;
  problem.derivatives(th, zz, present, jt, jz);
  out.by_theta.assign(static_cast<std::size_t>(r.size()) * kValveFitParams, 0.0);
  for (Eigen::Index row = 0; row < jt.rows(); ++row)
    for (std::size_t c = 0; c < present.size(); ++c)
      out.by_theta[static_cast<std::size_t>(row) * kValveFitParams + present[c]] = jt(row, static_cast<Eigen::Index>(c));
  out.by_start.assign(jz.begin(), jz.end());
  return out;
}

bool has_parameter(const model::PlantParams& prior, std::size_t i) noexcept {
  if (i == kHeatTransfer) return prior.has_thermal;
  if (i == kSpoolLag) return prior.valve.spool_time_constant_s > 0.0;
  return i < kValveFitParams;
}

ValveFit fit_valves(std::span<const Sample> s, std::span<const StuckPhase> phases, const model::PlantParams& prior,
                    const Options& o) {
  std::vector<FitPhase> fit = fit_phases(s, phases, prior, o);
  ValveFit out;
  out.plant = prior;
  out.joint = prior;
  out.phases = static_cast<int>(fit.size());
  if (fit.empty()) {
    out.basis.fill("no stuck phase long enough to fit the pressure transients");
    return out;
  }
  // The command delay: the whole samples that fit best (0 in process; a Modbus link adds one),
  // tried from 0 up while the fit improves, unless given.
  const Theta prior_theta = theta_of(prior);
  // The model's parameters (the heat transfer and the spool lag only where it has them).
  std::array<bool, kValveFitParams> present{}, free{};
  for (std::size_t i = 0; i < kValveFitParams; ++i) {
    present[i] = free[i] = has_parameter(prior, i);
    if (!present[i])
      out.basis[i] = i == kHeatTransfer ? "the model has no heat exchange (plant.thermal)" : "the model has no spool lag";
  }
  const auto held_back = [&] {  // a parameter of the model held at its prior
    for (std::size_t i = 0; i < kValveFitParams; ++i)
      if (present[i] && !free[i]) return true;
    return false;
  };
  std::size_t delay = o.command_delay_samples >= 0 ? static_cast<std::size_t>(o.command_delay_samples) : 0;
  std::optional<Problem> problem;
  problem.emplace(s, fit, prior, delay, o.rest_band_m);
  Solution all = levenberg_marquardt(*problem, prior_theta, prior_theta, free);
  // The fit is not convex: started from the prior it can settle in another minimum than from an
  // earlier fit (online, the last one with every parameter free). The lowest is kept; a start
  // already tried is not tried again.
  std::vector<Theta> tried{prior_theta};
  for (const model::PlantParams& start : o.valve_fit_starts) {
    const Theta theta = theta_of(start);
    if (std::find(tried.begin(), tried.end(), theta) != tried.end()) continue;
    tried.push_back(theta);
    const Solution from_start = levenberg_marquardt(*problem, theta, prior_theta, free);
    if (from_start.cost < all.cost) all = from_start;
  }
  for (std::size_t d = 1; o.command_delay_samples < 0 && d <= kMaxCommandDelaySamples; ++d) {
    Problem later(s, fit, prior, d, o.rest_band_m);
    Solution fitted = levenberg_marquardt(later, all.theta, prior_theta, free);
    if (!(fitted.rms_pa < all.rms_pa)) break;
    all = fitted;
    delay = d;
    problem.emplace(std::move(later));
  }
  out.command_delay_samples = static_cast<int>(delay);
  // Does the model fit? Its residual against what the sensors' noise explains. One that does not
  // (a bench with physics the model lacks: heat exchange, a spool lag) leaves residuals that run
  // through each phase, not white noise: each phase's then counts as one sample, and the
  // parameters' covariance grows by the rows per phase (on top of the residual's own scale).
  out.noise_pa = pressure_noise_pa(s, fit);
  out.explained_pa = std::max(out.noise_pa, kResidualFloor_pa);
  out.fits = all.rms_pa <= kMisfit * out.explained_pa;
  const double inflation = out.fits ? 1.0 : static_cast<double>(problem->size()) / static_cast<double>(fit.size());
  all.covariance *= inflation;
  out.joint = applied(prior, all.theta);
  // The parameters the data cannot tell apart (their posterior standard deviation with all the
  // others free stays near the prior's) go back to their priors, and the rest is fitted again.
  // The rest keep the larger of their two standard deviations: fitted around a prior that may be
  // wrong, they are no surer than the data made them with everything free.
  // The largest 1-sigma of an identified parameter: relative for a logarithm, 10 mV for the offset,
  // 1 ms for the spool lag.
  const auto max_std = [&](std::size_t i) {
    return i == kNullOffset ? kMaxNullOffsetStd_v : i == kSpoolLag ? kMaxSpoolLagStd_s : o.max_relative_std;
  };
  std::array<double, kValveFitParams> marginal{};
  for (std::size_t i = 0; i < kValveFitParams; ++i) {
    if (!present[i]) continue;
    marginal[i] = std::sqrt(std::max(0.0, all.covariance(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i))));
    const double score = marginal[i] / max_std(i);
    if (!(score <= 1.0)) {
      free[i] = false;
      out.basis[i] = "not separable from the others by these stuck phases (1 sigma " +
                     std::string(i == kNullOffset ? "over 10 mV" : i == kSpoolLag ? "over 1 ms" : "over the relative limit") +
                     "): prior kept";
    }
  }
  // A parameter refitted around those priors also moves by as much as holding them there shifts it
  // from the mode: that shift is part of its uncertainty (the priors may be wrong by their whole
  // spread). One it makes too uncertain joins the priors, and the rest is fitted again.
  Solution sol = all;
  while (held_back()) {
    Theta start = all.theta;
    for (std::size_t i = 0; i < kValveFitParams; ++i)
      if (!free[i]) start[static_cast<Eigen::Index>(i)] = prior_theta[static_cast<Eigen::Index>(i)];
    sol = levenberg_marquardt(*problem, start, prior_theta, free);
    sol.covariance *= inflation;
    bool held_more = false;
    for (std::size_t i = 0; i < kValveFitParams; ++i) {
      if (!free[i]) continue;
      const auto d = static_cast<Eigen::Index>(i);
      const double shift = sol.theta[d] - all.theta[d];
      sol.covariance(d, d) = std::max(sol.covariance(d, d), marginal[i] * marginal[i]) + shift * shift;
      const double sd = std::sqrt(sol.covariance(d, d));
      if (sd <= max_std(i)) continue;
      free[i] = false;
      held_more = true;
      char text[120];
      if (i == kNullOffset)
        std::snprintf(text, sizeof text, "%+.3g V", shift);
      else if (i == kSpoolLag)
        std::snprintf(text, sizeof text, "%+.3g ms", 1e3 * shift);
      else
        std::snprintf(text, sizeof text, "%+.0f %%", 100.0 * (std::exp(shift) - 1.0));
      out.basis[i] = std::string("moves by ") + text +
                     " when the parameters not separable keep their priors (1 sigma then over the limit): prior kept";
    }
    if (!held_more) break;
  }
  out.plant = applied(prior, sol.theta);
  // Parameters not identified keep the prior exactly (a leak of 0 stays 0), and no spread.
  model::PlantParams kept = prior;
  for (std::size_t i = 0; i < kValveFitParams; ++i) {
    out.identified[i] = free[i];
    const auto d = static_cast<Eigen::Index>(i);
    const double sd = std::sqrt(std::max(0.0, sol.covariance(d, d)));
    if (!free[i]) parameter(out.plant, i) = parameter(kept, i);
    out.std[i] = !free[i] ? 0.0 : logarithmic(i) ? sd * parameter(out.plant, i) : sd;
  }
  out.rms_residual_pa = sol.rms_pa;
  // Each phase's residual at the fit with every parameter free: where the model fails, by name.
  for (std::size_t j = 0; j < problem->phases().size(); ++j) {
    const auto [from, to] = problem->rows_of(j);
    const double sse = all.residual_pa.segment(from, to - from).squaredNorm();
    const double rms = to > from ? std::sqrt(sse / static_cast<double>(to - from)) : 0.0;
    const FitPhase& ph = problem->phases()[j];
    out.phase_residuals.push_back({ph.first, ph.last, ph.y_m, rms, rms > kPhaseMisfit * out.explained_pa});
  }
  out.joint_rms_residual_pa = all.rms_pa;
  return out;
}

}  // namespace pneu::identify::detail
