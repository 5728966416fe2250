// Detects when the carriage stops and when it leaves rest, from the sampled position alone.
#pragma once

#include "pneu/config/config.hpp"

#include <cstdint>

namespace pneu::controller {

using config::StopDetectorParams;


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
    stopped_ = true;
    anchor_t_s_ = t_s;
    anchor_y_m_ = y_m;
    last_rest_t_s_ = t_s;
  }

  [[nodiscard]] StopDetectorEvent update(double t_s, double y_m) noexcept {
    const double dy = y_m - anchor_y_m_;
    const double distance = dy < 0.0 ? -dy : dy;
    if (stopped_) {
      if (distance <= p_.rest_band_m) last_rest_t_s_ = t_s;
      if (distance > p_.motion_band_m) {
        stopped_ = false;
        event_t_s_ = last_rest_t_s_ + 0.5 * period_s_;
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
      return StopDetectorEvent::kNone;
    }
    if (t_s - anchor_t_s_ >= p_.hold_s - 1e-9 * period_s_) {
      stopped_ = true;
      last_rest_t_s_ = t_s;
      event_t_s_ = anchor_t_s_;
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
  StopDetectorParams p_;
  double period_s_;
  bool stopped_ = true;
  double anchor_t_s_ = 0.0, anchor_y_m_ = 0.0, last_rest_t_s_ = 0.0;
  double event_t_s_ = 0.0, event_y_m_ = 0.0;
};

}  // namespace pneu::controller
