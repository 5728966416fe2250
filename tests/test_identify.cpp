// Identification of the bench from its own signals (pneu/identify): the identification run on a
// simulated bench that is not its model, and what identify() makes of it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/config/text.hpp"
#include "pneu/controller/session.hpp"
#include "pneu/identify/identification_run.hpp"
#include "pneu/identify/online.hpp"
#include "pneu/model/valve.hpp"
#include "support/simulated_run.hpp"
#include "support/paths.hpp"

namespace {

using namespace pneu;
using ::testing::HasSubstr;
using ::testing::Not;

struct Bench {
  config::Config cfg;
  model::PlantParams bench;
};

// hil.yaml as the sweeps the scenarios below come from ran it: on the in-process plant, the
// in-position hold off (hil.yaml ships it on since; those scenarios' restarts are what it prevents).
const std::vector<std::string> kSweepsHil{"hal.backend=sim", "controller.hold.enabled=false"};

Bench mismatched(const std::string& shipped = "") {
  Bench b{shipped.empty() ? config::load_string(config::default_config_yaml())
                          : config::load_file(pneu::test::shipped_config(shipped), {"hal.backend=sim"}),
          {}};
  b.bench = b.cfg.plant;
  b.bench.friction.static_positive_n = 54.0;
  b.bench.friction.static_negative_n = -42.0;
  b.bench.friction.coulomb_positive_n = 40.0;
  b.bench.friction.coulomb_negative_n = -33.0;
  b.bench.friction.viscous_n_s_per_m = 75.0;
  b.bench.valve.max_conductance_m3_per_s_pa *= 1.15;
  b.bench.valve.leak_conductance_in_m3_per_s_pa *= 0.85;
  b.bench.valve.leak_conductance_out_m3_per_s_pa *= 1.2;
  b.bench.valve.null_offset_v = 0.07;
  b.bench.geometry.dead_volume_p_m3 *= 1.2;
  b.bench.geometry.dead_volume_n_m3 *= 0.85;
  return b;
}

double truth(const model::PlantParams& p, const std::string& key) {
  if (key == "plant.friction.static_positive_n") return p.friction.static_positive_n;
  if (key == "plant.friction.static_negative_n") return p.friction.static_negative_n;
  if (key == "plant.friction.coulomb_positive_n") return p.friction.coulomb_positive_n;
  if (key == "plant.friction.coulomb_negative_n") return p.friction.coulomb_negative_n;
  if (key == "plant.friction.viscous_n_s_per_m") return p.friction.viscous_n_s_per_m;
  if (key == "plant.valve.max_conductance_m3_per_s_pa") return p.valve.max_conductance_m3_per_s_pa;
  if (key == "plant.valve.leak_conductance_in_m3_per_s_pa") return p.valve.leak_conductance_in_m3_per_s_pa;
  if (key == "plant.valve.leak_conductance_out_m3_per_s_pa") return p.valve.leak_conductance_out_m3_per_s_pa;
  if (key == "plant.valve.null_offset_v") return p.valve.null_offset_v;
  if (key == "plant.geometry.dead_volume_p_m3") return p.geometry.dead_volume_p_m3;
  if (key == "plant.geometry.dead_volume_n_m3") return p.geometry.dead_volume_n_m3;
  if (key == "plant.friction.stribeck_velocity_m_per_s") return p.friction.stribeck_velocity_m_per_s;
  if (key == "plant.mass_kg") return p.mass_kg;
  if (key == "plant.thermal.heat_transfer_w_per_m2_k") return p.thermal.heat_transfer_w_per_m2_k;
  if (key == "plant.valve.spool_time_constant_s") return p.valve.spool_time_constant_s;
  return NAN;
}

double null_pressure_error_pa(const model::PlantParams& a, const model::PlantParams& b) {
  return identify::largest_null_pressure_difference_pa(a, b, 1.0);
}

identify::Identification run_identification(const Bench& b) {
  const assembly::RunSpec spec = assembly::RunSpec::of(b.cfg).reconfigured(
      [](config::Config& c) { c.controller.initial_setpoint_m = c.simulation.initial_position_m; });
  return identify::identify_by_run(spec, b.bench, spec.config().simulation.initial_position_m);
}

void print(const identify::Identification& id, const model::PlantParams& bench) {
  const auto& e = id.evidence;
  std::printf("phases %d fitted %d breakaways +%d -%d stuck %.1f s sliding %.2f s span %.0f mm u %.3f V rms %.1f Pa\n",
              e.stuck_phases, e.fitted_phases, e.breakaways_positive, e.breakaways_negative, e.stuck_s, e.sliding_s,
              e.stuck_position_span_m * 1e3, e.voltage_span_v, e.pressure_rms_residual_pa);
  for (const auto& x : id.estimates) {
    const double t = truth(bench, x.key);
    std::printf("%-48s prior %-11.4g value %-11.4g +- %-9.2g bench %-11.4g err %+.2f %% %s %s\n", x.key.c_str(), x.prior,
                x.value, x.std, t, t != 0 ? 100 * (x.value - t) / std::abs(t) : 0.0, x.identified ? "id" : "--",
                x.basis.c_str());
  }
  std::printf("p_null error over |u| < 1 V: %.0f Pa\n", null_pressure_error_pa(id.plant, bench));
}

// The identification run on `b`'s bench (the configured law), recorded.
identify::RecordedRun record_run(const Bench& b, const std::vector<std::string>& overrides = {}) {
  config::Config cfg = b.cfg;
  for (const auto& o : overrides) cfg = config::load_string(config::to_yaml(cfg), {o});
  return identify::record_run(assembly::RunSpec::of(cfg), b.bench, cfg.simulation.initial_position_m);
}

void expect_close_to_bench(const identify::Identification& id, const model::PlantParams& bench, double stiction_tolerance) {
  for (const char* key : {"plant.friction.static_positive_n", "plant.friction.static_negative_n"}) {
    const auto& e = id.at(key);
    EXPECT_TRUE(e.identified) << key << ": " << e.basis;
    EXPECT_NEAR(e.value, truth(bench, key), stiction_tolerance * std::abs(truth(bench, key))) << key;
    // The uncertainty it states covers its error.
    EXPECT_LE(std::abs(e.value - truth(bench, key)), 3 * e.std) << key;
  }
  // So do the sliding friction's (the fit's residuals are correlated along a motion: Newey-West).
  for (const char* key : {"plant.friction.coulomb_positive_n", "plant.friction.coulomb_negative_n",
                          "plant.friction.viscous_n_s_per_m"}) {
    const auto& e = id.at(key);
    if (e.identified) {
      EXPECT_LE(std::abs(e.value - truth(bench, key)), 3 * e.std) << key << ": " << e.basis;
    }
  }
  EXPECT_LT(null_pressure_error_pa(id.plant, bench), 5e3) << "p_null(u) within 5 kPa over |u| < 1 V";
  for (const auto& e : id.estimates) {
    if (!e.identified) continue;
    const double t = truth(bench, e.key);
    EXPECT_NEAR(e.value, t, std::max(0.03 * std::abs(t), 1e-3)) << e.key << ": " << e.basis;
  }
}

TEST(IdentificationRun, IdentifiesABenchThatIsNotItsModelWithIdealSensors) {
  const Bench b = mismatched();
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  expect_close_to_bench(id, b.bench, 0.02);
  for (const char* key : {"plant.valve.max_conductance_m3_per_s_pa", "plant.valve.leak_conductance_in_m3_per_s_pa",
                          "plant.valve.leak_conductance_out_m3_per_s_pa", "plant.valve.null_offset_v",
                          "plant.geometry.dead_volume_p_m3", "plant.geometry.dead_volume_n_m3",
                          "plant.friction.coulomb_positive_n", "plant.friction.coulomb_negative_n",
                          "plant.friction.viscous_n_s_per_m"})
    EXPECT_TRUE(id.at(key).identified) << key << ": " << id.at(key).basis;
  EXPECT_NEAR(id.plant.valve.null_offset_v, 0.07, 0.001);
  // What it does not identify, it says, and keeps.
  EXPECT_FALSE(id.at("plant.mass_kg").identified);
  EXPECT_EQ(id.plant.mass_kg, b.cfg.plant.mass_kg);
}

TEST(IdentificationRun, IdentifiesABenchThatIsNotItsModelWithHilSensors) {
  const Bench b = mismatched("hil.yaml");
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  expect_close_to_bench(id, b.bench, 0.05);
  // Eq. 19 is fitted only where the carriage stood still: within the rest band a stuck phase may
  // begin while the carriage still slides in and end with a slow breakaway's onset, and a moving
  // piston changes the chambers' volumes. What is left is the pressure sensors' own noise (20 Pa,
  // and a 15 Pa ADC step): 24.0 Pa; 35.3 Pa when those ends were fitted too (p_null then 66 Pa off,
  // now 23 Pa).
  EXPECT_LT(id.evidence.pressure_rms_residual_pa, 27.0);
}

TEST(IdentificationRun, StaysWithinTheSoftLimitsAndTakesUnderAMinute) {
  const Bench b = mismatched();
  const identify::RecordedRun r = record_run(b);
  EXPECT_TRUE(r.fault.empty()) << r.fault;
  EXPECT_LT(r.plan.duration_s, 60.0);
  ASSERT_FALSE(r.samples.empty());
  EXPECT_NEAR(r.samples.back().t_s, r.plan.duration_s, 0.002);
  for (const auto& step : r.plan.schedule) {
    EXPECT_GE(step.position_m, b.cfg.controller.soft_limit_min_m);
    EXPECT_LE(step.position_m, b.cfg.controller.soft_limit_max_m);
  }
  double lo = 1, hi = -1;
  for (const auto& x : r.samples) {
    lo = std::min(lo, x.y_m);
    hi = std::max(hi, x.y_m);
  }
  EXPECT_GE(lo, b.cfg.controller.soft_limit_min_m);
  EXPECT_LE(hi, b.cfg.controller.soft_limit_max_m);
  // ... and it goes near both ends of them, which separates the dead volumes.
  EXPECT_LT(lo, b.cfg.controller.soft_limit_min_m + 0.1);
  EXPECT_GT(hi, b.cfg.controller.soft_limit_max_m - 0.1);
}

// The plan's ramps carry the pressure force across the stiction band again and again; the
// in-position hold, which hil.yaml and bench.yaml ship on, would drive it to the band's middle
// instead (and end and begin again at each 10 ms step of the set point). The run drives without it.
TEST(IdentificationRun, DrivesWithTheHoldOffWhateverTheConfigurationSays) {
  const Bench b = mismatched("hil.yaml");
  ASSERT_TRUE(b.cfg.controller.hold.enabled) << "hil.yaml ships with the hold on";
  const identify::RecordedRun r = record_run(b);
  EXPECT_FALSE(identify::configured_for(b.cfg, r.plan).controller.hold.enabled);
  EXPECT_TRUE(identify::configured_for(b.cfg, r.plan).controller.start_armed);
}

TEST(IdentificationRun, AFaultEndsTheRunAndNothingIsIdentified) {
  Bench b = mismatched();
  b.cfg = config::load_string(config::default_config_yaml(), {"controller.supervisor.following_error_m=0.002",
                                                                "controller.supervisor.following_error_s=0.05"});
  const identify::RecordedRun r = record_run(b);
  EXPECT_NE(r.fault.find("following"), std::string::npos) << r.fault;
  // It names the key that decided, and what relaxing it costs.
  EXPECT_NE(r.fault.find("decided by controller.supervisor.following_error_s: relaxing it: "), std::string::npos)
      << r.fault;
  EXPECT_LT(r.samples.back().t_s, r.plan.duration_s - 10.0) << "ended at the fault";
  try {
    (void)identify::identify_by_run(assembly::RunSpec::of(b.cfg), b.bench, b.cfg.simulation.initial_position_m);
    ADD_FAILURE() << "identified from a run that faulted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("faulted"), std::string::npos) << e.what();
  }
}

// On the real clock the run lasts about a minute: it says, on the way, the share done and the phase.
TEST(IdentificationRun, SaysHowItGoesAtEachPhaseAndEveryTenthOfTheRun) {
  const Bench b = mismatched();
  const identify::RecordedRun r = record_run(b);
  ASSERT_EQ(r.plan.phases.size(), 2 * r.plan.positions_m.size());
  char* text = nullptr;
  std::size_t size = 0;
  std::FILE* out = open_memstream(&text, &size);
  ASSERT_NE(out, nullptr);
  {
    identify::Progress progress(r.plan, out);
    controller::TickRecord tick;
    for (const auto& sample : r.samples) {
      tick.t_s = sample.t_s;
      progress.on_tick(tick, {});
    }
  }
  std::fclose(out);
  const std::string said(text, size);
  std::free(text);
  int lines = 0;
  for (const char c : said) lines += c == '\n';
  // Six phases, and the tenths between them that no phase starts.
  EXPECT_GE(lines, 6 + 4) << said;
  EXPECT_LE(lines, 6 + 10) << said;
  EXPECT_NE(said.find("(position 1 of 3)"), std::string::npos) << said;
  EXPECT_NE(said.find("ramping the set point about"), std::string::npos) << said;
  EXPECT_NE(said.find("(position 3 of 3)"), std::string::npos) << said;
  EXPECT_NE(said.find(" 90 %"), std::string::npos) << said;
}

// The mismatched bench with the physics every real cylinder has: wall heat exchange (a thermal
// time constant of 1 s at mid-stroke: h = 25.72 W/m^2/K) and a 3 ms spool lag.
Bench thermal(const std::string& shipped = "") {
  Bench b = mismatched(shipped);
  b.bench.has_thermal = true;
  b.bench.thermal.heat_transfer_w_per_m2_k = 25.72;
  b.bench.valve.spool_time_constant_s = 0.003;
  return b;
}

// The model has both terms, at other values (a thermal time constant of 2 s, a 1 ms lag).
Bench thermal_with_a_thermal_model(const std::string& shipped = "") {
  Bench b = thermal(shipped);
  b.cfg.plant.has_thermal = true;
  b.cfg.plant.thermal.heat_transfer_w_per_m2_k = 12.86;
  b.cfg.plant.valve.spool_time_constant_s = 0.001;
  return b;
}

void expect_heat_and_spool_identified(const identify::Identification& id, const model::PlantParams& bench,
                                      double max_relative_std) {
  EXPECT_TRUE(id.plant.has_thermal);
  for (const char* key : {"plant.thermal.heat_transfer_w_per_m2_k", "plant.valve.spool_time_constant_s"}) {
    const auto& e = id.at(key);
    ASSERT_TRUE(e.identified) << key << ": " << e.basis;
    EXPECT_LE(std::abs(e.value - truth(bench, key)), 3 * e.std) << key;
    EXPECT_LT(e.std, max_relative_std * truth(bench, key)) << key << ": and that sigma is tight";
  }
}

TEST(IdentificationRun, IdentifiesAThermalBenchsHeatTransferAndSpoolLagWhereTheModelHasThemWithIdealSensors) {
  const Bench b = thermal_with_a_thermal_model();
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  EXPECT_TRUE(id.evidence.model_fits);
  EXPECT_LT(id.evidence.pressure_rms_residual_pa, 20.0) << "what an exact model leaves of ideal readings";
  EXPECT_TRUE(id.evidence.misfit.empty());
  expect_close_to_bench(id, b.bench, 0.02);
  expect_heat_and_spool_identified(id, b.bench, 0.02);
}

TEST(IdentificationRun, IdentifiesAThermalBenchsHeatTransferAndSpoolLagWhereTheModelHasThemWithHilSensors) {
  const Bench b = thermal_with_a_thermal_model("hil.yaml");
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  EXPECT_TRUE(id.evidence.model_fits) << identify::fit_verdict(id.evidence);
  EXPECT_LE(id.evidence.pressure_rms_residual_pa, 2 * id.evidence.pressure_explained_pa);
  EXPECT_GT(id.evidence.pressure_noise_pa, 15.0) << "hil.yaml's 20 Pa, as the phases show it";
  expect_close_to_bench(id, b.bench, 0.05);
  expect_heat_and_spool_identified(id, b.bench, 0.1);
}

TEST(IdentificationRun, SaysByNameThatAModelWithoutTheWallsHeatDoesNotFitAThermalBenchAndWidensItsSigmas) {
  const Bench b = thermal();  // the model is polytropic, no spool lag
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  const auto& e = id.evidence;
  EXPECT_FALSE(e.model_fits);
  EXPECT_GT(e.pressure_rms_residual_pa, 2 * e.pressure_explained_pa);
  // The phases that fail worst, by time and position, of the phases fitted.
  ASSERT_FALSE(e.misfit.empty());
  EXPECT_LE(static_cast<int>(e.misfit.size()), e.misfit_phases_of);
  for (const auto& m : e.misfit) {
    EXPECT_GT(m.rms_pa, 3 * e.pressure_explained_pa);
    EXPECT_GE(m.y_m, b.cfg.controller.soft_limit_min_m);
    EXPECT_LE(m.y_m, b.cfg.controller.soft_limit_max_m);
  }
  const std::string verdict = identify::fit_verdict(e);
  std::printf("%s\n", verdict.c_str());
  EXPECT_THAT(verdict, HasSubstr("THE MODEL DOES NOT FIT"));
  EXPECT_THAT(verdict, HasSubstr("the worst: t = "));
  EXPECT_THAT(verdict, HasSubstr("plant.thermal"));
  // No tight sigma on a fit that does not fit: each phase counts as one sample, and every valve
  // parameter is either published with an uncertainty that covers its error against the bench or
  // kept at the configured value, saying why.
  for (const char* key : {"plant.valve.max_conductance_m3_per_s_pa", "plant.valve.leak_conductance_in_m3_per_s_pa",
                          "plant.valve.leak_conductance_out_m3_per_s_pa", "plant.valve.null_offset_v",
                          "plant.geometry.dead_volume_p_m3", "plant.geometry.dead_volume_n_m3"}) {
    const auto& x = id.at(key);
    if (x.identified)
      EXPECT_LE(std::abs(x.value - truth(b.bench, key)), 3 * x.std) << key << ": " << x.value << " +- " << x.std;
    else
      EXPECT_THAT(x.basis, HasSubstr("the model does not fit")) << key;
  }
  EXPECT_THAT(id.at("plant.thermal.heat_transfer_w_per_m2_k").basis, HasSubstr("the model has no heat exchange"));
  EXPECT_THAT(id.at("plant.valve.spool_time_constant_s").basis, HasSubstr("the model has no spool lag"));
}

// A disturbance the model does not have spoils a phase or two of a run that is otherwise the
// model's (both pressure sensors glitching for 0.3 s here; on a bench, a knock on the carriage, a
// link that stalled): the fit leaves those phases out, says which, and identifies the bench from
// the others as it would without them, where counting them made the whole model "not fit" and
// kept its heat transfer and spool lag at the configured values.
TEST(IdentificationRun, LeavesOutAPhaseADisturbanceSpoiledSaysWhichAndIdentifiesTheBenchFromTheOthersWithHilSensors) {
  const Bench b = thermal_with_a_thermal_model("hil.yaml");
  identify::RecordedRun run = record_run(b);
  identify::Options o = identify::options_for(b.cfg);
  o.command_delay_samples = 0;  // in process, as identify_by_run takes it
  // The first second after 5 s in which the carriage stood still (its readings within 0.2 mm):
  // the glitch in its middle.
  auto& s = run.samples;
  std::size_t first = 0, last = 0;
  for (std::size_t k = 0, lo = 0; k < s.size() && last == 0; ++k) {
    while (s[k].t_s - s[lo].t_s > 1.0) ++lo;
    if (s[lo].t_s < 5.0 || s[k].t_s - s[lo].t_s < 0.999) continue;
    const auto [mn, mx] = std::minmax_element(s.begin() + lo, s.begin() + k + 1,
                                              [](const auto& a, const auto& c) { return a.y_m < c.y_m; });
    if (mx->y_m - mn->y_m < 2e-4) first = lo, last = k;
  }
  ASSERT_GT(last, first) << "a still second in the record";
  const double t_glitch = s[(first + last) / 2].t_s;
  for (auto& x : s)
    if (std::abs(x.t_s - t_glitch) < 0.15) x.p_p_pa += 3000.0, x.p_n_pa -= 3000.0;
  const identify::Identification id = identify::identify(run.samples, b.cfg.plant, o);
  print(id, b.bench);
  const auto& e = id.evidence;
  const std::string verdict = identify::fit_verdict(e);
  std::printf("%s\n", verdict.c_str());
  EXPECT_TRUE(e.model_fits) << verdict;
  ASSERT_EQ(e.left_out.size(), 1u) << verdict;
  EXPECT_LE(e.left_out[0].t_s, t_glitch) << "the phase the glitch is in";
  EXPECT_GT(e.left_out[0].rms_pa, 3 * e.pressure_explained_pa);
  EXPECT_GE(e.fitted_phases, 9 * static_cast<int>(e.left_out.size())) << "the others are many";
  EXPECT_THAT(verdict, HasSubstr("1 phase left out"));
  EXPECT_THAT(verdict, HasSubstr(text::format("t = %.2f s", e.left_out[0].t_s)));
  expect_close_to_bench(id, b.bench, 0.05);
  expect_heat_and_spool_identified(id, b.bench, 0.1);
}

// A loop that skips deadlines leaves gaps in its record; over a bus each shifts when a command
// reached the valves, which the fit's whole-sample delay does not have. The evidence counts the
// ticks missing within the fitted phases, and a misfit's verdict names them as a suspect.
TEST(Identify, CountsTheDeadlinesTheLoopSkippedWithinTheFittedPhasesAndNamesThemInAMisfit) {
  const Bench b = mismatched();
  const identify::RecordedRun run = record_run(b);
  const identify::Options o = identify::options_for(b.cfg);
  const identify::Identification whole = identify::identify(run.samples, b.cfg.plant, o);
  EXPECT_EQ(whole.evidence.fitted_deadlines_skipped, 0);
  EXPECT_GT(whole.evidence.fitted_samples, 0);
  // Every 100th tick missing, as from a loop that overran there.
  std::vector<identify::Sample> gappy;
  for (std::size_t k = 0; k < run.samples.size(); ++k)
    if (k % 100 != 50) gappy.push_back(run.samples[k]);
  const identify::Evidence e = identify::identify(gappy, b.cfg.plant, o).evidence;
  std::printf("%d deadlines skipped within %d fitted samples of %d phases\n", e.fitted_deadlines_skipped,
              e.fitted_samples, e.fitted_phases);
  EXPECT_NEAR(e.fitted_deadlines_skipped, e.fitted_samples / 99.0, e.fitted_phases + 1.0);
  identify::Evidence misfit = e;
  misfit.model_fits = false;
  misfit.pressure_rms_residual_pa = 60.0;
  misfit.pressure_explained_pa = 18.5;
  EXPECT_THAT(identify::fit_verdict(misfit),
              HasSubstr("Or the commands' timing: the loop skipped " + std::to_string(e.fitted_deadlines_skipped) +
                        " deadlines within these phases"));
  misfit.fitted_deadlines_skipped = 0;
  EXPECT_THAT(identify::fit_verdict(misfit), Not(HasSubstr("the commands' timing")));
}

std::string refusal(std::span<const identify::Sample> samples, const model::PlantParams& prior) {
  try {
    (void)identify::identify(samples, prior);
  } catch (const identify::InsufficientData& e) {
    return e.what();
  }
  return "";
}

TEST(Identify, RefusesATrajectoryWithNoStickingPhaseNamingIt) {
  const model::PlantParams prior;
  std::vector<identify::Sample> sliding;
  for (int k = 0; k < 2000; ++k) sliding.push_back({k * 1e-3, -0.2 + 0.1 * k * 1e-3, 4e5, 3e5, 1.0, true});
  EXPECT_NE(refusal(sliding, prior).find("no sticking phase"), std::string::npos) << refusal(sliding, prior);
}

TEST(Identify, RefusesATrajectoryWithNoBreakawayNamingIt) {
  const model::PlantParams prior;
  std::vector<identify::Sample> still;
  for (int k = 0; k < 2000; ++k) still.push_back({k * 1e-3, 0.01, 4e5 - 10.0 * k, 3e5, 0.1, true});
  EXPECT_NE(refusal(still, prior).find("no breakaway"), std::string::npos) << refusal(still, prior);
}

TEST(Identify, RefusesTooLittleExcitationNamingIt) {
  // Stuck phases of 50 ms with breakaways between them: stiction, but no transient to fit.
  const model::PlantParams prior;
  std::vector<identify::Sample> s;
  double y = 0.0;
  for (int k = 0; k < 3000; ++k) {
    const int phase = k % 100;
    if (phase >= 50) y += 1e-5 * ((k / 100) % 2 ? -1 : 1);
    const double force_p = phase < 50 ? 4e5 + 200.0 * phase : 4e5;
    s.push_back({k * 1e-3, y, force_p, 3e5, 0.1, true});
  }
  EXPECT_NE(refusal(s, prior).find("too little excitation"), std::string::npos) << refusal(s, prior);
}

TEST(Identify, TheValveFitEstimatesTheValvesTheDeadVolumesTheWallsHeatAndTheSpoolLagAlone) {
  std::vector<std::string> from_the_fit;
  for (const char* key : identify::identified_keys())
    if (identify::from_the_valve_fit(key)) from_the_fit.emplace_back(key);
  EXPECT_EQ(from_the_fit, (std::vector<std::string>{
                              "plant.valve.max_conductance_m3_per_s_pa", "plant.valve.leak_conductance_in_m3_per_s_pa",
                              "plant.valve.leak_conductance_out_m3_per_s_pa", "plant.valve.null_offset_v",
                              "plant.geometry.dead_volume_p_m3", "plant.geometry.dead_volume_n_m3",
                              "plant.thermal.heat_transfer_w_per_m2_k", "plant.valve.spool_time_constant_s"}));
  EXPECT_FALSE(identify::from_the_valve_fit("plant.valve.max_voltage_v"));  // a key it does not estimate
}

TEST(Identify, SaysWhatOnePositionCannotSeparate) {
  // The stuck phases of the run's last position alone: one volume per chamber for one conductance
  // scale, so the dead volumes and C_max cannot all be told apart.
  const Bench b = mismatched();
  const identify::RecordedRun r = record_run(b);
  const double t_last = r.plan.schedule.back().t_s;
  double t_from = -1;
  for (const auto& step : r.plan.schedule)
    if (t_from < 0 && step.position_m == r.plan.positions_m.back()) t_from = step.t_s;
  std::vector<identify::Sample> one_position;
  for (const auto& x : r.samples)
    if (x.t_s > t_from + 0.8 && x.t_s <= t_last) one_position.push_back(x);
  const identify::Identification id = identify::identify(one_position, b.cfg.plant);
  int not_separable = 0;
  for (const char* key : {"plant.valve.max_conductance_m3_per_s_pa", "plant.geometry.dead_volume_p_m3",
                          "plant.geometry.dead_volume_n_m3"}) {
    const auto& e = id.at(key);
    if (!e.identified) {
      ++not_separable;
      EXPECT_NE(e.basis.find("not separable"), std::string::npos) << e.basis;
      EXPECT_EQ(e.value, e.prior);
    }
  }
  EXPECT_GE(not_separable, 1);
  print(id, b.bench);
}

}  // namespace

namespace {

// The benches of issue 15's table: the paper's set-point step (config/paper.yaml's gains) on a
// bench that is not the model pneud holds. Identified first, pneud's nonlinear forecast of every
// restart after 0.5 s or more of sticking, against the simulated bench's own breakaway.
struct TableBench {
  const char* name;
  void (*apply)(model::PlantParams&);
  double setpoint_m;
};

const TableBench kTableBenches[] = {
    {"exact", [](model::PlantParams&) {}, 0.170},
    {"stiction 20 % high", [](model::PlantParams& p) { p.friction.static_positive_n = 54, p.friction.static_negative_n = -60; }, 0.170},
    {"stiction 20 % low", [](model::PlantParams& p) { p.friction.static_positive_n = 36, p.friction.static_negative_n = -40; }, 0.170},
    {"exhaust leak 22 % low", [](model::PlantParams& p) { p.valve.leak_conductance_out_m3_per_s_pa *= 0.78; }, 0.170},
    {"all a little off, set point 190 mm",
     [](model::PlantParams& p) {
       p.friction.static_positive_n *= 1.1, p.friction.coulomb_positive_n *= 1.1;
       p.friction.static_negative_n *= 0.92, p.friction.coulomb_negative_n *= 0.92;
       p.valve.leak_conductance_in_m3_per_s_pa *= 1.1, p.valve.leak_conductance_out_m3_per_s_pa *= 0.9;
       p.valve.max_conductance_m3_per_s_pa *= 0.95, p.valve.null_offset_v = 0.03;
       p.geometry.dead_volume_p_m3 *= 1.15, p.geometry.dead_volume_n_m3 *= 0.9;
     },
     0.190},
};

struct Judged {
  int long_restarts = 0;
  double worst_percent = 0.0;
  int wrong_verdicts = 0;
  std::vector<double> errors_percent;
  [[nodiscard]] int within(double percent) const {
    return static_cast<int>(std::count_if(errors_percent.begin(), errors_percent.end(), [&](double e) { return e <= percent; }));
  }
};

Judged judge(const controller::Run& run, const hal::SimBackend& plant, int after_restarts = 0);

// pneud's run of `config` on the simulated `bench`, in simulated time.
struct BenchRun {
  BenchRun(const config::Config& c, const model::PlantParams& bench)
      : assembled(assembly::AssembledRun::on_simulated_bench(assembly::RunSpec::of(c), bench)) {}
  BenchRun(const BenchRun&) = delete;
  BenchRun& operator=(const BenchRun&) = delete;
  void execute() { test::execute_simulated(assembled); }
  assembly::AssembledRun assembled;
  const config::Config& cfg = assembled.config();  ///< u_0 resolved
  const hal::SimBackend& plant = *assembled.simulated_bench();
  controller::Run& run = assembled.run();
};


// The paper's step on `bench` with pneud holding `model`; every stop's nonlinear forecast against
// the bench's breakaways.
Judged paper_step(config::Config cfg, const model::PlantParams& model, const model::PlantParams& bench, double y_d_m) {
  cfg.plant = model;
  cfg.controller.schedule = {{1.0, y_d_m}};
  BenchRun b(cfg, bench);
  b.execute();
  return judge(b.run, b.plant);
}

// Every stop's nonlinear forecast against the bench's breakaways, from the stop after the
// `after_restarts`-th restart on.
Judged judge(const controller::Run& run, const hal::SimBackend& plant, int after_restarts) {
  using Kind = plant::PlantEvent::Kind;
  Judged j;
  int restarts = 0;
  for (const auto& stop : run.runtime->stops()) {
    if (restarts < after_restarts) {
      restarts += stop.restarted ? 1 : 0;
      continue;
    }
    if (!stop.nonlinear || (stop.ended && !stop.restarted)) continue;
    // The plant at rest at the snapshot, and its next breakaway.
    const plant::PlantEvent* before = nullptr;
    const plant::PlantEvent* breakaway = nullptr;
    for (const auto& e : plant.motion_events()) {
      if (e.t_s <= stop.snapshot.t_s) before = &e;
      else if (!breakaway && e.kind == Kind::kBreakaway) breakaway = &e;
    }
    if (before && before->kind != Kind::kStick) continue;  // still sliding at the snapshot: not judged
    const bool restarted = breakaway != nullptr && breakaway->t_s < run.runtime->end_time_s();
    if (restarted != stop.nonlinear->will_restart) {
      ++j.wrong_verdicts;
      continue;
    }
    if (!restarted) continue;
    const double sticking = breakaway->t_s - stop.t_stop_s;
    if (sticking < 0.5) continue;
    ++j.long_restarts;
    j.errors_percent.push_back(100 * std::abs(stop.nonlinear->t_restart_s - breakaway->t_s) / sticking);
    j.worst_percent = std::max(j.worst_percent, 100 * std::abs(stop.nonlinear->t_restart_s - breakaway->t_s) / sticking);
  }
  return j;
}

// Every long restart within `all_percent`; at least 95 % of them, over all the table's benches,
// within `most_percent`.
void check_table_benches(const std::string& sensors_from, double most_percent, double all_percent) {
  int long_restarts = 0, within_most = 0;
  for (const TableBench& tb : kTableBenches) {
    SCOPED_TRACE(tb.name);
    config::Config cfg = sensors_from.empty()
                             ? config::load_file(pneu::test::shipped_config("paper.yaml"))
                             : config::load_file(pneu::test::shipped_config(sensors_from),
                                                 {"hal.backend=sim", "controller.law.gains=fixed",
                                                  "controller.hold.enabled=false"});  // the law's phases
    model::PlantParams bench = cfg.plant;
    tb.apply(bench);
    const Judged before = paper_step(cfg, cfg.plant, bench, tb.setpoint_m);
    // Identified from pneud's identification run, starting where the paper's step starts.
    const assembly::RunSpec prior = assembly::RunSpec::of(cfg);
    const identify::Identification id = identify::identify_by_run(
        prior.with_law(identify::identification_law(prior)), bench, cfg.simulation.initial_position_m);
    const Judged after = paper_step(cfg, id.plant, bench, tb.setpoint_m);
    std::printf("%-36s uncalibrated: %d long restarts, worst %.2f %%, %d wrong verdicts; identified: %d, worst %.3f %%, "
                "%d within %.0f %%, %d wrong\n",
                tb.name, before.long_restarts, before.worst_percent, before.wrong_verdicts, after.long_restarts,
                after.worst_percent, after.within(most_percent), most_percent, after.wrong_verdicts);
    EXPECT_LE(after.worst_percent, all_percent);
    EXPECT_LE(after.wrong_verdicts, before.wrong_verdicts) << "no verdict wrong that the uncalibrated model had right";
    long_restarts += after.long_restarts;
    within_most += after.within(most_percent);
  }
  std::printf("over the table's benches: %d of %d long restarts within %.0f %%\n", within_most, long_restarts, most_percent);
  ASSERT_GE(long_restarts, 10) << "the benches show long sticking phases to judge";
  EXPECT_GE(within_most, 0.95 * long_restarts);
}

// With ideal sensors: 95 % within 2 % and all within 10 %, as the criteria ask (13 of 13 within
// 2 %, at most 0.04 %). One used to miss 2 %: at the stop the force lay 0.3 mN short of F_S- and
// relaxed to 14 mN beyond it, so the 0.4 mN by which the identified model's equilibrium force
// differed moved the crossing by 27 ms of 715 (3.9 %); the valve fit then also took in the readings
// of a carriage creeping at nm/s within a stuck phase (now only identical readings).
TEST(TableBenches, IdentifiedLongStickingPhasesAreForecastWithin2PercentWithIdealSensors) {
  check_table_benches("", 2.0, 10.0);
}

TEST(TableBenches, IdentifiedEveryLongStickingPhaseIsForecastWithin5PercentWithHilSensors) {
  check_table_benches("hil.yaml", 5.0, 5.0);
}

// Online refinement (identify::OnlineIdentifier) on benches of `pneu-sweep --bench-spread 0.2`
// (seed 1; the bench_* columns of its scenarios file): the scenario's step, every update of the
// running estimate, and the nonlinear forecast on it of every stop after the bench's 3rd restart
// against the bench's breakaways.
struct OnlineRun {
  std::vector<controller::IdentificationRecord> updates;
  Judged judged;
  int stops_forecast = 0, stops_on_a_configured_bound = 0;
  identify::Identification estimate;  ///< the running estimate at the end
};

OnlineRun learn_online(config::Config cfg, const model::PlantParams& bench, double y0_m, double y_d_m, double duration_s,
                       identify::OnlineIdentifier::Fitting fitting = identify::OnlineIdentifier::Fitting::kOnTheDrainingThread) {
  cfg.simulation.initial_position_m = y0_m;
  cfg.controller.initial_setpoint_m = y0_m;
  cfg.controller.schedule = {{1.0, y_d_m}};
  cfg.controller.duration_s = duration_s;
  cfg.controller.clock = config::ClockKind::kSimulated;
  BenchRun b(cfg, bench);
  identify::OnlineIdentifier learner(b.cfg, *b.run.runtime, identify::OnlineIdentifier::kDefaultWindow_s, fitting);
  struct Updates final : controller::RunListener {
    std::vector<controller::IdentificationRecord> records;
    void on_identification(const controller::IdentificationRecord& r) override { records.push_back(r); }
  } updates;
  b.run.runtime->add_sink(updates);
  b.execute();
  // The sweep's --online: judged after the bench's 3rd restart.
  return {updates.records, judge(b.run, b.plant, 3), learner.stops_forecast(),
          learner.stops_on_a_configured_bound(), learner.estimate()};
}

// A bench of the sweep over `base`, from its scenarios file's bench_* columns in their order: F_S+,
// F_C+, F_S-, F_C-, sigma, C_max, C_leak_in, C_leak_out, V_P0, V_N0, the null offset.
model::PlantParams sweep_bench(model::PlantParams base, const std::array<double, 11>& c) {
  base.friction.static_positive_n = c[0];
  base.friction.coulomb_positive_n = c[1];
  base.friction.static_negative_n = c[2];
  base.friction.coulomb_negative_n = c[3];
  base.friction.viscous_n_s_per_m = c[4];
  base.valve.max_conductance_m3_per_s_pa = c[5];
  base.valve.leak_conductance_in_m3_per_s_pa = c[6];
  base.valve.leak_conductance_out_m3_per_s_pa = c[7];
  base.geometry.dead_volume_p_m3 = c[8];
  base.geometry.dead_volume_n_m3 = c[9];
  base.valve.null_offset_v = c[10];
  return base;
}

std::size_t key_index(const char* key) {
  const auto& keys = controller::kIdentifiedParameterKeys;
  return static_cast<std::size_t>(
      std::find_if(keys.begin(), keys.end(), [&](const char* k) { return std::string(k) == key; }) -
      keys.begin());
}

// Scenario 146 of the 200-step sweep identified first, with hil.yaml's sensors: the run's record
// ends while the force rises at 24 N/s past F_S+ (44.50 N), and the carriage's onset hides in the
// rest band for the last 40 ms. Those readings counted as held, a force of 45.05 N that F_S+ would
// have to exceed, and the estimate, held within that bracket, was its end: 45.05 +- 0.03 N,
// where the breakaways' onsets said 44.52 N (a 0.87 s sticking phase then forecast 4.3 % off).
TEST(IdentificationRun, TheRecordsLastMillisecondsMayHideAnOnsetAndHoldNoForceWithHilSensors) {
  Bench b = mismatched("hil.yaml");
  b.bench = sweep_bench(b.bench, {44.500291961563704, 38.380250694636089, -45.867621604461213, -34.91122894914546,
                                  57.07722501318694, 1.3774425632023336e-08, 8.7189465758625518e-10,
                                  1.0437376006382673e-09, 1.1863763291535864e-05, 1.1368737648551975e-05,
                                  0.020500094310924366});
  b.cfg.simulation.initial_position_m = -0.2234333852332154;
  const identify::Identification id = run_identification(b);
  print(id, b.bench);
  for (const char* key : {"plant.friction.static_positive_n", "plant.friction.static_negative_n"}) {
    const identify::Estimate& e = id.at(key);
    ASSERT_TRUE(e.identified) << key << ": " << e.basis;
    EXPECT_LE(std::abs(e.value - truth(b.bench, key)), 3 * e.std) << key << ": " << e.value << " +- " << e.std;
  }
  EXPECT_LE(id.evidence.held_positive_n, b.bench.friction.static_positive_n) << "no force beyond F_S+ held";
}

// A scenario of a `pneu-sweep --bench-spread 0.2` sweep: its number, its bench (the scenarios file's
// bench_* columns, as sweep_bench takes them) and its step.
struct Scenario {
  int number;
  std::array<double, 11> bench;
  double y0_m, y_d_m;
};

// Every valve and volume parameter that the updates of `r` published as identified lies within 3 of
// its stated sigmas of the bench's; returns how many were published.
int valve_parameters_within_3_sigma(const OnlineRun& r, const model::PlantParams& bench, int scenario) {
  const std::pair<const char*, double> valves[] = {
      {"plant.valve.max_conductance_m3_per_s_pa", bench.valve.max_conductance_m3_per_s_pa},
      {"plant.valve.leak_conductance_in_m3_per_s_pa", bench.valve.leak_conductance_in_m3_per_s_pa},
      {"plant.valve.leak_conductance_out_m3_per_s_pa", bench.valve.leak_conductance_out_m3_per_s_pa},
      {"plant.valve.null_offset_v", bench.valve.null_offset_v},
      {"plant.geometry.dead_volume_p_m3", bench.geometry.dead_volume_p_m3},
      {"plant.geometry.dead_volume_n_m3", bench.geometry.dead_volume_n_m3}};
  int published = 0;
  for (const auto& u : r.updates)
    for (const auto& [key, truth] : valves) {
      const std::size_t i = key_index(key);
      if (!u.identified[i]) continue;
      ++published;
      // The conductances and volumes are fitted as logarithms: their sigma is relative.
      const bool offset = std::string(key) == "plant.valve.null_offset_v";
      const double error_in_sigmas = offset ? std::abs(u.value[i] - truth) / u.sigma[i]
                                            : std::abs(std::log(u.value[i] / truth)) / (u.sigma[i] / u.value[i]);
      EXPECT_LE(error_in_sigmas, 3.0) << "scenario " << scenario << ", " << key << " at " << u.t_s
                                      << " s: " << u.value[i] << " +- " << u.sigma[i] << ", bench " << truth;
    }
  return published;
}

// Scenario 190 with hil.yaml's sensors: a step from -130 mm to 208 mm, near the stroke's end, where
// the carriage sticks for half a second at a time. The valve fit is not convex: started from the
// configured model alone, the fit over these stuck phases settled on a null offset of 27 to 50 mV
// for this bench's 92 mV (and dead volumes 40 % low) from 2.5 s to 4 s, and the long sticking phase
// at 3.35 s was forecast 72 % off. Started from an earlier fit too (the running estimate first,
// now the last fit with every parameter free), it keeps what it had identified: the null offset
// and V_P0, where identified, within 3 of their stated sigmas of the bench's (the offset's sigma
// is 10 mV at most, or it is not identified).
TEST(OnlineIdentification, KeepsTheValvesItIdentifiedNearTheStrokesEndWithHilSensors) {
  const config::Config cfg =
      config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const model::PlantParams bench =
      sweep_bench(config::simulated_bench(cfg),
                  {51.4346, 41.5546, -48.7893, -43.7132, 50.3059, 1.44733e-08, 8.79404e-10,
                   1.15749e-09, 9.81443e-06, 1.09907e-05, 0.0921853});
  const OnlineRun r = learn_online(cfg, bench, -0.129596, 0.208150, 4.0);
  const std::size_t offset = key_index("plant.valve.null_offset_v"),
                    volume_p = key_index("plant.geometry.dead_volume_p_m3");
  int identified = 0;
  for (const auto& u : r.updates) {
    if (!u.identified[offset]) continue;
    ++identified;
    EXPECT_NEAR(u.value[offset], bench.valve.null_offset_v, 3.0 * u.sigma[offset])
        << "the update at " << u.t_s << " s";
    if (u.identified[volume_p]) {
      EXPECT_NEAR(u.value[volume_p], bench.geometry.dead_volume_p_m3, 3.0 * u.sigma[volume_p])
          << "the update at " << u.t_s << " s";
    }
  }
  EXPECT_GE(identified, 5) << "of " << r.updates.size() << " updates";
  EXPECT_LE(r.judged.worst_percent, 5.0) << r.judged.long_restarts << " long restarts";
}

// The fit on the learner's own thread (pneud's, on the real clock): on the simulated clock the run
// waits for each update (execute), so that the run is the same as with the fit made within the
// stop's event: the same updates, to the last bit, and the same forecasts. (Scenario 190, as above.)
TEST(OnlineIdentification, FittedOnItsOwnThreadASimulatedRunMakesTheSameUpdatesAndForecasts) {
  const config::Config cfg =
      config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const model::PlantParams bench =
      sweep_bench(config::simulated_bench(cfg),
                  {51.4346, 41.5546, -48.7893, -43.7132, 50.3059, 1.44733e-08, 8.79404e-10,
                   1.15749e-09, 9.81443e-06, 1.09907e-05, 0.0921853});
  const OnlineRun within = learn_online(cfg, bench, -0.129596, 0.208150, 4.0);
  const OnlineRun own = learn_online(cfg, bench, -0.129596, 0.208150, 4.0,
                                     identify::OnlineIdentifier::Fitting::kOnItsOwnThread);
  ASSERT_GE(within.updates.size(), 5u);
  ASSERT_EQ(own.updates.size(), within.updates.size());
  for (std::size_t k = 0; k < own.updates.size(); ++k) {
    EXPECT_EQ(own.updates[k].t_s, within.updates[k].t_s);
    EXPECT_EQ(own.updates[k].updates, within.updates[k].updates);
    for (std::size_t i = 0; i < controller::kIdentifiedParameterKeys.size(); ++i) {
      EXPECT_EQ(own.updates[k].value[i], within.updates[k].value[i]) << controller::kIdentifiedParameterKeys[i];
      EXPECT_EQ(own.updates[k].sigma[i], within.updates[k].sigma[i]) << controller::kIdentifiedParameterKeys[i];
    }
  }
  EXPECT_EQ(own.judged.errors_percent, within.judged.errors_percent);
  EXPECT_EQ(own.judged.wrong_verdicts, within.judged.wrong_verdicts);
  EXPECT_EQ(own.stops_forecast, within.stops_forecast);
  EXPECT_EQ(own.stops_on_a_configured_bound, within.stops_on_a_configured_bound);
}

// Scenario 58 with ideal sensors: the carriage comes to rest at -95 mm with the force a few
// hundredths of a newton short of F_S-, and creeps onto the bound at nanometres per second between
// its stops. An ideal sensor reads such a creep still within a stuck phase (it does not leave by a
// micrometre), but it changes in every reading; its force, a sliding one 13 mN past F_S-, was
// counted as held and put the bracket of F_S- 5 mN off (-49.139 for -49.134), and the sticking
// phase of 0.81 s at 3.04 s was forecast 6.8 % off. Only identical readings hold a force now.
TEST(OnlineIdentification, AForceReadWhileTheCarriageCreepsIsNotHeldWithIdealSensors) {
  const config::Config cfg = config::load_string(config::default_config_yaml());
  const model::PlantParams bench =
      sweep_bench(cfg.plant, {36.919, 31.0087, -49.134, -39.3698, 52.7553, 1.91754e-08, 7.80375e-10,
                              1.13927e-09, 9.76737e-06, 9.13148e-06, -0.08478});
  const OnlineRun r = learn_online(cfg, bench, 0.036115, -0.095450, 4.0);
  const std::size_t fs = key_index("plant.friction.static_negative_n");
  int identified = 0;
  for (const auto& u : r.updates) {
    if (!u.identified[fs] || u.t_s < 2.5) continue;  // from the third breakaway towards -
    ++identified;
    EXPECT_NEAR(u.value[fs], bench.friction.static_negative_n, 0.001)
        << "the update at " << u.t_s << " s";
    EXPECT_LE(std::abs(u.value[fs] - bench.friction.static_negative_n), 3 * u.sigma[fs] + 1e-4)
        << "the uncertainty it states covers its error";
  }
  EXPECT_GE(identified, 3);
  ASSERT_GE(r.judged.long_restarts, 1);
  EXPECT_LE(r.judged.worst_percent, 2.0);
}

// Scenario 785 of the 1000-step sweep with hil.yaml's sensors (its values to 6 digits, as the
// scenarios file gave them then: it runs a little differently from the sweep's): stuck at
// 131.6 mm, the force rises at 21 N/s through this bench's F_S- (-42.84 N, its Coulomb level too:
// no Stribeck drop) at 1.56 s, and the carriage creeps off at about a millimetre per second. A
// stuck phase's reference is the running median of its readings, so it follows such a creep and
// the phase goes on; its still part ended at 1.60 s, but the forces up to there, 0.75 N past
// F_S-, counted as held: the forces held put F_S- below -43.55 N, beyond the bench. The onset that
// may hide in the rest band now ends the held forces before the still part's end too, as it does
// before a breakaway.
TEST(OnlineIdentification, AForceReadAfterTheCarriageCreptOffIsNotHeldWithHilSensors) {
  config::Config cfg = config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const model::PlantParams bench =
      sweep_bench(config::simulated_bench(cfg),
                  {49.065, 34.4141, -42.8394, -42.8394, 63.7705, 1.71876e-08, 7.32283e-10, 1.43308e-09,
                   8.59638e-06, 8.65878e-06, -0.0425883});
  cfg.simulation.initial_position_m = cfg.controller.initial_setpoint_m = 0.139927;
  cfg.controller.schedule = {{1.0, 0.131330}};
  cfg.controller.duration_s = 1.675;  // the stop that followed the creep
  cfg.controller.clock = config::ClockKind::kSimulated;
  BenchRun b(cfg, bench);
  struct Record final : controller::RunListener {
    std::vector<identify::Sample> samples;
    void on_tick(const controller::TickRecord& t, const controller::ExpectedAtTick&) override {
      samples.push_back(identify::sample_of(t));
    }
  } record;
  b.run.runtime->add_sink(record);
  b.execute();
  identify::Options o = identify::options_for(b.cfg);
  o.min_fit_phase_s = o.min_stuck_s;  // as online
  const identify::Identification id = identify::identify(record.samples, b.cfg.plant, o);
  EXPECT_GE(id.evidence.held_negative_n, bench.friction.static_negative_n)
      << "a force beyond the bench's F_S- counted as held";
  EXPECT_LE(id.evidence.held_negative_n, bench.friction.static_negative_n + 0.5)
      << "the forces held up to the creep still bound it";
}

// Scenario 802 of the 1000-step sweep with hil.yaml's sensors: its first three restarts, all
// towards -, are fast ones, and the onset fits of fast breakaways spread by newtons; their mean put
// F_S- at -45.084 N, inside the -45.131 N the carriage had held (bench: -45.128 N). At the sixth
// stop the force stood at -45.13 N and relaxed away from the bound, and the forecast said "restart
// at once": wrong. The forces held and the breakaways' readings bound F_S whatever the fits say;
// the estimate now stays within them.
TEST(OnlineIdentification, AStictionEstimateStaysWithinTheForcesHeldWithHilSensors) {
  const config::Config cfg =
      config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const model::PlantParams bench =
      sweep_bench(config::simulated_bench(cfg),
                  {46.14105910438068, 39.925974454745933, -45.12807586594348, -36.885359633264052,
                   70.212233964024932, 1.6708617027087791e-08, 7.5567582154922007e-10, 1.5355372722224406e-09,
                   1.0958295718093995e-05, 8.0895372787818115e-06, 0.055183083735767413});
  const OnlineRun r = learn_online(cfg, bench, 0.19194636381267791, 0.13915000000000002, 8.0);
  EXPECT_EQ(r.judged.wrong_verdicts, 0);
  const std::size_t fs = key_index("plant.friction.static_negative_n");
  int identified = 0;
  for (const auto& u : r.updates) {
    if (!u.identified[fs]) continue;
    ++identified;
    EXPECT_LE(std::abs(u.value[fs] - bench.friction.static_negative_n), 3 * u.sigma[fs])
        << "the update at " << u.t_s << " s: " << u.value[fs] << " +- " << u.sigma[fs];
  }
  EXPECT_GE(identified, 3);
}

// Online, few short stuck phases near one position cannot tell the dead volumes apart from the
// conductances, nor, then, the null offset from them: the estimate keeps the configured value of
// what it cannot separate and fits the rest around it, which then makes up for it. Forecast on that
// mixture, scenario 279 of the 1000-step sweep with ideal sensors (stops over 2 mm at -101.5 mm;
// the volumes kept at the configured 1e-5 m^3 for 9.5e-6 and 1.09e-5, the null offset 0.66 mV off)
// forecast a force settling 0.18 N beyond F_S+ to cross it after 0.51 s, for 1.37 s; scenario 457
// (V_P0 at 1.9e-5 from an earlier fit, kept beside conductances fitted around 1e-5) forecast a
// restart at a stop whose force relaxed away from the bound. The forecasts now use the valve fit's
// mode with every parameter free, which predicts the pressures best.
TEST(OnlineIdentification, ForecastsOnTheValveFitWithEveryParameterFreeWithIdealSensors) {
  const config::Config cfg = config::load_string(config::default_config_yaml());
  const model::PlantParams bench279 =
      sweep_bench(cfg.plant, {45.309761702482831, 31.840203195055416, -41.862351075674745, -38.726620372990332,
                              55.53466897576412, 1.6456354266608132e-08, 9.1497662538576906e-10,
                              1.2804851431090616e-09, 9.4599831790997561e-06, 1.0879948720083388e-05,
                              -0.006500849472251791});
  const OnlineRun r279 = learn_online(cfg, bench279, -0.15957652298582517, -0.10143000000000002, 5.0);
  ASSERT_GE(r279.judged.long_restarts, 1);
  EXPECT_LE(r279.judged.worst_percent, 2.0);
  EXPECT_EQ(r279.judged.wrong_verdicts, 0);
  const model::PlantParams bench457 =
      sweep_bench(cfg.plant, {36.505422679388424, 32.266749448259901, -40.687360565726529, -40.687360565726529,
                              53.663198731931139, 1.7320962094390984e-08, 9.3733174113380861e-10,
                              1.4460566453058506e-09, 9.6021793927894829e-06, 1.0003646727646311e-05,
                              0.011067546112794459});
  const OnlineRun r457 = learn_online(cfg, bench457, -0.19499690683792847, -0.019549999999999984, 4.0);
  EXPECT_EQ(r457.judged.wrong_verdicts, 0);
}

// Scenarios 457 and 825 of the 1000-step sweep with ideal sensors, a few short stops near one
// position. Three faults made the valve estimate published on LCM wrong by many of its own sigmas:
// - The fit's first Gauss-Newton step took the dead volumes from 1e-5 to 2e-8 m3, where the
//   pressures no longer depend on them, and it then crawled for its 100 iterations: 244 Pa rms on
//   457 with the bench 17 % away (the bench itself fits to 0.0 Pa). A step now moves no parameter
//   by more than its prior's spread.
// - On 825 the null offset, 81 +- 11 mV with everything free, was held at the configured 0 (1 sigma
//   over 10 mV), and the rest refitted around it: V_N0 published at 6.2e-6 +- 10 % for a bench of
//   1.15e-5. A refitted parameter's sigma now counts the shift that holding the others causes.
// - Later fits of 825, started from the configured model and from that running estimate, settled
//   with the conductances 11x the bench's, and the null offset alone, refitted, came out -106 +-
//   1.2 mV for a bench of +83 mV. The fit now starts from the configured model and from the last
//   fit with every parameter free, and finds the bench (0.0 Pa rms).
TEST(OnlineIdentification,
     EveryValveParameterPublishedStatesAnUncertaintyThatCoversItsErrorWithIdealSensors) {
  const config::Config cfg = config::load_string(config::default_config_yaml());
  const Scenario scenarios[] = {
      {457,
       {36.505422679388424, 32.266749448259901, -40.687360565726529, -40.687360565726529,
        53.663198731931139, 1.7320962094390984e-08, 9.3733174113380861e-10, 1.4460566453058506e-09,
        9.6021793927894829e-06, 1.0003646727646311e-05, 0.011067546112794459},
       -0.19499690683792847, -0.019549999999999984},
      {825,
       {44.948024138161621, 37.425516977111258, -49.929382021311859, -35.000263044919947,
        62.48567506036914, 1.4838972086052981e-08, 8.9102429096722629e-10, 1.082836927353698e-09,
        8.6987713255625507e-06, 1.1451862293864732e-05, 0.082561709270679184},
       -0.059058664308763387, 0.14973}};
  for (const Scenario& sc : scenarios) {
    const model::PlantParams bench = sweep_bench(cfg.plant, sc.bench);
    const OnlineRun r = learn_online(cfg, bench, sc.y0_m, sc.y_d_m, 6.0);
    EXPECT_GE(valve_parameters_within_3_sigma(r, bench, sc.number), 4) << "scenario " << sc.number;
    ASSERT_FALSE(r.updates.empty());
    EXPECT_TRUE(r.updates.back().identified[key_index("plant.valve.null_offset_v")])
        << "scenario " << sc.number << ": the null offset";
    EXPECT_EQ(r.judged.wrong_verdicts, 0) << "scenario " << sc.number;
    // What is still not identified says why in the last valve fit's words, not the first update's
    // (which fitted no valve: "not refitted").
    const identify::Estimate& volume_p = r.estimate.at("plant.geometry.dead_volume_p_m3");
    if (!volume_p.identified) {
      EXPECT_EQ(volume_p.basis.find("not refitted"), std::string::npos) << volume_p.basis;
    }
  }
}

// Scenarios 1, 32, 53, 55 and 61 of the 1000-step sweep with hil.yaml's sensors (few stuck phases,
// near the stroke's ends). Each phase's integration starts from its first readings, whose noise
// (20 Pa) stays in the phase for seconds: fitted with those starts taken as exact, the valves and
// dead volumes absorbed it, and scenario 1 published C_max, both leaks and both dead volumes 6 to 8
// sigma off the bench (V_N0 1.5e-5 +- 0.09e-5 for 0.95e-5); 53 and 61, the dead volumes and the
// null offset 6 to 11 sigma off. The starts are now fitted too. And the last milliseconds of a
// phase that a slow breakaway ends, where the carriage already moves within the rest band
// (scenario 32, 36 mm from the stroke's end): taken for still, they put V_N0 120 sigma off; the
// valve fit now stops where the breakaway's onset could begin.
TEST(OnlineIdentification, EveryValveParameterPublishedStatesAnUncertaintyThatCoversItsErrorWithHilSensors) {
  const config::Config cfg =
      config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const Scenario scenarios[] = {
      {1,
       {38.752116412819461, 38.752116412819461, -41.704946085707007, -41.704946085707007, 66.696933592672522,
        1.7672412535693666e-08, 7.7766762437047888e-10, 1.0612277370014462e-09, 1.1702829800241265e-05,
        9.4737201434766173e-06, 0.087889106718404761},
       -0.2203288549283056, -0.22931},
      {53,
       {39.685631453417649, 34.138159394842738, -43.42933592754526, -42.307994930347263, 51.272693982607848,
        1.6111667532841367e-08, 9.1569783969897806e-10, 1.1973741732160277e-09, 8.9857325051106241e-06,
        9.5152922484308569e-06, -0.095785610995236858},
       -0.1869507477093554, -0.20539000000000002},
      {61,
       {48.442782837349938, 38.763723565685673, -53.372626193848504, -41.752564712203117, 62.018749183214567,
        1.7437087755518966e-08, 7.3044077520368976e-10, 1.045120883911704e-09, 9.9370060787503858e-06,
        9.240420922463371e-06, -0.028911167589706022},
       -0.1331981639528442, -0.20171},
      {32,
       {45.195654629703427, 31.315625290937497, -59.980321542393014, -45.060189600871425, 58.779546004359098,
        1.5799011317451837e-08, 8.6573247122896437e-10, 1.1554751008993601e-09, 9.1163520302343735e-06,
        9.6786765405316142e-06, 0.040603675917871396},
       0.18040025439248628, -0.21505000000000002},
      {55,
       {47.616345475019131, 34.366146219959205, -41.533342091385379, -35.557826908071917, 64.129705076225378,
        1.863584650985745e-08, 6.5163243403772336e-10, 1.1660554438246244e-09, 1.0356000799871654e-05,
        8.749679398242333e-06, 0.080390767879992664},
       -0.21518234735090214, -0.20447}};
  int published = 0;
  for (const Scenario& sc : scenarios) {
    const model::PlantParams bench = sweep_bench(config::simulated_bench(cfg), sc.bench);
    const OnlineRun r = learn_online(cfg, bench, sc.y0_m, sc.y_d_m, 12.0);
    published += valve_parameters_within_3_sigma(r, bench, sc.number);
    // What the summary prints: the last valve fit's figures, also where the last window fitted none.
    EXPECT_GT(r.estimate.evidence.fitted_phases, 0) << "scenario " << sc.number;
    EXPECT_GT(r.estimate.evidence.pressure_rms_residual_pa, 15.0) << "scenario " << sc.number << ": 20 Pa of noise";
  }
  EXPECT_GE(published, 20);
}

// Scenario 175 with hil.yaml's sensors: the set-point step's breakaway, the force rising at 4000 N/s,
// is the only one towards + for the first 1.4 s. Dated by its onset within the rest band, it put
// F_S+ at 48.1 N for a bench of 45.2 N, and said +- 0.02 N: a single fit has no spread to show.
// Alone, it is now taken as good to how far the force moved on while the onset hid (43 N), so F_S+
// stays the configured one until slower breakaways bound it; whatever is identified states an
// uncertainty that covers its error.
TEST(OnlineIdentification, ASingleFastBreakawaysStictionStatesAnUncertaintyThatCoversItsError) {
  const config::Config cfg =
      config::load_file(pneu::test::hil_yaml(), kSweepsHil);
  const model::PlantParams bench =
      sweep_bench(config::simulated_bench(cfg),
                  {45.1792, 34.0915, -56.1286, -33.1991, 57.1752, 1.46683e-08, 9.52179e-10,
                   1.07523e-09, 9.27603e-06, 1.05456e-05, -0.0780062});
  const OnlineRun r = learn_online(cfg, bench, -0.002159, 0.173650, 4.0);
  int identified = 0;
  for (const char* key : {"plant.friction.static_positive_n", "plant.friction.static_negative_n"}) {
    const std::size_t i = key_index(key);
    const double truth = i == key_index("plant.friction.static_positive_n")
                             ? bench.friction.static_positive_n
                             : bench.friction.static_negative_n;
    for (const auto& u : r.updates) {
      if (!u.identified[i]) continue;
      ++identified;
      EXPECT_LE(std::abs(u.value[i] - truth), 3 * u.sigma[i])
          << key << " at " << u.t_s << " s: " << u.value[i] << " +- " << u.sigma[i] << ", bench "
          << truth;
    }
  }
  EXPECT_GE(identified, 5);
}

// Scenario 64 with ideal sensors: a step down to -82 mm whose first three restarts all go towards
// -; the fourth stop's force then relaxes towards + and the carriage restarts that way after 2 s.
// Nothing the bench did bounds F_S+ from beyond, so that forecast is the configured F_S+'s (45 N
// for a bench of 52 N) and 32 % off; pneud counts it as such. Once it has broken away towards +,
// the next long sticking phase that way is forecast within 2 %.
TEST(OnlineIdentification, SaysWhichStopsItForecastOnAStictionBoundNotYetIdentified) {
  const config::Config cfg = config::load_string(config::default_config_yaml());
  const model::PlantParams bench =
      sweep_bench(cfg.plant, {51.993, 33.9523, -55.6725, -33.2501, 61.3379, 1.29855e-08,
                              6.41254e-10, 1.26675e-09, 1.08034e-05, 8.34188e-06, -0.0414754});
  const OnlineRun r = learn_online(cfg, bench, 0.029746, -0.081650, 7.0);
  ASSERT_EQ(r.judged.long_restarts, 2);
  EXPECT_GT(r.judged.errors_percent[0], 10.0) << "on the configured F_S+";
  EXPECT_LE(r.judged.errors_percent[1], 2.0) << "on the F_S+ its first breakaway that way bounded";
  EXPECT_GE(r.stops_on_a_configured_bound, 1) << "of " << r.stops_forecast << " stops";
  EXPECT_LT(r.stops_on_a_configured_bound, r.stops_forecast);
}

}  // namespace
