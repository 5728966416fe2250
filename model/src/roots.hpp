// The model's root finder, shared by its sources (not installed).
#pragma once

#include <cmath>

namespace pneu::model {

// Finds the root of a decreasing function on [lo, hi] by bisection refined with regula falsi
// (Illinois). Returns the clamped end when there is no sign change.
template <typename F>
double decreasing_root(F&& f, double lo, double hi, double x_tolerance) noexcept {
  double f_lo = f(lo);
  double f_hi = f(hi);
  if (f_lo <= 0.0) return lo;
  if (f_hi >= 0.0) return hi;
  int side = 0;
  for (int i = 0; i < 200 && hi - lo > x_tolerance; ++i) {
    double x = (lo * f_hi - hi * f_lo) / (f_hi - f_lo);
    // Guard against regula falsi stagnation: fall back to bisection near the ends.
    if (!(x > lo && x < hi)) x = 0.5 * (lo + hi);
    const double fx = f(x);
    if (fx == 0.0) return x;
    if (fx > 0.0) {
      lo = x;
      f_lo = fx;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = x;
      f_hi = fx;
      if (side == +1) f_lo *= 0.5;
      side = +1;
    }
  }
  return 0.5 * (lo + hi);
}

}  // namespace pneu::model
