// The sweep's scenarios, drawn up front from the seed.
#include "pneu/sweep/scenario.hpp"

#include <algorithm>
#include <random>
#include <stdexcept>
#include <tuple>

#include "pneu/model/chamber.hpp"

namespace pneu::sweep {

model::PlantParams BenchDraw::applied_to(model::PlantParams p) const {
  auto& f = p.friction;
  f.static_positive_n *= static_positive;
  f.static_negative_n *= static_negative;
  f.coulomb_positive_n = std::min(f.coulomb_positive_n * coulomb_positive, f.static_positive_n);
  f.coulomb_negative_n = std::max(f.coulomb_negative_n * coulomb_negative, f.static_negative_n);
  f.viscous_n_s_per_m *= viscous;
  p.valve.max_conductance_m3_per_s_pa *= max_conductance;
  p.valve.leak_conductance_in_m3_per_s_pa *= leak_in;
  p.valve.leak_conductance_out_m3_per_s_pa *= leak_out;
  p.valve.null_offset_v += null_offset_v;
  p.geometry.dead_volume_p_m3 *= dead_volume_p;
  p.geometry.dead_volume_n_m3 *= dead_volume_n;
  if (!std::isnan(thermal_time_constant_s)) {
    p.has_thermal = true;
    p.thermal.heat_transfer_w_per_m2_k = model::heat_transfer_for_time_constant(p, thermal_time_constant_s);
  }
  if (!std::isnan(spool_time_constant_s)) p.valve.spool_time_constant_s = spool_time_constant_s;
  return p;
}

const char* design_name(Design d) noexcept {
  switch (d) {
    case Design::kMonteCarlo: return "mc";
    case Design::kLatinHypercube: return "lhs";
    case Design::kGrid: return "grid";
  }
  return "?";
}

std::size_t atlas_dimensions(const Options& o) noexcept {
  return 4 + (o.bench_thermal_s.given() ? 1 : 0) + (o.bench_spool_lag_s.given() ? 1 : 0);
}

namespace {

// Each scenario's place in the atlas's design, in [0, 1) per dimension (atlas_dimensions() used).
std::vector<std::array<double, kMaxAtlasDimensions>> design_points(const Options& o) {
  const std::size_t n = static_cast<std::size_t>(o.steps), dims = atlas_dimensions(o);
  std::vector<std::array<double, kMaxAtlasDimensions>> points(n);
  if (o.design == Design::kGrid) {
    for (std::size_t i = 0; i < n; ++i) {
      std::size_t rest = i;
      for (std::size_t d = 0; d < dims; ++d) {
        const auto levels = static_cast<std::size_t>(o.grid_levels[d]);
        points[i][d] = (static_cast<double>(rest % levels) + 0.5) / static_cast<double>(levels);
        rest /= levels;
      }
    }
    return points;
  }
  // A Latin hypercube: in each dimension, one scenario per stratum [k/n, (k+1)/n), a random
  // permutation assigning them (Fisher-Yates, written out: the same on every standard library).
  std::mt19937_64 rng(o.seed ^ 0x452821e638d01377ULL);
  std::uniform_real_distribution<double> within(0.0, 1.0);
  std::vector<std::size_t> stratum(n);
  for (std::size_t d = 0; d < dims; ++d) {
    for (std::size_t k = 0; k < n; ++k) stratum[k] = k;
    for (std::size_t k = n; k > 1; --k) std::swap(stratum[k - 1], stratum[rng() % k]);
    for (std::size_t i = 0; i < n; ++i)
      points[i][d] = (static_cast<double>(stratum[i]) + within(rng)) / static_cast<double>(n);
  }
  return points;
}

}  // namespace

TargetRange target_range(const Options& options, double half_stroke_m) noexcept {
  return {-half_stroke_m + options.margin_m, half_stroke_m - options.margin_m};
}

std::vector<Scenario> draw_scenarios(const Options& o, double half_stroke_m) {
  const TargetRange targets = target_range(o, half_stroke_m);
  const double lo = targets.lo_m, hi = targets.hi_m;
  // Every target needs a start at least min_step_m away inside [lo, hi]: the mid-range one too.
  if (!(o.steps >= 1 && o.margin_m >= 0 && o.min_step_m >= 0 && o.min_step_m < half_stroke_m - o.margin_m))
    throw std::invalid_argument("the sweep's options leave no room for its scenarios in the stroke");
  const int n = o.steps;
  const bool atlas = o.design != Design::kMonteCarlo;
  if (o.design == Design::kGrid) {
    long long product = 1;
    for (std::size_t d = 0; d < atlas_dimensions(o); ++d) {
      if (o.grid_levels[d] < 1) throw std::invalid_argument("the grid needs a number of levels >= 1 per dimension");
      product *= o.grid_levels[d];
      if (product > n) break;
    }
    if (product != n) throw std::invalid_argument("the grid's levels multiply to another number than the scenarios");
  }
  const auto points = atlas ? design_points(o) : std::vector<std::array<double, kMaxAtlasDimensions>>{};
  std::vector<Scenario> scenarios(static_cast<std::size_t>(n));
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    Scenario& s = scenarios[static_cast<std::size_t>(i)];
    s.index = i;
    s.y_d_m = atlas ? lo + (hi - lo) * points[static_cast<std::size_t>(i)][0] : lo + (hi - lo) * (i + 0.5) / n;
    do {
      s.y0_m = lo + (hi - lo) * 0.5 * (1.0 + unit(rng));
    } while (std::abs(s.y0_m - s.y_d_m) < o.min_step_m);
    s.friction_scale = 1.0 + o.friction_spread * unit(rng);
    s.gain_scale = 1.0 + o.gain_spread * unit(rng);
  }
  if (atlas) {
    // The atlas's benches: each tolerance where the design places it (see the header).
    const auto between = [](double lo_v, double hi_v, double at) { return lo_v + (hi_v - lo_v) * at; };
    const double b = o.bench_spread;
    for (Scenario& s : scenarios) {
      const auto& p = points[static_cast<std::size_t>(s.index)];
      BenchDraw& bench = s.bench;
      const double friction = between(1.0 - b, 1.0 + b, p[1]), dead_volume = between(1.0 - b, 1.0 + b, p[2]);
      for (double* x : {&bench.static_positive, &bench.coulomb_positive, &bench.static_negative,
                        &bench.coulomb_negative, &bench.viscous})
        *x = friction;
      bench.dead_volume_p = bench.dead_volume_n = dead_volume;
      bench.null_offset_v = between(-0.5 * b, 0.5 * b, p[3]);
      std::size_t d = 4;
      if (o.bench_thermal_s.given())
        bench.thermal_time_constant_s = between(o.bench_thermal_s.lo, o.bench_thermal_s.hi, p[d++]);
      if (o.bench_spool_lag_s.given())
        bench.spool_time_constant_s = between(o.bench_spool_lag_s.lo, o.bench_spool_lag_s.hi, p[d++]);
    }
    return scenarios;
  }
  // The benches from a generator of their own, so that the scenarios above stay those of the seed.
  if (o.bench_spread > 0.0) {
    std::mt19937_64 bench_rng(o.seed ^ 0x9e3779b97f4a7c15ULL);
    const auto factor = [&] { return 1.0 + o.bench_spread * unit(bench_rng); };
    for (Scenario& s : scenarios) {
      BenchDraw& b = s.bench;
      for (double* x : {&b.static_positive, &b.coulomb_positive, &b.static_negative, &b.coulomb_negative, &b.viscous,
                        &b.max_conductance, &b.leak_in, &b.leak_out, &b.dead_volume_p, &b.dead_volume_n})
        *x = factor();
      b.null_offset_v = 0.5 * o.bench_spread * unit(bench_rng);
    }
  }
  // The benches' physics, each from a generator of its own: the draws above stay those of the seed.
  for (const auto& [range, member, salt] :
       {std::tuple{o.bench_thermal_s, &BenchDraw::thermal_time_constant_s, 0x243f6a8885a308d3ULL},
        std::tuple{o.bench_spool_lag_s, &BenchDraw::spool_time_constant_s, 0x13198a2e03707344ULL}}) {
    if (!range.given()) continue;
    std::mt19937_64 physics_rng(o.seed ^ salt);
    std::uniform_real_distribution<double> in_range(0.0, 1.0);
    for (Scenario& s : scenarios) s.bench.*member = range.lo + (range.hi - range.lo) * in_range(physics_rng);
  }
  return scenarios;
}

}  // namespace pneu::sweep
