// Velocity and acceleration from the sampled position (they are not measured, docs/model.md section 1).
#pragma once

#include "pneu/controller/differentiator_params.hpp"

namespace pneu::controller {



/// Backward difference of the position, low-passed by a first-order discrete filter, then the same
/// again on the filtered velocity for the acceleration:
///   v_raw = (y_k - y_{k-1}) / T,  v_hat += alpha (v_raw - v_hat)
///   a_raw = (v_hat_k - v_hat_{k-1}) / T,  a_hat += alpha (a_raw - a_hat)
/// On a ramp the velocity settles exactly; its group delay at low frequency is
/// T/2 + T (1 - alpha) / alpha (2.83 ms at alpha = 0.3, T = 1 ms) per stage.
/// Real-time safe; the first sample initialises the state at rest.
class Differentiator {
 public:
  Differentiator(const DifferentiatorParams& params, double period_s) noexcept
      : alpha_(params.smoothing), period_s_(period_s) {}

  void reset(double y_m) noexcept {
    y_prev_ = y_m;
    v_hat_ = v_prev_ = a_hat_ = 0.0;
    primed_ = true;
  }
  void update(double y_m) noexcept { update(y_m, period_s_); }
  /// One new sample `dt_s` after the previous one (a backend that delivers samples at its own
  /// pace: the differences use the samples' own spacing).
  void update(double y_m, double dt_s) noexcept {
    if (!primed_ || !(dt_s > 0.0)) {
      if (!primed_) reset(y_m);
      return;
    }
    const double v_raw = (y_m - y_prev_) / dt_s;
    y_prev_ = y_m;
    v_prev_ = v_hat_;
    v_hat_ += alpha_ * (v_raw - v_hat_);
    const double a_raw = (v_hat_ - v_prev_) / dt_s;
    a_hat_ += alpha_ * (a_raw - a_hat_);
  }
  [[nodiscard]] double velocity_m_per_s() const noexcept { return v_hat_; }
  [[nodiscard]] double acceleration_m_per_s2() const noexcept { return a_hat_; }

 private:
  double alpha_;
  double period_s_;
  double y_prev_ = 0.0, v_hat_ = 0.0, v_prev_ = 0.0, a_hat_ = 0.0;
  bool primed_ = false;
};

}  // namespace pneu::controller
