#include "energy/ledger.hpp"

#include <algorithm>
#include <cmath>

namespace ldem {

EnergyReport energy_report(double time, double external_work, double elastic, double kinetic,
                           double damage, double damping, double initial) {
  EnergyReport r;
  r.time = time;
  r.external_work = external_work;
  r.elastic = elastic;
  r.kinetic = kinetic;
  r.damage_dissipated = damage;
  r.damping_dissipated = damping;
  r.initial = initial;
  const double input = r.external_work + initial;
  const double held = elastic + kinetic + damage + r.damping_dissipated;
  // "tiny": below 1e-30 J nothing has happened yet and the ratio would be noise.
  r.balance_error = std::abs(input - held) / std::max(std::abs(input), 1e-30);
  return r;
}

void Ledger::State::write(double* out) const {
  work.write(out);
  damping.write(out + ExactSum::kDoubles);
  out[2 * ExactSum::kDoubles] = initial;
}

void Ledger::State::read(const double* in) {
  work.read(in);
  damping.read(in + ExactSum::kDoubles);
  initial = in[2 * ExactSum::kDoubles];
}

ExactSum Ledger::twice_damping_at_report(const State& s, const ExactSum& damping_step) {
  // Twice (damping so far + half the step's), exactly: 2 D + S.
  ExactSum d = s.damping;
  d.twice();
  d.add(damping_step);
  return d;
}

} // namespace ldem
