#include "pneu/identify/identification_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/yaml_text.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <map>
#include <memory>
#include <stdexcept>
#include <utility>

#include "pneu/controller/clock.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/assembly/assembled_run.hpp"
#include "pneu/controller/supervisor.hpp"

namespace pneu::identify {

controller::ControlLaw identification_law(const assembly::RunSpec& spec) {
  return spec.scheduled_design().law;
}

RunPlan plan_run(const config::Config& cfg, const controller::ControlLaw& law, const model::ValveCharacteristic& valve,
                 double start_m, const PlanOptions& o) {
  const auto& c = cfg.controller;
  const double lo = c.soft_limit_min_m + o.margin_m, hi = c.soft_limit_max_m - o.margin_m;
  if (!(hi - lo > 0.05))
    throw std::invalid_argument("the soft limits leave under 50 mm inside a margin of " + std::to_string(o.margin_m) +
                                " m: no room for the identification run");
  // The force the ramps must reach either way, and the voltage that moves the equilibrium force
  // that much (F_e(u) of the prior, about u_0).
  const model::PlantParams& p = cfg.plant;
  const double band_n = p.friction.static_positive_n - p.friction.static_negative_n;
  const double u0 = c.law.offset_v;
  constexpr double kDu = 0.02;
  const model::ChamberProcess process(p);
  const double slope_n_per_v =
      (model::equilibrium_force_n(valve, process, u0 + kDu, 0.0) - model::equilibrium_force_n(valve, process, u0 - kDu, 0.0)) /
      (2 * kDu);
  if (!(slope_n_per_v > 0)) throw std::invalid_argument("the valve model's equilibrium force does not grow with u");
  const double reach_v = o.force_reach * band_n / slope_n_per_v;

  RunPlan plan;
  plan.initial_setpoint_m = start_m;
  plan.positions_m = {lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo), lo + 0.5 * (hi - lo)};
  double t = 0.2;
  for (const double y : plan.positions_m) {
    plan.phases.push_back({t, y, false});
    plan.schedule.push_back({t, y});
    t += o.settle_s;
    plan.phases.push_back({t, y, true});
    const double k_y = law.gains_at(y).position_gain_v_per_m;
    if (!(k_y > 0)) throw std::invalid_argument("the law has no position gain at " + std::to_string(y) + " m");
    const double reach_m = reach_v / k_y;
    // Up, down, back: set points from y to y + reach, to y - reach, to y, in steps.
    const double legs[][2] = {{0.0, 1.0}, {1.0, -1.0}, {-1.0, 0.0}};
    const double lengths[] = {1.0, 2.0, 1.0};
    for (int leg = 0; leg < 3; ++leg) {
      const int steps = std::max(1, static_cast<int>(std::lround(lengths[leg] * o.ramp_s / o.step_s)));
      for (int i = 1; i <= steps; ++i) {
        const double f = legs[leg][0] + (legs[leg][1] - legs[leg][0]) * i / steps;
        plan.schedule.push_back({t + i * o.step_s, std::clamp(y + f * reach_m, c.soft_limit_min_m, c.soft_limit_max_m)});
      }
      t += steps * o.step_s;
    }
    t += 0.2;
  }
  plan.duration_s = t + 0.3;
  return plan;
}

Sample sample_of(const controller::TickRecord& r) noexcept {
  return {r.t_s, r.y_m, r.p_p_pa, r.p_n_pa, r.u_v, controller::drives(r.mode), r.u_n_v};
}

void Recorder::on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) {
  samples_.push_back(sample_of(tick));
}

void Progress::on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) {
  // At each phase's start, and every tenth of the run in between.
  const bool phase_starts = next_ < plan_.phases.size() && tick.t_s + 1e-9 >= plan_.phases[next_].t_s;
  if (!phase_starts && tick.t_s < next_tenth_ * 0.1 * plan_.duration_s) return;
  if (phase_starts) ++next_;
  next_tenth_ = std::floor(10.0 * tick.t_s / plan_.duration_s) + 1.0;
  if (next_ == 0) return;
  const RunPlan::Phase& p = plan_.phases[next_ - 1];
  const std::size_t n = plan_.positions_m.size();
  std::fprintf(out_, "pneud: identification: %3.0f %% (%.1f of %.1f s): %s %.1f mm (position %zu of %zu)\n",
               100.0 * tick.t_s / plan_.duration_s, tick.t_s, plan_.duration_s,
               p.ramp ? "ramping the set point about" : "moving to and settling at", p.position_m * 1e3,
               (next_ + 1) / 2, n);
  std::fflush(out_);
}

void Recorder::on_event(const controller::LoopEvent& e) {
  if (e.kind != controller::LoopEvent::Kind::kFault || !fault_.empty()) return;
  fault_ = std::string(controller::fault_name(e.fault_cause)) + " (" + controller::fault_text(e.fault_cause) + ")";
  if (e.fault_key != nullptr)
    fault_ += std::string("; decided by ") + e.fault_key + ": relaxing it: " + controller::relaxing_costs(e.fault_key);
  fault_t_s_ = e.t_s;
  stop_.store(true);
}

config::Config configured_for(config::Config cfg, const RunPlan& plan) {
  cfg.controller.initial_setpoint_m = plan.initial_setpoint_m;
  cfg.controller.schedule = plan.schedule;
  cfg.controller.duration_s = plan.duration_s;
  cfg.controller.start_armed = true;
  // Without the in-position hold: the plan's ramps are to carry the pressure force across the
  // stiction band, again and again, where the hold would drive it to the band's middle (and end
  // and begin again at every 10 ms step of the set point). The written file keeps it as it was.
  cfg.controller.hold.enabled = false;
  return cfg;
}

assembly::RunSpec configured_for(const assembly::RunSpec& spec, const RunPlan& plan, controller::ControlLaw law) {
  return spec.reconfigured([&](config::Config& c) { c = configured_for(std::move(c), plan); }).with_law(std::move(law));
}

RecordedRun record_run(const assembly::RunSpec& spec, const model::PlantParams& bench, double start_m) {
  RecordedRun r;
  r.plan = plan_run(spec.config(), spec.law(), spec.valve(), start_m);
  std::unique_ptr<hal::SimBackend> backend = assembly::simulated_bench(spec, bench);
  const assembly::RunSpec planned = configured_for(spec, r.plan, spec.law()).reconfigured(
      [](config::Config& c) { c.controller.clock = config::ClockKind::kSimulated; });
  // What is recorded is the loop's ticks and events: no forecast is read here, so the runtime
  // makes none (under the in-position hold, forecasting every update period took half the run's
  // time). The loop, and so the record, is the same.
  assembly::AssembledRun run(planned, std::move(backend), {.forecasts = false});
  std::atomic<bool> stop{false};
  const Recorder& recorder = run.emplace_sink<Recorder>(stop);
  controller::SimulatedClock clock;
  run.execute(clock, stop);
  r.samples = recorder.samples();
  r.fault = recorder.fault();
  r.fault_t_s = recorder.fault_time_s();
  return r;
}

Identification identify_by_run(const assembly::RunSpec& spec, const model::PlantParams& bench, double start_m) {
  const RecordedRun r = record_run(spec, bench, start_m);
  if (!r.fault.empty())
    throw std::runtime_error("the identification run faulted at t = " + std::to_string(r.fault_t_s) + " s: " + r.fault);
  const config::Config& config = spec.config();
  Options o = options_for(config);
  // A simulated bench in process has no bus between the command and its valves: the delay is 0,
  // known, not searched for (searching tried 1 sample too, a whole second fit, more than half of
  // the identification's time on a thermal bench; the search is for a record over Modbus).
  if (config.hal.backend == config::BackendKind::kSim) o.command_delay_samples = 0;
  return identify(r.samples, config.plant, o);
}

namespace {

// The backend a configuration runs on, and its clock: "the sim backend (the in-process simulated
// bench), simulated clock", "the modbus backend (tcp 192.168.1.10:502), real clock".
std::string bench_of(const config::Config& c) {
  std::string text;
  if (c.hal.backend == config::BackendKind::kModbus) {
    const config::ModbusConfig& m = c.hal.modbus;
    text = m.transport == config::ModbusTransport::kTcp ? "the modbus backend (tcp " + m.host + ":" + std::to_string(m.port) + ")"
                                                        : "the modbus backend (rtu " + m.device + ")";
  } else {
    text = "the sim backend (the in-process simulated bench)";
  }
  return text + (c.controller.clock == config::ClockKind::kReal ? ", real clock" : ", simulated clock");
}

// The day (2026-11-28) and the minute (2026-11-28 08:31 UTC) of `when`, in UTC.
std::string utc(std::time_t when, bool with_time) {
  std::tm tm{};
  gmtime_r(&when, &tm);
  char text[64];
  const std::size_t n = with_time ? std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &tm)
                                  : std::strftime(text, sizeof text, "%Y-%m-%d", &tm);
  return std::string(text, n);
}

// `text` without the header of an earlier identification (up to kEndOfIdentifiedHeader's line).
std::string_view without_earlier_header(std::string_view text) {
  if (!text.starts_with("# identified ")) return text;
  const std::string end = std::string("\n") + kEndOfIdentifiedHeader;
  const std::size_t at = text.find(end);
  if (at == std::string_view::npos) return text;
  const std::size_t next = text.find('\n', at + end.size());
  return next == std::string_view::npos ? std::string_view() : text.substr(next + 1);
}

}  // namespace

IdentifiedYaml identified_config_yaml(std::string_view source_text, const config::Config& config, const Identification& id,
                                      const Provenance& from) {
  config::Config out = config;
  out.plant = id.plant;
  // How well the model fitted: forecasts made on a misfit say they are uncertain.
  if (id.evidence.fitted_phases > 0) {
    out.controller.predictor.has_model_fit = true;
    out.controller.predictor.model_fit = {id.evidence.pressure_rms_residual_pa, id.evidence.pressure_explained_pa};
  }
  // A simulated bench that was its model stays what it was: the run identified it, it did not change.
  const bool bench_kept = config.hal.backend == config::BackendKind::kSim && !config.hal.sim.has_plant;
  if (bench_kept) {
    out.hal.has_sim = out.hal.sim.has_plant = true;
    out.hal.sim.plant = config.plant;
  }
  const std::string day = utc(from.when, false);
  // The notes beside the values written: each identified one with its sigma and what it was.
  std::vector<std::string> identified;
  std::map<std::string, std::string> notes;
  char line[256];
  for (const Estimate& e : id.estimates) {
    if (!e.identified) continue;
    identified.push_back(e.key);
    std::snprintf(line, sizeof line, "identified %s: %.6g +- %.2g (was %.6g)", day.c_str(), e.value, e.std, e.prior);
    notes[e.key] = line;
  }
  const config::NoteOf note_of = [&](const std::string& path, const std::string& was) -> std::string {
    if (const auto n = notes.find(path); n != notes.end()) return n->second;
    if (path.starts_with("hal.sim.")) return "";  // the bench the run ran on (the header says so)
    if (path.starts_with("controller.predictor.model_fit."))
      return "identified " + day + ": how well plant: fits" + (was.empty() ? "" : " (was " + was + ")");
    return "identified " + day + ": as the run had it (--set)" + (was.empty() ? "" : ", was " + was);
  };
  IdentifiedYaml result;
  const std::string_view source = without_earlier_header(source_text);
  const std::string origin = from.source.empty() ? "the embedded sim.yaml" : from.source;
  std::string body;
  try {
    body = config::with_values_of(source, out, identified, note_of, origin);
  } catch (const config::ConfigError& e) {
    (void)config::load_string(config::to_yaml(out), {}, "the identified configuration");  // a rule broken is refused here
    result.text_not_kept = std::string(e.what());
    body = config::to_yaml(out);
  }
  // The header: when, by what, from which record on which bench, the fit, what the file is.
  std::string h = "# identified " + utc(from.when, true) + " by " + from.program + ": " + from.command +
                  "\n# from " + from.record + ", on " + bench_of(config) + "\n# the fit: " + fit_verdict(id.evidence) +
                  "\n";
  if (result.text_not_kept.empty())
    h += "# below: " + origin + " as it was, its comments kept; each value identified replaced in place with its 1-sigma "
         "uncertainty and the value it replaced beside it (# identified " + day + ": value +- sigma (was ...))\n";
  else
    h += "# below: the whole configuration, as pneud writes it: the text of " + origin + " could not be kept (" +
         result.text_not_kept + ")\n";
  std::string kept;
  for (const Estimate& e : id.estimates)
    if (!e.identified) kept += (kept.empty() ? "" : "; ") + e.key + " (" + e.basis + ")";
  if (!kept.empty()) h += "# not identified, kept: " + kept + "\n";
  if (bench_kept)
    h += "# hal.sim.plant: the simulated bench the run identified, plant: as it was, so that this file runs the same "
         "bench\n";
  else if (config.hal.backend == config::BackendKind::kSim)
    h += "# hal.sim.plant: the simulated bench the run identified, as the run had it\n";
  h += std::string(kEndOfIdentifiedHeader) + "\n";
  result.text = h + body;
  (void)config::load_string(result.text, {}, "the identified configuration");  // a rule broken is refused here
  return result;
}

std::string fit_verdict(const Evidence& e) {
  char line[256];
  if (e.model_fits) {
    std::snprintf(line, sizeof line,
                  "the model fits the stuck phases' pressures: %.1f Pa rms, within twice what the sensors' noise explains "
                  "(%.1f Pa)",
                  e.pressure_rms_residual_pa, e.pressure_explained_pa);
    std::string text = line;
    if (!e.left_out.empty()) {
      std::snprintf(line, sizeof line, "; %zu phase%s left out, beyond three times it where the %d others fit:",
                    e.left_out.size(), e.left_out.size() == 1 ? "" : "s", e.fitted_phases);
      text += line;
      for (std::size_t i = 0; i < e.left_out.size(); ++i) {
        std::snprintf(line, sizeof line, "%s t = %.2f s at %.0f mm, %.0f Pa", i > 0 ? ";" : "", e.left_out[i].t_s,
                      e.left_out[i].y_m * 1e3, e.left_out[i].rms_pa);
        text += line;
      }
      text += " (a disturbance the model does not have: a knock on the carriage, a glitch, a link that stalled? "
              "the record shows it there)";
    }
    return text;
  }
  std::snprintf(line, sizeof line,
                "THE MODEL DOES NOT FIT the stuck phases' pressures: %.0f Pa rms, %.0f times what the sensors' noise "
                "explains (%.1f Pa); %zu of %d phases beyond three times it",
                e.pressure_rms_residual_pa, e.pressure_rms_residual_pa / e.pressure_explained_pa, e.pressure_explained_pa,
                e.misfit.size(), e.misfit_phases_of);
  std::string text = line;
  std::vector<Evidence::PhaseMisfit> worst = e.misfit;
  std::sort(worst.begin(), worst.end(), [](const auto& a, const auto& b) { return a.rms_pa > b.rms_pa; });
  text += ", the worst:";
  for (std::size_t i = 0; i < worst.size() && i < 5; ++i) {
    std::snprintf(line, sizeof line, "%s t = %.2f s at %.0f mm, %.0f Pa", i > 0 ? ";" : "", worst[i].t_s,
                  worst[i].y_m * 1e3, worst[i].rms_pa);
    text += line;
  }
  text += ". Its valve, volume and thermal parameters' sigmas carry the misfit (each phase counted as one "
          "sample): a physics the model lacks? (plant.thermal, plant.valve.spool_time_constant_s)";
  if (e.fitted_deadlines_skipped > 0) {
    std::snprintf(line, sizeof line,
                  " Or the commands' timing: the loop skipped %d deadlines within these phases (of %d samples), each "
                  "shifting when a command reached the valves (controller.realtime, a real-time kernel)",
                  e.fitted_deadlines_skipped, e.fitted_samples);
    text += line;
  }
  return text;
}

void print_report(std::FILE* out, const Identification& id) {
  std::fprintf(out, "%-46s %12s %12s %10s  %s\n", "parameter", "before", "after", "+- 1 sigma", "from");
  for (const Estimate& x : id.estimates) {
    if (x.identified)
      std::fprintf(out, "%-46s %12.5g %12.5g %10.2g  %s\n", x.key.c_str(), x.prior, x.value, x.std, x.basis.c_str());
    else
      std::fprintf(out, "%-46s %12.5g %12s %10s  %s\n", x.key.c_str(), x.prior, "(kept)", "", x.basis.c_str());
  }
  const Evidence& e = id.evidence;
  std::fprintf(out,
               "evidence: %d stuck phases (%d fitted, %.1f s stuck, over %.0f mm, u over %.3f V), breakaways %d "
               "positive / %d negative, %.2f s sliding; pressure fit residual %.1f Pa rms, the valves acting %d samples "
               "after the command's record\n",
               e.stuck_phases, e.fitted_phases, e.stuck_s, e.stuck_position_span_m * 1e3, e.voltage_span_v,
               e.breakaways_positive, e.breakaways_negative, e.sliding_s, e.pressure_rms_residual_pa,
               e.command_delay_samples);
  if (e.fitted_deadlines_skipped > 0)
    std::fprintf(out, "timing: the loop skipped %d deadlines within the fitted phases (of %d samples)\n",
                 e.fitted_deadlines_skipped, e.fitted_samples);
  if (e.fitted_phases > 0) std::fprintf(out, "fit: %s\n", fit_verdict(e).c_str());
}

Options options_for(const config::Config& cfg) {
  Options o;
  o.rest_band_m = cfg.controller.stop_detector.rest_band_m;
  return o;
}

}  // namespace pneu::identify
