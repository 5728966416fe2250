// pneu-plant: the simulated bench. Open-loop runs, valve characterisation, the plant behind a
// Modbus server (serve.cpp, around pneu_plant_server) and the gain design on its tangent-linear
// model (tune.cpp).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iomanip>
#include <iostream>
#include <string>

#include "input_csv.hpp"
#include "serve.hpp"
#include "tune.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/model/pressure_force.hpp"
#include "pneu/model/valve_table.hpp"
#include "pneu/sim_plant/plant.hpp"
#include "pneu/sim_plant/sensors.hpp"

namespace {

using namespace pneu;

constexpr const char* kUsage = R"(pneu-plant: the simulated electropneumatic bench (Brun et al. 2005 model)

Usage:
  pneu-plant simulate [--config FILE] --input U.csv --out TRAJ.csv [--set KEY=VALUE ...] [--sensors] [--quiet]
  pneu-plant characterize-valve [--config FILE] --out TABLE.csv [--voltage-step-v V] [--pressure-step-pa P]
  pneu-plant null-flow [--config FILE] --out CURVE.csv [--voltage-step-v V]
  pneu-plant tune [--config FILE] [--set KEY=VALUE ...] [--step-mm N] [--map-only] [--delay-samples N]
                  [--csv MAP.csv]
  pneu-plant serve --config FILE [--set KEY=VALUE ...] [--duration S] [--outputs FILE] [--events FILE]
                   [--fault CHANNEL:MODE@T ...] [--reply-delay-s D [--delay-after-s T]] [--max-clients N]
                   [--watchdog-s S [--watchdog-outputs neutral|exhaust|U_P,U_N]] [--quiet]
  pneu-plant COMMAND -h | --help
  pneu-plant -h | --help | --version

Without --config the embedded default bench (config/sim.yaml) is used.
Exit codes: 0 success, 1 run failure, 2 bad command line, config or input (nothing written).
)";

constexpr const char* kSimulateHelp = R"(pneu-plant simulate: open-loop run of the plant model

  --config FILE     YAML configuration (default: the embedded config/sim.yaml)
  --input U.csv     valve voltage: header with columns t (s) and u (V), one row per sample, time
                    strictly increasing at a fixed sample rate. u is held between samples and drives
                    u_P = u, u_N = -u.
  --out TRAJ.csv    trajectory, one row per input sample, taken at the sample's time before its
                    input is applied: t (s), y (m, from mid-stroke), v (m/s), p_p, p_n (Pa abs),
                    force (N, Eq. 14), stuck (0/1), u (V, the input applied from t on)
  --sensors         add the sensor readings y_meas, p_p_meas, p_n_meas (sensor models of the config)
  --set KEY=VALUE   override a config key by its dotted path (repeatable)
  --quiet           no summary

The run starts at rest at simulation.initial_position_m with both pressures at the null-flow
pressures of the first sample, p_null(u) and p_null(-u). Prints a summary of the run.
)";

constexpr const char* kCharacterizeHelp = R"(pneu-plant characterize-valve: the valve's flow table q(w, p)

  --config FILE          YAML configuration (default: the embedded config/sim.yaml)
  --out TABLE.csv        the table ("pneu valve table v1", documented in its comment header):
                         voltage_v,pressure_pa,mass_flow_kg_per_s, one row per grid point
  --voltage-step-v V     voltage grid step (default 0.1 V); the grid runs from -u_max to +u_max
                         and always holds 0 and +-u_max
  --pressure-step-pa P   pressure grid step (default 2000 Pa); from p_E to p_S inclusive
  --set KEY=VALUE        override a config key (repeatable)

As a flow bench measures it (Fig. 12 of the paper): each chamber pressure held, the valve driven
at each voltage, the mass flow into the chamber recorded. The restart predictor loads this table
as the valve characteristic.
)";

constexpr const char* kNullFlowHelp = R"(pneu-plant null-flow: the complete-equilibrium curve (Fig. 6 and Fig. 7)

  --config FILE         YAML configuration (default: the embedded config/sim.yaml)
  --out CURVE.csv       u_v, p_null_p_pa = p_null(u), p_null_n_pa = p_null(-u), x_n = S_P p_null(u),
                        y_n = S_N p_null(-u) + S_r p_E, equilibrium_force_n = x - y (Eq. 7 / Eq. 14)
  --voltage-step-v V    voltage step (default 0.01 V), from -u_max to +u_max
  --set KEY=VALUE       override a config key (repeatable)

The null-flow curve in the pressure-force plane; with the stop and no-restarting areas of docs/model.md
section 5 it is what the pressure-force figure draws.
)";

const char* event_name(plant::PlantEvent::Kind k, int direction) {
  using K = plant::PlantEvent::Kind;
  switch (k) {
    case K::kBreakaway: return direction > 0 ? "breakaway +" : "breakaway -";
    case K::kStick: return "stick";
    case K::kReversal: return direction > 0 ? "reversal +" : "reversal -";
    case K::kEndStop: return direction > 0 ? "end stop +" : "end stop -";
  }
  return "?";
}

int simulate(int argc, char** argv) {
  const cli::Args args(argc, argv, 2, {"config", "input", "out"}, {"sensors", "quiet", "help"}, {"set"});
  if (args.flag("help")) {
    std::cout << kSimulateHelp;
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  const config::Config cfg = config::load_file_or_default(config_path, args.all("set"));
  const auto input = plant_app::read_input_csv(args.required("input"));
  const std::string out_path = args.required("out");
  const bool with_sensors = args.flag("sensors");

  const model::PlantParams& bench = config::simulated_bench(cfg);  // hal.sim.plant over plant:
  plant::Plant plant(bench);
  plant::SensorSuite sensors(cfg.sensors);
  plant.reset_at_rest(cfg.simulation.initial_position_m, input.u_v.front(), input.t_s.front());

  cli::OutputFile out(out_path, "--out");
  auto& os = out.stream();
  os << "t,y,v,p_p,p_n,force,stuck,u" << (with_sensors ? ",y_meas,p_p_meas,p_n_meas" : "") << '\n';
  os << std::setprecision(10);

  struct Stick { double start_s, end_s; };
  std::vector<plant::PlantEvent> events;
  std::vector<Stick> sticks;
  double stuck_since = plant.state().motion == plant::Motion::kStuck ? input.t_s.front() : NAN;
  double y_min = plant.state().y_m, y_max = y_min;
  const auto start_state = plant.state();

  const auto wall_start = std::chrono::steady_clock::now();
  std::chrono::steady_clock::duration plant_time{};
  const std::size_t n = input.t_s.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto& s = plant.state();
    const bool stuck = s.motion == plant::Motion::kStuck;
    os << input.t_s[i] << ',' << s.y_m << ',' << s.v_m_per_s << ',' << s.p_p_pa << ',' << s.p_n_pa
       << ',' << plant.pressure_force_n() << ',' << (stuck ? 1 : 0) << ',' << input.u_v[i];
    if (with_sensors) {
      const auto m = sensors.measure(s.y_m, s.p_p_pa, s.p_n_pa);
      os << ',' << m.y_m << ',' << m.p_p_pa << ',' << m.p_n_pa;
    }
    os << '\n';
    if (i + 1 == n) break;
    const auto t0 = std::chrono::steady_clock::now();
    plant::step_with_pushes(plant, input.t_s[i + 1], input.u_v[i], -input.u_v[i], cfg.hal.sim.pushes, [&](auto piece) {
      for (const auto& e : piece) {
        events.push_back(e);
        const bool now_stuck = e.kind == plant::PlantEvent::Kind::kStick ||
                               e.kind == plant::PlantEvent::Kind::kEndStop;
        if (now_stuck) stuck_since = e.t_s;
        if (e.kind == plant::PlantEvent::Kind::kBreakaway && !std::isnan(stuck_since)) {
          sticks.push_back({stuck_since, e.t_s});
          stuck_since = NAN;
        }
      }
    });
    plant_time += std::chrono::steady_clock::now() - t0;
    y_min = std::min(y_min, plant.state().y_m);
    y_max = std::max(y_max, plant.state().y_m);
  }
  out.commit();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  const double plant_s = std::chrono::duration<double>(plant_time).count();

  if (args.flag("quiet")) return cli::kExitOk;
  const double duration = input.t_s.back() - input.t_s.front();
  const auto& end = plant.state();
  std::printf("pneu-plant simulate: %zu samples over %.3f s, sample period %.4g ms (%s)\n", n,
              duration, input.period_s * 1e3, config_path.empty() ? "embedded sim.yaml" : config_path.c_str());
  std::printf("  start   y = %8.3f mm at rest, p_P = %.4f bar, p_N = %.4f bar, F = %7.2f N, u = %+.4f V\n",
              start_state.y_m * 1e3, start_state.p_p_pa * 1e-5, start_state.p_n_pa * 1e-5,
              model::PressureForce(bench.geometry, bench.gas.exhaust_pressure_pa)
                  .force_n(start_state.p_p_pa, start_state.p_n_pa),
              input.u_v.front());
  std::printf("  events  (stiction band [%.1f, %.1f] N)\n", bench.friction.static_negative_n,
              bench.friction.static_positive_n);
  constexpr std::size_t kShown = 24;
  for (std::size_t i = 0; i < events.size() && i < kShown; ++i) {
    const auto& e = events[i];
    std::printf("    t = %8.4f s  %-12s y = %8.3f mm  F = %8.2f N\n", e.t_s,
                event_name(e.kind, e.direction), e.y_m * 1e3, e.force_n);
  }
  if (events.size() > kShown) std::printf("    ... %zu more events\n", events.size() - kShown);
  if (!std::isnan(stuck_since)) sticks.push_back({stuck_since, NAN});
  std::size_t longest = sticks.size();
  for (std::size_t i = 0; i < sticks.size(); ++i) {
    const double d = (std::isnan(sticks[i].end_s) ? input.t_s.back() : sticks[i].end_s) - sticks[i].start_s;
    const double best = longest < sticks.size()
        ? (std::isnan(sticks[longest].end_s) ? input.t_s.back() : sticks[longest].end_s) - sticks[longest].start_s
        : -1.0;
    if (d > best) longest = i;
  }
  std::printf("  sticking phases: %zu", sticks.size());
  if (longest < sticks.size()) {
    const auto& s = sticks[longest];
    if (std::isnan(s.end_s))
      std::printf(" (longest: from %.4f s to the end of the run, %.3f s)", s.start_s, input.t_s.back() - s.start_s);
    else
      std::printf(" (longest: %.3f s, from %.4f s to the restart at %.4f s)", s.end_s - s.start_s, s.start_s, s.end_s);
  }
  std::printf("\n  end     y = %8.3f mm, v = %.4f m/s, p_P = %.4f bar, p_N = %.4f bar, F = %7.2f N, %s\n",
              end.y_m * 1e3, end.v_m_per_s, end.p_p_pa * 1e-5, end.p_n_pa * 1e-5,
              plant.pressure_force_n(), end.motion == plant::Motion::kStuck ? "stuck" : "sliding");
  std::printf("  travel  %.3f mm to %.3f mm\n", y_min * 1e3, y_max * 1e3);
  const auto& pp = plant.params();
  std::printf("  speed   plant %.1f ms for %.3f s simulated (%.0fx real time; RK4 steps from %.3g ms (the stiffest state) "
              "up to %.3g ms sliding, %.3g ms stuck; %llu rhs evaluations); whole run %.1f ms\n",
              plant_s * 1e3, duration, duration / plant_s, plant.step_size_s() * 1e3, pp.max_step_s * 1e3,
              pp.max_stuck_step_s * 1e3, static_cast<unsigned long long>(plant.rhs_evaluations()), wall_s * 1e3);
  std::printf("  wrote   %s (%zu rows)\n", out_path.c_str(), n);
  return cli::kExitOk;
}

std::vector<double> grid(double lo, double hi, double step, bool hold_zero) {
  std::vector<double> v;
  if (hold_zero) {  // symmetric grid through 0 with the ends at +-hi
    const auto k = static_cast<long>(std::floor(hi / step + 1e-9));
    v.push_back(lo);
    for (long i = -k; i <= k; ++i) {
      const double w = static_cast<double>(i) * step;
      if (w > v.back() + 1e-12 && w < hi - 1e-12) v.push_back(w);
    }
    v.push_back(hi);
    return v;
  }
  for (double x = lo; x < hi - 1e-9 * step; x += step) v.push_back(x);
  v.push_back(hi);
  return v;
}

// The voltage axis of --voltage-step-v (default `default_step_v`): -u_max .. u_max through 0.
std::vector<double> voltage_grid(const cli::Args& args, const config::Config& cfg, double default_step_v) {
  const double u_max = cfg.plant.valve.max_voltage_v;
  const double dw = args.number("voltage-step-v", default_step_v);
  if (!(dw > 0.0 && dw <= u_max)) throw cli::UsageError("--voltage-step-v must be in (0, u_max]");
  return grid(-u_max, u_max, dw, true);
}

int characterize(int argc, char** argv) {
  const cli::Args args(argc, argv, 2, {"config", "out", "voltage-step-v", "pressure-step-pa"}, {"help"},
                       {"set"});
  if (args.flag("help")) {
    std::cout << kCharacterizeHelp;
    return cli::kExitOk;
  }
  const config::Config cfg = config::load_file_or_default(args.value("config").value_or(""), args.all("set"));
  const std::string out_path = args.required("out");
  const std::vector<double> voltages = voltage_grid(args, cfg, 0.1);
  const double dp = args.number("pressure-step-pa", 2000.0);
  const double p_e = cfg.plant.gas.exhaust_pressure_pa, p_s = cfg.plant.gas.supply_pressure_pa;
  if (!(dp > 0.0 && dp <= p_s - p_e)) throw cli::UsageError("--pressure-step-pa must be in (0, p_S - p_E]");

  // The table measures the simulated bench's valve (hal.sim.plant over plant:); "model" is plant:'s.
  const model::ValveModel model(cfg.plant.valve, cfg.plant.gas);
  const model::PlantParams& bench = config::simulated_bench(cfg);
  const auto table = model::ValveTable::sample(model::ValveModel(bench.valve, bench.gas), voltages, grid(p_e, p_s, dp, false));
  cli::OutputFile out(out_path, "--out");
  table.write(out.stream());
  out.commit();

  const double ue_model = model::equilibrium_voltage_v(model, cfg.plant.geometry, p_e);
  const double ue_table = model::equilibrium_voltage_v(table, cfg.plant.geometry, p_e);
  std::printf("pneu-plant characterize-valve: %zu voltages x %zu pressures = %zu rows -> %s\n",
              table.voltages_v().size(), table.pressures_pa().size(),
              table.voltages_v().size() * table.pressures_pa().size(), out_path.c_str());
  std::printf("  p_null(0) = %.1f Pa (model %.1f Pa); u_e (Eq. 7) = %+.5f V (model %+.5f V)\n",
              table.null_pressure_pa(0.0), model.null_pressure_pa(0.0), ue_table, ue_model);
  return cli::kExitOk;
}

int null_flow(int argc, char** argv) {
  const cli::Args args(argc, argv, 2, {"config", "out", "voltage-step-v"}, {"help"}, {"set"});
  if (args.flag("help")) {
    std::cout << kNullFlowHelp;
    return cli::kExitOk;
  }
  const config::Config cfg = config::load_file_or_default(args.value("config").value_or(""), args.all("set"));
  const std::string out_path = args.required("out");
  const std::vector<double> voltages = voltage_grid(args, cfg, 0.01);
  const model::ValveModel valve(cfg.plant.valve, cfg.plant.gas);
  const model::PressureForce force(cfg.plant.geometry, cfg.plant.gas.exhaust_pressure_pa);
  cli::OutputFile out(out_path, "--out");
  auto& os = out.stream();
  os << "u_v,p_null_p_pa,p_null_n_pa,x_n,y_n,equilibrium_force_n\n" << std::setprecision(10);
  for (double w : voltages) {
    const double pp = valve.null_pressure_pa(w), pn = valve.null_pressure_pa(-w);
    const double x = force.plane_x_n(pp), y = force.plane_y_n(pn);
    os << w << ',' << pp << ',' << pn << ',' << x << ',' << y << ',' << x - y << '\n';
  }
  out.commit();
  return cli::kExitOk;
}

int dispatch(int argc, char** argv) {
  const std::string command = argc > 1 ? argv[1] : "";
  if (command == "simulate") return simulate(argc, argv);
  if (command == "characterize-valve") return characterize(argc, argv);
  if (command == "null-flow") return null_flow(argc, argv);
  if (command == "serve") return plant_app::serve(argc, argv);
  if (command == "tune") return plant_app::tune(argc, argv);
  if (command == "--version") {
    std::printf("pneu-plant %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  if (command == "--help" || command == "-h" || command == "help") {
    std::cout << kUsage;
    return cli::kExitOk;
  }
  std::cerr << (command.empty() ? std::string("pneu-plant: missing command")
                                : "pneu-plant: unknown command '" + command + "'")
            << "\n\n" << kUsage;
  return cli::kExitBadInput;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-plant", dispatch, argc, argv); }
