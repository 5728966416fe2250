#include "run_files.hpp"

#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "pneu/controller/run_summary.hpp"

namespace pneu::pneud {

RunFiles::RunFiles(const cli::Args& args) {
  const auto create = [](std::optional<File>& file, const std::string& path, const char* what) {
    file.emplace(File{path, std::ofstream(path)});
    if (!file->stream) throw std::runtime_error(path + ": cannot create the " + what + " file");
  };
  if (auto p = args.value("events")) create(events_, *p, "events");
  if (auto p = args.value("trajectory")) create(trajectory_, *p, "trajectory");
  // A path the summary cannot be written to fails now; the file itself appears at the end.
  summary_json_ = args.value("summary-json");
  if (summary_json_) {
    if (!std::ofstream(*summary_json_)) throw std::runtime_error(*summary_json_ + ": cannot create the summary file");
    std::filesystem::remove(*summary_json_);
  }
}

void RunFiles::add_sinks(controller::Runtime& runtime) {
  if (events_) runtime.add_sink(events_sink_.emplace(events_->stream));
  if (trajectory_) runtime.add_sink(trajectory_sink_.emplace(trajectory_->stream));
}

void RunFiles::discard() noexcept {
  for (std::optional<File>* file : {&events_, &trajectory_}) {
    if (!*file) continue;
    (*file)->stream.close();
    std::error_code ignored;
    std::filesystem::remove((*file)->path, ignored);
  }
}

void RunFiles::flush() {
  if (events_) events_->stream.flush();
  if (trajectory_) trajectory_->stream.flush();
  if ((events_ && !events_->stream) || (trajectory_ && !trajectory_->stream))
    throw std::runtime_error("writing the output failed");
}

void RunFiles::write_summary_json(const controller::RunFigures& figures, const controller::Runtime& runtime) const {
  if (!summary_json_) return;
  const std::string partial = *summary_json_ + ".partial";
  std::ofstream out(partial);
  controller::write_summary_json(out, figures, runtime);
  out.close();
  if (!out) throw std::runtime_error(partial + ": writing the summary file failed");
  std::filesystem::rename(partial, *summary_json_);
}

}  // namespace pneu::pneud
