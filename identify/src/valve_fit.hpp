// The output-error fit of Eq. 19 over the stuck phases (internal to pneu_identify).
#pragma once

#include <array>
#include <span>
#include <string>
#include <vector>

#include "phases.hpp"
#include "pneu/model/params.hpp"

namespace pneu::identify::detail {

/// The fitted parameters, in this order.
enum ValveFitParam : std::size_t {
  kMaxConductance,
  kLeakIn,
  kLeakOut,
  kNullOffset,
  kDeadVolumeP,
  kDeadVolumeN,
  kValveFitParams
};

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
};

/// Fits the conductances, the null offset and the dead volumes so that Eq. 19, integrated over each
/// phase from its first measured pressures with the recorded u, follows the measured pressures.
[[nodiscard]] ValveFit fit_valves(std::span<const Sample> samples, std::span<const StuckPhase> phases,
                                  const model::PlantParams& prior, const Options& options);

}  // namespace pneu::identify::detail
