#include "run_files.hpp"

#include <utility>
#include <vector>

#include "pneu/controller/run_summary.hpp"

namespace pneu::pneud {

RunFiles::RunFiles(const cli::Args& args) {
  constexpr const char* kOutputs[] = {"events", "trajectory", "summary-json", "identify"};
  std::vector<std::pair<std::string, std::string>> given;
  for (const char* option : kOutputs)
    if (auto p = args.value(option)) given.emplace_back(std::string("--") + option, *p);
  cli::refuse_same_file(given);
  const auto open = [&](std::optional<cli::OutputFile>& file, const char* option) {
    if (auto p = args.value(option)) file.emplace(*p, std::string("--") + option);
  };
  open(events_, "events");
  open(trajectory_, "trajectory");
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
  for (std::optional<cli::OutputFile>* file : {&events_, &trajectory_, &summary_json_})
    if (*file) (*file)->discard_removing_target();
  if (identified_) identified_->discard();
}

void RunFiles::commit() {
  // Both are put into place, the first error reported after.
  std::optional<std::runtime_error> failed;
  for (std::optional<cli::OutputFile>* file : {&events_, &trajectory_}) {
    if (!*file) continue;
    try {
      (*file)->commit();
    } catch (const std::runtime_error& e) {
      if (!failed) failed.emplace(e);
    }
  }
  if (failed) throw *failed;
}

void RunFiles::write_summary_json(const controller::RunFigures& figures, const controller::Runtime& runtime) {
  if (!summary_json_) return;
  controller::write_summary_json(summary_json_->stream(), figures, runtime);
  summary_json_->commit();
}

}  // namespace pneu::pneud
