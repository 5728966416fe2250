// Identification of the bench from its own signals (position, both chamber pressures, the voltage
// u the loop sent): what a bench is, rather than what its datasheet says. Pure computation on a
// recorded trajectory; no I/O, no threads. The estimators (docs/model.md, section 10):
//   - stiction F_S+ and F_S- from the breakaways (Eq. 15): the force just before the carriage
//     moved, and every force it held while stuck (a lower bound on F_S+, an upper one on F_S-);
//   - Coulomb friction and viscous coefficient from the sliding phases (Eq. 3, F_f = F - M a);
//   - the valves' conductances, their null offset and the two dead volumes from the pressure
//     transients of the stuck phases, where each chamber is a closed volume fed by its valve
//     (Eq. 19): an output-error fit of Eq. 19 integrated over every stuck phase. Stops at
//     different positions separate the volumes from the conductances.
#pragma once

#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/model/params.hpp"

namespace pneu::identify {

/// One sample of the bench as the controller saw it.
struct Sample {
  double t_s = 0.0;       ///< time [s]
  double y_m = 0.0;       ///< measured position [m]
  double p_p_pa = 0.0;    ///< measured chamber P pressure [Pa abs]
  double p_n_pa = 0.0;    ///< measured chamber N pressure [Pa abs]
  double u_v = 0.0;       ///< voltage sent to valve P (valve N got -u) [V]
  /// The valves were driven with +-u_v (armed, no fault): the samples of a phase the loop did not
  /// drive as recorded (disarmed, fault: the outputs were neutral or the safe output) are left
  /// out of the valve fit.
  bool driven = true;
  /// The voltage valve N was sent [V]: -u_v (NaN: -u_v), but for the exhaust safe output.
  double u_n_v = std::numeric_limits<double>::quiet_NaN();
};

/// How the trajectory is read.
struct Options {
  /// A stuck carriage's position readings stay this close to the first still sample [m]
  /// (controller.stop_detector.rest_band_m: 0 for ideal sensors, noise and one ADC step else).
  double rest_band_m = 0.0;
  /// A stuck phase is one at least this long [s].
  double min_stuck_s = 0.02;
  /// The valve fit uses stuck phases at least this long [s] ...
  double min_fit_phase_s = 0.1;
  /// ... and compares the measured pressures with Eq. 19 this often [s].
  double fit_sample_s = 0.005;
  /// Positions closer than this to an end of the stroke are at the end stop, not stuck [m].
  double end_stop_margin_m = 0.002;
  /// Sliding samples for Coulomb and viscous friction: |v| at least this many Stribeck velocities.
  double sliding_min_stribeck = 4.0;
  /// Samples between a command's record and the valves acting on it: -1 finds it (0 in process, 1
  /// over a Modbus link: the command written at a tick reaches the module after that tick's read).
  int command_delay_samples = -1;
  /// Fit the valves and dead volumes (the costly part); false keeps them at the prior, "not
  /// refitted" (online refinement between new long stuck phases).
  bool fit_valves = true;
  /// Where the valve fit starts from besides the prior (online: the last fit with every parameter
  /// free): the fit is not convex, and the lowest of the minima is kept. The prior still weighs as
  /// the prior.
  std::vector<model::PlantParams> valve_fit_starts;
  /// A parameter whose relative standard deviation (1 sigma) exceeds this is not identified: the
  /// data cannot tell it apart from the others, and the prior is kept.
  double max_relative_std = 0.2;
  /// The record starts at rest, the chambers at the wall temperature (an identification run); else
  /// (a window of a running record, online) the model's estimate of what no sensor gives (the
  /// temperatures, the spools) is taken to have forgotten its start only after five thermal time
  /// constants (ten spool lags), and the valve fit leaves out the phases before.
  bool at_rest_at_start = true;
};

/// One parameter before and after.
struct Estimate {
  std::string key;        ///< its config path (plant.friction.static_positive_n ...)
  double prior = 0.0;     ///< the value in the configuration the run started from
  double value = 0.0;     ///< identified (or the prior when not identified)
  double std = 0.0;       ///< 1-sigma uncertainty of `value` [same unit]; 0 when not identified
  bool identified = false;
  std::string basis;      ///< what it was identified from, or why not
};

/// What the trajectory held, counted.
struct Evidence {
  int stuck_phases = 0;            ///< away from the end stops
  int fitted_phases = 0;           ///< long enough for the valve fit
  int breakaways_positive = 0;
  int breakaways_negative = 0;
  /// What the forces held while stuck imply (less their noise): F_S+ >= held_positive_n,
  /// F_S- <= held_negative_n; -inf and +inf when nothing was held that way.
  double held_positive_n = -std::numeric_limits<double>::infinity();
  double held_negative_n = std::numeric_limits<double>::infinity();
  double stuck_s = 0.0;            ///< time stuck, in all
  double sliding_s = 0.0;          ///< time sliding fast enough for Coulomb and viscous friction
  double stuck_position_span_m = 0.0;  ///< the stuck phases' positions, max - min
  double voltage_span_v = 0.0;     ///< the stuck phases' u, max - min
  /// The valve fit's residual, both chambers, with every parameter free: how well the model fits [Pa]
  double pressure_rms_residual_pa = 0.0;
  int command_delay_samples = 0;         ///< the valve fit's command delay [samples]
  /// The pressure sensors' noise as the fitted phases show it, and what the noise explains of a
  /// residual: the noise, or what an exact model leaves of ideal readings (10 Pa) if more [Pa].
  double pressure_noise_pa = 0.0;
  double pressure_explained_pa = 0.0;
  /// The model fits the stuck phases: the residual (every parameter free) within twice what the
  /// noise explains. When it does not, the valve fit's parameters carry the misfit in their
  /// sigmas, and `misfit` names the phases beyond three times it.
  bool model_fits = true;
  struct PhaseMisfit {
    double t_s = 0.0;     ///< the phase's first fitted sample [s]
    double y_m = 0.0;     ///< where [m]
    double rms_pa = 0.0;  ///< its residual, both chambers [Pa]
  };
  std::vector<PhaseMisfit> misfit;
  int misfit_phases_of = 0;  ///< ... of this many fitted
  /// Phases left out of the valve fit: beyond three times what the noise explains when the others,
  /// many (nine or more for each), fit without them (a disturbance the model does not have: a
  /// knock on the carriage, a stalled link). Not counted in `fitted_phases`.
  std::vector<PhaseMisfit> left_out;
  /// The loop's deadlines missing from the fitted phases' samples (a gap over 1.5 times the
  /// record's median spacing counts the ticks it lacks), of `fitted_samples`: over a bus, each one
  /// shifts when the commands reached the valves, which the fit's whole-sample delay does not have.
  int fitted_deadlines_skipped = 0;
  int fitted_samples = 0;
};

/// The result: the bench's parameters (the prior where not identified), each estimate, and the
/// evidence.
struct Identification {
  model::PlantParams plant;
  /// When the valve fit ran: its mode with every valve and volume parameter free. It predicts the
  /// pressures of the stuck phases best, also where a parameter cannot be told apart from the
  /// others (and `plant` keeps the configured value); online learning forecasts on it.
  std::optional<model::PlantParams> jointly_fitted;
  std::vector<Estimate> estimates;
  Evidence evidence;

  /// The estimate of `key`; throws std::out_of_range when there is none.
  [[nodiscard]] const Estimate& at(const std::string& key) const;
};

/// The trajectory cannot identify the bench: `what()` names what is missing.
class InsufficientData : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Identifies the bench from `samples` (time increasing), starting from `prior` (the geometry's
/// areas and stroke, the gas, the mass and the ISO 6358 reference values are taken as known).
/// Throws InsufficientData when there is no sticking phase, no breakaway in either direction, or
/// too little excitation to fit the valves.
[[nodiscard]] Identification identify(std::span<const Sample> samples, const model::PlantParams& prior,
                                      const Options& options = {});

/// The largest |p_null(u) of `a`'s valve - p_null(u) of `b`'s| over |u| <= `u_max_v`, every 5 mV
/// [Pa]: how far two benches' null-flow characteristics (Fig. 6) lie apart.
[[nodiscard]] double largest_null_pressure_difference_pa(const model::PlantParams& a, const model::PlantParams& b,
                                                         double u_max_v);

/// The keys of the parameters identify() estimates, in the order of Identification::estimates.
[[nodiscard]] std::span<const char* const> identified_keys() noexcept;

/// Whether the valve fit estimates `key` (the valves' conductances and null offset, the dead
/// volumes): Options::fit_valves false leaves those at the prior, "not refitted".
[[nodiscard]] bool from_the_valve_fit(std::string_view key) noexcept;

}  // namespace pneu::identify
