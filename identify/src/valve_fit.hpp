// The output-error fit of Eq. 19 over the stuck phases (internal to pneu_identify).
#pragma once

#include <array>
#include <span>
#include <string>
#include <vector>

#include "phases.hpp"
#include "pneu/model/params.hpp"

namespace pneu::identify::detail {

/// The fitted parameters, in this order. The wall's heat transfer is fitted when the prior has the
/// chambers' energy balance (plant.thermal), the spool lag when the prior has one (> 0); else they
/// are not the model's, and not estimated.
enum ValveFitParam : std::size_t {
  kMaxConductance,
  kLeakIn,
  kLeakOut,
  kNullOffset,
  kDeadVolumeP,
  kDeadVolumeN,
  kHeatTransfer,
  kSpoolLag,
  kValveFitParams
};

/// Whether `prior`'s model has parameter i (the heat transfer and the spool lag only some).
[[nodiscard]] bool has_parameter(const model::PlantParams& prior, std::size_t i) noexcept;

/// The plant's value of fitted parameter i (the one place that maps the fit's parameters to the
/// plant's; the tests move them by it).
[[nodiscard]] inline double& parameter(model::PlantParams& p, std::size_t i) noexcept {
  switch (i) {
    case kMaxConductance: return p.valve.max_conductance_m3_per_s_pa;
    case kLeakIn: return p.valve.leak_conductance_in_m3_per_s_pa;
    case kLeakOut: return p.valve.leak_conductance_out_m3_per_s_pa;
    case kNullOffset: return p.valve.null_offset_v;
    case kDeadVolumeP: return p.geometry.dead_volume_p_m3;
    case kDeadVolumeN: return p.geometry.dead_volume_n_m3;
    case kHeatTransfer: return p.thermal.heat_transfer_w_per_m2_k;
    default: return p.valve.spool_time_constant_s;
  }
}

/// The fit's theta_i is the logarithm of parameter i's value, but for the null offset, an offset,
/// and the spool lag, which may be 0 (those are theta_i themselves).
[[nodiscard]] constexpr bool logarithmic(std::size_t i) noexcept { return i != kNullOffset && i != kSpoolLag; }

struct ValveFit {
  model::PlantParams plant;                         ///< the prior with the identified values
  /// The fit with every parameter free (the posterior's mode): the pressures' best prediction,
  /// also where single parameters cannot be told apart. The prior when no phase was fitted.
  model::PlantParams joint;
  std::array<double, kValveFitParams> std{};        ///< 1-sigma, in the parameter's unit
  std::array<bool, kValveFitParams> identified{};
  std::array<std::string, kValveFitParams> basis;   ///< why not identified
  int phases = 0;
  double rms_residual_pa = 0.0;
  int command_delay_samples = 0;   ///< the delay the fit found (or was given)
  /// The residual of the fit with every parameter free (the one the goodness is judged by) [Pa].
  double joint_rms_residual_pa = 0.0;
  /// The pressure sensors' noise as the fitted phases' readings show it [Pa].
  double noise_pa = 0.0;
  /// What the noise explains of a residual: the noise, but no less than what an exact model
  /// leaves of ideal readings (10 Pa) [Pa].
  double explained_pa = 0.0;
  /// The model fits: its residual is within twice what the noise explains. Else the parameters'
  /// sigmas carry the misfit (each phase's residuals counted as one sample).
  bool fits = true;
  /// Each fitted phase's residual at the joint fit, both chambers, rms [Pa], with its first sample
  /// and position, and whether it is beyond three times what the noise explains.
  struct PhaseResidual {
    std::size_t first = 0, last = 0;  ///< its first and last fitted samples
    double y_m = 0.0;
    double rms_pa = 0.0;
    bool misfit = false;
  };
  std::vector<PhaseResidual> phase_residuals;
};

/// Fits the conductances, the null offset and the dead volumes so that Eq. 19, integrated over each
/// phase from its first measured pressures with the recorded u, follows the measured pressures.
/// What the fit compares, for the tests: the residuals [Pa] (measured - model, chambers P and N at
/// each observed sample of the fitted phases) with the model at `at` and the phases' starts
/// corrected by z (two per phase, P and N, in the fit's units; missing ones 0), the command delay
/// options.command_delay_samples (at least 0); with `derivatives`, their derivatives as the fit takes
/// them: by each of the model's parameters (by_theta, row-major, rows x kValveFitParams, per unit of
/// the fit's theta_i: the parameter's logarithm, but the null offset [V] and the spool lag [s]; 0 for
/// a parameter the prior lacks) and each row's by its own start (by_start, when the starts are
/// fitted: start_of_row says which).
struct FitCheck {
  std::vector<double> residual_pa, by_theta, by_start;
  std::size_t starts = 0;
  std::vector<std::size_t> start_of_row;
};
[[nodiscard]] FitCheck check_fit_model(std::span<const Sample> samples, std::span<const StuckPhase> phases,
                                       const model::PlantParams& prior, const Options& options,
                                       const model::PlantParams& at, std::span<const double> z, bool derivatives);

[[nodiscard]] ValveFit fit_valves(std::span<const Sample> samples, std::span<const StuckPhase> phases,
                                  const model::PlantParams& prior, const Options& options);

}  // namespace pneu::identify::detail
