// How fast the controller runs. Targets: one tick's computation (sim backend excluded) has a
// median under 5 us; the 12 s paper scenario end to end in simulated time runs at least 200 times
// faster than real time.
//
// The paper scenario (docs/model.md section 7, config/sim.yaml): carriage at rest at 219.5 mm, set point
// 170 mm from t = 1 s, 12 s at 1 kHz. It is run once, before any timing, to record what the
// loop's sensors read at every tick and the snapshot of its longest sticking phase; the tick
// benchmark replays the recorded frames through a trivial backend, so the differentiator, the law
// and the stop detector see the real scenario (stops, starts, the set-point step) and the plant's
// integration is not timed.
//
// Run pinned to one core, from the build directory, with the options
// --benchmark_repetitions=5 --benchmark_report_aggregates_only=true:
//   taskset -c 1 bin/bench_controller --benchmark_repetitions=5 ...
#include <benchmark/benchmark.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <vector>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/clock.hpp"
#include "pneu/controller/loop.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/controller/runtime.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/model/valve.hpp"

namespace {

using namespace pneu;
using controller::ControlLoop;
using controller::LoopOutputs;

// Passes the sim backend through and keeps every frame the loop reads (recording only, not timed;
// the vector is reserved up front so the loop-side push_back never reallocates).
class RecordingBackend final : public hal::Backend {
 public:
  RecordingBackend(hal::Backend& inner, std::vector<hal::SensorFrame>& frames)
      : inner_(inner), frames_(frames) {}
  void open(double t0_s) override { inner_.open(t0_s); }
  void close() noexcept override { inner_.close(); }
  [[nodiscard]] hal::Status read(double t_s, hal::SensorFrame& frame) noexcept override {
    const hal::Status s = inner_.read(t_s, frame);
    if (frames_.size() < frames_.capacity()) frames_.push_back(frame);
    return s;
  }
  [[nodiscard]] hal::Status write(const hal::ActuatorCommand& command) noexcept override {
    return inner_.write(command);
  }

 private:
  hal::Backend& inner_;
  std::vector<hal::SensorFrame>& frames_;
};

// Hands out the recorded frames in order from open() on (the last one again past the end); costs a
// copy per read.
class ReplayBackend final : public hal::Backend {
 public:
  explicit ReplayBackend(const std::vector<hal::SensorFrame>& frames) : frames_(frames) {}
  void open(double) override { next_ = 0; }
  void close() noexcept override {}
  [[nodiscard]] hal::Status read(double, hal::SensorFrame& frame) noexcept override {
    frame = frames_[next_ < frames_.size() ? next_++ : frames_.size() - 1];
    return hal::Status::kOk;
  }
  [[nodiscard]] hal::Status write(const hal::ActuatorCommand& command) noexcept override {
    last_command_ = command;
    return hal::Status::kOk;
  }
  [[nodiscard]] const hal::ActuatorCommand& last_command() const noexcept { return last_command_; }

 private:
  const std::vector<hal::SensorFrame>& frames_;
  std::size_t next_ = 0;
  hal::ActuatorCommand last_command_;
};

struct Recording {
  std::optional<assembly::RunSpec> spec;  ///< the default's: its law designed once, as pneud does
  std::uint64_t ticks = 0;               ///< ticks of the 12 s run (both ends included)
  std::vector<hal::SensorFrame> frames;  ///< what the loop read: start()'s reading, then each tick
  std::vector<double> control_v;         ///< u of each tick
  controller::PredictorModel model;
  /// Snapshot of the longest sticking phase that ends in a restart.
  controller::StopSnapshot long_stop;
  double long_stop_sticking_s = 0.0;
  std::size_t stops = 0;

  [[nodiscard]] const config::Config& config() const { return spec->config(); }
  [[nodiscard]] const controller::ControlLaw& law() const { return spec->law(); }
};

// Built once in main(), before any benchmark runs.
std::optional<Recording> g_rec;

void record_paper_scenario(Recording& rec) {
  rec.spec.emplace(assembly::RunSpec::of(config::load_string(config::default_config_yaml())));
  rec.model = rec.spec->predictor_model();
  const double period = rec.config().controller.period_s();
  rec.ticks =
      static_cast<std::uint64_t>(std::llround(rec.config().controller.duration_s / period)) + 1;

  auto run = assembly::AssembledRun::on_simulated_bench(*rec.spec);
  rec.frames.reserve(rec.ticks + 1);
  RecordingBackend recorder(run.backend(), rec.frames);
  auto outputs = std::make_unique<LoopOutputs>();
  ControlLoop loop(controller::LoopParams::from(rec.config(), rec.law()), recorder, *outputs);
  loop.start(0.0);
  for (std::uint64_t k = 0; k < rec.ticks; ++k) {
    loop.tick(static_cast<double>(k) * period);
    controller::TickRecord r;
    while (outputs->ticks.try_pop(r)) rec.control_v.push_back(r.u_v);
    run.runtime().drain(*outputs);
  }
  run.runtime().finish(run.runtime().end_time_s());

  rec.stops = run.runtime().stops().size();
  for (const auto& s : run.runtime().stops()) {
    if (s.restarted && s.sticking_s() > rec.long_stop_sticking_s) {
      rec.long_stop_sticking_s = s.sticking_s();
      rec.long_stop = s.snapshot;
    }
  }
}

// The replay drives the loop through exactly the recorded run: same control, bit for bit.
bool replay_reproduces_recording(const Recording& rec) {
  ReplayBackend replay(rec.frames);
  auto outputs = std::make_unique<LoopOutputs>();
  ControlLoop loop(controller::LoopParams::from(rec.config(), rec.law()), replay, *outputs);
  loop.start(0.0);
  std::size_t i = 0;
  for (std::uint64_t k = 0; k < rec.ticks; ++k) {
    loop.tick(static_cast<double>(k) * rec.config().controller.period_s());
    controller::TickRecord r;
    while (outputs->ticks.try_pop(r))
      if (i >= rec.control_v.size() || r.u_v != rec.control_v[i++]) return false;
  }
  return i == rec.control_v.size();
}

// Empties both queues, as the non-real-time side would.
void discard_records(LoopOutputs& out) {
  controller::TickRecord r;
  while (out.ticks.try_pop(r)) {
  }
  controller::LoopEvent e;
  while (out.events.try_pop(e)) {
  }
}

// (a) One ControlLoop::tick on recorded frames: read (a copy), differentiate, Eq. 4, write, stop
// detector, queue the record. The queues are emptied every 4096 ticks and the replay restarts at
// the end of the 12 s with timing paused; the pause's own cost, once per 4096 ticks, is below
// 0.1 ns per tick.
void BM_TickReplayedPaperScenario(benchmark::State& state) {
  const Recording& rec = *g_rec;
  const double period = rec.config().controller.period_s();
  ReplayBackend replay(rec.frames);
  auto outputs = std::make_unique<LoopOutputs>();
  ControlLoop loop(controller::LoopParams::from(rec.config(), rec.law()), replay, *outputs);
  loop.start(0.0);
  std::uint64_t k = 0;
  for (auto _ : state) {
    loop.tick(static_cast<double>(k) * period);
    ++k;
    if (k == rec.ticks || (k & 4095u) == 0) {
      state.PauseTiming();
      discard_records(*outputs);
      if (k == rec.ticks) {
        loop.start(0.0);
        k = 0;
      }
      state.ResumeTiming();
    }
  }
  benchmark::DoNotOptimize(replay.last_command());
  if (outputs->ticks_dropped != 0 || outputs->events_dropped != 0)
    state.SkipWithError("records dropped");
}
BENCHMARK(BM_TickReplayedPaperScenario);

// For comparison: one tick with the sim backend in it (the plant integrated over 1 ms, sensors).
void BM_TickWithSimBackend(benchmark::State& state) {
  const Recording& rec = *g_rec;
  const double period = rec.config().controller.period_s();
  auto run = assembly::AssembledRun::on_simulated_bench(*rec.spec);
  run.loop().start(0.0);
  std::uint64_t k = 0;
  for (auto _ : state) {
    run.loop().tick(static_cast<double>(k) * period);
    ++k;
    if (k == rec.ticks || (k & 4095u) == 0) {
      state.PauseTiming();
      discard_records(run.outputs());
      if (k == rec.ticks) {
        run = assembly::AssembledRun::on_simulated_bench(*rec.spec);
        run.loop().start(0.0);
        k = 0;
      }
      state.ResumeTiming();
    }
  }
}
BENCHMARK(BM_TickWithSimBackend);

// (b) The 12 s paper scenario end to end in simulated time, as pneud runs it without output files:
// assembly (AssembledRun on the sim backend), the loop in lockstep with the plant, the runtime draining every
// tick and both predictors at every stop.
void BM_PaperScenarioSimulatedEndToEnd(benchmark::State& state) {
  const Recording& rec = *g_rec;
  const std::atomic<bool> never_stop{false};
  std::size_t stops = 0;
  for (auto _ : state) {
    auto run = assembly::AssembledRun::on_simulated_bench(*rec.spec);
    controller::SimulatedClock clock;
    run.execute(clock, never_stop);
    stops = run.runtime().stops().size();
    benchmark::DoNotOptimize(stops);
  }
  if (stops != rec.stops) {
    state.SkipWithError("the run differs from the recorded one");
    return;
  }
  // Simulated seconds per iteration divided by wall seconds per iteration (UseRealTime below).
  state.counters["real_time_factor"] = benchmark::Counter(
      rec.config().controller.duration_s, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_PaperScenarioSimulatedEndToEnd)->Unit(benchmark::kMillisecond)->UseRealTime();

// (c) The predictors alone, on the snapshot of the paper's long sticking phase (about 4 s).
void BM_PredictLinearizedLongStop(benchmark::State& state) {
  const Recording& rec = *g_rec;
  for (auto _ : state) {
    auto p = controller::predict_linearized(rec.model, rec.long_stop);
    benchmark::DoNotOptimize(p);
  }
  state.counters["sticking_s"] = rec.long_stop_sticking_s;
}
BENCHMARK(BM_PredictLinearizedLongStop);

void BM_PredictNonlinearLongStop(benchmark::State& state) {
  const Recording& rec = *g_rec;
  for (auto _ : state) {
    auto p = controller::predict_nonlinear(rec.model, rec.long_stop);
    benchmark::DoNotOptimize(p);
  }
  state.counters["sticking_s"] = rec.long_stop_sticking_s;
}
BENCHMARK(BM_PredictNonlinearLongStop)->Unit(benchmark::kMicrosecond);

// (c') The relaxation method made again half-way through the long stop: its pressures since the
// snapshot (about 2,000 ticks, thinned to at most 512 samples), both chambers fitted, the crossing
// solved. Also what the history costs to fill, per tick.
void BM_PredictRelaxationHalfWayLongStop(benchmark::State& state) {
  const Recording& rec = *g_rec;
  const double half_s = rec.long_stop.t_s + 0.5 * rec.long_stop_sticking_s;
  controller::PhaseHistory history;
  for (const auto& f : rec.frames)
    if (f.t_s >= rec.long_stop.t_s && f.t_s <= half_s) history.add(f.t_s, f.p_p_pa, f.p_n_pa);
  controller::StopSnapshot now = rec.long_stop;
  now.t_s = half_s;
  for (auto _ : state) {
    auto p = controller::predict_relaxation(rec.model, now, history);
    benchmark::DoNotOptimize(p);
  }
  state.counters["samples"] = static_cast<double>(history.size());
}
BENCHMARK(BM_PredictRelaxationHalfWayLongStop)->Unit(benchmark::kMicrosecond);

// (d) The live predictor's per-tick work: following the forecast made at the long stop through
// its whole sticking phase, one point per 1 ms tick (reported per tick).
void follow_long_stop(benchmark::State& state, controller::PredictionMethod method) {
  const Recording& rec = *g_rec;
  const auto ticks = static_cast<std::int64_t>(rec.long_stop_sticking_s / 1e-3);
  for (auto _ : state) {
    controller::ForecastTrack track(method, rec.model, rec.long_stop);
    double f = 0.0;
    for (std::int64_t k = 1; k <= ticks; ++k) f += track.at(rec.long_stop.t_s + static_cast<double>(k) * 1e-3).force_n;
    benchmark::DoNotOptimize(f);
  }
  state.SetItemsProcessed(state.iterations() * ticks);  // items: ticks followed
}
void BM_FollowLinearizedLongStop(benchmark::State& state) { follow_long_stop(state, controller::PredictionMethod::kLinearized); }
void BM_FollowNonlinearLongStop(benchmark::State& state) { follow_long_stop(state, controller::PredictionMethod::kNonlinear); }
BENCHMARK(BM_FollowLinearizedLongStop)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_FollowNonlinearLongStop)->Unit(benchmark::kMicrosecond);

}  // namespace

int main(int argc, char** argv) {
  g_rec.emplace();
  record_paper_scenario(*g_rec);
  if (g_rec->frames.size() != g_rec->ticks + 1 || g_rec->long_stop_sticking_s < 1.0) {
    std::fprintf(stderr,
                 "bench_controller: the recorded paper scenario is not the expected one "
                 "(%zu frames, longest sticking phase %.3f s)\n",
                 g_rec->frames.size(), g_rec->long_stop_sticking_s);
    return 1;
  }
  if (!replay_reproduces_recording(*g_rec)) {
    std::fprintf(stderr,
                 "bench_controller: replaying the recorded frames does not reproduce the run\n");
    return 1;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
