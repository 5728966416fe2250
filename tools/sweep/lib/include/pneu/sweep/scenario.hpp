// The sweep's scenarios: what the sweep is asked (Options), and the set-point steps and simulated
// benches drawn from it (draw_scenarios), up front, so that they do not depend on the threads.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "pneu/model/params.hpp"

namespace pneu::sweep {

/// A range a value is drawn from, uniformly (lo == hi: that value); not given: NaN.
struct DrawRange {
  double lo = NAN, hi = NAN;
  [[nodiscard]] bool given() const { return !std::isnan(lo); }
};

/// How a sweep draws its scenarios (--design): Monte Carlo (the set points spread evenly over the
/// stroke, the rest drawn at random), or an atlas's design over set point x bench tolerances: a
/// Latin hypercube, or a full grid of each dimension's levels.
enum class Design : std::uint8_t { kMonteCarlo, kLatinHypercube, kGrid };
/// "mc", "lhs", "grid" (--design's words).
[[nodiscard]] const char* design_name(Design d) noexcept;

/// The dimensions of an atlas's design, in this order (--grid-levels): the set point, the bench's
/// friction factor (every friction value), its dead-volume factor (both chambers), its valve null
/// offset, then its thermal time constant and its spool lag when their ranges are given.
inline constexpr std::size_t kMaxAtlasDimensions = 6;
inline constexpr const char* kAtlasDimensionNames[kMaxAtlasDimensions] = {
    "set point", "friction", "dead volume", "null offset", "thermal time constant", "spool lag"};

/// What a sweep is asked: pneu-sweep's options (its --help says what each does).
struct Options {
  int steps = 200;             ///< scenarios, one set-point step each
  std::uint64_t seed = 1;
  double duration_s = 12.0;    ///< each scenario's run; its stops judged
  double step_time_s = 1.0;    ///< the step's time
  double tail_s = 1.0;         ///< run on after duration_s, its stops not judged
  double margin_m = 0.02;      ///< the targets keep this from each end of the stroke
  double min_step_m = 0.005;   ///< |y_d - y0| at least this
  double friction_spread = 0.0, gain_spread = 0.0;  ///< model and bench alike, factors in [1-F, 1+F]
  double bench_spread = 0.0;   ///< each scenario's bench of its own, around the configured one
  DrawRange bench_thermal_s;   ///< the bench's thermal time constant at mid-stroke [s]
  DrawRange bench_spool_lag_s; ///< the bench's spool lag [s]
  bool supervised = false;     ///< every supervisor check on, as in pneud
  bool identify = false;       ///< pneud's identification run on each bench first
  bool online = false;         ///< pneud's online identification during each run
  Design design = Design::kMonteCarlo;
  /// kGrid: each dimension's number of levels (atlas_dimensions() of them; the others 0)
  std::array<int, kMaxAtlasDimensions> grid_levels{};
  std::filesystem::path config_dir;  ///< the configuration file's folder (relative valve tables)
};

/// A simulated bench that is not its model (--bench-spread, --bench-thermal-s,
/// --bench-spool-lag-s): factors on the model's values and a valve null offset, drawn per scenario.
struct BenchDraw {
  double static_positive = 1.0, coulomb_positive = 1.0, static_negative = 1.0, coulomb_negative = 1.0,
         viscous = 1.0, max_conductance = 1.0, leak_in = 1.0, leak_out = 1.0, dead_volume_p = 1.0,
         dead_volume_n = 1.0, null_offset_v = 0.0;
  /// The energy balance with this thermal time constant at mid-stroke [s]; this spool lag [s].
  /// NaN: the configured bench's.
  double thermal_time_constant_s = NAN, spool_time_constant_s = NAN;

  /// The bench: `model` with these applied. Each Coulomb level stays within its stiction bound.
  [[nodiscard]] model::PlantParams applied_to(model::PlantParams model) const;
};

/// One set-point step: from rest at y0_m to y_d_m, on its bench.
struct Scenario {
  int index = 0;
  double y0_m = 0.0, y_d_m = 0.0, friction_scale = 1.0, gain_scale = 1.0;
  BenchDraw bench;
};

/// The targets' range on a stroke of +-half_stroke_m: [lo, hi] = +-(half_stroke_m - margin_m).
struct TargetRange {
  double lo_m = 0.0, hi_m = 0.0;
};
[[nodiscard]] TargetRange target_range(const Options& options, double half_stroke_m) noexcept;

/// How many dimensions an atlas of `options` draws: 4, and one each for --bench-thermal-s and
/// --bench-spool-lag-s when given.
[[nodiscard]] std::size_t atlas_dimensions(const Options& options) noexcept;

/// The scenarios of `options` on a stroke of +-half_stroke_m: scenario i steps to the i-th of
/// `steps` targets spread evenly over target_range(), from a start drawn at least min_step_m away;
/// the same for a seed, whatever runs them. An atlas's design (lhs, grid) places each scenario's
/// set point and bench tolerances instead: in [0, 1) per dimension, either stratum i of a random
/// permutation per dimension plus a random offset within it (lhs), or the middle of each level of
/// the grid, the set point varying fastest (grid); mapped onto the target range, the factors
/// [1-B, 1+B] of friction (every value alike) and of the dead volumes (both alike), the null
/// offset [-B/2, B/2] V (B: bench_spread) and the thermal and spool ranges; the conductances stay
/// the model's. The grid needs steps == the product of grid_levels. Throws std::invalid_argument when the options leave
/// no room for that (pneu-sweep says which option first).
[[nodiscard]] std::vector<Scenario> draw_scenarios(const Options& options, double half_stroke_m);

}  // namespace pneu::sweep
