// The files pneud writes for a run: --events and --trajectory, sinks of the runtime created before
// the run starts (a path that cannot be written fails then) and removed when nothing ran; and
// --summary-json, written whole at the end (beside its path, then renamed): none is there meanwhile,
// nor when the run fails.
#pragma once

#include <fstream>
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
  /// Creates the files `args` asks for. Throws std::runtime_error naming one it cannot create.
  explicit RunFiles(const cli::Args& args);
  RunFiles(const RunFiles&) = delete;
  RunFiles& operator=(const RunFiles&) = delete;

  /// Adds the events and trajectory sinks, those asked for, to `runtime`.
  void add_sinks(controller::Runtime& runtime);
  /// After a run that failed before its first tick: leaves no empty file behind.
  void discard() noexcept;
  /// Flushes the sinks' files. Throws std::runtime_error when writing them failed.
  void flush();
  /// --summary-json, when asked for. Throws std::runtime_error when writing it failed.
  void write_summary_json(const controller::RunFigures& figures, const controller::Runtime& runtime) const;

 private:
  struct File {
    std::string path;
    std::ofstream stream;
  };
  std::optional<File> events_, trajectory_;
  std::optional<controller::EventsFile> events_sink_;
  std::optional<controller::TrajectoryFile> trajectory_sink_;
  std::optional<std::string> summary_json_;
};

}  // namespace pneu::pneud
