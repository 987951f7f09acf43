// The energy balance: external work = elastic + kinetic + damage + damping (+ initial).
#pragma once

#include <array>

namespace ldem {

struct EnergyReport {
  double time = 0.0;
  double external_work = 0.0;     // imposed forces and reactions of imposed velocities [J]
  double elastic = 0.0;           // recoverable energy stored in the bars
  double kinetic = 0.0;           // sum of m v_{n-1/2} . v_{n+1/2} / 2 (central differences)
  double damage_dissipated = 0.0; // sum over bars of the area O-A-P (paper Fig. 1c)
  double damping_dissipated = 0.0;
  double initial = 0.0;       // elastic + kinetic energy at t = 0 (initial velocities)
  double balance_error = 0.0; // |W + E0 - (U + K + D + Dc)| / max(W + E0, tiny)
};

// Accumulates work and damping dissipation step by step with the central-difference
// identity m (v+ - v-) . (v+ + v-) / 2 = F_n . (u_{n+1} - u_{n-1}) / 2: the increment of
// step n is F_n . dt (v_{n-1/2} + v_{n+1/2}) / 2. A report at t_n adds the half of step
// n's increment that lies before t_n, F_n . dt v_{n-1/2} / 2.
class Ledger {
public:
  void add_step(double external_work, double damping_dissipated) {
    work_ += external_work;
    damping_ += damping_dissipated;
  }
  void set_initial(double energy) { initial_ = energy; }
  // The accumulators, for checkpoints.
  std::array<double, 3> state() const { return {work_, damping_, initial_}; }
  void set_state(const std::array<double, 3>& s) {
    work_ = s[0];
    damping_ = s[1];
    initial_ = s[2];
  }
  double initial() const { return initial_; }

  EnergyReport report(double time, double elastic, double kinetic, double damage, double work_half,
                      double damping_half) const;

private:
  double work_ = 0.0, damping_ = 0.0, initial_ = 0.0;
};

} // namespace ldem
