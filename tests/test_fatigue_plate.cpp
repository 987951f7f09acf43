// The subcritical fatigue plate, coarsened (cases/subcritical_fatigue_coarse.toml: the plate on
// a lattice twice as coarse) and shortened to 60 growing cycles, with a pre-crack long enough
// (0.135 m) that the cycles' peak stress of 3.34 MPa is critical for it: the crack must grow
// under the cycles before it fails, and the energy balance must hold throughout. About 25 s.
#include "analysis/fatigue.hpp"
#include "app/case_run.hpp"

#include <cmath>
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
