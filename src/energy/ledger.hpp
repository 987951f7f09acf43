// The energy balance: external work (+ initial) = elastic + kinetic + damage + damping + fatigue
// + contact + friction.
#pragma once

#include "energy/exact_sum.hpp"

#include <array>

namespace ldem {

struct EnergyReport {
  double time = 0.0;
  double external_work = 0.0;     // imposed forces and reactions of imposed velocities [J]
  double elastic = 0.0;           // recoverable energy stored in the bars
  double kinetic = 0.0;           // sum of m v_{n-1/2} . v_{n+1/2} / 2 (central differences)
  double damage_dissipated = 0.0; // sum over bars of the area O-A-P (paper Fig. 1c)
  double damping_dissipated = 0.0;
  double fatigue_dissipated = 0.0; // stored in bars when their fatigue life ran out
  double contact = 0.0;            // held in the platens' penalty springs (normal and sticking)
  double friction_dissipated = 0.0; // by the platens' Coulomb friction
  double initial = 0.0;       // elastic + kinetic energy at t = 0 (initial velocities)
  double balance_error = 0.0; // |W + E0 - (U + K + D + Dc + ...)| / max(|W + E0|, floor)
};

// A report from its energies, with the balance error relative to the energy put in, W + E0,
// or to `floor` while that is smaller (balance_floor).
EnergyReport energy_report(double time, double external_work, double elastic, double kinetic,
                           double damage, double damping, double initial, double floor,
                           double fatigue = 0.0, double contact = 0.0, double friction = 0.0);

// The smallest energy the balance error is taken relative to: a billionth of E V e_p^2 / 2, the
// energy the body would hold with every bar at its peak strain, with the largest E and e_p of the
// body (V its volume). Below it nothing has happened yet, and an imbalance of a few of its
// round-off units reads as what it is, not as an error of 1e13 relative to an input of zero.
double balance_floor(double E_max, double e_p_max, double volume);

// Accumulates work and damping dissipation step by step with the central-difference
// identity m (v+ - v-) . (v+ + v-) / 2 = F_n . (u_{n+1} - u_{n-1}) / 2: the increment of
// step n is F_n . dt (v_{n-1/2} + v_{n+1/2}) / 2. A report at t_n adds the half of step
// n's increment that lies before t_n, F_n . dt v_{n-1/2} / 2.
// The sums are exact (ExactSum), term by term, so their bits do not depend on the order in
// which the terms come, nor on how the body is split among processes.
class Ledger {
public:
  struct State {
    ExactSum work, damping;
    ExactSum friction; // dissipated by the platens' friction
    double initial = 0.0;
    static constexpr int kDoubles = 3 * ExactSum::kDoubles + 1;
    void write(double* out) const;
    void read(const double* in);
    // The sum of two processes' accumulators (the initial energy is the body's, kept).
    void add(const State& other) {
      work.add(other.work);
      damping.add(other.damping);
      friction.add(other.friction);
    }
  };

  // A step's terms, each added exactly.
  ExactSum& work() { return s_.work; }
  ExactSum& damping() { return s_.damping; }
  ExactSum& friction() { return s_.friction; }
  void set_initial(double energy) { s_.initial = energy; }
  double initial() const { return s_.initial; }
  const State& state() const { return s_; }
  void set_state(const State& s) { s_ = s; }

  // At a report at the start of a step whose whole damping dissipation is `damping_step`, of
  // which half counts before t_n: twice the damping dissipated by then, 2 D + S, exactly
  // (the report's damping is half its value). The report's work is s.work plus the step's
  // work before t_n.
  static ExactSum twice_damping_at_report(const State& s, const ExactSum& damping_step);

private:
  State s_;
};

} // namespace ldem
