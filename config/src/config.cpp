#include "pneu/config/config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <concepts>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "pneu/config/schema.hpp"
#include "pneu/config/spelling.hpp"
#include "pneu/config/yaml_text.hpp"
#include "yaml_reader.hpp"

namespace pneu::config {

using detail::KeyCatalogue;
using detail::MapReader;


namespace {

// The schema's reading archive: reads one mapping into the struct its description fills,
// refusing what the description does not allow, with the key path and the reason.
class YamlReader {
 public:
  explicit YamlReader(MapReader map) : map_(std::move(map)) {}

  void field(schema::Field<double> f, schema::Range range, const char* /*doc*/) {
    if (absent(f.key)) return;
    const double read = map_.number(f.key.name);
    if (!range.contains(read)) throw ConfigError(map_.child_path(f.key.name), range.refusal(read));
    keep(f, read);
  }
  template <std::integral T>
  void field(schema::Field<T> f, schema::IntRange range, const char* /*doc*/) {
    if (absent(f.key)) return;
    const long long read = map_.integer(f.key.name);
    if (!range.contains(read)) throw ConfigError(map_.child_path(f.key.name), range.refusal(read));
    if (!std::in_range<T>(read))  // the description's range is wider than its member
      throw std::logic_error("config schema: " + map_.child_path(f.key.name) + " does not fit its member");
    keep(f, static_cast<T>(read));
  }
  void field(schema::Field<bool> f, const char* /*doc*/) {
    if (!absent(f.key)) keep(f, map_.boolean(f.key.name));
  }
  void field(schema::Field<std::string> f, const char* /*doc*/) {
    if (!absent(f.key)) keep(f, map_.string(f.key.name));
  }
  template <class E>
  void field(schema::Field<E> f, schema::Choices<E> choices, const char* /*doc*/) {
    if (absent(f.key)) return;
    const std::string name = map_.string(f.key.name);
    const auto known = std::find_if(choices.names.begin(), choices.names.end(),
                                    [&](const schema::Choice<E>& c) { return name == c.name; });
    if (known == choices.names.end()) throw ConfigError(map_.child_path(f.key.name), choices.refusal(name));
    keep(f, known->value);
  }
  void number_or_auto(schema::Field<double> f, bool& is_auto, const char* /*doc*/) {
    if (absent(f.key)) return;
    const YAML::Node n = map_.node(f.key.name);
    is_auto = n.IsScalar() && n.Scalar() == "auto";
    if (!is_auto) f.value = MapReader::to_number(n, map_.child_path(f.key.name));
  }
  template <class S>
  void flags(const schema::Key& k, S& owner, schema::Flags<S> flags, const char* /*doc*/) {
    if (absent(k)) return;
    const YAML::Node list = map_.node(k.name);
    const std::string path = map_.child_path(k.name);
    if (!list.IsSequence()) throw ConfigError(path, "expected a list, e.g. [" + flags.listed() + "]");
    for (const schema::Flag<S>& flag : flags.names) owner.*flag.member = false;
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string name = list[i].IsScalar() ? list[i].Scalar() : "";
      const auto known = std::find_if(flags.names.begin(), flags.names.end(),
                                      [&](const schema::Flag<S>& flag) { return name == flag.name; });
      if (known == flags.names.end())
        throw ConfigError(path + "[" + std::to_string(i) + "]",
                          "unknown " + std::string(flags.noun) + " '" + name + "' (" + flags.listed() + ")");
      owner.*known->member = true;
    }
  }
  template <class T, class... Context>
  void section(schema::Field<T> f, Context&&... context) {
    if (!absent(f.key))
      enter(f.key, [&](YamlReader& r) { schema::describe(r, f.value, std::forward<Context>(context)...); });
  }
  template <class T>
  void optional_section(schema::Field<T> f, bool& present) {
    present = map_.has(f.key.name);
    section(f);
  }
  template <class Describe>
  void group(const schema::Key& k, Describe&& describe) {
    if (!absent(k)) enter(k, describe);
  }
  template <class T, class... Context>
  void list(schema::Field<std::vector<T>> f, const Context&... context) {
    if (absent(f.key)) return;
    const YAML::Node elements = map_.sequence(f.key.name);
    const std::string path = map_.child_path(f.key.name);
    f.value.clear();
    for (std::size_t i = 0; i < elements.size(); ++i) {
      YamlReader element(map_.child(elements[i], path + "[" + std::to_string(i) + "]"));
      T item{};
      schema::describe(element, item, context...);
      element.finish();
      f.value.push_back(std::move(item));
    }
  }
  template <class Reason>
  void check(const std::string& path, bool ok, Reason&& reason) {
    if (ok) return;
    if constexpr (std::is_invocable_v<Reason>) throw ConfigError(map_.child_path(path), reason());
    else throw ConfigError(map_.child_path(path), reason);
  }

  /// Every key of the mapping has been read: any other is unknown.
  void finish() const { map_.finish(); }

 private:
  // An optional key left out keeps its default (true); a required one is refused as missing
  // when it is read (false).
  bool absent(const schema::Key& k) {
    if (k.presence == schema::Presence::kRequired || map_.has(k.name)) return false;
    map_.skip(k.name);
    return true;
  }
  template <class T, class U>
  static void keep(schema::Field<T> f, U&& value) {
    if (f.key.presence != schema::Presence::kIgnored) f.value = std::forward<U>(value);
  }
  template <class Describe>
  void enter(const schema::Key& k, Describe&& describe) {
    if (k.required_because != nullptr && !map_.has(k.name))
      map_.refuse_missing(k.name, "missing: " + std::string(k.required_because));
    YamlReader r(map_.map(k.name));
    describe(r);
    r.finish();
  }

  MapReader map_;
};

// "unknown key", and the override's path as the schema spells it when each of its keys is known
// or plausibly a typo of a known one ("did you mean controller.law.position_gain_v_per_m?"); a
// last key that is as plausibly a typo of several gives each.
std::string unknown_override_key(const std::vector<std::string>& keys) {
  const KeyCatalogue& schema = detail::key_catalogue();
  std::string meant;
  bool corrected = false;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto known = schema.find(meant);
    if (known == schema.end()) return "unknown key";
    if (known->second.count(keys[i])) {
      meant += (meant.empty() ? "" : ".") + keys[i];
      continue;
    }
    const std::vector<std::string> closest = closest_known(keys[i], {known->second.begin(), known->second.end()});
    if (closest.empty() || (closest.size() > 1 && i + 1 < keys.size())) return "unknown key";
    if (i + 1 == keys.size()) {
      std::vector<std::string> paths;
      for (const std::string& k : closest) paths.push_back((meant.empty() ? "" : meant + ".") + k);
      return detail::unknown_key_meaning(paths);
    }
    meant += (meant.empty() ? "" : ".") + closest.front();
    corrected = true;
  }
  return corrected ? detail::unknown_key_meaning({meant}) : "unknown key";
}

// "a.b.c=value": sets the node at a.b.c to the YAML value, creating missing keys; the schema
// decoder then rejects any key it does not know.
void apply_override(YAML::Node& root, const std::string& assignment) {
  const auto eq = assignment.find('=');
  if (eq == std::string::npos || eq == 0)
    throw ConfigError("", "override '" + assignment + "' is not KEY=VALUE");
  std::string path = assignment.substr(0, eq);
  while (!path.empty() && std::isspace(static_cast<unsigned char>(path.back()))) path.pop_back();
  while (!path.empty() && std::isspace(static_cast<unsigned char>(path.front()))) path.erase(0, 1);
  const std::string text = assignment.substr(eq + 1);
  YAML::Node value;
  try {
    value = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, "cannot parse override value '" + text + "': " + e.msg);
  }
  std::vector<std::string> keys;
  std::stringstream ss(path);
  for (std::string key; std::getline(ss, key, '.');) {
    if (key.empty()) throw ConfigError(path, "override key has an empty component");
    keys.push_back(key);
  }
  if (keys.empty()) throw ConfigError("", "override '" + assignment + "' has no key");
  // yaml-cpp nodes are handles: walk with copies of the handles, assign through the last one.
  std::vector<YAML::Node> chain{root};
  std::string walked;
  for (std::size_t i = 0; i + 1 < keys.size(); ++i) {
    walked += (walked.empty() ? "" : ".") + keys[i];
    YAML::Node next = chain.back()[keys[i]];
    if (next.IsDefined() && !next.IsNull() && !next.IsMap())
      throw ConfigError(walked, "is a value, not a section: cannot override '" + path + "'");
    if (!next.IsDefined() || next.IsNull()) {
      // An optional section the file leaves out (hal.sim.plant): created for the key.
      if (detail::key_catalogue().count(walked) == 0) throw ConfigError(path, unknown_override_key(keys));
      chain.back()[keys[i]] = YAML::Node(YAML::NodeType::Map);
      next = chain.back()[keys[i]];
    }
    chain.push_back(next);
  }
  // A key absent from the file may still be an optional key of the schema: create it and let
  // the decoder reject it when it is unknown.
  YAML::Node leaf = chain.back()[keys.back()];
  if (leaf.IsDefined() && leaf.IsMap())
    throw ConfigError(path, "is a section; override its keys one by one");
  chain.back()[keys.back()] = value;
}

// `over`'s keys (at `path`) laid over a copy of `base`, mapping by mapping. `over` is checked as
// the reader checks every mapping (a key given twice, or not a plain name, is refused): laid
// over, the reader would see such a key once.
YAML::Node laid_over(const YAML::Node& base, const YAML::Node& over, const std::string& path) {
  (void)MapReader(over, path);
  YAML::Node out = YAML::Clone(base);
  for (const auto& kv : over) {
    const std::string key = kv.first.Scalar();
    const YAML::Node below = out[key];
    if (below.IsDefined() && below.IsMap() && kv.second.IsMap()) out[key] = laid_over(below, kv.second, path + "." + key);
    else out[key] = YAML::Clone(kv.second);
  }
  return out;
}

Config decode(const YAML::Node& given) {
  // hal.sim.plant gives any subset of plant:'s keys: the bench is plant: with them over it, read
  // (and refused, key by key, at hal.sim.plant's paths) as a whole plant description.
  // (A const node's missing key is an invalid node: IsDefined() first, then the type.)
  const auto map_at = [](const YAML::Node& node, const char* key) {
    const YAML::Node child = node[key];
    return child.IsDefined() && child.IsMap() ? child : YAML::Node(YAML::NodeType::Undefined);
  };
  YAML::Node root = given;
  if (const YAML::Node hal = map_at(given, "hal"); hal.IsDefined()) {
    if (const YAML::Node sim = map_at(hal, "sim"); sim.IsDefined()) {
      if (const YAML::Node over = map_at(sim, "plant"); over.IsDefined() && map_at(given, "plant").IsDefined()) {
        root = YAML::Clone(given);
        root["hal"]["sim"]["plant"] = laid_over(given["plant"], over, "hal.sim.plant");
      }
    }
  }
  Config c;
  YamlReader r(MapReader(root, ""));
  schema::describe(r, c);
  r.finish();
  return c;
}

}  // namespace

namespace {

// Hostile text is refused before yaml-cpp sees it. yaml-cpp 0.7 spends about 2 s and 250 MB per
// MiB of a long flat list (20 MiB: 30 s and 4.9 GB), for configurations of about 12 KiB. Its
// parser does refuse nesting beyond 500 levels by itself (no stack overflow), but only as "bad
// file": the scan below says what is wrong, long before that.
constexpr std::size_t kMaxDocumentBytes = std::size_t{1} << 20;  // 1 MiB
constexpr std::size_t kMaxNesting = 64;

// The first line of a YAML text nested deeper than `limit` levels, or 0, without parsing it:
// block collections by their columns ("- " and "? " open a level at their own column, and a
// block sequence may sit at its parent key's column), flow collections by their brackets,
// outside comments, quoted scalars, plain scalars and block scalars. It errs towards counting
// more (each line's own key or scalar is a level).
std::size_t line_nested_deeper_than(std::string_view text, std::size_t limit) {
  constexpr auto npos = std::string_view::npos;
  struct Level {
    std::size_t column;
    bool sequence;
  };
  std::vector<Level> block;
  std::size_t flow = 0;
  char quote = 0;                 // inside a quoted scalar (which may span lines): its quote
  long block_scalar_parent = -2;  // inside a block scalar: the column its lines are deeper than
  bool node_start = true;         // the next character may start a node (not inside a plain scalar)
  bool after_json_node = false;   // flow: just after a quoted scalar or a collection (":" follows)
  long scalar_owner = -1;         // a plain scalar ending a line continues on lines deeper than this
  std::size_t line_no = 0;
  for (std::size_t begin = 0; begin < text.size();) {
    std::size_t end = text.find('\n', begin);
    if (end == npos) end = text.size();
    std::string_view line = text.substr(begin, end - begin);
    begin = end + 1;
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const std::size_t indent = line.find_first_not_of(' ');
    if (block_scalar_parent > -2) {
      if (indent == npos || static_cast<long>(indent) > block_scalar_parent) continue;
      block_scalar_parent = -2;
    }
    std::size_t pos = 0;
    std::size_t last_level = npos;  // the column of the last level this line opened
    if (quote == 0 && flow == 0) {
      if (indent == npos || line[indent] == '#' || (indent == 0 && line[0] == '%')) continue;
      pos = indent;
      // A line deeper than the node owning the plain scalar that ended the last one continues it.
      if (node_start || static_cast<long>(indent) <= scalar_owner) {
        node_start = true;
        if (indent == 0 && (line.starts_with("---") || line.starts_with("...")) &&
            (line.size() == 3 || line[3] == ' ' || line[3] == '\t')) {
          block.clear();  // the next document
          pos = line.find_first_not_of(" \t", 3);
          if (pos == npos || line[pos] == '#') continue;
        }
        for (;;) {
          const char c = line[pos];
          const bool indicator = (c == '-' || c == '?' || c == ':') &&
                                 (pos + 1 == line.size() || line[pos + 1] == ' ' || line[pos + 1] == '\t');
          const bool sequence = indicator && c == '-';
          while (!block.empty() && (block.back().column > pos ||
                                    (block.back().column == pos && block.back().sequence && !sequence)))
            block.pop_back();
          if (block.empty() || block.back().column < pos || block.back().sequence != sequence)
            block.push_back({pos, sequence});
          last_level = pos;
          if (block.size() > limit) return line_no;
          if (!indicator) break;
          pos = line.find_first_not_of(" \t", pos + 1);
          if (pos == npos || line[pos] == '#') break;
        }
        if (pos == npos) continue;
        // The owner of a scalar on this line: the key before it, else the level holding it.
        scalar_owner = block.size() < 2 ? -1 : static_cast<long>(block[block.size() - 2].column);
      }
    }
    for (std::size_t i = pos; i < line.size(); ++i) {
      const char c = line[i];
      if (quote != 0) {
        if (quote == '"' && c == '\\') ++i;
        else if (quote == '\'' && c == '\'' && i + 1 < line.size() && line[i + 1] == '\'') ++i;
        else if (c == quote) quote = 0, node_start = false, after_json_node = true;
        continue;
      }
      if (c == ' ' || c == '\t') continue;
      if (c == '#' && (i == 0 || line[i - 1] == ' ' || line[i - 1] == '\t')) break;
      const bool space_next = i + 1 == line.size() || line[i + 1] == ' ' || line[i + 1] == '\t';
      const bool flow_indicator_next = i + 1 < line.size() && std::string_view(",[]{}").find(line[i + 1]) != npos;
      if (node_start) {
        if (c == '"' || c == '\'') {
          quote = c;
          continue;
        }
        if (c == '&' || c == '!') {  // an anchor or a tag: the node follows
          while (i + 1 < line.size() && line[i + 1] != ' ' && line[i + 1] != '\t' &&
                 (flow == 0 || std::string_view(",[]{}").find(line[i + 1]) == npos))
            ++i;
          continue;
        }
        if (c == '[' || c == '{') {
          if (block.size() + ++flow > limit) return line_no;
          continue;
        }
        if ((c == '-' || c == '?') && space_next) continue;
        if ((c == '|' || c == '>') && flow == 0) {
          // A block scalar's header holds only indicators and a comment after the '|' or '>'.
          const std::size_t rest = line.find_first_not_of("-+0123456789", i + 1);
          const std::size_t more = rest == npos ? rest : line.find_first_not_of(" \t", rest);
          if ((rest == npos || line[rest] == ' ' || line[rest] == '\t') && (more == npos || line[more] == '#')) {
            // Its lines are deeper than the node holding it: the key before it, or the "- " entry.
            const std::size_t owner = i == last_level ? block.size() - 1 : block.size();
            block_scalar_parent = owner == 0 ? -1 : static_cast<long>(block[owner - 1].column);
            break;
          }
        }
      }
      if (flow > 0) {
        if (c == '[' || c == '{') {  // no plain scalar holds these in a flow collection
          if (block.size() + ++flow > limit) return line_no;
          node_start = true;
          continue;
        }
        if (c == ']' || c == '}') {
          --flow;
          node_start = false;
          after_json_node = true;
          continue;
        }
        if (c == ',' || (c == ':' && (space_next || flow_indicator_next || after_json_node))) {
          node_start = true;
          after_json_node = false;
          continue;
        }
      } else if (c == ':' && space_next) {
        if (last_level != npos) scalar_owner = static_cast<long>(last_level);
        node_start = true;
        continue;
      }
      node_start = false;  // inside a plain scalar or an alias
      after_json_node = false;
    }
  }
  return 0;
}

// Refuses `text` (named `origin`) when it is too large or too deeply nested to hand to yaml-cpp.
void refuse_hostile_text(std::string_view text, const std::string& origin) {
  if (text.size() > kMaxDocumentBytes)
    throw ConfigError(origin, "too large: " + std::to_string(text.size()) + " bytes, at most " +
                                  std::to_string(kMaxDocumentBytes) + " (1 MiB)");
  if (const std::size_t line = line_nested_deeper_than(text, kMaxNesting))
    throw ConfigError(origin, "nested too deeply: more than " + std::to_string(kMaxNesting) +
                                  " levels at line " + std::to_string(line));
}

}  // namespace

Config load_string(std::string_view yaml, const std::vector<std::string>& overrides,
                   std::string_view origin) {
  refuse_hostile_text(yaml, std::string(origin));
  for (const auto& o : overrides)
    if (const auto eq = o.find('='); eq != std::string::npos)
      refuse_hostile_text(std::string_view(o).substr(eq + 1), o.substr(0, eq));
  YAML::Node root;
  try {
    root = YAML::Load(std::string(yaml));
  } catch (const YAML::Exception& e) {
    throw ConfigError(std::string(origin),
                      "not valid YAML (line " + std::to_string(e.mark.line + 1) + "): " + e.msg);
  }
  if (!root.IsMap()) throw ConfigError(std::string(origin), "expected a YAML mapping at the top");
  for (const auto& o : overrides) apply_override(root, o);
  return decode(root);
}

namespace {

// The file's text, refused as load_file() refuses it.
std::string file_text(const std::filesystem::path& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(status))
    throw ConfigError(path.string(), "is a directory: --config takes a YAML file (e.g. config/sim.yaml)");
  if (!std::filesystem::exists(status))
    throw ConfigError(path.string(), "cannot open the file (no such file)");
  if (!std::filesystem::is_regular_file(status)) throw ConfigError(path.string(), "cannot open the file (not a regular file)");
  if (const auto size = std::filesystem::file_size(path, ec); !ec && size > kMaxDocumentBytes)
    throw ConfigError(path.string(), "too large: " + std::to_string(size) + " bytes, at most " +
                                         std::to_string(kMaxDocumentBytes) + " (1 MiB)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path.string(), "cannot open the file");
  // At most one byte beyond the limit: a file growing meanwhile is still refused, not read whole.
  std::string text(kMaxDocumentBytes + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  return text;
}

}  // namespace

Config load_file(const std::filesystem::path& path, const std::vector<std::string>& overrides) {
  return load_string(file_text(path), overrides, path.string());
}

std::string text_of(const std::filesystem::path& path) {
  return path.empty() ? std::string(default_config_yaml()) : file_text(path);
}

const model::PlantParams& simulated_bench(const Config& config) noexcept {
  return config.hal.sim.has_plant ? config.hal.sim.plant : config.plant;
}

Config load_file_or_default(const std::filesystem::path& path,
                            const std::vector<std::string>& overrides) {
  if (path.empty()) return load_string(default_config_yaml(), overrides, "<embedded sim.yaml>");
  return load_file(path, overrides);
}

namespace {
// A double as the shortest text that reads back as the same double: 0.032, where yaml-cpp writes
// 0.032000000000000001; without an exponent from 1e-4 to 1e9 (700000, not 7e+05). The dump is
// for people, and reads back exactly. (Non-finite values keep yaml-cpp's .inf/.nan.)
struct Shortest {
  double v;
};
YAML::Emitter& operator<<(YAML::Emitter& e, Shortest s) {
  if (!std::isfinite(s.v)) return e << s.v;
  char buf[64];
  const double a = std::fabs(s.v);
  const auto r = a == 0.0 || (a >= 1e-4 && a < 1e9) ? std::to_chars(buf, buf + sizeof buf, s.v, std::chars_format::fixed)
                                                     : std::to_chars(buf, buf + sizeof buf, s.v);
  return e << std::string(buf, r.ptr);
}

// The schema's writing archive: writes a struct as the mapping its description reads, in the
// description's order.
class YamlWriter {
 public:
  explicit YamlWriter(YAML::Emitter& e) : e_(e) {}

  void field(schema::Field<const double> f, schema::Range, const char*) { key(f.key) << Shortest{f.value}; }
  template <std::integral T>
  void field(schema::Field<T> f, schema::IntRange, const char*) {
    if constexpr (std::is_signed_v<T>) key(f.key) << static_cast<long long>(f.value);
    else key(f.key) << static_cast<unsigned long long>(f.value);
  }
  void field(schema::Field<const bool> f, const char*) {
    if (f.key.presence != schema::Presence::kIgnored) key(f.key) << f.value;
  }
  void field(schema::Field<const std::string> f, const char*) { key(f.key) << f.value; }
  template <class E>
  void field(schema::Field<const E> f, schema::Choices<E> choices, const char*) {
    key(f.key) << choices.name_of(f.value);
  }
  void number_or_auto(schema::Field<const double> f, const bool& is_auto, const char*) {
    if (is_auto) key(f.key) << "auto";
    else key(f.key) << Shortest{f.value};
  }
  template <class S>
  void flags(const schema::Key& k, const S& owner, schema::Flags<S> flags, const char*) {
    key(k) << YAML::Flow << YAML::BeginSeq;
    for (const schema::Flag<S>& flag : flags.names)
      if (owner.*flag.member) e_ << flag.name;
    e_ << YAML::EndSeq;
  }
  template <class T, class... Context>
  void section(schema::Field<const T> f, const Context&... context) {
    group(f.key, [&](YamlWriter& w) { schema::describe(w, f.value, context...); });
  }
  template <class T>
  void optional_section(schema::Field<const T> f, const bool& present) {
    if (present) section(f);
  }
  template <class Describe>
  void group(const schema::Key& k, Describe&& describe) {
    key(k);
    if (k.style == schema::Style::kFlow) e_ << YAML::Flow;
    e_ << YAML::BeginMap;
    describe(*this);
    e_ << YAML::EndMap;
  }
  /// A list of mappings, one line each.
  template <class T, class... Context>
  void list(schema::Field<const std::vector<T>> f, const Context&... context) {
    key(f.key) << YAML::BeginSeq;
    for (const T& item : f.value) {
      e_ << YAML::Flow << YAML::BeginMap;
      schema::describe(*this, item, context...);
      e_ << YAML::EndMap;
    }
    e_ << YAML::EndSeq;
  }
  template <class Reason>
  void check(const std::string&, bool, Reason&&) {}

 private:
  YAML::Emitter& key(const schema::Key& k) { return e_ << YAML::Key << k.name << YAML::Value; }

  YAML::Emitter& e_;
};
}  // namespace

std::string to_yaml(const Config& c) {
  YAML::Emitter e;
  e.SetDoublePrecision(17);
  YamlWriter w(e);
  e << YAML::BeginMap;
  schema::describe(w, c);
  e << YAML::EndMap;
  return std::string(e.c_str()) + "\n";
}

namespace {

// A value of to_yaml()'s document on one line: a scalar as written, a collection in flow style.
std::string one_line(YAML::Node node) {
  const std::function<void(YAML::Node)> flow = [&](YAML::Node n) {
    if (!n.IsMap() && !n.IsSequence()) return;
    n.SetStyle(YAML::EmitterStyle::Flow);
    for (auto it = n.begin(); it != n.end(); ++it) {
      if (n.IsMap()) flow(it->second);
      else flow(*it);
    }
  };
  flow(node);
  YAML::Emitter e;
  e << node;
  return e.c_str();
}

// The node at a dotted key path of a document.
YAML::Node node_at(const YAML::Node& root, const std::string& path) {
  YAML::Node n = root;
  std::stringstream keys(path);
  for (std::string key; std::getline(keys, key, '.');) {
    const YAML::Node& parent = n;
    n.reset(parent[key]);
  }
  return n;
}

}  // namespace

std::string with_values_of(std::string_view source, const Config& target, const std::vector<std::string>& always,
                           const NoteOf& note_of, std::string_view origin) {
  using Values = std::map<std::string, std::string>;
  const auto values = [](const Config& c) {
    const auto listed = schema::values_of(c);
    return Values(listed.begin(), listed.end());
  };
  const Values wanted = values(target);
  // The keys to_yaml() writes, in its order: what may be written, and how.
  std::map<std::string, std::size_t> order;
  std::map<std::string, schema::KeyKind> kind;
  for (const schema::KeyInfo& k : schema::keys_of(target)) {
    order.emplace(k.path, order.size());
    kind.emplace(k.path, k.kind);
  }
  const YAML::Node document = YAML::Load(to_yaml(target));
  std::string text(source);
  const Values was = values(load_string(text, {}, origin));
  std::set<std::string> written;
  for (bool first = true;; first = false) {
    const Values got = first ? was : values(load_string(text, {}, origin));
    std::set<std::string> due;
    if (first) due.insert(always.begin(), always.end());
    const auto differs = [&](const std::string& path) {
      const auto w = wanted.find(path), g = got.find(path);
      if (w != wanted.end() && g != got.end() && w->second == "absent" && g->second == "present")
        throw ConfigError(path, "the source has this optional section and the configuration to write does not: a "
                                "section is not removed");
      // A list entry's key: the list's, written whole.
      const std::string key = path.substr(0, path.find('['));
      const auto k = kind.find(key);
      if (k == kind.end()) {
        // Not written by to_yaml() either: the keys of a section left out (their defaults), an
        // ignored key.
        if (key == path) return;
        throw ConfigError(key, "its entries are not those to write, and the list is not written");
      }
      if (k->second != schema::KeyKind::kSection) {
        due.insert(key);
        return;
      }
      // An optional section the source lacks: written with all of its keys.
      for (const auto& [p, what] : kind)
        if (p.starts_with(key + ".") && what != schema::KeyKind::kSection && p.find('[') == std::string::npos)
          due.insert(p);
    };
    for (const auto& [path, value] : wanted)
      if (const auto g = got.find(path); g == got.end() || g->second != value) differs(path);
    for (const auto& [path, value] : got)
      if (!wanted.contains(path)) differs(path);
    if (due.empty()) return text;
    std::vector<std::string> keys(due.begin(), due.end());
    for (const std::string& key : keys)
      if (!order.contains(key)) throw ConfigError(key, "not a key the configuration to write has");
    std::sort(keys.begin(), keys.end(), [&](const auto& a, const auto& b) { return order.at(a) < order.at(b); });
    for (const std::string& key : keys) {
      // Written once: a key written that does not load back to its value would be written forever.
      if (!written.insert(key).second)
        throw ConfigError(key, "written as " + one_line(node_at(document, key)) + ", it does not load back to it");
      // What it was: where the source has the key (a key it leaves out has its default).
      const auto w = was.find(key);
      const bool given = w != was.end() && yaml_text::find(source, key).has_value();
      text = yaml_text::with_value(text, key, one_line(node_at(document, key)),
                                   note_of ? note_of(key, given ? w->second : "") : "");
    }
  }
}

}  // namespace pneu::config
