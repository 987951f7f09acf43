// The stable step of the central-difference method: dt < 2 / omega_max, with omega_max^2
// the largest eigenvalue of M^-1 K (undamaged bar stiffness at the reference geometry;
// softening only lowers stiffness, and fixed DOF only remove modes, so this is safe).
#pragma once

#include "lattice/lattice.hpp"
#include "material/bar_table.hpp"

#include <vector>

namespace ldem {

struct StableStep {
  double omega_max = 0.0;   // Lanczos estimate of the largest eigenfrequency [rad/s]
  double dt = 0.0;          // 2 / omega_max
  double omega_bound = 0.0; // Gershgorin upper bound on omega_max (proven)
  double dt_bound = 0.0;    // 2 / omega_bound: a step below this is stable for certain
  int iterations = 0;
};

// Lanczos iteration on M^-1/2 K M^-1/2 restricted to the free DOF (converged to 1e-7 in
// the top Ritz value) and a Gershgorin row-sum bound on the same matrix. `held` has one
// DofMask per node (bit d set: DOF d is fixed or imposed) and may be empty (all free).
StableStep compute_stable_step(const Lattice& lattice, const BarTable& table,
                               const std::vector<double>& mass,
                               const std::vector<unsigned char>& held);

} // namespace ldem
