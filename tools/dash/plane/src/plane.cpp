#include "pneu/dash/plane.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "pneu/model/pressure_force.hpp"
#include "pneu/model/valve.hpp"
#include "pneu/records/json.hpp"
#include "pneu/records/schema.hpp"

namespace pneu::dash {
namespace {

// The part of `polygon` where x - y <= bound (keep_below) or >= bound: Sutherland-Hodgman against
// one half-plane whose edge is a line of constant force.
std::vector<PlanePoint> clip(const std::vector<PlanePoint>& polygon, double bound_n, bool keep_below) {
  std::vector<PlanePoint> out;
  const auto inside = [&](const PlanePoint& p) {
    return keep_below ? p.x_n - p.y_n <= bound_n : p.x_n - p.y_n >= bound_n;
  };
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const PlanePoint& a = polygon[i];
    const PlanePoint& b = polygon[(i + 1) % polygon.size()];
    if (inside(a)) out.push_back(a);
    if (inside(a) != inside(b)) {
      const double fa = a.x_n - a.y_n, fb = b.x_n - b.y_n;
      const double s = (bound_n - fa) / (fb - fa);
      out.push_back({a.x_n + s * (b.x_n - a.x_n), a.y_n + s * (b.y_n - a.y_n)});
    }
  }
  return out;
}

// The band lo <= x - y <= hi of the box.
std::vector<PlanePoint> band(const PlaneGeometry& g, double lo_n, double hi_n) {
  const std::vector<PlanePoint> box = {
      {g.x_min_n, g.y_min_n}, {g.x_max_n, g.y_min_n}, {g.x_max_n, g.y_max_n}, {g.x_min_n, g.y_max_n}};
  return clip(clip(box, hi_n, true), lo_n, false);
}

}  // namespace

PlaneGeometry plane_geometry(const controller::PredictorModel& model, int max_points) {
  const model::PressureForce force(model.geometry, model.gas.exhaust_pressure_pa);
  const model::ValveCharacteristic& valve = *model.valve;
  PlaneGeometry g;
  // plane_x_n(p) = S_P p, plane_y_n(p) = S_N p + S_r p_E: their slopes are the areas, their
  // offsets their values at 0.
  g.x_per_pa = force.area_p_m2();
  g.x_offset_n = force.plane_x_n(0.0);
  g.y_per_pa = force.area_n_m2();
  g.y_offset_n = force.plane_y_n(0.0);
  g.static_positive_n = model.friction.static_positive_n;
  g.static_negative_n = model.friction.static_negative_n;
  g.coulomb_positive_n = model.friction.coulomb_positive_n;
  g.coulomb_negative_n = model.friction.coulomb_negative_n;
  g.x_min_n = force.plane_x_n(model.gas.exhaust_pressure_pa);
  g.x_max_n = force.plane_x_n(model.gas.supply_pressure_pa);
  g.y_min_n = force.plane_y_n(model.gas.exhaust_pressure_pa);
  g.y_max_n = force.plane_y_n(model.gas.supply_pressure_pa);
  g.stop_area = band(g, g.coulomb_negative_n, g.coulomb_positive_n);
  g.no_restart_area = band(g, g.static_negative_n, g.static_positive_n);

  // The curve turns sharply near u = 0 (the leaks' region) and is nearly straight towards the
  // ends: sample finely in u, keep a point each time the curve has gone a step further in the plane.
  const double u_lo = std::max(valve.min_voltage_v(), -valve.max_voltage_v());
  const double u_hi = std::min(valve.max_voltage_v(), -valve.min_voltage_v());
  const int fine = 20000;
  const double step_n = std::hypot(g.x_max_n - g.x_min_n, g.y_max_n - g.y_min_n) / std::max(max_points, 2);
  const auto point = [&](double u) {
    NullFlowPoint p;
    p.u_v = u;
    p.p_p_pa = valve.null_pressure_pa(u);
    p.p_n_pa = valve.null_pressure_pa(-u);
    p.x_n = force.plane_x_n(p.p_p_pa);
    p.y_n = force.plane_y_n(p.p_n_pa);
    p.force_n = force.force_n(p.p_p_pa, p.p_n_pa);
    return p;
  };
  g.null_flow.push_back(point(u_lo));
  for (int i = 1; i <= fine; ++i) {
    const NullFlowPoint p = point(u_lo + (u_hi - u_lo) * i / fine);
    const NullFlowPoint& last = g.null_flow.back();
    if (i == fine || std::hypot(p.x_n - last.x_n, p.y_n - last.y_n) >= step_n) g.null_flow.push_back(p);
  }
  return g;
}

std::optional<PlaneForecast> plane_forecast(const controller::PredictorModel& model,
                                            const controller::StopSnapshot& stop,
                                            const controller::ForecastRecord& made, double horizon_s, int points) {
  const controller::PredictionMethod method = made.prediction.method;
  if (method != controller::PredictionMethod::kLinearized && method != controller::PredictionMethod::kNonlinear)
    return std::nullopt;
  const model::PressureForce force(model.geometry, model.gas.exhaust_pressure_pa);
  const controller::Prediction& p = made.prediction;
  PlaneForecast f;
  f.stop = static_cast<std::int64_t>(made.stop);
  f.t_s = made.t_s;
  f.t_stop_s = made.t_stop_s;
  f.update = made.update;
  f.method = method;
  f.will_restart = p.will_restart && std::isfinite(p.t_restart_s) && p.t_restart_s >= stop.t_s;
  f.direction = static_cast<std::int8_t>(f.will_restart ? p.direction : 0);
  f.t_restart_s = f.will_restart ? p.t_restart_s : std::numeric_limits<double>::quiet_NaN();
  const double t_end = f.will_restart ? p.t_restart_s : stop.t_s + horizon_s;
  controller::ForecastTrack track(method, model, stop);
  const int n = std::max(points, 2);
  f.path.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const double t = i + 1 == n ? t_end : stop.t_s + (t_end - stop.t_s) * i / (n - 1);
    const controller::ForecastPoint e = track.at(t);
    f.path.push_back({t, force.plane_x_n(e.p_p_pa), force.plane_y_n(e.p_n_pa), e.force_n});
  }
  return f;
}

std::string to_json(const PlaneGeometry& plane) {
  std::string out;
  records::write_json_object(out, plane);
  return out;
}

std::string to_json(const PlaneForecast& forecast) {
  std::string out;
  records::write_json_object(out, forecast);
  return out;
}

std::string plane_schema(const std::string& id) { return records::json_schema<PlaneGeometry>(id); }
std::string plane_forecast_schema(const std::string& id) { return records::json_schema<PlaneForecast>(id); }

}  // namespace pneu::dash
