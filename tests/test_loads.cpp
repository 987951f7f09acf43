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
  EXPECT_THROW(TimeFunction({Tabulated{{0.0, 1.0, 1.0}, {0.0, 1.0, 2.0}}}), InputError); // t
  EXPECT_THROW(TimeFunction({Tabulated{{}, {}}}), InputError);
  EXPECT_THROW(TimeFunction({Constant{1.0, 2.0, 1.0}}), InputError); // ends before it starts
  EXPECT_THROW(TimeFunction({LinearRamp{1.0, 1.0, -1.0}}), InputError);
}

// A load history as a laboratory writes it: load to 1 over 1 ms, hold, unload over 1 ms. The
// table reproduces its points and is linear between them, held at its ends.
TEST(TimeFunction, TableReproducesItsPointsAndInterpolates) {
  const TimeFunction f({Tabulated{{0.0, 1e-3, 2e-3, 3e-3}, {0.0, 1.0, 1.0, 0.0}}});
  EXPECT_EQ(f(0.0), 0.0);
  EXPECT_EQ(f(1e-3), 1.0);
  EXPECT_EQ(f(2e-3), 1.0);
  EXPECT_EQ(f(3e-3), 0.0);
  EXPECT_NEAR(f(0.25e-3), 0.25, 1e-15);  // a quarter of the way up
  EXPECT_NEAR(f(2.75e-3), 0.25, 1e-15);  // three quarters of the way down
  EXPECT_EQ(f(1.5e-3), 1.0);             // the hold
  EXPECT_EQ(f(10e-3), 0.0);              // the last value after the last point
  const TimeFunction late({Tabulated{{1.0, 2.0}, {-3.0, 5.0}}});
  EXPECT_EQ(late(0.5), -3.0); // the first value before the first point
  EXPECT_NEAR(late(1.5), 1.0, 1e-15);
}

// Every term's window: 0 before t_start and from t_end on; inside, its own time s = t - t_start.
TEST(TimeFunction, TermsActInTheirWindowOnItsOwnClock) {
  const TimeFunction ramp({LinearRamp{4.0, 2.0, 1.0, 5.0}});
  EXPECT_EQ(ramp(0.5), 0.0);
  EXPECT_EQ(ramp(1.0), 0.0);             // s = 0
  EXPECT_DOUBLE_EQ(ramp(2.0), 2.0);      // s = 1: 4 * 1/2
  EXPECT_DOUBLE_EQ(ramp(4.9), 4.0);      // capped
  EXPECT_EQ(ramp(5.0), 0.0);             // ended
  const TimeFunction step({Constant{2.0, 0.0, 3.0}});
  EXPECT_EQ(step(2.999), 2.0);
  EXPECT_EQ(step(3.0), 0.0);
  const TimeFunction table({Tabulated{{0.0, 1.0}, {0.0, 2.0}, 10.0, kNever}});
  EXPECT_EQ(table(9.0), 0.0);
  EXPECT_NEAR(table(10.5), 1.0, 1e-15); // s = 0.5
  // Loading then unloading by two ramps, the second starting as the first ends: a triangle.
  const TimeFunction tri({LinearRamp{1.0, 1.0}, LinearRamp{-1.0, 1.0, 1.0}});
  EXPECT_DOUBLE_EQ(tri(0.5), 0.5);
  EXPECT_DOUBLE_EQ(tri(1.5), 0.5);
  EXPECT_EQ(tri(2.5), 0.0);
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

// A face's corner nodes stand for a quarter of each module face around them: on the top face
// of a 3 x 2 x 4 lattice (4 x 3 corner nodes), the 4 corners L^2 / 4, the 6 other border nodes
// L^2 / 2, the 2 inside L^2; 6 L^2 in all, the face's area.
TEST(Loads, FaceTributaryAreasAddUpToTheFace) {
  const double L = 0.5;
  const Lattice lat(3, 2, 4, L);
  const std::vector<index_t> nodes = select_face(lat, Face::ZMax);
  const std::vector<double> area = face_tributary_areas(lat, Face::ZMax);
  ASSERT_EQ(area.size(), nodes.size());
  double sum = 0.0;
  for (std::size_t q = 0; q < nodes.size(); ++q) {
    const Vec3 x = lat.position(nodes[q]);
    const int border = (x.x == 0.0 || x.x == 3 * L) + (x.y == 0.0 || x.y == 2 * L);
    EXPECT_DOUBLE_EQ(area[q], L * L / (border == 2 ? 4.0 : border == 1 ? 2.0 : 1.0)) << q;
    sum += area[q];
  }
  EXPECT_DOUBLE_EQ(sum, 6 * L * L);
}

// A column of 3 x 2 x 6 modules in uniaxial strain (x and y held at every node), its bottom
// corner nodes held in z, pulled by tractions. Under u_z = eps z every z bar (edges and
// centre-centre, area phi L^2 inside) stretches by eps and every diagonal (area
// 2 delta phi L^2 / sqrt(3)) by eps / 3; horizontal bars stay unstrained. Each module gives a
// top corner node a quarter of an edge, phi E L^2 eps / 4, and one diagonal's z force,
// 2 delta phi E L^2 eps / 9: the corner nodes' forces are their tributary areas times
// t_c = phi E eps (1 + 8 delta / 9). A top module's centre node lacks the centre-centre bar
// above it, phi E L^2 eps over its module face: t_m = phi E eps (the bottom ones the same,
// downwards). At nu = 0.25 (delta = 9/8, phi = 0.4), t_c = 0.8 E eps, t_m = 0.4 E eps, and the
// stress t_c + t_m = 1.2 E eps = E (1 - nu) / ((1 + nu)(1 - 2 nu)) eps, the constrained
// modulus. With those tractions on the face and on face_centres the affine field is the
// static solution, to the geometric nonlinearity, O(eps) = 1e-6 relative. The same corner
// force shared equally among the top nodes (a force per node) puts 4 and 2 times their share
// on the face's corners and borders: the top face no longer rises evenly.
TEST(Loads, TractionsOnFaceAndCentresHoldTheAffineUniaxialStrain) {
  const MaterialSpec m = unit_material(1.0, 4.0); // E = 1, e_p = 1: elastic
  const index_t nx = 3, ny = 2, nz = 6;
  const Lattice lat(nx, ny, nz, 1.0);
  const double eps = 1e-6, t_c = 0.8 * eps, t_m = 0.4 * eps;
  auto relaxed = [&](bool traction) {
    Conditions c;
    c.fixed.push_back({make_node_set("all", select_all(lat), "all"),
                       static_cast<DofMask>(kDofX | kDofY)});
    c.fixed.push_back({face(lat, Face::ZMin), kDofZ});
    const NodeSet top = face(lat, Face::ZMax);
    if (traction) {
      c.loads.push_back({top, {0.0, 0.0, t_c}, TimeFunction(), face_tributary_areas(lat, Face::ZMax)});
    } else {
      // The same total force, t_c nx ny L^2, equally on each of the top face's nodes.
      const double per_node = t_c * nx * ny / static_cast<double>(top.nodes.size());
      c.loads.push_back({top, {0.0, 0.0, per_node}, TimeFunction()});
    }
    for (Face f : {Face::ZMin, Face::ZMax}) {
      const std::vector<index_t> centres = select_face_module_centres(lat, f);
      c.loads.push_back({make_node_set(face_name(f), centres, "centres"),
                         {0.0, 0.0, f == Face::ZMax ? t_m : -t_m},
                         TimeFunction(),
                         std::vector<double>(centres.size(), 1.0)}); // L^2 = 1 each
    }
    SolverOptions o;
    o.damping = 0.5; // near-critical for the lowest mode, omega_1 ~ (pi / 2) sqrt(1.2) / 6 = 0.29
    Simulation sim = make_sim(nx, ny, nz, 1.0, m, c, o);
    for (int s = 0; s < 6000; ++s)
      sim.step();
    return sim;
  };
  const Simulation sim = relaxed(true);
  double worst = 0.0;
  for (index_t v = 0; v < lat.num_nodes(); ++v) {
    const double z = lat.position(v).z;
    if (z > 0.0)
      worst = std::max(worst, std::abs(sim.displacement(v).z / (eps * z) - 1.0));
  }
  EXPECT_LT(worst, 1e-5);
  // A force per node: the top corner nodes' rise spreads by more than a tenth of eps nz.
  const Simulation equal = relaxed(false);
  double lo = 1e300, hi = -1e300;
  for (index_t v : select_face(lat, Face::ZMax)) {
    lo = std::min(lo, equal.displacement(v).z);
    hi = std::max(hi, equal.displacement(v).z);
  }
  EXPECT_GT((hi - lo) / (eps * nz), 0.1);
}

} // namespace
} // namespace ldem
