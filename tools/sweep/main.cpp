// pneu-sweep: runs many set-point steps across the stroke in simulated time, in parallel, and
// judges every restart forecast against what the simulated bench did.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <random>
#include <span>
#include <stdexcept>
#include <thread>
#include <vector>

#include "pneu/backends/factory.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/controller/verdict.hpp"

namespace {

using namespace pneu;
using controller::Verdict;

constexpr const char* kHelp = R"(pneu-sweep: the restart predictor against many simulated set-point steps

Usage:
  pneu-sweep [--config FILE] --out SWEEP.csv [--steps N] [--seed S] [--jobs J] [--duration S]
             [--step-time S] [--tail S] [--margin-m M] [--min-step-m D] [--friction-spread F] [--gain-spread G]
             [--set KEY=VALUE ...] [--supervised] [--strict] [--quiet]

Scenario i starts at rest at a random position y0 and steps the set point at --step-time
(default 1 s) to y_d, the targets spread evenly over the stroke less --margin-m (default 0.02 m)
at each end, |y_d - y0| >= --min-step-m (default 0.005 m). --friction-spread F scales all friction
values of a scenario by a factor drawn in [1-F, 1+F], --gain-spread G the three gains likewise
(default 0: the config's values). Each scenario runs --duration seconds (default 12) in simulated
time, then --tail seconds more (default 1) in which no new stop is judged: a restart forecast just
before the end of the window is then seen or refuted by the signals rather than cut off (a
breakaway with a force a hair beyond stiction moves the carriage by less than the detector's
motion band for tens of milliseconds). --jobs threads (default: the cores) share the scenarios.

The sweep studies the control law and the forecast, not the bench's protection: unless
--supervised, the supervisor's motion and range checks are off (large steps slam the carriage
into an end stop and push a chamber past the pressure sensor's range, which pneud would rightly
latch as faults and so end the scenario), and so are its settling rules (oscillation, settle
time: controller.supervisor.oscillation_* and settle_time_s), so that every scenario runs its
whole duration and every stop counts in the forecast figures.

Stops are those pneud's stop detector sees; what happened after each is the simulated truth: the
plant's first breakaway after the forecast was made is the restart, timed exactly, even when it
moves the carriage less than the detector's motion band (a set-point change before it ends the
stop unjudged). With noisy sensors (e.g. --config config/hil.yaml --set hal.backend=sim) the
detector may confirm a stop while the plant still slides within its rest band: counted, not
judged (outcome plant_not_at_rest). SWEEP.csv has one row per stop: the scenario, the stop, what happened, and each
method's forecast with its verdict and error. The summary gives the confusion matrix of restart / no restart and the
error percentiles per method. Acceptance: restarts after >= 0.5 s of sticking within 1 % of the
sticking time (nonlinear) and 5 % (linearized), shorter ones within 10 ms; --strict exits 1 when
any forecast misses it. For those restarts the summary and the *_halfway_error_percent columns
also give the error of the live predictor: the forecast made again (every
controller.predictor.update_period_s) from the last pressures before half the sticking time, in %
of the whole sticking time; it is not judged.
)";

struct Scenario {
  int index = 0;
  double y0_m = 0.0, y_d_m = 0.0, friction_scale = 1.0, gain_scale = 1.0;
};

struct Truth {
  bool unseen = false;       // a true restart the stop detector did not see
  bool not_at_rest = false;  // the plant was sliding when the stop was confirmed: not judged
};

struct ScenarioResult {
  Scenario scenario;
  std::vector<controller::StopOutcome> stops;
  std::vector<Truth> truth;  // per stop
  double t_end_s = 0.0;
};

// What happened, by the simulated truth: the plant's first breakaway after the forecast was made
// (the stop's confirmation) is the restart. The stop detector sees a start only once the carriage
// has moved beyond its motion band; a breakaway under a force a hair beyond stiction can move it
// less than that before the pneumatic stiffness stops it again, a restart all the same. With
// noisy sensors the detector can also confirm a stop while the plant still slides slowly within
// its rest band: a forecast made then assumed a rest that was not there, and is not judged.
// Stops ended by a set-point change keep that outcome.
Truth apply_plant_truth(controller::StopOutcome& s, std::span<const plant::PlantEvent> events, double run_end_s,
                        double period_s) {
  using Kind = plant::PlantEvent::Kind;
  Truth truth;
  if (s.ended && !s.restarted) return truth;
  bool at_rest = true;  // runs start at rest
  for (const auto& e : events) {
    if (e.t_s > s.snapshot.t_s) break;
    at_rest = e.kind != Kind::kBreakaway;
  }
  if (!at_rest) {
    truth.not_at_rest = true;
    return truth;
  }
  // The detector dates a start midway between the last sample at rest and the first that moved:
  // the breakaway may lie up to a period after that.
  const double limit_s = s.ended ? s.t_end_s + period_s : run_end_s;
  for (const auto& e : events) {
    if (e.kind != Kind::kBreakaway || e.t_s <= s.snapshot.t_s) continue;
    if (e.t_s > limit_s) break;
    truth.unseen = !s.ended;
    s.ended = s.restarted = true;
    s.t_end_s = e.t_s;
    s.direction = e.direction;
    return truth;
  }
  return truth;
}

struct MethodStats {
  std::uint64_t tp = 0, tn = 0, fp = 0, fn = 0, not_judged = 0, wrong_direction = 0, misses = 0;
  std::vector<double> long_error_pct;  // sticking >= 0.5 s
  std::vector<double> short_error_ms;  // shorter
  std::vector<double> halfway_error_pct;  // sticking >= 0.5 s: the forecast made again half-way
};

constexpr double kLongSticking_s = 0.5;
// The CSV's and the summary's order: lin, nl.
constexpr controller::PredictionMethod kMethods[2] = {controller::PredictionMethod::kLinearized,
                                                      controller::PredictionMethod::kNonlinear};

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

const char* verdict_name(Verdict::Kind k) {
  switch (k) {
    case Verdict::Kind::kTruePositive: return "true_restart";
    case Verdict::Kind::kTrueNegative: return "true_no_restart";
    case Verdict::Kind::kFalsePositive: return "false_restart";
    case Verdict::Kind::kFalseNegative: return "missed_restart";
    case Verdict::Kind::kNotJudged: return "not_judged";
  }
  return "?";
}

// Tolerance of the acceptance criteria for one forecast.
bool within_criteria(const controller::StopOutcome& s, const Verdict& v, bool nonlinear) {
  if (v.kind == Verdict::Kind::kFalseNegative || v.kind == Verdict::Kind::kFalsePositive) return false;
  if (v.kind != Verdict::Kind::kTruePositive) return true;
  if (!v.direction_ok) return false;
  if (s.sticking_s() >= kLongSticking_s) return v.error_percent <= (nonlinear ? 1.0 : 5.0);
  return std::abs(v.error_s) <= 0.010;
}

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1,
                       {"config", "out", "steps", "seed", "jobs", "duration", "step-time", "margin-m",
                        "min-step-m", "friction-spread", "gain-spread", "tail"},
                       {"strict", "quiet", "help", "supervised"}, {"set"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  config::Config base = config::load_file_or_default(config_path, args.all("set"));
  if (!args.flag("supervised")) {
    auto& v = base.controller.supervisor;
    v.oscillation_sign_changes = 0;
    v.settle_time_s = 0.0;
    v.position_min_m = v.pressure_min_pa = -1e300;
    v.position_max_m = v.pressure_max_pa = 1e300;
    v.overtravel_m = 1e300;
    v.following_error_s = 0.0;
    v.max_speed_m_per_s = 0.0;
  }
  const std::string out_path = args.required("out");
  const double steps_d = args.number("steps", 200);
  const double seed_d = args.number("seed", 1);
  const double jobs_d = args.number("jobs", std::max(1u, std::thread::hardware_concurrency()));
  const double duration = args.number("duration", 12.0);
  const double step_time = args.number("step-time", 1.0);
  const double margin = args.number("margin-m", 0.02);
  const double min_step = args.number("min-step-m", 0.005);
  const double friction_spread = args.number("friction-spread", 0.0);
  const double gain_spread = args.number("gain-spread", 0.0);
  const double tail = args.number("tail", 1.0);
  const double half = base.plant.geometry.half_stroke_m();
  if (!(steps_d >= 1 && steps_d == std::floor(steps_d))) throw cli::UsageError("--steps must be a whole number >= 1");
  if (!(jobs_d >= 1 && jobs_d == std::floor(jobs_d))) throw cli::UsageError("--jobs must be a whole number >= 1");
  if (!(seed_d >= 0 && seed_d == std::floor(seed_d))) throw cli::UsageError("--seed must be a whole number >= 0");
  if (!(duration > step_time && step_time >= 0)) throw cli::UsageError("--duration must exceed --step-time >= 0");
  if (!(margin >= 0 && 2 * margin + min_step < 2 * half)) throw cli::UsageError("--margin-m leaves no room in the stroke");
  if (!(min_step >= 0)) throw cli::UsageError("--min-step-m must be >= 0");
  // Every target needs a start at least min_step away inside [lo, hi]: the mid-range one too.
  if (!(min_step < half - margin)) throw cli::UsageError("--min-step-m must be below half the usable stroke");
  if (!(friction_spread >= 0 && friction_spread < 1)) throw cli::UsageError("--friction-spread must be in [0, 1)");
  if (!(gain_spread >= 0 && gain_spread < 1)) throw cli::UsageError("--gain-spread must be in [0, 1)");
  if (!(tail >= 0)) throw cli::UsageError("--tail must be >= 0");
  const auto n = static_cast<int>(steps_d);
  const auto jobs = static_cast<int>(std::min<double>(jobs_d, n));

  // The scenarios, drawn up front so they do not depend on the thread count.
  std::vector<Scenario> scenarios(static_cast<std::size_t>(n));
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed_d));
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double lo = -half + margin, hi = half - margin;
  for (int i = 0; i < n; ++i) {
    Scenario& s = scenarios[static_cast<std::size_t>(i)];
    s.index = i;
    s.y_d_m = lo + (hi - lo) * (i + 0.5) / n;
    do {
      s.y0_m = lo + (hi - lo) * 0.5 * (1.0 + unit(rng));
    } while (std::abs(s.y0_m - s.y_d_m) < min_step);
    s.friction_scale = 1.0 + friction_spread * unit(rng);
    s.gain_scale = 1.0 + gain_spread * unit(rng);
  }

  cli::AtomicFile out(out_path);  // created before the run: an unwritable path fails fast

  std::vector<ScenarioResult> results(scenarios.size());
  std::atomic<int> next{0}, done{0};
  std::exception_ptr failure;
  std::mutex failure_mutex;
  const auto wall0 = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point finished = wall0;  // written once, read after the joins
  const auto worker = [&] {
    for (int i; (i = next.fetch_add(1)) < n;) {
      try {
        const Scenario& s = scenarios[static_cast<std::size_t>(i)];
        config::Config cfg = base;
        cfg.simulation.initial_position_m = s.y0_m;
        cfg.controller.initial_setpoint_m = s.y0_m;
        cfg.controller.schedule = {{step_time, s.y_d_m}};
        cfg.controller.duration_s = duration + tail;
        cfg.controller.clock = config::ClockKind::kSimulated;
        auto& f = cfg.plant.friction;
        f.static_positive_n *= s.friction_scale;
        f.coulomb_positive_n *= s.friction_scale;
        f.static_negative_n *= s.friction_scale;
        f.coulomb_negative_n *= s.friction_scale;
        f.viscous_n_s_per_m *= s.friction_scale;
        auto& law = cfg.controller.law;
        law.position_gain_v_per_m *= s.gain_scale;
        law.velocity_gain_v_s_per_m *= s.gain_scale;
        law.acceleration_gain_v_s2_per_m *= s.gain_scale;
        const auto valve = controller::make_valve_characteristic(
            cfg, config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path());
        controller::resolve_offset(cfg, *valve);
        auto plant = backends::make_sim_backend(cfg);
        const hal::SimBackend& bench = *plant;  // the simulated truth, owned by the run
        auto sim = controller::make_run(cfg, *valve, std::move(plant));
        sim.runtime->set_follow_forecasts(false);  // nobody sees the tick-by-tick comparison here
        sim.runtime->set_keep_reforecasts(true);   // judged below against the plant's breakaways
        controller::SimulatedClock clock;
        std::atomic<bool> never{false};
        controller::execute(sim, cfg, clock, never);
        // Stops from the tail are not judged: the tail only lets the carriage show what it did
        // after the stops of the judged window.
        ScenarioResult r{s, {}, {}, sim.runtime->end_time_s()};
        if (bench.motion_events_dropped() > 0)
          throw std::runtime_error("scenario " + std::to_string(s.index) + ": more plant events than recorded");
        for (auto stop : sim.runtime->stops()) {
          if (stop.t_stop_s > duration) continue;
          r.truth.push_back(apply_plant_truth(stop, bench.motion_events(), r.t_end_s, cfg.controller.period_s()));
          r.stops.push_back(stop);
        }
        results[static_cast<std::size_t>(i)] = std::move(r);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(failure_mutex);
        if (!failure) failure = std::current_exception();
      }
      // The last one done stamps the wall time (the progress loop below only polls every 100 ms).
      if (done.fetch_add(1) + 1 == n) finished = std::chrono::steady_clock::now();
    }
  };
  std::vector<std::thread> threads;
  for (int j = 0; j < jobs; ++j) threads.emplace_back(worker);

  // Progress bar on stderr: redrawn in place on a terminal, a line per 10 % otherwise.
  const bool tty = ::isatty(STDERR_FILENO) && !args.flag("quiet");
  int last_decile = -1;
  for (;;) {
    const int d = done.load();
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    if (!args.flag("quiet")) {
      constexpr int kWidth = 40;
      const int filled = kWidth * d / n;
      if (tty) {
        std::fprintf(stderr, "\r[%.*s%*s] %d/%d scenarios, %.1f s", filled,
                     "########################################", kWidth - filled, "", d, n, elapsed);
      } else if (d * 10 / n != last_decile) {
        last_decile = d * 10 / n;
        std::fprintf(stderr, "pneu-sweep: %d/%d scenarios, %.1f s\n", d, n, elapsed);
      }
    }
    if (d == n) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (tty) std::fprintf(stderr, "\n");
  for (auto& t : threads) t.join();
  if (failure) std::rethrow_exception(failure);
  const double wall_s = std::chrono::duration<double>(finished - wall0).count();

  // One CSV row per stop.
  auto& os = out.stream();
  os << "scenario,y0_m,y_d_m,friction_scale,gain_scale,stop,t_stop_s,y_stop_m,force_n,u_star_v,"
        "equilibrium_force_n,outcome,t_end_s,sticking_s,direction";
  for (const char* m : {"lin", "nl"})
    os << ',' << m << "_will_restart," << m << "_t_restart_s," << m << "_direction," << m << "_verdict,"
       << m << "_error_ms," << m << "_error_percent," << m << "_within_criteria";
  os << ",lin_halfway_error_percent,nl_halfway_error_percent\n";
  MethodStats stats[2];
  std::uint64_t stops = 0, restarts = 0, long_restarts = 0, longest_restart_count_1s = 0, unseen = 0, not_at_rest = 0;
  char buf[512];
  for (const auto& r : results) {
    for (std::size_t k = 0; k < r.stops.size(); ++k) {
      const auto& s = r.stops[k];
      ++stops;
      if (r.truth[k].unseen) ++unseen;
      const bool judged = !r.truth[k].not_at_rest;  // else the forecast's premise, rest, was not there
      if (!judged) ++not_at_rest;
      const char* outcome = !judged    ? "plant_not_at_rest"
                            : !s.ended ? "stuck_to_end"
                                       : (s.restarted ? "restart" : "setpoint_changed");
      if (judged && s.restarted) {
        ++restarts;
        if (s.sticking_s() >= kLongSticking_s) ++long_restarts;
        if (s.sticking_s() >= 1.0) ++longest_restart_count_1s;
      }
      const controller::Prediction* any = s.nonlinear ? &*s.nonlinear : (s.linearized ? &*s.linearized : nullptr);
      std::snprintf(buf, sizeof buf, "%d,%.6f,%.6f,%.4f,%.4f,%llu,%.6f,%.9f,%.4f,%.6f,%.4f,%s,%.6f,%.6f,%d",
                    r.scenario.index, r.scenario.y0_m, r.scenario.y_d_m, r.scenario.friction_scale,
                    r.scenario.gain_scale, static_cast<unsigned long long>(s.index), s.t_stop_s, s.y_stop_m,
                    s.force_n, s.snapshot.u_v, any ? any->equilibrium_force_n : NAN, outcome, s.t_end_s,
                    s.sticking_s(), s.direction);
      os << buf;
      const std::optional<controller::Prediction>* ps[2] = {&s.linearized, &s.nonlinear};
      for (int m = 0; m < 2; ++m) {
        if (!*ps[m]) {
          os << ",,,,,,,";
          continue;
        }
        const auto& p = **ps[m];
        const Verdict v = judged ? controller::judge(s, p, r.t_end_s) : Verdict{};
        const bool ok = within_criteria(s, v, m == 1);
        MethodStats& st = stats[m];
        switch (v.kind) {
          case Verdict::Kind::kTruePositive:
            ++st.tp;
            if (!v.direction_ok) ++st.wrong_direction;
            if (s.sticking_s() >= kLongSticking_s) st.long_error_pct.push_back(v.error_percent);
            else st.short_error_ms.push_back(std::abs(v.error_s) * 1e3);
            break;
          case Verdict::Kind::kTrueNegative: ++st.tn; break;
          case Verdict::Kind::kFalsePositive: ++st.fp; break;
          case Verdict::Kind::kFalseNegative: ++st.fn; break;
          case Verdict::Kind::kNotJudged: ++st.not_judged; break;
        }
        if (!ok) ++st.misses;
        const bool tp = v.kind == Verdict::Kind::kTruePositive;
        std::snprintf(buf, sizeof buf, ",%d,%.6f,%d,%s,%s,%s,%d", p.will_restart ? 1 : 0, p.t_restart_s,
                      p.direction, verdict_name(v.kind), tp ? std::to_string(v.error_s * 1e3).c_str() : "",
                      tp ? std::to_string(v.error_percent).c_str() : "", ok ? 1 : 0);
        os << buf;
      }
      // The live predictor: the forecast made again from the last pressures before half the
      // sticking time (restarts after >= 0.5 s only; not an acceptance figure).
      for (int m = 0; m < 2; ++m) {
        // (The half-way of the plant's truth: the runtime settled its own by the detector's.)
        const controller::Reforecast* halfway = judged && s.restarted && s.sticking_s() >= kLongSticking_s
                                                    ? controller::halfway_reforecast(s, kMethods[m])
                                                    : nullptr;
        const Verdict v = halfway ? controller::judge(s, halfway->prediction, r.t_end_s) : Verdict{};
        if (v.kind == Verdict::Kind::kTruePositive) {
          stats[m].halfway_error_pct.push_back(v.error_percent);
          os << ',' << std::to_string(v.error_percent);
        } else {
          os << ',';
        }
      }
      os << '\n';
    }
  }
  out.commit();

  std::printf("pneu-sweep: %d scenarios (%d set-point steps over [%.3f, %.3f] m, seed %llu, friction +-%.0f %%, gains +-%.0f %%), stops of the first %.0f s judged (+ %.1f s tail)\n",
              n, n, lo, hi, static_cast<unsigned long long>(seed_d), friction_spread * 100, gain_spread * 100, duration, tail);
  std::printf("  %llu stops, %llu restarts (%llu after >= 0.5 s of sticking, %llu after >= 1 s), timed by the plant's "
              "breakaways; %llu of them moved the carriage less than the stop detector's motion band\n",
              static_cast<unsigned long long>(stops), static_cast<unsigned long long>(restarts),
              static_cast<unsigned long long>(long_restarts), static_cast<unsigned long long>(longest_restart_count_1s),
              static_cast<unsigned long long>(unseen));
  if (not_at_rest > 0)
    std::printf("  %llu stops were confirmed while the plant was still sliding within the detector's rest band: "
                "their forecasts are not judged\n",
                static_cast<unsigned long long>(not_at_rest));
  std::printf("  %.2f s wall on %d threads: %.1f scenarios/s\n", wall_s, jobs, n / wall_s);
  const config::LinearizedSlope slope = base.controller.predictor.linearized_slope;
  const std::string names[2] = {slope == config::LinearizedSlope::kStopTangent
                                    ? std::string("linearized")
                                    : std::string("linearized (slope: ") + config::to_string(slope) + ")",
                                "nonlinear"};
  for (int m = 0; m < 2; ++m) {
    const MethodStats& st = stats[m];
    if (st.tp + st.tn + st.fp + st.fn == 0) continue;
    std::printf("  %s:\n", names[m].c_str());
    std::printf("    confusion            actual restart  actual none\n");
    std::printf("      forecast restart   %14llu  %11llu\n", static_cast<unsigned long long>(st.tp),
                static_cast<unsigned long long>(st.fp));
    std::printf("      forecast none      %14llu  %11llu\n", static_cast<unsigned long long>(st.fn),
                static_cast<unsigned long long>(st.tn));
    std::printf("    not judged: %llu (the set point moved, the plant was not at rest, or the forecast restart falls after the run)\n",
                static_cast<unsigned long long>(st.not_judged));
    std::printf("    wrong direction: %llu\n", static_cast<unsigned long long>(st.wrong_direction));
    std::printf("    error, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% of the sticking time\n",
                st.long_error_pct.size(), percentile(st.long_error_pct, 0.5), percentile(st.long_error_pct, 0.9),
                percentile(st.long_error_pct, 0.99), percentile(st.long_error_pct, 1.0));
    std::printf("    error, sticking <  0.5 s (%zu): p50 %.3f ms p90 %.3f ms p99 %.3f ms max %.3f ms\n",
                st.short_error_ms.size(), percentile(st.short_error_ms, 0.5), percentile(st.short_error_ms, 0.9),
                percentile(st.short_error_ms, 0.99), percentile(st.short_error_ms, 1.0));
    std::printf("    outside the acceptance criteria (%s %%, 10 ms): %llu\n", m == 0 ? "5" : "1",
                static_cast<unsigned long long>(st.misses));
    std::printf("    made again half-way, sticking >= 0.5 s (%zu): p50 %.3f %%  p90 %.3f %%  p99 %.3f %%  max %.3f %% "
                "(the live predictor, from the pressures of the moment; not judged)\n",
                st.halfway_error_pct.size(), percentile(st.halfway_error_pct, 0.5),
                percentile(st.halfway_error_pct, 0.9), percentile(st.halfway_error_pct, 0.99),
                percentile(st.halfway_error_pct, 1.0));
  }
  std::printf("  wrote %s\n", out_path.c_str());
  if (args.flag("strict") && (stats[0].misses || stats[1].misses)) return cli::kExitFailure;
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-sweep", run, argc, argv); }
