// Commands from the dashboard's page (issue 31): off unless pneu-dash is given a token file. A
// browser (or any Foxglove client) proves it knows the token by publishing it once on its
// connection (topic kLoginTopic, capability clientPublish); from then on that connection, and only
// it, may publish commands (topic kCommandTopic), which go to pneud over its own command path
// (command_t on <prefix>COMMAND), stamped with this dashboard's origin and the connection's
// session, so that pneud's own validation judges them and its events attribute them. pneud's
// verdict comes back on <prefix>EVENT (origin, session, seq): the page shows it from there.
//
// Why a token published on the WebSocket and no cookie: nothing is ambient. A page of another site
// that opens a WebSocket to the dashboard carries no credential the browser adds by itself (no
// cross-site WebSocket hijacking, no CSRF), and a connection that did not send the token cannot
// command, whoever opened it. The token crosses the connection once, so pneu-dash takes commands
// only on a loopback address (listen_allows_commands): it has no TLS of its own; reach it from
// elsewhere through an SSH tunnel or a TLS-terminating proxy on the same host.
//
// Pure logic (no sockets, no Beast): the transport is a function that sends one command_t; the
// clocks are given. Thread-safe (one mutex): the server's thread calls it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <string_view>

#include "pneu_lcm/command_t.hpp"

namespace pneu::dash {

/// The topics a client advertises and publishes on (encoding "json").
inline constexpr const char* kLoginTopic = "pneu.commands.login";      ///< {"token": "..."}
inline constexpr const char* kCommandTopic = "pneu.commands.command";  ///< {"kind": "...", "value": 0.17}
/// The ids of the status messages that answer them (Foxglove `status`, level info: "id").
inline constexpr const char* kLoginStatusId = "pneu.commands.login";
inline constexpr const char* kCommandStatusId = "pneu.commands.command";

/// Why the commands cannot be turned on: the token file or the address. what() says why, for people.
class CommandsRefused : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The shortest token taken [characters].
inline constexpr std::size_t kMinTokenChars = 16;

/// Reads the token from `file`, refusing (CommandsRefused, saying why): a file that is not a
/// regular file (a symbolic link is not followed), whose mode grants more than 0640 (owner read and
/// write, group read), that is not owned by group `group` when that group exists on this host, or
/// whose content is not one line of at least kMinTokenChars printable ASCII characters without
/// spaces (a final newline allowed).
[[nodiscard]] std::string read_token_file(const std::filesystem::path& file, const std::string& group = "pneu");

/// Whether `host` (a --listen address without its port) is loopback: 127.0.0.0/8, ::1, localhost.
[[nodiscard]] bool is_loopback_address(std::string_view host) noexcept;
/// Throws CommandsRefused, saying why, unless commands may be taken on `host`: loopback only.
void listen_allows_commands(std::string_view host);

/// Whether `given` is `expected`, in a time that depends on expected's length only (not on where
/// they differ, nor on given's length).
[[nodiscard]] bool same_token(std::string_view expected, std::string_view given) noexcept;

struct GateOptions {
  std::string token;               ///< read_token_file's
  std::string origin;              ///< command_t.origin: "pneu-dash ADDRESS:PORT" (cut to 32 bytes)
  int max_failures = 5;            ///< wrong tokens within failure_window_s, beyond which logins wait
  double failure_window_s = 10.0;
  std::size_t max_sessions = 1024; ///< sessions remembered (the oldest forgotten beyond)
};

struct GateCounters {
  std::uint64_t logins = 0;            ///< tokens taken
  std::uint64_t refused_tokens = 0;    ///< wrong (or malformed) tokens
  std::uint64_t throttled = 0;         ///< login attempts refused unread: too many wrong tokens lately
  std::uint64_t commands_sent = 0;     ///< command_t handed to the transport
  std::uint64_t commands_refused = 0;  ///< commands not sent: not logged in, malformed, unknown kind
  std::uint64_t send_failures = 0;     ///< the transport failed
};

/// The counters in the Prometheus text format (pneu_dash_command_*; no labels: the caller adds the
/// bench's).
[[nodiscard]] std::string counters_text(const GateCounters& c);

/// The answer to a client's message: a status for that client.
struct GateAnswer {
  bool ok = false;
  std::string message;        ///< for people (an error status when !ok)
  std::int64_t session = 0;   ///< the connection's session (0: none)
  std::int64_t seq = 0;       ///< a command sent: its command_t.seq
};

class CommandGate {
 public:
  /// Sends one command to pneud; false when it could not.
  using Sender = std::function<bool(const pneu_lcm::command_t&)>;
  using Clock = std::function<double()>;           ///< monotonic [s]
  using UnixClock = std::function<std::int64_t()>; ///< Unix time [us]

  /// Clocks default to the steady and system clocks.
  CommandGate(GateOptions options, Sender send, Clock steady_s = {}, UnixClock unix_us = {});

  /// A message on kLoginTopic from connection `client`: {"token": "..."}. A right token gives the
  /// connection a session (a random positive number below 2^53, public: pneud's events name it); a wrong one
  /// is refused and counted, and after max_failures within failure_window_s every login waits for
  /// the window to pass (unread: a guesser gains nothing by trying faster).
  GateAnswer login(std::uint64_t client, std::string_view payload);
  /// A message on kCommandTopic: {"kind": K, "value": V}; K one of arm, disarm, fault_reset,
  /// set_point (V [m]), set_point_step (V [m]), hold_on, hold_off. Sent only from a logged-in
  /// connection; nothing is sent otherwise.
  GateAnswer command(std::uint64_t client, std::string_view payload);
  /// The connection closed: its session ends.
  void forget(std::uint64_t client);
  /// The connection's session, 0 when it has none.
  [[nodiscard]] std::int64_t session_of(std::uint64_t client) const;

  [[nodiscard]] GateCounters counters() const;
  [[nodiscard]] const std::string& origin() const noexcept { return options_.origin; }

 private:
  GateOptions options_;
  Sender send_;
  Clock steady_s_;
  UnixClock unix_us_;
  mutable std::mutex m_;
  std::map<std::uint64_t, std::int64_t> sessions_;  // by connection
  double window_start_s_ = -1e300;
  int failures_in_window_ = 0;
  std::int64_t last_seq_ = 0;
  GateCounters counters_;
};

/// A random positive number below 2^53 (getrandom; exact in JavaScript): a session's number.
[[nodiscard]] std::int64_t random_session();

}  // namespace pneu::dash
