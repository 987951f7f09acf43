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
