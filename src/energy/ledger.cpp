#include "energy/ledger.hpp"

#include <algorithm>
#include <cmath>

namespace ldem {

double balance_floor(double E_max, double e_p_max, double volume) {
  return 1e-9 * 0.5 * E_max * volume * e_p_max * e_p_max;
}

EnergyReport energy_report(double time, double external_work, double elastic, double kinetic,
                           double damage, double damping, double initial, double floor,
                           double fatigue, double contact, double friction) {
  EnergyReport r;
  r.time = time;
  r.external_work = external_work;
  r.elastic = elastic;
  r.kinetic = kinetic;
  r.damage_dissipated = damage;
  r.damping_dissipated = damping;
  r.fatigue_dissipated = fatigue;
  r.contact = contact;
  r.friction_dissipated = friction;
  r.initial = initial;
  const double input = r.external_work + initial;
  const double held = elastic + kinetic + damage + r.damping_dissipated + fatigue + contact + friction;
  r.balance_error = std::abs(input - held) / std::max(std::abs(input), floor);
  return r;
}

void Ledger::State::write(double* out) const {
  work.write(out);
  damping.write(out + ExactSum::kDoubles);
  friction.write(out + 2 * ExactSum::kDoubles);
  out[3 * ExactSum::kDoubles] = initial;
}

void Ledger::State::read(const double* in) {
  work.read(in);
  damping.read(in + ExactSum::kDoubles);
  friction.read(in + 2 * ExactSum::kDoubles);
  initial = in[3 * ExactSum::kDoubles];
}

ExactSum Ledger::twice_damping_at_report(const State& s, const ExactSum& damping_step) {
  // Twice (damping so far + half the step's), exactly: 2 D + S.
  ExactSum d = s.damping;
  d.twice();
  d.add(damping_step);
  return d;
}

} // namespace ldem
