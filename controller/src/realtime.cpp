#include "pneu/controller/realtime.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstring>

namespace pneu::controller {

namespace {
// Touches this much stack so that its pages are mapped (and, after mlockall, locked) before the
// loop runs: a first touch inside a tick would be a page fault.
constexpr std::size_t kPrefaultStackBytes = 256 * 1024;

[[gnu::noinline]] void prefault_stack() {
  unsigned char stack[kPrefaultStackBytes];
  // Written through a volatile pointer, so the compiler cannot drop the stores.
  volatile unsigned char* p = stack;
  for (std::size_t i = 0; i < kPrefaultStackBytes; i += 4096) p[i] = 0;
  p[kPrefaultStackBytes - 1] = 0;
}

std::string rlimit_text(int resource) {
  rlimit l{};
  if (getrlimit(resource, &l) != 0) return "unknown";
  return l.rlim_cur == RLIM_INFINITY ? "unlimited" : std::to_string(l.rlim_cur);
}
}  // namespace

RealtimeReport setup_realtime_thread(const RealtimeConfig& rt, bool require) {
  RealtimeReport r;
  const auto problem = [&](const std::string& what) {
    if (require) throw RealtimeError(what + " (--require-rt)");
    r.warnings.push_back(what);
  };
  if (rt.lock_memory) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
      problem(std::string("mlockall: ") + std::strerror(errno) + " (RLIMIT_MEMLOCK " + rlimit_text(RLIMIT_MEMLOCK) +
              "; the unit sets LimitMEMLOCK=infinity, or grant CAP_IPC_LOCK)");
    } else {
      prefault_stack();
      r.memory = true;
    }
  }
  if (rt.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(static_cast<unsigned>(rt.cpu), &set);
    const int e = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
    if (e != 0) problem("pinning the loop thread to CPU " + std::to_string(rt.cpu) + ": " + std::strerror(e));
    else r.affinity = true;
  }
  if (rt.priority > 0) {
    sched_param p{};
    p.sched_priority = rt.priority;
    const int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
    if (e != 0)
      problem("SCHED_FIFO priority " + std::to_string(rt.priority) + " for the loop thread: " + std::strerror(e) +
              " (RLIMIT_RTPRIO " + rlimit_text(RLIMIT_RTPRIO) + "; the unit sets LimitRTPRIO, or grant CAP_SYS_NICE)");
    else r.scheduling = true;
  }
  return r;
}

}  // namespace pneu::controller
