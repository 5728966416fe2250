// A sweep's shards: their files written and read back, and merged.
#include "pneu/sweep/shard.hpp"

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "pneu/config/config.hpp"
#include "pneu/controller/supervisor.hpp"
#include "pneu/sweep/report.hpp"

namespace pneu::sweep {

namespace {

// The shard file's first line: what it is, and its format's version (2: the setting names the design).
constexpr const char* kMagic = "pneu-sweep shard 2";

// A string as one token: "s:" and the string with '%', white space and control characters as %XX.
std::string escape(const std::string& s) {
  std::string out = "s:";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '%' || u <= ' ' || u == 0x7f) {
      char hex[4];
      std::snprintf(hex, sizeof hex, "%%%02X", u);
      out += hex;
    } else {
      out += c;
    }
  }
  return out;
}

std::optional<std::string> unescape(const std::string& token) {
  if (token.rfind("s:", 0) != 0) return std::nullopt;
  std::string out;
  for (std::size_t i = 2; i < token.size(); ++i) {
    if (token[i] != '%') {
      out += token[i];
      continue;
    }
    if (i + 2 >= token.size()) return std::nullopt;
    const std::string hex = token.substr(i + 1, 2);
    char* end = nullptr;
    const long v = std::strtol(hex.c_str(), &end, 16);
    if (end != hex.c_str() + 2) return std::nullopt;
    out += static_cast<char>(v);
    i += 2;
  }
  return out;
}

// Writes values as space-separated tokens (named: "name=value"); doubles to all their digits.
class Writer {
 public:
  static constexpr bool kReading = false;
  explicit Writer(bool named) : named_(named) {}
  template <class T>
  void operator()(const char* name, const T& v) {
    if (!line_.empty()) line_ += ' ';
    if (named_) (line_ += name) += '=';
    line_ += text(v);
  }
  [[nodiscard]] const std::string& line() const { return line_; }

 private:
  template <class T>
  static std::string text(const T& v) {
    char buf[40];
    if constexpr (std::is_same_v<T, bool>) {
      return v ? "1" : "0";
    } else if constexpr (std::is_same_v<T, std::string>) {
      return escape(v);
    } else if constexpr (std::is_enum_v<T>) {
      return std::to_string(static_cast<long long>(v));
    } else if constexpr (std::is_floating_point_v<T>) {
      std::snprintf(buf, sizeof buf, "%.17g", v);
      return buf;
    } else {
      return std::to_string(v);
    }
  }
  bool named_;
  std::string line_;
};

// Reads them back, in the same order; throws std::invalid_argument on anything else.
class Reader {
 public:
  static constexpr bool kReading = true;
  Reader(const std::string& line, bool named) : in_(line), named_(named) {}
  template <class T>
  void operator()(const char* name, T& v) {
    std::string token;
    if (!(in_ >> token)) throw std::invalid_argument(std::string("ends before ") + name);
    if (named_) {
      const std::string want = std::string(name) + "=";
      if (token.rfind(want, 0) != 0) throw std::invalid_argument("'" + token + "' where " + name + "= was expected");
      token.erase(0, want.size());
    }
    if (!parse(token, v)) throw std::invalid_argument(std::string("bad value '") + token + "' of " + name);
  }
  void finish() const {
    std::string extra;
    if (in_ >> extra) throw std::invalid_argument("unexpected '" + extra + "' at the end of a line");
  }

 private:
  template <class T>
  static bool parse(const std::string& t, T& v) {
    char* end = nullptr;
    errno = 0;
    if constexpr (std::is_same_v<T, bool>) {
      if (t != "0" && t != "1") return false;
      v = t == "1";
      return true;
    } else if constexpr (std::is_same_v<T, std::string>) {
      const auto s = unescape(t);
      if (s) v = *s;
      return s.has_value();
    } else if constexpr (std::is_enum_v<T>) {
      const long long n = std::strtoll(t.c_str(), &end, 10);
      v = static_cast<T>(n);
    } else if constexpr (std::is_floating_point_v<T>) {
      v = std::strtod(t.c_str(), &end);
    } else if constexpr (std::is_signed_v<T>) {
      v = static_cast<T>(std::strtoll(t.c_str(), &end, 10));
    } else {
      v = static_cast<T>(std::strtoull(t.c_str(), &end, 10));
    }
    return !t.empty() && end == t.c_str() + t.size() && errno != ERANGE;
  }
  mutable std::istringstream in_;
  bool named_;
};

// A sequence: its length, then each element.
template <class Io, class V, class F>
void sequence(Io& io, const char* name, V& v, F each) {
  std::uint64_t n = v.size();
  io(name, n);
  if constexpr (Io::kReading) {
    if (n > 1000000) throw std::invalid_argument(std::string("implausible length of ") + name);
    v.resize(n);
  }
  for (auto& e : v) each(e);
}

// An optional: whether it holds a value, then the value.
template <class Io, class O, class F>
void optional_value(Io& io, const char* name, O& o, F each) {
  bool has = o.has_value();
  io(name, has);
  if constexpr (Io::kReading) {
    if (has) o.emplace();
    else o.reset();
  }
  if (has) each(*o);
}

// The sweep's setting: what makes two shards of one sweep (the options' config_dir aside: the
// configuration's fingerprint stands for what it leads to). Every member of Options and Setting
// is listed; the sizes below (on 64-bit builds) stop a new one from being left out unnoticed: add
// it here, then update them.
static_assert(sizeof(void*) != 8 || (sizeof(Options) == 184 && sizeof(Setting) == 288),
              "Options or Setting changed: list the new member in visit_setting (shard.cpp), then update these sizes");
template <class Io, class S>
void visit_setting(Io& io, S& s) {
  auto& o = s.options;
  io("steps", o.steps);
  io("seed", o.seed);
  io("duration_s", o.duration_s);
  io("step_time_s", o.step_time_s);
  io("tail_s", o.tail_s);
  io("margin_m", o.margin_m);
  io("min_step_m", o.min_step_m);
  io("friction_spread", o.friction_spread);
  io("gain_spread", o.gain_spread);
  io("bench_spread", o.bench_spread);
  io("bench_thermal_lo_s", o.bench_thermal_s.lo);
  io("bench_thermal_hi_s", o.bench_thermal_s.hi);
  io("bench_spool_lag_lo_s", o.bench_spool_lag_s.lo);
  io("bench_spool_lag_hi_s", o.bench_spool_lag_s.hi);
  io("supervised", o.supervised);
  io("identify", o.identify);
  io("online", o.online);
  io("design", o.design);
  for (std::size_t d = 0; d < kMaxAtlasDimensions; ++d) {
    const std::string name = "grid_levels_" + std::to_string(d);
    io(name.c_str(), o.grid_levels[d]);
  }
  io("targets_lo_m", s.targets.lo_m);
  io("targets_hi_m", s.targets.hi_m);
  io("hold_window_m", s.hold_window_m);
  io("hold_enabled", s.hold_enabled);
  io("rules_sign_changes", s.settling_rules.sign_changes);
  io("rules_amplitude_m", s.settling_rules.amplitude_m);
  io("rules_window_s", s.settling_rules.window_s);
  io("rules_settle_time_s", s.settling_rules.settle_time_s);
  io("halfway_linearized", s.halfway_enabled[0]);
  io("halfway_nonlinear", s.halfway_enabled[1]);
  io("halfway_relaxation", s.halfway_enabled[2]);
  io("linearized_name", s.linearized_name);
}

// Of a plant, what the statistics read: stiction, the walls' heat transfer, the spool lag.
template <class Io, class P>
void visit_plant(Io& io, P& p) {
  io("static_positive_n", p.friction.static_positive_n);
  io("static_negative_n", p.friction.static_negative_n);
  io("has_thermal", p.has_thermal);
  io("heat_transfer_w_per_m2_k", p.thermal.heat_transfer_w_per_m2_k);
  io("spool_time_constant_s", p.valve.spool_time_constant_s);
}

template <class Io, class V>
void visit_verdict(Io& io, V& v) {
  io("kind", v.kind);
  io("error_s", v.error_s);
  io("error_percent", v.error_percent);
  io("direction_ok", v.direction_ok);
}

// Of a scenario's result, everything aggregate() reads (statistics.cpp): a figure it comes to read
// from elsewhere in the result must be carried here too (the merge tests compare the summaries).
template <class Io, class R>
void visit_result(Io& io, R& r) {
  io("index", r.scenario.index);
  io("y0_m", r.scenario.y0_m);
  io("y_d_m", r.scenario.y_d_m);
  io("identification_failed", r.identification_failed);
  auto& g = r.settling;
  io("outcome", g.outcome);
  io("settle_time_s", g.settle_time_s);
  io("final_error_m", g.final_error_m);
  io("fault", g.fault);
  io("oscillation_rule_after_s", g.oscillation_rule_after_s);
  io("in_window_after_s", g.in_window_after_s);
  io("hold_after_s", g.hold_after_s);
  io("restarts_after_hold", g.restarts_after_hold);
  io("held_forecasts", g.held_forecasts);
  io("held_restart_forecasts", g.held_restart_forecasts);
  io("reaches_forecast_none", g.reaches_forecast_none);
  sequence(io, "reach_forecast_error_ms", g.reach_forecast_error_ms, [&](auto& e) { io("error_ms", e); });
  visit_plant(io, r.bench);
  optional_value(io, "identified", r.identified, [&](auto& p) { visit_plant(io, p); });
  auto& c = r.check;
  io("residual_pa", c.residual_pa);
  io("explained_pa", c.explained_pa);
  io("fits", c.fits);
  io("published", c.published);
  io("within_3_sigma", c.within_3_sigma);
  io("outside", c.outside);
  io("null_pressure_error_pa", c.null_pressure_error_pa);
  sequence(io, "by_key", c.by_key, [&](auto& k) {
    io("key", k.key);
    io("published", k.published);
    io("within_3_sigma", k.within_3_sigma);
  });
  sequence(io, "stops", r.stops, [&](auto& j) {
    io("restarted", j.stop.restarted);
    io("t_stop_s", j.stop.t_stop_s);
    io("t_end_s", j.stop.t_end_s);
    io("unseen", j.truth.unseen);
    io("on_configured_bound", j.truth.on_configured_bound);
    io("not_at_rest", j.truth.not_at_rest);
    io("start_dating_s", j.truth.start_dating_s);
    io("fate", j.fate);
    io("long_restart", j.long_restart);
    io("on_slow_side", j.on_slow_side);
    for (auto& f : j.at_stop)
      optional_value(io, "at_stop", f, [&](auto& judged) {
        visit_verdict(io, judged.verdict);
        io("within_criteria", judged.within_criteria);
      });
    for (auto& h : j.halfway) optional_value(io, "halfway", h, [&](auto& v) { visit_verdict(io, v); });
  });
}

template <class F>
std::string written(bool named, F visit) {
  Writer w(named);
  visit(w);
  return w.line();
}

// One shard file read back.
struct ShardFile {
  std::filesystem::path path;
  std::string setting_line, fingerprint;
  ShardHeader header;
  std::vector<ScenarioResult> results;
  std::vector<std::string> scenario_rows, stop_rows;  // as written, per result
};

ShardFile read_shard_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read the shard file " + path.string());
  ShardFile f;
  f.path = path;
  std::string line;
  std::size_t number = 0;
  const auto next = [&](const char* what) {
    if (!std::getline(in, line)) throw std::invalid_argument(std::string("ends before its ") + what);
    ++number;
  };
  const auto field = [&](const char* key) {
    const std::string prefix = std::string(key) + " ";
    if (line.rfind(prefix, 0) != 0) throw std::invalid_argument("line " + std::to_string(number) + " is not its " + key);
    return line.substr(prefix.size());
  };
  try {
    next("first line");
    if (line != kMagic) throw std::invalid_argument(std::string("is not a shard file (its first line is not '") + kMagic + "')");
    next("setting");
    f.setting_line = field("setting");
    Reader setting(f.setting_line, true);
    visit_setting(setting, f.header.setting);
    setting.finish();
    next("configuration");
    f.fingerprint = field("configuration");
    f.header.config_fingerprint = f.fingerprint;
    next("shard");
    Reader place(field("shard"), true);
    std::uint64_t scenarios = 0;
    place("index", f.header.shard.index);
    place("count", f.header.shard.count);
    place("wall_s", f.header.wall_s);
    place("jobs", f.header.jobs);
    place("scenarios", scenarios);
    place.finish();
    const ShardSpec& s = f.header.shard;
    if (!(s.count >= 1 && s.index >= 1 && s.index <= s.count))
      throw std::invalid_argument("has no shard K/N with 1 <= K <= N");
    for (std::uint64_t i = 0; i < scenarios; ++i) {
      next("scenarios");
      ScenarioResult& r = f.results.emplace_back();
      Reader figures(field("result"), false);
      visit_result(figures, r);
      figures.finish();
      std::string row, stops;
      next("scenario row");
      Reader rows(field("rows"), false);
      rows("scenario_row", row);
      rows("stop_rows", stops);
      rows.finish();
      f.scenario_rows.push_back(row);
      f.stop_rows.push_back(stops);
    }
    next("end");
    if (line != "end") throw std::invalid_argument("does not end where its scenarios do (line " + std::to_string(number) + ")");
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error("the shard file " + path.string() + " " + e.what());
  }
  return f;
}

// The first of `a`'s name=value tokens that `b` does not have alike, as "name=A (here name=B)".
std::string first_difference(const std::string& a, const std::string& b) {
  std::istringstream ia(a), ib(b);
  std::string ta, tb;
  while (true) {
    const bool ha = static_cast<bool>(ia >> ta), hb = static_cast<bool>(ib >> tb);
    if (!ha && !hb) return "?";
    if (ta != tb || ha != hb) return (ha ? ta : "nothing") + ", where the first has " + (hb ? tb : "nothing");
  }
}

}  // namespace

ShardSpec parse_shard(const std::string& text) {
  const auto slash = text.find('/');
  const auto whole = [](const std::string& t, int& v) {
    if (t.empty() || t.size() > 9 || t.find_first_not_of("0123456789") != std::string::npos) return false;
    v = std::stoi(t);
    return true;
  };
  ShardSpec s;
  if (slash == std::string::npos || !whole(text.substr(0, slash), s.index) || !whole(text.substr(slash + 1), s.count) ||
      s.count < 1 || s.index < 1 || s.index > s.count)
    throw std::invalid_argument("--shard must be K/N with whole numbers 1 <= K <= N (got '" + text + "')");
  return s;
}

std::vector<Scenario> scenarios_of(const ShardSpec& shard, std::span<const Scenario> all) {
  std::vector<Scenario> out;
  for (const Scenario& s : all)
    if (shard.takes(s.index)) out.push_back(s);
  return out;
}

std::filesystem::path shard_file_path(const std::filesystem::path& out) {
  std::filesystem::path p = out;
  p += ".shard";
  return p;
}

std::string config_fingerprint(const config::Config& config) {
  std::uint64_t h = 0xcbf29ce484222325ULL;  // FNV-1a, 64 bits
  for (const char c : config::to_yaml(config)) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  char text[24];
  std::snprintf(text, sizeof text, "%016" PRIx64, h);
  return text;
}

void write_shard(std::ostream& out, const ShardHeader& header, std::span<const ScenarioResult> results) {
  const bool online = header.setting.options.online, identify = header.setting.options.identify;
  out << kMagic << '\n';
  out << "setting " << written(true, [&](Writer& w) { visit_setting(w, header.setting); }) << '\n';
  out << "configuration " << header.config_fingerprint << '\n';
  out << "shard " << written(true, [&](Writer& w) {
    w("index", header.shard.index);
    w("count", header.shard.count);
    w("wall_s", header.wall_s);
    w("jobs", header.jobs);
    w("scenarios", static_cast<std::uint64_t>(results.size()));
  }) << '\n';
  for (const ScenarioResult& r : results) {
    out << "result " << written(false, [&](Writer& w) { visit_result(w, r); }) << '\n';
    out << "rows " << written(false, [&](Writer& w) {
      w("scenario_row", scenarios_csv_row(r, identify));
      w("stop_rows", stops_csv_rows(r, online));
    }) << '\n';
  }
  out << "end\n";
}

MergedSweep merge_shards(std::span<const std::filesystem::path> paths) {
  if (paths.empty()) throw std::runtime_error("no shard to merge");
  std::vector<ShardFile> files;
  for (const std::filesystem::path& p : paths) {
    const std::filesystem::path file = p.extension() == ".shard" ? p : shard_file_path(p);
    files.push_back(read_shard_file(file));
  }
  const ShardFile& first = files.front();
  const int n = first.header.shard.count;
  std::map<int, ShardFile*> by_index;
  for (ShardFile& f : files) {
    if (f.setting_line != first.setting_line)
      throw std::runtime_error(f.path.string() + " is a shard of another sweep than " + first.path.string() + ": " +
                               first_difference(f.setting_line, first.setting_line));
    if (f.fingerprint != first.fingerprint)
      throw std::runtime_error(f.path.string() + " is a shard of another sweep than " + first.path.string() +
                               ": another configuration (fingerprint " + f.fingerprint + ", where the first has " +
                               first.fingerprint + ")");
    if (f.header.shard.count != n)
      throw std::runtime_error(f.path.string() + " is shard " + std::to_string(f.header.shard.index) + "/" +
                               std::to_string(f.header.shard.count) + ", of another cut than " + first.path.string() +
                               " (" + std::to_string(first.header.shard.index) + "/" + std::to_string(n) + ")");
    const auto [it, fresh] = by_index.emplace(f.header.shard.index, &f);
    if (!fresh)
      throw std::runtime_error("shard " + std::to_string(f.header.shard.index) + "/" + std::to_string(n) +
                               " is given twice: " + it->second->path.string() + " and " + f.path.string());
  }
  std::string missing;
  for (int k = 1; k <= n; ++k)
    if (!by_index.count(k)) missing += (missing.empty() ? "" : ", ") + std::to_string(k) + "/" + std::to_string(n);
  if (!missing.empty()) throw std::runtime_error("shards missing: " + missing + " (of " + first.path.string() + "'s sweep)");

  // Each scenario in its place: every one the sweep drew, each from the shard it falls to.
  const Setting& setting = first.header.setting;
  const int steps = setting.options.steps;
  std::vector<ScenarioResult> results(static_cast<std::size_t>(steps));
  std::vector<const std::string*> scenario_rows(results.size()), stop_rows(results.size());
  MergedSweep m;
  double wall_s = 0.0;
  int jobs = 1;
  for (const auto& [k, f] : by_index) {
    const ShardSpec& spec = f->header.shard;
    std::size_t next = 0;
    for (int i = 0; i < steps; ++i) {
      if (!spec.takes(i)) continue;
      if (next >= f->results.size() || f->results[next].scenario.index != i)
        throw std::runtime_error("the shard file " + f->path.string() + " does not hold the scenarios of shard " +
                                 std::to_string(k) + "/" + std::to_string(n) + " (scenario " + std::to_string(i) + ")");
      results[static_cast<std::size_t>(i)] = std::move(f->results[next]);  // (the file's copy is not read again)
      scenario_rows[static_cast<std::size_t>(i)] = &f->scenario_rows[next];
      stop_rows[static_cast<std::size_t>(i)] = &f->stop_rows[next];
      ++next;
    }
    if (next != f->results.size())
      throw std::runtime_error("the shard file " + f->path.string() + " holds more scenarios than shard " +
                               std::to_string(k) + "/" + std::to_string(n) + " has");
    wall_s += f->header.wall_s;
    jobs = std::max(jobs, f->header.jobs);
    char line[160];
    std::snprintf(line, sizeof line, ": %zu scenarios, %.2f s wall on %d threads", f->results.size(), f->header.wall_s,
                  f->header.jobs);
    m.taken.push_back("shard " + std::to_string(k) + "/" + std::to_string(n) + " from " + f->path.string() + line);
  }
  m.statistics = aggregate(setting, std::span<const ScenarioResult>(results));
  m.statistics.wall_s = wall_s;
  m.statistics.jobs = jobs;
  m.statistics.shards = n;
  m.stops_csv = stops_csv_header();
  m.scenarios_csv = scenarios_csv_header(setting.options.identify);
  for (std::size_t i = 0; i < results.size(); ++i) {
    m.stops_csv += *stop_rows[i];
    m.scenarios_csv += *scenario_rows[i];
  }
  return m;
}

}  // namespace pneu::sweep
