// The identification run (pneud --identify): a short automatic sequence of moves and holds within
// the soft limits that makes the bench show what identify() needs, recorded from the run's ticks.
//
// The sequence: at three positions (near each end of the soft limits, then mid-way), the carriage
// settles, then the set point ramps slowly up, down and back, so that u* of Eq. 11 ramps while the
// carriage is stuck: the pressure force drifts slowly to each stiction bound and the carriage
// breaks away, sticks again further on, and so on (stick-slip at both bounds, stuck phases at
// many u and three positions). The moves between the positions are the sliding phases, at
// different speeds.
#pragma once

#include <atomic>
#include <cstdio>
#include <ctime>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/describe.hpp"
#include "pneu/controller/setpoint_params.hpp"
#include "pneu/controller/control_law.hpp"
#include "pneu/controller/run_listener.hpp"
#include "pneu/hal/backend.hpp"
#include "pneu/identify/identify.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, taken whole by reference here
}

namespace pneu::identify {

/// The run's set points and length.
struct RunPlan {
  double initial_setpoint_m = 0.0;
  std::vector<controller::SetpointStep> schedule;
  double duration_s = 0.0;
  std::vector<double> positions_m;  ///< where it ramps
  /// Its phases, in order: the move to each position (and the settling there), then the ramp.
  struct Phase {
    double t_s = 0.0;       ///< when it starts [s]
    double position_m = 0.0;
    bool ramp = false;      ///< false: moving there and settling
  };
  std::vector<Phase> phases;
};

/// What the plan is made of.
struct PlanOptions {
  double settle_s = 1.2;           ///< after each move, before the ramp
  double ramp_s = 2.5;             ///< each quarter of the up-down-up ramp
  double step_s = 0.01;            ///< the ramp's staircase: a set point this often
  /// The ramp's reach in force: this many times the prior's stiction band (F_S+ - F_S-), either
  /// way, so a bench whose stiction is off by half still breaks away both ways.
  double force_reach = 1.2;
  double margin_m = 0.03;          ///< the positions stay this far inside the soft limits
};

/// The law an identification run drives: gains designed on `spec`'s model (controller.law.design,
/// as with controller.law.gains: scheduled) whatever controller.law.gains says, because the run
/// visits the whole stroke and fixed gains need not be stable over it (the paper's are not, at
/// mid-stroke). Throws config::ConfigError when the design is refused.
[[nodiscard]] controller::ControlLaw identification_law(const assembly::RunSpec& spec);

/// The plan for `config` (soft limits, plant: as the prior) driven by `law`, starting at rest at
/// `start_m`. Throws std::invalid_argument when the soft limits leave no room for it.
[[nodiscard]] RunPlan plan_run(const config::Config& config, const controller::ControlLaw& law,
                               const model::ValveCharacteristic& valve, double start_m,
                               const PlanOptions& options = {});

/// A sink of the run that keeps every tick as a Sample, and asks the run to stop at the first
/// fault (`stop`, the flag controller::execute() watches).
class Recorder final : public controller::RunListener {
 public:
  explicit Recorder(std::atomic<bool>& stop) : stop_(stop) {}
  void on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) override;
  void on_event(const controller::LoopEvent& event) override;

  [[nodiscard]] const std::vector<Sample>& samples() const noexcept { return samples_; }
  /// The fault that ended the run early, or empty.
  [[nodiscard]] const std::string& fault() const noexcept { return fault_; }
  [[nodiscard]] double fault_time_s() const noexcept { return fault_t_s_; }

 private:
  std::atomic<bool>& stop_;
  std::vector<Sample> samples_;
  std::string fault_;
  double fault_t_s_ = 0.0;
};

/// A sink that says how the run goes, one line at each phase's start: the share done, the phase
/// and the position (pneud --identify on the real clock, whose run lasts about a minute).
class Progress final : public controller::RunListener {
 public:
  Progress(const RunPlan& plan, std::FILE* out) : plan_(plan), out_(out) {}
  void on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) override;

 private:
  const RunPlan& plan_;
  std::FILE* out_;
  std::size_t next_ = 0;     // the next phase to start
  double next_tenth_ = 1.0;  // the next tenth of the run to say
};

/// The sample a tick gives.
[[nodiscard]] Sample sample_of(const controller::TickRecord& tick) noexcept;

/// `config` with the plan's set points and length in force (armed from the start, the in-position
/// hold off).
[[nodiscard]] config::Config configured_for(config::Config config, const RunPlan& plan);
/// `spec` so configured, driven by `law` (identification_law()).
[[nodiscard]] assembly::RunSpec configured_for(const assembly::RunSpec& spec, const RunPlan& plan,
                                               controller::ControlLaw law);

/// An identification run as recorded.
struct RecordedRun {
  RunPlan plan;
  std::vector<Sample> samples;
  std::string fault;        ///< the fault that ended it early, or empty
  double fault_t_s = 0.0;
};

/// The run on the simulated clock, on the simulated bench `bench`: plans from `spec` (plant: the
/// prior) with its law, starting at rest at `start_m`, and records every tick, stopping at the
/// first fault. The bench starts at equilibrium for `spec`'s first output (RunSpec::first_output_v(),
/// before the plan).
[[nodiscard]] RecordedRun record_run(const assembly::RunSpec& spec, const model::PlantParams& bench, double start_m);

/// The whole run on the simulated clock, on the simulated bench `bench` (tests, pneu-sweep): records
/// it (record_run()) and identifies. Throws std::runtime_error naming the fault that ended the run,
/// or InsufficientData.
[[nodiscard]] Identification identify_by_run(const assembly::RunSpec& spec, const model::PlantParams& bench,
                                             double start_m);

/// Where an identification came from, for the header of the configuration it writes.
struct Provenance {
  std::string program;  ///< who identified, and its version ("pneud 0.1.0")
  std::string command;  ///< the command line as given (cli::Args::command_line())
  /// What it was identified from: "its own identification run: 34701 ticks over 34.70 s", "the
  /// trajectory run.csv: ..."
  std::string record;
  /// The configuration file the run started from, whose text is kept; empty: the embedded sim.yaml.
  std::string source;
  std::time_t when = 0;  ///< when it was identified
};

/// The configuration written.
struct IdentifiedYaml {
  std::string text;
  /// Why the source's text could not be kept (a key to write in flow style, ...), when it could
  /// not: the text is then the whole configuration as to_yaml() writes it, under the same header.
  std::string text_not_kept;
};

/// The line that ends the header identified_config_yaml() writes (an identification of a file
/// identified before replaces its header, up to this line).
inline constexpr const char* kEndOfIdentifiedHeader = "# (end of the identification's header)";

/// The configuration to write: `source_text` (the YAML the run's configuration came from: its
/// comments, the documentation of each key, kept byte for byte) edited to hold `config` (the
/// configuration the run started from, --set applied, its own set points and length) with plant:
/// identified (config::with_values_of()): each identified value replaced in place, its note beside
/// it ("# identified 2026-11-28: 45.3 +- 0.12 (was 45)"); the keys the source lacks added in their
/// sections (a simulated bench that was its model: hal.sim.plant, the old plant:, so that the
/// file runs the same bench; controller.predictor.model_fit). Headed by a comment saying when,
/// by what command from which record on which backend, with which fit residual, and what was kept.
/// Validated by loading it back: throws config::ConfigError when the identified values break a
/// rule of the configuration, or `source_text` is not the configuration's source.
[[nodiscard]] IdentifiedYaml identified_config_yaml(std::string_view source_text, const config::Config& config,
                                                   const Identification& id, const Provenance& from);

/// Each parameter before and after, with its uncertainty and what it came from (the table a user
/// reads first), then the evidence and whether the model fits.
void print_report(std::FILE* out, const Identification& id);
/// Whether the model fits the stuck phases' pressures, in a sentence: the residual against what the
/// noise explains, and when it does not fit, the phases that fail worst.
[[nodiscard]] std::string fit_verdict(const Evidence& evidence);

/// identify()'s options for a run of `config` (the stop detector's rest band).
[[nodiscard]] Options options_for(const config::Config& config);

}  // namespace pneu::identify
