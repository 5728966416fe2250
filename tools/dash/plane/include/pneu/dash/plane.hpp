// The pressure-force plane (Brun et al. 2005, Fig. 7, 10, 11; docs/model.md section 5) as the
// dashboard draws it, computed from the model library so that the page re-types no equation:
// the plane's axes x = S_P p_P and y = S_N p_N + S_r p_E (Eq. 14 split, model::PressureForce) as
// an affine map of the pressures, the stop area (Eq. 12) and the no-restarting area (Eq. 13) as
// polygons, the null-flow curve (complete equilibrium, p_null(u) and p_null(-u)) as points, and a
// restart forecast's path (controller::ForecastTrack) as points in time. Each is a record described
// once (pneu/records/record.hpp): its JSON message and JSON Schema follow from the description.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "pneu/controller/predictor.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/records/record.hpp"

namespace pneu::dash {

/// A point of the plane [N].
struct PlanePoint {
  double x_n = 0.0;  ///< S_P p_P
  double y_n = 0.0;  ///< S_N p_N + S_r p_E
};

/// A point of the null-flow curve: both chambers at their null-flow pressure under u (Fig. 6).
struct NullFlowPoint {
  double u_v = 0.0;
  double p_p_pa = 0.0;   ///< p_null(u)
  double p_n_pa = 0.0;   ///< p_null(-u)
  double x_n = 0.0;
  double y_n = 0.0;
  double force_n = 0.0;  ///< F_e(u) = x - y
};

/// Everything static the page draws in the plane (the latched channel PNEU_PLANE).
struct PlaneGeometry {
  /// The plane's axes as an affine map of the absolute pressures [Pa]:
  /// x = x_per_pa p_P + x_offset_n, y = y_per_pa p_N + y_offset_n; F = x - y (Eq. 14).
  double x_per_pa = 0.0, x_offset_n = 0.0, y_per_pa = 0.0, y_offset_n = 0.0;
  double static_positive_n = 0.0, static_negative_n = 0.0;    ///< F_S+, F_S-
  double coulomb_positive_n = 0.0, coulomb_negative_n = 0.0;  ///< F_C+, F_C-
  /// The reachable part of the plane: both pressures between p_E and p_S [N].
  double x_min_n = 0.0, x_max_n = 0.0, y_min_n = 0.0, y_max_n = 0.0;
  std::vector<PlanePoint> stop_area;        ///< Eq. 12, F_C- <= x - y <= F_C+, clipped to the reachable box
  std::vector<PlanePoint> no_restart_area;  ///< Eq. 13, F_S- <= x - y <= F_S+, clipped likewise
  std::vector<NullFlowPoint> null_flow;     ///< from the most negative u to the most positive
};

/// The plane of `model` (its geometry, gas, friction and valve characteristic, which must be set).
/// The null-flow curve is sampled finely over the valve's voltage range and thinned to at most
/// about `max_points` points spread evenly along the curve in the plane.
[[nodiscard]] PlaneGeometry plane_geometry(const controller::PredictorModel& model, int max_points = 400);

/// A point of a forecast's path through the plane at time t_s.
struct ForecastPathPoint {
  double t_s = 0.0;
  double x_n = 0.0;
  double y_n = 0.0;
  double force_n = 0.0;
};

/// What a restart forecast expects the pressures to do while the carriage stays stuck, as a path in
/// the plane (the channel PNEU_PLANE_FORECAST): from the snapshot to the forecast restart, or to
/// `horizon_s` after the snapshot when it forecasts none.
struct PlaneForecast {
  std::int64_t stop = 0;
  double t_s = 0.0;       ///< when the forecast was made
  double t_stop_s = 0.0;  ///< the stop's time
  std::int64_t update = 0;
  controller::PredictionMethod method = controller::PredictionMethod::kLinearized;
  bool will_restart = false;
  std::int8_t direction = 0;
  double t_restart_s = 0.0;  ///< NaN when none
  std::vector<ForecastPathPoint> path;
};

/// The path the forecast `made` expects from `stop` (its snapshot: the tick it was made from, u*
/// its u_star), as controller::ForecastTrack follows it for the forecast's method: `points`
/// points evenly in time from stop.t_s to the restart it forecasts, or to stop.t_s + horizon_s
/// when it forecasts none. The other members are the forecast's own. Only the methods the track
/// follows (linearized, nonlinear) have a path: for the others, none.
[[nodiscard]] std::optional<PlaneForecast> plane_forecast(const controller::PredictorModel& model,
                                                          const controller::StopSnapshot& stop,
                                                          const controller::ForecastRecord& made,
                                                          double horizon_s = 5.0, int points = 120);

/// The JSON message of each (the records' one description).
[[nodiscard]] std::string to_json(const PlaneGeometry& plane);
[[nodiscard]] std::string to_json(const PlaneForecast& forecast);
/// Their JSON Schemas (draft 2020-12), with `id` as $id.
[[nodiscard]] std::string plane_schema(const std::string& id);
[[nodiscard]] std::string plane_forecast_schema(const std::string& id);

}  // namespace pneu::dash

template <>
struct pneu::records::Description<pneu::dash::PlanePoint> {
  using R = pneu::dash::PlanePoint;
  static constexpr const char* kName = "plane_point";
  static constexpr const char* kDoc = "a point of the pressure-force plane";
  static constexpr auto kFields = std::tuple{
      field("x", &R::x_n, "N", "S_P p_P"),
      field("y", &R::y_n, "N", "S_N p_N + S_r p_E"),
  };
};

template <>
struct pneu::records::Description<pneu::dash::NullFlowPoint> {
  using R = pneu::dash::NullFlowPoint;
  static constexpr const char* kName = "null_flow_point";
  static constexpr const char* kDoc = "a point of the null-flow curve: both chambers at null flow under u";
  static constexpr auto kFields = std::tuple{
      field("u", &R::u_v, "V", "the control u"),
      field("p_p", &R::p_p_pa, "Pa", "p_null(u), chamber P"),
      field("p_n", &R::p_n_pa, "Pa", "p_null(-u), chamber N"),
      field("x", &R::x_n, "N", "S_P p_null(u)"),
      field("y", &R::y_n, "N", "S_N p_null(-u) + S_r p_E"),
      field("force", &R::force_n, "N", "F_e(u) = x - y, the force at complete equilibrium"),
  };
};

template <>
struct pneu::records::Description<pneu::dash::PlaneGeometry> {
  using R = pneu::dash::PlaneGeometry;
  static constexpr const char* kName = "plane";
  static constexpr const char* kDoc =
      "the pressure-force plane (Brun et al. 2005, Fig. 7): its axes as a map of the pressures, the stop and "
      "no-restarting areas and the null-flow curve, from the bench's model";
  static constexpr auto kFields = std::tuple{
      field("x_per_pa", &R::x_per_pa, "N/Pa", "x = x_per_pa p_P + x_offset: S_P"),
      field("x_offset", &R::x_offset_n, "N", "0"),
      field("y_per_pa", &R::y_per_pa, "N/Pa", "y = y_per_pa p_N + y_offset: S_N"),
      field("y_offset", &R::y_offset_n, "N", "S_r p_E"),
      field("static_positive", &R::static_positive_n, "N", "F_S+"),
      field("static_negative", &R::static_negative_n, "N", "F_S-"),
      field("coulomb_positive", &R::coulomb_positive_n, "N", "F_C+"),
      field("coulomb_negative", &R::coulomb_negative_n, "N", "F_C-"),
      field("x_min", &R::x_min_n, "N", "x at p_P = p_E"),
      field("x_max", &R::x_max_n, "N", "x at p_P = p_S"),
      field("y_min", &R::y_min_n, "N", "y at p_N = p_E"),
      field("y_max", &R::y_max_n, "N", "y at p_N = p_S"),
      field("stop_area", &R::stop_area, "", "Eq. 12, F_C- <= x - y <= F_C+: a polygon within the reachable box"),
      field("no_restart_area", &R::no_restart_area, "",
            "Eq. 13, F_S- <= x - y <= F_S+: a polygon within the reachable box"),
      field("null_flow", &R::null_flow, "", "the null-flow curve (complete equilibrium), by increasing u"),
  };
};

template <>
struct pneu::records::Description<pneu::dash::ForecastPathPoint> {
  using R = pneu::dash::ForecastPathPoint;
  static constexpr const char* kName = "forecast_path_point";
  static constexpr const char* kDoc = "where a forecast expects the state point at a time";
  static constexpr auto kFields = std::tuple{
      field("t", &R::t_s, "s", "loop time", 12),
      field("x", &R::x_n, "N", "S_P p_P expected"),
      field("y", &R::y_n, "N", "S_N p_N + S_r p_E expected"),
      field("force", &R::force_n, "N", "x - y expected (Eq. 14)"),
  };
};

template <>
struct pneu::records::Description<pneu::dash::PlaneForecast> {
  using R = pneu::dash::PlaneForecast;
  static constexpr const char* kName = "plane_forecast";
  static constexpr const char* kDoc =
      "a restart forecast's path through the pressure-force plane while the carriage stays stuck";
  static constexpr auto kFields = std::tuple{
      field("stop", &R::stop, "", "index of the stop"),
      field("t", &R::t_s, "s", "loop time the forecast was made", 12),
      field("t_stop", &R::t_stop_s, "s", "time of the stop", 12),
      field("update", &R::update, "", "0: made at the stop; k: the k-th made again while still stuck"),
      field("method", &R::method, "", "how it was made: METHOD_*").named(pneu::controller::kPredictionMethods),
      field("will_restart", &R::will_restart, "", "whether it forecasts a restart"),
      field("direction", &R::direction, "", "+1 / -1, 0 when no restart"),
      field("t_restart", &R::t_restart_s, "s", "forecast restart time, null when none", 12)
          .null_when(+[](const R& r) { return !r.will_restart; }),
      field("path", &R::path, "", "the state point expected, evenly in time up to the restart (or the horizon)"),
  };
};
