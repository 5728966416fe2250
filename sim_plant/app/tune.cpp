// pneu-plant tune: the gains of Eq. 4 designed on the tangent-linear model, and the stability map of
// a law over the stroke, continuous and sampled as pneud runs it (docs/model.md, "The
// tangent-linear model and the design of the gains").
#include "tune.hpp"

#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/assembly/run_spec.hpp"
#include "pneu/model/tangent_linear.hpp"
#include "pneu/model/valve_table.hpp"

namespace pneu::plant_app {

namespace {

constexpr const char* kTuneHelp = R"(pneu-plant tune: gains of Eq. 4 by pole placement, and the stability map of a law

  --config FILE         YAML configuration (default: the embedded config/sim.yaml); the model is
                        plant: with the controller's valve characteristic (controller.predictor.
                        valve_table, or the model)
  --set KEY=VALUE       override a config key (repeatable), e.g.
                        controller.law.design.natural_frequency_rad_per_s=60
  --step-mm N           positions of the printed table and map, every N mm over the stroke
                        (default 25)
  --map-only            only the stability map of the configured law (controller.law.gains: fixed
                        gains, or the schedule designed from controller.law.design)
  --delay-samples N     whole periods of delay beyond the hold in the sampled loop (default 0:
                        pneud on the sim backend reads y at tick k and drives the valves with it
                        over [t_k, t_k+1); a module on a bus may add one or more)
  --csv FILE            the map, one row per law and position: law,y_m,position_gain_v_per_m,
                        velocity_gain_v_s_per_m,acceleration_gain_v_s2_per_m,force_gain_n_per_v_s,
                        stiffness_n_per_m,max_real_part_1_per_s,max_abs_z,gain_margin,
                        stable_continuous,stable_sampled,continuous_poles,sampled_poles (poles
                        "re+imj" joined by ';')

Without --map-only: designs gains at every position from controller.law.design (a real pole
alpha and a damped pair omega, zeta, on the third-order model: K_y = M alpha omega^2 / b,
K_v = (M (omega^2 + 2 zeta omega alpha) - k_s) / b, K_a = (M (alpha + 2 zeta omega) - sigma) / b)
and prints them, then the stability map of the configured law and, when that law is fixed, of
the designed schedule too. The map gives at each position the closed-loop poles of the
4th-order tangent-linear model with exact v and a (continuous: stable when every Re(s) < 0) and
of the sampled loop (period 1 / controller.rate_hz, zero-order hold, pneud's differentiator as
coded, the delay above: stable when every |z| < 1), and the sampled loop's gain margin: the
largest factor (in 2 % steps, up to 100) by which the three gains may grow together before it is
unstable ("-" when it is unstable already).
Exit codes: 0 done (whatever the map says), 2 bad command line or config, or a design refused
(a gain negative or beyond its limit: the position, the gain and why). A schedule unstable on
the sampled loop is mapped, with a note: pneud refuses it at start-up.
)";

std::string pole_text(std::complex<double> p) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g%+.6gj", p.real(), p.imag());
  return buf;
}

std::string poles_text(const std::vector<std::complex<double>>& poles) {
  std::string out;
  for (const auto& p : poles) out += (out.empty() ? "" : ";") + pole_text(p);
  return out;
}

struct MapRow {
  double y_m = 0.0;
  model::LawGains gains;
  model::ThirdOrderModel third_order;
  std::vector<std::complex<double>> continuous, sampled;
  /// The sampled loop stays stable with all three gains multiplied by up to this factor (checked
  /// on a grid of 2 % steps up to kMaxGainFactor); 0 when it is unstable as it is.
  double gain_margin = 0.0;
  [[nodiscard]] double max_re() const { return model::max_real_part(continuous); }
  [[nodiscard]] double max_z() const { return model::max_magnitude(sampled); }
};

constexpr double kMaxGainFactor = 100.0;

double sampled_gain_margin(const model::TangentLinearModel& m, const model::LawGains& g, const model::SampledLoop& loop) {
  double k = 1.0;
  if (!(model::max_magnitude(model::sampled_poles(m, g, loop)) < 1.0)) return 0.0;
  while (k < kMaxGainFactor) {
    const double next = k * 1.02;
    const model::LawGains scaled{g.position_gain_v_per_m * next, g.velocity_gain_v_s_per_m * next,
                                 g.acceleration_gain_v_s2_per_m * next};
    if (!(model::max_magnitude(model::sampled_poles(m, scaled, loop)) < 1.0)) return k;
    k = next;
  }
  return kMaxGainFactor;
}

std::vector<double> positions(const model::Geometry& g, double step_m) {
  std::vector<double> out;
  const auto n = static_cast<long>(std::floor(g.stroke_m / step_m + 1e-9));
  for (long i = 0; i <= n; ++i) out.push_back(-g.half_stroke_m() + static_cast<double>(i) * step_m);
  if (out.back() < g.half_stroke_m() - 1e-12) out.push_back(g.half_stroke_m());
  return out;
}

std::vector<MapRow> stability_map(const config::Config& cfg, const model::ValveCharacteristic& valve, double u_e,
                                  const controller::ControlLaw& law, const std::vector<double>& ys,
                                  const model::SampledLoop& loop) {
  std::vector<MapRow> rows;
  for (const double y : ys) {
    MapRow r;
    r.y_m = y;
    r.gains = law.gains_at(y);
    const model::TangentLinearModel m = model::tangent_linear_model(cfg.plant, valve, y, u_e);
    r.third_order = m.third_order;
    r.continuous = model::continuous_poles(m, r.gains);
    r.sampled = model::sampled_poles(m, r.gains, loop);
    r.gain_margin = sampled_gain_margin(m, r.gains, loop);
    rows.push_back(std::move(r));
  }
  return rows;
}

// "[-225, 225] mm" stretches of consecutive positions where `bad` holds, or "nowhere".
template <class Bad>
std::string stretches(const std::vector<MapRow>& rows, Bad&& bad) {
  std::string out;
  for (std::size_t i = 0; i < rows.size();) {
    if (!bad(rows[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j + 1 < rows.size() && bad(rows[j + 1])) ++j;
    char buf[64];
    std::snprintf(buf, sizeof buf, "[%.0f, %.0f] mm", rows[i].y_m * 1e3, rows[j].y_m * 1e3);
    out += (out.empty() ? "" : ", ") + std::string(buf);
    i = j + 1;
  }
  return out.empty() ? "nowhere" : out;
}

void print_map(const std::string& title, const std::vector<MapRow>& rows, const model::SampledLoop& loop) {
  std::printf("\nStability map: %s\n", title.c_str());
  std::printf("  %7s %9s %9s %9s | %10s %-44s | %9s %10s %7s  %s\n", "y [mm]", "K_y", "K_v", "K_a", "max Re(s)",
              "continuous poles [1/s]", "max |z|", "ln|z|/T", "margin", "stable");
  for (const MapRow& r : rows) {
    std::string poles;
    for (const auto& p : r.continuous) {
      char buf[40];
      if (p.imag() < 0.0) continue;  // a pair once
      if (p.imag() > 0.0) std::snprintf(buf, sizeof buf, "%.1f+-%.1fj ", p.real(), p.imag());
      else std::snprintf(buf, sizeof buf, "%.1f ", p.real());
      poles += buf;
    }
    const bool c = r.max_re() < 0.0, s = r.max_z() < 1.0;
    char margin[16];
    if (r.gain_margin >= kMaxGainFactor) std::snprintf(margin, sizeof margin, ">%.0f", kMaxGainFactor);
    else if (r.gain_margin > 0.0) std::snprintf(margin, sizeof margin, "%.2f", r.gain_margin);
    else std::snprintf(margin, sizeof margin, "-");
    std::printf("  %7.1f %9.4g %9.4g %9.4g | %10.3f %-44s | %9.6f %10.3f %7s  %s\n", r.y_m * 1e3,
                r.gains.position_gain_v_per_m, r.gains.velocity_gain_v_s_per_m, r.gains.acceleration_gain_v_s2_per_m,
                r.max_re(), poles.c_str(), r.max_z(), std::log(r.max_z()) / loop.period_s, margin,
                c && s ? "yes" : !c && !s ? "NO" : c ? "NO (sampled)" : "NO (continuous)");
  }
  double worst_re = -HUGE_VAL, worst_z = 0.0, least_margin = HUGE_VAL;
  for (const MapRow& r : rows) {
    worst_re = std::max(worst_re, r.max_re());
    worst_z = std::max(worst_z, r.max_z());
    least_margin = std::min(least_margin, r.gain_margin);
  }
  std::printf("  worst: max Re(s) %.3f 1/s, max |z| %.6f (ln|z|/T %.3f 1/s), least sampled gain margin %s\n", worst_re,
              worst_z, std::log(worst_z) / loop.period_s,
              least_margin > 0.0 ? ("x" + std::to_string(least_margin).substr(0, 4)).c_str() : "none (unstable)");
  std::printf("  unstable, continuous: %s; sampled: %s\n",
              stretches(rows, [](const MapRow& r) { return !(r.max_re() < 0.0); }).c_str(),
              stretches(rows, [](const MapRow& r) { return !(r.max_z() < 1.0); }).c_str());
}

void write_csv(std::ostream& os, const std::string& law, const std::vector<MapRow>& rows) {
  char buf[512];
  for (const MapRow& r : rows) {
    std::snprintf(buf, sizeof buf, "%s,%.6g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.12g,%.4g,%d,%d,", law.c_str(), r.y_m,
                  r.gains.position_gain_v_per_m, r.gains.velocity_gain_v_s_per_m, r.gains.acceleration_gain_v_s2_per_m,
                  r.third_order.force_gain_n_per_v_s, r.third_order.stiffness_n_per_m, r.max_re(), r.max_z(),
                  r.gain_margin, r.max_re() < 0.0 ? 1 : 0, r.max_z() < 1.0 ? 1 : 0);
    os << buf << poles_text(r.continuous) << ',' << poles_text(r.sampled) << '\n';
  }
}

std::string fixed_title(const config::ControlLawParams& p) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "fixed gains K_y %g V/m, K_v %g V/(m/s), K_a %g V/(m/s^2)", p.position_gain_v_per_m,
                p.velocity_gain_v_s_per_m, p.acceleration_gain_v_s2_per_m);
  return buf;
}

std::string scheduled_title(const config::GainDesignParams& d) {
  char buf[200];
  std::snprintf(buf, sizeof buf,
                "gains scheduled by position, designed for alpha %g 1/s, omega %g rad/s, zeta %g (nodes every %g mm)",
                d.real_pole_1_per_s, d.natural_frequency_rad_per_s, d.damping, d.node_spacing_m * 1e3);
  return buf;
}

}  // namespace

int tune(int argc, char** argv) {
  const cli::Args args(argc, argv, 2, {"config", "step-mm", "delay-samples", "csv"}, {"map-only", "help"}, {"set"});
  if (args.flag("help")) {
    std::cout << kTuneHelp;
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  const config::Config loaded = config::load_file_or_default(config_path, args.all("set"));
  const double step_mm = args.number("step-mm", 25.0);
  if (!(step_mm >= 0.1 && step_mm <= loaded.plant.geometry.stroke_m * 1e3))
    throw cli::UsageError("--step-mm must be in [0.1, the stroke in mm]");
  const double delay = args.number("delay-samples", 0.0);
  if (!(delay >= 0.0 && delay <= 10.0 && delay == std::floor(delay)))
    throw cli::UsageError("--delay-samples must be a whole number in [0, 10]");
  const bool map_only = args.flag("map-only");

  // Every design first: a refusal prints nothing else. Falling back (controller.law.design.infeasible
  // fall_back), the design is pneud's, the sampled loop with --delay-samples checked; refusing, a
  // schedule the sampled loop cannot follow is not refused here (pneud refuses it): the map shows where.
  const bool falls_back = loaded.controller.law.design.infeasible == config::InfeasibleDesign::kFallBack;
  const assembly::RunSpec spec = assembly::RunSpec::of(
      loaded, {config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path(),
               falls_back, static_cast<int>(delay)});
  const config::Config& cfg = spec.config();
  const model::ValveCharacteristic& valve = spec.valve();
  const double u_e = spec.equilibrium_voltage_v();
  const model::SampledLoop loop{cfg.controller.period_s(), cfg.controller.differentiator.smoothing,
                                static_cast<int>(delay)};
  const std::vector<double> ys = positions(cfg.plant.geometry, step_mm * 1e-3);
  const auto& law = cfg.controller.law;
  const bool fixed = law.gains == config::GainsKind::kFixed;
  const controller::ControlLaw& configured = spec.law();
  std::vector<model::DesignFallback> fallbacks = spec.fallbacks();
  std::optional<controller::ControlLaw> designed;
  if (!map_only) {
    assembly::RunSpec::Scheduled scheduled = spec.scheduled_design();
    designed = std::move(scheduled.law);
    fallbacks = std::move(scheduled.fallbacks);
  }

  std::printf("pneu-plant tune: %s\n", config_path.empty() ? "embedded sim.yaml" : config_path.c_str());
  std::printf("  tangent-linear model around u_e = %.6f V (Eq. 7; u_0 = %.6f V), M %g kg, sigma %g N s/m\n", u_e,
              law.offset_v, cfg.plant.mass_kg, cfg.plant.friction.viscous_n_s_per_m);
  std::printf("  sampled loop: T %g s, differentiator smoothing %g, delay %d sample(s) beyond the hold\n",
              loop.period_s, loop.smoothing, loop.delay_samples);

  if (designed) {
    const auto& d = law.design;
    std::printf("\nDesigned gains: %s; limits K_y %g V/m, K_v %g V/(m/s), K_a %g V/(m/s^2)\n",
                scheduled_title(d).c_str(), d.max_position_gain_v_per_m, d.max_velocity_gain_v_s_per_m,
                d.max_acceleration_gain_v_s2_per_m);
    std::printf("  %7s %12s %10s | %9s %9s %9s\n", "y [mm]", "b [N/(V s)]", "k_s [N/m]", "K_y", "K_v", "K_a");
    for (const double y : ys) {
      const auto t = model::tangent_linear_model(cfg.plant, valve, y, u_e).third_order;
      const model::LawGains g = designed->gains_at(y);
      std::printf("  %7.1f %12.5g %10.5g | %9.5g %9.5g %9.5g\n", y * 1e3, t.force_gain_n_per_v_s, t.stiffness_n_per_m,
                  g.position_gain_v_per_m, g.velocity_gain_v_s_per_m, g.acceleration_gain_v_s2_per_m);
    }
    if (!fallbacks.empty())
      std::printf("  the requested dynamics cannot be had everywhere: the gains fall back (controller.law.design."
                  "infeasible: fall_back)\n  %s\n",
                  model::describe_fallbacks(fallbacks, cfg.controller.law.design.node_spacing_m).c_str());
  }

  const std::vector<MapRow> configured_map = stability_map(cfg, valve, u_e, configured, ys, loop);
  print_map("the configured law, " + (fixed ? fixed_title(law) : scheduled_title(law.design)), configured_map, loop);
  std::vector<MapRow> designed_map;
  if (designed && fixed) {
    designed_map = stability_map(cfg, valve, u_e, *designed, ys, loop);
    print_map(scheduled_title(law.design), designed_map, loop);
  }

  const auto sampled_unstable = [](const std::vector<MapRow>& map) {
    for (const MapRow& r : map)
      if (!(r.max_z() < 1.0)) return true;
    return false;
  };
  if (sampled_unstable(fixed ? designed_map : configured_map))
    std::printf("\nnote: the designed schedule is unstable on the sampled loop: pneud refuses it (ask for slower "
                "poles, or a higher controller.rate_hz)\n");

  if (const auto csv = args.value("csv")) {
    cli::OutputFile out(*csv, "--csv");
    auto& os = out.stream();
    os << "law,y_m,position_gain_v_per_m,velocity_gain_v_s_per_m,acceleration_gain_v_s2_per_m,force_gain_n_per_v_s,"
          "stiffness_n_per_m,max_real_part_1_per_s,max_abs_z,gain_margin,stable_continuous,stable_sampled,continuous_poles,"
          "sampled_poles\n";
    write_csv(os, fixed ? "fixed" : "scheduled", configured_map);
    if (!designed_map.empty()) write_csv(os, "scheduled", designed_map);
    out.commit();
    std::printf("\nmap -> %s\n", csv->c_str());
  }
  return cli::kExitOk;
}

}  // namespace pneu::plant_app
