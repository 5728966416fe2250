// pneu-sweep: runs many set-point steps across the stroke in simulated time, in parallel, and
// judges every restart forecast against what the simulated bench did. The sweep itself is the
// library pneu_sweep (tools/sweep/lib/); this is its command line.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "pneu/config/cli.hpp"
#include "pneu/config/config.hpp"
#include "pneu/sweep/report.hpp"
#include "pneu/sweep/run.hpp"
#include "pneu/sweep/scenario.hpp"
#include "pneu/sweep/shard.hpp"
#include "pneu/sweep/statistics.hpp"

namespace {

using namespace pneu;

constexpr const char* kHelp = R"(pneu-sweep: the restart predictor against many simulated set-point steps

Usage:
  pneu-sweep [--config FILE] --out SWEEP.csv [--steps N] [--seed S] [--jobs J] [--duration S]
             [--step-time S] [--tail S] [--margin-m M] [--min-step-m D] [--friction-spread F] [--gain-spread G]
             [--bench-spread B] [--bench-thermal-s LO[:HI]] [--bench-spool-lag-s LO[:HI]]
             [--scenarios-out SCENARIOS.csv] [--set KEY=VALUE ...] [--supervised] [--strict]
             [--strict-forecasts] [--identify] [--online] [--summary-json FILE] [--quiet] [--shard K/N]
             [--design mc|lhs|grid] [--grid-levels AxBxCxD[xE[xF]]]
  pneu-sweep merge --out SWEEP.csv [--scenarios-out SCENARIOS.csv] [--summary-json FILE] [--strict]
             [--strict-forecasts] SHARD.csv...

Scenario i starts at rest at a random position y0 and steps the set point at --step-time
(default 1 s) to y_d, the targets spread evenly over the stroke less --margin-m (default 0.02 m)
at each end, |y_d - y0| >= --min-step-m (default 0.005 m). --friction-spread F scales all friction
values of a scenario by a factor drawn in [1-F, 1+F], --gain-spread G the three gains likewise,
fixed or scheduled (every node of the table) (default 0: the config's values): model and bench
alike. --bench-spread B gives each scenario a simulated bench of its own, drawn around the configured
one (plant:, or hal.sim.plant over it), while plant: stays the controller's model: each friction value (F_S+, F_C+, F_S-, F_C-, sigma; a Coulomb level kept
within its stiction bound), each valve conductance (C_max, both leaks) and each dead volume
scaled by its own factor drawn in [1-B, 1+B], and a valve null offset drawn in [-B/2, B/2] V
(from a generator of its own: the scenarios stay those of the seed). Each scenario runs --duration seconds (default 12) in simulated
time, then --tail seconds more (default 1) in which no new stop is judged: a restart forecast just
before the end of the window is then seen or refuted by the signals rather than cut off (a
breakaway with a force a hair beyond stiction moves the carriage by less than the detector's
motion band for tens of milliseconds). --jobs threads (default: the cores) share the scenarios.

--design lhs|grid draws an atlas instead (default mc: the above): each scenario's set point and
bench tolerances placed by a Latin hypercube (lhs: in each dimension one scenario per stratum of
its range, the strata shuffled per dimension from the seed, a random place within each) or on a
full grid (grid: the middle of each level, the set point varying fastest; --grid-levels gives each
dimension's number of levels, their product the number of scenarios: --steps, if given, must be
it). The dimensions, in this order: the set point over the targets' range; the bench's friction,
every friction value scaled by one factor in [1-B, 1+B]; its dead volumes, both by one factor in
[1-B, 1+B]; its valve null offset in [-B/2, B/2] V (B: --bench-spread); then, when given, the
thermal time constant in --bench-thermal-s's range and the spool lag in --bench-spool-lag-s's. The
conductances stay the model's; the start y0 is drawn as above. The drawn bench is in the
scenarios file's bench_* columns (bench_static_positive_n / the model's F_S+: the friction factor).
tools/plots/atlas.py turns an atlas into maps (docs/atlas.md).

--online adds pneud's online identification to each scenario's run: the forecasts use what it has
identified so far, from the configured model (with --identify, from the identified one); the
stops before the scenario's 3rd restart (while it learns) are not judged, and counted. The
summary then splits the judged stops in two: those pneud forecast on a stiction bound it had not
identified yet (the configured one: no breakaway that way yet), and the others.

--identify first runs pneud's identification run (pneud --identify) on each scenario's bench, from
the configured model, and runs the scenario on the model it identified: plant: then holds what
was identified (u_0, the gain design and the forecasts use it); the bench stays the scenario's.
A scenario whose identification fails (a fault, too little shown) is counted as such, with the
reason, and not run. The summary gives the identified stiction's and null-flow pressure's errors
against each bench; the scenarios file, identified_* columns.

The sweep studies the control law and the forecast, not the bench's protection: unless
--supervised, the supervisor's motion and range checks are off (large steps slam the carriage
into an end stop and push a chamber past the pressure sensor's range, which pneud would rightly
latch as faults and so end the scenario), and so are its settling rules (oscillation, settle
time: controller.supervisor.oscillation_* and settle_time_s), so that every scenario runs its
whole duration and every stop counts in the forecast figures. Those rules are checked alongside
instead: a supervisor of the sweep's own, with only them on, is fed each scenario's ticks and
tells when it would have latched the oscillation or the not-settled fault (the run goes on). With --supervised
every check is on as in pneud, and a fault ends the scenario's control (outcome fault).

Each scenario gets an outcome, from the first time the carriage comes to rest after the step:
the stop detector's first stop after it, before any fault, at which the plant was at rest, or came
to rest without breaking away first (noisy sensors can make the detector confirm a stop while the
plant turns slowly, or creeps onto a stiction bound its Coulomb level nearly meets; the rest then
dates from the plant's stick). settled: at rest
inside the stroke; end-stop: at rest against an end stop (it may come off it later:
final_error_m tells); never-settled: no rest to the end of the run, tail included; fault: a fault
latched (--supervised). A carriage that the step does not move has settled at once. The summary
counts them (their sum is the number of scenarios), says where on the stroke those that did not
settle lie, and gives the settle time (the first rest, from the step) and the final error
(|y_d - y| at the end of the run) percentiles over the settled ones. --scenarios-out writes one
row per scenario: scenario,y0_m,y_d_m,friction_scale,gain_scale,outcome,settle_time_s,
final_error_m,fault_cause,fault_after_s,stops,restarts,at_rest_at_end,last_second_swing_m,
oscillation_rule_after_s (times from the step, empty where not applicable; stops and restarts
over the whole run; last_second_swing_m: the peak-to-peak position over the run's last second;
oscillation_rule_after_s: when the settling rules checked alongside would have latched the
oscillation or the not-settled fault, unless --supervised), then the simulated bench the scenario
ran, bench_* (the model's friction, conductances, dead volumes and null offset unless
--bench-spread; its heat transfer and thermal time constant at mid-stroke, empty without the
energy balance, and its spool lag; y0_m, y_d_m and bench_* exactly, to all their digits: the
scenario runs again in pneud with them), then in_window_after_s (the first rest within controller.hold.window_m of the
set point that the plant confirms, at once or by sticking before any breakaway), hold_after_s (the
in-position hold's first start within the window) and restarts_after_hold (the plant's breakaways
after it beyond the detector's motion band). The summary gives the time into the window over
those that came and over all (never counted as never), and with controller.hold on, the forecasts
under the hold's commands: how many made while held said restart, and each reach's breakaway
forecast against the start seen.

Stops are those pneud's stop detector sees; what happened after each is the simulated truth: the
plant's first breakaway after the forecast was made is the restart, timed exactly, even when it
moves the carriage less than the detector's motion band (a set-point change before it ends the
stop unjudged); the summary says how far the detector's dates of the starts it saw fall from the
breakaways. With noisy sensors (e.g. --config config/hil.yaml --set hal.backend=sim) the
detector may confirm a stop while the plant still slides within its rest band: counted, not
judged (outcome plant_not_at_rest). SWEEP.csv has one row per stop: the scenario, the stop, what happened, and each
method's forecast with its verdict and error. The summary gives the confusion matrix of restart / no restart and the
error percentiles per method. Acceptance: restarts after >= 0.5 s of sticking within 1 % of the
sticking time (nonlinear) and 5 % (linearized), shorter ones within 10 ms. The forecast figures
cover every stop of every scenario, whatever its outcome (a scenario that never settles has no
stop to judge). --strict exits 1 when any forecast misses its criteria or any scenario does not
settle, saying which; --strict-forecasts only on the forecasts. For those restarts the summary
and the *_halfway_error_percent columns also give the error of the live predictor: the forecast
made again (every controller.predictor.update_period_s) from the last pressures before half the
sticking time, in % of the whole sticking time; it is not judged. With "relaxation" among
controller.predictor.methods, the relaxation method (each chamber's relaxation fitted to the
phase's own pressures, no valve model) is reported the same way: it makes no forecast at the stop,
only half-way ones (rx_halfway_error_percent). With --online, forecast_on_unidentified_bound is 1
for a stop forecast on a stiction bound online learning had not identified yet (the configured
one: no breakaway that way yet), as pneud's summary counts them; and side_broken_away_slowly is 1
for a stop whose forecast turns on a side (the side of the restart it forecast, or for "no
restart" the side the force relaxes towards) that the bench had already broken away to after
0.5 s or more stuck: a slow breakaway, the pressures' drift crossing that bound, which dates it
far better than a set-point step's (the bench's own restarts, in the scenario before the stop).
The summary gives the judged stops of that kind apart too.

--summary-json FILE writes the summary's figures for programs, one JSON object: scenarios and
scenarios_run; setting (the options and the hold's window); stops (counts, the detector's dating
of the starts); outcomes (settled, never_settled, end_stop, fault: count, where they lie, in how
many the settling rules would latch); faults_by_cause; settle_time_s and final_error_m (over the
settled ones); in_window (the time into controller.hold.window_m; all_p50_s / all_p90_s null when
never); hold; settling_rules; identification (with --identify); methods (linearized, nonlinear,
relaxation: the verdicts' counts, the errors' percentiles, the half-way forecasts, the --online
splits); wall_s and jobs. Percentiles are objects of count, p50, p90, p99 and max (null when
count is 0). A sweep that fails once started leaves no file there (an earlier one's is removed).

--shard K/N (1 <= K <= N) runs only the scenarios whose index i falls to shard K (i % N == K - 1),
each exactly as the whole sweep runs it (the same draw, seed and bench), and writes beside its
--out file the shard file SWEEP.csv.shard: the sweep's setting, the configuration's fingerprint,
and each of its scenarios' rows and figures (every value the summary is computed from). Its
--out, --scenarios-out and summary are those of its own scenarios. A shard that failed is run
again alone, with the same options. Progress goes to stderr (scenarios done, rate, time left and
the estimated end): redrawn on a terminal, otherwise a line per 10 % or per minute.

pneu-sweep merge takes the shards of one sweep, each named by its --out file (or its .shard
file), in any order, and writes what the unsharded sweep writes: --out and --scenarios-out
identical to its files byte for byte, the summary and --summary-json the same figures, except the
wall time: the merge's is the shards' wall times summed (wall_s; jobs: the most threads a shard
ran on), and its summary's line says so. It says on stderr which shards it took. It refuses (exit
2), naming the file, a shard given twice, a shard of another sweep (other options, seed, number
of steps, configuration, or N: what differs is said) and a sweep with shards missing (which).
)";

// "LO" or "LO:HI" of --bench-thermal-s and --bench-spool-lag-s: the range drawn from [s].
sweep::DrawRange draw_range(const cli::Args& args, const char* option, double min_s) {
  const auto text = args.value(option);
  if (!text) return {};
  const auto colon = text->find(':');
  const auto number = [&](const std::string& t) {
    std::size_t used = 0;
    double v = NAN;
    try {
      v = std::stod(t, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != t.size() || !std::isfinite(v))
      throw cli::UsageError(std::string("--") + option + ": '" + *text + "' is not LO or LO:HI in seconds");
    return v;
  };
  sweep::DrawRange r;
  r.lo = number(text->substr(0, colon));
  r.hi = colon == std::string::npos ? r.lo : number(text->substr(colon + 1));
  if (!(r.lo >= min_s && r.hi >= r.lo))
    throw cli::UsageError(std::string("--") + option + " must be LO:HI with " + (min_s > 0 ? "0 < " : "0 <= ") +
                          "LO <= HI (got '" + *text + "')");
  return r;
}

// --design and --grid-levels into `o` (its ranges and steps already read): the grid's levels give
// the number of scenarios.
void design_options(const cli::Args& args, sweep::Options& o) {
  const std::string design = args.value("design").value_or("mc");
  const auto levels_text = args.value("grid-levels");
  // By the designs' own names (sweep::design_name), as the summary and the shard files spell them.
  constexpr sweep::Design kDesigns[] = {sweep::Design::kMonteCarlo, sweep::Design::kLatinHypercube,
                                        sweep::Design::kGrid};
  const auto named = std::find_if(std::begin(kDesigns), std::end(kDesigns),
                                  [&](sweep::Design d) { return design == sweep::design_name(d); });
  if (named == std::end(kDesigns)) throw cli::UsageError("--design must be mc, lhs or grid (got '" + design + "')");
  o.design = *named;
  if (o.design != sweep::Design::kGrid) {
    if (levels_text) throw cli::UsageError("--grid-levels goes with --design grid");
    return;
  }
  const std::size_t dims = sweep::atlas_dimensions(o);
  const std::string want = "--grid-levels must be " + std::to_string(dims) +
                           " whole numbers >= 1 joined by 'x', one per dimension (set point, friction, dead volume, "
                           "null offset" + (o.bench_thermal_s.given() ? ", thermal time constant" : "") +
                           (o.bench_spool_lag_s.given() ? ", spool lag" : "") + ")";
  if (!levels_text) throw cli::UsageError(want);
  std::size_t d = 0, at = 0;
  long long product = 1;
  while (at <= levels_text->size()) {
    const std::size_t x = std::min(levels_text->find('x', at), levels_text->size());
    const std::string word = levels_text->substr(at, x - at);
    if (d >= dims || word.empty() || word.size() > 6 || word.find_first_not_of("0123456789") != std::string::npos ||
        std::stoi(word) < 1)
      throw cli::UsageError(want + " (got '" + *levels_text + "')");
    o.grid_levels[d++] = std::stoi(word);
    product *= o.grid_levels[d - 1];
    if (product > 100000000) throw cli::UsageError("--grid-levels: more than 10^8 scenarios");
    at = x + 1;
  }
  if (d != dims) throw cli::UsageError(want + " (got '" + *levels_text + "')");
  if (args.value("steps") && o.steps != product)
    throw cli::UsageError("--steps " + std::to_string(o.steps) + " is not the grid's " + std::to_string(product) +
                          " scenarios (--grid-levels " + *levels_text + "): leave --steps out");
  o.steps = static_cast<int>(product);
}

// --strict and --strict-forecasts on a sweep's statistics: the exit code, and why on stderr.
int strict_exit_code(const cli::Args& args, const sweep::Statistics& stats) {
  int exit_code = cli::kExitOk;
  const sweep::MethodStatistics &lin = stats.methods[0], &nl = stats.methods[1];
  if ((args.flag("strict") || args.flag("strict-forecasts")) && (lin.outside_criteria || nl.outside_criteria)) {
    std::fprintf(stderr, "pneu-sweep: strict: %llu forecasts outside the acceptance criteria (linearized %llu, nonlinear %llu)\n",
                 static_cast<unsigned long long>(lin.outside_criteria + nl.outside_criteria),
                 static_cast<unsigned long long>(lin.outside_criteria),
                 static_cast<unsigned long long>(nl.outside_criteria));
    exit_code = cli::kExitFailure;
  }
  const auto count = [&](sweep::Outcome oc) { return static_cast<unsigned long long>(stats.count(oc)); };
  const unsigned long long unsettled = static_cast<unsigned long long>(stats.scenarios) - count(sweep::Outcome::kSettled);
  if (args.flag("strict") && unsettled > 0) {
    std::fprintf(stderr, "pneu-sweep: strict: %llu of %d scenarios did not settle (%llu never settled, %llu at an end stop, %llu faults)\n",
                 unsettled, stats.scenarios, count(sweep::Outcome::kNeverSettled), count(sweep::Outcome::kEndStop),
                 count(sweep::Outcome::kFault));
    exit_code = cli::kExitFailure;
  }
  return exit_code;
}

// pneu-sweep merge: the shards' arguments are the words that are not options.
int merge(int argc, char** argv) {
  const std::vector<std::string> value_options{"out", "scenarios-out", "summary-json"};
  std::vector<char*> option_argv{argv[0], argv[1]};
  std::vector<std::filesystem::path> shards;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("-", 0) != 0) {
      shards.emplace_back(a);
      continue;
    }
    option_argv.push_back(argv[i]);
    if (std::find(value_options.begin(), value_options.end(), a.substr(2)) != value_options.end() && i + 1 < argc)
      option_argv.push_back(argv[++i]);
  }
  const cli::Args args(static_cast<int>(option_argv.size()), option_argv.data(), 2, value_options,
                       {"strict", "strict-forecasts", "help"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  const std::string out_path = args.required("out");
  if (shards.empty()) throw cli::UsageError("merge: no shard named (SHARD.csv: each shard's --out)");
  std::vector<std::pair<std::string, std::string>> outputs{{"--out", out_path}};
  for (const char* option : {"scenarios-out", "summary-json"})
    if (const auto path = args.value(option)) outputs.emplace_back(std::string("--") + option, *path);
  if (outputs.size() > 1) cli::refuse_same_file(outputs);
  sweep::MergedSweep merged;
  try {
    merged = sweep::merge_shards(shards);
  } catch (const std::runtime_error& e) {
    throw cli::UsageError(std::string("merge: ") + e.what());
  }
  for (const std::string& line : merged.taken) std::fprintf(stderr, "pneu-sweep merge: took %s\n", line.c_str());
  cli::OutputFile out(out_path, "--out");
  std::optional<cli::OutputFile> scenarios_out, summary_json;
  if (const auto path = args.value("scenarios-out")) scenarios_out.emplace(*path, "--scenarios-out");
  if (const auto path = args.value("summary-json")) summary_json.emplace(*path, "--summary-json");
  out.stream() << merged.stops_csv;
  out.commit();
  if (scenarios_out) {
    scenarios_out->stream() << merged.scenarios_csv;
    scenarios_out->commit();
  }
  if (summary_json) {
    sweep::write_summary_json(summary_json->stream(), merged.statistics);
    summary_json->commit();
  }
  sweep::print_summary(stdout, merged.statistics);
  std::printf("  wrote %s\n", out_path.c_str());
  if (scenarios_out) std::printf("  wrote %s\n", scenarios_out->path().c_str());
  if (summary_json) std::printf("  wrote %s\n", summary_json->path().c_str());
  return strict_exit_code(args, merged.statistics);
}

// "HH:MM:SS UTC" of now + seconds_from_now.
std::string clock_after(double seconds_from_now) {
  const std::time_t t = std::time(nullptr) + static_cast<std::time_t>(std::lround(seconds_from_now));
  std::tm utc{};
  gmtime_r(&t, &utc);
  char text[16];
  std::strftime(text, sizeof text, "%H:%M:%S", &utc);
  return std::string(text) + " UTC";
}

int run(int argc, char** argv) {
  if (argc > 1 && std::string(argv[1]) == "merge") return merge(argc, argv);
  const cli::Args args(argc, argv, 1,
                       {"config", "out", "steps", "seed", "jobs", "duration", "step-time", "margin-m",
                        "min-step-m", "friction-spread", "gain-spread", "bench-spread", "tail", "scenarios-out",
                        "bench-thermal-s", "bench-spool-lag-s", "summary-json", "shard", "design", "grid-levels"},
                       {"strict", "strict-forecasts", "quiet", "help", "supervised", "identify", "online"}, {"set"});
  if (args.flag("help")) {
    std::cout << kHelp;
    return cli::kExitOk;
  }
  const std::string config_path = args.value("config").value_or("");
  const config::Config config = config::load_file_or_default(config_path, args.all("set"));
  sweep::Options o;
  o.supervised = args.flag("supervised");
  o.identify = args.flag("identify");
  o.online = args.flag("online") || config.controller.predictor.learn_online;
  o.config_dir = config_path.empty() ? std::filesystem::path() : std::filesystem::path(config_path).parent_path();
  const std::string out_path = args.required("out");
  const double steps_d = args.number("steps", 200);
  const double seed_d = args.number("seed", 1);
  const double jobs_d = args.number("jobs", std::max(1u, std::thread::hardware_concurrency()));
  o.duration_s = args.number("duration", 12.0);
  o.step_time_s = args.number("step-time", 1.0);
  o.margin_m = args.number("margin-m", 0.02);
  o.min_step_m = args.number("min-step-m", 0.005);
  o.friction_spread = args.number("friction-spread", 0.0);
  o.gain_spread = args.number("gain-spread", 0.0);
  o.bench_spread = args.number("bench-spread", 0.0);
  o.tail_s = args.number("tail", 1.0);
  const double half = config.plant.geometry.half_stroke_m();
  if (!(steps_d >= 1 && steps_d == std::floor(steps_d))) throw cli::UsageError("--steps must be a whole number >= 1");
  if (!(jobs_d >= 1 && jobs_d == std::floor(jobs_d))) throw cli::UsageError("--jobs must be a whole number >= 1");
  if (!(seed_d >= 0 && seed_d == std::floor(seed_d))) throw cli::UsageError("--seed must be a whole number >= 0");
  if (!(o.duration_s > o.step_time_s && o.step_time_s >= 0)) throw cli::UsageError("--duration must exceed --step-time >= 0");
  if (!(o.margin_m >= 0 && 2 * o.margin_m + o.min_step_m < 2 * half))
    throw cli::UsageError("--margin-m leaves no room in the stroke");
  if (!(o.min_step_m >= 0)) throw cli::UsageError("--min-step-m must be >= 0");
  // Every target needs a start at least min_step away inside [lo, hi]: the mid-range one too.
  if (!(o.min_step_m < half - o.margin_m)) throw cli::UsageError("--min-step-m must be below half the usable stroke");
  if (!(o.friction_spread >= 0 && o.friction_spread < 1)) throw cli::UsageError("--friction-spread must be in [0, 1)");
  if (!(o.gain_spread >= 0 && o.gain_spread < 1)) throw cli::UsageError("--gain-spread must be in [0, 1)");
  if (!(o.bench_spread >= 0 && o.bench_spread < 1)) throw cli::UsageError("--bench-spread must be in [0, 1)");
  if (!(o.tail_s >= 0)) throw cli::UsageError("--tail must be >= 0");
  o.bench_thermal_s = draw_range(args, "bench-thermal-s", 1e-6);
  o.bench_spool_lag_s = draw_range(args, "bench-spool-lag-s", 0.0);
  o.steps = static_cast<int>(steps_d);
  design_options(args, o);
  o.seed = static_cast<std::uint64_t>(seed_d);
  std::optional<sweep::ShardSpec> shard;
  if (const auto text = args.value("shard")) {
    try {
      shard = sweep::parse_shard(*text);
    } catch (const std::invalid_argument& e) {
      throw cli::UsageError(e.what());
    }
  }

  std::vector<sweep::Scenario> scenarios = sweep::draw_scenarios(o, half);
  if (shard) scenarios = sweep::scenarios_of(*shard, scenarios);
  // (A shard may hold no scenario, when N > --steps.)
  const auto jobs = static_cast<int>(std::max<double>(1.0, std::min<double>(jobs_d, static_cast<double>(scenarios.size()))));

  // Created before the run: an unwritable path, or two outputs on one file, fail fast.
  std::vector<std::pair<std::string, std::string>> outputs{{"--out", out_path}};
  for (const char* option : {"scenarios-out", "summary-json"})
    if (const auto path = args.value(option)) outputs.emplace_back(std::string("--") + option, *path);
  if (shard) outputs.emplace_back("the shard file", sweep::shard_file_path(out_path).string());
  if (outputs.size() > 1) cli::refuse_same_file(outputs);
  cli::OutputFile out(out_path, "--out");
  std::optional<cli::OutputFile> scenarios_out, summary_json, shard_out;
  if (const auto path = args.value("scenarios-out")) scenarios_out.emplace(*path, "--scenarios-out");
  if (const auto path = args.value("summary-json")) summary_json.emplace(*path, "--summary-json");
  if (shard) shard_out.emplace(sweep::shard_file_path(out_path), "the shard file");

  // Progress on stderr (scenarios done, rate, time left, estimated end): redrawn in place on a
  // terminal; otherwise a line per 10 % or per minute, for a batch job's log.
  const bool quiet = args.flag("quiet");
  const bool tty = ::isatty(STDERR_FILENO) && !quiet;
  const std::string who =
      shard ? "pneu-sweep shard " + std::to_string(shard->index) + "/" + std::to_string(shard->count) : "pneu-sweep";
  int last_decile = -1;
  double last_line_s = 0.0;
  const auto progress = [&](int d, int n, double elapsed) {
    if (quiet || n == 0) return;
    const double rate = elapsed > 0.0 ? d / elapsed : 0.0;
    char left[96] = "";
    if (d > 0 && d < n && rate > 0.0)
      std::snprintf(left, sizeof left, ", about %.0f s left (ends %s)", (n - d) / rate,
                    clock_after((n - d) / rate).c_str());
    if (tty) {
      constexpr int kWidth = 40;
      const int filled = kWidth * d / n;
      std::fprintf(stderr, "\r%s [%.*s%*s] %d/%d scenarios, %.1f s, %.2f/s%s\x1b[K", who.c_str(), filled,
                   "########################################", kWidth - filled, "", d, n, elapsed, rate, left);
      if (d == n) std::fprintf(stderr, "\n");
    } else if (d * 10 / n != last_decile || elapsed - last_line_s >= 60.0) {
      last_decile = d * 10 / n;
      last_line_s = elapsed;
      std::fprintf(stderr, "%s: %d/%d scenarios, %.1f s, %.2f scenarios/s%s\n", who.c_str(), d, n, elapsed, rate, left);
    }
  };
  std::optional<sweep::SweepRun> ran;
  try {
    ran.emplace(sweep::run_all(config, o, scenarios, jobs, progress));
  } catch (...) {
    // As pneud's: no figures of an earlier sweep left at --summary-json to be taken for this one's.
    if (summary_json) summary_json->discard_removing_target();
    if (shard_out) shard_out->discard_removing_target();  // the merge then names it missing
    throw;
  }
  const sweep::SweepRun& run = *ran;
  const sweep::Statistics stats = sweep::aggregate(sweep::setting_of(config, o), run);

  sweep::write_stops_csv(out.stream(), run.results, o.online);
  out.commit();
  if (shard_out) {
    sweep::write_shard(shard_out->stream(), {stats.setting, sweep::config_fingerprint(config), *shard, run.wall_s, run.jobs},
                       run.results);
    shard_out->commit();
  }
  if (scenarios_out) {
    sweep::write_scenarios_csv(scenarios_out->stream(), run.results, o.identify);
    scenarios_out->commit();
  }
  if (summary_json) {
    sweep::write_summary_json(summary_json->stream(), stats);
    summary_json->commit();
  }
  sweep::print_summary(stdout, stats);
  std::printf("  wrote %s\n", out_path.c_str());
  if (scenarios_out) std::printf("  wrote %s\n", scenarios_out->path().c_str());
  if (summary_json) std::printf("  wrote %s\n", summary_json->path().c_str());
  if (shard_out) std::printf("  wrote %s\n", shard_out->path().c_str());
  return strict_exit_code(args, stats);
}

}  // namespace

int main(int argc, char** argv) { return pneu::cli::run_main("pneu-sweep", run, argc, argv); }
