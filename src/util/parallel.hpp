// How small a loop runs on one thread, and how ranges of items are shared among threads.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ldem {

// Below this many items a parallel region costs more than it saves (and a waiting thread spins
// on a busy machine); loops over fewer items run on the calling thread.
inline constexpr std::int64_t kParallelMinItems = 20000;

// Each item's typical cost from Samples measurements of it (sample s of item i at
// times[s * items + i]) into cost: the median, so that a sample that an interruption of the
// thread lengthened (a few in a period, on a busy machine) does not count.
template <std::size_t Samples>
inline void typical_costs(const std::vector<double>& times, std::vector<double>& cost) {
  static_assert(Samples > 0 && Samples <= 64, "a few samples per item, sorted on the stack");
  const std::size_t items = times.size() / Samples;
  cost.resize(items);
  std::array<double, Samples> one{};
  for (std::size_t i = 0; i < items; ++i) {
    for (std::size_t s = 0; s < Samples; ++s)
      one[s] = times[s * items + i];
    std::sort(one.begin(), one.end());
    cost[i] = Samples % 2 == 1 ? one[Samples / 2] : 0.5 * (one[Samples / 2 - 1] + one[Samples / 2]);
  }
}

// Contiguous ranges of items, one per thread (range u is [start[u], start[u + 1])), placed so
// that their costs are as even as whole items allow: cost[i] is what item i took over the
// same steps (its plane's time in the walk, whichever thread took it). Each boundary goes to
// the item edge nearest its share of the total (u / n of it), which leaves each range within
// the largest item's cost of the best split's longest range; no range gets fewer than
// `min_items` items (the caller has at least that many per range). The new ranges are taken
// only if their longest is shorter than the present ranges' longest, on the same costs, by
// more than an item's average cost: ranges of equal cost stay where they are, and what noise
// is left in the costs (typical_costs) does not move them back and forth. Returns whether
// they moved.
inline bool balance_ranges(std::vector<std::int64_t>& start, const std::vector<double>& cost,
                           std::int64_t min_items = 2) {
  const auto n = static_cast<std::int64_t>(cost.size());
  const std::size_t ranges = start.size() - 1;
  // (Kept from call to call: the step loop allocates nothing once running.)
  thread_local std::vector<double> prefix;
  thread_local std::vector<std::int64_t> placed;
  prefix.assign(cost.size() + 1, 0.0);
  for (std::size_t i = 0; i < cost.size(); ++i)
    prefix[i + 1] = prefix[i] + cost[i];
  const double total = prefix.back();
  if (!(total > 0.0) || ranges < 2)
    return false;
  const auto longest = [&](const std::vector<std::int64_t>& s) {
    double most = 0.0;
    for (std::size_t u = 0; u < ranges; ++u)
      most = std::max(most, prefix[static_cast<std::size_t>(s[u + 1])] -
                                prefix[static_cast<std::size_t>(s[u])]);
    return most;
  };
  placed.assign(start.size(), 0);
  placed[ranges] = n;
  for (std::size_t u = 1; u < ranges; ++u) {
    const double target = total * static_cast<double>(u) / static_cast<double>(ranges);
    // The first edge at or past the target, or the one before it if nearer.
    auto k = static_cast<std::int64_t>(std::lower_bound(prefix.begin(), prefix.end(), target) -
                                       prefix.begin());
    if (k > 0 && target - prefix[static_cast<std::size_t>(k - 1)] <
                     prefix[static_cast<std::size_t>(k)] - target)
      --k;
    const std::int64_t lo = placed[u - 1] + min_items,
                       hi = n - min_items * static_cast<std::int64_t>(ranges - u);
    placed[u] = std::clamp(k, lo, std::max(lo, hi));
  }
  if (!(longest(placed) < longest(start) - total / static_cast<double>(n)))
    return false;
  start = placed;
  return true;
}

} // namespace ldem
