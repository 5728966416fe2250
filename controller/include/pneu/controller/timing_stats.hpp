// Distribution of a duration without allocation: exact min/max/count and a log-spaced histogram
// (0.5 % bins from 10 ns to 10 s) for the median and percentiles.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace pneu::controller {

class TimingStats {
 public:
  static constexpr double kMin_s = 1e-8;
  static constexpr double kMax_s = 10.0;
  static constexpr std::size_t kBins = 4200;  // ln(1e9) / ln(1.005) ~ 4155

  /// Real-time safe.
  void add(double seconds) noexcept {
    ++count_;
    min_ = std::min(min_, seconds);
    max_ = std::max(max_, seconds);
    ++bins_[bin_of(seconds)];
  }
  [[nodiscard]] std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] double min_s() const noexcept { return count_ ? min_ : 0.0; }
  [[nodiscard]] double max_s() const noexcept { return count_ ? max_ : 0.0; }
  /// The q-quantile (q in [0, 1]) to within one bin (0.5 %), clamped to [min, max].
  [[nodiscard]] double quantile_s(double q) const noexcept {
    if (count_ == 0) return 0.0;
    const auto rank = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_)));
    std::uint64_t seen = 0;
    for (std::size_t i = 0; i < kBins; ++i) {
      seen += bins_[i];
      if (seen >= std::max<std::uint64_t>(rank, 1))
        return std::clamp(kMin_s * std::pow(kRatio, static_cast<double>(i) + 0.5), min_, max_);
    }
    return max_;
  }
  void reset() noexcept { *this = TimingStats{}; }

 private:
  static constexpr double kRatio = 1.005;
  static std::size_t bin_of(double s) noexcept {
    if (!(s > kMin_s)) return 0;
    const double i = std::log(s / kMin_s) / std::log(kRatio);
    return i >= static_cast<double>(kBins - 1) ? kBins - 1 : static_cast<std::size_t>(i);
  }
  std::uint64_t count_ = 0;
  double min_ = std::numeric_limits<double>::infinity();
  double max_ = 0.0;
  std::array<std::uint32_t, kBins> bins_{};
};

}  // namespace pneu::controller
