// The parameters of the stop detector (controller.stop_detector).
#pragma once

#include "pneu/config/describe.hpp"

namespace pneu::controller {

struct StopDetectorParams {
  /// Positions within this band of the first still sample count as "not moving" [m], >= 0.
  /// 0 suits ideal sensors (a stuck carriage reads the same position bit for bit); with noise or
  /// quantisation use a few standard deviations / one LSB.
  double rest_band_m = 0.0;
  /// Leaving rest: the position must move more than this from the stop position [m], > rest band.
  double motion_band_m = 1.0e-6;
  /// A stop is confirmed once the position stays within the rest band this long [s], > 0.
  double hold_s = 0.005;
};

}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::StopDetectorParams;

void describe(auto& a, Like<StopDetectorParams> auto& d) {
  a.field(PNEU_NVP(d, rest_band_m), Range::non_negative(), "positions this close to the first still one rest [m]");
  a.field(PNEU_NVP(d, motion_band_m), Range::positive(), "leaving rest: moved more than this [m]");
  a.check("motion_band_m", d.motion_band_m > d.rest_band_m, "must exceed rest_band_m");
  a.field(PNEU_NVP(d, hold_s), Range::positive(), "a stop is confirmed after this long at rest [s]");
}

}  // namespace pneu::config::schema
