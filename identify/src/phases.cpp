#include "phases.hpp"

#include <algorithm>
#include <cmath>

namespace pneu::identify::detail {

namespace {

// How far beyond the rest band, and how soon, the position must go for the carriage to have left.
constexpr double kMotionBandFactor = 2.0;
constexpr double kMinMotion_m = 1.0e-6;
constexpr double kConfirmWithin_s = 0.2;
// The still readings the reference is the median of.
constexpr std::size_t kReferenceSamples = 15;

// Whether the position, from sample `k` on, goes beyond the motion band around `anchor` within
// kConfirmWithin_s without coming back into the rest band (noise at the band's edge comes back);
// the direction it went, or 0.
int confirmed_motion(std::span<const Sample> s, std::size_t k, double anchor_m, double band_m) {
  const double motion_m = std::max(kMotionBandFactor * band_m, kMinMotion_m);
  for (std::size_t j = k; j < s.size() && s[j].t_s - s[k].t_s <= kConfirmWithin_s; ++j) {
    const double d = std::abs(s[j].y_m - anchor_m);
    if (d > motion_m) return s[j].y_m > anchor_m ? +1 : -1;
    if (d <= band_m + kSamePosition_m) return 0;
  }
  return 0;
}

}  // namespace

std::vector<StuckPhase> stuck_phases(std::span<const Sample> s, double half_stroke_m, const Options& o) {
  std::vector<StuckPhase> phases;
  const std::size_t n = s.size();
  std::size_t i = 0;
  while (i < n) {
    // The reference is the median of the last still readings: noise and ADC steps around it stay
    // within the rest band, a carriage that was still sliding into the band when the phase began
    // does not bias it, and a breakaway runs away from it. With no band (ideal sensors: a stuck
    // carriage reads the same bits) it is the last still reading.
    const std::size_t window = o.rest_band_m > 0.0 ? kReferenceSamples : 1;
    std::size_t last = i;
    int direction = 0;
    for (std::size_t k = i + 1; k < n; ++k) {
      const std::size_t from = last + 1 >= window + i ? last + 1 - window : i;
      double recent[kReferenceSamples];
      std::size_t m = 0;
      for (std::size_t j = from; j <= last; ++j) recent[m++] = s[j].y_m;
      std::nth_element(recent, recent + m / 2, recent + m);
      const double reference = recent[m / 2];
      if (std::abs(s[k].y_m - reference) <= o.rest_band_m + kSamePosition_m) {
        last = k;
        continue;
      }
      // Out of the band: the carriage left, or a reading's noise (then it stays a still sample).
      direction = confirmed_motion(s, k, reference, o.rest_band_m);
      if (direction != 0) break;
      last = k;
    }
    if (s[last].t_s - s[i].t_s >= o.min_stuck_s) {
      StuckPhase p;
      p.first = i;
      p.last = last;
      double sum = 0.0;
      bool driven = true;
      for (std::size_t j = i; j <= last; ++j) {
        sum += s[j].y_m;
        driven = driven && s[j].driven;
      }
      p.y_m = sum / static_cast<double>(last - i + 1);
      p.driven = driven;
      p.breakaway = direction != 0;
      p.direction = direction;
      if (std::abs(p.y_m) <= half_stroke_m - o.end_stop_margin_m) phases.push_back(p);
    }
    i = last + 1;
  }
  return phases;
}

}  // namespace pneu::identify::detail
