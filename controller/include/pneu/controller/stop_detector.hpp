// Detects when the carriage stops and when it leaves rest, from the sampled position alone.
#pragma once

#include "pneu/controller/stop_detector_params.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

namespace pneu::controller {



/// What one update found.
enum class StopDetectorEvent : std::uint8_t { kNone, kStop, kStart };

/// Sample by sample: moving -> stopped when the position stays within `rest_band_m` of a first
/// still sample for `hold_s`; stopped -> moving when it leaves the stop position by more than
/// `motion_band_m`. Event times are backdated to the signals: a stop to its first still sample, a
/// start to midway between the last sample still at rest and the next one. Real-time safe.
class StopDetector {
 public:
  StopDetector(const StopDetectorParams& params, double period_s) noexcept
      : p_(params), period_s_(period_s) {}

  /// Starts at rest at `y_m` (no event).
  void reset_at_rest(double t_s, double y_m) noexcept {
    head_ = 0;  // forget any earlier run's samples
    stopped_ = true;
    anchor_t_s_ = t_s;
    anchor_y_m_ = y_m;
    last_rest_t_s_ = t_s;
    still_sum_m_ = 0.0;
    still_n_ = 1;
  }

  [[nodiscard]] StopDetectorEvent update(double t_s, double y_m) noexcept {
    history_[head_ % kHistory] = {t_s, y_m};
    ++head_;
    const double dy = y_m - anchor_y_m_;
    const double distance = dy < 0.0 ? -dy : dy;
    if (stopped_) {
      if (distance <= p_.rest_band_m) last_rest_t_s_ = t_s;
      if (distance > p_.motion_band_m) {
        stopped_ = false;
        event_t_s_ = departure_time_s(dy > 0.0 ? 1.0 : -1.0);
        event_y_m_ = anchor_y_m_;
        anchor_t_s_ = t_s;
        anchor_y_m_ = y_m;
        return StopDetectorEvent::kStart;
      }
      return StopDetectorEvent::kNone;
    }
    if (distance > p_.rest_band_m) {  // still moving: this sample becomes the candidate
      anchor_t_s_ = t_s;
      anchor_y_m_ = y_m;
      still_sum_m_ = 0.0;
      still_n_ = 1;
      return StopDetectorEvent::kNone;
    }
    still_sum_m_ += dy;  // deviations from the anchor: identical samples average to it exactly
    ++still_n_;
    if (t_s - anchor_t_s_ >= p_.hold_s - 1e-9 * period_s_) {
      stopped_ = true;
      last_rest_t_s_ = t_s;
      event_t_s_ = anchor_t_s_;
      // The rest position: the mean of the still samples, so that noise and ADC steps average out
      // of y* (and of u* = K_y (y_d - y*) + u_0 the predictor uses); exact for ideal sensors.
      anchor_y_m_ += still_sum_m_ / static_cast<double>(still_n_);
      event_y_m_ = anchor_y_m_;
      return StopDetectorEvent::kStop;
    }
    return StopDetectorEvent::kNone;
  }

  [[nodiscard]] bool stopped() const noexcept { return stopped_; }
  /// Time of the last event (backdated as described above) [s].
  [[nodiscard]] double event_time_s() const noexcept { return event_t_s_; }
  /// Position at the last event: the stop position [m].
  [[nodiscard]] double event_position_m() const noexcept { return event_y_m_; }
  /// The position the carriage rests at while stopped [m].
  [[nodiscard]] double rest_position_m() const noexcept { return anchor_y_m_; }

 private:
  // When the carriage left rest. With ideal sensors (rest band 0) the last sample still at rest
  // dates it to within a tick: midway to the next. With noise the displacement must first clear
  // the rest band, which a slow breakaway takes tens of milliseconds to do: the start of a
  // breakaway under a force ramping through stiction goes as d = c (t - t0)^3, so the cube root
  // of the displacements since the last sample at rest is a straight line in t, whose zero is t0.
  [[nodiscard]] double departure_time_s(double direction) const noexcept {
    const double fallback = last_rest_t_s_ + 0.5 * period_s_;
    if (p_.rest_band_m <= 0.0) return fallback;
    double n = 0.0, st = 0.0, sx = 0.0, stt = 0.0, stx = 0.0;
    for (std::size_t k = 1; k <= kHistory && k <= head_; ++k) {
      const Sample& h = history_[(head_ - k) % kHistory];
      if (h.t_s <= last_rest_t_s_) break;
      const double d = direction * (h.y_m - anchor_y_m_);
      if (d <= 0.0) break;
      const double x = std::cbrt(d);
      const double t = h.t_s - last_rest_t_s_;  // centred for conditioning
      n += 1.0, st += t, sx += x, stt += t * t, stx += t * x;
    }
    const double det = n * stt - st * st;
    if (n < 2.0 || det <= 0.0) return fallback;
    const double slope = (n * stx - st * sx) / det;
    if (slope <= 0.0) return fallback;
    const double t0 = last_rest_t_s_ + ((sx - slope * st) / n) / -slope;
    // It left rest after the stop, and no later than the first sample outside the rest band.
    return std::clamp(t0, std::max(anchor_t_s_, last_rest_t_s_ - 0.2), last_rest_t_s_ + period_s_);
  }

  struct Sample {
    double t_s, y_m;
  };
  static constexpr std::size_t kHistory = 256;
  std::array<Sample, kHistory> history_{};
  std::size_t head_ = 0;
  StopDetectorParams p_;
  double period_s_;
  bool stopped_ = true;
  double anchor_t_s_ = 0.0, anchor_y_m_ = 0.0, last_rest_t_s_ = 0.0;
  double event_t_s_ = 0.0, event_y_m_ = 0.0;
  double still_sum_m_ = 0.0;  // sum of the still samples' deviations from the anchor, while moving
  long still_n_ = 0;
};

}  // namespace pneu::controller
