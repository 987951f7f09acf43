// Reductions whose result does not depend on the number of threads.
#pragma once

#include <cstdint>
#include <vector>

namespace ldem {

// Below this many items a parallel region costs more than it saves (and a waiting thread spins
// on a busy machine); loops over fewer items run on the calling thread.
inline constexpr std::int64_t kParallelMinItems = 20000;

// Sum of f(i) for i in [0, n): fixed chunks of 4096 terms summed in parallel, then the
// chunk sums added in chunk order, so the rounding is the same for any thread count.
template <class F> double deterministic_sum(std::int64_t n, F&& f) {
  constexpr std::int64_t chunk = 4096;
  const std::int64_t nchunks = (n + chunk - 1) / chunk;
  std::vector<double> partial(static_cast<std::size_t>(nchunks), 0.0);
#pragma omp parallel for schedule(static) if (nchunks > 1)
  for (std::int64_t c = 0; c < nchunks; ++c) {
    double s = 0.0;
    const std::int64_t end = (c + 1) * chunk < n ? (c + 1) * chunk : n;
    for (std::int64_t i = c * chunk; i < end; ++i)
      s += f(i);
    partial[static_cast<std::size_t>(c)] = s;
  }
  double total = 0.0;
  for (double p : partial)
    total += p;
  return total;
}

} // namespace ldem
