// How small a loop runs on one thread, and how ranges of items are shared among threads.
#pragma once

#include <cstdint>
#include <vector>

namespace ldem {

// Below this many items a parallel region costs more than it saves (and a waiting thread spins
// on a busy machine); loops over fewer items run on the calling thread.
inline constexpr std::int64_t kParallelMinItems = 20000;

// Contiguous ranges of items, one per thread (range u is [start[u], start[u + 1])), moved
// towards equal times: at each boundary where the range on one side took longer than the other
// (busy[stride * u], its thread's time over the same steps) by more than 1.2 times what one of
// its items took on average, the slower range gives its item at the boundary to the other. One
// item at a time, and only past that margin, so that ranges of equal cost stay where they are
// and noise does not move them back and forth; no range gets fewer than `min_items` items this
// way.
inline void balance_ranges(std::vector<std::int64_t>& start, const double* busy,
                           std::size_t stride = 1, std::int64_t min_items = 2) {
  for (std::size_t u = 1; u + 1 < start.size(); ++u) {
    const double a = busy[stride * (u - 1)], b = busy[stride * u];
    const std::int64_t na = start[u] - start[u - 1], nb = start[u + 1] - start[u];
    if (a > b && na > min_items && a - b > 1.2 * a / static_cast<double>(na))
      --start[u];
    else if (b > a && nb > min_items && b - a > 1.2 * b / static_cast<double>(nb))
      ++start[u];
  }
}

} // namespace ldem
