// The valve fit's Jacobian (identify/src/valve_fit.cpp): with the model's hidden state (the chambers'
// energy balance, the spools' lag) the derivatives of the residuals come from one pass of Dual
// numbers through the model's own equations; here they are checked against central differences of
// the residuals themselves.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "phases.hpp"
#include "pneu/assembly/run_spec.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/text.hpp"
#include "pneu/identify/identification_run.hpp"
#include "support/paths.hpp"
#include "valve_fit.hpp"

namespace {

using namespace pneu;
using identify::detail::FitCheck;

// `p` with the fit's theta_i moved by `by`.
model::PlantParams moved(model::PlantParams p, std::size_t i, double by) {
  double& x = identify::detail::parameter(p, i);
  x = identify::detail::logarithmic(i) ? x * std::exp(by) : x + by;
  return p;
}

double norm(const std::vector<double>& v) {
  double s = 0.0;
  for (const double x : v) s += x * x;
  return std::sqrt(s);
}

// An identification run recorded with the HIL sensors (so that the phases' starts are fitted too),
// and its stuck phases. `hidden`: on a bench with heat exchange and a spool lag, the model with both
// terms at other values; else the plain model (polytropic, no lag) on a bench of that model.
struct Recorded {
  config::Config cfg;
  identify::RecordedRun run;
  identify::Options o;
  std::vector<identify::detail::StuckPhase> phases;
};

Recorded record(bool hidden) {
  Recorded x;
  x.cfg = config::load_file(test::shipped_config("hil.yaml"), {"hal.backend=sim"});
  if (hidden) {
    x.cfg.plant.has_thermal = true;
    x.cfg.plant.thermal.heat_transfer_w_per_m2_k = 12.86;
    x.cfg.plant.valve.spool_time_constant_s = 0.001;
  }
  model::PlantParams bench = x.cfg.plant;
  if (hidden) {
    bench.thermal.heat_transfer_w_per_m2_k = 25.72;
    bench.valve.spool_time_constant_s = 0.003;
  }
  bench.valve.max_conductance_m3_per_s_pa *= 1.15;
  bench.valve.null_offset_v = 0.07;
  bench.geometry.dead_volume_p_m3 *= 1.2;
  x.run = identify::record_run(assembly::RunSpec::of(x.cfg), bench, x.cfg.simulation.initial_position_m);
  x.o = identify::options_for(x.cfg);
  x.o.command_delay_samples = 0;
  x.phases = identify::detail::stuck_phases(x.run.samples, x.cfg.plant.geometry.half_stroke_m(), x.o);
  return x;
}

const Recorded& recorded() {
  static const Recorded r = record(true);
  return r;
}

// The exact derivatives the fit takes at `at` with the starts moved (by 0.4 and -0.3 noise floors,
// P and N), column by column against central differences of the residuals: each of the model's
// parameters (the ones it lacks: none) and the starts.
void expect_exact_jacobian(const Recorded& rec, const model::PlantParams& at) {
  const config::Config& cfg = rec.cfg;
  const identify::RecordedRun& run = rec.run;
  const identify::Options& o = rec.o;
  const std::vector<identify::detail::StuckPhase>& phases = rec.phases;
  ASSERT_TRUE(run.fault.empty()) << run.fault;
  const FitCheck base = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, at, {}, false);
  std::vector<double> z(base.starts);
  for (std::size_t c = 0; c < z.size(); ++c) z[c] = c % 2 == 0 ? 0.4 : -0.3;
  const FitCheck exact = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, at, z, true);
  const std::size_t rows = exact.residual_pa.size();
  ASSERT_GE(rows, 200u);
  ASSERT_GT(exact.starts, 0u);
  ASSERT_GT(at.valve.leak_conductance_in_m3_per_s_pa, 2e-3 * at.valve.max_conductance_m3_per_s_pa);
  ASSERT_GT(at.valve.leak_conductance_out_m3_per_s_pa, 2e-3 * at.valve.max_conductance_m3_per_s_pa);

  // Each parameter's column.
  for (std::size_t i = 0; i < identify::detail::kValveFitParams; ++i) {
    if (!identify::detail::has_parameter(cfg.plant, i)) continue;
    // Steps small against the kinks the null offset moves (a valve's opening at 0), whose crossings
    // central differences smear over h: 0.1 uV, 0.1 us, 1e-4 of a logarithm (with 1 uV one sample of
    // a record straddled a kink: 3.5e-6 off; the rounding floor at 0.1 uV is near 1e-8).
    const double h = i == identify::detail::kSpoolLag || i == identify::detail::kNullOffset ? 1e-7 : 1e-4;
    const FitCheck up = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, moved(at, i, h), z, false);
    const FitCheck down = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, moved(at, i, -h), z, false);
    std::vector<double> central(rows), error(rows);
    for (std::size_t r = 0; r < rows; ++r) {
      central[r] = (up.residual_pa[r] - down.residual_pa[r]) / (2.0 * h);
      error[r] = exact.by_theta[r * identify::detail::kValveFitParams + i] - central[r];
    }
    std::printf("theta %zu: |d r/d theta| %.6g Pa, relative error %.3g\n", i, norm(central), norm(error) / norm(central));
    EXPECT_GT(norm(central), 1.0) << "parameter " << i << " moves the residuals";
    EXPECT_LT(norm(error), 1e-6 * norm(central)) << "parameter " << i;
  }
  // The starts' column: each row depends on its own start alone, so all move at once.
  {
    const double h = 1e-3;
    std::vector<double> zu = z, zd = z;
    for (std::size_t c = 0; c < z.size(); ++c) {
      zu[c] += h;
      zd[c] -= h;
    }
    const FitCheck up = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, at, zu, false);
    const FitCheck down = identify::detail::check_fit_model(run.samples, phases, cfg.plant, o, at, zd, false);
    std::vector<double> central(rows), error(rows);
    for (std::size_t r = 0; r < rows; ++r) {
      central[r] = (up.residual_pa[r] - down.residual_pa[r]) / (2.0 * h);
      error[r] = exact.by_start[r] - central[r];
    }
    std::printf("starts: |d r/d z| %.6g Pa, relative error %.3g\n", norm(central), norm(error) / norm(central));
    EXPECT_LT(norm(error), 1e-6 * norm(central));
  }
}

TEST(ValveFit, TheExactJacobianWithHeatExchangeAndSpoolLagIsTheResidualsCentralDifferences) {
  // Somewhere between the prior and the bench.
  model::PlantParams at = recorded().cfg.plant;
  at.thermal.heat_transfer_w_per_m2_k = 19.0;
  at.valve.spool_time_constant_s = 0.0023;
  at.valve.null_offset_v = 0.03;
  at.valve.max_conductance_m3_per_s_pa *= 1.07;
  expect_exact_jacobian(recorded(), at);
}

TEST(ValveFit, ThePlainModelsExactJacobianIsTheResidualsCentralDifferences) {
  // Polytropic, no spool lag: the pressures' sensitivities integrated beside them.
  const Recorded rec = record(false);
  model::PlantParams at = rec.cfg.plant;
  at.valve.null_offset_v = 0.03;
  at.valve.max_conductance_m3_per_s_pa *= 1.07;
  at.geometry.dead_volume_p_m3 *= 1.1;
  expect_exact_jacobian(rec, at);
}

TEST(ValveFit, AtASpoolLagOf0TheDerivativeByItIsTheResidualsSlopeJustAbove) {
  // The fit's search may take the spool lag to its bound 0, where the model has no lag to
  // differentiate: the derivative it steps by is the residuals' slope just above 0, at a microsecond
  // (not the secant from 0 itself, where the integration's steps change as the lag appears).
  const Recorded& rec = recorded();
  ASSERT_TRUE(rec.run.fault.empty()) << rec.run.fault;
  model::PlantParams at = rec.cfg.plant;
  at.valve.spool_time_constant_s = 0.0;
  const std::size_t lag = identify::detail::kSpoolLag;
  const FitCheck exact = identify::detail::check_fit_model(rec.run.samples, rec.phases, rec.cfg.plant, rec.o, at, {}, true);
  const auto residuals_at = [&](double lag_s) {
    model::PlantParams p = at;
    p.valve.spool_time_constant_s = lag_s;
    return identify::detail::check_fit_model(rec.run.samples, rec.phases, rec.cfg.plant, rec.o, p, {}, false).residual_pa;
  };
  const std::vector<double> up = residuals_at(1.05e-6), down = residuals_at(0.95e-6);
  const std::size_t rows = exact.residual_pa.size();
  std::vector<double> slope(rows), error(rows);
  for (std::size_t r = 0; r < rows; ++r) {
    slope[r] = (up[r] - down[r]) / 1e-7;
    error[r] = exact.by_theta[r * identify::detail::kValveFitParams + lag] - slope[r];
  }
  std::printf("spool lag just above 0: |d r/d tau| %.6g Pa/s, relative error %.3g\n", norm(slope), norm(error) / norm(slope));
  EXPECT_GT(norm(slope), 1e6);
  EXPECT_LT(norm(error), 1e-6 * norm(slope));
}

}  // namespace
