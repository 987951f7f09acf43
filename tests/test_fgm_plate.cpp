// The functionally graded PMMA plate (cases/fgm_plate): the shipped cases run end to end,
// with the crack analysis (each run takes about a second).
#include "app/case_run.hpp"
#include "app/ensemble.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace ldem {
namespace {

struct Broken {
  double t, x, z;
};

struct PlateRun {
  nlohmann::json summary;
  std::vector<Broken> broken; // in order of time
};

// Runs a shipped case (with an optional change) into a fresh temporary folder of its own
// (tests run in parallel) and reads what the tests need.
PlateRun run_plate(const std::string& name, const std::function<void(CaseSpec&)>& adjust) {
  const std::string out =
      (fs::temp_directory_path() /
       ("ldem_fgm_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name())))
          .string();
  fs::remove_all(out);
  RunOptions o;
  o.out_dir = out;
  o.plots = false;
  o.adjust = [&](CaseSpec& s) {
    s.output.vtu = false;
    if (adjust)
      adjust(s);
  };
  EXPECT_EQ(run_command(std::string(LDEM_SOURCE_DIR) + "/cases/fgm_plate/" + name + ".toml", o),
            0);
  PlateRun r;
  std::ifstream js(out + "/summary.json");
  r.summary = nlohmann::json::parse(js);
  std::ifstream ev(out + "/events.csv");
  std::string line;
  std::getline(ev, line);
  while (std::getline(ev, line)) {
    std::istringstream ls(line);
    std::string f[6];
    for (auto& x : f)
      std::getline(ls, x, ',');
    if (f[1] == "broken")
      r.broken.push_back({std::stod(f[2]), std::stod(f[3]), std::stod(f[5])});
  }
  fs::remove_all(out);
  return r;
}

// The pre-crack tip of the shipped cases: x = 0.3 mm, a quarter module above z = 1.5 mm.
constexpr double kL = 5e-5, kTipX = 6 * kL, kPlaneZ = 30 * kL;

TEST(FgmPlate, HomogeneousCrackStartsAtTheTipAndGrowsOneMillimetre) {
  const PlateRun r = run_plate("homogeneous", nullptr);
  ASSERT_FALSE(r.broken.empty());
  // The first bar to break after the pre-crack is at its tip (within two modules).
  EXPECT_NEAR(r.broken.front().x, kTipX, 2 * kL);
  EXPECT_NEAR(r.broken.front().z, kPlaneZ, 2 * kL);
  // SPEC 3A: the crack runs at least 1 mm by the end time (its length along its path
  // beyond the pre-crack).
  const auto& c = r.summary["analysis"]["crack"];
  EXPECT_GE(c["final_crack_length_m"].get<double>() - kTipX, 1e-3);
  // Crack speeds stay physical: a mode-I crack cannot outrun the Rayleigh wave (Freund,
  // Dynamic Fracture Mechanics, 1990, sec. 5.3). The largest tip speed, fitted over 10 L of
  // advance with jumps (the crack joining bars broken ahead of it) left out, lies below c_R
  // to within two of its standard errors.
  const double cR = c["rayleigh_speed_m_s"].get<double>();
  EXPECT_GT(c["max_crack_speed_m_s"].get<double>(), 0.0);
  EXPECT_LT(c["max_crack_speed_m_s"].get<double>() - 2 * c["max_crack_speed_se_m_s"].get<double>(),
            cR);
}

TEST(FgmPlate, BalanceErrorBelowOnePercentAtHalfThePapersStep) {
  // The energy balance closes to O(dt^2): the kinks of the bar law (at e_p, at e_r and at
  // the closing of broken bars) each leave an error of order (strain increment)^2 per bar
  // and step. At the paper's Courant number 0.6 the homogeneous plate ends near 1.7 %
  // (docs/validation/fgm-plate.md); at 0.3 it must be below 1 %.
  const PlateRun r = run_plate("homogeneous", [](CaseSpec& s) { s.step.courant = 0.3; });
  EXPECT_LT(r.summary["max_balance_error"].get<double>(), 0.01);
}

// The first layer of modules along the pulled borders is soft (docs/model.md, "The first
// layer along a face"): its centre nodes lag behind the affine field and its bars stretch
// about 1.2 times the mean strain (test BoundaryLayer.*), so they break early. Driving those
// centre nodes too (cases/fgm_plate/driven_layer/) puts the layer back on the affine field.
// Over the ensemble of docs/validation/fgm-plate.md the bars broken within one module of the
// borders go from 135..146 per run to 6..101: at most 0.75 times, run for run; run 0 is
// checked against that bound.
TEST(FgmPlate, DrivenBorderLayerRemovesMostFirstLayerBreaks) {
  auto first_layer = [](const PlateRun& r) {
    const double H = 60 * kL;
    int n = 0;
    for (const Broken& b : r.broken)
      n += b.z < kL || b.z > H - kL;
    return n;
  };
  const int plain = first_layer(run_plate("homogeneous", nullptr));
  const int driven = first_layer(run_plate("driven_layer/homogeneous", nullptr));
  EXPECT_GT(plain, 100);
  EXPECT_LT(driven, 0.75 * plain);
}

TEST(FgmPlate, GradedToughnessCrackTurnsToTheWeakerSide) {
  // Case 2: Gf grows from bottom to top, so the crack runs into the lower, less tough half:
  // the mean height of the bars broken in the crack lies below the pre-crack plane. Taken
  // over the bars within 0.5 mm of the plate's mid-height, so that damage along the pulled
  // borders does not count.
  const PlateRun r = run_plate("graded_toughness", nullptr);
  double sum = 0.0;
  int n = 0;
  for (const Broken& b : r.broken)
    if (std::abs(b.z - kPlaneZ) < 10 * kL) {
      sum += b.z;
      ++n;
    }
  ASSERT_GT(n, 50);
  EXPECT_LT(sum / n, kPlaneZ);
}

TEST(FgmPlate, EnsemblePerturbationsAreAdmissible) {
  // Run 0 is the case as given; the others span the Courant numbers 0.5 to 0.6, change the
  // velocity by 1e-12 relative, and put the pre-crack on either side of its node plane.
  EXPECT_DOUBLE_EQ(perturbation(0, 8).courant, 0.6);
  EXPECT_EQ(perturbation(0, 8).velocity_eps, 0.0);
  EXPECT_FALSE(perturbation(0, 8).mirror_precrack);
  EXPECT_NEAR(perturbation(7, 8).courant, 0.5, 1e-15);
  int mirrored = 0;
  for (int i = 0; i < 8; ++i) {
    const Perturbation p = perturbation(i, 8);
    EXPECT_GE(p.courant, 0.5 - 1e-15);
    EXPECT_LE(p.courant, 0.6);
    EXPECT_LE(std::abs(p.velocity_eps), 1e-12);
    mirrored += p.mirror_precrack;
  }
  EXPECT_EQ(mirrored, 4);
}

} // namespace
} // namespace ldem
