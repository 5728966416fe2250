// The loop thread is real-time safe (docs/architecture.md, "the rules of the loop thread"): after start-up it allocates nothing and
// throws nothing, and it never waits for the non-real-time side; a full queue drops and counts.
//
// Allocations are counted by replacing the global allocation functions for this test executable:
// every operator new / new[] (plain, aligned, nothrow) and operator delete / delete[] bumps a
// counter while `g_counting` is set. Allocations that bypass operator new (a direct malloc from C
// code) are not seen; nothing in controller/, hal/ or sim_plant/ calls malloc directly.
#include <gtest/gtest.h>

#include <sys/prctl.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <new>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/controller/clock.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/session.hpp"
#include "support/simulated_run.hpp"
#include "pneu/controller/spsc_queue.hpp"
#include "pneu/controller/timing_stats.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/model/valve.hpp"

namespace {

std::atomic<bool> g_counting{false};
std::atomic<std::uint64_t> g_allocations{0};
std::atomic<std::uint64_t> g_deallocations{0};

void note_allocation() noexcept {
  if (g_counting.load(std::memory_order_relaxed))
    g_allocations.fetch_add(1, std::memory_order_relaxed);
}
void note_deallocation(void* p) noexcept {
  if (p != nullptr && g_counting.load(std::memory_order_relaxed))
    g_deallocations.fetch_add(1, std::memory_order_relaxed);
}

void* allocate(std::size_t size) noexcept {
  note_allocation();
  return std::malloc(size == 0 ? 1 : size);
}
void* allocate_aligned(std::size_t size, std::align_val_t alignment) noexcept {
  note_allocation();
  const auto a = std::max(static_cast<std::size_t>(alignment), sizeof(void*));
  void* p = nullptr;
  return posix_memalign(&p, a, size == 0 ? 1 : size) == 0 ? p : nullptr;
}
void* allocate_or_throw(std::size_t size) {
  if (void* p = allocate(size)) return p;
  throw std::bad_alloc();
}
void* allocate_aligned_or_throw(std::size_t size, std::align_val_t alignment) {
  if (void* p = allocate_aligned(size, alignment)) return p;
  throw std::bad_alloc();
}
void release(void* p) noexcept {
  note_deallocation(p);
  std::free(p);
}

}  // namespace

// The replaceable global allocation functions ([new.delete]); all route through the counters.
void* operator new(std::size_t n) { return allocate_or_throw(n); }
void* operator new[](std::size_t n) { return allocate_or_throw(n); }
void* operator new(std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new[](std::size_t n, const std::nothrow_t&) noexcept { return allocate(n); }
void* operator new(std::size_t n, std::align_val_t a) { return allocate_aligned_or_throw(n, a); }
void* operator new[](std::size_t n, std::align_val_t a) { return allocate_aligned_or_throw(n, a); }
void* operator new(std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return allocate_aligned(n, a);
}
void* operator new[](std::size_t n, std::align_val_t a, const std::nothrow_t&) noexcept {
  return allocate_aligned(n, a);
}
void operator delete(void* p) noexcept { release(p); }
void operator delete[](void* p) noexcept { release(p); }
void operator delete(void* p, std::size_t) noexcept { release(p); }
void operator delete[](void* p, std::size_t) noexcept { release(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { release(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { release(p); }
void operator delete(void* p, std::align_val_t) noexcept { release(p); }
void operator delete[](void* p, std::align_val_t) noexcept { release(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { release(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { release(p); }
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept { release(p); }
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept { release(p); }

namespace {

using namespace pneu;
using controller::ControlLoop;
using controller::SpscQueue;
using controller::TimingStats;

// Nothing on the loop thread can throw: an exception escaping tick() would leave the valves at
// whatever they were last told. These fail the build, not the run.
static_assert(noexcept(std::declval<ControlLoop&>().tick(0.0)));
static_assert(noexcept(std::declval<ControlLoop&>().stop()));
static_assert(noexcept(std::declval<hal::Backend&>().read(0.0, std::declval<hal::SensorFrame&>())));
static_assert(noexcept(std::declval<hal::Backend&>().write(hal::ActuatorCommand{})));
static_assert(noexcept(std::declval<controller::Clock&>().sleep_until(0.0)));
static_assert(noexcept(std::declval<SpscQueue<int, 4>&>().try_push(0)));
static_assert(noexcept(std::declval<TimingStats&>().add(0.0)));

// Opens and closes the counted window around exactly one call.
class CountedWindow {
 public:
  CountedWindow() { g_counting.store(true, std::memory_order_seq_cst); }
  ~CountedWindow() { g_counting.store(false, std::memory_order_seq_cst); }
  CountedWindow(const CountedWindow&) = delete;
  CountedWindow& operator=(const CountedWindow&) = delete;
};

void reset_counters() {
  g_allocations.store(0);
  g_deallocations.store(0);
}

// The default bench running the paper scenario (embedded config/sim.yaml), as pneud assembles it.
struct DefaultRun {
  assembly::AssembledRun assembled;
  const config::Config& config = assembled.config();
  controller::Run& run = assembled.run();
  const hal::SimBackend* bench = assembled.simulated_bench();  // the simulated truth, owned by the run

  explicit DefaultRun(const std::vector<std::string>& overrides = {})
      : assembled(test::simulated_run(config::load_string(config::default_config_yaml(), overrides))) {}
  DefaultRun(const DefaultRun&) = delete;
  DefaultRun& operator=(const DefaultRun&) = delete;
  [[nodiscard]] double period_s() const { return config.controller.period_s(); }
};

void* volatile g_sink = nullptr;  // keeps the control allocation from being optimised away

TEST(AllocationCounter, CountsAnAllocationMadeInsideTheWindow) {
  reset_counters();
  {
    CountedWindow window;
    g_sink = ::operator new(64);
  }
  ::operator delete(g_sink);
  {
    CountedWindow window;
    // The vector and its buffer are freed inside the window too.
    auto v = std::make_unique<std::vector<double>>(16);
    g_sink = v.get();
  }
  EXPECT_EQ(g_allocations.load(), 3u);  // raw block, the vector object, its buffer
  EXPECT_EQ(g_deallocations.load(), 2u);
}

TEST(AllocationCounter, IgnoresAllocationsOutsideTheWindow) {
  reset_counters();
  auto v = std::make_unique<std::vector<double>>(16);
  g_sink = v.get();
  v.reset();
  EXPECT_EQ(g_allocations.load(), 0u);
  EXPECT_EQ(g_deallocations.load(), 0u);
}

TEST(ControlLoop, AllocatesNothingOverTenThousandTicksAfterStart) {
  DefaultRun d;
  auto& run = d.run;
  run.loop->start(0.0);
  reset_counters();
  constexpr std::uint64_t kTicks = 10'000;  // 10 s: the set-point step and the long sticking phase
  for (std::uint64_t k = 0; k < kTicks; ++k) {
    {
      CountedWindow window;
      run.loop->tick(static_cast<double>(k) * d.period_s());
    }
    run.runtime->drain(*run.outputs);  // the non-real-time side, outside the window: it allocates
  }
  EXPECT_EQ(g_allocations.load(), 0u);
  EXPECT_EQ(g_deallocations.load(), 0u);

  // The ticks did real work: the carriage moved, stopped, and restarted (events were queued),
  // and no record was lost on the way.
  EXPECT_EQ(run.loop->ticks(), kTicks);
  EXPECT_EQ(run.runtime->ticks_seen(), kTicks);
  ASSERT_FALSE(run.runtime->stops().empty());
  EXPECT_TRUE(run.runtime->stops().front().ended);
  EXPECT_EQ(run.outputs->ticks_dropped, 0u);
  EXPECT_EQ(run.outputs->events_dropped, 0u);
}

// The gains scheduled by position: a step from mid-stroke, the gains read from the table at
// every tick as the carriage travels (controller.law.gains: scheduled).
TEST(ControlLoop, AllocatesNothingWithGainsScheduledByPosition) {
  DefaultRun d({"controller.law.gains=scheduled", "simulation.initial_position_m=0", "controller.setpoints.initial_m=0",
                "controller.setpoints.schedule=[{t_s: 0.1, position_m: 0.05}]"});
  auto& run = d.run;
  ASSERT_FALSE(run.loop->law().schedule().empty());
  run.loop->start(0.0);
  reset_counters();
  constexpr std::uint64_t kTicks = 2'000;
  for (std::uint64_t k = 0; k < kTicks; ++k) {
    {
      CountedWindow window;
      run.loop->tick(static_cast<double>(k) * d.period_s());
    }
    run.runtime->drain(*run.outputs);
  }
  EXPECT_EQ(g_allocations.load(), 0u);
  EXPECT_EQ(g_deallocations.load(), 0u);
  // The carriage travelled to the set point and came to rest there (the table's gains settle it).
  EXPECT_NEAR(d.bench->plant().state().y_m, 0.05, 1e-3);
  ASSERT_FALSE(run.runtime->stops().empty());
}

// The in-position hold (controller.hold) and a push that throws the carriage out of it: the ticks
// that hold, hand back and hold again allocate nothing either.
TEST(ControlLoop, AllocatesNothingWhileHoldingHandingBackAndHoldingAgain) {
  DefaultRun d({"controller.hold.enabled=true", "hal.sim.pushes=[{t_s: 6, force_n: 150, duration_s: 0.1}]"});
  auto& run = d.run;
  run.loop->start(0.0);
  reset_counters();
  constexpr std::uint64_t kTicks = 12'000;
  std::uint64_t holding = 0;
  for (std::uint64_t k = 0; k < kTicks; ++k) {
    {
      CountedWindow window;
      run.loop->tick(static_cast<double>(k) * d.period_s());
    }
    holding += run.loop->mode() == controller::Mode::kHold ? 1 : 0;
    run.runtime->drain(*run.outputs);
  }
  EXPECT_EQ(g_allocations.load(), 0u);
  EXPECT_EQ(g_deallocations.load(), 0u);
  EXPECT_GT(holding, 5'000u);  // most of the run: held before the push and after it
  EXPECT_EQ(run.outputs->events_dropped, 0u);
}

// The movement test at the first ARM of a run started disarmed (as on a real backend): the ticks
// that step the test, end it and arm the law allocate nothing either.
TEST(ControlLoop, AllocatesNothingThroughTheMovementTestAtArm) {
  DefaultRun d({"controller.start_armed=false", "controller.setpoints.schedule=[]"});
  auto& run = d.run;
  controller::LoopParams params = controller::LoopParams::from(d.config, run.loop->law());
  params.movement_test_at_arm = true;  // as hal.backend modbus makes it
  ControlLoop loop(params, *run.backend, *run.outputs);
  loop.start(0.0);
  ASSERT_TRUE(run.outputs->commands.try_push({controller::LoopCommand::Kind::kArm, 0.0, 1}));
  reset_counters();
  constexpr std::uint64_t kTicks = 3'000;
  std::uint64_t testing = 0;
  for (std::uint64_t k = 0; k < kTicks; ++k) {
    {
      CountedWindow window;
      loop.tick(static_cast<double>(k) * d.period_s());
    }
    testing += loop.mode() == controller::Mode::kMovementTest ? 1 : 0;
    run.runtime->drain(*run.outputs);
  }
  EXPECT_EQ(g_allocations.load(), 0u);
  EXPECT_EQ(g_deallocations.load(), 0u);
  EXPECT_GT(testing, 100u) << "the test ran";
  EXPECT_EQ(loop.mode(), controller::Mode::kArmed) << "and passed";
}

// The forecasts made again while stuck take u* of Eq. 11 from the same scheduled law as the loop:
// the gains at y*, not controller.law's fixed ones.
TEST(ControlLoop, TheForecastsTakeUStarFromTheLoopsScheduledGains) {
  DefaultRun d({"controller.law.gains=scheduled", "simulation.initial_position_m=0", "controller.setpoints.initial_m=0",
                "controller.setpoints.schedule=[{t_s: 0.1, position_m: 0.05}]"});
  auto& run = d.run;
  run.runtime->set_keep_reforecasts(true);
  run.loop->start(0.0);
  for (std::uint64_t k = 0; k < 3'000; ++k) {
    run.loop->tick(static_cast<double>(k) * d.period_s());
    run.runtime->drain(*run.outputs);
  }
  ASSERT_FALSE(run.runtime->stops().empty());
  const auto& stop = run.runtime->stops().back();
  ASSERT_FALSE(stop.reforecasts.empty());
  const double y_star = stop.snapshot.y_m;  // ideal sensors: every reading at rest is y*
  const double scheduled = run.loop->law().resting_control_v(0.05, y_star);
  const double fixed = controller::ControlLaw(d.config.controller.law).resting_control_v(0.05, y_star);
  ASSERT_GT(std::abs(scheduled - fixed), 1e-3);  // the two laws tell apart here
  EXPECT_NEAR(stop.snapshot.u_v, scheduled, 1e-12);
  for (const auto& f : stop.reforecasts) EXPECT_NEAR(f.u_star_v, scheduled, 1e-9);
}

TEST(SpscQueue, FullQueueRefusesAndKeepsWhatItHolds) {
  SpscQueue<int, 4> q;
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(q.try_push(i));
  EXPECT_FALSE(q.try_push(4));
  int v = -1;
  ASSERT_TRUE(q.try_pop(v));
  EXPECT_EQ(v, 0);
  EXPECT_TRUE(q.try_push(5));  // one slot freed, one push accepted
  EXPECT_FALSE(q.try_push(6));
  for (int expected : {1, 2, 3, 5}) {
    ASSERT_TRUE(q.try_pop(v));
    EXPECT_EQ(v, expected);
  }
  EXPECT_FALSE(q.try_pop(v));
}

TEST(ControlLoop, CountsDroppedTickRecordsAndKeepsTickingWhenNobodyDrains) {
  DefaultRun d;
  auto& run = d.run;
  run.loop->start(0.0);
  constexpr std::uint64_t kCapacity = decltype(controller::LoopOutputs::ticks)::capacity();
  constexpr std::uint64_t kExtra = 100;
  for (std::uint64_t k = 0; k < kCapacity + kExtra; ++k)
    run.loop->tick(static_cast<double>(k) * d.period_s());

  EXPECT_EQ(run.loop->ticks(), kCapacity + kExtra);
  EXPECT_EQ(run.outputs->ticks_dropped, kExtra);  // the queue held exactly its capacity
  // The loop went on controlling while its records were dropped: the set point stepped at 1 s and
  // the carriage followed it (it started at 219.5 mm, the set point is 170 mm).
  EXPECT_LT(d.bench->plant().state().y_m, 0.19);

  // The reader sees the loss as one gap in the sequence numbers once the loop's records flow again.
  run.runtime->drain(*run.outputs);
  EXPECT_EQ(run.runtime->ticks_seen(), kCapacity);
  EXPECT_EQ(run.runtime->sequence_gaps(), 0u);
  run.loop->tick(static_cast<double>(kCapacity + kExtra) * d.period_s());
  run.runtime->drain(*run.outputs);
  EXPECT_EQ(run.runtime->sequence_gaps(), 1u);
}

TEST(SpscQueue, CarriesAMillionSequenceNumbersBetweenThreadsInOrderWithoutLoss) {
  constexpr std::uint64_t kCount = 1'000'000;
  // Small, so that the queue runs full and empty often.
  auto q = std::make_unique<SpscQueue<std::uint64_t, 1024>>();
  std::uint64_t out_of_order = 0;
  std::uint64_t received = 0;
  std::thread consumer([&] {
    std::uint64_t v = 0;
    while (received < kCount) {
      if (!q->try_pop(v)) {
        std::this_thread::yield();
        continue;
      }
      if (v != received) ++out_of_order;
      ++received;
    }
  });
  for (std::uint64_t i = 0; i < kCount; ++i) {
    while (!q->try_push(i)) std::this_thread::yield();
  }
  consumer.join();
  EXPECT_EQ(received, kCount);
  EXPECT_EQ(out_of_order, 0u);
  std::uint64_t leftover = 0;
  EXPECT_FALSE(q->try_pop(leftover));
}

// The empirical q-quantile of the sorted sample, by the same rank rule as TimingStats.
double empirical_quantile(const std::vector<double>& sorted, double q) {
  const auto rank = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size())));
  return sorted[std::max<std::size_t>(rank, 1) - 1];
}

TEST(TimingStats, QuantilesOfALogNormalSampleMatchTheSortedSampleWithinOneBin) {
  // Compute times of a loop: median 2 us, a long right tail (sigma 0.5 in log space: p99 ~ 6 us).
  std::mt19937_64 rng(20240601);
  std::lognormal_distribution<double> dist(std::log(2.0e-6), 0.5);
  std::vector<double> sample(100'000);
  TimingStats stats;
  for (double& s : sample) {
    s = dist(rng);
    stats.add(s);
  }
  std::sort(sample.begin(), sample.end());

  EXPECT_EQ(stats.count(), sample.size());
  EXPECT_EQ(stats.min_s(), sample.front());  // exact, not binned
  EXPECT_EQ(stats.max_s(), sample.back());
  // The histogram returns the geometric centre of the bin holding the rank: within one bin ratio
  // (1.005) of the true order statistic, by construction.
  constexpr double kBinRatio = 1.005;
  for (double q : {0.01, 0.1, 0.5, 0.9, 0.99, 0.999}) {
    const double truth = empirical_quantile(sample, q);
    const double got = stats.quantile_s(q);
    EXPECT_GE(got, truth / kBinRatio) << "q = " << q;
    EXPECT_LE(got, truth * kBinRatio) << "q = " << q;
  }
}

TEST(TimingStats, EmptyReadsZero) {
  TimingStats stats;
  EXPECT_EQ(stats.count(), 0u);
  EXPECT_EQ(stats.quantile_s(0.5), 0.0);
  EXPECT_EQ(stats.min_s(), 0.0);
  EXPECT_EQ(stats.max_s(), 0.0);
}

TEST(TimingStats, EveryQuantileOfOneSampleIsThatSampleExactly) {
  TimingStats stats;
  stats.add(3.7e-6);
  for (double q : {0.0, 0.5, 1.0}) EXPECT_EQ(stats.quantile_s(q), 3.7e-6) << "q = " << q;
}

TEST(TimingStats, ValuesOutsideTheHistogramKeepExactExtremesAndQuantilesStayBetweenThem) {
  TimingStats stats;
  stats.add(1.0e-9);  // below the 10 ns floor of the histogram
  stats.add(30.0);    // above its 10 s ceiling
  EXPECT_EQ(stats.min_s(), 1.0e-9);
  EXPECT_EQ(stats.max_s(), 30.0);
  for (double q : {0.0, 0.5, 1.0}) {
    EXPECT_GE(stats.quantile_s(q), 1.0e-9) << "q = " << q;
    EXPECT_LE(stats.quantile_s(q), 30.0) << "q = " << q;
  }
  stats.reset();
  EXPECT_EQ(stats.count(), 0u);
}

}  // namespace

namespace {

// A backend whose reads go stale on request (a module that stopped answering).
class FlakyBackend final : public pneu::hal::Backend {
 public:
  void open(double) override {}
  void close() noexcept override {}
  pneu::hal::Status read(double t_s, pneu::hal::SensorFrame& frame) noexcept override {
    frame = pneu::hal::SensorFrame{t_s, 0.2195, 3.4e5, 4.9e5, 0.0, false, true, 0, 0.0};
    if (!stale) return pneu::hal::Status::kOk;
    frame.validity = pneu::hal::kSampleStale;
    return pneu::hal::Status::kStale;
  }
  pneu::hal::Status write(const pneu::hal::ActuatorCommand&) noexcept override { return pneu::hal::Status::kOk; }
  bool stale = false;
};

TEST(ControlLoop, CountsBackendFailuresAndHandsThemToHealth) {
  auto config = pneu::config::load_string(pneu::config::default_config_yaml(), {"controller.law.gains=fixed"});
  config.controller.schedule.clear();
  FlakyBackend backend;
  auto outputs = std::make_unique<pneu::controller::LoopOutputs>();
  pneu::controller::ControlLoop loop(pneu::controller::LoopParams::from(config), backend, *outputs);
  pneu::controller::SimulatedClock clock;
  pneu::controller::LoopTiming timing;
  const std::atomic<bool> never{false};
  int k = 0;
  // 100 good ticks, then 60 stale ones; health every 50 ms, and a final record as the loop ends.
  pneu::controller::run_loop(loop, clock, 1e-3, 160, never, timing, [&] { backend.stale = ++k >= 100; }, 0.05,
                             outputs.get());
  EXPECT_EQ(loop.comms_errors(), 60u);
  pneu::controller::HealthRecord h, last;
  int n = 0;
  while (outputs->health.try_pop(h)) last = h, ++n;
  ASSERT_EQ(n, 4) << "three periodic records and the final one";
  EXPECT_TRUE(last.is_final);
  EXPECT_EQ(last.comms_errors, 60u) << "the last health record saw every failure so far";
  EXPECT_EQ(last.mode, pneu::controller::Mode::kFault) << "50 ms of stale samples latch the comms fault";
  EXPECT_EQ(last.fault_cause, pneu::controller::FaultCause::kComms);
}

}  // namespace

namespace {

// A clock that is not simulated (the runner measures overruns on it) and never sleeps: time jumps
// to each deadline asked for, and `stall_s` more whenever a test adds it (a stall of the machine).
class StallingClock final : public pneu::controller::Clock {
 public:
  double now_s() noexcept override { return now_s_; }
  void sleep_until(double t_s) noexcept override {
    if (t_s > now_s_) now_s_ = t_s;
  }
  bool simulated() const noexcept override { return false; }
  void stall(double s) { now_s_ += s; }

 private:
  double now_s_ = 0.0;
};

// Every deadline of a run is either ticked or skipped, once: a stall skips the deadlines it
// passed, those of the run only, however close to its end it comes.
class LoopDeadlines : public ::testing::TestWithParam<int> {};

TEST_P(LoopDeadlines, AreEachTickedOrSkippedOnceWhereverAStallComes) {
  auto config = pneu::config::load_string(pneu::config::default_config_yaml(), {"controller.law.gains=fixed"});
  config.controller.supervisor.overruns_in_a_row = 0;
  config.controller.supervisor.max_tick_interval_s = 0.0;
  FlakyBackend backend;
  auto outputs = std::make_unique<pneu::controller::LoopOutputs>();
  pneu::controller::ControlLoop loop(pneu::controller::LoopParams::from(config), backend, *outputs);
  StallingClock clock;
  pneu::controller::LoopTiming timing;
  const std::atomic<bool> never{false};
  const int stall_after_tick = GetParam();
  int k = 0;
  // A 5.5-period stall after the given tick (between it and the next deadline), of a run of 20
  // deadlines: the next deadline is ticked late, the 4 the late tick ends past are skipped.
  pneu::controller::run_loop(loop, clock, 1e-3, 20, never, timing, [&] {
    if (++k == stall_after_tick) clock.stall(5.5e-3);
  });
  EXPECT_EQ(timing.overruns, 1u);
  EXPECT_EQ(timing.ticks + timing.deadlines_skipped, 20u) << timing.ticks << " ticks";
  EXPECT_EQ(timing.deadlines_skipped, static_cast<std::uint64_t>(std::min(4, 19 - stall_after_tick)));
}

INSTANTIATE_TEST_SUITE_P(StallAfterTick, LoopDeadlines, ::testing::Values(1, 10, 15, 17, 19),
                         [](const auto& p) { return "Tick" + std::to_string(p.param); });

}  // namespace

namespace {

// The thread's timer slack [ns] (prctl PR_GET_TIMERSLACK).
long timer_slack_ns() { return prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0); }

// The timer slack run_loop's thread has while it ticks on `clock`, starting from the 50 us a thread
// under normal scheduling has by default. Runs on a thread of its own, so this one is left as it is.
long slack_while_ticking(pneu::controller::Clock& clock) {
  long during = -1;
  std::thread loop_thread([&] {
    (void)prctl(PR_SET_TIMERSLACK, 50'000UL, 0UL, 0UL, 0UL);
    auto config = pneu::config::load_string(pneu::config::default_config_yaml(), {"controller.law.gains=fixed"});
    FlakyBackend backend;
    auto outputs = std::make_unique<pneu::controller::LoopOutputs>();
    pneu::controller::ControlLoop loop(pneu::controller::LoopParams::from(config), backend, *outputs);
    pneu::controller::LoopTiming timing;
    const std::atomic<bool> never{false};
    pneu::controller::run_loop(loop, clock, 1e-3, 3, never, timing, [&] { during = timer_slack_ns(); });
  });
  loop_thread.join();
  return during;
}

// Under normal scheduling the kernel may defer a thread's wake-up by its timer slack (50 us by
// default) to group it with others: the loop's deadlines would all be met that much late.
TEST(RealClock, RunsTheLoopThreadWithATimerSlackOf1ns) {
  pneu::controller::RealClock clock;
  EXPECT_EQ(slack_while_ticking(clock), 1);
}

TEST(SimulatedClock, LeavesTheLoopThreadsTimerSlackAsItIs) {
  pneu::controller::SimulatedClock clock;
  EXPECT_EQ(slack_while_ticking(clock), 50'000);
}

}  // namespace
