#include "material/bar_law_bilinear.hpp"

#include "material/bar_table.hpp"

namespace ldem {

BilinearLaw::Row BilinearLaw::row(const BarTable& table, int family, index_t first_bar) {
  const FamilyMaterial& m = table.family(family);
  if (!table.per_bar())
    return {{m.e_p, m.e_r}, nullptr, nullptr};
  return {{m.e_p, m.e_r}, table.e_p_bar().data() + first_bar, table.e_r_bar().data() + first_bar};
}

} // namespace ldem
