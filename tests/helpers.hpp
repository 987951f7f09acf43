// Shared set-ups for the solver tests.
#pragma once

#include "lattice/node_set.hpp"
#include "solver/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <gtest/gtest.h>
#include <limits>
#include <vector>

namespace ldem::testing {

// A material in units where E = rho = L = 1 (so c = sqrt(E / rho) = 1 and L / c = 1).
// e_p = 0.05 keeps the small-strain tests elastic; Gf makes K_r = 4 for the normal bars
// (eq. 12: K_r = Gf / (E e_p^2) (A^f / A) (2 / L)).
inline MaterialSpec unit_material(double e_p = 0.05, double K_r = 4.0, double L = 1.0) {
  MaterialSpec m;
  m.E = 1.0;
  m.rho = 1.0;
  m.nu = 0.25;
  m.e_p = e_p;
  const double ratio_n = (3.0 / 22.0) / 0.4; // eq. 14 with phi = 0.4
  m.Gf = K_r * m.E * e_p * e_p * L / (2.0 * ratio_n);
  return m;
}

inline Simulation make_sim(index_t nx, index_t ny, index_t nz, double L, const MaterialSpec& m,
                           Conditions c = {}, SolverOptions o = {},
                           std::vector<index_t> precracked = {}, const BarFields& fields = {}) {
  Lattice lat(nx, ny, nz, L);
  BarTable table(lat, m, fields);
  return Simulation(std::move(lat), std::move(table), std::move(c), o, std::move(precracked));
}

// Minus the gradient of the stored energy at every node, by central differences with step h
// (each node's displacement moved by +-h along each axis and put back).
inline std::vector<Vec3> minus_energy_gradient(Simulation& sim, double h) {
  std::vector<Vec3> g(sim.lattice().num_nodes());
  for (index_t n = 0; n < sim.lattice().num_nodes(); ++n) {
    const Vec3 x = sim.displacement(n);
    for (int d = 0; d < 3; ++d) {
      Vec3 p = x, q = x;
      (d == 0 ? p.x : d == 1 ? p.y : p.z) += h;
      (d == 0 ? q.x : d == 1 ? q.y : q.z) -= h;
      sim.set_displacement(n, p);
      const double up = sim.stored_energy();
      sim.set_displacement(n, q);
      const double uq = sim.stored_energy();
      sim.set_displacement(n, x);
      (d == 0 ? g[n].x : d == 1 ? g[n].y : g[n].z) = -(up - uq) / (2 * h);
    }
  }
  return g;
}

// The affine displacement u = eps X at every node of `lat`.
inline std::vector<Vec3> affine_field(const Lattice& lat, const double (&eps)[3][3]) {
  std::vector<Vec3> u(lat.num_nodes());
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 X = lat.position(n);
    u[n] = {eps[0][0] * X.x + eps[0][1] * X.y + eps[0][2] * X.z,
            eps[1][0] * X.x + eps[1][1] * X.y + eps[1][2] * X.z,
            eps[2][0] * X.x + eps[2][1] * X.y + eps[2][2] * X.z};
  }
  return u;
}

inline NodeSet face(const Lattice& lat, Face f) {
  return make_node_set(face_name(f), select_face(lat, f), "face " + face_name(f));
}

// Every state array of a simulation by node and bar number, value by value (a checkpoint's
// content).
inline std::vector<std::vector<double>> all_state(const Simulation& sim) {
  std::vector<std::vector<double>> out;
  const std::vector<Simulation::NamedArray> arrays = sim.state_arrays();
  for (std::size_t a = 0; a < arrays.size(); ++a) {
    out.emplace_back();
    sim.append_state(a, 0, arrays[a].per_bar ? sim.lattice().num_bars() : sim.lattice().num_nodes(),
                     out.back());
  }
  return out;
}

// One step of `sim` from rest (every half-step velocity 0, set by the caller) against the
// per-bar loop (Simulation::internal_forces): m v_{1/2} / dt must be each node's force f(u_0).
// The step's intact kernel computes s = k - k l0 / l with 1 / l from the hardware estimate,
// whose error is about 2 eps k whatever the strain, so a node's force (14 links, lengths up to
// L = 1) differs by at most 14 * 2 eps k_max; twice that for the force recovered from the
// velocity. A term lost, doubled or taken with another bar's state would be of the order of
// the largest force (asserted first to be a million times the tolerance or more).
inline void expect_step_from_rest_gives_bar_forces(Simulation& sim) {
  const Lattice& lat = sim.lattice();
  std::vector<double> fx, fy, fz;
  sim.internal_forces(fx, fy, fz);
  double fmax = 0.0, k_max = 0.0;
  for (index_t n = 0; n < lat.num_nodes(); ++n)
    fmax = std::max({fmax, std::abs(fx[n]), std::abs(fy[n]), std::abs(fz[n])});
  for (int f = 0; f < kFamilies; ++f)
    k_max = std::max(k_max, sim.table().family(f).k);
  const double tol = 4 * 14 * std::numeric_limits<double>::epsilon() * k_max * 1.0;
  ASSERT_LT(tol, 1e-6 * fmax);
  sim.step();
  for (index_t n = 0; n < lat.num_nodes(); ++n) {
    const Vec3 v = sim.half_step_velocity(n);
    const double k = sim.mass(n) / sim.dt();
    EXPECT_NEAR(v.x * k, fx[n], tol) << "node " << n;
    EXPECT_NEAR(v.y * k, fy[n], tol) << "node " << n;
    EXPECT_NEAR(v.z * k, fz[n], tol) << "node " << n;
  }
}

} // namespace ldem::testing
