// Private helper: walks a YAML map with its key path, converts scalars with clear messages and
// rejects keys nobody asked for, naming the known key a misspelt one stands for.
#pragma once

#include <yaml-cpp/yaml.h>

#include <cctype>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "pneu/config/config.hpp"
#include "pneu/config/spelling.hpp"

namespace pneu::config::detail {

/// The keys the schema knows in each mapping, by schema_path().
using KeyCatalogue = std::map<std::string, std::set<std::string>>;

/// The schema's keys: a walk of its descriptions (schema.cpp).
const KeyCatalogue& key_catalogue();

/// A key path as the catalogue files it: list indexes dropped ("a.list[3].b" -> "a.list[].b").
inline std::string schema_path(const std::string& path) {
  std::string out;
  for (std::size_t i = 0; i < path.size(); ++i) {
    out += path[i];
    if (path[i] == '[')
      while (i + 1 < path.size() && std::isdigit(static_cast<unsigned char>(path[i + 1]))) ++i;
  }
  return out;
}

/// "unknown key", and "; did you mean a?" (or "a or b?", "a, b or c?") for `meant`.
inline std::string unknown_key_meaning(const std::vector<std::string>& meant) {
  std::string reason = "unknown key";
  for (std::size_t i = 0; i < meant.size(); ++i)
    reason += (i == 0 ? "; did you mean " : i + 1 == meant.size() ? " or " : ", ") + meant[i];
  return meant.empty() ? reason : reason + "?";
}

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
  long long integer(const std::string& key) {
    const YAML::Node n = require(key);
    const std::string path = child_path(key);
    try {
      return n.as<long long>();
    } catch (const YAML::Exception&) {
      throw ConfigError(path, "expected an integer, got " + describe(n));
    }
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
  /// A required list.
  YAML::Node sequence(const std::string& key) {
    const YAML::Node n = require(key);
    if (!n.IsSequence()) throw ConfigError(child_path(key), "expected a list, got " + describe(n));
    return n;
  }
  MapReader map(const std::string& key) {
    seen_.insert(key);
    if (!has(key)) refuse_missing(key, "missing section");
    return child(node_[key], child_path(key));
  }
  /// A reader of a mapping below this one that is not one of its keys (an element of a list).
  [[nodiscard]] MapReader child(const YAML::Node& node, std::string path) const {
    return MapReader(node, std::move(path));
  }
  YAML::Node node(const std::string& key) { return require(key); }

  /// Every key of the mapping must have been read.
  void finish() const {
    for (const auto& kv : node_) {
      const std::string key = kv.first.Scalar();
      if (!seen_.count(key)) throw ConfigError(child_path(key), unknown_key(key));
    }
  }

  /// `key`, left out and optional, counts as read.
  void skip(const std::string& key) { seen_.insert(key); }

  /// Refuses `key`, required here and absent, for `reason`; but when the map holds a key the
  /// schema does not know that is plausibly a typo of `key`, names that key instead: the value
  /// was given, under a misspelt name.
  [[noreturn]] void refuse_missing(const std::string& key, const std::string& reason) const {
    if (const std::set<std::string>* known = known_keys()) {
      std::optional<std::string> typo;
      std::size_t typo_distance = 0;
      for (const auto& kv : node_) {
        const std::string& given = kv.first.Scalar();
        if (known->count(given) || !plausible_typo(given, key)) continue;
        const std::size_t d = edit_distance(given, key);
        if (!typo || d < typo_distance) typo = given, typo_distance = d;
      }
      if (typo) throw ConfigError(child_path(*typo), unknown_key_meaning({key}));
    }
    throw ConfigError(child_path(key), reason);
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
    if (!n.IsDefined() || n.IsNull()) refuse_missing(key, "missing");
    return n;
  }

  // The keys the schema knows in this mapping; none for a mapping it does not know.
  [[nodiscard]] const std::set<std::string>* known_keys() const {
    const auto it = key_catalogue().find(schema_path(path_));
    return it == key_catalogue().end() ? nullptr : &it->second;
  }

  // "unknown key", and the known keys `key` is most plausibly a typo of.
  [[nodiscard]] std::string unknown_key(const std::string& key) const {
    const std::set<std::string>* known = known_keys();
    return unknown_key_meaning(known ? closest_known(key, {known->begin(), known->end()}) : std::vector<std::string>{});
  }

  YAML::Node node_;
  std::string path_;
  std::set<std::string> seen_;
};

}  // namespace pneu::config::detail
