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

// A crack straight to a = 1.0 mm (14 modules beyond the pre-crack tip) at 500 m/s, then two
// branches at +30 and -30 degrees, `up` and `down` modules long, growing at their speeds.
std::vector<CrackPoint> fork(int up, double up_speed, int down, double down_speed) {
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 14 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 14 * kL / 500.0;
  segment(b, a1, n1, 30.0, up * kL, t1, up_speed);
  segment(b, a1, n1, -30.0, down * kL, t1, down_speed);
  return b;
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

// A first bifurcation at `at` (from the mouth, within at_tol) into two branches at `upper` and
// `lower` degrees (within angle_tol).
void expect_bifurcation(const CrackAnalysis& r, double at, double at_tol, double upper,
                        double lower, double angle_tol) {
  ASSERT_TRUE(r.branching_length.has_value());
  EXPECT_NEAR(*r.branching_length, at, at_tol);
  ASSERT_GE(r.branches.size(), 2u);
  EXPECT_EQ(r.branches[1].level, 1);
  EXPECT_NEAR(r.branches[0].angle_deg, upper, angle_tol);
  EXPECT_NEAR(r.branches[1].angle_deg, lower, angle_tol);
}

// A straight crack from the pre-crack tip to the right border at 500 m/s that sheds, `stem`
// modules beyond the tip, a side branch of `side` modules at `angle` degrees growing at
// `speed`.
CrackAnalysis side_branch_crack(int stem, double angle, int side, double speed) {
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, stem * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + stem * kL / 500.0;
  segment(b, a1, n1, 0.0, (54 - stem) * kL, t1, 500.0);
  segment(b, a1, n1, angle, side * kL, t1, speed);
  return analyze_crack(b, plate(), options());
}

// Its analysis: a bifurcation at `at` into the straight path (0 degrees, open) and the side
// branch (arrested).
void expect_side_branch(const CrackAnalysis& r, double at, double angle, double angle_tol) {
  expect_bifurcation(r, at, 1.5 * kL, 0.0, angle, angle_tol);
  ASSERT_EQ(r.branches.size(), 2u);
  EXPECT_TRUE(r.branches[0].opens);
  EXPECT_FALSE(r.branches[1].opens);
}

// The tip speed is a least-squares slope over a window in which the tip advances at least
// speed_fit_length (10 L). The extent is known to a cell, h = L/2, at every sample, so the
// slope over a window of duration T >= 10 L / v is off by at most 2 h / T = v / 10.
TEST(CrackAnalysis, StraightCrackHasNoBranchAndItsSpeed) {
  // 44 modules of straight growth at 500 m/s: no bifurcation, speed 500 m/s to within 50 m/s,
  // final length = 6 + 44 modules.
  std::vector<CrackPoint> b;
  segment(b, 6 * kL, 30.25 * kL, 0.0, 44 * kL, 3e-6, 500.0);
  add_noise(b);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  EXPECT_FALSE(r.branching_length.has_value());
  EXPECT_TRUE(r.branches.empty());
  EXPECT_FALSE(r.secondary_branching);
  EXPECT_NEAR(r.max_speed, 500.0, 50.0);
  EXPECT_NEAR(r.median_speed, 500.0, 50.0);
  EXPECT_LT(r.max_speed_se, 50.0);
  EXPECT_NEAR(r.final_length, 50 * kL, kL);
  EXPECT_GE(r.bars_elsewhere, 20u); // the isolated bars are not part of the crack
  // Before the first rupture the trunk's tip is the pre-crack's.
  ASSERT_FALSE(r.tip.empty());
  EXPECT_EQ(r.tip.front().branch, 0);
  EXPECT_NEAR(r.tip.front().length, 6 * kL, 1e-15);
}

// Each branch has its own tip: after a bifurcation at a = 1.0 mm, an upper branch at 500 m/s
// and a lower one at 250 m/s, 24 modules each, give median speeds of 500 and 250 m/s to within
// a tenth (above); the farthest point of the whole crack would follow the fast branch alone.
TEST(CrackAnalysis, EachBranchHasItsOwnTipSpeed) {
  std::vector<CrackPoint> b = fork(24, 500.0, 24, 250.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  ASSERT_EQ(r.branches.size(), 2u);
  EXPECT_NEAR(r.branches[0].median_speed, 500.0, 50.0);
  EXPECT_NEAR(r.branches[1].median_speed, 250.0, 25.0);
  EXPECT_NEAR(r.branches[1].max_speed, 250.0, 25.0);
  EXPECT_NEAR(r.speed_before_branching, 500.0, 50.0);
  int rows[3] = {0, 0, 0};
  for (const TipSample& s : r.tip)
    ++rows[s.branch];
  EXPECT_GT(rows[0], 0);
  EXPECT_GT(rows[1], 0);
  EXPECT_GT(rows[2], 0);
}

// Coalescence: a crack at 500 m/s reaches, at 20 modules from the pre-crack tip, 8 modules
// that broke together just before (less than the speed window ahead of it, so they are part
// of the crack). Its extent jumps by 8 L within one sample: the windows that hold the jump are
// marked, their speeds (far above 500 m/s) are not the tip's, and the largest speed is the
// crack's 500 m/s.
TEST(CrackAnalysis, JumpsOfTheTipAreMarkedNotTakenForItsSpeed) {
  std::vector<CrackPoint> b;
  const double t20 = 3e-6 + 20 * kL / 500.0;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 20 * kL, 3e-6, 500.0);
  segment(b, a1, n1, 0.0, 8 * kL, t20 - 0.05e-6, 1e9); // all at once
  segment(b, a1 + 8 * kL, n1, 0.0, 24 * kL, t20, 500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  EXPECT_NEAR(r.max_speed, 500.0, 50.0);
  EXPECT_NEAR(r.max_unflagged_speed, 500.0, 50.0);
  EXPECT_EQ(r.jumps, 1);
  bool marked = false;
  double fastest_marked = 0.0;
  for (const TipSample& s : r.tip)
    if (s.jump) {
      marked = marked || std::abs(s.t - t20) < 0.1e-6;
      fastest_marked = std::max(fastest_marked, s.speed);
    }
  EXPECT_TRUE(marked);
  EXPECT_GT(fastest_marked, 1000.0);
}

// The softened zone: bars soften 2 modules ahead of a crack running at 500 m/s, except a
// ligament 20 to 30 modules from the pre-crack tip that softens all at once when the tip is
// at 18 modules. With the default flag at 3 L, the softened zone runs 3 L or more ahead while the
// tip is between 18 and 27 modules; a speed is flagged when its window (10 L of advance, about
// 5 L on each side of the sample) holds such a sample: the tip between about 13 and 32 modules,
// and never below 12 or above 33.
TEST(CrackAnalysis, SoftenedZoneFarAheadOfTheTipIsFlagged) {
  std::vector<CrackPoint> broken, soft;
  segment(broken, 6 * kL, 30.25 * kL, 0.0, 40 * kL, 3e-6, 500.0);
  const double t18 = 3e-6 + 18 * kL / 500.0;
  for (const CrackPoint& p : broken) {
    const double d = p.a - 6 * kL;
    const double t_soft = d >= 20 * kL && d <= 30 * kL ? t18 : p.t - 2 * kL / 500.0;
    soft.push_back({t_soft, p.a, p.n});
  }
  CrackOptions o = options();
  o.zone_flag_length = 3 * kL;
  const CrackAnalysis r = analyze_crack(broken, plate(), o, soft);
  int flagged = 0, checked = 0;
  for (const TipSample& s : r.tip) {
    const double d = s.length - 6 * kL; // the tip's advance
    if (d > 19 * kL && d < 26 * kL) {
      EXPECT_TRUE(s.flagged) << d / kL;
      flagged += s.flagged;
    } else if ((d > 14.5 * kL && d < 17.5 * kL) || (d > 27.5 * kL && d < 31 * kL)) {
      // The zone is short at the sample itself but not everywhere in its window.
      EXPECT_LE(s.softened_ahead, 3 * kL + 1e-12) << d / kL;
      EXPECT_TRUE(s.flagged) << d / kL;
    } else if (d < 12 * kL || d > 33 * kL) {
      EXPECT_FALSE(s.flagged) << d / kL;
      ++checked;
    }
  }
  EXPECT_GT(flagged, 10);
  EXPECT_GT(checked, 10);
  // The softened front: 2 L ahead of the tip at the end, 46 + 2 modules from the mouth.
  EXPECT_NEAR(r.final_softening_length, 46 * kL, kL);
  EXPECT_GT(r.flagged_time, 0.0);
}

TEST(CrackAnalysis, SymmetricBranchingAtKnownLengthAndAngles) {
  // Straight to a = 1.0 mm, then two branches at +30 and -30 degrees, 1 mm each.
  std::vector<CrackPoint> b = fork(20, 500.0, 20, 500.0);
  add_noise(b);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  expect_bifurcation(r, 1.0e-3, kL, 30.0, -30.0, 2.0); // within one module
  ASSERT_EQ(r.branches.size(), 2u);
  EXPECT_FALSE(r.secondary_branching);
  EXPECT_FALSE(r.branches[0].opens); // their ends are 0.5 mm inside the plate
}

TEST(CrackAnalysis, OneStraightOneInclinedBranch) {
  // The crack goes on straight and sheds one branch at -35 degrees at a = 1.2 mm: the two
  // separate slowly, and the bifurcation point comes from crossing the two fitted lines.
  // The straight path runs to the right border: it opens.
  expect_side_branch(side_branch_crack(18, -35.0, 16, 500.0), 1.2e-3, -35.0, 2.0);
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

// An early side branch that arrests: the crack runs straight from the pre-crack tip to the
// right border and, 4 modules beyond the tip (a = 0.5 mm), sheds a branch at -45 degrees that
// stops after 14 modules. A reader sees a bifurcation at 0.5 mm, branches at 0 and -45
// degrees, the straight one open.
TEST(CrackAnalysis, EarlyArrestedSideBranch) {
  expect_side_branch(side_branch_crack(4, -45.0, 14, 400.0), 0.5e-3, -45.0, 3.0);
}

// A band of alternating paths: two parallel paths 2 modules apart from the pre-crack tip to
// the right border, linked by a diagonal every 4 modules (the zig-zag of bars a band of the
// lattice breaks). One crack: no bifurcation.
TEST(CrackAnalysis, BandOfAlternatingPathsIsOneCrack) {
  std::vector<CrackPoint> b;
  segment(b, 6 * kL, 30.25 * kL, 0.0, 54 * kL, 3e-6, 500.0);
  segment(b, 6 * kL, 28.25 * kL, 0.0, 54 * kL, 3e-6, 500.0);
  for (double a = 8 * kL; a < 58 * kL; a += 4 * kL)
    segment(b, a, 28.25 * kL, 45.0, 2 * std::sqrt(2.0) * kL, 3e-6 + (a - 6 * kL) / 500.0,
            500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  EXPECT_FALSE(r.branching_length.has_value());
}

// The shape of the homogeneous plate's run 0 (docs/validation/fgm-plate.md): from the
// pre-crack tip a 45-degree path runs down for 16 modules and arrests; 3 modules along it a
// horizontal band leaves for the right border; later, bars linking the two break (vertical
// links 6, 9 and 12 modules along the 45-degree path). A reader sees the band leave the
// 45-degree path where it starts, at a = 6 + 3 / sqrt(2) = 8.1 modules (0.41 mm): that is
// the bifurcation, with branches at 0 and -45 degrees, whatever links them afterwards.
TEST(CrackAnalysis, PathsLinkedAfterTheySeparateStillBranch) {
  std::vector<CrackPoint> b;
  const double tip_a = 6 * kL, tip_n = 30.25 * kL, s = 1.0 / std::sqrt(2.0);
  segment(b, tip_a, tip_n, -45.0, 16 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 3 * kL / 500.0;
  const double a1 = tip_a + 3 * kL * s, n1 = tip_n - 3 * kL * s;
  segment(b, a1, n1, 0.0, 60 * kL - a1, t1, 500.0);
  for (double d : {6.0, 9.0, 12.0})
    segment(b, tip_a + d * kL * s, tip_n - d * kL * s, 90.0, (d - 3.0) * kL * s, 6e-6, 500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  expect_bifurcation(r, a1, 1.5 * kL, 0.0, -45.0, 3.0);
  EXPECT_EQ(r.branches.size(), 2u);
}

// A loop as the graded plate's runs close it (docs/validation/fgm-plate.md): 6 modules beyond
// the pre-crack tip (a = 0.6 mm) a path turns down to 2 modules above the bottom border, runs
// along it for 40 modules and back up 26 modules, to meet a horizontal path that left the same
// point and ran 40 modules. A reader sees a bifurcation at 0.6 mm with branches at 0 and -90
// degrees that meet again 2 mm away: two branches that coalesced, not an island.
TEST(CrackAnalysis, LargeLoopIsTwoBranchesThatMeetAgain) {
  std::vector<CrackPoint> b;
  const auto [a1, n1] = segment(b, 6 * kL, 30.25 * kL, 0.0, 6 * kL, 3e-6, 500.0);
  const double t1 = 3e-6 + 6 * kL / 500.0;
  segment(b, a1, n1, 0.0, 40 * kL, t1, 500.0);
  const auto [a2, n2] = segment(b, a1, n1, -90.0, 28 * kL, t1, 500.0);
  const double t2 = t1 + 28 * kL / 500.0;
  const auto [a3, n3] = segment(b, a2, n2, 0.0, 40 * kL, t2, 500.0);
  segment(b, a3, n3, 90.0, 26 * kL, t2 + 40 * kL / 500.0, 500.0);
  const CrackAnalysis r = analyze_crack(b, plate(), options());
  expect_bifurcation(r, a1, 1.5 * kL, 0.0, -90.0, 3.0);
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

