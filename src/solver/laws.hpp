// The registry of bar laws (laws.cpp): each law's kernels by its name in a case file.
#pragma once

#include <string_view>

namespace ldem {

struct LawKernels;

// The paper's bilinear law.
const LawKernels& default_law();
// The law called `name`, or nullptr.
const LawKernels* find_law(std::string_view name);

} // namespace ldem
