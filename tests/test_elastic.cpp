// Elastic physics of the lattice and of the integrator.
#include "helpers.hpp"
#include "io/output.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <limits>
#include <random>

namespace ldem {
namespace {

using testing::affine_field;
using testing::make_sim;
using testing::unit_material;

// An affine displacement u = eps X gives, in an interior module, the stress of an isotropic
// solid. The module's stress is the virial (1 / L^3) sum_b w_b F_b d_b d_b^T / l_b over the
// bars of the module with w = 1 for its 8 diagonals, 1/4 for its 12 edges (each shared by 4
// modules) and 1/2 for the 6 centre-centre bars leaving its centre (each shared by 2).
// Expected (SPEC 2): C1111 = phi E (2 + 8 delta / 9) = 1.2 E, C1122 = C1212 = 8 delta phi E / 9
// = 0.4 E for delta = 1.125, phi = 0.4; i.e. Lame lambda = mu = 0.4 E, which is
// E nu / ((1 + nu)(1 - 2 nu)) and E / (2 (1 + nu)) for nu = 0.25.
TEST(Elastic, AffineStrainGivesIsotropicStressInTheInterior) {
  const double L = 0.01, E = 30e9;
  MaterialSpec m = unit_material();
  m.E = E;
  m.Gf = 1e6; // elastic: K_r >> 1
  m.e_p = 1e-2;
  Simulation sim = make_sim(4, 4, 4, L, m);
  const Lattice& lat = sim.lattice();
  // A general symmetric strain, small enough that geometric nonlinearity (O(eps)) is < 1e-5.
  const double eps[3][3] = {
      {2e-6, 0.7e-6, -0.4e-6}, {0.7e-6, -1e-6, 0.9e-6}, {-0.4e-6, 0.9e-6, 1.5e-6}};
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 X = lat.position(n);
    sim.set_displacement(n, {eps[0][0] * X.x + eps[0][1] * X.y + eps[0][2] * X.z,
                             eps[1][0] * X.x + eps[1][1] * X.y + eps[1][2] * X.z,
                             eps[2][0] * X.x + eps[2][1] * X.y + eps[2][2] * X.z});
  }
  const double lambda = 0.4 * E, mu = 0.4 * E;
  const double tr = eps[0][0] + eps[1][1] + eps[2][2];
  for (index_t mi : {1u, 2u}) { // two interior modules
    const index_t mj = 1, mk = 2;
    const index_t centre = lat.centre(mi, mj, mk);
    double sigma[3][3] = {};
    for (index_t b = 0; b < lat.num_bars(); ++b) {
      const auto [na, nb] = lat.bar_nodes(b);
      const BarAddress ad = lat.bar_address(b);
      double w = 0.0;
      if (lat.family(ad.family).kind == BarKind::Diagonal)
        w = (na == centre) ? 1.0 : 0.0;
      else if (lat.is_centre(na))
        w = (na == centre || nb == centre) ? 0.5 : 0.0;
      else {
        // An edge of the module: both ends among its corners.
        auto corner_of_module = [&](index_t n) {
          const NodeAddress a = lat.node_address(n);
          return a.i - mi <= 1 && a.j - mj <= 1 && a.k - mk <= 1 && a.i >= mi && a.j >= mj &&
                 a.k >= mk;
        };
        w = corner_of_module(na) && corner_of_module(nb) ? 0.25 : 0.0;
      }
      if (w == 0.0)
        continue;
      const Vec3 xa = lat.position(na), xb = lat.position(nb);
      const Vec3 ua = sim.displacement(na), ub = sim.displacement(nb);
      const double d[3] = {xb.x + ub.x - xa.x - ua.x, xb.y + ub.y - xa.y - ua.y,
                           xb.z + ub.z - xa.z - ua.z};
      const double l = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      const double F = sim.bar_force(b);
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q)
          sigma[p][q] += w * F * d[p] * d[q] / l / (L * L * L);
    }
    double smax = 0.0;
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q)
        smax = std::max(smax, std::abs(lambda * tr * (p == q) + 2 * mu * eps[p][q]));
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) {
        const double expected = lambda * tr * (p == q) + 2.0 * mu * eps[p][q];
        EXPECT_NEAR(sigma[p][q], expected, 0.01 * smax) << "sigma_" << p << q;
      }
  }
}

// The snapshots' stress at the nodes (node_stresses) under the affine field of the test above:
// at the nodes whose modules are all interior (the corner (2, 2, 2) of the 4 x 4 x 4 box, whose
// 8 modules are those with indices 1 and 2, and those modules' centres) it is the isotropic
// solid's, lambda tr(eps) I + 2 mu eps with lambda = mu = 0.4 E. What is left: geometric
// nonlinearity, O(eps) = 2e-6 relative.
TEST(Elastic, NodeStressesAreTheIsotropicStressOfAnAffineStrain) {
  const double L = 0.01, E = 30e9;
  MaterialSpec m = unit_material();
  m.E = E;
  m.Gf = 1e6;
  m.e_p = 1e-2;
  Simulation sim = make_sim(4, 4, 4, L, m);
  const Lattice& lat = sim.lattice();
  const double eps[3][3] = {
      {2e-6, 0.7e-6, -0.4e-6}, {0.7e-6, -1e-6, 0.9e-6}, {-0.4e-6, 0.9e-6, 1.5e-6}};
  const std::vector<Vec3> u = affine_field(lat, eps);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    sim.set_displacement(n, u[n]);
  std::vector<std::uint8_t> state;
  std::vector<double> damage, force, stress;
  sim.bar_snapshot(state, damage, force);
  node_stresses(lat, u, force, stress);
  const double mu = 0.4 * E, lambda = 0.4 * E, tr = eps[0][0] + eps[1][1] + eps[2][2];
  // VTK's order of a symmetric tensor: xx, yy, zz, xy, yz, xz.
  const int p_of[6] = {0, 1, 2, 0, 1, 0}, q_of[6] = {0, 1, 2, 1, 2, 2};
  double smax = 0.0;
  for (int c = 0; c < 6; ++c)
    smax = std::max(smax, std::abs(lambda * tr * (c < 3) + 2.0 * mu * eps[p_of[c]][q_of[c]]));
  std::vector<index_t> nodes = {lat.corner(2, 2, 2)};
  for (index_t k = 1; k <= 2; ++k)
    for (index_t j = 1; j <= 2; ++j)
      for (index_t i = 1; i <= 2; ++i)
        nodes.push_back(lat.centre(i, j, k));
  for (index_t n : nodes)
    for (int c = 0; c < 6; ++c)
      EXPECT_NEAR(stress[6 * std::size_t{n} + c],
                  lambda * tr * (c < 3) + 2.0 * mu * eps[p_of[c]][q_of[c]], 1e-5 * smax)
          << "node " << n << ", component " << c;
}

// The snapshots' strain at the nodes (node_strains): a module's strain is the volume mean of
// the gradient of its corners' trilinear interpolation, symmetrised, so under an affine field
// u = eps X every module's, and so every node's, is eps to rounding, on the faces and corners of
// the body too. Under the multilinear field u = (a y z, b x z, c x y), which trilinear
// interpolation holds exactly, a module's strain is the field's at its centre: e_xy =
// (a z + b z) / 2, e_yz = (b x + c x) / 2, e_xz = (a y + c y) / 2, the diagonal 0. An interior
// corner node takes the mean over its 8 modules, whose centres lie at its coordinates +- L/2:
// the field's strain is linear, so the mean is the field's at the node, to rounding.
TEST(Elastic, NodeStrainsAreTheMeanGradientOfTheModules) {
  const double L = 0.01;
  const Lattice lat(4, 3, 5, L);
  const double eps[3][3] = {
      {2e-6, 0.7e-6, -0.4e-6}, {0.2e-6, -1e-6, 0.9e-6}, {-0.8e-6, 0.3e-6, 1.5e-6}};
  const int p_of[6] = {0, 1, 2, 0, 1, 0}, q_of[6] = {0, 1, 2, 1, 2, 2};
  std::vector<Vec3> u = affine_field(lat, eps);
  std::vector<double> strain;
  node_strains(lat, u, strain);
  ASSERT_EQ(strain.size(), 6 * std::size_t{lat.num_nodes()});
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    for (int c = 0; c < 6; ++c)
      EXPECT_NEAR(strain[6 * std::size_t{n} + c],
                  0.5 * (eps[p_of[c]][q_of[c]] + eps[q_of[c]][p_of[c]]), 1e-15)
          << "node " << n << ", component " << c;
  const double a = 3e-5, b = -2e-5, c = 4e-5; // [1/m]
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 X = lat.position(n);
    u[n] = {a * X.y * X.z, b * X.x * X.z, c * X.x * X.y};
  }
  node_strains(lat, u, strain);
  for (index_t k = 1; k < lat.nz(); ++k)
    for (index_t j = 1; j < lat.ny(); ++j)
      for (index_t i = 1; i < lat.nx(); ++i) {
        const index_t n = lat.corner(i, j, k);
        const Vec3 X = lat.position(n);
        const double expected[6] = {0, 0, 0, 0.5 * (a + b) * X.z, 0.5 * (b + c) * X.x,
                                    0.5 * (a + c) * X.y};
        for (int e = 0; e < 6; ++e)
          EXPECT_NEAR(strain[6 * std::size_t{n} + e], expected[e], 1e-15)
              << "corner " << i << " " << j << " " << k << ", component " << e;
      }
  // A centre node: its module's, the field's at the centre.
  const Vec3 X = lat.position(lat.centre(1, 2, 3));
  EXPECT_NEAR(strain[6 * std::size_t{lat.centre(1, 2, 3)} + 3], 0.5 * (a + b) * X.z, 1e-15);
}

// A long prism 1 x 1 x N with the lateral DOF fixed is in uniaxial strain, so long waves
// travel at c_p = sqrt(C1111 / rho) = sqrt(1.2 E / rho) (C1111 above). A Gaussian initial
// displacement splits into two pulses; the centroid of the one moving to +z must advance
// at c_p within 3 %.
TEST(Elastic, PulseTravelsAtTheLatticeWaveSpeed) {
  const index_t N = 400;
  MaterialSpec m = unit_material();
  Lattice probe(1, 1, N, 1.0);
  Conditions c;
  c.fixed.push_back({make_node_set("all", select_all(probe), "all nodes"), kDofX | kDofY});
  SolverOptions o;
  o.step.safety = 0.5;
  Simulation sim = make_sim(1, 1, N, 1.0, m, c, o);
  const Lattice& lat = sim.lattice();
  // The left-moving half reflects at z = 0 and is back at z0 only after t = 2 z0 / c_p = 274.
  const double z0 = 150.0, width = 10.0, amp = 1e-6;
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const double z = lat.position(n).z;
    sim.set_displacement(n, {0.0, 0.0, amp * std::exp(-(z - z0) * (z - z0) / (width * width))});
  }
  auto centroid = [&] { // of the right-moving pulse, once the halves have separated
    double s = 0.0, sz = 0.0;
    for (index_t n = 0; n < lat.num_nodes(); ++n) {
      const double z = lat.position(n).z, u = sim.displacement(n).z;
      if (z > z0) {
        s += u;
        sz += u * z;
      }
    }
    return sz / s;
  };
  const double c_p = std::sqrt(1.2);
  // Let the two halves separate (t = 60 L/c: 120 L apart), then time 120 L/c of travel.
  while (sim.time() < 60.0)
    sim.step();
  const double t1 = sim.time(), z1 = centroid();
  while (sim.time() < 180.0)
    sim.step();
  const double t2 = sim.time(), z2 = centroid();
  const double speed = (z2 - z1) / (t2 - t1);
  EXPECT_NEAR(speed / c_p, 1.0, 0.03) << "measured " << speed << ", expected " << c_p;
}

// Central differences conserve, for a linear system, H_n = 1/2 v_{n-1/2}^T M v_{n+1/2} + U(u_n)
// exactly (M (v_{n+3/2} - v_{n-1/2}) = -dt K (u_{n+1} + u_n) gives H_{n+1} = H_n). At strains
// of 1e-7 the lattice is linear to 1e-7, so over 10^4 steps H may drift by < 1e-6 relative;
// K_n + U_n itself oscillates by O((omega dt)^2) and is checked for boundedness only.
TEST(Elastic, UndampedVibrationConservesEnergy) {
  MaterialSpec m = unit_material();
  Simulation sim = make_sim(3, 2, 4, 1.0, m);
  const Lattice& lat = sim.lattice();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1e-7, 1e-7);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    sim.set_half_step_velocity(n, {u(rng), u(rng), u(rng)});
  auto kinetic_cross = [&](const std::vector<Vec3>& a) {
    double s = 0.0;
    for (index_t n = 0; n < lat.num_nodes(); ++n) {
      const Vec3 b = sim.half_step_velocity(n);
      s += 0.5 * sim.mass(n) * (a[n].x * b.x + a[n].y * b.y + a[n].z * b.z);
    }
    return s;
  };
  std::vector<Vec3> v_old(lat.num_nodes());
  double h0 = 0.0, h_max_dev = 0.0, e_min = INFINITY, e_max = 0.0;
  for (int s = 0; s < 10000; ++s) {
    for (index_t n = 0; n < lat.num_nodes(); ++n)
      v_old[n] = sim.half_step_velocity(n);
    sim.step(true);
    const EnergyReport& r = sim.last_report();
    const double h = kinetic_cross(v_old) + r.elastic;
    if (s == 0)
      h0 = h;
    h_max_dev = std::max(h_max_dev, std::abs(h - h0));
    e_min = std::min(e_min, r.kinetic + r.elastic);
    e_max = std::max(e_max, r.kinetic + r.elastic);
  }
  EXPECT_LT(h_max_dev / h0, 1e-6);
  // (omega_max dt)^2 / 4 <= (2 * 0.9)^2 / 4 = 0.81 bounds the oscillation of K_n + U_n.
  EXPECT_LT((e_max - e_min) / h0, 0.81);
}

// Central differences are time-reversible: from (u_N, -v_{N+1/2}) N steps lead back to u_0.
TEST(Elastic, IntegratorIsTimeReversible) {
  MaterialSpec m = unit_material();
  Simulation sim = make_sim(3, 3, 3, 1.0, m);
  const Lattice& lat = sim.lattice();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1e-4, 1e-4);
  std::vector<Vec3> u0(lat.num_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    u0[n] = {u(rng), u(rng), u(rng)};
    sim.set_displacement(n, u0[n]);
    sim.set_half_step_velocity(n, {u(rng), u(rng), u(rng)});
  }
  const int N = 2000;
  for (int s = 0; s < N; ++s)
    sim.step();
  std::vector<Vec3> uN(lat.num_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    uN[n] = sim.displacement(n);
  sim.step(); // gives v_{N+1/2}
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 v = sim.half_step_velocity(n);
    sim.set_displacement(n, uN[n]);
    sim.set_half_step_velocity(n, {-v.x, -v.y, -v.z});
  }
  for (int s = 0; s < N; ++s)
    sim.step();
  double err = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 x = sim.displacement(n);
    err =
        std::max({err, std::abs(x.x - u0[n].x), std::abs(x.y - u0[n].y), std::abs(x.z - u0[n].z)});
  }
  // Round-off only: amplitudes are 1e-4, double precision 1e-16, 4000 steps.
  EXPECT_LT(err, 1e-12);
}

// The forces of the step loop and of the reference per-bar loop equal minus the gradient of
// the stored energy, by central finite differences (error O(h^2) ~ 1e-10 relative), on a
// randomly displaced lattice that includes pre-cracked bars (compression only).
TEST(Elastic, ForcesAreMinusTheEnergyGradient) {
  MaterialSpec m = unit_material(0.2, 4.0);
  Lattice lat0(2, 2, 2, 1.0);
  std::vector<index_t> cracked;
  for (index_t b = 0; b < lat0.num_bars(); b += 7)
    cracked.push_back(b);
  Simulation sim = make_sim(2, 2, 2, 1.0, m, {}, {}, cracked);
  const Lattice& lat = sim.lattice();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.02, 0.02);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    sim.set_displacement(n, {u(rng), u(rng), u(rng)});
  std::vector<double> fx, fy, fz;
  sim.internal_forces(fx, fy, fz);
  double fmax = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    fmax = std::max({fmax, std::abs(fx[n]), std::abs(fy[n]), std::abs(fz[n])});
  const std::vector<Vec3> grad = testing::minus_energy_gradient(sim, 1e-6);
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    EXPECT_NEAR(fx[n], grad[n].x, 1e-7 * fmax) << "node " << n;
    EXPECT_NEAR(fy[n], grad[n].y, 1e-7 * fmax) << "node " << n;
    EXPECT_NEAR(fz[n], grad[n].z, 1e-7 * fmax) << "node " << n;
  }
  // The step loop: from v = 0 without damping, v_{1/2} = dt f / m.
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    sim.set_half_step_velocity(n, {0, 0, 0});
  std::vector<Vec3> u_before(lat.num_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    u_before[n] = sim.displacement(n);
  sim.step();
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 v = sim.half_step_velocity(n);
    const double k = sim.mass(n) / sim.dt();
    EXPECT_NEAR(v.x * k, fx[n], 1e-9 * fmax);
    EXPECT_NEAR(v.y * k, fy[n], 1e-9 * fmax);
    EXPECT_NEAR(v.z * k, fz[n], 1e-9 * fmax);
  }
}

// The run's look for displacements past a limit (time.stop_displacement, the blow-up test)
// names the first node past it, in node order, on any thread count: whether the motions of
// all nodes add up past the limit (as they do in any loaded body) does not matter, only each
// component's size; a NaN counts as past any limit. A body of 24^3 modules (29,449 nodes) so
// that the quick test runs on both threads.
TEST(Simulation, FirstNodeBeyondNamesTheFirstNodePastTheLimit) {
  for (const int threads : {1, 2}) {
    Simulation sim = make_sim(24, 24, 24, 1.0, unit_material(0.2, 4.0));
    sim.set_threads(threads);
    const index_t nn = sim.lattice().num_nodes();
    const double limit = 0.5;
    // Every node at 0.4 along x and -0.4 along z: the sum is some 2e4 times the limit.
    for (index_t n = 0; n < nn; ++n)
      sim.set_displacement(n, {0.4, 0.0, -0.4});
    EXPECT_EQ(sim.first_node_beyond(limit), nn) << threads << " threads";
    const index_t a = nn / 3, b = 2 * nn / 3;
    sim.set_displacement(b, {0.0, -0.6, 0.0});
    EXPECT_EQ(sim.first_node_beyond(limit), b) << threads << " threads";
    sim.set_displacement(a, {0.0, 0.0, std::numeric_limits<double>::quiet_NaN()});
    EXPECT_EQ(sim.first_node_beyond(limit), a) << threads << " threads";
    EXPECT_EQ(sim.first_node_beyond(1e300), a) << threads << " threads";
    sim.set_displacement(a, {0.0, 0.0, 0.0});
    EXPECT_EQ(sim.first_node_beyond(1e300), nn) << threads << " threads";
  }
}

// The step loop gathers whole node rows in one fused pass, a missing link at a row's end
// reading a zero pad; face, edge and end rows take other paths. On every kind of row its
// forces must equal the reference per-bar loop's (internal_forces), which adds each bar's
// force to its two nodes, to the round-off of the intact kernel's 1 / l
// (expect_step_from_rest_gives_bar_forces). A term lost or doubled at a row end would be of
// order fmax (k e L, e ~ 1e-4 here), some 1e10 times more.
TEST(Elastic, StepForcesMatchThePerBarLoopOnEveryKindOfRow) {
  MaterialSpec m = unit_material();
  Simulation sim = make_sim(9, 4, 3, 1.0, m);
  const Lattice& lat = sim.lattice();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1e-4, 1e-4);
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    sim.set_displacement(n, {u(rng), u(rng), u(rng)});
    sim.set_half_step_velocity(n, {0, 0, 0});
  }
  testing::expect_step_from_rest_gives_bar_forces(sim);
}

// A row whose E varies along it (BarRow::own_stiffness) takes, while its bars are pristine and
// below the smallest of their elastic limits, the intact kernel with each bar's own k. Its
// forces must equal the per-bar loop's as the other rows' do, with the same bound (every bar's
// k at most its family's: E at most m.E here), and a report step's elastic energy must be
// U = sum k (l - l0)^2 / 2 over the bars, to rounding (positive terms, 1e-12 relative: some
// 10^3 ulps). A kernel that took one k for the row (the family's, or its first bar's) would be
// off by up to 0.6 of a bar's force and some 0.1 of U, 10^9 times the tolerances.
TEST(Elastic, RowsWhoseStiffnessVariesMatchThePerBarLoop) {
  const MaterialSpec m = unit_material();
  const Lattice lat(9, 4, 3, 1.0);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> g(0.4, 1.0), u(-1e-4, 1e-4);
  BarFields fields;
  for (index_t b = 0; b < lat.num_bars(); ++b)
    fields.E.push_back(g(rng) * m.E);
  Simulation sim = make_sim(9, 4, 3, 1.0, m, {}, {}, {}, fields);
  ASSERT_TRUE(sim.table().per_bar());
  std::vector<Vec3> at(lat.num_nodes());
  for (Vec3& d : at)
    d = {u(rng), u(rng), u(rng)};
  const auto place = [&] {
    for (index_t n = 0; n < lat.num_nodes(); ++n) {
      sim.set_displacement(n, at[n]);
      sim.set_half_step_velocity(n, {0, 0, 0});
    }
  };
  place();
  testing::expect_step_from_rest_gives_bar_forces(sim);
  place();
  double U = 0.0;
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const auto [na, nb] = lat.bar_nodes(b);
    const FamilyInfo& fi = lat.family(lat.bar_address(b).family);
    const Vec3 ua = sim.displacement(na), ub = sim.displacement(nb);
    const Vec3 w{ub.x - ua.x, ub.y - ua.y, ub.z - ua.z};
    const Vec3 d{fi.d0.x + w.x, fi.d0.y + w.y, fi.d0.z + w.z};
    // l - l0 = (l^2 - l0^2) / (l + l0) = w . (w + 2 d0) / (l + l0): no cancellation.
    const double dl =
        (w.x * (w.x + 2 * fi.d0.x) + w.y * (w.y + 2 * fi.d0.y) + w.z * (w.z + 2 * fi.d0.z)) /
        (std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z) + fi.l0);
    U += 0.5 * sim.table().stiffness(lat, b) * dl * dl;
  }
  sim.step(true);
  EXPECT_NEAR(sim.last_report().elastic, U, 1e-12 * U);
}

// SPEC 2: with the lumped masses the stable step is about 0.54 L/c for a free 3-D box and
// about 0.62 L/c for a one-module-thick plate in plane strain; the paper's 0.6 L/c is thus
// refused for the first and accepted for the second. The Lanczos estimate must also lie
// between the Gershgorin bound (a proven lower bound on the step) and 1.0 L/c.
TEST(StableStep, MatchesTheSpecAndBoundsThePaperRule) {
  MaterialSpec m = unit_material();
  Simulation box = make_sim(6, 6, 6, 1.0, m);
  EXPECT_NEAR(box.stable_step().dt, 0.54, 0.02);
  EXPECT_LE(box.stable_step().dt_bound, box.stable_step().dt);
  SolverOptions paper;
  paper.step.rule = TimeStep::Rule::Paper;
  EXPECT_THROW(make_sim(6, 6, 6, 1.0, m, {}, paper), InputError);

  Conditions plane;
  plane.plane_strain_axis = 1;
  Simulation plate = make_sim(12, 1, 12, 1.0, m, plane);
  EXPECT_NEAR(plate.stable_step().dt, 0.62, 0.02);
  Simulation plate_paper = make_sim(12, 1, 12, 1.0, m, plane, paper);
  EXPECT_DOUBLE_EQ(plate_paper.dt(), 0.6);
}

// The Gershgorin bound is by definition the largest absolute row sum, over the free DOF, of
// A = M^-1/2 K M^-1/2 restricted to them (the free-DOF block of K = sum over bars of
// k e e^T in the ++ and -- blocks, -k e e^T across). Assembled here bar by bar, densely, for
// an 11 x 3 x 3 box (rows of 11 and 12 nodes, whose inner nodes the estimate takes together
// where they are alike) with a lighter module in the middle of the body (lighter nodes: larger
// sums, in rows that are not alike) and a fixed DOF inside a row; the two sums differ in their
// order only (relative 1e-12). The Lanczos estimate, a Ritz value of A, lies below the bound,
// and is the same bits whether it allocates its vectors or borrows six arrays.
TEST(StableStep, BoundIsTheLargestRowSumOfTheAssembledMatrix) {
  const MaterialSpec m = unit_material();
  const Lattice lat(11, 3, 3, 1.0);
  BarFields fields;
  fields.rho.assign(lat.num_modules(), m.rho);
  fields.rho[5 + 11 * (1 + 3 * 1)] = 0.4 * m.rho; // module (5, 1, 1)
  Conditions c;
  c.fixed.push_back({NodeSet{"one", {lat.corner(3, 0, 2)}}, DofMask{1}});
  Simulation sim = make_sim(11, 3, 3, 1.0, m, c, {}, {}, fields);
  ASSERT_FALSE(sim.table().per_bar()); // (a box of one material: rows taken together)
  const std::vector<double> mass = sim.masses();
  const std::vector<DofMask> held = sim.held_dofs();
  const std::size_t n = lat.num_nodes(), dofs = 3 * n;
  std::vector<double> A(dofs * dofs, 0.0);
  for (index_t b = 0; b < lat.num_bars(); ++b) {
    const auto [na, nb] = lat.bar_nodes(b);
    const Vec3 pa = lat.position(na), pb = lat.position(nb);
    const double d[3] = {pb.x - pa.x, pb.y - pa.y, pb.z - pa.z};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    const double k = sim.table().stiffness(lat, b);
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) {
        const double kpq = k * d[p] * d[q] / (len * len);
        A[(3 * na + p) * dofs + 3 * na + q] += kpq;
        A[(3 * nb + p) * dofs + 3 * nb + q] += kpq;
        A[(3 * na + p) * dofs + 3 * nb + q] -= kpq;
        A[(3 * nb + p) * dofs + 3 * na + q] -= kpq;
      }
  }
  const auto is_free = [&](std::size_t dof) { return !(held[dof / 3] & (1u << (dof % 3))); };
  double largest = 0.0;
  for (std::size_t r = 0; r < dofs; ++r) {
    if (!is_free(r))
      continue;
    double sum = 0.0;
    for (std::size_t q = 0; q < dofs; ++q)
      if (is_free(q))
        sum += std::abs(A[r * dofs + q]) / std::sqrt(mass[r / 3] * mass[q / 3]);
    largest = std::max(largest, sum);
  }
  const StableStep& s = sim.stable_step();
  EXPECT_NEAR(s.omega_bound * s.omega_bound / largest, 1.0, 1e-12);
  EXPECT_LE(s.omega_max, s.omega_bound);

  std::vector<std::vector<double>> arrays(6, std::vector<double>(n + 5, 1e300));
  StableStepScratch scratch;
  for (int a = 0; a < 6; ++a)
    scratch.v[a] = arrays[static_cast<std::size_t>(a)].data();
  const StableStep own = compute_stable_step(lat, sim.table(), mass, held);
  const StableStep lent = compute_stable_step(lat, sim.table(), mass, held, nullptr, &scratch);
  EXPECT_EQ(own.omega_max, lent.omega_max);
  EXPECT_EQ(own.omega_bound, lent.omega_bound);
  EXPECT_EQ(own.iterations, lent.iterations);
  EXPECT_EQ(own.omega_max, s.omega_max);
}

TEST(StableStep, UnstableStepIsRefusedAndAStepJustBelowStaysBounded) {
  MaterialSpec m = unit_material();
  Simulation ref = make_sim(3, 3, 3, 1.0, m);
  const double limit = ref.stable_step().dt;
  SolverOptions over;
  over.step.rule = TimeStep::Rule::Given;
  over.step.dt = 1.02 * limit;
  try {
    make_sim(3, 3, 3, 1.0, m, {}, over);
    FAIL() << "dt above the limit was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("stable limit"), std::string::npos) << e.what();
  }
  // Just below the limit the integration stays bounded.
  SolverOptions at;
  at.step.rule = TimeStep::Rule::Given;
  at.step.dt = 0.99 * limit;
  Simulation good = make_sim(3, 3, 3, 1.0, m, {}, at);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1e-6, 1e-6);
  for (index_t n = 0; n < good.lattice().num_nodes(); ++n)
    good.set_half_step_velocity(n, {u(rng), u(rng), u(rng)});
  good.step(true);
  const double e0 = good.last_report().kinetic + good.last_report().elastic;
  for (int s = 0; s < 3000; ++s)
    good.step();
  good.step(true);
  EXPECT_LT(good.last_report().kinetic + good.last_report().elastic, 10 * e0);
}

} // namespace
} // namespace ldem
