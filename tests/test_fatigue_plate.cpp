// The subcritical fatigue plate, coarsened (cases/subcritical_fatigue_coarse.toml: the plate on
// a lattice twice as coarse) and shortened to 60 growing cycles, with a pre-crack long enough
// (0.135 m) that the cycles' peak stress of 3.34 MPa is critical for it: the crack must grow
// under the cycles before it fails, and the energy balance must hold throughout. About 25 s.
#include "analysis/fatigue.hpp"
#include "app/case_run.hpp"

#include <cmath>
#include <fmt/format.h>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace ldem {
namespace {

TEST(FatiguePlate, CoarseCrackGrowsOverSeveralCyclesBeforeFailing) {
  const std::string out = (fs::temp_directory_path() / "ldem_fatigue_plate").string();
  fs::remove_all(out);
  // 60 cycles of growing amplitude from t = 0.1 s at 150 Hz (time constant a quarter of their
  // duration, as the full case), then 20 at constant amplitude.
  constexpr double kStart = 0.1, kFreq = 150.0, kGrowing = 60.0;
  RunOptions o;
  o.out_dir = out;
  o.plots = false;
  o.adjust = [&](CaseSpec& s) {
    s.output.vtu = false;
    s.precracks.at(0).rect.edge1.x = 0.136; // from x = -0.001: a pre-crack of 0.135 m (9 L)
    for (LoadSpec& l : s.loads)
      l.scale = TimeFunction({ExponentialRise{1.0, 0.02},
                              GrowingSine{0.14, kFreq, kStart, kGrowing / kFreq / 4, kGrowing}});
    s.end_time = kStart + (kGrowing + 20.0) / kFreq;
  };
  ASSERT_EQ(run_command(std::string(LDEM_SOURCE_DIR) + "/cases/subcritical_fatigue_coarse.toml", o),
            0);
  std::ifstream js(out + "/summary.json");
  const nlohmann::json summary = nlohmann::json::parse(js);
  const auto& f = summary["analysis"]["fatigue"];

  // It fails: the onset of unstable failure is found, after the oscillation has started, and
  // the run ends soon after (the plate comes apart: time.stop_displacement).
  ASSERT_FALSE(f["unstable_t_over_tmax"].is_null());
  const double tmax = f["tmax_s"].get<double>();
  const double t_unstable = f["unstable_t_over_tmax"].get<double>() * tmax;
  EXPECT_GT(t_unstable, kStart + 10.0 / kFreq);
  EXPECT_FALSE(summary["stopped_by"].is_null());

  // Before failing, the crack grows under the cycles: the damage front moves at least once
  // while the load cycles, and bars near the crack plane start to soften in at least five
  // different cycles (the damage grows cycle after cycle, not in one event).
  std::ifstream fr(out + "/fatigue_front.csv");
  std::string line;
  std::getline(fr, line);
  int cyclic_front_steps = 0;
  while (std::getline(fr, line)) {
    const double t = std::stod(line.substr(0, line.find(',')));
    cyclic_front_steps += t >= kStart && t < t_unstable;
  }
  EXPECT_GE(cyclic_front_steps, 1);
  std::ifstream ev(out + "/events.csv");
  std::getline(ev, line);
  std::set<long> damaged_cycles;
  while (std::getline(ev, line)) {
    std::istringstream ls(line);
    std::string c[6];
    for (auto& x : c)
      std::getline(ls, x, ',');
    const double t = std::stod(c[2]), z = std::stod(c[5]);
    // Within the analysis band (a quarter of the height) of the crack plane z = 10.25 L.
    if (c[1] == "softening" && t >= kStart && t < t_unstable && std::abs(z - 0.15375) < 0.079)
      damaged_cycles.insert(std::lround(std::floor((t - kStart) * kFreq)));
  }
  EXPECT_GE(damaged_cycles.size(), 5u);

  // The energy balance holds through softening, rupture and the unstable run (docs/model.md 8:
  // the central-difference error at the kinks of the bar law, well below 1 % at this step).
  EXPECT_LT(summary["max_balance_error"].get<double>(), 0.01);
  fs::remove_all(out);
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// A small plate, run end to end in a fraction of a second (also under the sanitizers): an edge
// pre-crack, a cyclic load and [analysis] fatigue = true give fatigue.csv, the front and
// analysis.fatigue with its keys; then the same plate under a load far beyond its strength,
// with time.stop_displacement, ends normally once it has come apart, before time.end.
std::string small_plate(double force, double end, const std::string& extra) {
  return fmt::format(R"(
[lattice]
modules = [20, 1, 9]
L = 0.01
plane_strain = "y"

[material]
E = 30e9
rho = 2400
Gf = 100
e_p = 1e-4

[[node_set]]
name = "right"
face = "x+"

[[node_set]]
name = "top"
face_centres = "z+"

[[node_set]]
name = "bottom"
face_centres = "z-"

[[fixed]]
set = "right"

[[load]]
name = "top"
set = "top"
force = [0.0, 0.0, {0}]
function = [{{ type = "exp_rise", tau = 1e-4 }},
            {{ type = "growing_sine", amplitude = 0.2, frequency = 2000.0, t_start = 5e-4, tau = 1e-3, n_cycles = 4 }}]

[[load]]
name = "bottom"
set = "bottom"
force = [0.0, 0.0, -{0}]
function = [{{ type = "exp_rise", tau = 1e-4 }},
            {{ type = "growing_sine", amplitude = 0.2, frequency = 2000.0, t_start = 5e-4, tau = 1e-3, n_cycles = 4 }}]

[[precrack]]
name = "edge"
origin = [-0.001, -0.001, 0.0425]
edge1 = [0.061, 0.0, 0.0]
edge2 = [0.0, 0.012, 0.0]

[time]
end = {1}
{2}

[output]
vtu = false

[analysis]
fatigue = true
)",
                     force, end, extra);
}

std::string write_case(const std::string& name, const std::string& text) {
  const std::string path = (fs::temp_directory_path() / name).string();
  std::ofstream(path) << text;
  return path;
}

TEST(FatigueRun, SmallPlateWritesTheFatigueOutputs) {
  const std::string out = (fs::temp_directory_path() / "ldem_fatigue_small").string();
  fs::remove_all(out);
  RunOptions o;
  o.out_dir = out;
  o.plots = false;
  // 1000 N per face module: 10 MPa remote stress, below the lattice's strength (30 MPa).
  ASSERT_EQ(run_command(write_case("ldem_fatigue_small.toml", small_plate(1000.0, 3e-3, "")), o),
            0);
  std::ifstream js(out + "/summary.json");
  const nlohmann::json s = nlohmann::json::parse(js);
  const auto& f = s["analysis"]["fatigue"];
  for (const char* key : {"paris_C", "paris_m", "paris_r2", "subcritical_start_t_over_tmax",
                          "unstable_t_over_tmax", "cycles_to_failure"})
    EXPECT_TRUE(f.contains(key)) << key;
  // N = 0 when the amplitude becomes constant: 5e-4 s + 4 cycles at 2 kHz.
  EXPECT_NEAR(f["constant_amplitude_from_s"].get<double>(), 2.5e-3, 1e-12);
  // The remote stress range at constant amplitude: 2 x 0.2 x 10 MPa.
  EXPECT_NEAR(f["stress_range_constant_pa"].get<double>(), 4e6, 4e6 * 2e-3);
  EXPECT_NEAR(f["precrack_length_m"].get<double>(), 0.06, 1e-12);
  std::ifstream csv(out + "/fatigue.csv");
  std::string head;
  std::getline(csv, head);
  EXPECT_EQ(head, "N,a,da_dN,delta_K,in_fit");
  EXPECT_TRUE(s["stopped_by"].is_null());
  fs::remove_all(out);
}

TEST(FatigueRun, StopDisplacementEndsARunThatComesApart) {
  const std::string out = (fs::temp_directory_path() / "ldem_fatigue_apart").string();
  fs::remove_all(out);
  RunOptions o;
  o.out_dir = out;
  o.plots = false;
  // 20 kN per face module, 200 MPa: the ligament breaks at once and the halves fly apart.
  ASSERT_EQ(run_command(write_case("ldem_fatigue_apart.toml",
                                   small_plate(2e4, 1.0, "stop_displacement = 0.005")),
                        o),
            0);
  std::ifstream js(out + "/summary.json");
  const nlohmann::json s = nlohmann::json::parse(js);
  ASSERT_FALSE(s["stopped_by"].is_null());
  EXPECT_NE(s["stopped_by"].get<std::string>().find("time.stop_displacement = 0.005 m"),
            std::string::npos);
  EXPECT_LT(s["end_time"].get<double>(), 0.1); // long before time.end = 1 s
  // The last energy row is the stopping step's: the outputs end where the run ended.
  std::ifstream en(out + "/energy.csv");
  std::string line, last;
  while (std::getline(en, line))
    if (!line.empty())
      last = line;
  EXPECT_NEAR(std::stod(last.substr(0, last.find(','))), s["end_time"].get<double>(), 1e-5);
  fs::remove_all(out);
}

} // namespace
} // namespace ldem
