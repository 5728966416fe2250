// Plumbing shared by the command-line programs: option parsing with clear usage errors, and output
// files, opened the same way by every program.
#pragma once

#include <filesystem>
#include <cstdint>
#include <cstdio>
#include <ostream>
#include <streambuf>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
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
  /// The command as given: the program by its file name, then every argument, each quoted for a
  /// POSIX shell where it needs it ("pneud --identify out.yaml --set 'a.b=[x, y]'").
  [[nodiscard]] const std::string& command_line() const noexcept { return command_line_; }

 private:
  std::map<std::string, std::vector<std::string>> values_;
  std::string command_line_;
};

/// Runs a program's body and turns what it throws into the exit codes above, with the message on
/// stderr prefixed by the program's name: UsageError and config::ConfigError are bad input (2),
/// anything else a failure (1).
int run_main(const char* program, int (*body)(int, char**), int argc, char** argv) noexcept;

/// How an output that names a regular file (or nothing yet) is written.
enum class OutputKind {
  kWhole,  ///< into a temporary file beside the target, renamed over it by commit(): whole or not at all
  kLive,   ///< into the target itself as it goes (a record read while it grows, kept after a SIGKILL)
};

/// Where an output path leads, its symbolic links followed (a dangling one: to the file it names).
struct OutputTarget {
  std::filesystem::path target;  ///< the file written: the path with its links followed, absolute
  bool exists = false;
  bool regular = false;          ///< an existing regular file (it, or nothing yet, is written as OutputKind says)
  int fd_alias = -1;             ///< /dev/stdout, /dev/stderr, /dev/fd/N, /proc/self/fd/N: N, written to directly
  std::uint64_t device = 0, inode = 0;  ///< of an existing regular file
};
/// Follows `path`'s symbolic links. Throws UsageError when it cannot lead to a writable file (a
/// directory, a loop of links, a directory that does not exist), naming `option`.
OutputTarget resolve_output(const std::filesystem::path& path, const std::string& option = {});

/// Refuses (UsageError) two outputs of one invocation that name the same file, after their links are
/// followed (or the same device and inode): `outputs` holds each given output's option and path.
/// Devices, FIFOs and the standard streams may be shared.
void refuse_same_file(const std::vector<std::pair<std::string, std::string>>& outputs);

/// An output file of a pneu program, opened the same way by all of them. Its path's links are
/// followed. A regular file (or none yet) is written as `kind` says: kWhole into a temporary file
/// beside the resolved target, renamed over it by commit() with the existing file's mode and owner
/// (a new file: the umask's mode); destroyed without commit (an error, an exception), the temporary
/// file is removed and the target left as it was. kLive writes the target itself. Anything else (a
/// character or block device, a FIFO, a socket, /dev/stdout) is opened and written directly: never
/// renamed over, never removed. Write errors (a full disk, /dev/full) throw at commit().
class OutputFile {
 public:
  /// Opens it (a FIFO: waits for its reader). Throws std::runtime_error naming `option` (or the
  /// path) when it cannot.
  explicit OutputFile(std::filesystem::path path, std::string option = {}, OutputKind kind = OutputKind::kWhole);
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  [[nodiscard]] std::ostream& stream() { return out_; }
  /// The same file for a C stdio writer (fprintf); use one of stream() and c_file(), not both.
  [[nodiscard]] std::FILE* c_file();
  /// Flushes and checks what was written, then (kWhole, a regular file) renames it into place.
  /// Throws std::runtime_error on failure; the second call does nothing.
  void commit();
  /// Gives up the output: a kWhole regular file's temporary file is removed (the target is left as
  /// it was); a live or direct output is closed as it is.
  void discard() noexcept;
  /// discard(), and a regular file the path named is removed too: no figures of an earlier run
  /// are left to be taken for this one's. Devices, FIFOs and standard streams are left alone.
  void discard_removing_target() noexcept;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  /// Whether it is written directly (a device, a FIFO, a standard stream), not as a regular file.
  [[nodiscard]] bool direct() const { return target_.fd_alias >= 0 || (target_.exists && !target_.regular); }

 private:
  class Buffer : public std::streambuf {
   public:
    explicit Buffer(int fd);
    int fd() const { return fd_; }
    int error() const { return error_; }
    void close() noexcept;

   protected:
    int_type overflow(int_type c) override;
    int sync() override;

   private:
    int fd_ = -1;
    int error_ = 0;
    std::vector<char> buffer_;
  };
  [[nodiscard]] std::string name() const;
  std::filesystem::path path_;
  std::string option_;
  OutputTarget target_;
  OutputKind kind_;
  std::filesystem::path temp_;  ///< kWhole, a regular file: written here first
  std::optional<Buffer> buffer_;
  std::ostream out_{nullptr};
  std::FILE* c_file_ = nullptr;
  bool done_ = false;
};

}  // namespace pneu::cli
