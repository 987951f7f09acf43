// Property fields: gradings and Weibull random fields.
#include "material/field.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <omp.h>

namespace ldem {
namespace {

// Shapes for given CVs, from CV^2 = G(1 + 2/g) / G(1 + 1/g)^2 - 1 (the values quoted in the
// literature on Weibull toughness fields: about 12.15, 5.80 and 2.10).
TEST(Weibull, ShapeFromCoefficientOfVariation) {
  EXPECT_NEAR(weibull_shape(0.10), 12.15, 0.01);
  EXPECT_NEAR(weibull_shape(0.20), 5.80, 0.01);
  EXPECT_NEAR(weibull_shape(0.50), 2.10, 0.01);
  // Scale from the mean: mean = scale G(1 + 1/g); for g = 1 (CV = 1, exponential) scale = mean.
  EXPECT_NEAR(weibull_shape(1.0), 1.0, 1e-6);
  EXPECT_NEAR(weibull_scale(3.0, 1.0), 3.0, 1e-12);
}

// 10^6 draws through the lattice path: sample mean and CV within 1 % of the targets, and the
// Kolmogorov-Smirnov distance to the Weibull CDF F(x) = 1 - exp(-(x / scale)^g) below its 1 %
// critical value 1.628 / sqrt(n) (asymptotic, n large).
TEST(Weibull, OneMillionDrawsFollowTheDistribution) {
  const Lattice lat(40, 40, 46, 0.01);
  ASSERT_GE(lat.num_bars(), 1000000u);
  Field f;
  f.kind = Field::Kind::Weibull;
  f.mean = 1155.0;
  f.cv = 0.05;
  f.seed = 42;
  std::vector<double> v = evaluate_field(f, lat);
  const double n = static_cast<double>(v.size());
  double s = 0.0, s2 = 0.0;
  for (double x : v)
    s += x;
  const double mean = s / n;
  for (double x : v)
    s2 += (x - mean) * (x - mean);
  const double cv = std::sqrt(s2 / (n - 1)) / mean;
  EXPECT_NEAR(mean / f.mean, 1.0, 0.01);
  EXPECT_NEAR(cv / f.cv, 1.0, 0.01);
  const double g = weibull_shape(f.cv), scale = weibull_scale(f.mean, g);
  std::sort(v.begin(), v.end());
  double d = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const double F = 1.0 - std::exp(-std::pow(v[i] / scale, g));
    d = std::max({d, std::abs(F - static_cast<double>(i) / n),
                  std::abs(F - static_cast<double>(i + 1) / n)});
  }
  EXPECT_LT(d, 1.628 / std::sqrt(n));
}

TEST(Weibull, SameSeedSameFieldWhateverTheThreads) {
  const Lattice lat(30, 30, 30, 0.01); // 360k bars: evaluated in parallel
  Field f;
  f.kind = Field::Kind::Weibull;
  f.mean = 100.0;
  f.cv = 0.2;
  f.seed = 9;
  const int before = omp_get_max_threads();
  omp_set_num_threads(1);
  const std::vector<double> a = evaluate_field(f, lat);
  omp_set_num_threads(2);
  const std::vector<double> b = evaluate_field(f, lat), c = evaluate_field(f, lat);
  omp_set_num_threads(before);
  EXPECT_EQ(a, b);
  EXPECT_EQ(b, c);
  f.seed = 10;
  EXPECT_NE(evaluate_field(f, lat), a);
}

// A linear grading is reproduced exactly at every bar centre: v = v0 + (v1 - v0) (z - z0) /
// (z1 - z0) (the paper's graded e_p: 0.0125 at the bottom to 0.0375 at the top).
TEST(Field, LinearGradingAtBarCentres) {
  const double L = 5e-5;
  const Lattice lat(6, 1, 60, L);
  Field f;
  f.kind = Field::Kind::Linear;
  f.axis = 2;
  f.table = {{0.0, 0.0125}, {60 * L, 0.0375}};
  validate_field(f, lat, "e_p");
  const std::vector<double> v = evaluate_field(f, lat);
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const double z = lat.bar_centre(b).z;
    EXPECT_NEAR(v[b], 0.0125 + 0.025 * z / (60 * L), 1e-15) << "bar " << b;
  }
}

TEST(Field, TableIsPiecewiseLinearAndConstantBeyondItsEnds) {
  const Lattice lat(10, 1, 1, 1.0);
  Field f;
  f.kind = Field::Kind::Table;
  f.axis = 0;
  f.table = {{2.0, 1.0}, {4.0, 3.0}, {8.0, 3.0}};
  validate_field(f, lat, "E");
  const std::vector<double> v = evaluate_field(f, lat);
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const double x = lat.bar_centre(b).x;
    const double expected = x <= 2.0 ? 1.0 : x >= 4.0 ? 3.0 : 1.0 + (x - 2.0);
    EXPECT_NEAR(v[b], expected, 1e-14) << "x = " << x;
  }
}

TEST(Field, InvalidDefinitionsAreRefused) {
  const Lattice lat(10, 1, 10, 1.0);
  auto message = [&](const Field& f) {
    try {
      validate_field(f, lat, "material.Gf");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  Field w;
  w.kind = Field::Kind::Weibull;
  w.mean = 1.0;
  w.cv = -0.1;
  EXPECT_NE(message(w).find("material.Gf: Weibull field: cv = -0.1 gives no Weibull shape"),
            std::string::npos)
      << message(w);
  w.cv = 50.0;
  EXPECT_NE(message(w).find("gives no Weibull shape"), std::string::npos);
  Field g;
  g.kind = Field::Kind::Linear;
  g.axis = 2;
  g.table = {{0.0, 1.0}, {12.0, 2.0}};
  EXPECT_NE(message(g).find("grading point 12 m lies outside the body (0 to 10 m along z)"),
            std::string::npos)
      << message(g);
  g.kind = Field::Kind::Table;
  g.table = {{0.0, 1.0}, {5.0, 2.0}, {3.0, 1.0}};
  EXPECT_NE(message(g).find("table coordinates must increase, got 3 after 5"), std::string::npos)
      << message(g);
}

} // namespace
} // namespace ldem
