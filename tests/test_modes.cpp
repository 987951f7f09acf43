// The lowest eigenfrequencies of the lattice (solver/modes.hpp).
#include "helpers.hpp"
#include "solver/modes.hpp"
#include "util/error.hpp"

// As in solver/modes.cpp, which this program links: one version of Eigen's templates.
#define EIGEN_DONT_PARALLELIZE
// GCC 12's AVX-512 headers trip this warning in Eigen's vectorised kernels (a known false alarm).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <numbers>
#include <omp.h>

namespace ldem {
namespace {

using testing::face;
using testing::make_sim;
using testing::unit_material;

// Columns of 1 x 1 x N modules with every node's x and y held (uniaxial strain): rods with the
// lattice's confined (P-wave) modulus C3333 = phi E (2 + 8 delta / 9) = 1.2 E (nu = 0.25:
// delta = 1.125, phi = 0.4), wave speed c_p = sqrt(1.2 E / rho), height H = N L.
Conditions confined_column(const Lattice& lat, bool fixed_base = true) {
  Conditions c;
  c.fixed.push_back({make_node_set("all", select_all(lat), "all nodes"), kDofX | kDofY});
  if (fixed_base)
    c.fixed.push_back({face(lat, Face::ZMin), kDofAll});
  return c;
}

std::vector<Mode> column_modes(index_t N, double L, const MaterialSpec& m, bool fixed_base,
                               int count) {
  const Lattice probe(1, 1, N, L);
  Simulation sim = make_sim(1, 1, N, L, m, confined_column(probe, fixed_base));
  return lowest_modes(sim, count);
}

MaterialSpec concrete(double L) {
  MaterialSpec m = unit_material(0.05, 4.0, L);
  m.E = 30e9;
  m.Gf *= m.E; // the same K_r as with E = 1
  m.rho = 2400.0;
  return m;
}

// Free at both ends: f_n = n c_p / (2 H) (after the rigid translation along z). The lattice's
// error is its dispersion, of order (k L)^2: a chain of spacing h has omega lowered by
// sin(k h / 2) / (k h / 2) = 1 - (k h)^2 / 24 + ..., and k L = 3 pi / 40 = 0.24 for the third
// mode of 40 modules; measured -0.02, -0.08 and -0.17 %, well inside 0.5 %.
TEST(Modes, ConfinedFreeColumnMatchesTheFreeFreeRod) {
  const index_t N = 40;
  const double L = 0.01;
  const MaterialSpec m = concrete(L);
  const std::vector<Mode> modes = column_modes(N, L, m, false, 4);
  ASSERT_EQ(modes.size(), 4u);
  EXPECT_TRUE(modes[0].zero_energy);
  const double c_p = std::sqrt(1.2 * m.E / m.rho), H = N * L;
  for (int n = 1; n <= 3; ++n) {
    const Mode& mode = modes[static_cast<std::size_t>(n)];
    const double expected = n * c_p / (2 * H);
    EXPECT_FALSE(mode.zero_energy);
    EXPECT_NEAR(mode.frequency_hz, expected, 0.005 * expected) << "mode " << n;
    EXPECT_NEAR(mode.omega, 2 * std::numbers::pi * mode.frequency_hz, 1e-12 * mode.omega);
    // Only z is free: all kinetic energy is in z.
    EXPECT_DOUBLE_EQ(mode.participation[2], 1.0);
    EXPECT_EQ(mode.participation[0], 0.0);
    EXPECT_EQ(mode.participation[1], 0.0);
  }
}

// Fixed at the base (its corner nodes), free at the top: f_n = (2n - 1) c_p / (4 H). Besides
// the dispersion above, a fixed face is a softer support than a clamp: only its corners are
// held, and the first centre plane, half a module up, reaches them through diagonals only. The
// column then vibrates as a rod about 0.29 L taller (measured for N = 10 to 160; a free end
// adds nothing, two fixed ends twice as much), so the frequencies lie about 0.29 L / H below
// the rod's: -0.72, -0.76, -0.83 % for N = 40. Checked here: within 1 % (and below); the ratios
// f_n / f_1 = 2n - 1, where the end effect cancels, within 0.2 %; and the extrapolation
// 2 f(2N) - f(N), which removes an error proportional to 1 / N, within 0.1 %.
TEST(Modes, ConfinedColumnMatchesTheFixedFreeRod) {
  const index_t N = 40;
  const double L = 0.01;
  const MaterialSpec m = concrete(L);
  const std::vector<Mode> modes = column_modes(N, L, m, true, 3);
  const std::vector<Mode> fine = column_modes(2 * N, L * 0.5, m, true, 3); // same H
  ASSERT_EQ(modes.size(), 3u);
  const double c_p = std::sqrt(1.2 * m.E / m.rho), H = N * L;
  for (int n = 1; n <= 3; ++n) {
    const Mode& mode = modes[static_cast<std::size_t>(n - 1)];
    const double expected = (2 * n - 1) * c_p / (4 * H);
    EXPECT_FALSE(mode.zero_energy);
    EXPECT_NEAR(mode.frequency_hz, expected, 0.01 * expected) << "mode " << n;
    EXPECT_LT(mode.frequency_hz, expected) << "mode " << n;
    EXPECT_NEAR(mode.frequency_hz / modes[0].frequency_hz, 2 * n - 1, 0.002 * (2 * n - 1))
        << "mode " << n;
    const double extrapolated =
        2 * fine[static_cast<std::size_t>(n - 1)].frequency_hz - mode.frequency_hz;
    EXPECT_NEAR(extrapolated, expected, 0.001 * expected) << "mode " << n;
  }
}

// A free body has six rigid-body modes (three translations, three rotations) at zero
// frequency; the seventh stores energy.
TEST(Modes, FreeBodyHasSixRigidBodyModes) {
  Simulation sim = make_sim(4, 3, 2, 1.0, unit_material());
  const std::vector<Mode> modes = lowest_modes(sim, 8);
  ASSERT_EQ(modes.size(), 8u);
  for (int i = 0; i < 6; ++i) {
    EXPECT_TRUE(modes[i].zero_energy) << "mode " << i + 1;
    EXPECT_EQ(modes[i].frequency_hz, 0.0);
  }
  EXPECT_FALSE(modes[6].zero_energy);
  EXPECT_GT(modes[6].frequency_hz, 0.01); // E = rho = L = 1: c / (2 pi x 4 L) is about 0.04
  EXPECT_GE(modes[7].frequency_hz, modes[6].frequency_hz);
  for (const Mode& mode : modes)
    EXPECT_NEAR(mode.participation[0] + mode.participation[1] + mode.participation[2], 1.0, 1e-12);
}

// Against a dense solution of the same problem, with K built column by column from the
// simulation's own internal forces (f_int = -K u for a small u), on a small body with some
// DOF held (a fixed face, and plane strain).
TEST(Modes, MatchesADenseEigenSolution) {
  MaterialSpec m = unit_material();
  m.Gf *= 100.0; // stays elastic
  const Lattice probe(2, 2, 3, 1.0);
  Conditions c;
  c.fixed.push_back({face(probe, Face::XMax), kDofAll});
  c.plane_strain_axis = 1;
  Simulation sim = make_sim(2, 2, 3, 1.0, m, c);
  const Lattice& lat = sim.lattice();
  std::vector<std::pair<index_t, int>> free;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    for (int d = 0; d < 3; ++d)
      if (!(sim.held(n) & (1u << d)))
        free.emplace_back(n, d);
  ASSERT_EQ(free.size(), free_dof_count(sim));
  const Eigen::Index nf = static_cast<Eigen::Index>(free.size());
  Eigen::MatrixXd K(nf, nf);
  const double eps = 1e-9;
  std::vector<double> fx, fy, fz;
  for (Eigen::Index j = 0; j < nf; ++j) {
    const auto [n, d] = free[static_cast<std::size_t>(j)];
    sim.set_displacement(n, {d == 0 ? eps : 0.0, d == 1 ? eps : 0.0, d == 2 ? eps : 0.0});
    sim.internal_forces(fx, fy, fz);
    sim.set_displacement(n, {});
    for (Eigen::Index i = 0; i < nf; ++i) {
      const auto [ni, di] = free[static_cast<std::size_t>(i)];
      K(i, j) = -(di == 0 ? fx[ni] : di == 1 ? fy[ni] : fz[ni]) / eps;
    }
  }
  Eigen::MatrixXd A(nf, nf);
  for (Eigen::Index i = 0; i < nf; ++i)
    for (Eigen::Index j = 0; j < nf; ++j)
      A(i, j) = 0.5 * (K(i, j) + K(j, i)) /
                std::sqrt(sim.mass(free[static_cast<std::size_t>(i)].first) *
                          sim.mass(free[static_cast<std::size_t>(j)].first));
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> dense(A);
  const std::vector<Mode> modes = lowest_modes(sim, 6);
  for (int i = 0; i < 6; ++i) {
    const double f = std::sqrt(dense.eigenvalues()[i]) / (2 * std::numbers::pi);
    EXPECT_NEAR(modes[i].frequency_hz, f, 1e-6 * f) << "mode " << i + 1;
    // Participation from the dense eigenvector (phi = M^-1/2 psi: m phi^2 = psi^2).
    double share[3] = {0, 0, 0};
    for (Eigen::Index k = 0; k < nf; ++k)
      share[free[static_cast<std::size_t>(k)].second] +=
          dense.eigenvectors()(k, i) * dense.eigenvectors()(k, i);
    for (int d = 0; d < 3; ++d)
      EXPECT_NEAR(modes[i].participation[d], share[d], 1e-5) << "mode " << i + 1 << " dof " << d;
    EXPECT_EQ(modes[i].participation[1], 0.0); // plane strain along y
  }
}

// Pre-cracked (broken) bars carry no stiffness in the modes: a column cut through by a
// pre-crack leaves its upper part free to move along z (one zero-energy mode), and its lowest
// elastic mode is that of the lower part, a fixed-free column half as tall.
TEST(Modes, PrecrackedBarsAreLeftOut) {
  const index_t N = 40;
  const double L = 1.0;
  MaterialSpec m = unit_material();
  const Lattice probe(1, 1, N, L);
  std::vector<index_t> cut; // every bar crossing the plane z = 20.25 L
  for (index_t b = 0; b < probe.num_bars(); ++b) {
    const auto [a, c] = probe.bar_nodes(b);
    const double za = probe.position(a).z, zc = probe.position(c).z;
    if (std::min(za, zc) < 20.25 * L && std::max(za, zc) > 20.25 * L)
      cut.push_back(b);
  }
  Simulation sim = make_sim(1, 1, N, L, m, confined_column(probe), {}, cut);
  const std::vector<Mode> modes = lowest_modes(sim, 2);
  EXPECT_TRUE(modes[0].zero_energy);
  ASSERT_FALSE(modes[1].zero_energy);
  // The cut leaves the lower 20 modules (corners up to z = 20 L, centres up to 19.5 L) as a
  // fixed-free column of 20 L, less the fixed-base effect of about 0.29 L / 20 L (see above).
  // Its top corners keep their share of the module above, rho L^3 / 4 in all, a tip mass of
  // mu = 1 / 80 of the column's, which lowers the first mode by mu (beta tan beta = 1 / mu with
  // beta = pi / 2 (1 - mu) to first order): -1.45 % - 1.25 %.
  const double rod = std::sqrt(1.2) / (4 * 20.0 * L);
  EXPECT_NEAR(modes[1].frequency_hz, rod * (1.0 - 0.29 / 20.0 - 1.0 / 80.0), 0.005 * rod);
}

// Load shares (Mode::load_share) -------------------------------------------------------------

NodalLoad face_load(const Lattice& lat, Face f, Vec3 force) {
  return {face(lat, f), force, TimeFunction({Constant{1.0}})};
}

// End-loaded confined columns. A uniform rod with a force P at an end, fixed at the other,
// has the static work P^2 H / EA, and mode n (phi = sqrt(2 / m_rod) sin(k_n z), k_n = (2n - 1)
// pi / 2H) carries 2 P^2 / m_rod / omega_n^2 of it: the share 8 / (pi^2 (2n - 1)^2), whatever
// H (81.06, 9.01, 3.24 %). Free at both ends and pulled by P at each, the same for the odd
// modes n = 2m - 1 (k_n = n pi / H; the even ones are not excited). On the lattice:
//  - End effects. Where a force enters the column through a corner plane (a loaded end, or the
//    fixed base), the centre chain starts half a module away, reached through diagonals only;
//    there the column is about 0.29 L longer than its H (the fixed-base frequencies above).
//    The modes see that length at a fixed base only (a free end has no strain in the modes),
//    the static response at the base and at every loaded end. As the shares do not depend on
//    the rod's length, the fixed base cancels and each loaded end leaves a factor
//    H_modes / H_static = 1 - 0.29 L / H: -0.72 % for N = 40 fixed-free, -1.45 % free-free.
//  - Dispersion: a chain of N springs has the shares 1 / (2 N^2 sin^2(theta_n / 2)) exactly
//    (theta_n = (2n - 1) pi / 2N), the rod's over the frequency error squared, since an end
//    force's modal forces are exact. With the lattice's dispersion -(k L)^2 / 32 (-0.17 % for
//    k L = 0.24, above) the shares grow by (k L)^2 / 16: +0.01, +0.09, +0.24 % for N = 40.
// Measured for N = 20 to 160: the share over the rod's, less (k L)^2 / 16, is 1 - c L / H with
// c = 0.281 to 0.288 fixed-free (0.285 to 0.287 for N = 40) and about twice that free-free
// (0.569 to 0.573 for N = 40). Checked, with e loaded ends: within e % of the rod's and below
// it, and within 0.05 % of rod (1 - e 0.29 L / H) (1 + (k L)^2 / 16); what that leaves out is
// (0.29 e - c) L / H, at most 2.7e-4 for N = 40, and higher orders of k L.
double rod_share(int n) {
  return 8.0 / (std::numbers::pi * std::numbers::pi * (2 * n - 1) * (2 * n - 1));
}

TEST(Modes, LoadSharesOfEndLoadedColumnsMatchTheRod) {
  const index_t N = 40;
  const double L = 0.01, H = N * L;
  const MaterialSpec m = concrete(L);
  const Lattice probe(1, 1, N, L);
  for (const bool fixed_base : {true, false}) {
    Conditions c = confined_column(probe, fixed_base);
    c.loads.push_back(face_load(probe, Face::ZMax, {0.0, 0.0, 1e3}));
    if (!fixed_base)
      c.loads.push_back(face_load(probe, Face::ZMin, {0.0, 0.0, -1e3}));
    Simulation sim = make_sim(1, 1, N, L, m, c);
    const std::vector<Mode> modes = lowest_modes(sim, 7);
    const int loaded_ends = fixed_base ? 1 : 2;
    for (int n = 1; n <= 3; ++n) {
      // Fixed-free: the modes 1, 2, 3; free-free: after the translation, every other one.
      const std::size_t i = fixed_base ? n - 1 : 2 * n - 1;
      const double kL = (2 * n - 1) * std::numbers::pi * L / (fixed_base ? 2 * H : H);
      const double rod = rod_share(n);
      const double lattice = rod * (1 - loaded_ends * 0.29 * L / H) * (1 + kL * kL / 16);
      const double share = modes[i].load_share;
      const char* what = fixed_base ? " fixed" : " free";
      EXPECT_NEAR(share, rod, 0.01 * loaded_ends * rod) << "mode " << n << what;
      EXPECT_LT(share, rod) << "mode " << n << what;
      EXPECT_NEAR(share, lattice, 5e-4 * lattice) << "mode " << n << what;
      if (!fixed_base) {
        EXPECT_LT(modes[i + 1].load_share, 1e-12) << "even mode " << 2 * n << what;
      }
    }
    if (!fixed_base) {
      EXPECT_TRUE(modes[0].zero_energy);
      EXPECT_EQ(modes[0].load_share, 0.0); // the pull is in equilibrium
    }
  }
}

// The dense eigenvectors of A = M^-1/2 K M^-1/2, K assembled from the bars as in modes.cpp
// (k e e^T per unbroken bar, checked against the internal forces by MatchesADenseEigenSolution),
// here exactly rather than by finite differences, which are accurate to 1e-7 only.
struct DenseModes {
  std::vector<std::pair<index_t, int>> free; // (node, axis) per free DOF
  Eigen::VectorXd lambda;
  Eigen::MatrixXd psi;
};

DenseModes dense_modes(const Simulation& sim) {
  const Lattice& lat = sim.lattice();
  DenseModes d;
  std::vector<Eigen::Index> index(3 * static_cast<std::size_t>(lat.num_nodes()), -1);
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    for (int a = 0; a < 3; ++a)
      if (!(sim.held(n) & (1u << a))) {
        index[3 * static_cast<std::size_t>(n) + a] = static_cast<Eigen::Index>(d.free.size());
        d.free.emplace_back(n, a);
      }
  const Eigen::Index nf = static_cast<Eigen::Index>(d.free.size());
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nf, nf);
  for (index_t bar = 0; bar < lat.num_bars(); ++bar) {
    if (sim.bar_state(bar) == BarState::Broken)
      continue;
    const FamilyInfo& fi = lat.family(lat.bar_address(bar).family);
    const double k = sim.table().stiffness(lat, bar);
    const auto [a, b] = lat.bar_nodes(bar);
    const index_t nodes[2] = {a, b};
    for (int p = 0; p < 2; ++p)
      for (int q = 0; q < 2; ++q)
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const Eigen::Index i = index[3 * static_cast<std::size_t>(nodes[p]) + r];
            const Eigen::Index j = index[3 * static_cast<std::size_t>(nodes[q]) + c];
            if (i >= 0 && j >= 0)
              A(i, j) += (p == q ? 1.0 : -1.0) * k * fi.d0[r] * fi.d0[c] / (fi.l0 * fi.l0) /
                         std::sqrt(sim.mass(nodes[p]) * sim.mass(nodes[q]));
          }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(A);
  d.lambda = eig.eigenvalues();
  d.psi = eig.eigenvectors();
  return d;
}

// The load shares of all the dense modes (0 for the zero-energy ones, lambda below `zero`).
Eigen::VectorXd dense_load_shares(const DenseModes& d, const Simulation& sim,
                                  const std::vector<NodalLoad>& loads, double zero = 0.0) {
  const Eigen::Index nf = d.lambda.size();
  Eigen::VectorXd g = Eigen::VectorXd::Zero(nf); // M^-1/2 F on the free DOF
  for (const NodalLoad& load : loads)
    for (index_t n : load.set.nodes)
      for (Eigen::Index i = 0; i < nf; ++i)
        if (d.free[static_cast<std::size_t>(i)].first == n)
          g[i] += load.force[d.free[static_cast<std::size_t>(i)].second] / std::sqrt(sim.mass(n));
  const Eigen::VectorXd f = d.psi.transpose() * g;
  Eigen::VectorXd terms(nf);
  for (Eigen::Index i = 0; i < nf; ++i)
    terms[i] = d.lambda[i] <= zero ? 0.0 : f[i] * f[i] / d.lambda[i];
  return terms / terms.sum();
}

// The shares of all the modes sum to 1: on a small body (72 free DOF) the solver finds all
// but the highest mode; with that mode's share from the dense solution the sum is 1 within
// 1e-9. Each share matches the dense one within 1e-9 too, but only summed over a multiple
// eigenvalue (two pairs here): there the modes are any orthonormal basis of their space, and
// so are their shares.
TEST(Modes, LoadSharesOfAllModesSumToOne) {
  MaterialSpec m = unit_material();
  const Lattice probe(2, 2, 3, 1.0);
  Conditions c;
  c.fixed.push_back({face(probe, Face::XMax), kDofAll});
  c.plane_strain_axis = 1;
  c.loads.push_back(face_load(probe, Face::ZMax, {0.3, 0.0, 1.0}));
  c.loads.push_back(face_load(probe, Face::XMin, {-0.5, 0.7, 0.2})); // y: a held DOF
  Simulation sim = make_sim(2, 2, 3, 1.0, m, c);
  const DenseModes d = dense_modes(sim);
  const Eigen::Index nf = d.lambda.size();
  ASSERT_EQ(static_cast<std::size_t>(nf), free_dof_count(sim));
  ASSERT_EQ(nf, 72);
  const Eigen::VectorXd dense = dense_load_shares(d, sim, c.loads);
  ASSERT_GT(d.lambda[nf - 1] - d.lambda[nf - 2], 1e-6 * d.lambda[nf - 1]); // a single top mode
  const std::vector<Mode> modes = lowest_modes(sim, static_cast<int>(nf) - 1);
  double sum = dense[nf - 1];
  for (const Mode& mode : modes)
    sum += mode.load_share;
  EXPECT_NEAR(sum, 1.0, 1e-9);
  EXPECT_GT(dense[nf - 1], 1e-3); // the remainder is not negligible: the sum tests it
  int multiple = 0;
  for (Eigen::Index i = 0; i + 1 < nf;) {
    Eigen::Index j = i + 1; // the modes [i, j) share an eigenvalue
    while (j + 1 < nf && d.lambda[j] - d.lambda[i] <= 1e-8 * d.lambda[i])
      ++j;
    double lib = 0.0;
    for (Eigen::Index k = i; k < j; ++k)
      lib += modes[static_cast<std::size_t>(k)].load_share;
    EXPECT_NEAR(lib, dense.segment(i, j - i).sum(), 1e-9) << "modes " << i + 1 << " to " << j;
    multiple += j - i > 1;
    i = j;
  }
  EXPECT_EQ(multiple, 2);
}

// A plate in plane strain (x, z), fixed at x+, opened by equal and opposite loads on its top
// and bottom faces: the load is symmetric about the mid-plane z = 4.5 L, and the first mode,
// bending, antisymmetric (u_z of the same sign above and below), so its modal force vanishes.
TEST(Modes, ASymmetricLoadDoesNotExciteTheBendingMode) {
  const Lattice probe(20, 1, 9, 1.0);
  Conditions c;
  c.fixed.push_back({face(probe, Face::XMax), kDofAll});
  c.plane_strain_axis = 1;
  c.loads.push_back(face_load(probe, Face::ZMax, {0.0, 0.0, 1.0}));
  c.loads.push_back(face_load(probe, Face::ZMin, {0.0, 0.0, -1.0}));
  Simulation sim = make_sim(20, 1, 9, 1.0, unit_material(), c);
  const std::vector<Mode> modes = lowest_modes(sim, 8);
  EXPECT_LT(modes[0].load_share, 1e-6);
}

// A free body pulled at both ends, against the dense solution. Its elastic modes need the
// second, deflated run (modes.cpp, DeflatedLu): without it they were off by 1e-3. The shares are
// defined for loads in equilibrium (the rigid-body modes then carry none of the work), not for
// a net force; not either when only zero-energy modes are found.
TEST(Modes, FreeBodyMatchesTheDenseSolution) {
  const Lattice probe(4, 3, 2, 1.0);
  Conditions pulled;
  pulled.loads.push_back(face_load(probe, Face::XMax, {1.0, 0.0, 0.0}));
  pulled.loads.push_back(face_load(probe, Face::XMin, {-1.0, 0.0, 0.0}));
  Simulation sim = make_sim(4, 3, 2, 1.0, unit_material(), pulled);
  const DenseModes d = dense_modes(sim);
  const Eigen::VectorXd dense = dense_load_shares(d, sim, pulled.loads, 1e-10);
  const std::vector<Mode> modes = lowest_modes(sim, 14);
  for (std::size_t i = 0; i < modes.size(); ++i) {
    const Eigen::Index k = static_cast<Eigen::Index>(i);
    EXPECT_EQ(modes[i].zero_energy, i < 6) << "mode " << i + 1;
    if (i >= 6) {
      EXPECT_NEAR(modes[i].omega * modes[i].omega, d.lambda[k], 1e-9 * d.lambda[k])
          << "mode " << i + 1;
    }
    EXPECT_NEAR(modes[i].load_share, dense[k], 1e-9) << "mode " << i + 1;
  }
  EXPECT_EQ(modes[0].load_share, 0.0);
  EXPECT_GT(modes[12].load_share, 0.4); // the first stretching mode
  EXPECT_GT(modes[12].participation[0], 0.8);

  Conditions pushed; // a net force: no static response
  pushed.loads.push_back(face_load(probe, Face::XMax, {1.0, 0.0, 0.0}));
  for (const Mode& mode : lowest_modes(make_sim(4, 3, 2, 1.0, unit_material(), pushed), 8))
    EXPECT_TRUE(std::isnan(mode.load_share));
  for (const Mode& mode : lowest_modes(make_sim(4, 3, 2, 1.0, unit_material()), 8))
    EXPECT_TRUE(std::isnan(mode.load_share)); // no loads
  for (const Mode& mode : lowest_modes(sim, 6))
    EXPECT_TRUE(std::isnan(mode.load_share)); // only the rigid-body modes
}

TEST(Modes, RefusesACountOutOfRange) {
  const Lattice probe(1, 1, 4, 1.0);
  Simulation sim = make_sim(1, 1, 4, 1.0, unit_material(), confined_column(probe));
  const std::size_t n_free = free_dof_count(sim);
  EXPECT_EQ(n_free, 20u); // z of the 4 corners of each plane z = L..4L, and of the 4 centres
  EXPECT_THROW(lowest_modes(sim, 0), InputError);
  EXPECT_THROW(lowest_modes(sim, static_cast<int>(n_free)), InputError);
  try {
    lowest_modes(sim, -1);
    ADD_FAILURE() << "count -1 accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("free DOF (20)"), std::string::npos) << e.what();
  }
  EXPECT_EQ(lowest_modes(sim, static_cast<int>(n_free) - 1).size(), n_free - 1);
}

// The modes are computed on one thread: the same digits whatever the thread count.
TEST(Modes, IndependentOfTheThreadCount) {
  MaterialSpec m = unit_material();
  const Lattice probe(12, 1, 8, 1.0);
  Conditions c;
  c.fixed.push_back({face(probe, Face::XMax), kDofAll});
  c.plane_strain_axis = 1;
  const int before = omp_get_max_threads();
  std::vector<std::vector<Mode>> runs;
  for (int threads : {1, 4}) {
    omp_set_num_threads(threads);
    Simulation sim = make_sim(12, 1, 8, 1.0, m, c);
    runs.push_back(lowest_modes(sim, 5));
  }
  omp_set_num_threads(before);
  for (std::size_t i = 0; i < runs[0].size(); ++i) {
    EXPECT_EQ(runs[0][i].frequency_hz, runs[1][i].frequency_hz) << "mode " << i + 1;
    EXPECT_EQ(runs[0][i].participation, runs[1][i].participation) << "mode " << i + 1;
  }
}

} // namespace
} // namespace ldem
