#include "energy/ledger.hpp"

#include <algorithm>
#include <cmath>

namespace ldem {

EnergyReport Ledger::report(double time, double elastic, double kinetic, double damage,
                            double work_half, double damping_half) const {
  EnergyReport r;
  r.time = time;
  r.external_work = work_ + work_half;
  r.elastic = elastic;
  r.kinetic = kinetic;
  r.damage_dissipated = damage;
  r.damping_dissipated = damping_ + damping_half;
  r.initial = initial_;
  const double input = r.external_work + initial_;
  const double held = elastic + kinetic + damage + r.damping_dissipated;
  // "tiny": below 1e-30 J nothing has happened yet and the ratio would be noise.
  r.balance_error = std::abs(input - held) / std::max(std::abs(input), 1e-30);
  return r;
}

} // namespace ldem
