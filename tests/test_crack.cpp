// The crack analysis on synthetic crack patterns with known answers.
#include "analysis/crack.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <random>

namespace ldem {
namespace {

// The FGM half plate's geometry: L = 0.05 mm, 3 mm x 3 mm, pre-crack from the symmetry plane
// (a = 0) to a = 0.3 mm, a quarter module above the node plane n = 1.5 mm.
constexpr double kL = 5e-5;
constexpr double kPi = 3.14159265358979323846;

CrackGeometry plate() {
  CrackGeometry g;
  g.L = kL;
  g.a_lo = 0.0;
  g.a_hi = 60 * kL;
  g.n_lo = 0.0;
  g.n_hi = 60 * kL;
  g.mouth_a = 0.0;
  g.tip_a = 6 * kL;
  g.line_n = 30.25 * kL;
  return g;
}

CrackOptions options() {
  CrackOptions o;
  o.min_branch_length = 6 * kL;
  o.fit_length = 10 * kL;
  o.speed_window = 4 * kL / 959.0;
  return o;
}

// A straight crack from (a0, n0) running `length` at `angle_deg`, starting at time t0 and
// growing at `speed`: broken-bar centres every L/4 along it, in a band one module thick (the
// lattice breaks normal and diagonal bars on both sides of the crack line). Returns the end.
std::pair<double, double> segment(std::vector<CrackPoint>& out, double a0, double n0,
                                  double angle_deg, double length, double t0, double speed) {
  const double c = std::cos(angle_deg * kPi / 180), s = std::sin(angle_deg * kPi / 180);
  for (double d = 0.0; d <= length + 1e-12; d += kL / 4)
    for (double off : {-kL / 4, 0.0, kL / 4})
      out.push_back({t0 + d / speed, a0 + d * c - off * s, n0 + d * s + off * c});
  return {a0 + length * c, n0 + length * s};
}

// Isolated broken bars away from the crack and a short side crack (3 modules): noise that is
// not a branch.
void add_noise(std::vector<CrackPoint>& out) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(0.0, 60 * kL);
  for (int k = 0; k < 40; ++k) {
    const double a = u(gen), n = u(gen);
    if (std::abs(n - 30 * kL) > 10 * kL) // away from the crack and its branches' start
      out.push_back({5e-6, a, n});
  }
  segment(out, 12 * kL, 30.25 * kL, 90.0, 3 * kL, 4e-6, 300.0);
}

TEST(CrackAnalysis, StraightCrackHasNoBranchAndItsSpeed) {
  // 44 modules of straight growth at 500 m/s: no bifurcation, speed 500 m/s up to the
  // resolution of the centred difference (the extent is known to a cell, h = L/2, at each end
  // of a window 2 tau long: |error| <= h / (2 tau) = 60 m/s), final length = 6 + 44 modules.
  std::vector<CrackPoint> b;
  segment(b, 6 * kL, 30.25 * kL, 0.0, 44 * kL, 3e-6, 500.0);
  add_noise(b);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  EXPECT_FALSE(r.branching_length.has_value());
  EXPECT_TRUE(r.branches.empty());
  EXPECT_FALSE(r.secondary_branching);
  const CrackOptions o = options();
  EXPECT_NEAR(r.max_speed, 500.0, (kL / 2) / (2 * o.speed_window));
  EXPECT_NEAR(r.final_length, 50 * kL, kL);
  EXPECT_GE(r.bars_elsewhere, 20u); // the isolated bars are not part of the crack
}

TEST(CrackAnalysis, SymmetricBranchingAtKnownLengthAndAngles) {
  // Straight to a = 1.0 mm, then two branches at +30 and -30 degrees, 1 mm each.
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 14 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 14 * kL / 500.0;
  segment(b, a1, n1, 30.0, 20 * kL, t1, 500.0);
  segment(b, a1, n1, -30.0, 20 * kL, t1, 500.0);
  add_noise(b);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  ASSERT_TRUE(r.branching_length.has_value());
  EXPECT_NEAR(*r.branching_length, 1.0e-3, kL); // within one module
  ASSERT_EQ(r.branches.size(), 2u);
  EXPECT_NEAR(r.branches[0].angle_deg, 30.0, 2.0);
  EXPECT_NEAR(r.branches[1].angle_deg, -30.0, 2.0);
  EXPECT_FALSE(r.secondary_branching);
  EXPECT_FALSE(r.branches[0].opens); // their ends are 0.5 mm inside the plate
}

TEST(CrackAnalysis, OneStraightOneInclinedBranch) {
  // The crack goes on straight and sheds one branch at -35 degrees at a = 1.2 mm: the two
  // separate slowly, and the bifurcation point comes from crossing the two fitted lines.
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 18 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 18 * kL / 500.0;
  segment(b, a1, n1, 0.0, 36 * kL, t1, 500.0); // to the right border: it opens
  segment(b, a1, n1, -35.0, 16 * kL, t1, 500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  ASSERT_TRUE(r.branching_length.has_value());
  EXPECT_NEAR(*r.branching_length, 1.2e-3, 1.5 * kL);
  ASSERT_EQ(r.branches.size(), 2u);
  EXPECT_NEAR(r.branches[0].angle_deg, 0.0, 2.0);
  EXPECT_NEAR(r.branches[1].angle_deg, -35.0, 2.0);
  EXPECT_TRUE(r.branches[0].opens);
  EXPECT_FALSE(r.branches[1].opens);
}

TEST(CrackAnalysis, TwoLevelsOfBranching) {
  // Branching at a = 0.8 mm (+-30 degrees, 0.6 mm), then the upper branch splits again into
  // +60 and +5 degrees: secondary branching, first branching length 0.8 mm.
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 10 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 10 * kL / 500.0;
  const auto [a2, n2] = segment(b, a1, n1, 30.0, 12 * kL, t1, 500.0);
  segment(b, a1, n1, -30.0, 24 * kL, t1, 500.0);
  const double t2 = t1 + 12 * kL / 500.0;
  segment(b, a2, n2, 60.0, 14 * kL, t2, 500.0);
  segment(b, a2, n2, 5.0, 14 * kL, t2, 500.0);
  add_noise(b);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  ASSERT_TRUE(r.branching_length.has_value());
  EXPECT_NEAR(*r.branching_length, 0.8e-3, kL);
  EXPECT_TRUE(r.secondary_branching);
  int level2 = 0;
  for (const BranchInfo& br : r.branches)
    level2 += br.level == 2;
  EXPECT_EQ(level2, 2);
}

TEST(CrackAnalysis, BandAroundAnIslandIsOneCrack) {
  // The crack splits around an island of intact bars 2 modules high and 4 long and joins
  // again: one crack, not a bifurcation.
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 10 * kL, 3e-6, 500.0);
  segment(b, a1, n1 + 1.25 * kL, 0.0, 4 * kL, 3.5e-6, 500.0);
  segment(b, a1, n1 - 1.25 * kL, 0.0, 4 * kL, 3.5e-6, 500.0);
  segment(b, a1 + 4 * kL, n1, 0.0, 30 * kL, 3.7e-6, 500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  EXPECT_FALSE(r.branching_length.has_value());
}

TEST(CrackAnalysis, NoBrokenBars) {
  const CrackAnalysis r = analyze_crack({}, plate(), options());
  EXPECT_FALSE(r.branching_length.has_value());
  EXPECT_EQ(r.max_speed, 0.0);
  EXPECT_NEAR(r.final_length, 6 * kL, 1e-15);
}

TEST(CrackAnalysis, RayleighSpeed) {
  // Poisson solid (nu = 1/4): c_R / c_s = sqrt(2 - 2 / sqrt(3)) = 0.919402 (Graff, Wave
  // Motion in Elastic Solids, sec. 6.3); PMMA, E = 3.24 GPa, rho = 1190: c_s = 1043.6 m/s.
  const double cs = std::sqrt(3.24e9 / (2.5 * 1190.0));
  EXPECT_NEAR(rayleigh_speed(3.24e9, 0.25, 1190.0) / cs, std::sqrt(2.0 - 2.0 / std::sqrt(3.0)),
              1e-9);
  // nu = 0.3: 0.9274 (Viktorov's approximation (0.862 + 1.14 nu) / (1 + nu) gives 0.9262).
  EXPECT_NEAR(rayleigh_speed(1.0, 0.3, 1.0) / std::sqrt(1.0 / 2.6), 0.9274, 5e-4);
}

} // namespace
} // namespace ldem
