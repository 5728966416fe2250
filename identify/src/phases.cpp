#include "phases.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pneu::identify::detail {

namespace {

// How far beyond the rest band, and how soon, the position must go for the carriage to have left.
constexpr double kMotionBandFactor = 2.0;
constexpr double kMinMotion_m = 1.0e-6;
constexpr double kConfirmWithin_s = 0.2;
// The still readings the reference is the median of.
constexpr std::size_t kReferenceSamples = 15;

// The median position of samples [first, last].
double median_position(std::span<const Sample> s, std::size_t first, std::size_t last) {
  std::vector<double> y;
  y.reserve(last - first + 1);
  for (std::size_t j = first; j <= last; ++j) y.push_back(s[j].y_m);
  std::nth_element(y.begin(), y.begin() + static_cast<std::ptrdiff_t>(y.size() / 2), y.end());
  return y[y.size() / 2];
}

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
      p.still_first = i;
      p.still_last = last;
      if (o.rest_band_m > 0.0) {
        // The reference follows the readings, so a phase may begin while the carriage still slides
        // into the band and end with a slow breakaway's onset, or creep throughout: the still part
        // is the longest run of samples whose running median (of kReferenceSamples) lies within
        // half the band of the phase's median (noise stays within about one ADC step of it).
        const double rest = median_position(s, i, last);
        const std::size_t half = kReferenceSamples / 2;
        std::size_t run_first = i, best_first = i, best_last = i;
        bool in_run = false, any = false;
        for (std::size_t j = i; j <= last; ++j) {
          const std::size_t a = j >= i + half ? j - half : i, b = std::min(last, j + half);
          const bool still = std::abs(median_position(s, a, b) - rest) <= 0.5 * o.rest_band_m;
          if (still && !in_run) run_first = j;
          in_run = still;
          if (still && (!any || j - run_first > best_last - best_first)) {
            best_first = run_first;
            best_last = j;
            any = true;
          }
        }
        // Its ends: the first and the last reading within half the band (the readings of a
        // carriage still sliding in, or already leaving, lie further out).
        while (best_first < best_last && std::abs(s[best_first].y_m - rest) > 0.5 * o.rest_band_m) ++best_first;
        while (best_last > best_first && std::abs(s[best_last].y_m - rest) > 0.5 * o.rest_band_m) --best_last;
        p.still_first = best_first;
        p.still_last = best_last;
      } else {
        // An ideal sensor reads a stuck carriage bit for bit; a carriage creeping at nanometres per
        // second (sliding to rest, or past a stiction bound, near v = 0) reads still within the
        // phase (it does not leave by a micrometre) but changes in every reading: the still part is
        // the longest run of identical readings.
        std::size_t run_first = i, best_first = i, best_last = i;
        for (std::size_t j = i + 1; j <= last; ++j) {
          if (std::abs(s[j].y_m - s[j - 1].y_m) > kSamePosition_m) run_first = j;
          if (j - run_first > best_last - best_first) {
            best_first = run_first;
            best_last = j;
          }
        }
        p.still_first = best_first;
        p.still_last = best_last;
      }
      if (std::abs(p.y_m) <= half_stroke_m - o.end_stop_margin_m) phases.push_back(p);
    }
    i = last + 1;
  }
  return phases;
}

}  // namespace pneu::identify::detail
