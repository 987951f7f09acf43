// Time functions and nodal loads.
#include "helpers.hpp"
#include "util/error.hpp"

#include <cmath>
#include <gtest/gtest.h>
#include <numbers>

namespace ldem {
namespace {

using testing::face;
using testing::make_sim;
using testing::unit_material;

TEST(TimeFunction, TermsFollowTheirDefinitions) {
  EXPECT_DOUBLE_EQ(TimeFunction()(12.0), 1.0); // default: constant 1
  EXPECT_DOUBLE_EQ(TimeFunction({Constant{2.5}})(7.0), 2.5);
  const TimeFunction ramp({LinearRamp{4.0, 2.0}});
  EXPECT_DOUBLE_EQ(ramp(1.0), 2.0); // 4 * 1/2
  EXPECT_DOUBLE_EQ(ramp(5.0), 4.0); // capped at the value
  const TimeFunction rise({ExponentialRise{3.0, 0.5}});
  EXPECT_NEAR(rise(0.5), 3.0 * (1.0 - std::exp(-1.0)), 1e-15);
  EXPECT_DOUBLE_EQ(rise(0.0), 0.0);
  // GrowingSine: zero before t_start; full amplitude after n_cycles cycles; before that the
  // amplitude is amplitude * exp((s - n / f) / tau).
  const double A = 2.0, f = 10.0, t0 = 1.0, tau = 0.3, n = 5.0;
  const TimeFunction sine({GrowingSine{A, f, t0, tau, n}});
  EXPECT_DOUBLE_EQ(sine(0.5), 0.0);
  const double t_full = n / f;
  // A quarter period after full amplitude is reached: sin = 1.
  EXPECT_NEAR(sine(t0 + t_full + 0.25 / f), A, 1e-12);
  // A quarter period before: sin(2 pi n - pi / 2) = -1, amplitude A exp(-(1/(4f)) / tau).
  EXPECT_NEAR(sine(t0 + t_full - 0.25 / f), -A * std::exp(-0.25 / f / tau), 1e-12);
  // A sum is the sum of its terms.
  const TimeFunction sum({Constant{1.0}, LinearRamp{4.0, 2.0}, ExponentialRise{3.0, 0.5}});
  EXPECT_NEAR(sum(1.0), 1.0 + 2.0 + 3.0 * (1.0 - std::exp(-2.0)), 1e-15);
}

TEST(TimeFunction, BadParametersAreRefused) {
  EXPECT_THROW(TimeFunction({LinearRamp{1.0, 0.0}}), InputError);
  EXPECT_THROW(TimeFunction({ExponentialRise{1.0, -1.0}}), InputError);
  EXPECT_THROW(TimeFunction({GrowingSine{1.0, 0.0, 0.0, 1.0, 1.0}}), InputError);
  EXPECT_THROW(TimeFunction({GrowingSine{1.0, 1.0, 0.0, 1.0, -2.0}}), InputError);
}

// Clapeyron: a constant load P suddenly applied to a linear elastic body, with damping that
// brings it to rest, ends with stored energy U = P.u / 2 = W / 2; the damper took the other
// half. A 2 x 2 x 4 prism fixed at z = 0, each top corner pushed up by P.
TEST(Loads, SuddenDeadLoadEndsWithHalfTheWorkStored) {
  const MaterialSpec m = unit_material(0.05, 4.0);
  const Lattice lat(2, 2, 4, 1.0);
  Conditions c;
  c.fixed.push_back({face(lat, Face::ZMin), kDofAll});
  const double P = 1e-6; // strains ~1e-6: linear
  c.loads.push_back({face(lat, Face::ZMax), {0.0, 0.0, P}, TimeFunction({Constant{1.0}})});
  SolverOptions o;
  o.damping = 0.05; // about 1/4 of critical for the first mode (omega ~ 0.4 c / L)
  Simulation sim = make_sim(2, 2, 4, 1.0, m, c, o);
  while (sim.time() < 1000.0)
    sim.step();
  sim.step(true);
  const EnergyReport& r = sim.last_report();
  double Pu = 0.0;
  for (index_t n : face(lat, Face::ZMax).nodes)
    Pu += P * sim.displacement(n).z;
  EXPECT_LT(std::abs(r.kinetic), 1e-9 * r.external_work); // at rest
  EXPECT_NEAR(r.external_work / Pu, 1.0, 1e-3);
  EXPECT_NEAR(r.elastic / (0.5 * Pu), 1.0, 1e-3);
  EXPECT_NEAR(r.damping_dissipated / (0.5 * Pu), 1.0, 1e-2);
  EXPECT_LT(r.balance_error, 1e-3);
}

// An oscillating load of growing amplitude (the fatigue loading of SPEC 3B) on a free prism,
// undamped: the work of the load must balance the elastic and kinetic energy.
TEST(Loads, GrowingSineLoadKeepsTheBalance) {
  const MaterialSpec m = unit_material(0.05, 4.0);
  const Lattice lat(2, 1, 6, 1.0);
  Conditions c;
  c.fixed.push_back({face(lat, Face::ZMin), kDofAll});
  c.loads.push_back(
      {face(lat, Face::ZMax),
       {1e-6, 0.0, 1e-6},
       TimeFunction({ExponentialRise{1.0, 20.0}, GrowingSine{0.3, 0.01, 50.0, 40.0, 3.0}})});
  Simulation sim = make_sim(2, 1, 6, 1.0, m, c);
  double worst = 0.0;
  for (int s = 0; sim.time() < 600.0; ++s) {
    sim.step(s % 10 == 0);
    if (s % 10 == 0 && sim.time() > 20.0)
      worst = std::max(worst, sim.last_report().balance_error);
  }
  EXPECT_GT(sim.last_report().external_work, 0.0);
  EXPECT_LT(worst, 1e-3);
}

} // namespace
} // namespace ldem
