// A sweep cut in shards (pneu-sweep --shard K/N) and merged back (pneu-sweep merge): shard K of N
// runs the scenarios whose index i has i % N == K - 1, each with the seed and bench of the whole
// sweep's draw, and writes its shard file beside its --out file: the sweep's setting (what makes
// it this sweep), the shard's place, and for each of its scenarios its scenarios-file row, its
// stops-file rows and the figures the statistics are aggregated from (every value, not partial
// percentiles), doubles to all their digits. Merging every shard of a sweep gives back the
// results the statistics read, in the scenarios' order: the merged files are an unsharded run's,
// byte for byte, and its statistics the same.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <span>
#include <string>
#include <vector>

#include "pneu/sweep/run.hpp"
#include "pneu/sweep/scenario.hpp"
#include "pneu/sweep/statistics.hpp"

namespace pneu::sweep {

/// Shard `index` (1-based) of `count`.
struct ShardSpec {
  int index = 1, count = 1;
  /// Whether scenario `scenario` (0-based) falls to this shard.
  [[nodiscard]] bool takes(int scenario) const noexcept { return scenario % count == index - 1; }
};
/// "K/N" with 1 <= K <= N; std::invalid_argument saying what is wrong otherwise.
[[nodiscard]] ShardSpec parse_shard(const std::string& text);
/// The scenarios of `all` that fall to `shard`, in order.
[[nodiscard]] std::vector<Scenario> scenarios_of(const ShardSpec& shard, std::span<const Scenario> all);

/// Where the shard file of a shard whose --out is `out` lies: beside it, `out` + ".shard".
[[nodiscard]] std::filesystem::path shard_file_path(const std::filesystem::path& out);

/// A shard's run: where it falls, what it ran, and the configuration's fingerprint (the sweep's
/// effective configuration, as pneud --check-config writes it, hashed).
struct ShardHeader {
  Setting setting;
  std::string config_fingerprint;
  ShardSpec shard;
  double wall_s = 0.0;
  int jobs = 1;
};
/// The configuration's fingerprint.
[[nodiscard]] std::string config_fingerprint(const config::Config& config);

/// Writes the shard file of `run` (its results: the scenarios of header.shard, in order).
void write_shard(std::ostream& out, const ShardHeader& header, std::span<const ScenarioResult> results);

/// A sweep merged from its shards.
struct MergedSweep {
  Statistics statistics;  ///< wall_s summed over the shards, jobs the most a shard ran on, shards N
  std::string stops_csv, scenarios_csv;  ///< the files, whole
  /// What was taken, one line per shard in the shards' order: "shard K/N from PATH: ...".
  std::vector<std::string> taken;
};
/// Merges the shards named by their --out files (or their shard files). Throws
/// std::runtime_error naming the shard when one cannot be read or is not a shard file, when two
/// are the same shard, when one is of another sweep (another setting, configuration or N: what
/// differs is said), and when shards are missing (which).
[[nodiscard]] MergedSweep merge_shards(std::span<const std::filesystem::path> shards);

}  // namespace pneu::sweep
