// The fatigue measurement on known data: Tada's geometry factor, the Paris fit, the damage
// front of a synthetic events set with a known a(t), and the whole chain from a crack grown by
// a given Paris law back to its C and m.
#include "analysis/fatigue.hpp"

#include "util/error.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <numbers>
#include <random>

namespace ldem {
namespace {

// Tada, Paris & Irwin, The Stress Analysis of Cracks Handbook, single-edge-cracked strip in
// tension: F(a/b) = 1.196, 1.367, 1.655, 2.108, 2.827, 4.043 at a/b = 0.1 ... 0.6.
TEST(Fatigue, TadaFactorMatchesTabulatedValues) {
  const double table[] = {1.196, 1.367, 1.655, 2.108, 2.827, 4.043};
  for (int i = 0; i < 6; ++i) {
    const double s = (i + 1) / 10.0;
    EXPECT_NEAR(tada_edge_crack_factor(s) / table[i], 1.0, 0.005) << "a/b = " << s;
  }
  // A short crack tends to the edge crack in a half plane, F = 1.1215.
  EXPECT_NEAR(tada_edge_crack_factor(1e-4), 1.1215, 0.0015);
}

TEST(Fatigue, TadaFactorRefusesRatiosOutsideItsRange) {
  EXPECT_THROW(tada_edge_crack_factor(0.0), InputError);
  EXPECT_THROW(tada_edge_crack_factor(-0.1), InputError);
  EXPECT_THROW(tada_edge_crack_factor(0.61), InputError);
  EXPECT_NO_THROW(tada_edge_crack_factor(0.6));
}

// Exact power-law data: the log-log line passes through every point, so C and m come back to
// rounding, R^2 = 1 and the confidence interval of m has zero width.
TEST(Fatigue, ParisFitRecoversExactPowerLaw) {
  const double C = 3.7e-21, m = 3.4;
  std::vector<double> dK, rate;
  for (int i = 0; i < 10; ++i) {
    dK.push_back(2e5 * std::pow(1.25, i));
    rate.push_back(C * std::pow(dK.back(), m));
  }
  const ParisFit f = fit_paris(dK, rate);
  EXPECT_NEAR(f.m, m, 1e-10);
  EXPECT_NEAR(f.C / C, 1.0, 1e-8);
  EXPECT_NEAR(f.r2, 1.0, 1e-12);
  EXPECT_NEAR(f.m_high - f.m_low, 0.0, 1e-8);
  EXPECT_EQ(f.points, 10u);
}

// Noisy data (log-normal scatter of da/dN): the 95 % interval of m must contain the true m in
// about 95 % of samples. Over 400 independent samples the coverage has a standard deviation of
// sqrt(0.95 * 0.05 / 400) = 1.1 %, so [0.91, 0.99] is a 3.6-sigma band around 0.95.
TEST(Fatigue, ParisIntervalCoversTrueExponentAtItsConfidence) {
  const double C = 4.26e-5, m = 0.22;
  std::mt19937_64 gen(2026);
  std::normal_distribution<double> noise(0.0, 0.05); // in log10(da/dN)
  int covered = 0;
  const int samples = 400;
  for (int s = 0; s < samples; ++s) {
    std::vector<double> dK, rate;
    for (int i = 0; i < 9; ++i) {
      dK.push_back(1e5 * std::pow(1.2, i));
      rate.push_back(C * std::pow(dK.back(), m) * std::pow(10.0, noise(gen)));
    }
    const ParisFit f = fit_paris(dK, rate);
    EXPECT_LT(f.r2, 1.0);
    if (f.m_low <= m && m <= f.m_high)
      ++covered;
  }
  const double coverage = static_cast<double>(covered) / samples;
  EXPECT_GT(coverage, 0.91);
  EXPECT_LT(coverage, 0.99);
}

TEST(Fatigue, ParisFitRefusesUnusableData) {
  EXPECT_THROW(fit_paris({1e5, 2e5}, {1e-6, 2e-6}), InputError);             // 2 points
  EXPECT_THROW(fit_paris({1e5, 2e5, 3e5}, {1e-6, 0.0, 2e-6}), InputError);   // da/dN = 0
  EXPECT_THROW(fit_paris({1e5, 1e5, 1e5}, {1e-6, 2e-6, 3e-6}), InputError);  // one Delta K
}

// A plate 0.75 m wide with L = 7.5 mm, pre-crack to 0.15 m at mid-height 0.15375 m.
FrontOptions plate() {
  FrontOptions o;
  o.L = 0.0075;
  o.tip = 0.15;
  o.plane = 0.15375;
  o.band = 0.075;
  o.x_end = 0.75;
  return o;
}

// The bars a crack damages in column c of a module when it reaches that column at time t:
// the vertical edge at x = c L, the four diagonals' centres at (c + 1/4) L and (c + 3/4) L,
// and the centre bar at (c + 1/2) L, just above and below the crack plane; later bars of the
// same column come after t.
void damage_column(std::vector<BarEvent>& e, const FrontOptions& o, int c, double t) {
  const double L = o.L;
  const double xs[] = {0.0, 0.25, 0.5, 0.75};
  for (int k = 0; k < 4; ++k)
    for (double dn : {-0.25 * L, 0.25 * L})
      e.push_back({t + 1e-4 * k, (c + xs[k]) * L, o.plane + dn});
}

// a(t) = tip + v t: column c (beyond the tip's column 20) is reached at (c - 20) L / v and
// the front is then (c + 1) L. Damage far from the crack plane (near the loaded faces, at
// early times) and a damaged column beyond a gap must not move the front.
TEST(Fatigue, FrontFollowsAKnownGrowth) {
  const FrontOptions o = plate();
  const double v = 0.01; // m/s
  std::vector<BarEvent> e;
  for (int c = 20; c < 60; ++c)
    damage_column(e, o, c, (c - 20) * o.L / v);
  for (int c = 0; c < 100; c += 7)
    e.push_back({0.001, (c + 0.5) * o.L, 0.30}); // near the top face: outside the band
  damage_column(e, o, 80, 0.002);                 // an isolated damaged column ahead
  const std::vector<FrontStep> f = damage_front(e, o);
  ASSERT_EQ(f.size(), 40u);
  for (int c = 20; c < 60; ++c) {
    const FrontStep& s = f[static_cast<std::size_t>(c - 20)];
    EXPECT_DOUBLE_EQ(s.t, (c - 20) * o.L / v);
    EXPECT_DOUBLE_EQ(s.a, (c + 1) * o.L);
  }
  EXPECT_DOUBLE_EQ(front_at(f, o.tip, -1.0), o.tip);
  EXPECT_DOUBLE_EQ(front_at(f, o.tip, 25 * o.L / v + 1e-9), 46 * o.L);
  // The isolated column 80 counts only once the front has reached column 79: never here.
  EXPECT_DOUBLE_EQ(f.back().a, 60 * o.L);
}

// A column reached before its predecessor joins the front when the predecessor does.
TEST(Fatigue, FrontIsTheUnbrokenRunFromTheTip) {
  const FrontOptions o = plate();
  std::vector<BarEvent> e;
  damage_column(e, o, 20, 1.0);
  damage_column(e, o, 22, 2.0);
  damage_column(e, o, 21, 3.0);
  const std::vector<FrontStep> f = damage_front(e, o);
  ASSERT_EQ(f.size(), 2u);
  EXPECT_DOUBLE_EQ(f[0].t, 1.0);
  EXPECT_DOUBLE_EQ(f[0].a, 21 * o.L);
  EXPECT_DOUBLE_EQ(f[1].t, 3.0);
  EXPECT_DOUBLE_EQ(f[1].a, 23 * o.L);
}

// A constant-amplitude load: remote stress 2.93 MPa +- 0.41 MPa at f Hz from t = 0, so the
// range is 0.82 MPa in every cycle.
CyclicLoad constant_load(double f, double t_end) {
  CyclicLoad l;
  l.frequency = f;
  l.t_cycles = 0.0;
  l.t_constant = 0.0;
  const double h = 1.0 / (64 * f);
  for (double t = 0.0; t <= t_end + h; t += h) {
    l.t.push_back(t);
    l.sigma.push_back(2.93e6 + 0.41e6 * std::sin(2 * std::numbers::pi * f * t));
  }
  return l;
}

// The whole chain: a crack grown from a0 = 0.15 m by da/dN = C DK^m with DK = 0.82 MPa
// sqrt(pi a) F(a/b) (integrated in small steps of N), written as column events on a fine
// lattice (L = 0.5 mm, so that the front's granularity is small against the growth between
// representative points), then a jump of the front across the plate at N = 400 (unstable
// failure). The analysis must give back m within its confidence interval and within 3 %,
// C within 10 %, the unstable onset within one cycle, and R^2 close to 1.
TEST(Fatigue, AnalysisRecoversTheParisLawAGrowthWasMadeWith) {
  const double f = 100.0, C = 3.0e-13, m = 1.5, b = 0.75;
  FrontOptions o = plate();
  o.L = 0.0005;
  const double t_fail = 400.0 / f;
  const CyclicLoad load = constant_load(f, 5.0);
  std::vector<BarEvent> e;
  double a = o.tip, N = 0.0;
  int next = static_cast<int>(std::floor(o.tip / o.L + 1e-9));
  while (N < 400.0) {
    const double dK = 0.82e6 * std::sqrt(std::numbers::pi * a) * tada_edge_crack_factor(a / b);
    const double dN = 0.01;
    a += C * std::pow(dK, m) * dN;
    N += dN;
    // Column c is reached when the crack passes its near edge c L: the front then is (c+1) L.
    while (next * o.L <= a && N < 400.0) {
      damage_column(e, o, next, N / f);
      ++next;
    }
  }
  const double a_fail = a;
  for (int c = next; c < 1000; ++c) // the unstable run: 0.2 m in 0.1 ms
    damage_column(e, o, c, t_fail + (c - next) * 1e-7);
  FatigueOptions fo;
  fo.b = b;
  fo.points = 10;
  fo.unstable_advance = 0.075;
  const FatigueAnalysis r = analyze_fatigue(e, {}, o, load, fo, 5.0);
  ASSERT_TRUE(r.unstable_t.has_value());
  EXPECT_NEAR(*r.cycles_to_failure, 400.0, 1.0);
  ASSERT_TRUE(r.subcritical_start_t.has_value());
  EXPECT_LT(*r.subcritical_start_t * f, 1.0); // growth from the first cycle
  ASSERT_TRUE(r.paris.has_value()) << r.note;
  EXPECT_EQ(r.paris->points, 9u);
  EXPECT_GT(r.paris->r2, 0.99);
  EXPECT_LE(r.paris->m_low, m);
  EXPECT_GE(r.paris->m_high, m);
  EXPECT_NEAR(r.paris->m / m, 1.0, 0.03);
  // C is the intercept at DK = 1 Pa sqrt(m), seven decades from the data: an error e in m
  // moves log C by e log(DK); so C is checked through the rate at the data's centre instead.
  const double dK_mid = 0.82e6 * std::sqrt(std::numbers::pi * 0.25) * tada_edge_crack_factor(0.25 / b);
  EXPECT_NEAR(r.paris->C * std::pow(dK_mid, r.paris->m) / (C * std::pow(dK_mid, m)), 1.0, 0.05);
  EXPECT_GT(a_fail, o.tip + 0.05); // the synthetic crack did grow subcritically
}

// A crack that grows only while the amplitude rises (N < 0) and then arrests: no growth rate
// at constant amplitude, hence no Paris fit and a note that says why; counted from the first
// cycle, the same growth gives one.
TEST(Fatigue, GrowthOnlyUnderTheRisingAmplitudeIsReportedAsSuch) {
  const double f = 100.0;
  const FrontOptions o = plate();
  CyclicLoad load = constant_load(f, 3.0);
  load.t_cycles = 0.0;
  load.t_constant = 1.0; // N = 0 at t = 1 s; the crack arrests at t = 0.8 s
  std::vector<BarEvent> e;
  for (int c = 20; c < 36; ++c)
    damage_column(e, o, c, 0.05 * (c - 19));
  FatigueOptions fo;
  fo.b = 0.75;
  fo.unstable_advance = 0.075;
  const FatigueAnalysis r = analyze_fatigue(e, {}, o, load, fo, 3.0);
  EXPECT_FALSE(r.unstable_t.has_value());
  EXPECT_FALSE(r.paris.has_value());
  EXPECT_NE(r.note.find("the front does not advance at constant amplitude"), std::string::npos)
      << r.note;
  EXPECT_DOUBLE_EQ(r.a_at_constant, 36 * o.L);
  fo.from_first_cycle = true;
  const FatigueAnalysis g = analyze_fatigue(e, {}, o, load, fo, 3.0);
  ASSERT_TRUE(g.paris.has_value()) << g.note;
  // One column per 5 cycles while Delta K grows with a: every interval advanced, and the
  // rate does not fall as Delta K rises.
  EXPECT_EQ(g.paris->points, 9u);
  EXPECT_GE(g.paris->m, 0.0);
}

// A crack of the fatigue law: its bars break from the intact state, with no softening event.
// Their ruptures are the first damage, so the front follows them; a bar that softened before
// it broke is first damaged when it softened, whatever its rupture.
TEST(Fatigue, BreaksWithoutSofteningMakeTheFront) {
  const FrontOptions o = plate();
  std::vector<BarEvent> broken, softening;
  for (int c = 20; c < 30; ++c)
    damage_column(broken, o, c, 0.1 * (c - 19));
  const std::vector<FrontStep> f = damage_front(first_damage({}, broken), o);
  ASSERT_EQ(f.size(), 10u);
  EXPECT_DOUBLE_EQ(f.back().t, 1.0);
  EXPECT_DOUBLE_EQ(f.back().a, 30 * o.L);
  damage_column(softening, o, 20, 0.05); // column 20 softened at 0.05 s, broke at 0.1 s
  const std::vector<FrontStep> g = damage_front(first_damage(softening, broken), o);
  ASSERT_EQ(g.size(), 10u);
  EXPECT_DOUBLE_EQ(g.front().t, 0.05);
}

// The coarse lattice of the secant tests (L = 5 mm, the tip at 0.15 m) and the analysis's
// options for it: secant rates in a strip 0.75 m wide.
FrontOptions coarse_plate() {
  FrontOptions o = plate();
  o.L = 0.005;
  o.tip = 0.15;
  return o;
}
FatigueOptions secant_options() {
  FatigueOptions fo;
  fo.b = 0.75;
  fo.unstable_advance = 0.075;
  fo.secant = true;
  return fo;
}

// Column events of a crack grown by da/dN = C DK^m from the tip of `o` to a = 0.3 m in a strip
// of width b = 0.75 m, 10^4 integration steps per column; the first `transient` columns are
// crossed in 100 cycles each whatever Delta K (the growth away from a cut notch). Returns the
// events and the last cycle.
std::pair<std::vector<BarEvent>, double> paris_crack(const FrontOptions& o, double f, double C,
                                                     double m, int transient = 0) {
  std::vector<BarEvent> e;
  double a = o.tip, N = 0.0;
  int next = static_cast<int>(std::floor(o.tip / o.L + 1e-9));
  const int first = next;
  while (a < 0.3) {
    const double dK = 0.82e6 * std::sqrt(std::numbers::pi * a) * tada_edge_crack_factor(a / 0.75);
    const double rate = next - first <= transient ? o.L / 100.0 : C * std::pow(dK, m);
    const double dN = 1e-4 * o.L / rate;
    a += rate * dN;
    N += dN;
    while (next * o.L <= a) {
      damage_column(e, o, next, N / f);
      ++next;
    }
  }
  return {e, N};
}

// The secant method on a lattice as coarse as the study plates (L = 5 mm; 30 columns of
// growth): a crack grown by da/dN = C DK^m with m = 4, its rate rising 30-fold over the growth.
// Between two front steps the rate is the exact mean over one column, placed at the column's
// centre (the fronts' mean less L). The mean over a column (L / the cycles it takes, a
// harmonic mean) differs from the rate at its centre by a share of order m^2 (L / a)^2 / 8,
// under 0.4 % here, so the fit gives m back within 1 % (the data have no noise, so its
// interval is narrow and need not cover m). Evenly spaced points in N would put most
// intervals in the slow start.
TEST(Fatigue, SecantRatesFollowAParisLawOnACoarseLattice) {
  const double f = 100.0, C = 3.0e-28, m = 4.0;
  const FrontOptions o = coarse_plate();
  const CyclicLoad load = constant_load(f, 1000.0);
  const auto [e, N] = paris_crack(o, f, C, m);
  FatigueOptions fo = secant_options();
  const FatigueAnalysis r = analyze_fatigue(e, {}, o, load, fo, N / f + 1.0);
  EXPECT_FALSE(r.unstable_t.has_value());
  ASSERT_TRUE(r.paris.has_value()) << r.note;
  EXPECT_GE(r.paris->points, 28u);
  EXPECT_NEAR(r.paris->m / m, 1.0, 0.01) << r.paris->m;
  EXPECT_GT(r.paris->r2, 0.999);
}

// fit_after: a crack that first crosses 4 columns at a rate of its own (the growth away from a
// cut notch) and then follows Paris' law. Fitted over all its intervals, the start moves the
// exponent by more than 10 %; with fit_after = 5 L the fit sees the Paris part alone and gives
// m within 1 %, and the note says how many intervals it left out.
TEST(Fatigue, FitAfterLeavesTheGrowthFromTheNotchOut) {
  const double f = 100.0, C = 3.0e-28, m = 4.0;
  const FrontOptions o = coarse_plate();
  const CyclicLoad load = constant_load(f, 1000.0);
  const auto [e, N] = paris_crack(o, f, C, m, 4);
  FatigueOptions fo = secant_options();
  const FatigueAnalysis all = analyze_fatigue(e, {}, o, load, fo, N / f + 1.0);
  ASSERT_TRUE(all.paris.has_value()) << all.note;
  EXPECT_GT(std::abs(all.paris->m - m), 0.1 * m) << all.paris->m;
  fo.fit_after = 5 * o.L;
  const FatigueAnalysis later = analyze_fatigue(e, {}, o, load, fo, N / f + 1.0);
  ASSERT_TRUE(later.paris.has_value()) << later.note;
  EXPECT_NEAR(later.paris->m / m, 1.0, 0.01) << later.paris->m;
  EXPECT_NE(later.note.find("interval(s) within fatigue_fit_after = 0.025 m of the pre-crack's "
                            "tip left out"),
            std::string::npos)
      << later.note;
}

// fit_elastic: a bar near the crack softens when the front has grown 20 columns; the
// intervals that end after it leave the fit (the note says so), the earlier ones keep the
// exponent within 1 %. A softening far from the crack (outside the band) does not count.
TEST(Fatigue, FitElasticStopsAtTheFirstSofteningNearTheCrack) {
  const double f = 100.0, C = 3.0e-28, m = 4.0;
  const FrontOptions o = coarse_plate();
  const CyclicLoad load = constant_load(f, 1000.0);
  const auto [e, N] = paris_crack(o, f, C, m);
  FatigueOptions fo = secant_options();
  const std::vector<FrontStep> front = damage_front(e, o);
  ASSERT_GT(front.size(), 30u);
  const double t_soft = front[20].t + 1e-6;
  const std::vector<BarEvent> softening{{0.5 * t_soft, 0.2, 0.30}, // near the top face
                                        {t_soft, front[20].a - 0.5 * o.L, o.plane + 0.25 * o.L}};
  fo.fit_elastic = true;
  const FatigueAnalysis r = analyze_fatigue(softening, e, o, load, fo, N / f + 1.0);
  ASSERT_TRUE(r.first_softening_t.has_value());
  EXPECT_DOUBLE_EQ(*r.first_softening_t, t_soft);
  ASSERT_TRUE(r.paris.has_value()) << r.note;
  // Front steps 0 to 20 bound 20 intervals, all ended by t_soft.
  EXPECT_EQ(r.paris->points, 20u);
  EXPECT_NEAR(r.paris->m / m, 1.0, 0.01) << r.paris->m;
  EXPECT_NE(r.note.find("after the first softening near the crack"), std::string::npos) << r.note;
}

} // namespace
} // namespace ldem
