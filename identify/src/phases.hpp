// The trajectory cut into stuck phases (internal to pneu_identify).
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "pneu/identify/identify.hpp"

namespace pneu::identify::detail {

/// Readings this close are the same position (an ideal sensor's conversions differ in the last
/// bits) [m].
inline constexpr double kSamePosition_m = 1.0e-12;

/// A run of samples whose positions stay within the rest band of the first one.
struct StuckPhase {
  std::size_t first = 0;   ///< first sample of the phase
  std::size_t last = 0;    ///< last sample within the rest band
  double y_m = 0.0;        ///< the rest position (mean of the phase's readings) [m]
  /// The carriage left: the samples after `last` moved on beyond the band (not noise, not the
  /// end of the trajectory); `direction` is then +1 or -1.
  bool breakaway = false;
  int direction = 0;
  bool driven = true;      ///< every sample of the phase was driven as recorded
  /// The part of the phase where the carriage stood at its rest position, which the valve fit and
  /// the forces held use. With ideal sensors, the longest run of identical readings (a carriage
  /// creeping at nm/s reads still within the phase but changes in every reading). Within a rest
  /// band the phase may begin while the carriage still slides into the band and end with a slow
  /// breakaway's onset (or creep throughout): the part whose running median stays at the phase's.
  std::size_t still_first = 0;
  std::size_t still_last = 0;
};

/// The stuck phases of `samples` at least options.min_stuck_s long, away from the end stops of a
/// stroke of `half_stroke_m` either side of mid-stroke.
[[nodiscard]] std::vector<StuckPhase> stuck_phases(std::span<const Sample> samples, double half_stroke_m,
                                                   const Options& options);

}  // namespace pneu::identify::detail
