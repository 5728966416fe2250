#include "page.hpp"

#include <chrono>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "pneu/config/config.hpp"
#include "pneu/controller/records.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/dash/plane.hpp"
#include "pneu/model/valve.hpp"
#include "pneu/model/valve_table.hpp"
#include "pneu/records/lcm.hpp"
#include "pneu_lcm/prediction_t_members.hpp"
#include "pneu_lcm/state_t_members.hpp"

namespace pneu::dash {
namespace {

constexpr double kTicksKept_s = 5.0;

std::uint64_t now_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count());
}

template <class Message, class Record>
bool decode(const void* data, std::size_t size, Record& r) {
  if (size < 8 || size > 0x7fffffff) return false;
  Message m{};
  if (m.decode(data, 0, static_cast<int>(size)) != static_cast<int>(size)) return false;
  records::from_lcm(m, r);
  return true;
}

std::shared_ptr<const model::ValveCharacteristic> predictor_valve(const config::Config& config,
                                                                  const std::filesystem::path& config_dir) {
  const std::string& table = config.controller.predictor.valve_table;
  if (table.empty()) return std::make_shared<const model::ValveModel>(config.plant.valve, config.plant.gas);
  std::filesystem::path path(table);
  if (path.is_relative()) path = config_dir / path;
  return std::make_shared<const model::ValveTable>(model::ValveTable::load(path));
}

}  // namespace

void serve_chart_js(Server& server, const std::filesystem::path& chart_js_dir) {
  const std::filesystem::path file = chart_js_dir / "chart.min.js";
  std::ifstream in(file, std::ios::binary);
  if (!in)
    throw std::runtime_error(file.string() + ": cannot read it: the page draws with Chart.js (Debian package "
                             "libjs-chart.js)");
  std::ostringstream body;
  body << in.rdbuf();
  server.add_route("GET", "/js/chart.js/chart.min.js", [js = body.str()](const HttpRequest&) {
    return HttpResponse{200, "text/javascript; charset=utf-8", js};
  });
}

PlaneFeed::PlaneFeed(Server& server, const std::string& prefix, const config::Config& config,
                     const std::filesystem::path& config_dir)
    : server_(server),
      state_channel_(prefix + "STATE"),
      prediction_channel_(prefix + "PREDICTION"),
      valve_(predictor_valve(config, config_dir)),
      model_(controller::predictor_model(config, *valve_)) {
  const std::string schemas = "https://pneu.invalid/schemas/";
  const ChannelId plane = server_.add_channel(
      {prefix + "PLANE", "plane", plane_schema(schemas + "plane.schema.json"), true, ""});
  forecast_id_ = server_.add_channel(
      {prefix + "PLANE_FORECAST", "plane_forecast", plane_forecast_schema(schemas + "plane_forecast.schema.json"),
       false, ""});
  server_.publish(plane, now_ns(), to_json(plane_geometry(model_)));
}

PlaneFeed::~PlaneFeed() = default;

void PlaneFeed::forward(const std::string& lcm_channel, const void* data, std::size_t size, std::int64_t recv_utime) {
  if (lcm_channel == state_channel_) {
    controller::TickRecord r{};
    if (!decode<pneu_lcm::state_t>(data, size, r)) return;
    if (!ticks_.empty() && r.t_s < ticks_.back().t_s) ticks_.clear();  // pneud restarted
    ticks_.push_back({r.t_s, r.y_m, r.p_p_pa, r.p_n_pa});
    while (ticks_.front().t_s < r.t_s - kTicksKept_s) ticks_.pop_front();
  } else if (lcm_channel == prediction_channel_) {
    controller::ForecastRecord made{};
    if (!decode<pneu_lcm::prediction_t>(data, size, made)) return;
    // The tick it was made from (the loop publishes the forecast after that tick's record).
    const Tick* from = nullptr;
    for (auto it = ticks_.rbegin(); it != ticks_.rend(); ++it) {
      if (it->t_s <= made.t_s + 1e-9) {
        from = &*it;
        break;
      }
    }
    if (from == nullptr || made.t_s - from->t_s > 0.01) return;  // not received: no path rather than a wrong one
    controller::StopSnapshot stop;
    stop.t_s = made.t_s;
    stop.y_m = from->y_m;
    stop.p_p_pa = from->p_p_pa;
    stop.p_n_pa = from->p_n_pa;
    stop.u_v = made.u_star_v;
    if (!controller::snapshot_is_finite(stop)) return;
    if (const auto path = plane_forecast(model_, stop, made))
      server_.publish(forecast_id_, static_cast<std::uint64_t>(recv_utime) * 1000U, to_json(*path));
  }
}

}  // namespace pneu::dash
