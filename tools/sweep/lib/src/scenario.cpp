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
  std::vector<Scenario> scenarios(static_cast<std::size_t>(n));
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    Scenario& s = scenarios[static_cast<std::size_t>(i)];
    s.index = i;
    s.y_d_m = lo + (hi - lo) * (i + 0.5) / n;
    do {
      s.y0_m = lo + (hi - lo) * 0.5 * (1.0 + unit(rng));
    } while (std::abs(s.y0_m - s.y_d_m) < o.min_step_m);
    s.friction_scale = 1.0 + o.friction_spread * unit(rng);
    s.gain_scale = 1.0 + o.gain_spread * unit(rng);
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
