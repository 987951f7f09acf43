// Property fields: gradings and Weibull random fields.
#include "material/field.hpp"
#include "solver/simulation.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <gtest/gtest.h>
#include <map>
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

// A distributed run evaluates the fields at its window's bars and modules only: each takes the
// value it has in the whole body's evaluation, bit for bit (draws by the body's numbers,
// correlated fields from the body's one grid, gradings at the same centres), for a subset in
// any order.
TEST(Field, SomeBarsOrModulesTakeTheWholeBodysValues) {
  const Lattice lat(7, 5, 6, 0.01);
  std::vector<Field> fields(3);
  fields[0].kind = Field::Kind::Weibull;
  fields[0].mean = 100.0;
  fields[0].cv = 0.2;
  fields[0].seed = 3;
  fields[1] = fields[0];
  fields[1].correlation_length = 0.03;
  fields[2].kind = Field::Kind::Linear;
  fields[2].axis = 1;
  fields[2].table = {{0.0, 1.0}, {0.05, 2.0}};
  std::vector<index_t> bars, modules;
  for (index_t b = lat.num_bars(); b-- > 0;) // every third bar, backwards
    if (b % 3 == 1)
      bars.push_back(b);
  for (index_t m = 5; m < lat.num_modules(); m += 7)
    modules.push_back(m);
  for (const Field& f : fields) {
    SCOPED_TRACE(describe_field(f));
    const std::vector<double> all = evaluate_field(f, lat), some = evaluate_field(f, lat, bars);
    ASSERT_EQ(some.size(), bars.size());
    for (std::size_t q = 0; q < bars.size(); ++q)
      ASSERT_EQ(some[q], all[bars[q]]) << "bar " << bars[q];
    const std::vector<double> all_m = evaluate_field_modules(f, lat),
                              some_m = evaluate_field_modules(f, lat, modules);
    ASSERT_EQ(some_m.size(), modules.size());
    for (std::size_t q = 0; q < modules.size(); ++q)
      ASSERT_EQ(some_m[q], all_m[modules[q]]) << "module " << modules[q];
    EXPECT_NE(all.front(), all.back()); // the field varies
  }
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

namespace ldem {
namespace {

// The correlated Gaussian field's empirical correlation between bars one correlation length
// apart matches the target covariance at r = l, exp(-1) for both models, within 15 %. A plate
// of 240 x 240 modules with l = 6 L holds about 1600 independent patches (error ~ 2.5 %).
// Each bar is paired with the bar of its family 6 modules further along x.
double correlation_at_length(Field::Covariance cov) {
  const Lattice lat(240, 1, 240, 1.0);
  const double ell = 6.0;
  std::vector<Vec3> centres(lat.num_bars());
  for (index_t b = 0; b < lat.num_bars(); ++b)
    centres[b] = lat.bar_centre(b);
  const std::vector<double> z = correlated_gaussian(lat, centres, ell, cov, 5);
  double s = 0.0, s2 = 0.0, sab = 0.0;
  std::size_t n = 0;
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    for (index_t k = 0; k < fi.nk; ++k)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i + 6 < fi.ni; ++i) {
          const double a = z[lat.bar(static_cast<Family>(f), i, j, k)];
          const double b = z[lat.bar(static_cast<Family>(f), i + 6, j, k)];
          s += a;
          s2 += a * a;
          sab += a * b;
          ++n;
        }
  }
  const double m = static_cast<double>(n), mean = s / m, var = s2 / m - mean * mean;
  return (sab / m - mean * mean) / var;
}

TEST(CorrelatedField, CorrelationAtOneLengthMatchesTheCovariance) {
  EXPECT_NEAR(correlation_at_length(Field::Covariance::Exponential) / std::exp(-1.0), 1.0, 0.15);
  EXPECT_NEAR(correlation_at_length(Field::Covariance::SquaredExponential) / std::exp(-1.0), 1.0,
              0.15);
}

// The correlation length is physical: the field lives on a grid of spacing l / 8 fixed by the
// body and l, so a coarse and a fine lattice of the same body and seed take identical values
// wherever their bar centres fall on the same grid point.
TEST(CorrelatedField, SameFieldForCoarseAndFineLattices) {
  Field f;
  f.kind = Field::Kind::Weibull;
  f.mean = 1155.0;
  f.cv = 0.05;
  f.correlation_length = 0.02;
  const Lattice coarse(20, 1, 10, 0.01), fine(40, 2, 20, 0.005);
  const std::vector<double> a = evaluate_field(f, coarse), b = evaluate_field(f, fine);
  const double h = f.correlation_length / 8.0;
  auto key = [h](Vec3 c) {
    return std::array<long, 3>{std::lround(c.x / h), std::lround(c.y / h), std::lround(c.z / h)};
  };
  std::map<std::array<long, 3>, double> on_grid;
  for (index_t bar = 0; bar < coarse.num_bars(); ++bar)
    on_grid[key(coarse.bar_centre(bar))] = a[bar];
  std::size_t shared = 0;
  for (index_t bar = 0; bar < fine.num_bars(); ++bar) {
    const auto it = on_grid.find(key(fine.bar_centre(bar)));
    if (it == on_grid.end())
      continue;
    ++shared;
    ASSERT_EQ(it->second, b[bar]) << "fine bar " << bar;
  }
  EXPECT_GT(shared, 1000u);
  // And the field does vary: its sample CV is of the order of the target.
  double s = 0.0, s2 = 0.0;
  for (double x : b) {
    s += x;
    s2 += x * x;
  }
  const double n = static_cast<double>(b.size()), mean = s / n;
  EXPECT_GT(std::sqrt(s2 / n - mean * mean) / mean, 0.01);
}

} // namespace
} // namespace ldem

namespace ldem {
namespace {

// A density field is lumped module by module: the total mass is the sum over modules of
// rho(module centre) L^3; for a linear grading the module centres are symmetric about the
// middle, so the total is the mean density times the volume.
TEST(Field, DensityFieldKeepsTheMassOfEveryModule) {
  const double L = 0.01;
  const Lattice lat(6, 2, 10, L);
  Field rho;
  rho.kind = Field::Kind::Linear;
  rho.axis = 2;
  rho.table = {{0.0, 1000.0}, {10 * L, 3000.0}};
  BarFields fields;
  fields.rho = evaluate_field_modules(rho, lat);
  MaterialSpec m;
  m.E = 30e9;
  m.rho = 2000.0;
  m.Gf = 100.0;
  m.e_p = 1e-4;
  Simulation sim(lat, BarTable(lat, m, fields), {}, {});
  double total = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    total += sim.mass(n);
  EXPECT_NEAR(total / (2000.0 * lat.volume()), 1.0, 1e-12);
  // The top module layer is 2.9 times as dense as the bottom one (centres at z = 0.5 L and
  // 9.5 L: 1100 and 2900 kg/m^3): its centre nodes carry 2900 / 1100 the mass.
  EXPECT_NEAR(sim.mass(lat.centre(0, 0, 9)) / sim.mass(lat.centre(0, 0, 0)), 2900.0 / 1100.0,
              1e-12);
}

} // namespace
} // namespace ldem
