// The derived run specification: what a run is made of, derived once from a validated
// configuration and immutable from then on: the valve characteristic the controller uses, the
// configuration with u_0 resolved (controller.law.offset_v: u_e of Eq. 7 when "auto"), and the
// law of Eq. 4 designed (its gain table, where the design fell back). pneud, the sweep, the
// identification run, pneu-plant tune, the benchmarks and the tests take their runs' parts here.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "pneu/controller/control_law.hpp"
#include "pneu/controller/predictor.hpp"
#include "pneu/model/tangent_linear.hpp"
#include "pneu/model/valve.hpp"

namespace pneu::config {
struct Config;  // pneu/config/config.hpp: the root configuration, a run's whole description
}

namespace pneu::assembly {

/// How a specification is derived.
struct SpecOptions {
  /// Where a relative controller.predictor.valve_table is looked up (the configuration file's
  /// directory); empty: the working directory.
  std::filesystem::path config_dir;
  /// Whether the law's design checks the sampled loop (pneu-plant tune maps it instead) ...
  bool check_sampled = true;
  /// ... with this delay beyond the hold [samples]; unset: the backend's (controller::sampled_loop()).
  std::optional<int> delay_samples;
};

/// A run's specification, derived once; copies share the valve characteristic. Every accessor is
/// const: nothing derived is changed after the fact (with_law() and reconfigured() make another).
class RunSpec {
 public:
  /// Derives it from `config` (validated): loads the valve characteristic (config::ConfigError at
  /// controller.predictor.valve_table when its table cannot be read), resolves u_0, designs the
  /// law (config::ConfigError at controller.law.design when the design is refused; where it fell
  /// back, fallbacks() says).
  [[nodiscard]] static RunSpec of(const config::Config& config, const SpecOptions& options = {});

  /// The configuration as validated, u_0 resolved.
  [[nodiscard]] const config::Config& config() const noexcept { return *config_; }
  /// The valve characteristic the controller uses (u_0 of Eq. 7, the design, the predictors).
  [[nodiscard]] const model::ValveCharacteristic& valve() const noexcept { return *valve_; }
  [[nodiscard]] const std::shared_ptr<const model::ValveCharacteristic>& shared_valve() const noexcept { return valve_; }
  /// The law the run drives: controller.law's fixed gains, or the gain table designed.
  [[nodiscard]] const controller::ControlLaw& law() const noexcept { return law_; }
  /// Where the design fell back (controller.law.design.infeasible: fall_back), node by node.
  [[nodiscard]] const std::vector<model::DesignFallback>& fallbacks() const noexcept { return fallbacks_; }
  /// u_0 [V] (controller.law.offset_v resolved).
  [[nodiscard]] double u_0_v() const noexcept;
  /// u_e of Eq. 7 for the configured model [V]: the voltage at which its chambers at rest at
  /// mid-stroke balance the force.
  [[nodiscard]] double equilibrium_voltage_v() const;
  /// The loop's first output, which a simulated plant starts at equilibrium under: u* of Eq. 11
  /// under law() at controller.setpoints.initial_m, the carriage at simulation.initial_position_m [V].
  [[nodiscard]] double first_output_v() const noexcept;
  /// The predictors' view of the bench (its valve: this specification's, shared).
  [[nodiscard]] controller::PredictorModel predictor_model() const;

  /// The same law designed with controller.law.gains: scheduled whatever the configuration says,
  /// with this specification's options (an identification run visits the whole stroke; pneu-plant
  /// tune shows the design beside fixed gains), and where that design fell back.
  struct Scheduled {
    controller::ControlLaw law;
    std::vector<model::DesignFallback> fallbacks;
  };
  [[nodiscard]] Scheduled scheduled_design() const;

  /// This specification driven by `law` in place of its own (an identification run's, a sweep's
  /// mistuned copy); the rest shared, but for fallbacks(), empty: they were the replaced design's.
  [[nodiscard]] RunSpec with_law(controller::ControlLaw law) const;
  /// This specification with `change` made to its configuration: what a run does rather than what
  /// the bench is (the set points, the length, the clock, the supervisor's limits; an
  /// identification run's plan). The valve characteristic, u_0 and the law stay this one's: the
  /// change keeps plant:, controller.law and the valve table, which they were derived from
  /// (std::invalid_argument when it changed the valve table or u_0).
  template <class Change>
  [[nodiscard]] RunSpec reconfigured(Change&& change) const {
    std::shared_ptr<config::Config> next = copy_config();
    change(*next);
    return with_config(std::move(next));
  }

 private:
  RunSpec() = default;
  [[nodiscard]] std::shared_ptr<config::Config> copy_config() const;
  [[nodiscard]] RunSpec with_config(std::shared_ptr<config::Config> config) const;

  std::shared_ptr<const config::Config> config_;
  std::shared_ptr<const model::ValveCharacteristic> valve_;
  controller::ControlLaw law_{controller::ControlLawParams{}};
  std::vector<model::DesignFallback> fallbacks_;
  SpecOptions options_;
};

}  // namespace pneu::assembly
