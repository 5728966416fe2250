// Forecasts judged against what happened: the verdicts the summary prints, the sweep scores and
// the tests hold to the acceptance criteria. Pure functions of a stop's outcome.
#pragma once

#include "pneu/controller/predictor.hpp"
#include "pneu/controller/stop_outcome.hpp"

namespace pneu::controller {

/// How a forecast compares with what happened (stops ended by a set-point change are not judged).
struct Verdict {
  enum class Kind { kTruePositive, kTrueNegative, kFalsePositive, kFalseNegative, kNotJudged };
  Kind kind = Kind::kNotJudged;
  double error_s = 0.0;       ///< predicted minus actual restart time (true positives) [s]
  double error_percent = 0.0; ///< |error| in percent of the sticking duration
  bool direction_ok = true;
};

/// How far before the end of a run a forecast restart must lie to be judged: max(10 ms, 1 % of the
/// sticking time), the acceptance tolerance.
[[nodiscard]] double observation_tolerance_s(const StopOutcome& stop) noexcept;
/// Stops ended by a set-point change, stops whose forecast stopped holding before the carriage
/// left (forecast_void_at_s), and restart forecasts within observation_tolerance_s() of the end
/// of the run, are not judged.
[[nodiscard]] Verdict judge(const StopOutcome& stop, const Prediction& prediction, double t_end_s) noexcept;

/// The last forecast of `method` made again before half the stop's sticking time (as its
/// t_end_s stands), from its kept `reforecasts`; null when none.
[[nodiscard]] const Reforecast* halfway_reforecast(const StopOutcome& stop, PredictionMethod method) noexcept;

}  // namespace pneu::controller
