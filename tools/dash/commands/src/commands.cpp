#include "pneu/dash/commands.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <grp.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <nlohmann/json.hpp>

namespace pneu::dash {

namespace {

std::string octal(unsigned mode) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%04o", mode);
  return buf;
}

// A JSON object's member as a string, or "" when it is missing or not a string.
std::string string_member(const nlohmann::json& j, const char* name) {
  const auto it = j.find(name);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

struct Kind {
  const char* name;
  std::int8_t wire;
  bool takes_value;
};
constexpr Kind kKinds[] = {
    {"set_point", pneu_lcm::command_t::KIND_SET_POINT, true},
    {"set_point_step", pneu_lcm::command_t::KIND_SET_POINT_STEP, true},
    {"arm", pneu_lcm::command_t::KIND_ARM, false},
    {"disarm", pneu_lcm::command_t::KIND_DISARM, false},
    {"fault_reset", pneu_lcm::command_t::KIND_FAULT_RESET, false},
    {"hold_on", pneu_lcm::command_t::KIND_HOLD_ON, false},
    {"hold_off", pneu_lcm::command_t::KIND_HOLD_OFF, false},
};

}  // namespace

std::string read_token_file(const std::filesystem::path& file, const std::string& group) {
  const std::string name = file.string();
  const int fd = ::open(name.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY | O_NONBLOCK);
  if (fd < 0) {
    const int e = errno;
    throw CommandsRefused("--commands-token-file " + name + ": " +
                          (e == ELOOP ? std::string("a symbolic link: name the file itself") : std::strerror(e)));
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st{};
  if (::fstat(fd, &st) != 0) throw CommandsRefused("--commands-token-file " + name + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw CommandsRefused("--commands-token-file " + name + ": not a regular file");
  const unsigned mode = static_cast<unsigned>(st.st_mode) & 07777u;
  if ((mode & ~0640u) != 0)
    throw CommandsRefused("--commands-token-file " + name + ": mode " + octal(mode) +
                          " grants more than 0640 (owner read and write, group read; nobody else): whoever can "
                          "read the token can move the carriage. chmod 0640 " + name);
  if (!group.empty()) {
    // The group's entry, if this host has one (getgrnam_r: no static buffer).
    std::string buffer(16384, '\0');
    struct group g{};
    struct group* found = nullptr;
    int e = 0;
    while ((e = ::getgrnam_r(group.c_str(), &g, buffer.data(), buffer.size(), &found)) == ERANGE &&
           buffer.size() < (1u << 20))
      buffer.resize(buffer.size() * 4);
    if (e == 0 && found != nullptr && st.st_gid != found->gr_gid)
      throw CommandsRefused("--commands-token-file " + name + ": owned by group id " + std::to_string(st.st_gid) +
                            ", not by group '" + group + "' (" + std::to_string(found->gr_gid) +
                            "): the group this host gives the token to. chgrp " + group + " " + name);
  }
  std::string text;
  char chunk[512];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw CommandsRefused("--commands-token-file " + name + ": " + std::strerror(errno));
    if (n == 0) break;
    text.append(chunk, static_cast<std::size_t>(n));
    if (text.size() > 4096) throw CommandsRefused("--commands-token-file " + name + ": longer than 4096 bytes");
  }
  if (!text.empty() && text.back() == '\n') text.pop_back();
  if (!text.empty() && text.back() == '\r') text.pop_back();
  for (const char c : text)
    if (c <= 0x20 || c > 0x7e)
      throw CommandsRefused("--commands-token-file " + name +
                            ": the token must be one line of printable ASCII without spaces");
  if (text.size() < kMinTokenChars)
    throw CommandsRefused("--commands-token-file " + name + ": a token of " + std::to_string(text.size()) +
                          " characters; at least " + std::to_string(kMinTokenChars) +
                          " are needed (e.g. head -c 24 /dev/urandom | base64)");
  return text;
}

bool is_loopback_address(std::string_view host) noexcept {
  if (host == "localhost" || host == "::1" || host == "[::1]") return true;
  char buf[INET_ADDRSTRLEN] = {};
  if (host.size() >= sizeof buf) return false;
  std::memcpy(buf, host.data(), host.size());
  in_addr a{};
  if (::inet_pton(AF_INET, buf, &a) != 1) return false;
  return (ntohl(a.s_addr) >> 24) == 127;
}

void listen_allows_commands(std::string_view host) {
  if (is_loopback_address(host)) return;
  throw CommandsRefused(
      "commands (--commands-token-file) are taken on a loopback --listen address only, not on '" + std::string(host) +
      "': pneu-dash has no TLS, and the token would cross the network in the clear. Listen on 127.0.0.1 and reach "
      "it from elsewhere through an SSH tunnel (ssh -L 8765:127.0.0.1:8765 bench) or a TLS-terminating proxy on "
      "this host; or serve without commands");
}

bool same_token(std::string_view expected, std::string_view given) noexcept {
  // Every byte of `expected` is compared, whatever came before; `given`'s length only enters
  // through one comparison folded in at the end.
  unsigned char diff = expected.size() == given.size() ? 0 : 1;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const unsigned char g = i < given.size() ? static_cast<unsigned char>(given[i]) : 0;
    diff |= static_cast<unsigned char>(static_cast<unsigned char>(expected[i]) ^ g);
  }
  // Not folded into a branch on the way (the compiler may not know the loop's result early).
  volatile unsigned char result = diff;
  return result == 0;
}

std::string counters_text(const GateCounters& c) {
  struct Line {
    const char* name;
    const char* help;
    std::uint64_t value;
  };
  const Line lines[] = {
      {"pneu_dash_command_logins_total", "Browsers let in to command: the right token.", c.logins},
      {"pneu_dash_command_tokens_refused_total", "Wrong tokens refused (nothing sent).", c.refused_tokens},
      {"pneu_dash_command_logins_throttled_total", "Logins refused unread after too many wrong tokens.", c.throttled},
      {"pneu_dash_commands_sent_total", "Commands sent to pneud (its verdict is in its events).", c.commands_sent},
      {"pneu_dash_commands_refused_total", "Commands not sent: not logged in, malformed, unknown kind.",
       c.commands_refused},
      {"pneu_dash_command_send_failures_total", "Commands the LCM transport failed to send.", c.send_failures},
  };
  std::string s;
  for (const Line& l : lines) {
    s += std::string("# HELP ") + l.name + " " + l.help + "\n# TYPE " + l.name + " counter\n";
    s += std::string(l.name) + " " + std::to_string(l.value) + "\n";
  }
  return s;
}

std::int64_t random_session() {
  for (;;) {
    std::uint64_t v = 0;
    if (::getrandom(&v, sizeof v, 0) != static_cast<ssize_t>(sizeof v)) continue;
    // 53 bits: exact in JavaScript, whose numbers the page compares it as.
    const auto s = static_cast<std::int64_t>(v >> 11);
    if (s != 0) return s;
  }
}

CommandGate::CommandGate(GateOptions options, Sender send, Clock steady_s, UnixClock unix_us)
    : options_(std::move(options)), send_(std::move(send)), steady_s_(std::move(steady_s)), unix_us_(std::move(unix_us)) {
  if (!steady_s_)
    steady_s_ = [] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
    };
  if (!unix_us_)
    unix_us_ = [] {
      return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count();
    };
  if (options_.origin.size() > sizeof(pneu_lcm::command_t::origin))
    options_.origin.resize(sizeof(pneu_lcm::command_t::origin));
}

GateAnswer CommandGate::login(std::uint64_t client, std::string_view payload) {
  std::lock_guard<std::mutex> l(m_);
  GateAnswer a;
  const double now_s = steady_s_();
  if (now_s - window_start_s_ >= options_.failure_window_s) {
    window_start_s_ = now_s;
    failures_in_window_ = 0;
  }
  if (failures_in_window_ >= options_.max_failures) {
    ++counters_.throttled;
    char wait[32];
    std::snprintf(wait, sizeof wait, "%.0f s", std::ceil(options_.failure_window_s - (now_s - window_start_s_)));
    a.message = "login refused: too many wrong tokens lately; try again in " + std::string(wait);
    return a;
  }
  std::string token;
  try {
    token = string_member(nlohmann::json::parse(payload), "token");
  } catch (const nlohmann::json::exception&) {
  }
  if (!same_token(options_.token, token)) {
    ++counters_.refused_tokens;
    ++failures_in_window_;
    sessions_.erase(client);  // a wrong token ends what the connection had
    a.message = "login refused: wrong token (" + std::to_string(counters_.refused_tokens) +
                " refused since pneu-dash started); nothing is sent";
    return a;
  }
  ++counters_.logins;
  if (sessions_.size() >= options_.max_sessions && !sessions_.contains(client)) sessions_.erase(sessions_.begin());
  const std::int64_t session = random_session();
  sessions_[client] = session;
  a.ok = true;
  a.session = session;
  a.message = "logged in: session " + std::to_string(session) + "; commands go to pneud as \"" + options_.origin + "\"";
  return a;
}

GateAnswer CommandGate::command(std::uint64_t client, std::string_view payload) {
  std::lock_guard<std::mutex> l(m_);
  GateAnswer a;
  const auto it = sessions_.find(client);
  if (it == sessions_.end()) {
    ++counters_.commands_refused;
    a.message = "command refused: not logged in (send the token first); nothing is sent";
    return a;
  }
  a.session = it->second;
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(payload);
  } catch (const nlohmann::json::exception&) {
    ++counters_.commands_refused;
    a.message = "command refused: not JSON; nothing is sent";
    return a;
  }
  const std::string kind = j.is_object() ? string_member(j, "kind") : std::string();
  const Kind* k = std::find_if(std::begin(kKinds), std::end(kKinds), [&](const Kind& x) { return kind == x.name; });
  if (k == std::end(kKinds)) {
    ++counters_.commands_refused;
    a.message = "command refused: unknown kind '" + kind +
                "' (arm, disarm, fault_reset, set_point, set_point_step, hold_on, hold_off); nothing is sent";
    return a;
  }
  double value = 0.0;
  if (k->takes_value) {
    const auto v = j.find("value");
    if (v == j.end() || !v->is_number() || !std::isfinite(v->get<double>())) {
      ++counters_.commands_refused;
      a.message = std::string("command refused: ") + k->name + " needs a finite number \"value\" [m]; nothing is sent";
      return a;
    }
    value = v->get<double>();
  }
  pneu_lcm::command_t c{};
  c.utime = unix_us_();
  // pneud takes only increasing sequence numbers (from any sender): the time, as pneu-command's.
  last_seq_ = std::max(last_seq_ + 1, c.utime);
  c.seq = last_seq_;
  c.kind = k->wire;
  c.value = value;
  std::memset(c.origin, 0, sizeof c.origin);
  std::memcpy(c.origin, options_.origin.data(), std::min(options_.origin.size(), sizeof c.origin));
  c.session = it->second;
  if (!send_(c)) {
    ++counters_.send_failures;
    a.message = std::string("command not sent: publishing ") + k->name + " to pneud failed";
    return a;
  }
  ++counters_.commands_sent;
  a.ok = true;
  a.seq = c.seq;
  a.message = std::string("sent ") + k->name + " (seq " + std::to_string(c.seq) + "); pneud's verdict follows";
  return a;
}

void CommandGate::forget(std::uint64_t client) {
  std::lock_guard<std::mutex> l(m_);
  sessions_.erase(client);
}

std::int64_t CommandGate::session_of(std::uint64_t client) const {
  std::lock_guard<std::mutex> l(m_);
  const auto it = sessions_.find(client);
  return it == sessions_.end() ? 0 : it->second;
}

GateCounters CommandGate::counters() const {
  std::lock_guard<std::mutex> l(m_);
  return counters_;
}

}  // namespace pneu::dash
