// The lowest eigenfrequencies of a simulation's lattice: K phi = omega^2 M phi with the
// undamaged bar stiffness at the reference geometry and the lumped masses, on the free DOF
// (fixed, imposed-velocity and plane-strain DOF removed), without the bars that are broken
// (pre-cracked) in the simulation's current state.
#pragma once

#include "solver/simulation.hpp"

#include <array>
#include <cstddef>
#include <limits>
#include <vector>

namespace ldem {

struct Mode {
  double frequency_hz = 0.0; // omega / (2 pi)
  double omega = 0.0;        // [rad/s]
  // Share of the mode's kinetic energy sum 0.5 m phi^2 in the x, y and z DOF (sums to 1).
  std::array<double, 3> participation{};
  // A zero-energy mode (rigid-body motion, or a mechanism left by broken bars): omega^2 at
  // the round-off level of the factorisation. Its omega and frequency are reported as 0.
  bool zero_energy = false;
  // Share of the loads' static work carried by the mode: with F the nodal forces of all the
  // simulation's loads (Conditions::loads) at unit time-function scale on the free DOF, and
  // phi the mode normalised to phi^T M phi = 1, the static response u = K^-1 F has the work
  // F^T u = sum_i (phi_i^T F)^2 / omega_i^2, and this is the mode's term of it over the sum
  // (the shares of all modes sum to 1). 0 for a zero-energy mode when the share is defined.
  // NaN when there are no loads (or none on a free DOF), when F has a component along a
  // zero-energy mode (a free body loaded out of equilibrium: no static response), and when
  // all the modes found are zero-energy (the zero-energy space may be larger). Within a
  // multiple eigenvalue the modes are any orthonormal basis of its space: only the sum of
  // their shares is defined.
  double load_share = std::numeric_limits<double>::quiet_NaN();
};

// Number of free DOF: 3 per node minus the held ones (Simulation::held).
std::size_t free_dof_count(const Simulation& sim);

// The `count` lowest modes, by ascending frequency. The symmetric form
// A = M^-1/2 K M^-1/2 is factorised (sparse LU, nested-dissection order) with a small negative
// shift, so that a singular K (a free body) still factorises, and the Lanczos iteration of
// Spectra's shift-invert solver finds the eigenvalues nearest the shift; if some are
// zero-energy modes, a second run with them projected out finds the elastic ones (same
// factorisation; the first run's are inaccurate, see DeflatedLu). Single-threaded and
// deterministic. The factorisation bounds the size: a plate of 10^5 DOF takes seconds, a 3-D
// body of 20^3 modules (5 10^4 DOF) about 10 s and 1 GB, growing as DOF^2 in time. Throws
// InputError for count < 1 or count >= the number of free DOF, and if the iteration does not
// converge. The load shares need F^T K^-1 F: solved with the same factorisation, the shift
// removed by iterative refinement (each step reduces the error by shift / lowest omega^2).
std::vector<Mode> lowest_modes(const Simulation& sim, int count);

} // namespace ldem
