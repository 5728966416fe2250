#include "pneu/config/cli.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <iostream>

#include "pneu/config/config.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <cstdlib>

namespace pneu::cli {

Args::Args(int argc, char** argv, int first, std::vector<std::string> value_options,
           std::vector<std::string> flags, std::vector<std::string> repeated) {
  const auto contains = [](const std::vector<std::string>& v, const std::string& s) {
    return std::find(v.begin(), v.end(), s) != v.end();
  };
  // Where an unknown option points: the program's (and its command's) --help.
  std::string help = argc > 0 ? std::filesystem::path(argv[0]).filename().string() : std::string("the program");
  if (first > 1 && argc > 1) help += std::string(" ") + argv[1];
  help = " (see " + help + " --help)";
  command_line_ = argc > 0 ? std::filesystem::path(argv[0]).filename().string() : std::string();
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    const bool plain = !word.empty() && word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                                "0123456789-_.,/=:+@%") == std::string::npos;
    std::string quoted = "'";
    for (const char c : word) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    command_line_ += " " + (plain ? word : quoted + "'");
  }
  for (int i = first; i < argc; ++i) {
    std::string arg = argv[i];
    if (arg == "-h" && contains(flags, "help")) arg = "--help";
    if (arg.rfind("--", 0) != 0 || arg.size() == 2)
      throw UsageError("unexpected argument '" + arg + "'" + help);
    std::string name = arg.substr(2);
    std::optional<std::string> inline_value;
    if (const auto eq = name.find('='); eq != std::string::npos) {
      inline_value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    if (contains(flags, name)) {
      if (inline_value) throw UsageError("--" + name + " takes no value");
      values_[name].push_back("");
      continue;
    }
    if (!contains(value_options, name) && !contains(repeated, name))
      throw UsageError("unknown option --" + name + help);
    if (!inline_value) {
      if (i + 1 >= argc) throw UsageError("--" + name + " needs a value");
      inline_value = argv[++i];
    }
    if (!contains(repeated, name) && values_.count(name))
      throw UsageError("--" + name + " given twice");
    values_[name].push_back(*inline_value);
  }
}

bool Args::flag(const std::string& name) const { return values_.count(name) != 0; }

std::optional<std::string> Args::value(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second.back();
}

std::string Args::required(const std::string& name) const {
  auto v = value(name);
  if (!v) throw UsageError("missing --" + name);
  return *v;
}

double Args::number(const std::string& name, double fallback) const {
  const auto v = value(name);
  if (!v) return fallback;
  char* end = nullptr;
  const double d = std::strtod(v->c_str(), &end);
  if (v->empty() || *end != '\0' || !std::isfinite(d))
    throw UsageError("--" + name + ": '" + *v + "' is not a finite number");
  return d;
}

std::vector<std::string> Args::all(const std::string& name) const {
  const auto it = values_.find(name);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

int run_main(const char* program, int (*body)(int, char**), int argc, char** argv) noexcept {
  try {
    return body(argc, argv);
  } catch (const UsageError& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitBadInput;
  } catch (const config::ConfigError& e) {
    std::cerr << program << ": config: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return kExitFailure;
  } catch (...) {
    std::cerr << program << ": unknown failure\n";
    return kExitFailure;
  }
}

// --- Output files ---------------------------------------------------------------------------------

namespace {

namespace fs = std::filesystem;

std::string quoted_option(const std::string& option, const fs::path& path) {
  return option.empty() ? path.string() : option + " " + path.string();
}

// /dev/stdout, /dev/stderr, /dev/fd/N and /proc/self/fd/N: the descriptor N (as the kernel would
// reach it by the link), or -1.
int fd_alias(const fs::path& path) {
  const std::string s = path.lexically_normal().string();
  if (s == "/dev/stdin") return 0;
  if (s == "/dev/stdout") return 1;
  if (s == "/dev/stderr") return 2;
  for (const std::string prefix : {"/dev/fd/", "/proc/self/fd/", "/proc/thread-self/fd/"}) {
    if (s.rfind(prefix, 0) != 0 || s.size() == prefix.size() || s.size() > prefix.size() + 6) continue;
    const std::string digits = s.substr(prefix.size());
    if (digits.find_first_not_of("0123456789") != std::string::npos) continue;
    return std::stoi(digits);
  }
  return -1;
}

}  // namespace

OutputTarget resolve_output(const fs::path& path, const std::string& option) {
  const auto bad = [&](const std::string& why) { return UsageError(quoted_option(option, path) + ": " + why); };
  if (path.empty()) throw bad("an empty path");
  OutputTarget t;
  if (const int fd = fd_alias(path); fd >= 0) {
    struct stat st {};
    if (::fstat(fd, &st) != 0) throw bad("the descriptor " + std::to_string(fd) + " is not open");
    t.target = path;
    t.exists = true;
    t.fd_alias = fd;
    t.device = st.st_dev;
    t.inode = st.st_ino;
    return t;  // never regular: written to the descriptor, whatever it holds
  }
  std::error_code ec;
  fs::path cur = fs::absolute(path, ec);
  if (ec) throw bad(ec.message());
  for (int hops = 0;; ++hops) {
    if (hops > 40) throw bad("too many levels of symbolic links");
    struct stat st {};
    if (::lstat(cur.c_str(), &st) != 0) {
      if (errno != ENOENT) throw bad(std::strerror(errno));
      // Nothing there (or a dangling link's target): a new file, in a directory that must exist.
      const fs::path dir = cur.parent_path();
      if (!fs::is_directory(dir, ec)) throw bad("cannot open for writing: the directory " + dir.string() + " does not exist");
      t.target = fs::weakly_canonical(cur, ec);
      if (ec) t.target = cur;
      return t;
    }
    if (S_ISLNK(st.st_mode)) {
      const fs::path to = fs::read_symlink(cur, ec);
      if (ec) throw bad(ec.message());
      // /proc's links (a descriptor's, "pipe:[...]") are not paths: the kernel follows them.
      if (cur.string().rfind("/proc/", 0) == 0) break;
      cur = to.is_absolute() ? to : cur.parent_path() / to;
      continue;
    }
    break;
  }
  struct stat st {};
  if (::stat(cur.c_str(), &st) != 0) throw bad(std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw bad("cannot open for writing: it is a directory");
  t.target = S_ISREG(st.st_mode) ? fs::weakly_canonical(cur, ec) : cur;
  if (ec) t.target = cur;
  t.exists = true;
  t.regular = S_ISREG(st.st_mode);
  t.device = st.st_dev;
  t.inode = st.st_ino;
  return t;
}

void refuse_same_file(const std::vector<std::pair<std::string, std::string>>& outputs) {
  // A path that cannot lead to a file is left to the program's opening of it to report.
  std::vector<std::optional<OutputTarget>> targets;
  for (const auto& [option, path] : outputs) {
    try {
      targets.emplace_back(resolve_output(path, option));
    } catch (const UsageError&) {
      targets.emplace_back();
    }
  }
  for (std::size_t i = 0; i < targets.size(); ++i)
    for (std::size_t j = 0; j < i; ++j) {
      if (!targets[i] || !targets[j]) continue;
      const OutputTarget& a = *targets[j];
      const OutputTarget& b = *targets[i];
      // A descriptor alias counts as its file when that is a regular one (`--events /dev/stdout > f`).
      const auto regular_or_new = [](const OutputTarget& t) {
        if (t.fd_alias < 0) return t.regular || !t.exists;
        struct stat st {};
        return ::fstat(t.fd_alias, &st) == 0 && S_ISREG(st.st_mode);
      };
      if (!regular_or_new(a) || !regular_or_new(b)) continue;
      const bool same = (a.exists && b.exists && a.device == b.device && a.inode == b.inode) ||
                        (a.fd_alias < 0 && b.fd_alias < 0 && a.target == b.target);
      if (same)
        throw UsageError(outputs[j].first + " " + outputs[j].second + " and " + outputs[i].first + " " +
                         outputs[i].second + " name the same file (" + a.target.string() +
                         "): each output needs a file of its own");
    }
}

OutputFile::Buffer::Buffer(int fd) : fd_(fd), buffer_(1 << 16) { setp(buffer_.data(), buffer_.data() + buffer_.size()); }

std::streambuf::int_type OutputFile::Buffer::overflow(int_type c) {
  if (sync() != 0) return traits_type::eof();
  if (!traits_type::eq_int_type(c, traits_type::eof())) {
    *pptr() = traits_type::to_char_type(c);
    pbump(1);
  }
  return traits_type::not_eof(c);
}

int OutputFile::Buffer::sync() {
  const char* p = pbase();
  while (p < pptr()) {
    const ssize_t n = ::write(fd_, p, static_cast<std::size_t>(pptr() - p));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error_ = n < 0 ? errno : EIO;
      setp(buffer_.data(), buffer_.data() + buffer_.size());  // dropped: the stream fails
      return -1;
    }
    p += n;
  }
  setp(buffer_.data(), buffer_.data() + buffer_.size());
  return 0;
}

void OutputFile::Buffer::close() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

std::string OutputFile::name() const { return quoted_option(option_, path_); }

OutputFile::OutputFile(fs::path path, std::string option, OutputKind kind)
    : path_(std::move(path)), option_(std::move(option)), kind_(kind) {
  try {
    target_ = resolve_output(path_, option_);
  } catch (const UsageError& e) {
    throw std::runtime_error(e.what());
  }
  const auto fail = [&](const std::string& what) {
    return std::runtime_error(name() + ": " + what + ": " + std::strerror(errno));
  };
  int fd = -1;
  if (target_.fd_alias >= 0) {
    fd = ::fcntl(target_.fd_alias, F_DUPFD_CLOEXEC, 3);
    if (fd < 0) throw fail("cannot write to the descriptor " + std::to_string(target_.fd_alias));
  } else if (target_.exists && !target_.regular) {
    // A device, a FIFO, a socket: written as it is (the original path: /proc's links included).
    fd = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) throw fail("cannot open for writing");
  } else if (kind_ == OutputKind::kLive) {
    fd = ::open(target_.target.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOCTTY, 0666);
    if (fd < 0) throw fail("cannot open for writing");
  } else {
    temp_ = target_.target;
    temp_ += ".partial-" + std::to_string(::getpid());
    fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOCTTY, 0666);
    if (fd < 0) throw fail("cannot create the output file beside it (" + temp_.filename().string() + ")");
    if (target_.exists) {  // the replacement keeps the file's mode and owner
      struct stat st {};
      struct stat mine {};
      const bool ok = ::stat(target_.target.c_str(), &st) == 0 && ::fstat(fd, &mine) == 0 &&
                      ((st.st_uid == mine.st_uid && st.st_gid == mine.st_gid) || ::fchown(fd, st.st_uid, st.st_gid) == 0) &&
                      ::fchmod(fd, st.st_mode & 07777) == 0;
      if (!ok) {
        const int saved = errno;
        ::close(fd);
        ::unlink(temp_.c_str());
        errno = saved;
        throw fail("cannot give the replacement the file's owner and mode");
      }
    }
  }
  buffer_.emplace(fd);
  out_.rdbuf(&*buffer_);
}

std::FILE* OutputFile::c_file() {
  if (c_file_ == nullptr && !done_) {
    out_.flush();
    const int fd = ::fcntl(buffer_->fd(), F_DUPFD_CLOEXEC, 3);
    c_file_ = fd < 0 ? nullptr : ::fdopen(fd, "w");
    if (c_file_ == nullptr) {
      if (fd >= 0) ::close(fd);
      throw std::runtime_error(name() + ": " + std::strerror(errno));
    }
  }
  return c_file_;
}

OutputFile::~OutputFile() {
  if (!done_) discard();
}

void OutputFile::discard() noexcept {
  if (done_) return;
  done_ = true;
  out_.rdbuf(nullptr);
  if (c_file_ != nullptr) std::fclose(c_file_);  // flushes: a live record keeps what it holds
  c_file_ = nullptr;
  if (buffer_) {
    if (temp_.empty()) (void)buffer_->pubsync();  // a live record keeps what it holds
    buffer_->close();
  }
  if (!temp_.empty()) ::unlink(temp_.c_str());
}

void OutputFile::discard_removing_target() noexcept {
  if (done_) return;  // committed (or given up already): the file is this run's
  discard();
  if (target_.regular && target_.fd_alias < 0) ::unlink(target_.target.c_str());
}

void OutputFile::commit() {
  if (done_) return;
  out_.flush();
  int error = buffer_->error();
  if (c_file_ != nullptr) {
    const bool c_failed = std::fflush(c_file_) != 0 || std::ferror(c_file_) != 0;
    if (c_failed && error == 0) error = errno != 0 ? errno : EIO;
    if (std::fclose(c_file_) != 0 && error == 0) error = errno;
    c_file_ = nullptr;
  }
  if (!out_ || error != 0) {
    discard();
    throw std::runtime_error(name() + ": write failed" + (error != 0 ? std::string(": ") + std::strerror(error) : ""));
  }
  if (!temp_.empty() && ::fsync(buffer_->fd()) != 0) {
    const int saved = errno;
    discard();
    throw std::runtime_error(name() + ": write failed: " + std::strerror(saved));
  }
  done_ = true;
  out_.rdbuf(nullptr);
  buffer_->close();
  if (temp_.empty()) return;
  if (::rename(temp_.c_str(), target_.target.c_str()) != 0) {
    const int saved = errno;
    ::unlink(temp_.c_str());
    throw std::runtime_error(name() + ": cannot move the output into place: " + std::strerror(saved));
  }
}

}  // namespace pneu::cli
