// Test support: child processes with their output in files, CSV files read by column name, the
// figures of a pneud run (--summary-json).
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "support/json.hpp"

extern char** environ;

namespace pneu::test {

namespace fs = std::filesystem;

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Whether `holds()` is true within `limit`, asked every `every` (and once at the limit): the
/// tests' wait for a sign from a child instead of a sleep.
template <typename Predicate>
bool eventually(Predicate&& holds, std::chrono::milliseconds limit,
                std::chrono::milliseconds every = std::chrono::milliseconds(10)) {
  const auto until = std::chrono::steady_clock::now() + limit;
  for (;;) {
    if (holds()) return true;
    if (std::chrono::steady_clock::now() >= until) return false;
    std::this_thread::sleep_for(every);
  }
}

/// Whether the file at `p` holds `text` within `limit`, polled every 10 ms: a child's sign that it
/// is ready, or that something happened.
inline bool wait_for_text(const fs::path& p, const std::string& text, std::chrono::milliseconds limit) {
  return eventually([&] { return slurp(p).find(text) != std::string::npos; }, limit);
}

// A fresh directory for one test, named after it (and this process): removed when the test
// passed, kept for a look when it failed. Construct it in the fixture (the test is known then).
class TestDir {
 public:
  explicit TestDir(const std::string& prefix) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = info ? info->name() : "run";
    for (char& ch : name)
      if (ch == '/') ch = '_';  // parameterised tests: "Suite/Name/Param"
    path_ = fs::temp_directory_path() / (prefix + name + "_" + std::to_string(getpid()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TestDir() {
    std::error_code ignored;
    if (!::testing::Test::HasFailure()) fs::remove_all(path_, ignored);
  }
  TestDir(const TestDir&) = delete;
  TestDir& operator=(const TestDir&) = delete;
  operator const fs::path&() const noexcept { return path_; }
  [[nodiscard]] const fs::path& path() const noexcept { return path_; }
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

// A child process with its output in files; killed if still running when destroyed.
struct Child {
  pid_t pid = -1;
  static Child spawn(const std::vector<std::string>& args, const fs::path& out, const fs::path& err) {
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    Child c;
    if (posix_spawnp(&c.pid, argv[0], &fa, nullptr, argv.data(), environ) != 0) c.pid = -1;
    posix_spawn_file_actions_destroy(&fa);
    return c;
  }
  int wait() {
    int status = 0;
    if (pid <= 0 || waitpid(pid, &status, 0) != pid) return -1;
    pid = -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  ~Child() {
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

// A CSV file as rows of named cells.
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::size_t col(const std::string& name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return i;
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
  static Csv read(const fs::path& p) {
    std::ifstream in(p);
    return parse(in);
  }
  static Csv parse(const std::string& text) {
    std::istringstream in(text);
    return parse(in);
  }
  static Csv parse(std::istream& in) {
    Csv c;
    std::string line;
    bool first = true;
    while (std::getline(in, line)) {
      std::vector<std::string> cells;
      std::string cell;
      bool quoted = false;
      for (std::size_t i = 0; i < line.size(); ++i) {
        const char ch = line[i];
        if (quoted) {
          if (ch == '"' && i + 1 < line.size() && line[i + 1] == '"') cell += '"', ++i;
          else if (ch == '"') quoted = false;
          else cell += ch;
        } else if (ch == '"') {
          quoted = true;
        } else if (ch == ',') {
          cells.push_back(cell);
          cell.clear();
        } else {
          cell += ch;
        }
      }
      cells.push_back(cell);
      if (first) c.header = cells, first = false;
      else c.rows.push_back(cells);
    }
    return c;
  }
};

/// A loopback TCP port nobody listens on right now.
inline int free_port() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  const int port = ntohs(a.sin_port);
  close(fd);
  return port;
}

/// pneud arguments that turn its loop-timing supervision off (controller.supervisor.overruns_in_a_row
/// and max_tick_interval_s set to 0), for tests of something else run on the real clock. A shared
/// machine stalls a process for tens of milliseconds now and then (62 ms in one CI run). On a bench
/// that rightly latches an overrun fault, but it would fail a test about commands or Modbus. The
/// supervision itself is tested in test_supervisor, and end to end by the PneudStall tests (SIGSTOP).
inline std::vector<std::string> loop_timing_faults_off(std::vector<std::string> args) {
  for (const char* a : {"--set", "controller.supervisor.overruns_in_a_row=0", "--set",
                        "controller.supervisor.max_tick_interval_s=0"})
    args.emplace_back(a);
  return args;
}

/// pneud arguments `args` and, after them (so that a test's own, added next, still win), those for
/// HIL tests whose subject is not the Modbus link: a response timeout and a sample age limit of
/// 0.5 s, and a comms fault after 2 s of bad samples. hil.yaml's 20 ms, 20 ms and 50 ms are a
/// bench's: on a shared machine a stall of the plant's process past 20 ms is a timeout, the
/// reconnection backs off, and the samples stay bad past 50 ms, a comms fault in a test of
/// something else. Tests of the link keep hil.yaml's values.
inline std::vector<std::string> link_stalls_tolerated(std::vector<std::string> args) {
  for (const char* a : {"--set", "hal.modbus.response_timeout_s=0.5", "--set", "hal.modbus.max_sample_age_s=0.5",
                        "--set", "controller.comms_fault_after_s=2"})
    args.emplace_back(a);
  return args;
}

/// The figures of a pneud run that the tests check, from its --summary-json file (docs/pneud.md
/// describes its members; the file appears whole at the end of the run).
struct PneudSummary {
  bool has_loop = false, has_modbus = false;  ///< the file was there; the run was on the modbus backend
  unsigned long long ticks = 0, overruns = 0, skipped = 0;
  unsigned long long transactions = 0, errors = 0, reconnects = 0, out_of_range = 0, stale = 0;
  double rate_per_s = 0.0, oldest_ms = 0.0;
  /// CLOCK_MONOTONIC at the loop's time 0 [s] (real clock): loop time t is monotonic t + this.
  double epoch_monotonic_s = 0.0;
  bool safe_output_delivered = false;
  unsigned long long safe_output_attempts = 0;

  /// Throws when the file is there but is not the JSON pneud writes.
  static PneudSummary read(const fs::path& path) {
    PneudSummary s;
    if (!fs::exists(path)) return s;
    const Json j = Json::read(path);
    const Json& loop = j["loop"];
    s.has_loop = true;
    s.ticks = loop["ticks"].count();
    s.overruns = loop["overruns"].count();
    s.skipped = loop["deadlines_skipped"].count();
    s.epoch_monotonic_s = loop["epoch_monotonic_s"].is_null() ? NAN : loop["epoch_monotonic_s"].number();
    const Json& mb = j["modbus"];
    if (mb.is_null()) return s;
    s.has_modbus = true;
    s.transactions = mb["transactions"].count();
    s.rate_per_s = mb["transactions_per_s"].number();
    s.errors = mb["errors"].count();
    s.reconnects = mb["reconnects"].count();
    s.out_of_range = mb["samples_out_of_range"].count();
    s.stale = mb["stale_reads"].count();
    s.oldest_ms = mb["oldest_sample_ms"].number();
    s.safe_output_delivered = mb["safe_output_on_closing"]["delivered"].flag();
    s.safe_output_attempts = mb["safe_output_on_closing"]["attempts"].count();
    return s;
  }
};

}  // namespace pneu::test
