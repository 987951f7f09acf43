// How small a loop runs on one thread.
#pragma once

#include <cstdint>

namespace ldem {

// Below this many items a parallel region costs more than it saves (and a waiting thread spins
// on a busy machine); loops over fewer items run on the calling thread.
inline constexpr std::int64_t kParallelMinItems = 20000;

} // namespace ldem
