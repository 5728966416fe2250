#include "run_files.hpp"

#include <utility>
#include <vector>

#include "pneu/controller/run_summary.hpp"

namespace pneu::pneud {

namespace {

// Whether an output at `path` is a regular file (or none yet): one that has a file beside it. A
// live output (a FIFO, a device, standard output) has none. A path that cannot be written is
// refused when the output is opened.
bool written_as_a_file(const std::string& path, const char* option) {
  try {
    const cli::OutputTarget t = cli::resolve_output(path, option);
    return t.fd_alias < 0 && (!t.exists || t.regular);
  } catch (const cli::UsageError&) {
    return false;
  }
}

}  // namespace

RunFiles::RunFiles(const cli::Args& args) {
  constexpr const char* kOutputs[] = {"events", "trajectory", "summary-json", "identify"};
  std::vector<std::pair<std::string, std::string>> given;
  for (const char* option : kOutputs)
    if (auto p = args.value(option)) given.emplace_back(std::string("--") + option, *p);
  for (const char* option : {"events", "trajectory"})
    if (auto p = args.value(option); p && written_as_a_file(*p, option))
      given.emplace_back(std::string("--") + option + "'s configuration", effective_configuration_path(*p));
  cli::refuse_same_file(given);
  const auto open = [&](std::optional<cli::OutputFile>& file, const char* option) {
    if (auto p = args.value(option)) file.emplace(*p, std::string("--") + option);
  };
  open(events_, "events");
  open(trajectory_, "trajectory");
  // A live output (a FIFO, a device, standard output) has no file beside it.
  const auto open_beside = [](std::optional<cli::OutputFile>& config, const std::optional<cli::OutputFile>& file,
                              const char* option) {
    if (file && !file->direct())
      config.emplace(effective_configuration_path(file->path().string()), std::string("--") + option + "'s configuration");
  };
  open_beside(events_config_, events_, "events");
  open_beside(trajectory_config_, trajectory_, "trajectory");
  open(summary_json_, "summary-json");  // a path the summary cannot be written to fails now
  open(identified_, "identify");
}

RunFiles::~RunFiles() {
  if (summary_json_) summary_json_->discard_removing_target();  // does nothing once committed
}

void RunFiles::add_sinks(controller::Runtime& runtime) {
  if (events_) runtime.add_sink(events_sink_.emplace(events_->stream()));
  if (trajectory_) runtime.add_sink(trajectory_sink_.emplace(trajectory_->stream()));
}

void RunFiles::discard() noexcept {
  // No record of an earlier run is left to be taken for this one's (an earlier identified
  // configuration is kept: it is no record of a run).
  for (std::optional<cli::OutputFile>* file :
       {&events_, &trajectory_, &summary_json_, &events_config_, &trajectory_config_})
    if (*file) (*file)->discard_removing_target();
  if (identified_) identified_->discard();
}

void RunFiles::commit() {
  // Both are put into place, the first error reported after.
  std::optional<std::runtime_error> failed;
  for (std::optional<cli::OutputFile>* file : {&events_, &trajectory_, &events_config_, &trajectory_config_}) {
    if (!*file) continue;
    try {
      (*file)->commit();
    } catch (const std::runtime_error& e) {
      if (!failed) failed.emplace(e);
    }
  }
  if (failed) throw *failed;
}

void RunFiles::write_effective_configuration(const std::string& yaml) {
  for (std::optional<cli::OutputFile>* file : {&events_config_, &trajectory_config_})
    if (*file) (*file)->stream() << yaml;
}

void RunFiles::write_summary_json(const controller::RunFigures& figures, const controller::Runtime& runtime) {
  if (!summary_json_) return;
  controller::write_summary_json(summary_json_->stream(), figures, runtime);
  summary_json_->commit();
}

}  // namespace pneu::pneud
