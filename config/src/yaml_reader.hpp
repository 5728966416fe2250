// Private helper: walks a YAML map with its key path, converts scalars with clear messages and
// rejects keys nobody asked for.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <set>
#include <string>

#include "pneu/config/config.hpp"

namespace pneu::config::detail {

class MapReader {
 public:
  MapReader(const YAML::Node& node, std::string path) : node_(node), path_(std::move(path)) {
    if (!node_.IsDefined() || node_.IsNull()) throw ConfigError(path_, "missing section");
    if (!node_.IsMap()) throw ConfigError(path_, "expected a mapping of keys");
    // yaml-cpp keeps repeated keys and answers the first: refuse them, and non-text keys.
    std::set<std::string> keys;
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) throw ConfigError(path_, "keys must be plain names, got " + describe(kv.first));
      if (!keys.insert(kv.first.Scalar()).second)
        throw ConfigError(child_path(kv.first.Scalar()), "given twice");
    }
  }

  [[nodiscard]] std::string child_path(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }
  [[nodiscard]] bool has(const std::string& key) const {
    const YAML::Node n = node_[key];
    return n.IsDefined() && !n.IsNull();
  }

  /// A required finite number.
  double number(const std::string& key) {
    return to_number(require(key), child_path(key));
  }
  double number_or(const std::string& key, double fallback) {
    return has(key) ? number(key) : (seen_.insert(key), fallback);
  }
  long long integer(const std::string& key) {
    const YAML::Node n = require(key);
    const std::string path = child_path(key);
    try {
      return n.as<long long>();
    } catch (const YAML::Exception&) {
      throw ConfigError(path, "expected an integer, got " + describe(n));
    }
  }
  long long integer_or(const std::string& key, long long fallback) {
    return has(key) ? integer(key) : (seen_.insert(key), fallback);
  }
  bool boolean(const std::string& key) {
    const YAML::Node n = require(key);
    try {
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      throw ConfigError(child_path(key), "expected true or false, got " + describe(n));
    }
  }
  std::string string(const std::string& key) {
    const YAML::Node n = require(key);
    if (!n.IsScalar()) throw ConfigError(child_path(key), "expected a string, got " + describe(n));
    return n.Scalar();
  }
  bool boolean_or(const std::string& key, bool fallback) {
    if (has(key)) return boolean(key);
    seen_.insert(key);
    return fallback;
  }
  std::string string_or(const std::string& key, const std::string& fallback) {
    if (has(key)) return string(key);
    seen_.insert(key);
    return fallback;
  }
  /// An optional sequence: an empty one when the key is absent.
  YAML::Node sequence_or_empty(const std::string& key) {
    seen_.insert(key);
    if (!has(key)) return YAML::Node(YAML::NodeType::Sequence);
    const YAML::Node n = node_[key];
    if (!n.IsSequence()) throw ConfigError(child_path(key), "expected a list, got " + describe(n));
    return n;
  }
  MapReader map(const std::string& key) {
    seen_.insert(key);
    return MapReader(node_[key], child_path(key));
  }
  YAML::Node node(const std::string& key) { return require(key); }

  /// Every key of the mapping must have been read.
  void finish() const {
    for (const auto& kv : node_) {
      const std::string key = kv.first.Scalar();
      if (!seen_.count(key)) throw ConfigError(child_path(key), "unknown key");
    }
  }

  [[nodiscard]] const std::string& path() const { return path_; }

  static double to_number(const YAML::Node& n, const std::string& path) {
    double value = 0.0;
    try {
      if (!n.IsScalar()) throw YAML::Exception(YAML::Mark(), "not a scalar");
      value = n.as<double>();
    } catch (const YAML::Exception&) {
      throw ConfigError(path, "expected a number, got " + describe(n));
    }
    if (!std::isfinite(value)) throw ConfigError(path, "must be a finite number");
    return value;
  }

  static std::string describe(const YAML::Node& n) {
    switch (n.Type()) {
      case YAML::NodeType::Scalar: return "'" + n.Scalar() + "'";
      case YAML::NodeType::Sequence: return "a list";
      case YAML::NodeType::Map: return "a mapping";
      case YAML::NodeType::Null: return "nothing";
      default: return "an undefined value";
    }
  }

 private:
  YAML::Node require(const std::string& key) {
    seen_.insert(key);
    const YAML::Node n = node_[key];
    if (!n.IsDefined() || n.IsNull()) throw ConfigError(child_path(key), "missing");
    return n;
  }

  YAML::Node node_;
  std::string path_;
  std::set<std::string> seen_;
};

/// Range checks that name the key and the value.
inline void check(bool ok, const std::string& path, const std::string& reason) {
  if (!ok) throw ConfigError(path, reason);
}

inline std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace pneu::config::detail
