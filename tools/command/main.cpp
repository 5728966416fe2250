// pneu-command: sends one command to pneud over LCM and waits for its verdict (what an operator's
// tool or script does).
#include <lcm/lcm-cpp.hpp>
#include <lcm/lcm.h>

#include <cerrno>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <string>

#include <pwd.h>
#include <unistd.h>

#include "pneu/config/cli.hpp"
#include "pneu/telemetry/telemetry_params.hpp"
#include "pneu_lcm/command_t.hpp"
#include "pneu_lcm/event_t.hpp"

namespace {

using namespace pneu;

/// pneud rejected the command (its reason on stderr).
constexpr int kExitRejected = 3;
/// No verdict within --timeout-s: whether the command was applied is unknown.
constexpr int kExitNoAnswer = 4;

constexpr const char* kHelp = R"(pneu-command: send a command to pneud over LCM and wait for its verdict

Usage:
  pneu-command [--lcm-url URL] [--prefix PNEU_] [--seq N] [--origin TEXT]
               [--timeout-s S | --no-wait] COMMAND [VALUE]

Commands:
  set-point Y_M     move to the set point Y_M [m, from mid-stroke] (armed only: refused
                    while disarmed, since arming holds the present position)
  step DY_M         change the set point by DY_M [m] (armed only, likewise)
  arm               start controlling (holds the present position)
  disarm            stop controlling (valves at the neutral voltage u_0)
  fault-reset       clear a latched fault (the daemon comes back disarmed)
  hold-on           allow the in-position hold for the rest of the run (controller.hold)
  hold-off          do not take the in-position hold any more; one in force ends

--lcm-url defaults to udpm://239.255.76.67:7667?ttl=0, --prefix to PNEU_ (publishes on
<prefix>COMMAND). The sequence number (--seq, a positive integer) defaults to the present Unix
time in microseconds, so successive invocations increase; pneud refuses a command whose
sequence number does not.

pneud answers each command on <prefix>EVENT with a command_accepted or command_rejected event
that carries the command's sequence number and says what was done or why not (and writes the
same to its --events file as a "command" event). pneu-command listens there before it sends,
waits up to --timeout-s (default 2 s) for the verdict on its own command, and prints it:
accepted on stdout, rejected on stderr. Accepted means validated and handed to the loop.
--no-wait only sends (exit 0 once sent): for a script that streams set points and reads
the verdicts itself.

Each command says who sends it: its origin is "pneu-command USER" (the user running it; --origin
TEXT says something else: printable ASCII, at most 32 characters) and its session this process's
id. pneud writes both into the verdict's event, so that every command in its events is attributed.

Exit codes:
  0  accepted (with --no-wait: sent)
  1  not sent: LCM could not start, or publishing failed
  2  bad command line (nothing sent)
  3  rejected by pneud (its reason on stderr)
  4  no answer within --timeout-s: pneud is not running, listens on another LCM URL or prefix,
     takes no commands (commands.enabled false, or the simulated clock), or published no event
     for this rejection (at most 20 rejection events a second; its health counts them all).
     Whether the command was applied is unknown.
)";

std::int64_t unix_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// A whole argument as a number, or a usage error naming `what`.
double finite_number(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double d = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(d)) throw cli::UsageError(what + ": not a finite number: " + text);
  return d;
}
std::int64_t positive_integer(const std::string& text, const std::string& what) {
  char* end = nullptr;
  errno = 0;
  const long long n = std::strtoll(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || errno == ERANGE || n <= 0)
    throw cli::UsageError(what + ": not a positive integer: " + text);
  return n;
}


// The verdict on one command, as pneud publishes it.
struct Verdict {
  std::int64_t seq = 0;  // the command's
  bool answered = false, accepted = false;
  std::string text;
};

// LCM's C interface: its C++ subscriptions (1.3.1) crash under the sanitizers (see
// tests/support/lcm_sniffer.hpp).
void on_event(const lcm_recv_buf_t* rbuf, const char* /*channel*/, void* user) {
  auto& v = *static_cast<Verdict*>(user);
  pneu_lcm::event_t e;
  if (v.answered || e.decode(rbuf->data, 0, rbuf->data_size) < 0 || e.seq != v.seq) return;
  if (e.kind != pneu_lcm::event_t::KIND_COMMAND_ACCEPTED && e.kind != pneu_lcm::event_t::KIND_COMMAND_REJECTED) return;
  v.answered = true;
  v.accepted = e.kind == pneu_lcm::event_t::KIND_COMMAND_ACCEPTED;
  v.text = e.text;
}

// "pneu-command USER": the program and the user running it.
std::string default_origin() {
  const passwd* pw = ::getpwuid(::geteuid());
  return std::string("pneu-command ") + (pw != nullptr && pw->pw_name != nullptr ? pw->pw_name
                                                                               : std::to_string(::geteuid()).c_str());
}

int run(int argc, char** argv) {
  std::string url = "udpm://239.255.76.67:7667?ttl=0", prefix = "PNEU_", origin = default_origin();
  std::int64_t seq = unix_now_us();
  double timeout_s = 2.0;
  bool wait = true, timeout_given = false;
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::cout << kHelp;
      return cli::kExitOk;
    }
    if (a.rfind("--", 0) != 0) break;
    if (a == "--no-wait") {
      wait = false;
      continue;
    }
    if (a != "--lcm-url" && a != "--prefix" && a != "--seq" && a != "--timeout-s" && a != "--origin")
      throw cli::UsageError("unknown option " + a + " (see pneu-command --help)");
    if (i + 1 >= argc) throw cli::UsageError(a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--lcm-url") {
      url = v;
    } else if (a == "--prefix") {
      prefix = v;
    } else if (a == "--origin") {
      if (v.empty() || v.size() > sizeof(pneu_lcm::command_t::origin))
        throw cli::UsageError("--origin: 1 to " + std::to_string(sizeof(pneu_lcm::command_t::origin)) +
                              " characters, not " + std::to_string(v.size()));
      for (const char c : v)
        if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) > 0x7e)
          throw cli::UsageError("--origin: printable ASCII only");
      origin = v;
    } else if (a == "--seq") {
      seq = positive_integer(v, "--seq");
    } else if (a == "--timeout-s") {
      timeout_s = finite_number(v, "--timeout-s");
      if (timeout_s <= 0.0) throw cli::UsageError("--timeout-s must be positive (--no-wait does not wait)");
      timeout_given = true;
    }
  }
  if (timeout_given && !wait) throw cli::UsageError("--timeout-s and --no-wait exclude each other");
  if (i >= argc) throw cli::UsageError("missing command (set-point, step, arm, disarm, fault-reset, hold-on, hold-off)");
  const std::string command = argv[i++];
  pneu_lcm::command_t msg;
  msg.seq = seq;
  msg.value = 0.0;
  // Who sends it (pneud attributes the verdict to it): cut to the field, NUL-padded.
  std::memset(msg.origin, 0, sizeof msg.origin);
  std::memcpy(msg.origin, origin.data(), std::min(origin.size(), sizeof msg.origin));
  msg.session = ::getpid();
  const auto value = [&]() {
    if (i >= argc) throw cli::UsageError(command + " needs a value in metres");
    return finite_number(argv[i++], command);
  };
  if (command == "set-point") {
    msg.kind = pneu_lcm::command_t::KIND_SET_POINT;
    msg.value = value();
  } else if (command == "step") {
    msg.kind = pneu_lcm::command_t::KIND_SET_POINT_STEP;
    msg.value = value();
  } else if (command == "arm") {
    msg.kind = pneu_lcm::command_t::KIND_ARM;
  } else if (command == "disarm") {
    msg.kind = pneu_lcm::command_t::KIND_DISARM;
  } else if (command == "fault-reset") {
    msg.kind = pneu_lcm::command_t::KIND_FAULT_RESET;
  } else if (command == "hold-on") {
    msg.kind = pneu_lcm::command_t::KIND_HOLD_ON;
  } else if (command == "hold-off") {
    msg.kind = pneu_lcm::command_t::KIND_HOLD_OFF;
  } else {
    throw cli::UsageError("unknown command '" + command + "'");
  }
  if (i < argc) throw cli::UsageError(std::string("unexpected argument '") + argv[i] + "'");

  lcm::LCM lcm(url);
  if (!lcm.good()) throw std::runtime_error("LCM could not start on '" + url + "'");
  // Listening before sending: the verdict can come within a millisecond.
  const std::string event_channel = prefix + "EVENT";
  Verdict verdict;
  verdict.seq = seq;
  lcm_subscription_t* subscription =
      wait ? lcm_subscribe(lcm.getUnderlyingLCM(), telemetry::regex_literal(event_channel).c_str(), on_event, &verdict) : nullptr;
  if (wait && subscription == nullptr) throw std::runtime_error("LCM could not subscribe to " + event_channel);
  msg.utime = unix_now_us();  // stamped when sent: pneud refuses a command older than commands.max_age_s
  if (lcm.publish(prefix + "COMMAND", &msg) != 0) throw std::runtime_error("publish failed");
  if (!wait) return cli::kExitOk;

  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!verdict.answered) {
    const auto left_ms =
        std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()).count();
    if (left_ms <= 0) break;
    if (lcm_handle_timeout(lcm.getUnderlyingLCM(), static_cast<int>(left_ms)) < 0)
      throw std::runtime_error("LCM failed while waiting for the verdict on " + event_channel);
  }
  lcm_unsubscribe(lcm.getUnderlyingLCM(), subscription);
  if (!verdict.answered) {
    char limit[32];
    std::snprintf(limit, sizeof limit, "%g s", timeout_s);
    std::cerr << "pneu-command: no answer from pneud within " << limit << " to command " << seq << " (" << command
              << ") on " << event_channel << " (" << url << "); whether it was applied is unknown. Either pneud is "
              << "not running, or it listens on another LCM URL or channel prefix (--lcm-url, --prefix), or it takes "
                 "no commands (commands.enabled: false, or the simulated clock), or it published no event for this "
                 "rejection (at most 20 rejection events a second; its health message counts every rejection).\n";
    return kExitNoAnswer;
  }
  if (verdict.accepted) {
    std::cout << "pneud " << verdict.text << "\n";
    return cli::kExitOk;
  }
  std::cerr << "pneu-command: pneud " << verdict.text << "\n";
  return kExitRejected;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-command", run, argc, argv); }
