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

// The walk's slabs (util/parallel.hpp, balance_ranges): ranges of planes whose costs differ
// move towards equal times, and ranges of equal cost stay where they are.
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
} // namespace

TEST(BalanceRanges, EqualCostsStayAndNoiseBelowTheMarginMovesNothing) {
  std::vector<std::int64_t> start{0, 30, 61};
  const std::vector<double> equal{30.0, 31.0}; // one per plane: balanced as well as it can be
  balance_ranges(start, equal.data());
  EXPECT_EQ(start[1], 30);
  // 3 % apart: less than 1.2 planes' time (1.2 / 30 = 4 %), noise rather than a cost.
  const std::vector<double> noisy{1.03, 1.0};
  balance_ranges(start, noisy.data());
  EXPECT_EQ(start[1], 30);
}

TEST(BalanceRanges, CostlyPlanesMoveTheBoundaryUntilTheTimesAreEven) {
  // 61 planes of cost 1 but for a damaged layer, planes 20 to 27 at cost 6 (a crack's planes);
  // two and three threads. The best split's longest range is found by trying every split; the
  // rule moves one plane at a time and stops within a margin of 1.2 planes' time of even, so
  // after enough rounds the longest range is at most the best one's plus two planes of the
  // costliest kind (6 each), and on the way no range has fewer than 2 planes.
  std::vector<double> cost(61, 1.0);
  for (std::size_t k = 20; k < 28; ++k)
    cost[k] = 6.0;
  for (const std::size_t threads : {2u, 3u}) {
    std::vector<std::int64_t> start(threads + 1);
    for (std::size_t u = 0; u <= threads; ++u)
      start[u] = static_cast<std::int64_t>(u * 61 / threads);
    for (int round = 0; round < 200; ++round) {
      const std::vector<double> t = range_times(start, cost);
      balance_ranges(start, t.data());
      for (std::size_t u = 0; u < threads; ++u)
        ASSERT_GE(start[u + 1] - start[u], 2) << threads << " threads, round " << round;
    }
    const std::vector<double> t = range_times(start, cost);
    const double longest = longest_of(t);
    double best = 1e300;
    if (threads == 2) {
      for (std::int64_t b = 1; b < 61; ++b)
        best = std::min(best, longest_of(range_times({0, b, 61}, cost)));
    } else {
      for (std::int64_t b = 1; b < 61; ++b)
        for (std::int64_t c = b + 1; c < 61; ++c)
          best = std::min(best, longest_of(range_times({0, b, c, 61}, cost)));
    }
    EXPECT_LE(longest, best + 2 * 6.0) << threads << " threads";
    // And clearly better than the even split's.
    std::vector<std::int64_t> even(threads + 1);
    for (std::size_t u = 0; u <= threads; ++u)
      even[u] = static_cast<std::int64_t>(u * 61 / threads);
    const std::vector<double> te = range_times(even, cost);
    EXPECT_LT(longest, longest_of(te)) << threads << " threads";
  }
}
