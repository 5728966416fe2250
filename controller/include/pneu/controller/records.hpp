// The descriptions of the controller's records (pneu/records/record.hpp): the fields the outside
// world sees of each, in order, each spelled once. The trajectory file's columns, the state_t
// message (its .lcm definition is written from here at build time), pneu-log2csv's columns and the
// JSON Schemas all follow from them: a new field is one line here.
#pragma once

#include <tuple>
#include <utility>

#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/records/record.hpp"

namespace pneu::controller {

/// The loop's modes as the messages name them (state_t's MODE_* constants).
inline constexpr std::pair<Mode, const char*> kModeNames[] = {
    {Mode::kDisarmed, "DISARMED"}, {Mode::kArmed, "ARMED"},  {Mode::kFault, "FAULT"},
    {Mode::kHold, "HOLD"},         {Mode::kMovementTest, "MOVEMENT_TEST"},
};

}  // namespace pneu::controller

/// One tick of the loop: the trajectory file's row, the state_t message.
template <>
struct pneu::records::Description<pneu::controller::TickRecord> {
  using R = pneu::controller::TickRecord;
  static constexpr const char* kName = "tick";
  static constexpr const char* kDoc = "one tick of the loop: the sample, the estimates, the control sent, the loop's state";
  static constexpr auto kFields = std::tuple{
      field("seq", &R::seq, "", "tick sequence number, from 0 at start-up, no gaps"),
      field("t", &R::t_s, "s", "loop time of the sample since start-up", 12),
      field("y_d", &R::y_d_m, "m", "set point, from mid-stroke"),
      field("y", &R::y_m, "m", "measured position, from mid-stroke", 12),
      field("v_hat", &R::v_hat_m_per_s, "m/s", "estimated velocity"),
      field("a_hat", &R::a_hat_m_per_s2, "m/s^2", "estimated acceleration"),
      field("p_p", &R::p_p_pa, "Pa", "chamber P pressure, absolute"),
      field("p_n", &R::p_n_pa, "Pa", "chamber N pressure, absolute"),
      field("force", &R::force_n, "N", "pressure force S_P p_P - S_N p_N - S_r p_E (Eq. 14)"),
      field("u", &R::u_v, "V", "control sent: u_P = u, u_N = -u"),
      field("stuck", &R::stuck, "", "the stop detector holds the carriage at rest"),
      field("mode", &R::mode, "", "the loop's mode: MODE_*"),
      field("validity", &R::sensor_validity, "", "sensor validity flags, 0 = all readings valid"),
  };
};

/// What a forecast made at the stop expects at a tick while the carriage is stuck: the trajectory
/// file's columns NAME_linearized and NAME_nonlinear (empty when there is none).
template <>
struct pneu::records::Description<pneu::controller::ForecastPoint> {
  using R = pneu::controller::ForecastPoint;
  static constexpr const char* kName = "expected";
  static constexpr const char* kDoc = "what a forecast made at the stop expects at this tick";
  static constexpr auto kFields = std::tuple{
      field("p_p", &R::p_p_pa, "Pa", "chamber P pressure expected, absolute"),
      field("p_n", &R::p_n_pa, "Pa", "chamber N pressure expected, absolute"),
      field("force", &R::force_n, "N", "pressure force expected (Eq. 14)"),
  };
};
