// The bar laws a case can choose: one line per law.
#include "solver/laws.hpp"

#include "material/bar_law_bilinear.hpp"
#include "material/bar_law_fatigue.hpp"
#include "solver/law_kernels.hpp"

namespace ldem {

namespace {

const LawKernels* const kLaws[] = {&law_kernels<BilinearLaw>(),
                                   &law_kernels<BilinearFatigueLaw>()};

} // namespace

const LawKernels& default_law() {
  return *kLaws[0];
}

const LawKernels* find_law(std::string_view name) {
  for (const LawKernels* law : kLaws)
    if (law->name == name)
      return law;
  return nullptr;
}

} // namespace ldem
