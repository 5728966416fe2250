// Plumbing shared by the command-line programs: option parsing with clear usage errors, and output
// files that appear whole or not at all.
#pragma once

#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace pneu::cli {

/// Exit codes of every pneu program (0, 1, 2), and those only pneud gives (3, 4).
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;    ///< a run failed after it started (I/O, hardware)
inline constexpr int kExitBadInput = 2;   ///< bad command line, config or input file: nothing was run
/// pneud: the run ended with a fault still latched (its outputs in the safe state, the summary
/// naming the cause).
inline constexpr int kExitFaulted = 3;
/// pneud: the module did not confirm the safe output on closing (it may still hold the last
/// command); wins over kExitFaulted when both hold.
inline constexpr int kExitSafeOutputUnconfirmed = 4;

/// Bad command line or input file; the message is for the user.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Parses "--name value", "--name=value" and "--flag" options. Unknown options are errors.
class Args {
 public:
  /// `value_options` take a value, `flags` do not, `repeated` may appear several times.
  Args(int argc, char** argv, int first, std::vector<std::string> value_options,
       std::vector<std::string> flags, std::vector<std::string> repeated = {});

  [[nodiscard]] bool flag(const std::string& name) const;
  [[nodiscard]] std::optional<std::string> value(const std::string& name) const;
  /// The value, or a UsageError naming the missing option.
  [[nodiscard]] std::string required(const std::string& name) const;
  [[nodiscard]] double number(const std::string& name, double fallback) const;
  [[nodiscard]] std::vector<std::string> all(const std::string& name) const;

 private:
  std::map<std::string, std::vector<std::string>> values_;
};

/// Runs a program's body and turns what it throws into the exit codes above, with the message on
/// stderr prefixed by the program's name: UsageError and config::ConfigError are bad input (2),
/// anything else a failure (1).
int run_main(const char* program, int (*body)(int, char**), int argc, char** argv) noexcept;

/// A file written beside its final path and renamed into place by commit(); destroyed without
/// commit (an error, an exception), it removes the partial file, so nothing half-written is left.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  [[nodiscard]] std::ofstream& stream() { return out_; }
  /// Flushes, checks the stream and renames into place. Throws std::runtime_error on failure.
  void commit();
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  std::filesystem::path temp_;
  std::ofstream out_;
  bool committed_ = false;
};

}  // namespace pneu::cli
