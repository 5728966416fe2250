// The archives of the schema that read no YAML: the keys (the catalogue behind the misspelling
// suggestions, the keys of a configuration) and the values (comparison).
#include "pneu/config/schema.hpp"

#include <charconv>
#include <concepts>
#include <string>
#include <utility>
#include <vector>

#include "yaml_reader.hpp"

namespace pneu::config::schema {
namespace {

// Lists the keys of a configuration: every key of the schema (kEverything: each optional section,
// one entry of each list, as "list[]"), or the keys to_yaml() writes (kAsWritten).
class KeyLister {
 public:
  enum class Mode : std::uint8_t { kEverything, kAsWritten };

  KeyLister(Mode mode, std::vector<KeyInfo>& out, std::vector<std::string>* rules = nullptr, std::string prefix = "")
      : mode_(mode), out_(out), rules_(rules), prefix_(std::move(prefix)) {}

  void field(Field<const double> f, Range range, const char* doc) { add(f.key, KeyKind::kNumber, range.text(), doc); }
  template <std::integral T>
  void field(Field<T> f, IntRange range, const char* doc) {
    add(f.key, KeyKind::kInteger, range.text(), doc);
  }
  void field(Field<const bool> f, const char* doc) { add(f.key, KeyKind::kBoolean, "true | false", doc); }
  void field(Field<const std::string> f, const char* doc) { add(f.key, KeyKind::kText, "", doc); }
  template <class E>
  void field(Field<const E> f, Choices<E> choices, const char* doc) {
    add(f.key, KeyKind::kChoice, choices.unquoted().listed(" | ", " | "), doc);
  }
  void number_or_auto(Field<const double> f, const bool&, const char* doc) {
    add(f.key, KeyKind::kNumberOrAuto, "a number | auto", doc);
  }
  template <class S>
  void flags(const Key& k, const S&, Flags<S> flags, const char* doc) {
    add(k, KeyKind::kNames, "[" + flags.listed() + "]", doc);
  }
  template <class T, class... Context>
  void section(Field<const T> f, const Context&... context) {
    group(f.key, [&](KeyLister& sub) { describe(sub, f.value, context...); });
  }
  template <class T>
  void optional_section(Field<const T> f, const bool& present) {
    if (present || mode_ == Mode::kEverything) section(f);
  }
  template <class Describe>
  void group(const Key& k, Describe&& describe_group) {
    add(k, KeyKind::kSection);
    KeyLister sub(mode_, out_, rules_, prefix_ + k.name + ".");
    describe_group(sub);
  }
  template <class T, class... Context>
  void list(Field<const std::vector<T>> f, const Context&... context) {
    add(f.key, KeyKind::kList);
    if (mode_ == Mode::kEverything) {
      KeyLister sub(mode_, out_, rules_, prefix_ + f.key.name + "[].");
      const T entry{};
      describe(sub, entry, context...);
      return;
    }
    for (std::size_t i = 0; i < f.value.size(); ++i) {
      KeyLister sub(mode_, out_, rules_, prefix_ + f.key.name + "[" + std::to_string(i) + "].");
      describe(sub, f.value[i], context...);
    }
  }
  template <class Reason>
  void check(const std::string& path, bool, Reason&&) {
    if (rules_ != nullptr) rules_->push_back(prefix_ + path);
  }

 private:
  void add(const Key& k, KeyKind kind, std::string range = "", const char* doc = "") {
    if (k.presence == Presence::kIgnored && mode_ == Mode::kAsWritten) return;  // to_yaml leaves it out
    out_.push_back({prefix_ + k.name, kind, k.presence, std::move(range), doc});
  }

  Mode mode_;
  std::vector<KeyInfo>& out_;
  std::vector<std::string>* rules_;
  std::string prefix_;
};

// The shortest text that reads back as the same double.
std::string exact(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// Lists every value of a configuration by its key path (values_of()).
class ValueLister {
 public:
  using Values = std::vector<std::pair<std::string, std::string>>;

  explicit ValueLister(Values& out, std::string prefix = "") : out_(out), prefix_(std::move(prefix)) {}

  void field(Field<const double> f, Range, const char*) { add(f.key, exact(f.value)); }
  template <std::integral T>
  void field(Field<T> f, IntRange, const char*) {
    add(f.key, std::to_string(f.value));
  }
  void field(Field<const bool> f, const char*) { add(f.key, f.value ? "true" : "false"); }
  void field(Field<const std::string> f, const char*) { add(f.key, "'" + f.value + "'"); }
  template <class E>
  void field(Field<const E> f, Choices<E> choices, const char*) {
    for (const Choice<E>& c : choices.names)
      if (c.value == f.value) return add(f.key, c.name);
    add(f.key, "<" + std::to_string(static_cast<long long>(f.value)) + ">");  // a value without a name
  }
  void number_or_auto(Field<const double> f, const bool& is_auto, const char*) {
    add(f.key, is_auto ? "auto" : exact(f.value));
  }
  template <class S>
  void flags(const Key& k, const S& owner, Flags<S> flags, const char*) {
    std::string names;
    for (const Flag<S>& flag : flags.names)
      if (owner.*flag.member) names += (names.empty() ? "" : ", ") + std::string(flag.name);
    add(k, "[" + names + "]");
  }
  template <class T, class... Context>
  void section(Field<const T> f, const Context&... context) {
    group(f.key, [&](ValueLister& sub) { describe(sub, f.value, context...); });
  }
  template <class T>
  void optional_section(Field<const T> f, const bool& present) {
    add(f.key, present ? "present" : "absent");
    section(f);
  }
  template <class Describe>
  void group(const Key& k, Describe&& describe_group) {
    ValueLister sub(out_, prefix_ + k.name + ".");
    describe_group(sub);
  }
  template <class T, class... Context>
  void list(Field<const std::vector<T>> f, const Context&... context) {
    add(f.key, std::to_string(f.value.size()) + (f.value.size() == 1 ? " entry" : " entries"));
    for (std::size_t i = 0; i < f.value.size(); ++i) {
      ValueLister sub(out_, prefix_ + f.key.name + "[" + std::to_string(i) + "].");
      describe(sub, f.value[i], context...);
    }
  }
  template <class Reason>
  void check(const std::string&, bool, Reason&&) {}

 private:
  void add(const Key& k, std::string value) { out_.emplace_back(prefix_ + k.name, std::move(value)); }

  Values& out_;
  std::string prefix_;
};

std::vector<KeyInfo> keys(const Config& config, KeyLister::Mode mode, std::vector<std::string>* rules = nullptr) {
  std::vector<KeyInfo> out;
  KeyLister lister(mode, out, rules);
  describe(lister, config);
  return out;
}

}  // namespace

std::vector<KeyInfo> all_keys() { return keys(Config{}, KeyLister::Mode::kEverything); }

std::vector<KeyInfo> keys_of(const Config& config) { return keys(config, KeyLister::Mode::kAsWritten); }

std::vector<std::string> rule_paths_of(const Config& config) {
  std::vector<std::string> rules;
  (void)keys(config, KeyLister::Mode::kAsWritten, &rules);
  return rules;
}

std::vector<std::pair<std::string, std::string>> values_of(const Config& config) {
  ValueLister::Values out;
  ValueLister lister(out);
  describe(lister, config);
  return out;
}

}  // namespace pneu::config::schema

namespace pneu::config::detail {

const KeyCatalogue& key_catalogue() {
  static const KeyCatalogue catalogue = [] {
    KeyCatalogue c;
    for (const schema::KeyInfo& k : schema::all_keys()) {
      const std::size_t dot = k.path.rfind('.');
      if (dot == std::string::npos) c[""].insert(k.path);
      else c[k.path.substr(0, dot)].insert(k.path.substr(dot + 1));
    }
    return c;
  }();
  return catalogue;
}

}  // namespace pneu::config::detail
