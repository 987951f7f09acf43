// The first module layer along a face (docs/model.md, "The first layer along a face"): a
// boundary module's centre node lacks the centre-centre bar that would cross the face, so a
// homogeneous strain leaves a force on it, and the layer is softer than the interior.
#include "helpers.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <vector>

namespace ldem {
namespace {

using testing::make_sim;
using testing::unit_material;

// Under u = eps X every bar's strain is d.eps.d (to first order), and the bars meeting at an
// interior node come in opposite pairs with equal forces: no node of the interior feels a
// force. A boundary module's centre node misses the centre-centre bar through the face with
// outward normal e_a; its partner on the other side, of area phi L^2 (phi = 0.4 at
// nu = 0.25), length L and strain eps_aa, pulls it inwards with phi E L^2 eps_aa. So the
// centre node of a module on face a (outward sign s = +-1) carries -s phi E L^2 eps_aa along
// a, summed over the faces the module touches. For a plate pulled along z (uniaxial stress,
// eps_xx = -nu eps_zz) that is -0.1 E L^2 eps_zz on its free faces x: the boundary layer of
// the review.
TEST(BoundaryLayer, AffineStrainLeavesTheMissingBarForceOnBoundaryCentres) {
  const double L = 0.01, E = 30e9;
  MaterialSpec m = unit_material();
  m.E = E;
  m.Gf = 1e6; // K_r >> 1: elastic
  m.e_p = 1e-2;
  Simulation sim = make_sim(4, 3, 5, L, m);
  const Lattice& lat = sim.lattice();
  // A general symmetric strain; geometric nonlinearity is O(eps) = 1e-6 relative.
  const double eps[3][3] = {
      {2e-6, 0.7e-6, -0.4e-6}, {0.7e-6, -1e-6, 0.9e-6}, {-0.4e-6, 0.9e-6, 1.5e-6}};
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 X = lat.position(n);
    sim.set_displacement(n, {eps[0][0] * X.x + eps[0][1] * X.y + eps[0][2] * X.z,
                             eps[1][0] * X.x + eps[1][1] * X.y + eps[1][2] * X.z,
                             eps[2][0] * X.x + eps[2][1] * X.y + eps[2][2] * X.z});
  }
  std::vector<double> fx, fy, fz;
  sim.internal_forces(fx, fy, fz);
  const double phi = 0.4, scale = phi * E * L * L * 2e-6; // the largest expected force
  const std::array<index_t, 3> n = lat.modules();
  int boundary_centres = 0;
  for (index_t k = 0; k < n[2]; ++k)
    for (index_t j = 0; j < n[1]; ++j)
      for (index_t i = 0; i < n[0]; ++i) {
        const index_t c = lat.centre(i, j, k);
        const index_t idx[3] = {i, j, k};
        double expected[3] = {0.0, 0.0, 0.0};
        for (int a = 0; a < 3; ++a) {
          if (idx[a] == 0) // face a-, outward normal -e_a: the force points along +e_a
            expected[a] += phi * E * L * L * eps[a][a];
          if (idx[a] == n[a] - 1) // face a+
            expected[a] -= phi * E * L * L * eps[a][a];
        }
        boundary_centres += expected[0] != 0.0 || expected[1] != 0.0 || expected[2] != 0.0;
        EXPECT_NEAR(fx[c], expected[0], 1e-5 * scale) << "module " << i << " " << j << " " << k;
        EXPECT_NEAR(fy[c], expected[1], 1e-5 * scale) << "module " << i << " " << j << " " << k;
        EXPECT_NEAR(fz[c], expected[2], 1e-5 * scale) << "module " << i << " " << j << " " << k;
      }
  EXPECT_EQ(boundary_centres, 4 * 3 * 5 - 2 * 1 * 3);
  // Corner nodes off the box's faces feel nothing either.
  for (index_t k = 1; k < n[2]; ++k)
    for (index_t j = 1; j < n[1]; ++j)
      for (index_t i = 1; i < n[0]; ++i) {
        const index_t c = lat.corner(i, j, k);
        EXPECT_NEAR(fx[c], 0.0, 1e-5 * scale);
        EXPECT_NEAR(fy[c], 0.0, 1e-5 * scale);
        EXPECT_NEAR(fz[c], 0.0, 1e-5 * scale);
      }
}

// Dense Gaussian elimination with partial pivoting (a few dozen unknowns).
std::vector<double> solve(std::vector<std::vector<double>> a, std::vector<double> b) {
  const std::size_t n = b.size();
  for (std::size_t c = 0; c < n; ++c) {
    std::size_t p = c;
    for (std::size_t r = c + 1; r < n; ++r)
      if (std::abs(a[r][c]) > std::abs(a[p][c]))
        p = r;
    std::swap(a[c], a[p]);
    std::swap(b[c], b[p]);
    for (std::size_t r = c + 1; r < n; ++r) {
      const double f = a[r][c] / a[c][c];
      for (std::size_t q = c; q < n; ++q)
        a[r][q] -= f * a[c][q];
      b[r] -= f * b[c];
    }
  }
  std::vector<double> x(n);
  for (std::size_t c = n; c-- > 0;) {
    double s = b[c];
    for (std::size_t q = c + 1; q < n; ++q)
      s -= a[c][q] * x[q];
    x[c] = s / a[c][c];
  }
  return x;
}

// The static strain of the layers of a column of N modules in uniaxial strain along z (every
// x held, plane strain in y), its end faces held at z = -U and +U, from an independent model:
// with x and y held the lattice moves level by level, so each level of corner nodes (u_k, k =
// 0..N) and of centre nodes (c_k, k = 0..N-1) is one unknown, tied per module by springs of
// the axial stiffness projected on z (E = L = 1): the module's edges phi = 0.4 (four quarter
// edges of 0.4 each), the centre-centre bar phi = 0.4, and 4 + 4 diagonals of
// E A_d / l_d = (4/3) delta phi = 0.6 each, cos^2 = 1/3 on z: 0.8 between c_k and u_k, 0.8
// between c_k and u_{k+1}. With `grip` the centres c_0 and c_{N-1} are held at the affine
// position too. Returns the edge strains (u_{k+1} - u_k) over the mean strain 2U / N.
std::vector<double> chain_layer_strains(int N, bool grip) {
  const double ke = 0.4, kc = 0.4, kd = 0.8, U = 0.5;
  const int n = (N + 1) + N;
  auto C = [&](int k) { return N + 1 + k; };
  std::vector<std::vector<double>> K(n, std::vector<double>(n, 0.0));
  auto spring = [&](int a, int b, double k) {
    K[a][a] += k;
    K[b][b] += k;
    K[a][b] -= k;
    K[b][a] -= k;
  };
  for (int k = 0; k < N; ++k) {
    spring(k, k + 1, ke);
    spring(C(k), k, kd);
    spring(C(k), k + 1, kd);
  }
  for (int k = 0; k + 1 < N; ++k)
    spring(C(k), C(k + 1), kc);
  std::vector<double> x(n, 0.0);
  std::vector<bool> held(n, false);
  auto hold = [&](int i, double v) {
    held[i] = true;
    x[i] = v;
  };
  hold(0, -U);
  hold(N, U);
  if (grip) {
    hold(C(0), -U + 2 * U * 0.5 / N);
    hold(C(N - 1), U - 2 * U * 0.5 / N);
  }
  std::vector<int> free;
  for (int i = 0; i < n; ++i)
    if (!held[i])
      free.push_back(i);
  std::vector<std::vector<double>> A(free.size(), std::vector<double>(free.size()));
  std::vector<double> b(free.size(), 0.0);
  for (std::size_t r = 0; r < free.size(); ++r) {
    for (std::size_t c = 0; c < free.size(); ++c)
      A[r][c] = K[free[r]][free[c]];
    for (int i = 0; i < n; ++i)
      if (held[i])
        b[r] -= K[free[r]][i] * x[i];
  }
  const std::vector<double> y = solve(A, b);
  for (std::size_t r = 0; r < free.size(); ++r)
    x[free[r]] = y[r];
  std::vector<double> e(N);
  for (int k = 0; k < N; ++k)
    e[k] = (x[k + 1] - x[k]) / (2 * U / N);
  return e;
}

// A column of 3 x 1 x 10 modules in uniaxial strain, its end faces' corner nodes held at
// +-U, relaxed from the affine field by heavy damping to its static state. Without a grip the
// centre nodes of the end layers, pulled inwards by their one centre-centre bar, lag behind,
// and the end layers' edges stretch by 1.199 times the mean strain (the chain model: the
// interior 0.945); holding those centre nodes at the affine position as well (the remedy of a
// driven layer: a [[velocity]] on the face's `face_centres` set) leaves the affine field in
// equilibrium, every layer at 1.
TEST(BoundaryLayer, EndLayerOfAPulledColumnMatchesTheChainModelAndAGripRemovesIt) {
  const int N = 10;
  const std::vector<double> free_chain = chain_layer_strains(N, false);
  const std::vector<double> grip_chain = chain_layer_strains(N, true);
  EXPECT_NEAR(free_chain[0], 1.1987, 1e-4); // the value quoted in docs/model.md
  EXPECT_NEAR(free_chain[N / 2], 0.9454, 1e-4);
  for (int k = 0; k < N; ++k)
    EXPECT_NEAR(grip_chain[k], 1.0, 1e-12);
  for (bool grip : {false, true}) {
    MaterialSpec m = unit_material(1.0, 4.0); // e_p = 1: elastic at these strains
    Lattice lat0(3, 1, N, 1.0);
    Conditions c;
    c.plane_strain_axis = 1;
    c.fixed.push_back({make_node_set("all", select_all(lat0), "all"), kDofX});
    std::vector<index_t> ends = select_face(lat0, Face::ZMin);
    for (index_t v : select_face(lat0, Face::ZMax))
      ends.push_back(v);
    if (grip)
      for (Face f : {Face::ZMin, Face::ZMax})
        for (index_t v : select_face_module_centres(lat0, f))
          ends.push_back(v);
    std::sort(ends.begin(), ends.end());
    c.fixed.push_back({make_node_set("ends", ends, "ends"), kDofZ});
    SolverOptions o;
    o.damping = 0.6; // near-critical for the lowest mode, omega_1 ~ pi sqrt(1.2) / 10 = 0.34
    Simulation sim = make_sim(3, 1, N, 1.0, m, c, o);
    const Lattice& lat = sim.lattice();
    const double U = 0.5e-3; // a mean strain of 1e-4
    for (index_t v = 0; v < lat.num_nodes(); ++v)
      sim.set_displacement(v, {0.0, 0.0, -U + 2 * U * lat.position(v).z / N});
    for (int s = 0; s < 3000; ++s)
      sim.step();
    for (int k = 0; k < N; ++k) {
      // Every corner of a level moves alike (the column has no x or y dependence).
      const double du = sim.displacement(lat.corner(1, 0, k + 1)).z -
                        sim.displacement(lat.corner(1, 0, k)).z;
      const double expected = grip ? grip_chain[k] : free_chain[k];
      // Geometric nonlinearity (O(1e-4)) and what is left of the transient.
      EXPECT_NEAR(du / (2 * U / N), expected, 1e-3) << "layer " << k << (grip ? " grip" : "");
    }
  }
}

} // namespace
} // namespace ldem
