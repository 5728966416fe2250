// pneu-command: sends one command to pneud over LCM (what an operator's tool or script does).
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>

#include "pneu/config/cli.hpp"
#include "pneu_lcm/command_t.hpp"

namespace {

using namespace pneu;

constexpr const char* kHelp = R"(pneu-command: send a command to pneud over LCM

Usage:
  pneu-command [--lcm-url URL] [--prefix PNEU_] [--seq N] COMMAND [VALUE]

Commands:
  set-point Y_M     move to the set point Y_M [m, from mid-stroke]
  step DY_M         change the set point by DY_M [m]
  arm               start controlling (holds the present position)
  disarm            stop controlling (valves at the neutral voltage u_0)
  fault-reset       clear a latched fault (the daemon comes back disarmed)

--lcm-url defaults to udpm://239.255.76.67:7667?ttl=0, --prefix to PNEU_ (publishes on
<prefix>COMMAND). The sequence number defaults to the present Unix time in microseconds, so
successive invocations increase; pneud refuses a command whose sequence number does not.
pneud answers on <prefix>EVENT with a command_accepted or command_rejected event that says why.
)";

int run(int argc, char** argv) {
  std::string url = "udpm://239.255.76.67:7667?ttl=0", prefix = "PNEU_";
  long long seq = std::chrono::duration_cast<std::chrono::microseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  int i = 1;
  for (; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      std::cout << kHelp;
      return cli::kExitOk;
    }
    if (a.rfind("--", 0) != 0) break;
    if (i + 1 >= argc) throw cli::UsageError(a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--lcm-url") url = v;
    else if (a == "--prefix") prefix = v;
    else if (a == "--seq") seq = std::stoll(v);
    else throw cli::UsageError("unknown option " + a);
  }
  if (i >= argc) throw cli::UsageError("missing command (set-point, step, arm, disarm, fault-reset)");
  const std::string command = argv[i++];
  pneu_lcm::command_t msg;
  msg.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                  std::chrono::system_clock::now().time_since_epoch())
                  .count();
  msg.seq = seq;
  msg.value = 0.0;
  const auto value = [&]() {
    if (i >= argc) throw cli::UsageError(command + " needs a value in metres");
    char* end = nullptr;
    const double d = std::strtod(argv[i], &end);
    if (*end != '\0' || !std::isfinite(d)) throw cli::UsageError(std::string("not a finite number: ") + argv[i]);
    ++i;
    return d;
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
  } else {
    throw cli::UsageError("unknown command '" + command + "'");
  }
  if (i < argc) throw cli::UsageError(std::string("unexpected argument '") + argv[i] + "'");
  lcm::LCM lcm(url);
  if (!lcm.good()) throw std::runtime_error("LCM could not start on '" + url + "'");
  if (lcm.publish(prefix + "COMMAND", &msg) != 0) throw std::runtime_error("publish failed");
  return cli::kExitOk;
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-command", run, argc, argv); }
