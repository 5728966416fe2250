// pneud: the controller daemon of the electropneumatic bench.
#include <algorithm>
#include <csignal>
#include <functional>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/events_file.hpp"
#include "pneu/controller/realtime.hpp"
#include "pneu/controller/run_summary.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/controller/trajectory_file.hpp"
#include "pneu/controller/watchdog.hpp"
#ifdef PNEU_WITH_SYSTEMD
#include <systemd/sd-daemon.h>
#endif
#ifdef PNEU_WITH_LCM
#include "pneu/telemetry/lcm_bridge.hpp"
#endif
#ifdef PNEU_WITH_MODBUS
#include "pneu/hal/modbus_backend.hpp"
#endif
#ifdef PNEU_WITH_GPIOD
#include "pneu/hal/gpio_backend.hpp"
#include "pneu/hal/gpio_lines.hpp"
#endif

namespace {

using namespace pneu;

constexpr const char* kHelp = R"(pneud: real-time controller of the electropneumatic positioning bench

Usage:
  pneud [--config FILE] [--clock real|simulated] [--duration S] [--events FILE]
        [--trajectory FILE] [--summary-json FILE] [--set KEY=VALUE ...] [--check-config]
        [--require-telemetry] [--require-rt] [--quiet]
  pneud --help | --version

  --config FILE      YAML configuration (default: the embedded config/sim.yaml, the simulated bench
                     running the paper's set-point step)
  --clock C          real: fixed rate on CLOCK_MONOTONIC (clock_nanosleep, absolute deadlines);
                     simulated: lockstep with the in-process plant, as fast as the CPU allows
                     (same as --set controller.clock=C)
  --duration S       run length in seconds; 0 runs until SIGINT/SIGTERM (real clock)
                     (same as --set controller.duration_s=S)
  --events FILE      one JSON object per line: start, stop, prediction, reforecast, fault,
                     fault_reset, fault_reset_refused, command (each command's verdict), end
  --trajectory FILE  one CSV row per tick: seq,t,y_d,y,v_hat,a_hat,p_P,p_N,F,u,stuck,validity,
                     then, while stuck, the pressures and force each forecast made at the stop
                     expects (p_P_linearized,...,F_nonlinear; empty otherwise)
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

Faults (controller.supervisor, the e-stop, comms) latch the safe output until a FAULT_RESET
command once the cause is gone; the daemon then waits disarmed for an ARM command.
Under systemd (Type=notify): READY=1 once the loop runs, WATCHDOG=1 while it ticks, STOPPING=1
on SIGTERM/SIGINT, which write the safe output and publish a final health message before exit.

Exit codes: 0 success, 1 run failure, 2 bad command line or configuration (nothing was run).
)";

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }

// systemd's side of the service thread: READY=1 after the loop's first tick, WATCHDOG=1 only
// while the loop's heartbeat advances, STATUS= on mode changes, STOPPING=1 once asked to stop.
// Without NOTIFY_SOCKET (not under systemd) every call is a no-op.
class SystemdNotifier {
 public:
  explicit SystemdNotifier(const controller::LoopOutputs& loop) : loop_(loop), watchdog_(watchdog_interval_s()) {}
  void service() {
#ifdef PNEU_WITH_SYSTEMD
    const std::uint64_t beat = loop_.heartbeat.load(std::memory_order_acquire);
    if (!ready_ && beat > 0) {
      ready_ = true;
      sd_notify(0, "READY=1");
    }
    const auto mode = loop_.mode.load(std::memory_order_relaxed);
    const auto cause = loop_.fault_cause.load(std::memory_order_relaxed);
    if (ready_ && (mode != last_mode_ || cause != last_cause_)) {
      last_mode_ = mode;
      last_cause_ = cause;
      sd_notifyf(0, "STATUS=%s%s%s", mode == 0 ? "disarmed" : mode == 1 ? "armed" : "FAULT: ",
                 mode == 2 ? controller::fault_name(cause) : "", mode == 0 ? " (send ARM to drive)" : "");
    }
    const double now_s = std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    if (watchdog_.due(beat, now_s)) sd_notify(0, "WATCHDOG=1");  // the loop ticked since the last check
    if (g_stop.load()) stopping();
#endif
  }
  /// Asked to stop (SIGTERM/SIGINT): said once, from the service thread or after the run.
  void stopping() {
#ifdef PNEU_WITH_SYSTEMD
    if (stopping_) return;
    stopping_ = true;
    sd_notify(0, "STOPPING=1\nSTATUS=stopping: safe output written, final health published");
#endif
  }

 private:
  // A quarter of WatchdogSec (systemd's WATCHDOG_USEC); 0 when the watchdog is off.
  static double watchdog_interval_s() {
#ifdef PNEU_WITH_SYSTEMD
    std::uint64_t usec = 0;
    if (sd_watchdog_enabled(0, &usec) > 0) return static_cast<double>(usec) * 1e-6 / 4.0;
#endif
    return 0.0;
  }

  const controller::LoopOutputs& loop_;
  controller::WatchdogGate watchdog_;
  bool ready_ = false, stopping_ = false;
  std::uint8_t last_mode_ = 255, last_cause_ = 255;
};

int run(int argc, char** argv) {
  const cli::Args args(argc, argv, 1, {"config", "clock", "duration", "events", "trajectory", "summary-json"},
                       {"check-config", "quiet", "help", "version", "require-telemetry", "require-rt"}, {"set"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  if (args.flag("version")) {
    std::printf("pneud %s\n", PNEU_VERSION);
    return cli::kExitOk;
  }
  std::vector<std::string> overrides = args.all("set");
  if (auto c = args.value("clock")) {
    if (*c != "real" && *c != "simulated") throw cli::UsageError("--clock must be real or simulated");
    overrides.push_back("controller.clock=" + *c);
  }
  if (auto d = args.value("duration")) {
    (void)args.number("duration", 0.0);  // a number, or a usage error
    overrides.push_back("controller.duration_s=" + *d);
  }
  const std::string config_path = args.value("config").value_or("");
  config::Config cfg = config::load_file_or_default(config_path, overrides);
  if (args.flag("require-rt") && cfg.controller.clock != config::ClockKind::kReal)
    throw cli::UsageError("--require-rt needs the real clock (the simulated clock runs as fast as it can)");
  std::unique_ptr<model::ValveCharacteristic> valve;
  try {
    valve = controller::make_valve_characteristic(
        cfg, config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path());
  } catch (const model::ValveTableError& e) {
    throw config::ConfigError("controller.predictor.valve_table", e.what());
  }
  controller::resolve_offset(cfg, *valve);

  if (args.flag("check-config")) {
    std::cout << "# effective configuration of pneud (u_0 = u_e of Eq. 7 = " << cfg.controller.law.offset_v
              << " V)\n"
              << config::to_yaml(cfg);
    return cli::kExitOk;
  }

  // What this build left out is refused before any output file is created.
#ifndef PNEU_WITH_MODBUS
  if (cfg.hal.backend == config::BackendKind::kModbus)
    throw config::ConfigError("hal.backend", "this pneud was built without the modbus backend");
#endif
#ifndef PNEU_WITH_GPIOD
  if (cfg.hal.gpio.enabled) throw config::ConfigError("hal.gpio.enabled", "this pneud was built without libgpiod");
#endif
#ifndef PNEU_WITH_LCM
  if (args.flag("require-telemetry")) throw cli::UsageError("--require-telemetry: this pneud was built without LCM");
#endif

  std::optional<std::ofstream> events, trajectory;
  if (auto p = args.value("events")) {
    events.emplace(*p);
    if (!*events) throw std::runtime_error(*p + ": cannot create the events file");
  }
  if (auto p = args.value("trajectory")) {
    trajectory.emplace(*p);
    if (!*trajectory) throw std::runtime_error(*p + ": cannot create the trajectory file");
  }
  // The summary file appears whole at the end of the run (written beside it, then renamed): none
  // is there meanwhile, nor when the run fails. A path it cannot be written to fails now.
  const std::optional<std::string> summary_json = args.value("summary-json");
  if (summary_json) {
    if (!std::ofstream(*summary_json)) throw std::runtime_error(*summary_json + ": cannot create the summary file");
    std::filesystem::remove(*summary_json);
  }

  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  const bool real_clock = cfg.controller.clock == config::ClockKind::kReal;
  // The backend: the in-process plant or the I/O module, with the GPIO lines around it when
  // configured (they outlive the run: declared before it).
  std::unique_ptr<hal::Backend> inner;
#ifdef PNEU_WITH_GPIOD
  std::unique_ptr<hal::LibgpiodLines> lines;
#endif
  controller::Run run;
  if (cfg.hal.backend == config::BackendKind::kModbus) {
#ifdef PNEU_WITH_MODBUS
    inner = std::make_unique<hal::ModbusBackend>(cfg.hal.modbus, cfg.sensors);
#endif
  } else if (cfg.hal.gpio.enabled) {
    inner = controller::make_sim_backend(cfg);
  }
  if (cfg.hal.gpio.enabled) {
#ifdef PNEU_WITH_GPIOD
    const auto& g = cfg.hal.gpio;
    lines = std::make_unique<hal::LibgpiodLines>(hal::GpioParams{g.chip, g.estop_line, g.estop_active_low,
                                                                 g.valve_power_line, g.valve_power_active_low, g.consumer});
    run = controller::make_run(cfg, *valve, std::make_unique<hal::GpioBackend>(*inner, *lines));
#endif
  } else if (inner) {
    run = controller::make_run(cfg, *valve, std::move(inner));
  } else {
    run = controller::make_run(cfg, *valve, controller::make_sim_backend(cfg));
  }
  // The runtime's sinks: the files asked for, then LCM.
  std::optional<controller::EventsFile> events_sink;
  std::optional<controller::TrajectoryFile> trajectory_sink;
  if (events) run.runtime->add_sink(events_sink.emplace(*events));
  if (trajectory) run.runtime->add_sink(trajectory_sink.emplace(*trajectory));
  std::function<void(int)> wait_for_input;
  std::function<void(int)> handle_input;
#ifdef PNEU_WITH_LCM
  std::unique_ptr<telemetry::LcmBridge> bridge;
  if (cfg.telemetry.enabled && (real_clock || cfg.telemetry.in_simulated_time)) {
    try {
      bridge = std::make_unique<telemetry::LcmBridge>(cfg, *run.outputs, real_clock && cfg.commands.enabled);
      run.runtime->add_sink(*bridge);
      bridge->set_command_log(run.runtime.get());  // both on the service thread (execute)
      handle_input = [&](int ms) { (void)bridge->handle(ms); };
    } catch (const telemetry::LcmError& e) {
      if (args.flag("require-telemetry")) throw;
      std::fprintf(stderr, "pneud: warning: telemetry off: %s\n", e.what());
    }
  }
#else
  if (cfg.telemetry.enabled && (real_clock || cfg.telemetry.in_simulated_time))
    std::fprintf(stderr, "pneud: warning: telemetry off: this pneud was built without LCM\n");
#endif
  std::unique_ptr<controller::Clock> clock;
  if (cfg.controller.clock == config::ClockKind::kReal) clock = std::make_unique<controller::RealClock>();
  else clock = std::make_unique<controller::SimulatedClock>();
  SystemdNotifier notifier(*run.outputs);
  if (real_clock)
    wait_for_input = [&](int ms) {
      notifier.service();
      if (handle_input) handle_input(ms);
      else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    };
  const bool require_rt = args.flag("require-rt");
  std::function<void()> on_loop_thread;
  if (real_clock)
    on_loop_thread = [&] {
      const auto report = controller::setup_realtime_thread(cfg.controller.realtime, require_rt);
      for (const auto& w : report.warnings) std::fprintf(stderr, "pneud: warning: real time: %s\n", w.c_str());
    };
  const auto wall0 = std::chrono::steady_clock::now();
  try {
    controller::execute(run, cfg, *clock, g_stop, wait_for_input, on_loop_thread);
  } catch (...) {
    // Nothing ran (the module unreachable, real time refused): leave no empty output behind.
    if (run.outputs->heartbeat.load() == 0) {
      const std::pair<std::optional<std::ofstream>*, const char*> outputs[] = {{&events, "events"},
                                                                               {&trajectory, "trajectory"}};
      for (const auto& [stream, option] : outputs)
        if (*stream) {
          (*stream)->close();
          std::error_code ignored;
          std::filesystem::remove(*args.value(option), ignored);
        }
    }
    throw;
  }
  if (g_stop.load()) notifier.stopping();
#ifdef PNEU_WITH_MODBUS
  const auto* modbus = dynamic_cast<const hal::ModbusBackend*>(inner ? inner.get() : run.backend.get());
  if (modbus && !modbus->safe_output_delivery().delivered)  // the journal's, quiet or not
    std::fprintf(stderr,
                 "pneud: warning: the module did not confirm the safe output on closing (%d attempts, last error: %s): "
                 "it may still hold the last command\n",
                 modbus->safe_output_delivery().attempts, modbus->last_error().c_str());
#endif
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();

  if (events) events->flush();
  if (trajectory) trajectory->flush();
  if ((events && !*events) || (trajectory && !*trajectory)) throw std::runtime_error("writing the output failed");

  controller::RunFigures figures;
  figures.version = PNEU_VERSION;
  figures.backend = cfg.hal.backend == config::BackendKind::kModbus ? "modbus" : "sim";
  figures.clock = real_clock ? "real" : "simulated";
  figures.config = config_path.empty() ? "embedded sim.yaml" : config_path;
  figures.u_0_v = cfg.controller.law.offset_v;
  figures.wall_s = wall_s;
  figures.timing = run.timing;
  figures.ticks_dropped = run.outputs->ticks_dropped;
  figures.events_dropped = run.outputs->events_dropped;
#ifdef PNEU_WITH_LCM
  if (bridge) figures.telemetry = bridge->figures();
#endif
#ifdef PNEU_WITH_MODBUS
  if (modbus) {
    const auto& c = modbus->counters();
    const auto d = modbus->safe_output_delivery();
    figures.modbus = controller::ModbusFigures{c.transactions.load(), c.errors.load(), c.reconnects.load(),
                                               c.out_of_range.load(), c.stale_reads.load(), c.max_age_s.load(),
                                               modbus->last_error(), d.attempts,
                                               hal::ModbusBackend::kSafeOutputAttempts, d.delivered};
  }
#endif
  if (summary_json) {
    const std::string partial = *summary_json + ".partial";
    std::ofstream out(partial);
    controller::write_summary_json(out, figures, *run.runtime);
    out.close();
    if (!out) throw std::runtime_error(partial + ": writing the summary file failed");
    std::filesystem::rename(partial, *summary_json);
  }
  if (!args.flag("quiet")) controller::print_summary(stdout, figures, *run.runtime);
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneud", run, argc, argv); }
