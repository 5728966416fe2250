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
