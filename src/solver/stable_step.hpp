// The stable step of the central-difference method: dt < 2 / omega_max, with omega_max^2
// the largest eigenvalue of M^-1 K (undamaged bar stiffness at the reference geometry;
// softening only lowers stiffness, and fixed DOF only remove modes, so this is safe).
#pragma once

#include "lattice/lattice.hpp"
#include "material/bar_table.hpp"

#include <functional>
#include <span>
#include <vector>

namespace ldem {

class ExactSum;

struct StableStep {
  double omega_max = 0.0;   // Lanczos estimate of the largest eigenfrequency [rad/s]
  double dt = 0.0;          // 2 / omega_max
  double omega_bound = 0.0; // Gershgorin upper bound on omega_max (proven)
  double dt_bound = 0.0;    // 2 / omega_bound: a step below this is stable for certain
  int iterations = 0;
};

// A body shared among processes (src/parallel): the lattice given to compute_stable_step is
// one process's window, whose nodes it owns or holds as ghosts of their owners. Every process
// calls compute_stable_step with its window at the same time; the results agree bit for bit
// with the whole body's in one process.
struct StableStepParts {
  std::vector<unsigned char> owned; // per window node: 1 if this process owns it
  std::vector<index_t> global_node; // per window node: its number in the body
  // Sets every ghost node's 3 values (3 per node, node after node) to its owner's.
  std::function<void(std::vector<double>&)> exchange;
  // Adds every process's part into each (all processes get the same sums); the largest.
  std::function<void(ExactSum&)> sum;
  std::function<double(double)> max;
};

// Arrays compute_stable_step may take instead of allocating its own (a simulation's arrays
// before its first step: the displacements, the bar states), each of at least the lattice's
// number of nodes or nullptr (then its own): its Lanczos vectors q, the one before and w by
// component (0 to 8) and 1 / sqrt(m) (9). What they hold afterwards is unspecified.
struct StableStepScratch {
  double* v[10] = {};
};

// Lanczos iteration on M^-1/2 K M^-1/2 restricted to the free DOF (converged to 1e-7 in
// the top Ritz value) and a Gershgorin row-sum bound on the same matrix. `held` has one
// DofMask per node (bit d set: DOF d is fixed or imposed) and may be empty (all free).
// Dot products are summed row by row of nodes (in order along x), the rows' sums exactly, so
// the result does not depend on the thread count nor, with `parts`, on the processes.
StableStep compute_stable_step(const Lattice& lattice, const BarTable& table,
                               std::span<const double> mass, const std::vector<unsigned char>& held,
                               const StableStepParts* parts = nullptr,
                               const StableStepScratch* scratch = nullptr);

} // namespace ldem
