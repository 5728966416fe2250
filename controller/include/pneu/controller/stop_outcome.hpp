// The runtime's account of each sticking phase: what was forecast at its start, what was forecast
// again while it lasted, and what happened.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "pneu/controller/predictor.hpp"

namespace pneu::controller {

/// A forecast made again while the carriage is still stuck, from the pressures of a later tick:
/// the live predictor. Not judged; the one made at the stop is.
struct Reforecast {
  std::uint32_t update = 0;       ///< 1, 2, ... within its stop
  double t_s = 0.0;               ///< the tick it was made from [s]
  double force_n = 0.0;           ///< F measured at that tick [N]
  /// u* it assumed: the stop's, which the loop holds while the carriage is at rest [V]
  double u_star_v = 0.0;
  /// F the same method's forecast made at the stop expected then (NaN when the runtime does not
  /// follow the forecasts, Runtime::set_follow_forecasts, and for the relaxation method, which
  /// makes none at the stop) [N]
  double stop_forecast_force_n = std::numeric_limits<double>::quiet_NaN();
  Prediction prediction;
};

/// One sticking phase, what was forecast at its start and what happened.
struct StopOutcome {
  std::uint64_t index = 0;
  double t_stop_s = 0.0;           ///< the stop event's time
  double y_stop_m = 0.0;
  double force_n = 0.0;            ///< F at confirmation
  double y_d_m = 0.0;
  StopSnapshot snapshot;
  std::optional<Prediction> linearized;
  std::optional<Prediction> nonlinear;
  bool ended = false;              ///< the carriage left rest before the run ended
  bool restarted = false;          ///< ... and the set point had not changed (a true restart)
  double t_end_s = 0.0;            ///< the start's time, or the run's end
  int direction = 0;               ///< of the start
  /// When the forecast stopped holding while the carriage was still stuck: the set point moved,
  /// or the loop was disarmed or faulted (u* no longer held); NaN if it held to the end [s].
  double forecast_void_at_s = std::numeric_limits<double>::quiet_NaN();
  /// From the snapshot until the start is seen (a breakaway is seen once the carriage has moved
  /// the detector's motion band, up to tens of ms later), while the forecast held (armed, same set
  /// point): the largest |F measured - F forecast| of each method's forecast made at the stop;
  /// NaN when none was followed [N].
  double largest_gap_linearized_n = std::numeric_limits<double>::quiet_NaN();
  double largest_gap_nonlinear_n = std::numeric_limits<double>::quiet_NaN();
  std::uint32_t updates = 0;            ///< times the forecasts were made again while stuck
  /// Each method's last forecast made again before half the sticking time, settled when the stop
  /// ends (or the run does).
  std::optional<Reforecast> halfway_linearized, halfway_nonlinear, halfway_relaxation;
  /// The forecasts made again, in time order, the methods interleaved: while the stop is open,
  /// and after it only when the runtime keeps them (Runtime::set_keep_reforecasts). At most
  /// kMaxReforecastsKept: a longer sticking phase keeps every 2nd, 4th, ... update.
  std::vector<Reforecast> reforecasts;
  static constexpr std::size_t kMaxReforecastsKept = 512;
  /// Under the in-position hold (predict_held, when the runtime has the hold's law): the forecasts
  /// made while it held this stop (at its start, then every update period), how many of them a
  /// restart, and the first of the last hold (reaching: when its ramp breaks the carriage away).
  std::uint32_t held_forecasts = 0;
  std::uint32_t held_restart_forecasts = 0;
  std::optional<Reforecast> held_first;

  [[nodiscard]] double sticking_s() const noexcept { return t_end_s - t_stop_s; }
};

}  // namespace pneu::controller
