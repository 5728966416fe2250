// The parameters of the control law of Eq. 4 (controller.law): fixed gains, or the design of a gain
// table scheduled by position (controller.law.design).
#pragma once

#include <cstdint>
#include "pneu/config/describe.hpp"
#include "pneu/model/params.hpp"
#include "pneu/model/tangent_linear.hpp"

namespace pneu::controller {

/// Where the gains of Eq. 4 come from (controller.law.gains).
enum class GainsKind : std::uint8_t {
  kFixed,      ///< "fixed": the three gains of controller.law, the same over the whole stroke
  kScheduled,  ///< "scheduled": designed at start-up at nodes over the stroke (pole placement on
               ///< the tangent-linear model, controller.law.design) and interpolated in position
};

/// What a design does where the requested dynamics cannot be had (controller.law.design.infeasible).
enum class InfeasibleDesign : std::uint8_t {
  kFallBack,  ///< "fall_back": node by node, the nearest feasible dynamics the sampled loop is stable with, reported
  kRefuse,    ///< "refuse": the whole design refused, pneud does not start
};

/// The design of scheduled gains (controller.law.design; pneu-plant tune designs with it too):
/// the requested closed-loop dynamics, the table's node spacing and the largest gains accepted.
struct GainDesignParams {
  double real_pole_1_per_s = 10.0;             ///< alpha: real pole at s = -alpha [1/s], > 0
  double natural_frequency_rad_per_s = 45.0;   ///< omega of the damped pair [rad/s], > 0
  double damping = 0.7;                        ///< zeta of the damped pair [-], > 0
  double node_spacing_m = 0.01;                ///< the table's nodes over the stroke, about this far apart [m]
  double max_position_gain_v_per_m = 1000.0;          ///< a design beyond this K_y is refused [V/m]
  double max_velocity_gain_v_s_per_m = 200.0;         ///< ... K_v [V/(m/s)]
  double max_acceleration_gain_v_s2_per_m = 5.0;      ///< ... K_a [V/(m/s^2)]
  InfeasibleDesign infeasible = InfeasibleDesign::kFallBack;  ///< where the requested dynamics cannot be had
};

struct ControlLawParams {
  GainsKind gains = GainsKind::kFixed;             ///< fixed gains, or scheduled by position
  double position_gain_v_per_m = 80.0;             ///< K_y [V/m]
  double velocity_gain_v_s_per_m = 1.5;            ///< K_v [V/(m/s)]
  double acceleration_gain_v_s2_per_m = 0.002;     ///< K_a [V/(m/s^2)]
  double offset_v = 0.0;                           ///< u_0 [V]: u_e of Eq. 7 unless configured
  double max_voltage_v = 10.0;                     ///< u_max: saturation [V], > 0
  GainDesignParams design;                         ///< controller.law.design (optional section)
};


}  // namespace pneu::controller

// Its keys, described once (pneu/config/describe.hpp; config/include/pneu/config/schema.hpp reads
// the whole configuration with it).
namespace pneu::config::schema {

using controller::GainsKind;
using controller::InfeasibleDesign;
using controller::GainDesignParams;
using controller::ControlLawParams;

inline constexpr Choice<GainsKind> kGainsKinds[] = {{"fixed", GainsKind::kFixed}, {"scheduled", GainsKind::kScheduled}};
inline constexpr Choice<InfeasibleDesign> kInfeasibleDesigns[] = {{"fall_back", InfeasibleDesign::kFallBack},
                                                                  {"refuse", InfeasibleDesign::kRefuse}};

void describe(auto& a, Like<GainDesignParams> auto& d, const model::Geometry& geometry) {
  a.field(PNEU_NVP(d, real_pole_1_per_s), Range::positive(), "alpha: the real pole, s = -alpha [1/s]");
  a.field(PNEU_NVP(d, natural_frequency_rad_per_s), Range::positive(), "omega: the damped pair's natural frequency [rad/s]");
  a.field(PNEU_NVP(d, damping), Range::positive(), "zeta: the damped pair's damping");
  a.field(PNEU_NVP(d, node_spacing_m), Range::positive(), "the gain table's nodes over the stroke, about this far apart [m]");
  a.check("node_spacing_m", geometry.stroke_m / d.node_spacing_m <= static_cast<double>(model::GainSchedule::kMaxNodes - 1),
          [&] {
            return "makes more than " + std::to_string(model::GainSchedule::kMaxNodes) +
                   " nodes over the stroke (plant.geometry.stroke_m " + fmt(geometry.stroke_m) + " m): at least " +
                   fmt(geometry.stroke_m / static_cast<double>(model::GainSchedule::kMaxNodes - 1)) + " m";
          });
  a.field(PNEU_NVP(d, max_position_gain_v_per_m), Range::positive(), "a design beyond this K_y is refused [V/m]");
  a.field(PNEU_NVP(d, max_velocity_gain_v_s_per_m), Range::positive(), "... K_v [V/(m/s)]");
  a.field(PNEU_NVP(d, max_acceleration_gain_v_s2_per_m), Range::positive(), "... K_a [V/(m/s^2)]");
  a.field(optional(PNEU_NVP(d, infeasible)), one_of(kInfeasibleDesigns),
          "where the requested dynamics cannot be had: fall_back | refuse");
}

void describe(auto& a, Like<ControlLawParams> auto& law, Like<bool> auto& offset_auto, const model::Geometry& geometry) {
  a.field(optional(PNEU_NVP(law, gains)), one_of(kGainsKinds),
          "fixed: the three gains below | scheduled: designed by position from controller.law.design");
  a.field(PNEU_NVP(law, position_gain_v_per_m), Range::non_negative(), "K_y [V/m]");
  a.field(PNEU_NVP(law, velocity_gain_v_s_per_m), Range::non_negative(), "K_v [V/(m/s)]");
  a.field(PNEU_NVP(law, acceleration_gain_v_s2_per_m), Range::non_negative(), "K_a [V/(m/s^2)]");
  a.number_or_auto(PNEU_NVP(law, offset_v), offset_auto, "u_0 [V]; auto = u_e of Eq. 7");
  a.field(PNEU_NVP(law, max_voltage_v), Range::positive(), "u_max: the control saturates at +-u_max [V]");
  a.section(optional(PNEU_NVP(law, design)), geometry);
}

}  // namespace pneu::config::schema

namespace pneu::controller {

/// The key's value: "fixed" or "scheduled".
[[nodiscard]] inline const char* to_string(GainsKind g) noexcept {
  return config::schema::one_of(config::schema::kGainsKinds).name_of(g);
}

}  // namespace pneu::controller
