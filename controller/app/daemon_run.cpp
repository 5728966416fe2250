#include "daemon_run.hpp"
#include "pneu/config/config.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <thread>

#include "pneu/backends/factory.hpp"
#include "pneu/config/text.hpp"
#include "pneu/controller/journal.hpp"
#include "pneu/controller/realtime.hpp"
#include "pneu/controller/run_summary.hpp"
#include "systemd_notifier.hpp"

namespace pneu::pneud {

namespace {

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop.store(true); }

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
  f.link_transactions_before_time = run.link_transactions_before_time;
  f.fault_at_end = run.loop->fault_cause();
  return f;
}

// The start-up line of a real bench: the movement test's verdict (starting armed), that it runs at
// the first ARM (starting disarmed: the loop runs it, JournalLines says how it went), or that the
// key skipped it.
void say_movement_test_plan(const config::Config& cfg) {
  if (controller::movement_test_at_first_arm(cfg))
    std::fprintf(stderr, "pneud: movement test: at the first ARM (controller.start_armed: false): open-loop pulses "
                         "check the wiring before the law drives the valves\n");
  else if (cfg.hal.backend == config::BackendKind::kModbus && !controller::movement_test_runs(cfg))
    std::fprintf(stderr, "pneud: movement test: skipped (controller.movement_test.enabled: false): the wiring is not "
                         "checked before closed loop\n");
}

}  // namespace

DaemonRun::DaemonRun(const cli::Args& args, const std::string& config_path, const assembly::RunSpec& spec)
    : args_(args), config_path_(config_path), quiet_(args.flag("quiet")) {
  const config::Config& cfg = spec.config();
  // What this build left out is refused before any output file is created.
  backends::require_built(cfg);
  Telemetry::require_built(args.flag("require-telemetry"));
  if (cfg.hal.backend == config::BackendKind::kModbus && cfg.hal.modbus.module_watchdog_s == 0.0)  // docs/serve.md
    std::fprintf(stderr, "pneud: warning: hal.modbus.module_watchdog_s is 0: no module watchdog stated; should pneud "
                         "die, the module holds its last command until a watchdog of its own trips\n");
  files_.emplace(args);  // before the run: a path that cannot be written, or two outputs on one file, fail here
  files_->write_effective_configuration(effective_configuration(cfg, config_path));
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  run_.emplace(assembly::AssembledRun::on_configured_backend(spec));
  files_->add_sinks(run_->runtime());
  run_->emplace_sink<controller::JournalLines>(stderr);  // faults, resets, arming, holds, the link: at once, quiet or not
}

DaemonRun::~DaemonRun() = default;

bool DaemonRun::real_clock() const noexcept { return config().controller.clock == config::ClockKind::kReal; }

bool DaemonRun::interrupted() const noexcept { return g_stop.load(); }

controller::RunFigures DaemonRun::execute(const std::atomic<bool>* fault_stop, bool summary_later) {
  const config::Config& cfg = config();
  controller::Run& run = run_->run();
  const bool real = real_clock();
  telemetry_ = Telemetry::start(cfg, run, args_.flag("require-telemetry"));
  // One controller per bench: another pneud's health on these channels refuses the start, before
  // anything is driven or reported ready. Where none can be heard, a bench's run says so.
  std::string why_not_checked = "LCM telemetry is off";
  if (telemetry_) {
    why_not_checked.clear();
    if (const auto other = telemetry_->another_controller(1.5 * cfg.telemetry.health_period_s, why_not_checked)) {
      files_->discard();
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
  if (real) {
    wait_for_input = [&](int ms) {
      notifier.service();
      if (telemetry_) telemetry_->handle(ms);
      else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    };
    const bool require_rt = args_.flag("require-rt");
    on_loop_thread = [&cfg, require_rt] {
      const auto report = controller::setup_realtime_thread(cfg.controller.realtime, require_rt);
      for (const auto& w : report.warnings) std::fprintf(stderr, "pneud: warning: real time: %s\n", w.c_str());
    };
  }
  say_movement_test_plan(cfg);
  const auto said_movement_test = [](const controller::MovementTestResult& r) {
    if (r.passed() || r.finding == controller::MovementFinding::kInterrupted)  // a finding: the error line says it
      std::fprintf(stderr, "pneud: movement test %s\n", controller::describe(r).c_str());
  };
  const auto clock = controller::make_clock(cfg.controller.clock);
  const auto wall0 = std::chrono::steady_clock::now();
  try {
    // With `fault_stop` (an identification run), the run also stops at its first fault (the loop
    // holds the safe output): on the simulated clock that flag alone stops it; on the real clock
    // the service thread's wait raises either.
    std::atomic<bool> stop_either{false};
    std::function<void(int)> wait = wait_for_input;
    if (fault_stop != nullptr) {
      const std::function<void(int)> inner = wait_for_input;
      wait = [&, inner](int ms) {
        if (inner) inner(ms);
        else std::this_thread::sleep_for(std::chrono::milliseconds(ms));
        if (g_stop.load() || fault_stop->load()) stop_either.store(true);
      };
    }
    const std::atomic<bool>& stop = fault_stop == nullptr ? g_stop : real ? stop_either : *fault_stop;
    run_->execute(*clock, stop, wait, on_loop_thread, said_movement_test);
  } catch (...) {
    if (run.outputs->heartbeat.load() == 0) {
      files_->discard();  // nothing ran: no empty output left
    } else {
      try {
        files_->commit();  // what happened until the error is kept
      } catch (const std::exception& e) {
        std::fprintf(stderr, "pneud: %s\n", e.what());
      }
    }
    throw;
  }
  if (g_stop.load()) notifier.stopping();
  controller::RunFigures figures =
      figures_of(cfg, config_path_, run, std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count());
  if (figures.modbus && !figures.modbus->safe_output_delivered)  // the journal's, quiet or not
    std::fprintf(stderr,
                 "pneud: warning: the module did not confirm the safe output on closing (%d attempts, last error: %s): "
                 "it may still hold the last command\n",
                 figures.modbus->safe_output_attempts, figures.modbus->last_error.c_str());
  files_->commit();
  if (telemetry_) figures.telemetry = telemetry_->figures();
  files_->write_summary_json(figures, *run.runtime);
  if (!summary_later) print_summary(figures);
  return figures;
}

void DaemonRun::print_summary(const controller::RunFigures& figures) const {
  if (!quiet_) controller::print_summary(stdout, figures, *run_->run().runtime);
}

int DaemonRun::ended(const controller::RunFigures& figures) const {
  const controller::RunEnding ending = controller::run_ending(figures);
  if (ending != controller::RunEnding::kOk)
    controller::journal_line(stderr, controller::Priority::kErr, controller::ending_text(figures, run_->runtime()));
  return controller::exit_code(ending);
}

}  // namespace pneu::pneud
