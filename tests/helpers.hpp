// Shared set-ups for the solver tests.
#pragma once

#include "lattice/node_set.hpp"
#include "solver/simulation.hpp"

#include <cmath>

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

inline NodeSet face(const Lattice& lat, Face f) {
  return make_node_set(face_name(f), select_face(lat, f), "face " + face_name(f));
}

} // namespace ldem::testing
