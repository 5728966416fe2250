// pneud: the controller daemon of the electropneumatic bench. The composition root: the
// configuration, the backend (pneu/backends/factory.hpp), the run, its files, LCM and systemd.
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>

#include "pneu/backends/factory.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/text.hpp"
#include "pneu/controller/journal.hpp"
#include "pneu/controller/realtime.hpp"
#include "pneu/controller/run_summary.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/online.hpp"
#include "run_files.hpp"
#include "systemd_notifier.hpp"
#include "telemetry.hpp"

namespace {

using namespace pneu;
using pneud::RunFiles;
using pneud::SystemdNotifier;
using pneud::Telemetry;

constexpr const char* kHelp = R"(pneud: real-time controller of the electropneumatic positioning bench

Usage:
  pneud [--config FILE] [--clock real|simulated] [--duration S] [--events FILE]
        [--trajectory FILE] [--summary-json FILE] [--set KEY=VALUE ...] [--check-config]
        [--require-telemetry] [--require-rt] [--quiet]
  pneud --identify OUT.yaml [--armed] [--config FILE] [--clock real|simulated] [--set KEY=VALUE ...] ...
  pneud -h | --help | --version

  --config FILE      YAML configuration (default: the embedded config/sim.yaml, the simulated bench
                     running the paper's set-point step)
  --clock C          real: fixed rate on CLOCK_MONOTONIC (clock_nanosleep, absolute deadlines);
                     simulated: lockstep with the in-process plant, as fast as the CPU allows
                     (same as --set controller.clock=C)
  --duration S       run length in seconds; 0 runs until SIGINT/SIGTERM (real clock)
                     (same as --set controller.duration_s=S)
  --events FILE      one JSON object per line: start, stop, prediction, reforecast, fault,
                     fault_reset, fault_reset_refused, hold_start, hold_end, movement_test (its
                     end at ARM), command (each command's verdict), end
  --trajectory FILE  one CSV row per tick: seq,t,y_d,y,v_hat,a_hat,p_p,p_n,force,u,stuck,mode,validity,
                     then, while stuck, the pressures and force each forecast made at the stop
                     expects (p_p_linearized,...,force_nonlinear; empty otherwise)
                     Beside each of the two (a regular file), FILE.config.yaml: the run's
                     effective configuration, as --check-config prints it; pneu_plots.py and
                     pneu-identify read it in place of the source YAML
  --summary-json FILE  the run's figures as one JSON object, written whole at the end of the run
                     (--quiet or not; none is left when the run fails): the loop's ticks,
                     overruns, deadlines skipped and timing; the runtime's ticks, stops and
                     faults; LCM's publish errors and command counters; the Modbus counters and
                     the safe output on closing (telemetry, modbus: null when not used)
  --set KEY=VALUE    override a config key by its dotted path, e.g. controller.law.position_gain_v_per_m=60
  --check-config     validate, print the effective configuration (u_0 resolved) and exit
  --require-telemetry  exit with an error when LCM cannot start, instead of running without it
  --require-rt       exit with an error when controller.realtime cannot be applied (SCHED_FIFO,
                     CPU affinity, mlockall), instead of warning and running without it
  --quiet            no summary on stdout
  --identify OUT.yaml  an identification run instead of the configured set points: an automatic
                     sequence of moves and slow set-point ramps within the soft limits (under a
                     minute), driven by gains designed on the model (controller.law.design, even
                     with gains: fixed: the run visits the whole stroke), supervised as any run,
                     then plant: identified from the run's own
                     signals (stiction, Coulomb and viscous friction, the valves' conductances and
                     null offset, the dead volumes) and written, with the rest of the configuration,
                     to OUT.yaml; each parameter is printed before and after with its uncertainty.
                     A fault ends the run in the safe state and writes nothing (exit 3); a run that
                     showed too little to identify writes nothing either, naming what is missing
                     (exit 1)
  --armed            required with --identify on hal.backend modbus (a real bench, or pneu-plant
                     serve): the run moves the carriage over the stroke on its own

Output files (--events, --trajectory, --summary-json, --identify): a regular file, or a new one,
is written to FILE.partial-PID beside it and renamed over it when complete, keeping its mode and
owner; --events and --trajectory grow there while the run lasts (tail -F it) and are renamed when
the run ends, however it ends once started (nothing when it never started). A symbolic link is
followed; a device, a FIFO or /dev/stdout is written directly. Two outputs naming the same file
are refused.

Faults (controller.supervisor, the e-stop, comms) latch the safe output until a FAULT_RESET
command once the cause is gone; the daemon then waits disarmed for an ARM command.
Under systemd (Type=notify): READY=1 once the loop runs, WATCHDOG=1 while it ticks, STOPPING=1
on SIGTERM/SIGINT, which write the safe output and publish a final health message before exit.

Faults, fault resets (and refused ones), arming, disarming, the movement test's pass or abort at
ARM, the hold's start and end, and the link to the device lost and back are each one line on
stderr as they happen, quiet or not, with the syslog priority prefix journald reads ("<3>" a
fault, a movement test's finding among them, "<4>" a refused reset or a link lost, "<5>" a reset,
arming, disarming, the movement test passed or aborted, a link back, "<6>" the hold).

Exit codes: 0 success; 1 run failure (an --identify run that showed too little among them); 2 bad
command line or configuration (nothing was run); 3 the run ended with a fault still latched (the
outputs in the safe state); 4 the module did not confirm the safe output on closing (it may still
hold the last command; 4 wins over 3). On 3 and 4 the summary's first line and the last line on
stderr say why. Another pneud heard on the LCM channels at start-up: exit 1, naming it.
)";

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }

// The configuration, with --clock and --duration as overrides.
config::Config load_config(const cli::Args& args, const std::string& config_path) {
  std::vector<std::string> overrides = args.all("set");
  if (auto c = args.value("clock")) {
    if (*c != "real" && *c != "simulated") throw cli::UsageError("--clock must be real or simulated");
    overrides.push_back("controller.clock=" + *c);
  }
  if (auto d = args.value("duration")) {
    (void)args.number("duration", 0.0);  // a number, or a usage error
    overrides.push_back("controller.duration_s=" + *d);
  }
  return config::load_file_or_default(config_path, overrides);
}

// The valve characteristic the controller uses; a bad table is a configuration error.
std::unique_ptr<model::ValveCharacteristic> load_valve(const config::Config& cfg, const std::string& config_path) {
  try {
    return controller::make_valve_characteristic(
        cfg, config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path());
  } catch (const model::ValveTableError& e) {
    throw config::ConfigError("controller.predictor.valve_table", e.what());
  }
}

// The run's effective configuration as written beside its outputs: what the loop runs with, a
// valve table named by its absolute path (the file lands elsewhere than the source YAML).
std::string effective_configuration(config::Config cfg, const std::string& config_path) {
  std::string& table = cfg.controller.predictor.valve_table;
  if (!table.empty() && std::filesystem::path(table).is_relative()) {
    const std::filesystem::path dir =
        config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path();
    table = std::filesystem::absolute(dir / table).lexically_normal().string();
  }
  return "# the effective configuration of a pneud " PNEU_VERSION " run: what its loop ran with (" +
         (config_path.empty() ? std::string("the embedded sim.yaml") : config_path) +
         ", --set applied; u_0 = " + text::format("%.9g", cfg.controller.law.offset_v) + " V)\n" + config::to_yaml(cfg);
}

// What the summary says besides the runtime's account.
controller::RunFigures figures_of(const config::Config& cfg, const std::string& config_path, const controller::Run& run,
                                  double wall_s) {
  controller::RunFigures f;
  f.version = PNEU_VERSION;
  f.backend = cfg.hal.backend == config::BackendKind::kModbus ? "modbus" : "sim";
  f.clock = cfg.controller.clock == config::ClockKind::kReal ? "real" : "simulated";
  f.config = config_path.empty() ? "embedded sim.yaml" : config_path;
  f.u_0_v = cfg.controller.law.offset_v;
  f.wall_s = wall_s;
  f.timing = run.timing;
  f.ticks_dropped = run.outputs->ticks_dropped;
  f.events_dropped = run.outputs->events_dropped;
  f.modbus = run.backend->link_report();
  f.fault_at_end = run.loop->fault_cause();
  return f;
}

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1,
                       {"config", "clock", "duration", "events", "trajectory", "summary-json", "identify"},
                       {"check-config", "quiet", "help", "version", "require-telemetry", "require-rt", "armed"}, {"set"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  if (args.flag("version")) {
    std::printf("pneud %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  config::Config cfg = load_config(args, config_path);
  const bool real_clock = cfg.controller.clock == config::ClockKind::kReal;
  const bool require_rt = args.flag("require-rt");
  if (require_rt && !real_clock)
    throw cli::UsageError("--require-rt needs the real clock (the simulated clock runs as fast as it can)");
  const std::unique_ptr<model::ValveCharacteristic> valve = load_valve(cfg, config_path);  // outlives the run
  controller::resolve_offset(cfg, *valve);
  // Designed once, here: a scheduled law's design refused before any output; where it fell back
  // (the requested dynamics infeasible at some node), said at once, on stderr (the journal).
  std::vector<model::DesignFallback> fallbacks;
  const controller::ControlLaw law = controller::make_control_law(cfg, *valve, {true, std::nullopt, &fallbacks});
  if (!fallbacks.empty())
    std::fprintf(stderr,
                 "pneud: warning: controller.law.design: the requested dynamics cannot be had everywhere on the "
                 "stroke; the gains fall back there:\n%s\n",
                 model::describe_fallbacks(fallbacks, cfg.controller.law.design.node_spacing_m).c_str());
  // An identification run: its own set points and length, on the configured backend.
  const std::optional<std::string> identify_path = args.value("identify");
  std::optional<controller::ControlLaw> run_law;  // the identification run's, when not the configured one
  const config::Config as_configured = cfg;
  identify::RunPlan plan;
  if (identify_path) {
    if (args.flag("check-config")) throw cli::UsageError("--identify and --check-config do not go together");
    if (args.value("duration")) throw cli::UsageError("--identify makes its own run: no --duration");
    if (cfg.hal.backend == config::BackendKind::kModbus && !args.flag("armed"))
      throw cli::UsageError("--identify on hal.backend modbus moves the carriage over the stroke on its own: "
                            "clear the stroke and add --armed");
    // The simulated bench starts at rest at simulation.initial_position_m; a real one goes to the
    // configured first set point.
    if (cfg.hal.backend == config::BackendKind::kSim) cfg.controller.initial_setpoint_m = cfg.simulation.initial_position_m;
    run_law = identify::identification_law(cfg, *valve);
    try {
      plan = identify::plan_run(cfg, *run_law, *valve, cfg.controller.initial_setpoint_m);
    } catch (const std::invalid_argument& e) {
      throw config::ConfigError("controller.soft_limit_min_m", e.what());
    }
    cfg = identify::configured_for(cfg, plan);
  } else if (args.flag("armed")) {
    throw cli::UsageError("--armed goes with --identify");
  }
  if (args.flag("check-config")) {
    std::cout << "# effective configuration of pneud (u_0 = u_e of Eq. 7 = " << cfg.controller.law.offset_v
              << " V)\n"
              << config::to_yaml(cfg);
    return cli::kExitOk;
  }

  // What this build left out is refused before any output file is created.
  backends::require_built(cfg);
  Telemetry::require_built(args.flag("require-telemetry"));
  if (cfg.hal.backend == config::BackendKind::kModbus && cfg.hal.modbus.module_watchdog_s == 0.0)  // docs/serve.md
    std::fprintf(stderr, "pneud: warning: hal.modbus.module_watchdog_s is 0: no module watchdog stated; should pneud "
                         "die, the module holds its last command until a watchdog of its own trips\n");
  RunFiles files(args);  // before the run: a path that cannot be written, or two outputs on one file, fail here
  files.write_effective_configuration(effective_configuration(cfg, config_path));
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  const controller::ControlLaw& driving = run_law ? *run_law : law;
  controller::Run run = controller::make_run(cfg, *valve, backends::make_backend(cfg, driving), driving);
  files.add_sinks(*run.runtime);
  controller::JournalLines journal(stderr);  // faults, resets, arming, holds, the link: at once, quiet or not
  run.runtime->add_sink(journal);
  std::atomic<bool> fault_stop{false};
  identify::Recorder recorder(fault_stop);
  if (identify_path) run.runtime->add_sink(recorder);
  // On the real clock the run lasts about a minute: how it goes, on stderr.
  identify::Progress progress(plan, stderr);
  if (identify_path && real_clock) run.runtime->add_sink(progress);
  // Online identification (controller.predictor.learn_online): the forecasts on what it learns.
  std::optional<identify::OnlineIdentifier> learner;
  // On the real clock the fit runs on the learner's own thread: the service thread that drains
  // also pets systemd's watchdog, publishes health and handles commands.
  if (cfg.controller.predictor.learn_online && !identify_path)
    learner.emplace(as_configured, *run.runtime, identify::OnlineIdentifier::kDefaultWindow_s,
                    real_clock ? identify::OnlineIdentifier::Fitting::kOnItsOwnThread
                               : identify::OnlineIdentifier::Fitting::kOnTheDrainingThread);
  const std::unique_ptr<Telemetry> telemetry = Telemetry::start(cfg, run, args.flag("require-telemetry"));
  // One controller per bench: another pneud's health on these channels refuses the start, before
  // anything is driven or reported ready. Where none can be heard, a bench's run says so.
  std::string why_not_checked = "LCM telemetry is off";
  if (telemetry) {
    why_not_checked.clear();
    if (const auto other = telemetry->another_controller(1.5 * cfg.telemetry.health_period_s, why_not_checked)) {
      files.discard();
      throw std::runtime_error("another controller is running on the channels " + cfg.telemetry.channel_prefix +
                               "*: " + *other + "; one controller per bench: stop it first (or give this one its "
                               "own telemetry.channel_prefix, if it drives another axis)");
    }
  }
  if (!why_not_checked.empty() && cfg.hal.backend != config::BackendKind::kSim)
    std::fprintf(stderr, "pneud: warning: not checked that no other controller drives this bench: %s\n",
                 why_not_checked.c_str());
  SystemdNotifier notifier(*run.outputs, g_stop);
  std::function<void(int)> wait_for_input;
  std::function<void()> on_loop_thread;
  if (real_clock) {
    wait_for_input = [&](int ms) {
      notifier.service();
      if (telemetry) telemetry->handle(ms);
      else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    };
    on_loop_thread = [&] {
      const auto report = controller::setup_realtime_thread(cfg.controller.realtime, require_rt);
      for (const auto& w : report.warnings) std::fprintf(stderr, "pneud: warning: real time: %s\n", w.c_str());
    };
  }
  // The start-up line of a real bench: the movement test's verdict (starting armed), that it runs
  // at the first ARM (starting disarmed: the loop runs it, JournalLines says how it went), or that
  // the key skipped it.
  if (controller::movement_test_at_first_arm(cfg))
    std::fprintf(stderr, "pneud: movement test: at the first ARM (controller.start_armed: false): open-loop pulses "
                         "check the wiring before the law drives the valves\n");
  else if (cfg.hal.backend == config::BackendKind::kModbus && !controller::movement_test_runs(cfg))
    std::fprintf(stderr, "pneud: movement test: skipped (controller.movement_test.enabled: false): the wiring is not "
                         "checked before closed loop\n");
  const auto said_movement_test = [](const controller::MovementTestResult& r) {
    if (r.passed() || r.finding == controller::MovementFinding::kInterrupted)  // a finding: the error line says it
      std::fprintf(stderr, "pneud: movement test %s\n", controller::describe(r).c_str());
  };
  const auto clock = controller::make_clock(cfg.controller.clock);
  const auto wall0 = std::chrono::steady_clock::now();
  try {
    // An identification run also stops at its first fault (the loop holds the safe output).
    std::atomic<bool> stop_either{false};
    std::function<void(int)> wait = wait_for_input;
    if (identify_path) {
      const std::function<void(int)> inner = wait_for_input;
      wait = [&, inner](int ms) {
        if (inner) inner(ms);
        else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
        if (g_stop.load() || fault_stop.load()) stop_either.store(true);
      };
    }
    controller::execute(run, cfg, *clock, identify_path && real_clock ? stop_either : identify_path ? fault_stop : g_stop,
                        wait, on_loop_thread, said_movement_test);
  } catch (...) {
    if (run.outputs->heartbeat.load() == 0) {
      files.discard();  // nothing ran: no empty output left
    } else {
      try {
        files.commit();  // what happened until the error is kept
      } catch (const std::exception& e) {
        std::fprintf(stderr, "pneud: %s\n", e.what());
      }
    }
    throw;
  }
  if (g_stop.load()) notifier.stopping();
  controller::RunFigures figures =
      figures_of(cfg, config_path, run, std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count());
  if (figures.modbus && !figures.modbus->safe_output_delivered)  // the journal's, quiet or not
    std::fprintf(stderr,
                 "pneud: warning: the module did not confirm the safe output on closing (%d attempts, last error: %s): "
                 "it may still hold the last command\n",
                 figures.modbus->safe_output_attempts, figures.modbus->last_error.c_str());
  files.commit();
  if (telemetry) figures.telemetry = telemetry->figures();
  files.write_summary_json(figures, *run.runtime);
  if (!args.flag("quiet")) controller::print_summary(stdout, figures, *run.runtime);
  if (learner && !args.flag("quiet")) {
    std::printf("online identification: %d updates from the run's own signals, the longest %.0f ms %s "
                "(%d stops after a breakaway could not update%s%s)\n",
                learner->updates(), learner->longest_update_s() * 1e3,
                real_clock ? "on the learner's own thread" : "off the loop's thread", learner->refused(),
                learner->refused() > 0 ? ": " : "", learner->last_refusal().c_str());
    std::printf("  %d updates late (their stop forecast on the model before: the fit outlasted %.1f s of ticks "
                "queued), %d stops after a breakaway found a late fit still running\n",
                learner->updates_late(),
                static_cast<double>(controller::Runtime::kMaxTicksQueuedWaiting) * cfg.controller.period_s(),
                learner->stops_while_busy());
    if (learner->stops_forecast() > 0)
      std::printf("  %d of %d stops were forecast on a stiction bound not identified yet (the configured one: no "
                  "breakaway that way yet)\n",
                  learner->stops_on_a_configured_bound(), learner->stops_forecast());
    if (learner->updates() > 0) identify::print_report(stdout, learner->estimate());
  }
  const controller::RunEnding ending = controller::run_ending(figures);
  if (identify_path) {
    if (!recorder.fault().empty()) {  // the run stops at its first fault: still latched (exit 3, or 4)
      std::fprintf(stderr, "pneud: the identification run ended at t = %s s by a fault, %s: outputs in the safe state, "
                           "nothing written\n", std::to_string(recorder.fault_time_s()).c_str(), recorder.fault().c_str());
      return controller::exit_code(ending);
    }
    if (g_stop.load()) throw std::runtime_error("the identification run was interrupted: nothing written");
    identify::Identification id;
    try {
      id = identify::identify(recorder.samples(), as_configured.plant, identify::options_for(as_configured));
    } catch (const identify::InsufficientData& e) {
      throw std::runtime_error(std::string("the identification run showed too little: ") + e.what() + "; nothing written");
    }
    if (!args.flag("quiet")) {
      std::printf("identified from the run's own signals (%zu ticks):\n", recorder.samples().size());
      identify::print_report(stdout, id);
    }
    cli::OutputFile& identified = *files.identified();
    identified.stream() << identify::identified_config_yaml(as_configured, id, "pneud --identify");
    identified.commit();
    std::printf("written: %s\n", identified.path().c_str());
  }
  // A fault still latched, or the safe output not confirmed: said last on stderr, and the exit code.
  if (ending != controller::RunEnding::kOk)
    controller::journal_line(stderr, controller::Priority::kErr, controller::ending_text(figures, *run.runtime));
  return controller::exit_code(ending);
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneud", run, argc, argv); }
