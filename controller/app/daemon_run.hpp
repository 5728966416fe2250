// What every run of pneud does around the run assembly::AssembledRun builds, whatever its mode
// (the configured set points, --identify's, learning online): what this build left out refused,
// the output files (the effective configuration beside them), SIGINT and SIGTERM, the journal's
// lines, LCM (one controller per bench), systemd, the real-time set-up, the clock; then the
// summary, and the ending said and turned into the exit code.
#pragma once

#include <atomic>
#include <memory>
#include <optional>
#include <string>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/cli.hpp"
#include "pneu/controller/run_figures.hpp"
#include "run_files.hpp"
#include "telemetry.hpp"

namespace pneu::pneud {

class DaemonRun {
 public:
  /// Refuses what this build left out (before any output file), opens the output files `args`
  /// asks for and writes the effective configuration beside them, catches SIGINT and SIGTERM, and
  /// assembles the run of `spec` on the configured backend, its sinks the files' and the
  /// journal's lines (the mode's own come next: assembled()).
  DaemonRun(const cli::Args& args, const std::string& config_path, const assembly::RunSpec& spec);
  DaemonRun(const DaemonRun&) = delete;
  DaemonRun& operator=(const DaemonRun&) = delete;
  ~DaemonRun();

  [[nodiscard]] assembly::AssembledRun& assembled() noexcept { return *run_; }
  [[nodiscard]] const config::Config& config() const noexcept { return run_->config(); }
  [[nodiscard]] bool real_clock() const noexcept;
  [[nodiscard]] RunFiles& files() noexcept { return *files_; }
  [[nodiscard]] bool quiet() const noexcept { return quiet_; }
  /// Whether SIGINT or SIGTERM asked the run to stop.
  [[nodiscard]] bool interrupted() const noexcept;

  /// Starts LCM (another controller heard on its channels: refused, before anything is driven),
  /// runs the run to its end on the configured clock, puts the files into place (those of a run
  /// that failed once started, too) and writes the summary (print_summary(), unless
  /// `summary_later`: the mode prints it after what it has to say first). With `fault_stop`, that
  /// flag stops the run as well (an identification run's first fault).
  [[nodiscard]] controller::RunFigures execute(const std::atomic<bool>* fault_stop = nullptr, bool summary_later = false);
  /// The run's summary, on stdout unless --quiet.
  void print_summary(const controller::RunFigures& figures) const;

  /// A fault still latched, or the safe output not confirmed: said last on stderr. The exit code.
  [[nodiscard]] int ended(const controller::RunFigures& figures) const;

 private:
  const cli::Args& args_;
  std::string config_path_;
  bool quiet_ = false;
  std::optional<RunFiles> files_;
  std::optional<assembly::AssembledRun> run_;
  std::unique_ptr<Telemetry> telemetry_;
};

}  // namespace pneu::pneud
