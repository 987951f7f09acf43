// Sharing the machine's cores among ldem runs (util/core_share.hpp): which processes count as
// runs, and each run's share.
#include "util/core_share.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <gtest/gtest.h>
#include <string>
#include <unistd.h>

namespace fs = std::filesystem;
using namespace ldem;

namespace {

// A process directory as /proc has it: stat ("pid (comm) state ...") and cmdline (the
// arguments, each ended by a NUL).
void add_process(const fs::path& proc, int pid, const std::string& comm, char state,
                 const std::string& args) {
  const fs::path d = proc / std::to_string(pid);
  fs::create_directories(d);
  std::ofstream(d / "stat") << pid << " (" << comm << ") " << state << " 1 1 1 0 -1\n";
  std::ofstream(d / "cmdline", std::ios::binary) << args;
}

} // namespace

// Runs are the ldem processes that step a body, not stopped or ended: here 101 (run), 205
// (resume, sleeping: waiting is running), 300 (bench) and 412 (modes); not 150 (a stopped run),
// 160 (a zombie), 170 (`ldem check`), 180 (an ensemble's own process, which waits for its
// runs), 190 (another program given "run"), 195 (a command name with a space and parentheses).
TEST(CoreShare, RunsAreTheLdemProcessesThatStep) {
  const fs::path proc = fs::temp_directory_path() / ("ldem_proc_" + std::to_string(getpid()));
  fs::remove_all(proc);
  add_process(proc, 205, "ldem", 'S', std::string("ldem\0resume\0out\0", 16));
  add_process(proc, 101, "ldem", 'R', std::string("/usr/bin/ldem\0run\0c.toml\0", 25));
  add_process(proc, 150, "ldem", 'T', std::string("ldem\0run\0c.toml\0", 16));
  add_process(proc, 160, "ldem", 'Z', "");
  add_process(proc, 170, "ldem", 'R', std::string("ldem\0check\0c.toml\0", 18));
  add_process(proc, 180, "ldem", 'S', std::string("ldem\0ensemble\0c.toml\0", 21));
  add_process(proc, 190, "python3", 'R', std::string("python3\0run\0", 12));
  add_process(proc, 195, "ld (em) x", 'R', std::string("ldem\0run\0", 9));
  add_process(proc, 300, "ldem", 'R', std::string("ldem\0bench\0", 11));
  add_process(proc, 412, "ldem", 'R', std::string("ldem\0modes\0c.toml\0", 18));
  fs::create_directories(proc / "self");
  std::ofstream(proc / "uptime") << "1.0 1.0\n";
  EXPECT_EQ(stepping_runs(proc.string()), (std::vector<int>{101, 205, 300, 412}));
  fs::remove_all(proc);
  EXPECT_TRUE(stepping_runs(proc.string()).empty()); // no such folder: no runs
}

// cores / runs each, the first cores % runs one more, at least one; a process not (yet)
// listed counts as one more run, the last.
TEST(CoreShare, EachRunTakesItsShareOfTheCores) {
  EXPECT_EQ(core_share(2, {7}, 7), 2);         // alone
  EXPECT_EQ(core_share(2, {7, 9}, 7), 1);      // two on two cores
  EXPECT_EQ(core_share(2, {7, 9}, 9), 1);
  EXPECT_EQ(core_share(2, {7, 9, 11}, 11), 1); // more runs than cores: one thread each
  EXPECT_EQ(core_share(8, {3, 5, 7}, 3), 3);   // 8 = 3 + 3 + 2
  EXPECT_EQ(core_share(8, {3, 5, 7}, 5), 3);
  EXPECT_EQ(core_share(8, {3, 5, 7}, 7), 2);
  EXPECT_EQ(core_share(8, {3, 5}, 9), 2);      // unlisted: the third of three, 8 / 3
  EXPECT_EQ(core_share(4, {}, 9), 4);          // unlisted and alone
}

// The walk's slabs (util/parallel.hpp, balance_ranges): ranges of planes placed by the planes'
// costs, so that their times are even to within a plane; ranges of equal cost stay where they
// are.
namespace {
// Each range's time: the sum of its planes' costs.
std::vector<double> range_times(const std::vector<std::int64_t>& start,
                                const std::vector<double>& cost) {
  std::vector<double> t(start.size() - 1, 0.0);
  for (std::size_t u = 0; u + 1 < start.size(); ++u)
    for (std::int64_t k = start[u]; k < start[u + 1]; ++k)
      t[u] += cost[static_cast<std::size_t>(k)];
  return t;
}
double longest_of(const std::vector<double>& t) {
  return *std::max_element(t.begin(), t.end());
}
std::vector<std::int64_t> even_split(std::size_t ranges, std::int64_t items) {
  std::vector<std::int64_t> s(ranges + 1);
  for (std::size_t u = 0; u <= ranges; ++u)
    s[u] = static_cast<std::int64_t>(u) * items / static_cast<std::int64_t>(ranges);
  return s;
}
// The best split's longest range, by trying every split of 61 items (2 or 3 ranges).
double best_longest(std::size_t ranges, const std::vector<double>& cost) {
  double best = 1e300;
  for (std::int64_t b = 1; b < 61; ++b) {
    if (ranges == 2)
      best = std::min(best, longest_of(range_times({0, b, 61}, cost)));
    else
      for (std::int64_t c = b + 1; c < 61; ++c)
        best = std::min(best, longest_of(range_times({0, b, c, 61}, cost)));
  }
  return best;
}
} // namespace

TEST(BalanceRanges, EqualCostsStayAndNoiseBelowTheMarginMovesNothing) {
  // 61 planes of cost 1 in 2 ranges of 30 and 31: as even as whole planes allow.
  std::vector<std::int64_t> start{0, 30, 61};
  EXPECT_FALSE(balance_ranges(start, std::vector<double>(61, 1.0)));
  EXPECT_EQ(start[1], 30);
  // The upper range's 31 planes each dearer by d: moving one plane down gives the ranges
  // 31 + d and 30 (1 + d), where the upper one alone was 31 (1 + d). With d = 0.4 / 31 (a
  // clock's noise) the gain, 31 (1 + d) - (31 + d) = 0.39, is under the margin of a plane's
  // average cost ((61 + 0.4) / 61 = 1.007): nothing moves. With d = 2 / 31 (a cost) the gain,
  // 31 (1 + d) - 30 (1 + d) = 1.065, is past it (63 / 61 = 1.033): the boundary moves up by one
  // plane (by two, the lower range would cost 32.13, more than the 31.94 of the upper one).
  for (const double extra : {0.4, 2.0}) {
    std::vector<double> cost(61, 1.0);
    for (std::size_t k = 30; k < 61; ++k)
      cost[k] += extra / 31.0;
    start = {0, 30, 61};
    EXPECT_EQ(balance_ranges(start, cost), extra > 1.0) << extra;
    EXPECT_EQ(start[1], extra > 1.0 ? 31 : 30) << extra;
  }
}

TEST(BalanceRanges, CostlyPlanesPlaceTheBoundariesAtOnce) {
  // 61 planes of cost 1 but for a damaged layer, planes 20 to 27 at cost 6 (a crack's planes);
  // two and three threads, from the even split. One call places each boundary at the plane edge
  // nearest its share of the total, so every range is within one plane's cost of that share:
  // the longest range is at most the best split's (found by trying every split) plus the
  // costliest plane (6). A second call on the same costs moves nothing.
  std::vector<double> cost(61, 1.0);
  for (std::size_t k = 20; k < 28; ++k)
    cost[k] = 6.0;
  for (const std::size_t threads : {2u, 3u}) {
    std::vector<std::int64_t> start = even_split(threads, 61);
    const double even_longest = longest_of(range_times(start, cost));
    EXPECT_TRUE(balance_ranges(start, cost)) << threads << " threads";
    for (std::size_t u = 0; u < threads; ++u)
      EXPECT_GE(start[u + 1] - start[u], 2) << threads << " threads";
    const double longest = longest_of(range_times(start, cost));
    EXPECT_LE(longest, best_longest(threads, cost) + 6.0) << threads << " threads";
    EXPECT_LT(longest, even_longest) << threads << " threads";
    const std::vector<std::int64_t> placed = start;
    EXPECT_FALSE(balance_ranges(start, cost)) << threads << " threads";
    EXPECT_EQ(start, placed) << threads << " threads";
  }
}

TEST(BalanceRanges, TypicalCostsIgnoreAnInterruptedSample) {
  // 3 planes, 4 samples each (sample s of plane i at s * 3 + i); in each plane one sample is
  // 50 times the others (the thread interrupted while it took that plane). The median of 4,
  // the mean of the middle two, is the plane's own cost.
  const std::vector<double> times{1.0,  2.0,   150.0, //
                                  50.0, 2.0,   3.0,   //
                                  1.0,  100.0, 3.0,   //
                                  1.0,  2.0,   3.0};
  std::vector<double> cost;
  typical_costs<4>(times, cost);
  EXPECT_EQ(cost, (std::vector<double>{1.0, 2.0, 3.0}));
  // An odd count: the middle sample.
  typical_costs<3>({4.0, 1.0, 9.0}, cost);
  EXPECT_EQ(cost, (std::vector<double>{4.0}));
}

TEST(BalanceRanges, NoRangeGetsFewerThanTheLeastItems) {
  // 12 planes of cost 1 but plane 0 at 10 (total 21), 3 ranges from the even split (13, 4 and 4).
  // The first boundary's share, 7, lies inside plane 0, whose nearer edge, 1, would leave range 0
  // one plane: it keeps 2 (the walk's slabs need a plane below their top one), costing 11. The
  // second's share, 14, is edge 5 (10 + 4). Longest 11 against 13, a gain of 2 past the margin
  // of 21 / 12 = 1.75: moved.
  std::vector<double> cost(12, 1.0);
  cost[0] = 10.0;
  std::vector<std::int64_t> start = even_split(3, 12);
  EXPECT_TRUE(balance_ranges(start, cost));
  EXPECT_EQ(start, (std::vector<std::int64_t>{0, 2, 5, 12}));
}
