// What pneu-dash adds for its page (tools/dash/www): Debian's Chart.js served under /js/chart.js/,
// and the pressure-force plane's channels computed from the bench's model (pneu_dash_plane):
// <prefix>PLANE, latched, the stop and no-restarting areas and the null-flow curve; and
// <prefix>PLANE_FORECAST, each restart forecast's path through the plane, from the tick it was
// made from and the forecast's u*, as the predictor's own track follows it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>

#include "pneu/controller/predictor.hpp"
#include "pneu/dash/server.hpp"

namespace pneu::config {
struct Config;
}

namespace pneu::dash {

/// Serves the Chart.js of `chart_js_dir` (Debian's libjs-chart.js: /usr/share/javascript/chart.js)
/// at /js/chart.js/chart.min.js. Throws std::runtime_error, saying which package, when it is missing.
void serve_chart_js(Server& server, const std::filesystem::path& chart_js_dir);

/// The plane's channels. Give it every LCM message pneu-dash forwards (forward(), from one thread).
class PlaneFeed {
 public:
  /// `config`: pneud's configuration (the plant, the friction, the predictor's valve);
  /// `config_dir`: where a relative controller.predictor.valve_table is found.
  PlaneFeed(Server& server, const std::string& prefix, const config::Config& config,
            const std::filesystem::path& config_dir);
  ~PlaneFeed();
  PlaneFeed(const PlaneFeed&) = delete;
  PlaneFeed& operator=(const PlaneFeed&) = delete;

  void forward(const std::string& lcm_channel, const void* data, std::size_t size, std::int64_t recv_utime);

 private:
  struct Tick {
    double t_s, y_m, p_p_pa, p_n_pa;
  };
  Server& server_;
  std::string state_channel_, prediction_channel_;
  std::shared_ptr<const model::ValveCharacteristic> valve_;
  controller::PredictorModel model_;
  ChannelId forecast_id_ = 0;
  std::deque<Tick> ticks_;  // the last few seconds: the ticks forecasts are made from
};

}  // namespace pneu::dash
