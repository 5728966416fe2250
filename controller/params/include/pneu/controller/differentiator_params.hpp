// The parameters of the position's differentiator (controller.differentiator).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

struct DifferentiatorParams {
  /// Smoothing gain alpha of each first-order low-pass, x += alpha (raw - x) per sample, in (0, 1].
  /// alpha = 1 is the bare backward difference. Pole at z = 1 - alpha: time constant
  /// -T / ln(1 - alpha) (2.8 ms at alpha = 0.3, T = 1 ms), -3 dB bandwidth about
  /// acos(1 - alpha^2 / (2 (1 - alpha))) / (2 pi T) (57 Hz at alpha = 0.3, T = 1 ms).
  double smoothing = 0.3;
};

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::DifferentiatorParams;

void describe(auto& a, Like<DifferentiatorParams> auto& d) {
  a.field(PNEU_NVP(d, smoothing), Range::left_open(0.0, 1.0), "alpha of each low-pass, x += alpha (raw - x)");
}

}  // namespace pneu::config::schema
