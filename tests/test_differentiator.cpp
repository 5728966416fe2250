// Specification of the differentiator (docs/model.md sections 1 and 7): velocity and acceleration of the
// carriage from the sampled position, by a backward difference smoothed by a first-order low-pass,
// twice. Expected values are the analytic answers for ramps, parabolas and sines, written out in
// this file from the discrete transfer function
//   H(z) = alpha (1 - z^-1) / T / (1 - (1 - alpha) z^-1),
// not taken from the code under test.
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/differentiator.hpp"

namespace pneu::controller {
namespace {

constexpr double kPeriodS = 1.0e-3;  // the bench's sample period (docs/model.md section 7)
constexpr double kPi = std::numbers::pi;
// The paper bench's smoothing, and alpha = 1: the bare backward difference.
constexpr double kSmoothings[] = {0.3, 1.0};

Differentiator make_differentiator(double alpha) {
  config::DifferentiatorParams params;
  params.smoothing = alpha;
  return Differentiator(params, kPeriodS);
}

struct Outputs {
  std::vector<double> t_s, v_m_per_s, a_m_per_s2;
};

// Feeds y(t_k), t_k = k T for k = 0 .. n-1 (the first sample primes) and records both outputs.
Outputs run(double alpha, const std::function<double(double)>& y_of_t, int n) {
  Differentiator d = make_differentiator(alpha);
  Outputs out;
  for (int k = 0; k < n; ++k) {
    const double t = k * kPeriodS;
    d.update(y_of_t(t));
    out.t_s.push_back(t);
    out.v_m_per_s.push_back(d.velocity_m_per_s());
    out.a_m_per_s2.push_back(d.acceleration_m_per_s2());
  }
  return out;
}

// H(e^{j w T}), the velocity stage's frequency response.
std::complex<double> velocity_stage(double alpha, double omega_rad_per_s) {
  const std::complex<double> z_inv =
      std::exp(std::complex<double>(0.0, -omega_rad_per_s * kPeriodS));
  return alpha * (1.0 - z_inv) / kPeriodS / (1.0 - (1.0 - alpha) * z_inv);
}

double wrap_phase(double rad) { return std::remainder(rad, 2.0 * kPi); }

// Amplitude and phase of x_k ~ P sin(w t_k) + Q cos(w t_k) = amp sin(w t_k + phase), by linear
// least squares over samples [first, last) (2x2 normal equations; exact for a pure sinusoid).
struct Harmonic {
  double amplitude, phase_rad;
};
Harmonic fit_harmonic(const std::vector<double>& t, const std::vector<double>& x, double omega,
                      std::size_t first, std::size_t last) {
  double ss = 0, sc = 0, cc = 0, xs = 0, xc = 0;
  for (std::size_t k = first; k < last; ++k) {
    const double s = std::sin(omega * t[k]), c = std::cos(omega * t[k]);
    ss += s * s;
    sc += s * c;
    cc += c * c;
    xs += x[k] * s;
    xc += x[k] * c;
  }
  const double det = ss * cc - sc * sc;
  const double p = (xs * cc - xc * sc) / det;
  const double q = (xc * ss - xs * sc) / det;
  return {std::hypot(p, q), std::atan2(q, p)};
}

// Gain and phase of v_hat relative to the true derivative A w cos(w t) of y = A sin(w t), measured
// on a simulated run: 500 samples of transient dropped (0.7^500 ~ 1e-78), then about 1 s fitted.
Harmonic measured_velocity_response(double alpha, double f_hz) {
  constexpr double kAmplitudeM = 0.01;
  const double omega = 2.0 * kPi * f_hz;
  constexpr int kTransient = 500;
  // Whole periods when 1/(f T) is an integer (then sin and cos are orthogonal on the grid).
  const int window = static_cast<int>(std::round(std::ceil(f_hz) / (f_hz * kPeriodS)));
  const Outputs out = run(
      alpha, [&](double t) { return kAmplitudeM * std::sin(omega * t); }, kTransient + window);
  const Harmonic h = fit_harmonic(out.t_s, out.v_m_per_s, omega, kTransient, out.t_s.size());
  return {h.amplitude / (kAmplitudeM * omega), wrap_phase(h.phase_rad - kPi / 2.0)};
}

// The frequency in [lo, hi] where a decreasing gain crosses 1/sqrt(2) (-3 dB), by bisection.
double minus_3db_frequency_hz(const std::function<double(double)>& gain_of_f, double lo,
                              double hi) {
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (gain_of_f(mid) > 1.0 / std::sqrt(2.0) ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// --- Start-up ----------------------------------------------------------------------------------

TEST(Differentiator, FirstUpdateOnlyPrimesTheStateAtRest) {
  for (double alpha : kSmoothings) {
    SCOPED_TRACE(alpha);
    Differentiator d = make_differentiator(alpha);
    d.update(0.1717);  // far from the zero the state was built with: no jump may come of it
    EXPECT_EQ(d.velocity_m_per_s(), 0.0);
    EXPECT_EQ(d.acceleration_m_per_s2(), 0.0);
    d.update(0.1717);
    EXPECT_EQ(d.velocity_m_per_s(), 0.0);
    EXPECT_EQ(d.acceleration_m_per_s2(), 0.0);
  }
}

TEST(Differentiator, ResetForgetsThePastMotion) {
  Differentiator d = make_differentiator(0.3);
  for (int k = 0; k < 50; ++k) d.update(0.5 * k * kPeriodS);
  ASSERT_GT(d.velocity_m_per_s(), 0.4);  // the ramp was being followed
  d.reset(-0.1);
  EXPECT_EQ(d.velocity_m_per_s(), 0.0);
  EXPECT_EQ(d.acceleration_m_per_s2(), 0.0);
  d.update(-0.1);  // the reset position is the new previous sample
  EXPECT_EQ(d.velocity_m_per_s(), 0.0);
  EXPECT_EQ(d.acceleration_m_per_s2(), 0.0);
}

// --- Ramp: y = s t -------------------------------------------------------------------------------

TEST(Differentiator, VelocityApproachesARampSlopeGeometrically) {
  constexpr double kSlope = 0.25;
  for (double alpha : kSmoothings) {
    SCOPED_TRACE(alpha);
    const Outputs out = run(
        alpha, [](double t) { return kSlope * t; }, 40);
    // Every backward difference after priming is s, so after n of them v_hat = s (1 - (1-alpha)^n).
    for (int n = 1; n < 40; ++n) {
      const double expected = kSlope * (1.0 - std::pow(1.0 - alpha, n));
      // Position rounding (1 ulp of y <= 0.01 m, ~2e-18 m) over T: ~1e-14 m/s.
      EXPECT_NEAR(out.v_m_per_s[n], expected, 1e-12) << "n = " << n;
    }
  }
}

TEST(Differentiator, SettlesToTheExactSlopeOfARamp) {
  constexpr double kSlope = 0.25;
  for (double alpha : kSmoothings) {
    SCOPED_TRACE(alpha);
    const Outputs out = run(
        alpha, [](double t) { return 0.05 + kSlope * t; }, 1000);
    // After 200 samples the transient (1-alpha)^n is below 1e-30: only rounding is left. One ulp
    // of y (<= 0.3 m: 5.6e-17 m) over T = 1 ms is 5.6e-14 m/s; over T again 5.6e-11 m/s^2.
    for (std::size_t k = 200; k < out.t_s.size(); ++k) {
      EXPECT_NEAR(out.v_m_per_s[k], kSlope, 1e-12) << "k = " << k;
      EXPECT_NEAR(out.a_m_per_s2[k], 0.0, 1e-9) << "k = " << k;
    }
  }
}

// --- Parabola: y = c t^2 / 2 ---------------------------------------------------------------------

TEST(Differentiator, ParabolaGivesItsCurvatureAndTheDocumentedVelocityDelay) {
  constexpr double kCurvature = 2.0;  // c [m/s^2]
  for (double alpha : kSmoothings) {
    SCOPED_TRACE(alpha);
    const Outputs out = run(
        alpha, [](double t) { return 0.5 * kCurvature * t * t; }, 1000);
    // The backward difference of c t^2/2 is c (t - T/2); a first-order low-pass x += alpha (r - x)
    // lags a ramp of r by T (1 - alpha) / alpha in steady state. Header: 2.83 ms at alpha = 0.3.
    const double delay_s = kPeriodS / 2.0 + kPeriodS * (1.0 - alpha) / alpha;
    if (alpha == 0.3) {
      EXPECT_NEAR(delay_s, 2.83e-3, 0.005e-3);
    }
    for (std::size_t k = 300; k < out.t_s.size(); ++k) {
      const double t = out.t_s[k];
      // Transient (k (1-alpha)^k < 1e-43) gone; y <= 1 m so one ulp (2.2e-16 m) over T is
      // 2.2e-13 m/s and over T^2 2.2e-10 m/s^2: allow ~50 ulps.
      EXPECT_NEAR(out.v_m_per_s[k], kCurvature * (t - delay_s), 1e-11) << "k = " << k;
      EXPECT_NEAR(out.a_m_per_s2[k], kCurvature, 1e-8) << "k = " << k;
    }
  }
}

// --- Sines: the discrete frequency response ------------------------------------------------------

TEST(Differentiator, VelocityOfASineFollowsTheDiscreteTransferFunction) {
  for (double alpha : kSmoothings) {
    for (double f_hz : {1.0, 10.0, 50.0, 100.0}) {
      SCOPED_TRACE(testing::Message() << "alpha " << alpha << ", f " << f_hz << " Hz");
      const double omega = 2.0 * kPi * f_hz;
      const std::complex<double> h = velocity_stage(alpha, omega);
      const double expected_gain = std::abs(h) / omega;  // relative to the true derivative j w
      const double expected_phase = wrap_phase(std::arg(h) - kPi / 2.0);
      const Harmonic measured = measured_velocity_response(alpha, f_hz);
      // The fit of a pure steady-state sinusoid is exact; rounding of y (~1e-18 m) over T against
      // an amplitude A w >= 0.06 m/s leaves ~1e-13. 1e-9 keeps a margin and still catches any
      // change of the filter (moving alpha by 1e-6 changes the 10 Hz gain by ~1e-7).
      EXPECT_NEAR(measured.amplitude, expected_gain, 1e-9);
      EXPECT_NEAR(measured.phase_rad, expected_phase, 1e-9);
    }
  }
}

TEST(Differentiator, SlowSineIsDelayedByTheDocumentedGroupDelay) {
  // At 1 Hz (w T = 6e-3) the phase is -w (T/2 + T (1-alpha)/alpha) up to O((w T)^3) terms, which
  // are 1e-4 of the phase: 1e-3 relative is a fair check of the header's 2.83 ms.
  const double omega = 2.0 * kPi * 1.0;
  for (double alpha : kSmoothings) {
    SCOPED_TRACE(alpha);
    const double delay_s = kPeriodS / 2.0 + kPeriodS * (1.0 - alpha) / alpha;
    const Harmonic measured = measured_velocity_response(alpha, 1.0);
    EXPECT_NEAR(-measured.phase_rad / omega, delay_s, 1e-3 * delay_s);
    EXPECT_NEAR(measured.amplitude, 1.0, 2e-4);  // |H|/w = 1 - O((w T / alpha)^2) = 1 - 1.6e-4
  }
}

TEST(Differentiator, AccelerationOfASineFollowsTheCascadedTransferFunction) {
  constexpr double kAmplitudeM = 0.01;
  for (double alpha : kSmoothings) {
    for (double f_hz : {1.0, 10.0}) {
      SCOPED_TRACE(testing::Message() << "alpha " << alpha << ", f " << f_hz << " Hz");
      const double omega = 2.0 * kPi * f_hz;
      const int window = static_cast<int>(std::round(1.0 / kPeriodS));  // 1 s: whole periods
      const Outputs out = run(
          alpha, [&](double t) { return kAmplitudeM * std::sin(omega * t); }, 500 + window);
      const Harmonic measured = fit_harmonic(out.t_s, out.a_m_per_s2, omega, 500, out.t_s.size());
      // a_hat = H(z)^2 y; the true second derivative is (j w)^2 y = -w^2 y. The fit measures the
      // phase of H^2 itself, which is that of the ratio plus pi.
      const std::complex<double> h = velocity_stage(alpha, omega);
      const std::complex<double> ratio = h * h / -(omega * omega);
      // Amplitude A w^2 >= 0.39 m/s^2; rounding of y over T^2 ~1e-12 m/s^2.
      EXPECT_NEAR(measured.amplitude / (kAmplitudeM * omega * omega), std::abs(ratio), 1e-8);
      EXPECT_NEAR(wrap_phase(measured.phase_rad - kPi), wrap_phase(std::arg(ratio)), 1e-8);
    }
  }
}

// --- Bandwidth (the header's "57 Hz at alpha = 0.3, T = 1 ms") -----------------------------------

TEST(Differentiator, SmoothingLowPassHasTheDocumentedMinus3dBBandwidth) {
  // The claim is about the low-pass x += alpha (raw - x) alone: measure v_hat against the backward
  // difference it smooths, whose amplitude for y = A sin(w t) is A 2 sin(w T / 2) / T.
  constexpr double kAlpha = 0.3;
  const auto low_pass_gain = [](double f_hz) {
    const double omega = 2.0 * kPi * f_hz;
    const double backward_difference_gain =
        2.0 * std::sin(omega * kPeriodS / 2.0) / kPeriodS / omega;
    return measured_velocity_response(kAlpha, f_hz).amplitude / backward_difference_gain;
  };
  const double f_3db = minus_3db_frequency_hz(low_pass_gain, 20.0, 100.0);
  // |alpha / (1 - (1-alpha) e^{-j theta})|^2 = 1/2  <=>  cos theta = 1 - alpha^2 / (2 (1-alpha)).
  const double documented_formula_hz =
      std::acos(1.0 - kAlpha * kAlpha / (2.0 * (1.0 - kAlpha))) / (2.0 * kPi * kPeriodS);
  // The simulation is exact up to rounding and the bisection resolves 80 Hz / 2^60: 1e-6 Hz.
  EXPECT_NEAR(f_3db, documented_formula_hz, 1e-6);
  EXPECT_NEAR(f_3db, 57.4, 0.05);  // the header rounds it to "57 Hz"
}

TEST(Differentiator, VelocityIsThreeDecibelsBelowTheTrueDerivativeNear57Hz) {
  // Against the true derivative the backward difference adds its own droop sin(wT/2)/(wT/2)
  // (0.5 % at 57 Hz), so the whole v_hat is at -3 dB a little below the low-pass alone.
  constexpr double kAlpha = 0.3;
  const double f_3db = minus_3db_frequency_hz(
      [](double f_hz) { return measured_velocity_response(kAlpha, f_hz).amplitude; }, 20.0, 100.0);
  const double analytic_hz = minus_3db_frequency_hz(
      [](double f_hz) {
        return std::abs(velocity_stage(kAlpha, 2.0 * kPi * f_hz)) / (2.0 * kPi * f_hz);
      },
      20.0, 100.0);
  EXPECT_NEAR(f_3db, analytic_hz, 1e-6);  // simulation vs H(z): exact up to rounding
  EXPECT_NEAR(f_3db, 56.76, 0.01);
  EXPECT_NEAR(f_3db, 57.0, 0.5);  // still "about 57 Hz" as the header says
}

}  // namespace
}  // namespace pneu::controller
