#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/config.hpp"

#include <stdexcept>
#include <utility>

#include "pneu/controller/session.hpp"
#include "pneu/model/valve_table.hpp"

namespace pneu::assembly {

namespace {

// The measured table of controller.predictor.valve_table (relative to `config_dir`), or the model.
std::shared_ptr<const model::ValveCharacteristic> load_valve(const config::Config& config,
                                                             const std::filesystem::path& config_dir) {
  const std::string& table = config.controller.predictor.valve_table;
  if (table.empty()) return std::make_shared<const model::ValveModel>(config.plant.valve, config.plant.gas);
  std::filesystem::path path(table);
  if (path.is_relative() && !config_dir.empty()) path = config_dir / path;
  try {
    return std::make_shared<const model::ValveTable>(model::ValveTable::load(path));
  } catch (const model::ValveTableError& e) {
    throw config::ConfigError("controller.predictor.valve_table", e.what());
  }
}

controller::LawDesign design_of(const SpecOptions& o, std::vector<model::DesignFallback>* fallbacks) {
  return {o.check_sampled, o.delay_samples, fallbacks};
}

}  // namespace

RunSpec RunSpec::of(const config::Config& config, const SpecOptions& options) {
  RunSpec spec;
  spec.options_ = options;
  spec.valve_ = load_valve(config, options.config_dir);
  auto resolved = std::make_shared<config::Config>(config);
  if (resolved->controller.offset_auto)
    resolved->controller.law.offset_v = controller::equilibrium_voltage_v(*resolved, *spec.valve_);
  spec.law_ = controller::make_control_law(*resolved, *spec.valve_, design_of(options, &spec.fallbacks_));
  spec.config_ = std::move(resolved);
  return spec;
}

double RunSpec::u_0_v() const noexcept { return config_->controller.law.offset_v; }

double RunSpec::equilibrium_voltage_v() const { return controller::equilibrium_voltage_v(*config_, *valve_); }

double RunSpec::first_output_v() const noexcept {
  return law_.resting_control_v(config_->controller.initial_setpoint_m, config_->simulation.initial_position_m);
}

controller::PredictorModel RunSpec::predictor_model() const { return controller::predictor_model(*config_, *valve_); }

RunSpec::Scheduled RunSpec::scheduled_design() const {
  config::Config designed = *config_;
  designed.controller.law.gains = config::GainsKind::kScheduled;
  Scheduled s{controller::ControlLaw(designed.controller.law), {}};
  s.law = controller::make_control_law(designed, *valve_, design_of(options_, &s.fallbacks));
  return s;
}

RunSpec RunSpec::with_law(controller::ControlLaw law) const {
  RunSpec spec = *this;
  spec.law_ = std::move(law);
  spec.fallbacks_.clear();
  return spec;
}

std::shared_ptr<config::Config> RunSpec::copy_config() const { return std::make_shared<config::Config>(*config_); }

RunSpec RunSpec::with_config(std::shared_ptr<config::Config> config) const {
  if (config->controller.predictor.valve_table != config_->controller.predictor.valve_table)
    throw std::invalid_argument("RunSpec::reconfigured: the valve table changed; derive a new RunSpec (RunSpec::of)");
  if (config->controller.law.offset_v != u_0_v())
    throw std::invalid_argument("RunSpec::reconfigured: u_0 changed; derive a new RunSpec (RunSpec::of)");
  RunSpec spec = *this;
  spec.config_ = std::move(config);
  return spec;
}

}  // namespace pneu::assembly
