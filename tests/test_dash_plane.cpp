// The pressure-force plane the dashboard draws (pneu/dash/plane.hpp), held against the model it is
// computed from: the null-flow curve is where neither chamber has a net flow, the areas are the
// bands of Eq. 12 and 13, the axes give the pressure force of Eq. 14, and a forecast's path is the
// predictor's own from the snapshot to the stiction bound at the forecast restart.
#include "pneu/dash/plane.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "pneu/model/params.hpp"
#include "pneu/model/pressure_force.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::dash {
namespace {

// The paper's bench (the model's defaults, docs/model.md section 7) with its ISO 6358 valve.
struct Bench {
  model::PlantParams plant;
  model::ValveModel valve{plant.valve, plant.gas};
  controller::PredictorModel model() const {
    controller::PredictorModel m;
    m.geometry = plant.geometry;
    m.gas = plant.gas;
    m.friction = plant.friction;
    m.valve = &valve;
    return m;
  }
  model::PressureForce force() const { return {plant.geometry, plant.gas.exhaust_pressure_pa}; }
};

double x_of(const PlaneGeometry& g, double p_p_pa) { return g.x_per_pa * p_p_pa + g.x_offset_n; }
double y_of(const PlaneGeometry& g, double p_n_pa) { return g.y_per_pa * p_n_pa + g.y_offset_n; }

// Whether (x, y) is inside the convex polygon (either orientation), edges included.
bool inside(const std::vector<PlanePoint>& polygon, double x, double y) {
  int sign = 0;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const PlanePoint& a = polygon[i];
    const PlanePoint& b = polygon[(i + 1) % polygon.size()];
    const double cross = (b.x_n - a.x_n) * (y - a.y_n) - (b.y_n - a.y_n) * (x - a.x_n);
    if (std::abs(cross) < 1e-9) continue;
    const int s = cross > 0 ? 1 : -1;
    if (sign != 0 && s != sign) return false;
    sign = s;
  }
  return true;
}

TEST(DashPlane, EveryPointOfTheNullFlowCurveHasNoNetFlowIntoEitherChamber) {
  const Bench b;
  const PlaneGeometry g = plane_geometry(b.model());
  ASSERT_GE(g.null_flow.size(), 50U);
  // The scale of a flow: the valve fully open into a chamber at mid-pressure.
  const double scale = std::abs(b.valve.mass_flow_kg_per_s(b.plant.valve.max_voltage_v, 4.0e5));
  for (const NullFlowPoint& p : g.null_flow) {
    SCOPED_TRACE("u = " + std::to_string(p.u_v));
    EXPECT_LT(std::abs(b.valve.mass_flow_kg_per_s(p.u_v, p.p_p_pa)), 1e-6 * scale);
    EXPECT_LT(std::abs(b.valve.mass_flow_kg_per_s(-p.u_v, p.p_n_pa)), 1e-6 * scale);
    EXPECT_NEAR(p.force_n, model::equilibrium_force_n(b.valve, b.plant.geometry, b.plant.gas.exhaust_pressure_pa, p.u_v),
                1e-9);
    EXPECT_NEAR(p.x_n, x_of(g, p.p_p_pa), 1e-9);
    EXPECT_NEAR(p.y_n, y_of(g, p.p_n_pa), 1e-9);
    EXPECT_NEAR(p.x_n - p.y_n, p.force_n, 1e-9);
  }
}

TEST(DashPlane, TheNullFlowCurveRunsFromOneEndOfTheValveToTheOtherWithoutJumps) {
  const Bench b;
  const PlaneGeometry g = plane_geometry(b.model(), 400);
  EXPECT_DOUBLE_EQ(g.null_flow.front().u_v, -b.plant.valve.max_voltage_v);
  EXPECT_DOUBLE_EQ(g.null_flow.back().u_v, b.plant.valve.max_voltage_v);
  const double diagonal = std::hypot(g.x_max_n - g.x_min_n, g.y_max_n - g.y_min_n);
  for (std::size_t i = 1; i < g.null_flow.size(); ++i) {
    EXPECT_GT(g.null_flow[i].u_v, g.null_flow[i - 1].u_v);
    EXPECT_GT(g.null_flow[i].force_n, g.null_flow[i - 1].force_n);  // F_e(u) increases in u
    // thinned evenly along the curve: no step longer than a few hundredths of the plane
    EXPECT_LT(std::hypot(g.null_flow[i].x_n - g.null_flow[i - 1].x_n, g.null_flow[i].y_n - g.null_flow[i - 1].y_n),
              0.02 * diagonal);
  }
}

TEST(DashPlane, TheAxesGiveThePressureForceOfEquation14) {
  const Bench b;
  const PlaneGeometry g = plane_geometry(b.model());
  for (double p_p : {1.0e5, 2.7e5, 4.4e5, 7.0e5}) {
    for (double p_n : {1.0e5, 3.1e5, 5.5e5, 7.0e5}) {
      EXPECT_NEAR(x_of(g, p_p) - y_of(g, p_n), b.force().force_n(p_p, p_n), 1e-9);
    }
  }
  EXPECT_NEAR(g.x_min_n, x_of(g, b.plant.gas.exhaust_pressure_pa), 1e-9);
  EXPECT_NEAR(g.x_max_n, x_of(g, b.plant.gas.supply_pressure_pa), 1e-9);
  EXPECT_NEAR(g.y_min_n, y_of(g, b.plant.gas.exhaust_pressure_pa), 1e-9);
  EXPECT_NEAR(g.y_max_n, y_of(g, b.plant.gas.supply_pressure_pa), 1e-9);
}

TEST(DashPlane, TheStopAndNoRestartAreasHoldExactlyThePointsWhoseForceIsInTheirBands) {
  const Bench b;
  const PlaneGeometry g = plane_geometry(b.model());
  const model::FrictionParams& f = b.plant.friction;
  ASSERT_GE(g.stop_area.size(), 3U);
  ASSERT_GE(g.no_restart_area.size(), 3U);
  for (const PlanePoint& p : g.stop_area) {
    EXPECT_GE(p.x_n - p.y_n, f.coulomb_negative_n - 1e-9);
    EXPECT_LE(p.x_n - p.y_n, f.coulomb_positive_n + 1e-9);
  }
  for (const PlanePoint& p : g.no_restart_area) {
    EXPECT_GE(p.x_n - p.y_n, f.static_negative_n - 1e-9);
    EXPECT_LE(p.x_n - p.y_n, f.static_positive_n + 1e-9);
  }
  // A grid of pressures over the reachable box: inside an area exactly when its force is in the band.
  int in_stop = 0, in_no_restart = 0;
  for (int i = 0; i <= 60; ++i) {
    for (int j = 0; j <= 60; ++j) {
      const double p_p = 1.0e5 + 6.0e5 * i / 60.0, p_n = 1.0e5 + 6.0e5 * j / 60.0;
      const double force = b.force().force_n(p_p, p_n);
      const double x = x_of(g, p_p), y = y_of(g, p_n);
      const bool stop = force >= f.coulomb_negative_n && force <= f.coulomb_positive_n;
      const bool no_restart = force >= f.static_negative_n && force <= f.static_positive_n;
      EXPECT_EQ(inside(g.stop_area, x, y), stop) << "p_P " << p_p << " p_N " << p_n << " F " << force;
      EXPECT_EQ(inside(g.no_restart_area, x, y), no_restart) << "p_P " << p_p << " p_N " << p_n << " F " << force;
      in_stop += stop;
      in_no_restart += no_restart;
    }
  }
  EXPECT_GT(in_stop, 0);
  EXPECT_GT(in_no_restart, in_stop);
}

TEST(DashPlane, AForecastPathRunsFromTheSnapshotToTheStictionBoundAtTheForecastRestart) {
  const Bench b;
  const controller::PredictorModel m = b.model();
  const model::PressureForce force = b.force();
  // Stuck at mid-stroke at the null pressures of u_e (F = 0), then held at a u* whose equilibrium force
  // lies beyond F_S+: the force creeps up to F_S+ and the carriage restarts towards +.
  controller::StopSnapshot stop;
  stop.t_s = 3.0;
  const double u_e = model::equilibrium_voltage_v(b.valve, b.plant.geometry, b.plant.gas.exhaust_pressure_pa);
  stop.p_p_pa = b.valve.null_pressure_pa(u_e);
  stop.p_n_pa = b.valve.null_pressure_pa(-u_e);
  double u_star = 0.0;
  while (model::equilibrium_force_n(b.valve, b.plant.geometry, b.plant.gas.exhaust_pressure_pa, u_star) <
         b.plant.friction.static_positive_n + 20.0)
    u_star += 0.001;
  stop.u_v = u_star;
  ASSERT_LT(std::abs(force.force_n(stop.p_p_pa, stop.p_n_pa)), b.plant.friction.static_positive_n);
  for (auto method : {controller::PredictionMethod::kLinearized, controller::PredictionMethod::kNonlinear}) {
    SCOPED_TRACE(controller::to_string(method));
    controller::ForecastRecord made;
    made.stop = 4;
    made.t_stop_s = 2.9;
    made.t_s = stop.t_s;
    made.u_star_v = stop.u_v;
    made.prediction = controller::predict(method, m, stop);
    const auto f = plane_forecast(m, stop, made, 5.0, 120);
    ASSERT_TRUE(f.has_value());
    ASSERT_TRUE(f->will_restart);
    EXPECT_EQ(f->direction, 1);
    EXPECT_EQ(f->stop, 4);
    EXPECT_DOUBLE_EQ(f->t_restart_s, made.prediction.t_restart_s);
    EXPECT_GT(f->t_restart_s, stop.t_s);
    ASSERT_EQ(f->path.size(), 120U);
    EXPECT_DOUBLE_EQ(f->path.front().t_s, stop.t_s);
    EXPECT_DOUBLE_EQ(f->path.back().t_s, f->t_restart_s);
    EXPECT_NEAR(f->path.front().x_n, force.plane_x_n(stop.p_p_pa), 1e-6);
    EXPECT_NEAR(f->path.front().y_n, force.plane_y_n(stop.p_n_pa), 1e-6);
    // the path reaches the bound F_S+ at the forecast restart, and not before
    EXPECT_NEAR(f->path.back().force_n, b.plant.friction.static_positive_n, 0.01);
    for (const ForecastPathPoint& p : f->path) {
      EXPECT_NEAR(p.x_n - p.y_n, p.force_n, 1e-6);
      if (&p != &f->path.back()) {
        EXPECT_LT(p.force_n, b.plant.friction.static_positive_n + 1e-6);
      }
    }
  }
  // A forecast of no restart: the path runs to the horizon; the methods the track does not follow
  // have none.
  controller::ForecastRecord none;
  none.prediction = controller::predict(controller::PredictionMethod::kLinearized, m, stop);
  none.prediction.will_restart = false;
  const auto to_horizon = plane_forecast(m, stop, none, 2.0, 10);
  ASSERT_TRUE(to_horizon.has_value());
  EXPECT_FALSE(to_horizon->will_restart);
  EXPECT_DOUBLE_EQ(to_horizon->path.back().t_s, stop.t_s + 2.0);
  none.prediction.method = controller::PredictionMethod::kRelaxation;
  EXPECT_FALSE(plane_forecast(m, stop, none).has_value());
}

TEST(DashPlane, ItsMessagesFollowTheirDescriptions) {
  const Bench b;
  const std::string json = to_json(plane_geometry(b.model(), 50));
  EXPECT_EQ(json.front(), '{');
  EXPECT_NE(json.find("\"stop_area\":[{\"x\":"), std::string::npos) << json.substr(0, 400);
  EXPECT_NE(json.find("\"null_flow\":[{\"u\":"), std::string::npos);
  const std::string schema = plane_schema("plane.schema.json");
  EXPECT_NE(schema.find("\"no_restart_area\""), std::string::npos);
  EXPECT_NE(schema.find("\"additionalProperties\": false"), std::string::npos);
  controller::StopSnapshot stop;
  stop.p_p_pa = stop.p_n_pa = 4.0e5;
  controller::ForecastRecord made;
  made.prediction = controller::predict(controller::PredictionMethod::kLinearized, b.model(), stop);
  const std::string forecast = to_json(*plane_forecast(b.model(), stop, made));
  EXPECT_NE(forecast.find("\"method\":\"linearized\""), std::string::npos) << forecast.substr(0, 300);
  EXPECT_NE(plane_forecast_schema("f").find("\"path\""), std::string::npos);
}

}  // namespace
}  // namespace pneu::dash
