// Specification of the pressure force, Eq. 14 (docs/model.md section 2), and of the pressure-force
// plane of Fig. 7 (section 5). Expected values are the formulas written out again here.
#include <gtest/gtest.h>

#include <numbers>

#include "pneu/model/params.hpp"
#include "pneu/model/pressure_force.hpp"

namespace pneu::model {
namespace {

constexpr double kExhaustPa = 1.0e5;
const double kAreaP = std::numbers::pi / 4.0 * 0.032 * 0.032;  // the default bore, 32 mm
const double kAreaRod = std::numbers::pi / 4.0 * 0.020 * 0.020;  // the default rod, 20 mm

TEST(PressureForce, IsEquation14) {
  const PressureForce force(Geometry{}, kExhaustPa);
  const double expected = kAreaP * 5.0e5 - (kAreaP - kAreaRod) * 3.0e5 - kAreaRod * kExhaustPa;
  EXPECT_NEAR(force.force_n(5.0e5, 3.0e5), expected, 1e-10);  // rounding of a ~100 N sum
}

TEST(PressureForce, TheRodSideSeesTheExhaustPressureOnTheRodsOutside) {
  // Both chambers at p_E: the rod's outside area is the only imbalance, S_r p_E towards -y.
  const PressureForce force(Geometry{}, kExhaustPa);
  EXPECT_NEAR(force.force_n(kExhaustPa, kExhaustPa), 0.0, 1e-10);
  EXPECT_NEAR(force.force_n(0.0, 0.0), -kAreaRod * kExhaustPa, 1e-10);
}

TEST(PressureForce, IsThePushingSideLessTheOpposingSideOfTheForcePlane) {
  const PressureForce force(Geometry{}, kExhaustPa);
  for (const double p_p : {1.0e5, 3.3e5, 7.0e5}) {
    for (const double p_n : {1.0e5, 4.1e5, 7.0e5}) {
      EXPECT_DOUBLE_EQ(force.plane_x_n(p_p), kAreaP * p_p);
      EXPECT_NEAR(force.plane_y_n(p_n), (kAreaP - kAreaRod) * p_n + kAreaRod * kExhaustPa, 1e-10);
      EXPECT_NEAR(force.plane_x_n(p_p) - force.plane_y_n(p_n), force.force_n(p_p, p_n), 1e-10);
    }
  }
}

TEST(PressureForce, TakesItsAreasFromTheGeometry) {
  Geometry g;
  g.bore_diameter_m = 0.050;
  g.rod_diameter_m = 0.025;
  const PressureForce force(g, 2.0e5);
  EXPECT_DOUBLE_EQ(force.area_p_m2(), g.area_p_m2());
  EXPECT_DOUBLE_EQ(force.area_n_m2(), g.area_n_m2());
  EXPECT_DOUBLE_EQ(force.area_rod_m2(), g.area_rod_m2());
  EXPECT_DOUBLE_EQ(force.exhaust_pressure_pa(), 2.0e5);
}

}  // namespace
}  // namespace pneu::model
