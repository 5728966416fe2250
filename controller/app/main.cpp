// pneud: the controller daemon of the electropneumatic bench. The composition root: the command
// line and the configuration, the run's specification (pneu/assembly/run_spec.hpp), then one of
// its modes, each around a DaemonRun (daemon_run.hpp: the files, LCM, systemd, the summary): the
// configured set points (learning online or not), or an identification run.
#include <atomic>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "daemon_run.hpp"
#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/yaml_text.hpp"
#include "pneu/config/text.hpp"
#include "pneu/controller/run_summary.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/online.hpp"

namespace {

using namespace pneu;
using pneud::DaemonRun;

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
                     to OUT.yaml: the text of --config (its comments kept), each identified value
                     replaced in place with its uncertainty beside it, under a header saying when,
                     from which run and with which fit residual; each parameter is printed before
                     and after with its uncertainty, then the evidence, then the run's summary.
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

// The run's specification, derived once, here: a bad valve table or a scheduled law's design
// refused before any output; where the design fell back (the requested dynamics infeasible at some
// node), said at once, on stderr (the journal).
assembly::RunSpec specified(const config::Config& cfg, const std::string& config_path) {
  assembly::RunSpec spec = assembly::RunSpec::of(
      cfg, {config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path(), true,
            std::nullopt});
  if (!spec.fallbacks().empty())
    std::fprintf(stderr,
                 "pneud: warning: controller.law.design: the requested dynamics cannot be had everywhere on the "
                 "stroke; the gains fall back there:\n%s\n",
                 model::describe_fallbacks(spec.fallbacks(), cfg.controller.law.design.node_spacing_m).c_str());
  return spec;
}

// What online identification (controller.predictor.learn_online) said of the run.
void print_learning(const identify::OnlineIdentifier& learner, bool real_clock, double period_s) {
  std::printf("online identification: %d updates from the run's own signals, the longest %.0f ms %s "
              "(%d stops after a breakaway could not update%s%s)\n",
              learner.updates(), learner.longest_update_s() * 1e3,
              real_clock ? "on the learner's own thread" : "off the loop's thread", learner.refused(),
              learner.refused() > 0 ? ": " : "", learner.last_refusal().c_str());
  std::printf("  %d updates late (their stop forecast on the model before: the fit outlasted %.1f s of ticks "
              "queued), %d stops after a breakaway found a late fit still running\n",
              learner.updates_late(), static_cast<double>(controller::Runtime::kMaxTicksQueuedWaiting) * period_s,
              learner.stops_while_busy());
  if (learner.stops_forecast() > 0)
    std::printf("  %d of %d stops were forecast on a stiction bound not identified yet (the configured one: no "
                "breakaway that way yet)\n",
                learner.stops_on_a_configured_bound(), learner.stops_forecast());
  if (learner.updates() > 0) identify::print_report(stdout, learner.estimate());
}

// The configured run: its set points, until its length or a signal; with
// controller.predictor.learn_online, the forecasts on what it learns.
int configured_run(const cli::Args& args, const std::string& config_path, const assembly::RunSpec& spec) {
  DaemonRun daemon(args, config_path, spec);
  std::optional<identify::OnlineIdentifier> learner;
  // On the real clock the fit runs on the learner's own thread: the service thread that drains
  // also pets systemd's watchdog, publishes health and handles commands.
  if (spec.config().controller.predictor.learn_online)
    learner.emplace(spec.config(), daemon.assembled().runtime(), identify::OnlineIdentifier::kDefaultWindow_s,
                    daemon.real_clock() ? identify::OnlineIdentifier::Fitting::kOnItsOwnThread
                                        : identify::OnlineIdentifier::Fitting::kOnTheDrainingThread);
  const controller::RunFigures figures = daemon.execute();
  if (learner && !daemon.quiet()) print_learning(*learner, daemon.real_clock(), spec.config().controller.period_s());
  return daemon.ended(figures);
}

// An identification run (--identify): its own set points and length on the configured backend,
// driven by the law designed for the whole stroke; plant: identified from its ticks and written
// with the rest of the configuration.
int identification_run(const cli::Args& args, const std::string& config_path, const assembly::RunSpec& configured) {
  if (args.flag("check-config")) throw cli::UsageError("--identify and --check-config do not go together");
  if (args.value("duration")) throw cli::UsageError("--identify makes its own run: no --duration");
  const config::Config& as_configured = configured.config();
  if (as_configured.hal.backend == config::BackendKind::kModbus && !args.flag("armed"))
    throw cli::UsageError("--identify on hal.backend modbus moves the carriage over the stroke on its own: "
                          "clear the stroke and add --armed");
  // The simulated bench starts at rest at simulation.initial_position_m; a real one goes to the
  // configured first set point.
  const assembly::RunSpec start = configured.reconfigured([](config::Config& c) {
    if (c.hal.backend == config::BackendKind::kSim) c.controller.initial_setpoint_m = c.simulation.initial_position_m;
  });
  controller::ControlLaw law = identify::identification_law(start);
  identify::RunPlan plan;
  try {
    plan = identify::plan_run(start.config(), law, start.valve(), start.config().controller.initial_setpoint_m);
  } catch (const std::invalid_argument& e) {
    throw config::ConfigError("controller.soft_limit_min_m", e.what());
  }
  // The text the configuration came from, read now: its comments are kept in the file written.
  const std::string source_text = config::text_of(config_path);
  std::atomic<bool> fault_stop{false};
  DaemonRun daemon(args, config_path, identify::configured_for(start, plan, std::move(law)));
  const identify::Recorder& recorder = daemon.assembled().emplace_sink<identify::Recorder>(fault_stop);
  // On the real clock the run lasts about a minute: how it goes, on stderr.
  if (daemon.real_clock()) daemon.assembled().emplace_sink<identify::Progress>(plan, stderr);
  // The run's summary (its stops, the loop's timing: a hundred lines) comes after what it identified.
  const controller::RunFigures figures = daemon.execute(&fault_stop, true);
  if (!recorder.fault().empty()) {  // the run stops at its first fault: still latched (exit 3, or 4)
    daemon.print_summary(figures);
    std::fprintf(stderr, "pneud: the identification run ended at t = %s s by a fault, %s: outputs in the safe state, "
                         "nothing written\n", std::to_string(recorder.fault_time_s()).c_str(), recorder.fault().c_str());
    return controller::exit_code(controller::run_ending(figures));
  }
  if (daemon.interrupted()) {
    daemon.print_summary(figures);
    throw std::runtime_error("the identification run was interrupted: nothing written");
  }
  identify::Identification id;
  try {
    id = identify::identify(recorder.samples(), as_configured.plant, identify::options_for(as_configured));
  } catch (const identify::InsufficientData& e) {
    daemon.print_summary(figures);
    throw std::runtime_error(std::string("the identification run showed too little: ") + e.what() + "; nothing written");
  }
  const double run_s = recorder.samples().empty() ? 0.0 : recorder.samples().back().t_s - recorder.samples().front().t_s;
  if (!daemon.quiet()) {
    std::printf("identified from the run's own signals (%zu ticks over %.1f s):\n", recorder.samples().size(), run_s);
    identify::print_report(stdout, id);
  }
  const identify::IdentifiedYaml yaml = identify::identified_config_yaml(
      source_text, as_configured, id,
      {"pneud " PNEU_VERSION, args.command_line(),
       text::format("its own identification run: %zu ticks over %.2f s", recorder.samples().size(), run_s), config_path,
       std::time(nullptr)});
  cli::OutputFile& identified = *daemon.files().identified();
  identified.stream() << yaml.text;
  identified.commit();
  std::printf("written: %s\n", identified.path().c_str());
  if (!yaml.text_not_kept.empty())
    std::fprintf(stderr, "pneud: warning: %s: the whole configuration, without the comments of %s: %s\n",
                 identified.path().c_str(), config_path.empty() ? "the embedded sim.yaml" : config_path.c_str(),
                 yaml.text_not_kept.c_str());
  if (!daemon.quiet()) std::printf("\nthe identification run:\n");
  daemon.print_summary(figures);
  return daemon.ended(figures);
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
  const config::Config cfg = load_config(args, config_path);
  if (args.flag("require-rt") && cfg.controller.clock != config::ClockKind::kReal)
    throw cli::UsageError("--require-rt needs the real clock (the simulated clock runs as fast as it can)");
  const assembly::RunSpec spec = specified(cfg, config_path);
  if (args.value("identify")) return identification_run(args, config_path, spec);
  if (args.flag("armed")) throw cli::UsageError("--armed goes with --identify");
  if (args.flag("check-config")) {
    std::cout << "# effective configuration of pneud (u_0 = u_e of Eq. 7 = " << spec.u_0_v() << " V)\n"
              << config::to_yaml(spec.config());
    return cli::kExitOk;
  }
  return configured_run(args, config_path, spec);
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneud", run, argc, argv); }
