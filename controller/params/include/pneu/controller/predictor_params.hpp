// The parameters of the restart predictors (controller.predictor): which run, on which valve
// characteristic, how far ahead, how often made again, learnt online or not.
#pragma once

#include <cstdint>
#include <string>
#include "pneu/config/describe.hpp"

namespace pneu::controller {

/// Where the linearized restart predictor takes each chamber's flow slope C_p of Eq. 23 (its time
/// constant tau = V(y*) / (k r T C_p)), controller.predictor.linearized_slope. Every choice relaxes
/// each pressure exponentially from its stop value to p_null(+-u*) (Eq. 24) and keeps Eq.
/// 16/17/25; only tau differs.
enum class LinearizedSlope : std::uint8_t {
  kStopTangent,         ///< "stop": -dq/dp at the stop pressure, the paper's Eq. 23 (default)
  kChord,               ///< "chord": q(p_stop) / (p_null - p_stop), the secant from the stop
                        ///< pressure to the null-flow pressure: the forecast starts at the model's
                        ///< own rate dp/dt and ends where the model does
  kEquilibriumTangent,  ///< "equilibrium": -dq/dp at the null-flow pressure p_null(+-u*)
};


/// Which predictors run at each stop, and with which valve characteristic.
struct PredictorConfig {
  bool linearized = true;           ///< controller.predictor.methods holds "linearized"
  bool nonlinear = true;            ///< controller.predictor.methods holds "nonlinear"
  /// controller.predictor.methods holds "relaxation": while stuck, forecasts also from each
  /// chamber's relaxation fitted to the phase's own pressures (no valve model; needs
  /// update_period_s > 0)
  bool relaxation = false;
  std::string valve_table;          ///< table from `pneu-plant characterize-valve`; empty: the model
  double horizon_s = 600.0;         ///< the nonlinear method stops looking this long after a stop [s]
  LinearizedSlope linearized_slope = LinearizedSlope::kStopTangent;  ///< optional key
  /// While stuck, the forecasts are made again from the pressures of the moment this often
  /// (0: only at the stop) [s].
  double update_period_s = 0.1;
  /// Online identification: at each stop after a breakaway, the bench identified again from the
  /// last minute of the run's own signals, and the forecasts made on the running estimate
  /// (stiction, the valves' conductances and null offset, the dead volumes).
  bool learn_online = false;
  /// controller.predictor.model_fit (optional section, written by pneud --identify): how well
  /// plant: fitted the bench's stuck-phase pressures when it was identified. A residual beyond
  /// twice what the sensors' noise explains marks every forecast made on it uncertain.
  bool has_model_fit = false;
  struct ModelFit {
    double pressure_residual_pa = 0.0;   ///< the fit's residual, both chambers, rms [Pa]
    double pressure_explained_pa = 10.0; ///< what the sensors' noise explains of it [Pa]
    /// The residual is within twice what the noise explains.
    [[nodiscard]] bool fits() const noexcept { return pressure_residual_pa <= 2.0 * pressure_explained_pa; }
  } model_fit;
};

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::LinearizedSlope;
using controller::PredictorConfig;

inline constexpr Choice<LinearizedSlope> kLinearizedSlopes[] = {{"stop", LinearizedSlope::kStopTangent},
                                                               {"chord", LinearizedSlope::kChord},
                                                               {"equilibrium", LinearizedSlope::kEquilibriumTangent}};
inline constexpr Flag<PredictorConfig> kPredictorMethods[] = {{"linearized", &PredictorConfig::linearized},
                                                              {"nonlinear", &PredictorConfig::nonlinear},
                                                              {"relaxation", &PredictorConfig::relaxation}};

void describe(auto& a, Like<PredictorConfig::ModelFit> auto& f) {
  a.field(PNEU_NVP(f, pressure_residual_pa), Range::non_negative(),
          "the identification's pressure residual, both chambers, rms [Pa]");
  a.field(PNEU_NVP(f, pressure_explained_pa), Range::positive(), "what the sensors' noise explains of it [Pa]");
}

void describe(auto& a, Like<PredictorConfig> auto& p) {
  a.flags("methods", p, any_of(kPredictorMethods, "method"), "the restart predictors run at each stop");
  a.field(optional(PNEU_NVP(p, valve_table)), "valve table from pneu-plant characterize-valve; empty: the model");
  a.field(PNEU_NVP(p, horizon_s), Range::positive(), "the nonlinear method gives up after this long [s]");
  a.field(optional(PNEU_NVP(p, linearized_slope)), one_of(kLinearizedSlopes),
          "the linearized method's flow slope (Eq. 23)");
  a.field(optional(PNEU_NVP(p, update_period_s)), Range::non_negative(),
          "while stuck, forecast again this often [s]; 0 = only at the stop");
  a.check("update_period_s", !p.relaxation || p.update_period_s > 0.0,
          "must be > 0 with the relaxation method, which forecasts only while stuck");
  a.field(optional(PNEU_NVP(p, learn_online)),
          "identify the bench again at each stop after a breakaway and forecast on what was identified");
  a.optional_section(optional(PNEU_NVP(p, model_fit)), p.has_model_fit);
}

}  // namespace pneu::config::schema

namespace pneu::controller {

/// The key's value: "stop", "chord" or "equilibrium".
[[nodiscard]] inline const char* to_string(LinearizedSlope s) noexcept {
  return config::schema::one_of(config::schema::kLinearizedSlopes).name_of(s);
}

}  // namespace pneu::controller
