// The floor pneud's real-clock loop is measured against: a fixed-rate loop that does nothing but
// sleep to each absolute deadline (clock_nanosleep, TIMER_ABSTIME, CLOCK_MONOTONIC, as pneud's
// RealClock does) and record how late it woke. bench/loop_jitter.sh runs it beside pneud.
//
// Usage: bare_loop [SECONDS] [--slack-ns N] [--period-us P] [--priority P]
//   SECONDS       how long to run (default 10)
//   --slack-ns N  the thread's timer slack [ns] (default 1, as pneud's loop thread; 0 leaves the
//                 default of 50 us, which a thread under normal scheduling has)
//   --period-us P the period [us] (default 1000: 1 kHz)
//   --priority P  SCHED_FIFO priority 1..99 (default 0: normal scheduling; real-time threads
//                 ignore the timer slack)
// Prints the wake-up latency (wake-up minus deadline) in the format of pneud's summary.
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

constexpr long kNsPerS = 1000000000L;

long long now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<long long>(ts.tv_sec) * kNsPerS + ts.tv_nsec;
}

void sleep_until_ns(long long t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / kNsPerS);
  ts.tv_nsec = static_cast<long>(t_ns % kNsPerS);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr, "bare_loop: %s\nusage: bare_loop [SECONDS] [--slack-ns N] [--period-us P] [--priority P]\n", why);
  std::exit(2);
}

long parse_long(const char* text, const char* what) {
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || v < 0) usage((std::string("bad ") + what + ": " + text).c_str());
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  double seconds = 10.0;
  long slack_ns = 1;
  long period_us = 1000;
  long priority = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&](const char* what) {
      if (i + 1 >= argc) usage((a + " needs a value").c_str());
      return parse_long(argv[++i], what);
    };
    if (a == "--slack-ns") slack_ns = next("slack");
    else if (a == "--period-us") period_us = next("period");
    else if (a == "--priority") priority = next("priority");
    else if (!a.empty() && a[0] != '-') seconds = static_cast<double>(parse_long(argv[i], "seconds"));
    else usage(("unknown option " + a).c_str());
  }
  if (period_us <= 0 || seconds <= 0.0) usage("the period and the duration must be positive");

  if (slack_ns > 0 && prctl(PR_SET_TIMERSLACK, static_cast<unsigned long>(slack_ns), 0, 0, 0) != 0)
    std::fprintf(stderr, "bare_loop: PR_SET_TIMERSLACK: %s\n", std::strerror(errno));
  if (priority > 0) {
    sched_param p{};
    p.sched_priority = static_cast<int>(priority);
    if (const int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); e != 0) {
      std::fprintf(stderr, "bare_loop: SCHED_FIFO %ld: %s\n", priority, std::strerror(e));
      return 1;
    }
  }
  const long slack_now = prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0);

  const long long period_ns = period_us * 1000L;
  const auto n = static_cast<std::size_t>(std::llround(seconds * 1e6 / static_cast<double>(period_us)));
  std::vector<long long> late_ns(n);  // allocated (and touched) before the loop starts
  const long long epoch = now_ns() + period_ns;
  for (std::size_t k = 0; k < n; ++k) {
    const long long deadline = epoch + static_cast<long long>(k) * period_ns;
    sleep_until_ns(deadline);
    late_ns[k] = now_ns() - deadline;
  }

  std::sort(late_ns.begin(), late_ns.end());
  const auto at = [&](double q) {  // the q-quantile, nearest rank
    const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(n)));
    return static_cast<double>(late_ns[std::clamp<std::size_t>(rank, 1, n) - 1]) * 1e-3;
  };
  std::printf("bare loop: %zu wake-ups at %.0f Hz, timer slack %ld ns, %s\n", n, 1e6 / static_cast<double>(period_us),
              slack_now, priority > 0 ? ("SCHED_FIFO " + std::to_string(priority)).c_str() : "normal scheduling");
  std::printf("  wake-up latency [us]  min %8.2f  median %8.2f  p99 %8.2f  max %8.2f\n", at(0.0), at(0.5), at(0.99),
              at(1.0));
  return 0;
}
