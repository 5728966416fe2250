// One assembly (controller/assembly): the run's specification derived once from the configuration,
// and the run built on it owning what it refers to.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "pneu/assembly/assembled_run.hpp"
#include "pneu/config/config.hpp"
#include "pneu/controller/session.hpp"
#include "support/simulated_run.hpp"

namespace {

using namespace pneu;

struct TickLog final : controller::RunListener {
  std::vector<double> u_v;
  void on_tick(const controller::TickRecord& tick, const controller::ExpectedAtTick&) override { u_v.push_back(tick.u_v); }
};

}  // namespace

TEST(RunSpec, ResolvesUZeroInACopyOfItsOwnLeavingTheConfigurationHandedInAsItWas) {
  const config::Config loaded = config::load_string(config::default_config_yaml());
  ASSERT_TRUE(loaded.controller.offset_auto);
  const double as_loaded = loaded.controller.law.offset_v;
  const assembly::RunSpec spec = assembly::RunSpec::of(loaded);
  EXPECT_EQ(loaded.controller.law.offset_v, as_loaded) << "the configuration handed in is not changed";
  EXPECT_EQ(spec.u_0_v(), spec.equilibrium_voltage_v()) << "auto: u_0 = u_e of Eq. 7";
  EXPECT_EQ(spec.config().controller.law.offset_v, spec.u_0_v());
  EXPECT_EQ(spec.law().params().offset_v, spec.u_0_v()) << "the law designed with it";
  EXPECT_NEAR(spec.u_0_v(), -0.1925, 5e-5);  // docs/model.md: the default bench
  // A fixed offset stays as given.
  const assembly::RunSpec fixed =
      assembly::RunSpec::of(config::load_string(config::default_config_yaml(), {"controller.law.offset_v=0.1"}));
  EXPECT_EQ(fixed.u_0_v(), 0.1);
}

TEST(RunSpec, ReconfiguredChangesWhatTheRunDoesAndRefusesAChangeOfWhatUZeroWasDerivedFrom) {
  const assembly::RunSpec spec = assembly::RunSpec::of(config::load_string(config::default_config_yaml()));
  const assembly::RunSpec longer = spec.reconfigured([](config::Config& c) { c.controller.duration_s = 30.0; });
  EXPECT_EQ(longer.config().controller.duration_s, 30.0);
  EXPECT_NE(spec.config().controller.duration_s, 30.0) << "the original stays as it was";
  EXPECT_EQ(&longer.valve(), &spec.valve()) << "the valve characteristic shared";
  EXPECT_EQ(longer.u_0_v(), spec.u_0_v());
  EXPECT_THROW((void)spec.reconfigured([](config::Config& c) { c.controller.law.offset_v += 0.01; }),
               std::invalid_argument);
  EXPECT_THROW((void)spec.reconfigured([](config::Config& c) { c.controller.predictor.valve_table = "other.csv"; }),
               std::invalid_argument);
}

TEST(AssembledRun, OwnsTheValveItsForecastsUseSoThatTheSpecificationItWasBuiltFromMayGo) {
  // The specification is a temporary: the run keeps what its runtime forecasts with.
  assembly::AssembledRun run = assembly::AssembledRun::on_simulated_bench(
      assembly::RunSpec::of(config::load_string(config::default_config_yaml())));
  EXPECT_EQ(run.runtime().model().valve, &run.spec().valve());
  ASSERT_NE(run.simulated_bench(), nullptr);
  assembly::AssembledRun moved = std::move(run);  // held by pointer: moving keeps it in place
  test::execute_simulated(moved);
  ASSERT_FALSE(moved.runtime().stops().empty());
  int forecast = 0;
  for (const auto& stop : moved.runtime().stops()) forecast += stop.nonlinear ? 1 : 0;
  EXPECT_GT(forecast, 0);
}

TEST(AssembledRun, WithoutForecastsRunsTheSameLoopAndForecastsNothing) {
  const assembly::RunSpec spec = assembly::RunSpec::of(config::load_string(config::default_config_yaml()));
  assembly::AssembledRun forecasting = assembly::AssembledRun::on_simulated_bench(spec);
  assembly::AssembledRun recording = assembly::AssembledRun::on_simulated_bench(spec, {.forecasts = false});
  const TickLog& a = forecasting.emplace_sink<TickLog>();
  const TickLog& b = recording.emplace_sink<TickLog>();
  test::execute_simulated(forecasting);
  test::execute_simulated(recording);
  ASSERT_EQ(a.u_v.size(), 12001u);
  EXPECT_TRUE(a.u_v == b.u_v) << "the loop, and so its records, the same";
  ASSERT_FALSE(recording.runtime().stops().empty());
  for (const auto& stop : recording.runtime().stops()) {
    EXPECT_FALSE(stop.linearized);
    EXPECT_FALSE(stop.nonlinear);
  }
}
