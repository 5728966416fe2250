// A number with its first derivatives by N directions (forward-mode automatic differentiation):
// the model's equations written once for a scalar type S are, at S = double, the plant's own
// arithmetic, and at S = Dual<N> the same arithmetic with the derivatives carried beside it (the
// identification's exact Jacobian). Each operation's value is the double operation's, bit for bit.
// A value type; no allocation.
#pragma once

#include <array>
#include <cmath>

namespace pneu::model {

template <int N>
struct Dual {
  double v = 0.0;            ///< the value
  std::array<double, N> d{};  ///< d v / d direction i

  Dual() = default;
  Dual(double value) noexcept : v(value) {}  // NOLINT(google-explicit-constructor): a constant
  /// The independent variable `value` along direction i.
  static Dual variable(double value, int i, double slope = 1.0) noexcept {
    Dual x(value);
    x.d[static_cast<std::size_t>(i)] = slope;
    return x;
  }

  friend Dual operator-(const Dual& a) noexcept {
    Dual r(-a.v);
    for (int i = 0; i < N; ++i) r.d[i] = -a.d[i];
    return r;
  }
  friend Dual operator+(const Dual& a, const Dual& b) noexcept {
    Dual r(a.v + b.v);
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] + b.d[i];
    return r;
  }
  friend Dual operator-(const Dual& a, const Dual& b) noexcept {
    Dual r(a.v - b.v);
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] - b.d[i];
    return r;
  }
  friend Dual operator*(const Dual& a, const Dual& b) noexcept {
    Dual r(a.v * b.v);
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] * b.v + a.v * b.d[i];
    return r;
  }
  friend Dual operator/(const Dual& a, const Dual& b) noexcept {
    Dual r(a.v / b.v);
    const double inverse = 1.0 / b.v;  // (the derivatives by a multiplication; the value as divided)
    for (int i = 0; i < N; ++i) r.d[i] = (a.d[i] - r.v * b.d[i]) * inverse;
    return r;
  }
  friend Dual operator+(const Dual& a, double b) noexcept {
    Dual r = a;
    r.v = a.v + b;
    return r;
  }
  friend Dual operator+(double a, const Dual& b) noexcept {
    Dual r = b;
    r.v = a + b.v;
    return r;
  }
  friend Dual operator-(const Dual& a, double b) noexcept {
    Dual r = a;
    r.v = a.v - b;
    return r;
  }
  friend Dual operator-(double a, const Dual& b) noexcept {
    Dual r(a - b.v);
    for (int i = 0; i < N; ++i) r.d[i] = -b.d[i];
    return r;
  }
  friend Dual operator*(const Dual& a, double b) noexcept {
    Dual r(a.v * b);
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] * b;
    return r;
  }
  friend Dual operator*(double a, const Dual& b) noexcept {
    Dual r(a * b.v);
    for (int i = 0; i < N; ++i) r.d[i] = a * b.d[i];
    return r;
  }
  friend Dual operator/(const Dual& a, double b) noexcept {
    Dual r(a.v / b);
    const double inverse = 1.0 / b;
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] * inverse;
    return r;
  }
  friend Dual operator/(double a, const Dual& b) noexcept {
    Dual r(a / b.v);
    const double slope = -r.v / b.v;
    for (int i = 0; i < N; ++i) r.d[i] = slope * b.d[i];
    return r;
  }
  Dual& operator+=(const Dual& b) noexcept { return *this = *this + b; }
  Dual& operator-=(const Dual& b) noexcept { return *this = *this - b; }
  Dual& operator*=(const Dual& b) noexcept { return *this = *this * b; }

  // Comparisons are of the values (a branch of the equations is taken as at the value).
  friend bool operator<(const Dual& a, const Dual& b) noexcept { return a.v < b.v; }
  friend bool operator>(const Dual& a, const Dual& b) noexcept { return a.v > b.v; }
  friend bool operator<=(const Dual& a, const Dual& b) noexcept { return a.v <= b.v; }
  friend bool operator>=(const Dual& a, const Dual& b) noexcept { return a.v >= b.v; }
  friend bool operator<(const Dual& a, double b) noexcept { return a.v < b; }
  friend bool operator>(const Dual& a, double b) noexcept { return a.v > b; }
  friend bool operator<=(const Dual& a, double b) noexcept { return a.v <= b; }
  friend bool operator>=(const Dual& a, double b) noexcept { return a.v >= b; }
  friend bool operator<(double a, const Dual& b) noexcept { return a < b.v; }
  friend bool operator>(double a, const Dual& b) noexcept { return a > b.v; }
  friend bool operator<=(double a, const Dual& b) noexcept { return a <= b.v; }
  friend bool operator>=(double a, const Dual& b) noexcept { return a >= b.v; }

  friend Dual sqrt(const Dual& a) noexcept {
    Dual r(std::sqrt(a.v));
    const double slope = 0.5 / r.v;
    for (int i = 0; i < N; ++i) r.d[i] = a.d[i] * slope;
    return r;
  }
  friend Dual exp(const Dual& a) noexcept {
    Dual r(std::exp(a.v));
    for (int i = 0; i < N; ++i) r.d[i] = r.v * a.d[i];
    return r;
  }
  // std::fmax's and std::fmin's choice (a NaN loses), with the chosen one's derivatives.
  friend Dual fmax(const Dual& a, const Dual& b) noexcept { return std::fmax(a.v, b.v) == a.v && !std::isnan(a.v) ? a : b; }
  friend Dual fmin(const Dual& a, const Dual& b) noexcept { return std::fmin(a.v, b.v) == a.v && !std::isnan(a.v) ? a : b; }
};

/// Whether T is a Dual (a number with derivatives).
template <class T>
inline constexpr bool kIsDual = false;
template <int N>
inline constexpr bool kIsDual<Dual<N>> = true;

/// r's derivatives += k times x's (nothing for a constant): a function's derivatives from its partial
/// derivatives by each argument, in one pass over the directions per argument.
template <int N>
void add_scaled(Dual<N>& r, double k, const Dual<N>& x) noexcept {
  for (int i = 0; i < N; ++i) r.d[i] += k * x.d[i];
}
template <int N>
void add_scaled(Dual<N>&, double, double) noexcept {}

/// The value of a number, with or without derivatives.
[[nodiscard]] inline double value(double x) noexcept { return x; }
template <int N>
[[nodiscard]] double value(const Dual<N>& x) noexcept {
  return x.v;
}

}  // namespace pneu::model
