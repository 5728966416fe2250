// The one configuration of a pneu program: YAML loaded once into typed, validated structs, SI units
// in the key names. A bad file is refused with the key path and the reason (ConfigError).
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "pneu/sim_plant/params.hpp"
#include "pneu/sim_plant/sensors.hpp"
#include "pneu/sim_plant/valve.hpp"

namespace pneu::config {

/// Bad user configuration: `what()` reads "<key.path>: <reason>".
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string key_path, const std::string& reason)
      : std::runtime_error(key_path.empty() ? reason : key_path + ": " + reason),
        key_path_(std::move(key_path)) {}
  [[nodiscard]] const std::string& key_path() const noexcept { return key_path_; }

 private:
  std::string key_path_;
};

/// How the open-loop simulator starts (pneu-plant simulate).
struct SimulationConfig {
  double initial_position_m = 0.2195;  ///< simulation.initial_position_m: rest position at t = 0 [m], inside the stroke
};

/// The whole configuration.
struct Config {
  plant::PlantParams plant;          ///< plant.*
  plant::SensorParams sensors;       ///< sensors.*
  SimulationConfig simulation;       ///< simulation.*
};

/// Loads and validates a YAML file. `overrides` are "dotted.key.path=value" strings applied
/// before validation; an override naming a key the schema does not know is an error.
/// Throws ConfigError.
[[nodiscard]] Config load_file(const std::filesystem::path& path,
                               const std::vector<std::string>& overrides = {});
/// Same, from YAML text (`origin` names it in messages).
[[nodiscard]] Config load_string(std::string_view yaml, const std::vector<std::string>& overrides = {},
                                 std::string_view origin = "<string>");
/// The default bench (config/sim.yaml), embedded at build time.
[[nodiscard]] std::string_view default_config_yaml() noexcept;
/// Loads `path`, or the embedded default when `path` is empty.
[[nodiscard]] Config load_file_or_default(const std::filesystem::path& path,
                                          const std::vector<std::string>& overrides = {});

/// The effective configuration as YAML, loadable by load_string().
[[nodiscard]] std::string to_yaml(const Config& config);

}  // namespace pneu::config
