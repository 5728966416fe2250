// The files pneud writes for a run, each opened by cli::OutputFile (links followed; a device, a
// FIFO or /dev/stdout written directly): --events and --trajectory, sinks of the runtime opened
// before the run starts (a path that cannot be written fails then) and written beside their path,
// then renamed into place when the run ends, however it ends once it started (nothing is left when
// it never started); --summary-json, written whole at the end (when the run fails, none is
// left: not an earlier run's either); and --identify's YAML. Beside the events file and the
// trajectory file (regular files), PATH.config.yaml: the run's effective configuration, what the
// loop ran with (--set applied, u_0 resolved, an identification run's own set points), which the
// tools that read the run (pneu_plots.py, pneu-identify) take in place of the source YAML; opened,
// put into place and discarded with its file. Two of them naming the same file are refused before
// anything is opened.
#pragma once

#include <optional>
#include <string>

#include "pneu/config/cli.hpp"
#include "pneu/controller/events_file.hpp"
#include "pneu/controller/run_figures.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/controller/trajectory_file.hpp"

namespace pneu::pneud {

class RunFiles {
 public:
  /// Opens the files `args` asks for. Throws cli::UsageError when two name the same file,
  /// std::runtime_error naming one it cannot create.
  explicit RunFiles(const cli::Args& args);
  RunFiles(const RunFiles&) = delete;
  RunFiles& operator=(const RunFiles&) = delete;
  /// A summary not written (the run failed) leaves no earlier run's summary at its path.
  ~RunFiles();

  /// Adds the events and trajectory sinks, those asked for, to `runtime`.
  void add_sinks(controller::Runtime& runtime);
  /// After a run that failed before its first tick: leaves no events, trajectory or summary at
  /// their paths (not an earlier run's either); an earlier --identify file is left as it was.
  void discard() noexcept;
  /// The effective configuration, written beside the events and the trajectory file.
  void write_effective_configuration(const std::string& yaml);
  /// The path of the effective configuration beside an output at `path`.
  [[nodiscard]] static std::string effective_configuration_path(const std::string& path) {
    return path + ".config.yaml";
  }
  /// Puts the events and trajectory files, and their configurations, into place. Throws std::runtime_error when writing them
  /// failed.
  void commit();
  /// --summary-json, when asked for. Throws std::runtime_error when writing it failed.
  void write_summary_json(const controller::RunFigures& figures, const controller::Runtime& runtime);
  /// --identify's file, when asked for.
  [[nodiscard]] cli::OutputFile* identified() { return identified_ ? &*identified_ : nullptr; }

 private:
  std::optional<cli::OutputFile> events_, trajectory_, summary_json_, identified_;
  std::optional<cli::OutputFile> events_config_, trajectory_config_;  ///< beside them
  std::optional<controller::EventsFile> events_sink_;
  std::optional<controller::TrajectoryFile> trajectory_sink_;
};

}  // namespace pneu::pneud
