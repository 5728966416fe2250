// The restart predictor (docs/model.md section 6): while the carriage is stuck at y* under the constant
// control u* (Eq. 11), will the pressure force leave the stiction band, in which direction, when?
// A pure library: no state, no allocation, no exception.
#pragma once

#include <array>
#include <complex>
#include <cstdint>
#include <cstddef>
#include <limits>
#include <optional>

#include "pneu/controller/predictor_params.hpp"
#include "pneu/controller/hold_law.hpp"
#include "pneu/model/chamber.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::controller {

enum class PredictionMethod : std::uint8_t {
  kLinearized,  ///< the paper's closed form, Eq. 16/17/23-25
  kNonlinear,   ///< the two pressure equations of Eq. 19 integrated with u held at u*
  /// Each chamber's relaxation fitted to the pressures measured since the stop (an exponential
  /// towards its own asymptote), without the valve model: the live predictor only, once the
  /// phase has some history (predict_relaxation).
  kRelaxation,
  /// While the in-position hold drives the valves: the two pressure equations of Eq. 19
  /// integrated under the hold's own commands (its PI law closed on the model's force, tick by
  /// tick), from the pressures of the moment: will the hold keep the force in the band, or (reaching
  /// for the window) when will its ramp break the carriage away (predict_held).
  kHeld,
};

[[nodiscard]] const char* to_string(PredictionMethod m) noexcept;

/// Where the linearized method takes each chamber's flow slope of Eq. 23 (the config's key).

/// What the predictor knows of the bench.
struct PredictorModel {
  model::Geometry geometry;
  model::Gas gas;
  model::FrictionParams friction;                 ///< the stiction bounds F_S+, F_S-
  /// The model or the measured table, not owned: the runtime that forecasts on it owns it
  /// (Runtime's constructor, set_model(); assembly::AssembledRun hands it the run's).
  const model::ValveCharacteristic* valve = nullptr;
  double horizon_s = 600.0;  ///< the nonlinear method gives up (no restart) this long after the stop
  /// The time constants' slope (the linearized method's; both methods report the time constants).
  LinearizedSlope linearized_slope = LinearizedSlope::kStopTangent;
  /// With has_thermal, the chambers' energy balance with wall heat exchange (plant.thermal) in
  /// place of the polytropic process of gas.polytropic_index.
  bool has_thermal = false;
  model::ThermalParams thermal;
  /// The spools' lag (plant.valve.spool_time_constant_s) [s]; 0: none.
  double spool_time_constant_s = 0.0;
  /// Ticks between a command's record and the valves acting on it (a module on a bus: 1), for the
  /// estimate of the chambers' hidden state.
  int command_delay_samples = 0;
  /// The model fitted the bench when it was identified (controller.predictor.model_fit, online
  /// learning's last valve fit): else every forecast made on it says it is uncertain.
  bool fits = true;

  /// The chambers' process of this model (geometry, gas, the energy balance if any).
  [[nodiscard]] model::ChamberProcess process() const noexcept {
    return model::ChamberProcess(geometry, gas, has_thermal ? &thermal : nullptr);
  }
  /// Whether a forecast needs what no sensor gives: the chamber temperatures or the spools'
  /// positions (StopSnapshot's, from a model::ChamberObserver).
  [[nodiscard]] bool has_hidden_state() const noexcept { return has_thermal || spool_time_constant_s > 0.0; }
};

/// The snapshot taken when the stop is confirmed.
struct StopSnapshot {
  double t_s = 0.0;        ///< time the pressures were measured [s]
  double y_m = 0.0;        ///< y*, the rest position [m]
  double p_p_pa = 0.0;     ///< chamber P pressure at t_s [Pa]
  double p_n_pa = 0.0;     ///< chamber N pressure at t_s [Pa]
  double u_v = 0.0;        ///< u*, the control held while stuck (Eq. 11) [V]
  /// +1: at the +L/2 end stop (a push towards + cannot move it), -1 at -L/2, 0 elsewhere.
  int blocked_direction = 0;
  /// What no sensor gives, as estimated (model::ChamberObserver) for a model that has it: the
  /// chamber temperatures [K] (NaN: at the wall's) and the spools' positions as voltages [V] (NaN:
  /// at u* and -u*).
  double t_p_k = std::numeric_limits<double>::quiet_NaN();
  double t_n_k = std::numeric_limits<double>::quiet_NaN();
  double w_p_v = std::numeric_limits<double>::quiet_NaN();
  double w_n_v = std::numeric_limits<double>::quiet_NaN();
};

struct Prediction {
  PredictionMethod method = PredictionMethod::kNonlinear;
  bool will_restart = false;
  int direction = 0;               ///< +1 / -1 when will_restart, else 0
  double t_restart_s = std::numeric_limits<double>::quiet_NaN();  ///< absolute time, NaN if none
  double equilibrium_force_n = 0.0;   ///< F at complete equilibrium under u*, Eq. 17 at t -> inf [N]
  double p_p_equilibrium_pa = 0.0;    ///< p_null(u*) [Pa]
  double p_n_equilibrium_pa = 0.0;    ///< p_null(-u*) [Pa]
  /// The time constants of chambers P and N, Eq. 23 with the model's linearized_slope [s].
  double tau_p_s = 0.0;
  double tau_n_s = 0.0;
  /// Smallest distance of F(t) to the nearer stiction bound it can cross (an end stop blocks
  /// one) from the snapshot up to the restart, or forever when none [N]; 0 at a restart.
  double min_margin_n = 0.0;
  bool horizon_reached = false;       ///< nonlinear: undecided at the horizon, reported as no restart
  /// Made on a model that fitted the bench when identified (PredictorModel::fits): false, the
  /// forecast is uncertain, whatever it says.
  bool model_fits = true;
};

/// The stiction bound a forecast made at force `force_n` turns on: the side of the restart it
/// forecasts, or for "no restart" the side the force relaxes towards (+1 F_S+, -1 F_S-).
[[nodiscard]] constexpr int side_turned_on(const Prediction& p, double force_n) noexcept {
  return p.will_restart ? p.direction : (p.equilibrium_force_n > force_n ? +1 : -1);
}

/// Eq. 16/17/25 with the time constants of Eq. 23 (slope: model.linearized_slope); the condition
/// is checked exactly over all t >= t_stop (F(t) is monotone on both sides of its one possible
/// extremum). With the energy balance or a spool lag, each chamber's state (pressure, temperature,
/// spool) linearised in the same way relaxes as a sum of exponentials (one per state), and the
/// force's crossings are searched on a grid fine against its time constants.
[[nodiscard]] Prediction predict_linearized(const PredictorModel& model, const StopSnapshot& stop) noexcept;
/// Integrates dp/dt = k r T / V(y*) q(+-u*, p) for both chambers (RK4, step a fraction of the
/// local time constant) and locates the first crossing of a stiction bound inside the step; with
/// the energy balance, each chamber's pressure and temperature from the snapshot's (and the spools
/// from theirs, lagging towards +-u*).
[[nodiscard]] Prediction predict_nonlinear(const PredictorModel& model, const StopSnapshot& stop) noexcept;
/// The model-based methods. kRelaxation needs the phase's history (predict_relaxation): here it
/// gives no forecast (no restart, horizon_reached set).
[[nodiscard]] Prediction predict(PredictionMethod method, const PredictorModel& model,
                                 const StopSnapshot& stop) noexcept;

/// The chamber pressures measured since the stop, as the relaxation method fits them. Bounded:
/// past kCapacity samples, every other one is let go and only every 2nd (4th, ...) new one is
/// taken, so that the samples stay spread over the whole phase. A value type, no allocation.
class PhaseHistory {
 public:
  static constexpr std::size_t kCapacity = 512;
  void clear() noexcept { n_ = 0, stride_ = 1, skipped_ = 0; }
  void add(double t_s, double p_p_pa, double p_n_pa) noexcept;
  [[nodiscard]] std::size_t size() const noexcept { return n_; }
  [[nodiscard]] double t_s(std::size_t i) const noexcept { return t_[i]; }
  [[nodiscard]] double p_pa(int chamber, std::size_t i) const noexcept { return chamber == 0 ? p_p_[i] : p_n_[i]; }
  /// From the first sample kept to the last [s].
  [[nodiscard]] double span_s() const noexcept { return n_ < 2 ? 0.0 : t_[n_ - 1] - t_[0]; }

 private:
  std::array<double, kCapacity> t_{}, p_p_{}, p_n_{};
  std::size_t n_ = 0;
  std::uint32_t stride_ = 1, skipped_ = 0;
};

/// One chamber's pressure as the relaxation method fits it: p(t) = p_inf + (p(t_ref) - p_inf)
/// exp(-(t - t_ref) / tau), least squares over the history.
struct RelaxationFit {
  double p_now_pa = 0.0;     ///< the fitted curve at the time forecast from [Pa]
  double p_inf_pa = 0.0;     ///< its asymptote [Pa]
  double tau_s = 0.0;        ///< its time constant [s]
  double rms_pa = 0.0;       ///< the residual [Pa]
  bool tau_at_cap = false;   ///< the history shows no curvature: tau is kMaxTauSpans spans, its cap
};

/// The relaxation method wants this much history before it forecasts.
inline constexpr double kRelaxationMinSpan_s = 0.05;
inline constexpr std::size_t kRelaxationMinSamples = 10;
/// Its time constants are searched up to this many times the history's span: a longer one would
/// extrapolate a straight drift into a far asymptote the history cannot see.
inline constexpr double kRelaxationMaxTauSpans = 10.0;

/// Fits one chamber's relaxation to `history` (chamber 0: P, 1: N) and evaluates it at `t_now_s`.
[[nodiscard]] RelaxationFit fit_relaxation(const PhaseHistory& history, int chamber, double t_now_s) noexcept;

/// The live predictor's third method: each chamber's relaxation fitted to the phase's own history
/// (fit_relaxation), then the pressure force of the two fitted exponentials (Eq. 14, the form of
/// Eq. 17) against the stiction bounds of `model`, from `now` on. It uses the geometry and the
/// friction of `model`, not its valve. Empty with less history than kRelaxationMinSpan_s and
/// kRelaxationMinSamples.
[[nodiscard]] std::optional<Prediction> predict_relaxation(const PredictorModel& model, const StopSnapshot& now,
                                                           const PhaseHistory& history) noexcept;
/// The held forecast looks this far ahead at most (or the model's horizon, if shorter) [s].
inline constexpr double kHeldHorizon_s = 60.0;

/// The live predictor under the in-position hold: from the pressures of `now` (its u_v: the
/// command the hold sent at now.t_s), the chambers' equations integrated one loop period at a
/// time, each period under the command `law` gives from the model's force at its start (as the
/// loop does from the measured one), with `state` the hold as it stands after now.t_s's tick.
/// Within the window: no restart once the force has settled on its reference (min_margin: the
/// smallest distance to a bound on the way), or a restart if the way crosses a bound; reaching:
/// when the ramp breaks the carriage away, and which way. equilibrium_force_n: the reference
/// it settles on (holding) or the force at the breakaway (reaching). Undecided after
/// kHeldHorizon_s: no restart, horizon_reached.
[[nodiscard]] Prediction predict_held(const PredictorModel& model, const HoldLaw& law, HoldState state,
                                      const StopSnapshot& now) noexcept;

/// The chamber pressures and the pressure force a forecast expects at one instant of the
/// sticking phase.
struct ForecastPoint {
  double p_p_pa = 0.0;
  double p_n_pa = 0.0;
  double force_n = 0.0;  ///< Eq. 14 [N]
};

/// One chamber's pressure as the linearized method sees it with the energy balance or a spool lag:
/// its state (pressure, temperature, spool) linearised as Eq. 23 linearises the flow, relaxing to
/// its equilibrium (p_null(+-u*) at the wall temperature, u*) as p(x) = p_e + Re sum_i a_i e^(s_i x),
/// x the time since the snapshot: one mode per state.
struct ChamberModes {
  double p_equilibrium_pa = 0.0;
  int count = 0;
  std::array<std::complex<double>, 3> amplitude_pa{}, rate_1_per_s{};

  [[nodiscard]] double pressure_pa(double x_s) const noexcept {
    double p = p_equilibrium_pa;
    for (int i = 0; i < count; ++i) p += (amplitude_pa[i] * std::exp(rate_1_per_s[i] * x_s)).real();
    return p;
  }
  /// The time constant of the mode carrying most of the pressure's way [s] (infinite when none).
  [[nodiscard]] double main_time_constant_s() const noexcept;
};

/// Follows a forecast through the sticking phase, so that it can be held against the measured
/// pressures and force as they come (the paper's Fig. 13): the linearized method's Eq. 24 and 17
/// in closed form, the nonlinear method's pressure equations integrated forward with the steps
/// of predict_nonlinear and interpolated between them (cubic Hermite: RK4's accuracy, one step
/// per several ticks). A value type: no allocation, no exception; the model's valve must outlive
/// it.
class ForecastTrack {
 public:
  ForecastTrack(PredictionMethod method, const PredictorModel& model, const StopSnapshot& stop) noexcept;

  /// The forecast at `t_s` (absolute). Before the snapshot: the snapshot itself. The nonlinear
  /// method only goes forward, one RK4 step per 10 ms or less of the span it covers: an earlier
  /// time than the last one asked (or NaN, or infinity) gives the last point.
  [[nodiscard]] ForecastPoint at(double t_s) noexcept;
  [[nodiscard]] PredictionMethod method() const noexcept { return method_; }

 private:
  PredictionMethod method_;
  PredictorModel model_;
  StopSnapshot stop_;
  double p_p_equilibrium_pa_ = 0.0, p_n_equilibrium_pa_ = 0.0;
  double tau_p_s_ = 0.0, tau_n_s_ = 0.0;
  ChamberModes modes_[2];  // linearized, with the energy balance or a spool lag: P, N
  // Nonlinear: the last point asked, and the integration step that holds it.
  double t_asked_s_ = 0.0;
  double p_p_pa_ = 0.0, p_n_pa_ = 0.0;
  double step_start_s_ = 0.0, step_end_s_ = 0.0;
  std::array<double, 2> start_{}, start_slope_{}, end_{}, end_slope_{};  // p_P, p_N and their rates
  std::array<double, 2> end_temperature_{};  // T_P, T_N at the step's end
};

/// A forecast needs finite inputs: callers skip the predictors otherwise (a NaN pressure would
/// read as "no restart").
[[nodiscard]] bool snapshot_is_finite(const StopSnapshot& stop) noexcept;

}  // namespace pneu::controller
