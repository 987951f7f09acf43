#include "material/bar_law_fatigue.hpp"

#include "material/bar_table.hpp"
#include "util/error.hpp"

namespace ldem {

BilinearFatigueLaw::Row BilinearFatigueLaw::row(const BarTable& table, int family,
                                                index_t first_bar) {
  const BilinearLaw::Row b = BilinearLaw::row(table, family, first_bar);
  return {{b.family}, b.e_p, b.e_r};
}

FatigueConstants BilinearFatigueLaw::fatigue_constants(const BarTable& table, int family) {
  const std::optional<FatigueSpec>& f = table.spec().fatigue;
  if (!f)
    throw InputError("law = \"bilinear_fatigue\": expected a [fatigue] table, got none");
  const FamilyMaterial& m = table.family(family);
  const double gate = f->gate > 0.0 ? f->gate : kDefaultGate * m.e_p;
  return {fatigue_coefficient(f->A, f->m, m.l0, f->length), f->m, f->threshold, gate};
}

} // namespace ldem
