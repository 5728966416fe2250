// pneu-plant as a user runs it: the open-loop simulator's file contract, valve characterisation,
// and bad input refused with exit code 2, a message naming the place, and no output left behind.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "pneu/model/valve_table.hpp"
#include "pneu/sim_plant/plant.hpp"

#include "support/child_process.hpp"
#include "support/paths.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;

namespace {

struct Outcome {
  int exit_code;
  std::string out;
  std::string err;
};

using pneu::test::slurp;

class PneuPlantCli : public ::testing::Test {
 protected:

  Outcome run(const std::string& args) const {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    const std::string cmd = std::string(PNEU_BINARY_DIR) + "/bin/pneu-plant " + args + " >" +
                            out.string() + " 2>" + err.string();
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(out), slurp(err)};
  }
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p;
  }
  // Nothing but the inputs and our captured streams remain in the directory.
  std::vector<std::string> leftovers() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const auto n = e.path().filename().string();
      if (n != "stdout.txt" && n != "stderr.txt" && n.rfind("in", 0) != 0) names.push_back(n);
    }
    return names;
  }
  static std::vector<std::vector<double>> rows(const std::string& csv, std::string* header) {
    std::vector<std::vector<double>> out;
    std::stringstream ss(csv);
    std::string line;
    std::getline(ss, *header);
    while (std::getline(ss, line)) {
      std::vector<double> r;
      std::stringstream ls(line);
      for (std::string cell; std::getline(ls, cell, ',');) r.push_back(std::stod(cell));
      out.push_back(r);
    }
    return out;
  }

  pneu::test::TestDir dir_{"pneu_cli_"};
};

std::string constant_input(double u, int samples, double dt) {
  std::string s = "t,u\n";
  for (int i = 0; i < samples; ++i) s += std::to_string(i * dt) + "," + std::to_string(u) + "\n";
  return s;
}

}  // namespace

TEST_F(PneuPlantCli, PrintsItsVersionAndHelpForEveryCommand) {
  const Outcome v = run("--version");
  EXPECT_EQ(v.exit_code, 0);
  EXPECT_THAT(v.out, HasSubstr("pneu-plant 0."));
  for (const char* cmd : {"--help", "simulate --help", "characterize-valve --help", "tune --help"}) {
    const Outcome h = run(cmd);
    EXPECT_EQ(h.exit_code, 0) << cmd;
    EXPECT_THAT(h.out, HasSubstr("--config")) << cmd;
  }
}

TEST_F(PneuPlantCli, SimulateWritesOneRowPerSampleTakenBeforeTheSamplesInputIsApplied) {
  // u steps from -0.19 V (near u_e: F inside the stiction band, at rest) to +2 V at the third
  // sample: the carriage must still be at rest in row 3, because each row is the state at its
  // own time, before its own input takes effect.
  const auto in = write("in.csv", "t,u\n0,-0.19\n0.01,-0.19\n0.02,2\n0.03,2\n0.04,2\n");
  const fs::path out = dir_ / "traj.csv";
  const Outcome r = run("simulate --input " + in.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string header;
  const auto data = rows(slurp(out), &header);
  EXPECT_EQ(header, "t,y,v,p_p,p_n,force,stuck,u");
  ASSERT_EQ(data.size(), 5u);
  EXPECT_DOUBLE_EQ(data[2][0], 0.02);

  // The same run with the model directly: initial pressures at p_null(u), p_null(-u) of the first
  // sample, input held between samples.
  const pneu::model::PlantParams params;  // == config/sim.yaml (the embedded default)
  pneu::plant::Plant plant(params);
  plant.reset_at_rest(0.2195, -0.19);
  EXPECT_NEAR(data[0][3], plant.valve().null_pressure_pa(-0.19), 1e-3);
  EXPECT_NEAR(data[0][4], plant.valve().null_pressure_pa(0.19), 1e-3);
  const double u[] = {-0.19, -0.19, 2, 2};
  for (int i = 0; i < 4; ++i) {
    EXPECT_NEAR(data[static_cast<std::size_t>(i)][1], plant.state().y_m, 1e-9) << "row " << i;
    EXPECT_NEAR(data[static_cast<std::size_t>(i)][3], plant.state().p_p_pa, 1e-3) << "row " << i;
    plant.step(0.01, u[i]);
  }
  EXPECT_NEAR(data[4][1], plant.state().y_m, 1e-9);
  EXPECT_EQ(data[2][6], 1.0) << "still stuck at the sample where the step is applied";
  EXPECT_EQ(data[2][1], 0.2195);
  EXPECT_GT(data[4][1], 0.2195) << "the +2 V step moves the carriage";
  EXPECT_THAT(r.out, HasSubstr("5 samples"));
}

// hal.sim.plant: the simulated bench runs its own parameters, laid over plant:.
TEST_F(PneuPlantCli, SimulateRunsTheBenchOfHalSimPlant) {
  const auto in = write("in.csv", "t,u\n0,-0.19\n0.01,-0.19\n");
  const fs::path out = dir_ / "traj.csv";
  const Outcome model = run("simulate --input " + in.string() + " --out " + out.string());
  ASSERT_EQ(model.exit_code, 0) << model.err;
  EXPECT_THAT(model.out, HasSubstr("stiction band [-50.0, 45.0] N"));
  const Outcome bench = run("simulate --input " + in.string() + " --out " + out.string() +
                            " --set hal.sim.plant.friction.static_negative_n=-60");
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  EXPECT_THAT(bench.out, HasSubstr("stiction band [-60.0, 45.0] N"));
}

TEST_F(PneuPlantCli, SimulateAddsSensorReadingsOnRequest) {
  const auto in = write("in.csv", constant_input(-0.19, 3, 0.001));
  const fs::path out = dir_ / "traj.csv";
  const Outcome r = run("simulate --sensors --quiet --set sensors.position.adc_bits=12 --input " +
                    in.string() + " --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(r.out.empty());
  std::string header;
  const auto data = rows(slurp(out), &header);
  EXPECT_EQ(header, "t,y,v,p_p,p_n,force,stuck,u,y_meas,p_p_meas,p_n_meas");
  // 12 bits over 10 V at 20 V/m: one step is 0.122 mm; the reading is within half a step.
  EXPECT_NEAR(data[0][8], data[0][1], 0.5 * 10.0 / 4095.0 / 20.0 + 1e-12);
  EXPECT_NE(data[0][8], data[0][1]) << "quantisation must show at 219.5 mm";
}

TEST_F(PneuPlantCli, MalformedInputIsRefusedNamingTheLineAndLeavesNoOutput) {
  struct Case {
    const char* text;
    const char* expected;
  } cases[] = {
      {"time,u\n0,0\n0.1,0\n", ":1: the header must name the columns 't'"},
      {"t,u\n0,0\n0.1,zero\n", ":3: column 'u' is not a finite number: 'zero'"},
      {"t,u\n0,0\n0.1,0\n0.1,0\n", ":4: time does not increase"},
      {"t,u\n0,0\n0.1,0\n0.3,0\n", ":4: sample period"},
      {"t,u\n0,0\n0.1\n", ":3: expected 2 columns, got 1"},
      {"t,u\n0,nan\n0.1,0\n", ":2: column 'u' is not a finite number"},
      {"", "empty file"},
  };
  for (const auto& c : cases) {
    const auto in = write("in.csv", c.text);
    const fs::path out = dir_ / "traj.csv";
    const Outcome r = run("simulate --input " + in.string() + " --out " + out.string());
    EXPECT_EQ(r.exit_code, 2) << c.text;
    EXPECT_THAT(r.err, HasSubstr(c.expected)) << c.text;
    EXPECT_FALSE(fs::exists(out)) << c.text;
    EXPECT_THAT(leftovers(), ::testing::IsEmpty()) << c.text;
  }
}

TEST_F(PneuPlantCli, ConfigErrorsNameTheKeyAndTheReason) {
  const auto in = write("in.csv", constant_input(0.0, 3, 0.001));
  const fs::path out = dir_ / "traj.csv";
  const std::string io = " --input " + in.string() + " --out " + out.string();

  Outcome r = run("simulate --set plant.mass_kg=-3" + io);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("plant.mass_kg: must be > 0 (got -3)"));

  r = run("simulate --set plant.geometry.rod_diameter_m=0.04" + io);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("plant.geometry.rod_diameter_m: must be smaller than"));

  r = run("simulate --set plant.mass=3" + io);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("plant.mass: unknown key"));

  const auto bad = write("in_bad.yaml", "plant:\n  mass_kg: 17\n");
  r = run("simulate --config " + bad.string() + io);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("plant.geometry: missing"));

  r = run("simulate --config " + (dir_ / "in_absent.yaml").string() + io);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("cannot open"));
  EXPECT_FALSE(fs::exists(out));
  EXPECT_THAT(leftovers(), ::testing::IsEmpty());
}

TEST_F(PneuPlantCli, BadCommandLinesExitWithTwo) {
  EXPECT_EQ(run("").exit_code, 2);
  EXPECT_EQ(run("fly").exit_code, 2);
  const Outcome r = run("simulate --out x.csv");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("missing --input"));
  EXPECT_THAT(run("simulate --frobnicate").err, HasSubstr("unknown option --frobnicate"));
  EXPECT_THAT(run("characterize-valve --out t.csv --voltage-step-v -1").err,
              HasSubstr("--voltage-step-v"));
}

TEST_F(PneuPlantCli, CharacterizeValveWritesATableThePredictorCanLoad) {
  const fs::path out = dir_ / "valve.csv";
  const Outcome r = run("characterize-valve --voltage-step-v 0.5 --pressure-step-pa 10000 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto table = pneu::model::ValveTable::load(out);
  // -10..10 V by 0.5 V holds 0 and both ends; 1e5..7e5 Pa by 1e4 Pa.
  EXPECT_EQ(table.voltages_v().size(), 41u);
  EXPECT_EQ(table.pressures_pa().size(), 61u);
  const pneu::model::PlantParams params;
  const pneu::model::ValveModel model(params.valve, params.gas);
  for (double w : {-10.0, -0.5, 0.0, 1.5, 10.0})
    for (double p : {1.0e5, 3.5e5, 7.0e5})
      EXPECT_NEAR(table.mass_flow_kg_per_s(w, p), model.mass_flow_kg_per_s(w, p),
                  1e-15 + 1e-12 * std::abs(model.mass_flow_kg_per_s(w, p)))
          << "w=" << w << " p=" << p;
  EXPECT_THAT(r.out, HasSubstr("u_e (Eq. 7)"));
}

TEST_F(PneuPlantCli, NullFlowCurveIsTheEquilibriumForceOfEquation7) {
  const fs::path out = dir_ / "curve.csv";
  const Outcome r = run("null-flow --voltage-step-v 0.5 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::string header;
  const auto data = rows(slurp(out), &header);
  EXPECT_EQ(header, "u_v,p_null_p_pa,p_null_n_pa,x_n,y_n,equilibrium_force_n");
  ASSERT_EQ(data.size(), 41u);
  const pneu::model::PlantParams params;
  const pneu::model::ValveModel model(params.valve, params.gas);
  const auto& g = params.geometry;
  // The file holds 10 significant digits: forces of a few hundred newtons to about 1e-7 N.
  for (const auto& row : data) {
    EXPECT_NEAR(row[1], model.null_pressure_pa(row[0]), 1e-3);
    EXPECT_NEAR(row[3], g.area_p_m2() * row[1], 1e-6);
    EXPECT_NEAR(row[4], g.area_n_m2() * row[2] + g.area_rod_m2() * 1.0e5, 1e-6);
    EXPECT_NEAR(row[5], row[3] - row[4], 1e-6);
  }
  for (std::size_t i = 1; i < data.size(); ++i) EXPECT_GT(data[i][5], data[i - 1][5]) << "increasing in u";
}

// --- tune: the gains designed on the tangent-linear model, the stability map -------------------

TEST_F(PneuPlantCli, TuneRunsOnEveryShippedConfig) {
  int configs = 0;
  for (const auto& e : fs::directory_iterator(fs::path(PNEU_SOURCE_DIR) / "config")) {
    if (e.path().extension() != ".yaml") continue;
    ++configs;
    const Outcome r = run("tune --config " + e.path().string());
    EXPECT_EQ(r.exit_code, 0) << e.path() << ": " << r.err;
    EXPECT_THAT(r.out, HasSubstr("Stability map: the configured law")) << e.path();
  }
  EXPECT_GE(configs, 3);
}

TEST_F(PneuPlantCli, TuneSaysWhereThePapersGainsAreUnstableAndTheDesignedScheduleIsNot) {
  // config/paper.yaml: the paper's fixed gains, and the designed schedule beside them.
  const std::string paper = (fs::path(PNEU_SOURCE_DIR) / "config/paper.yaml").string();
  const Outcome r = run("tune --config " + paper);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("Designed gains: gains scheduled by position"));
  EXPECT_THAT(r.out, HasSubstr("fixed gains K_y 80 V/m, K_v 1.5 V/(m/s), K_a 0.002 V/(m/s^2)"));
  // Every 25 mm: unstable everywhere but at the two ends (docs/model.md), and stable everywhere designed.
  EXPECT_THAT(r.out, HasSubstr("unstable, continuous: [-225, 225] mm; sampled: [-225, 225] mm"));
  EXPECT_THAT(r.out, HasSubstr("unstable, continuous: nowhere; sampled: nowhere"));
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("note:")));
  // The embedded sim.yaml drives the designed schedule: one map, stable everywhere.
  const Outcome designed = run("tune");
  ASSERT_EQ(designed.exit_code, 0) << designed.err;
  EXPECT_THAT(designed.out, HasSubstr("Stability map: the configured law, gains scheduled by position"));
  EXPECT_THAT(designed.out, ::testing::Not(HasSubstr("fixed gains K_y")));
  EXPECT_THAT(designed.out, HasSubstr("unstable, continuous: nowhere; sampled: nowhere"));
  // At 300 Hz the same schedule is stable on the continuous model, not on the sampled loop: refusing
  // (controller.law.design.infeasible refuse), mapped, with a note that pneud refuses it ...
  const Outcome slow = run("tune --step-mm 50 --set controller.rate_hz=300 --set controller.law.design.infeasible=refuse");
  ASSERT_EQ(slow.exit_code, 0) << slow.err;
  EXPECT_THAT(slow.out, HasSubstr("unstable, continuous: nowhere; sampled: [-200, 200] mm"));
  EXPECT_THAT(slow.out, HasSubstr("note: the designed schedule is unstable on the sampled loop: pneud refuses it"));
  // ... falling back (the default), the nodes where it fails get slower poles: said, and stable.
  const Outcome fallen_back = run("tune --step-mm 50 --set controller.rate_hz=300");
  ASSERT_EQ(fallen_back.exit_code, 0) << fallen_back.err;
  EXPECT_THAT(fallen_back.out, HasSubstr("the requested dynamics cannot be had everywhere: the gains fall back"));
  EXPECT_THAT(fallen_back.out, HasSubstr("the sampled loop is unstable (max |z| = 1.00"));
  EXPECT_THAT(fallen_back.out, HasSubstr("unstable, continuous: nowhere; sampled: nowhere"));
  EXPECT_THAT(fallen_back.out, ::testing::Not(HasSubstr("note:")));
}

TEST_F(PneuPlantCli, TuneWritesTheMapAsCsvOneRowPerLawAndPosition) {
  const fs::path out = dir_ / "map.csv";
  const Outcome r = run("tune --step-mm 50 --csv " + out.string() + " --config " +
                        (fs::path(PNEU_SOURCE_DIR) / "config/paper.yaml").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  std::stringstream ss(slurp(out));
  std::string line;
  std::getline(ss, line);
  EXPECT_EQ(line,
            "law,y_m,position_gain_v_per_m,velocity_gain_v_s_per_m,acceleration_gain_v_s2_per_m,force_gain_n_per_v_s,"
            "stiffness_n_per_m,max_real_part_1_per_s,max_abs_z,gain_margin,stable_continuous,stable_sampled,"
            "continuous_poles,sampled_poles");
  int fixed = 0, scheduled = 0, fixed_stable = 0, scheduled_stable = 0;
  while (std::getline(ss, line)) {
    std::vector<std::string> cells;
    std::stringstream ls(line);
    for (std::string cell; std::getline(ls, cell, ',');) cells.push_back(cell);
    ASSERT_EQ(cells.size(), 14u) << line;
    const bool stable = cells[10] == "1" && cells[11] == "1";
    EXPECT_EQ(std::stod(cells[7]) < 0.0, cells[10] == "1") << line;
    EXPECT_EQ(std::stod(cells[8]) < 1.0, cells[11] == "1") << line;
    if (cells[0] == "fixed") {
      ++fixed;
      fixed_stable += stable;
      EXPECT_EQ(std::stod(cells[2]), 80.0);
    } else {
      ++scheduled;
      scheduled_stable += stable;
    }
  }
  EXPECT_EQ(fixed, 11);  // -250 .. 250 mm by 50 mm
  EXPECT_EQ(scheduled, 11);
  EXPECT_EQ(fixed_stable, 2);  // the two ends
  EXPECT_EQ(scheduled_stable, 11);
}

TEST_F(PneuPlantCli, TuneRefusesBadArgumentsAndImpossibleDesignsWithExitTwoSayingWhy) {
  EXPECT_EQ(run("tune --step-mm 0").exit_code, 2);
  EXPECT_EQ(run("tune --delay-samples 1.5").exit_code, 2);
  EXPECT_THAT(run("tune --frobnicate").err, HasSubstr("unknown option --frobnicate"));
  const Outcome negative =
      run("tune --set controller.law.design.natural_frequency_rad_per_s=20 --set controller.law.design.infeasible=refuse");
  EXPECT_EQ(negative.exit_code, 2);
  EXPECT_THAT(negative.err, HasSubstr("controller.law.design"));
  EXPECT_THAT(negative.err, HasSubstr("K_v would be negative"));
  EXPECT_EQ(negative.out, "");  // refused before printing anything
  const Outcome beyond =
      run("tune --set controller.law.design.max_acceleration_gain_v_s2_per_m=0.5 --set controller.law.design.infeasible=refuse");
  EXPECT_EQ(beyond.exit_code, 2);
  EXPECT_THAT(beyond.err, HasSubstr("beyond its limit 0.5 V/(m/s^2)"));
  EXPECT_EQ(run("tune --set controller.law.design.damping=0").exit_code, 2);  // the schema: > 0
}

// --- serve: fault injection and outputs record, refused before serving --------------------------

namespace {
std::string serve_hil() { return "serve --config " + pneu::test::hil_yaml() + " --duration 0.1 "; }
}  // namespace

// serve needs libmodbus: a pneu-plant built without it (PNEU_WITH_MODBUS=OFF) refuses the command
// (tests/test_options_off.sh), and these are skipped.
class PneuPlantServe : public PneuPlantCli {
 protected:
  void SetUp() override {
#ifndef PNEU_WITH_MODBUS
    GTEST_SKIP() << "pneu-plant was built without libmodbus (PNEU_WITH_MODBUS=OFF): serve is refused";
#endif
  }
};

TEST_F(PneuPlantServe, HelpDocumentsFaultsAndTheOutputsRecord) {
  const Outcome h = run("serve --help");
  EXPECT_EQ(h.exit_code, 0);
  for (const char* text : {"--outputs FILE", "t_s,u_p_v,u_n_v", "--fault SPEC", "CHANNEL:MODE@T", "rail-low", "rail-high",
                           "raw=N", "volts=V", "freeze", "nan", "dead", "stuck=V", "tubes:swapped", "pressure_sensors:swapped",
                           "valve_p -> u_P, valve_n -> u_N",
                           "--max-clients N", "(default 4)", "owns them until it disconnects", "exception 06"})
    EXPECT_THAT(h.out, HasSubstr(text));
  EXPECT_THAT(run("--help").out, HasSubstr("[--outputs FILE] [--events FILE]"));
  EXPECT_THAT(run("--help").out, HasSubstr("[--fault CHANNEL:MODE@T ...]"));
  EXPECT_THAT(run("--help").out, HasSubstr("[--max-clients N]"));
}

TEST_F(PneuPlantServe, TakesAMaxClientsFrom1To64AndRefusesOthersBeforeServing) {
  for (const char* n : {"0", "65", "2.5", "-1"}) {
    const Outcome r = run(serve_hil() + "--max-clients=" + n + " --set hal.modbus.port=" + std::to_string(pneu::test::free_port()));
    EXPECT_EQ(r.exit_code, 2) << n;
    EXPECT_THAT(r.err, HasSubstr("--max-clients must be a whole number from 1 to 64")) << n;
    EXPECT_THAT(r.out, ::testing::Not(HasSubstr("listening"))) << n;
  }
  for (const char* n : {"1", "64"}) {
    const Outcome r = run(serve_hil() + "--max-clients " + n + " --set hal.modbus.port=" + std::to_string(pneu::test::free_port()));
    EXPECT_EQ(r.exit_code, 0) << n << ": " << r.err;
    EXPECT_THAT(r.out, HasSubstr(std::string("up to ") + n + " clients")) << n;
  }
}

TEST_F(PneuPlantServe, RefusesBadFaultSpecsNamingTheSpecAndTheReason) {
  const std::vector<std::pair<std::string, std::string>> cases{
      {"pressure_p", "expected CHANNEL:MODE@T"},
      {"pressure_p:rail-high", "missing @T"},
      {"pressure_q:rail-high@1", "unknown channel 'pressure_q'"},
      {"pressure_p:melt@1", "unknown mode 'melt'"},
      {"pressure_p:freeze@-0.5", "T must be >= 0"},
      {"pressure_p:freeze@soon", "T must be a number of seconds"},
      {"valve_p:rail-high@1", "rail-high is a sensor mode: a valve channel takes stuck=V only"},
      {"valve_n:freeze@1", "freeze is a sensor mode"},
      {"position:stuck=2@1", "stuck=V is a valve mode"},
      {"pressure_p:nan@1", "nan needs a float32 channel"},
      {"pressure_p:raw=65536@1", "raw=65536 does not fit the channel's unsigned 16-bit register"},
      {"pressure_p:raw=-1@1", "raw=-1 does not fit the channel's unsigned 16-bit register"},
      {"position:raw=7.5@1", "raw=7.5 does not fit the channel's unsigned 16-bit register (an integer"},
      {"position:raw@1", "raw needs a value"},
      {"position:volts=abc@1", "volts=abc: not a finite number of volts"},
      {"position:freeze=1@1", "freeze takes no value"},
      {"valve_p:stuck=@1", "stuck needs a value"},
      // hil.yaml's valve takes +-10 V: a spool stuck at 20 V is no fault the bench can have.
      {"valve_p:stuck=20@1", "stuck=20 is outside the valve's range [-10, 10] V (plant.valve.max_voltage_v"},
      {"valve_n:stuck=-10.5@1", "stuck=-10.5 is outside the valve's range [-10, 10] V"},
      {"tubes:freeze@0", "tubes takes swapped only"},
      {"pressure_sensors:dead@0", "pressure_sensors takes swapped only"},
      {"pressure_p:swapped@0", "swapped is for tubes and pressure_sensors only"},
      {"valve_p:dead@0", "dead is a sensor mode: a valve channel takes stuck=V only"},
  };
  for (const auto& [spec, reason] : cases) {
    const Outcome r = run(serve_hil() + "--fault '" + spec + "'");
    EXPECT_EQ(r.exit_code, 2) << spec;
    EXPECT_THAT(r.err, HasSubstr("--fault '" + spec + "': " + reason)) << spec;
    EXPECT_THAT(r.out, ::testing::Not(HasSubstr("listening"))) << spec << ": refused before serving";
  }
}

TEST_F(PneuPlantServe, TakesNanAndFloatRawValuesOnAFloat32Channel) {
  // On a float32 channel nan is a valid fault and raw=N a float (beyond a single's range it does
  // not fit). A valid spec would start serving: its acceptance shows as the --outputs refusal,
  // which comes after the faults are parsed.
  const std::string f32 = "--set hal.modbus.channels.pressure_p.format=float32 --set hal.modbus.channels.pressure_p.register=4 ";
  const Outcome nan = run(serve_hil() + f32 + "--fault pressure_p:nan@1 --outputs " + (dir_ / "no/such/dir.csv").string());
  EXPECT_EQ(nan.exit_code, 2);
  EXPECT_THAT(nan.err, ::testing::Not(HasSubstr("--fault")));
  EXPECT_THAT(nan.err, HasSubstr("--outputs"));
  const Outcome big = run(serve_hil() + f32 + "--fault pressure_p:raw=1e39@1");
  EXPECT_EQ(big.exit_code, 2);
  EXPECT_THAT(big.err, HasSubstr("does not fit the channel's float32 register"));
}

TEST_F(PneuPlantServe, RefusesAnOutputsOrEventsFileItCannotOpenBeforeServing) {
  for (const std::string option : {"--outputs", "--events"}) {
    const Outcome r = run(serve_hil() + option + " " + (dir_ / "no/such/dir/file").string());
    EXPECT_EQ(r.exit_code, 2) << option;
    EXPECT_THAT(r.err, HasSubstr(option + " " + (dir_ / "no/such/dir/file").string() + ": cannot open for writing"));
    EXPECT_THAT(r.out, ::testing::Not(HasSubstr("listening")));
  }
}

// Issue 29, item 12: every option a command accepts is in its help, and serve's in the usage
// pneu-plant --help prints. The accepted options are read from the command's cli::Args in the
// source, so an option added there and not to the help fails here.
namespace {

// The quoted names of each `cli::Args args(argc, argv, 2, {...}, {...}[, {...}])` in `source`, in order.
std::vector<std::vector<std::string>> accepted_options(const fs::path& source) {
  const std::string text = slurp(source);
  std::vector<std::vector<std::string>> found;
  for (std::size_t at = text.find("cli::Args args("); at != std::string::npos; at = text.find("cli::Args args(", at + 1)) {
    const std::size_t end = text.find(");", at);
    const std::string call = text.substr(at, end - at);
    std::vector<std::string> names;
    for (std::size_t q = call.find('"'); q != std::string::npos; q = call.find('"', q + 1)) {
      const std::size_t close = call.find('"', q + 1);
      names.push_back(call.substr(q + 1, close - q - 1));
      q = close;
    }
    found.push_back(names);
  }
  return found;
}

}  // namespace

TEST_F(PneuPlantCli, EveryOptionACommandAcceptsIsInItsHelpAndServesInTheUsage) {
  const fs::path app = fs::path(PNEU_SOURCE_DIR) / "sim_plant" / "app";
  const auto in_main = accepted_options(app / "main.cpp");
  ASSERT_EQ(in_main.size(), 3u) << "simulate, characterize-valve, null-flow";
  const std::vector<std::pair<std::string, std::vector<std::string>>> commands{
      {"simulate", in_main[0]}, {"characterize-valve", in_main[1]}, {"null-flow", in_main[2]},
      {"tune", accepted_options(app / "tune.cpp").at(0)}, {"serve", accepted_options(app / "serve.cpp").at(0)}};
  const std::string usage = run("--help").out;
  for (const auto& [command, options] : commands) {
    ASSERT_FALSE(options.empty()) << command;
    const Outcome h = run(command + " --help");
    EXPECT_EQ(h.exit_code, 0) << command;
    EXPECT_EQ(run(command + " -h").out, h.out) << command << ": -h is --help";
    for (const std::string& option : options) {
      if (option == "help") continue;
      EXPECT_THAT(h.out, HasSubstr("--" + option)) << command << " --help";
      if (command == "serve") {
        EXPECT_THAT(usage, HasSubstr("--" + option)) << "pneu-plant --help, serve's line";
      }
    }
  }
  EXPECT_THAT(usage, HasSubstr("--reply-delay-s")) << "not vacuous";
}

TEST_F(PneuPlantCli, AnUnknownOptionPointsToTheCommandsHelp) {
  const Outcome r = run("simulate --frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.err, HasSubstr("unknown option --frobnicate (see pneu-plant simulate --help)"));
}

// Issue 29, item 1: pneu-plant's outputs opened as every program's (cli::OutputFile).
TEST_F(PneuPlantCli, NullFlowOnACharacterDeviceWritesToItAndLeavesItADevice) {
  fs::path null = "/dev/null";
  if (::geteuid() == 0) {  // a device of the test's own: code that replaces it harms nothing else
    null = dir_ / "null";
    ASSERT_EQ(::mknod(null.c_str(), S_IFCHR | 0666, makedev(1, 3)), 0);
  }
  const Outcome r = run("null-flow --out " + null.string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  struct stat st {};
  ASSERT_EQ(::lstat(null.c_str(), &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
}

TEST_F(PneuPlantCli, NullFlowThroughASymbolicLinkWritesItsTargetAndTheLinkStays) {
  fs::create_symlink("curve_target.csv", dir_ / "curve.csv");
  const Outcome r = run("null-flow --out " + (dir_ / "curve.csv").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_TRUE(fs::is_symlink(dir_ / "curve.csv"));
  EXPECT_THAT(slurp(dir_ / "curve_target.csv"), ::testing::StartsWith("u_v,p_null_p_pa"));
}

TEST_F(PneuPlantServe, RefusesOutputsAndEventsOnTheSameFileBeforeServing) {
  const fs::path same = dir_ / "same";
  fs::create_symlink("same", dir_ / "lnk");
  for (const fs::path& events : {same, dir_ / "lnk"}) {
    const Outcome r = run(serve_hil() + "--outputs " + same.string() + " --events " + events.string());
    EXPECT_EQ(r.exit_code, 2) << events;
    EXPECT_THAT(r.err, HasSubstr("--outputs " + same.string() + " and --events " + events.string() + " name the same file"));
    EXPECT_THAT(r.out, ::testing::Not(HasSubstr("listening")));
  }
}
