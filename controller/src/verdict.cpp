#include "pneu/controller/verdict.hpp"

#include <algorithm>
#include <cmath>

namespace pneu::controller {

double observation_tolerance_s(const StopOutcome& s) noexcept {
  return std::max(0.010, 0.01 * s.sticking_s());
}

Verdict judge(const StopOutcome& s, const Prediction& p, double t_end_s) noexcept {
  Verdict v;
  if (s.ended && !s.restarted) return v;  // the set point moved: the forecast no longer applies
  // The forecast stopped holding while still stuck (u* changed) and the carriage had not left yet.
  if (!std::isnan(s.forecast_void_at_s) && !(s.restarted && s.t_end_s <= s.forecast_void_at_s)) return v;
  const bool predicted = p.will_restart && p.t_restart_s <= t_end_s;
  if (s.restarted) {
    v.kind = predicted ? Verdict::Kind::kTruePositive : Verdict::Kind::kFalseNegative;
    if (predicted) {
      v.error_s = p.t_restart_s - s.t_end_s;
      v.error_percent = 100.0 * std::abs(v.error_s) / std::max(s.sticking_s(), 1e-9);
      v.direction_ok = p.direction == s.direction;
    }
  } else if (p.will_restart && p.t_restart_s > t_end_s - observation_tolerance_s(s)) {
    // A restart forecast after the end of the run, or this close to it, cannot be confirmed or
    // refuted by the signals (a start is seen only once the carriage has moved): not judged.
  } else {
    v.kind = predicted ? Verdict::Kind::kFalsePositive : Verdict::Kind::kTrueNegative;
  }
  return v;
}

const Reforecast* halfway_reforecast(const StopOutcome& s, PredictionMethod method) noexcept {
  const Reforecast* last = nullptr;
  for (const Reforecast& f : s.reforecasts) {
    if (f.t_s > s.t_stop_s + 0.5 * s.sticking_s()) break;  // in time order
    if (f.prediction.method == method) last = &f;
  }
  return last;
}

}  // namespace pneu::controller
