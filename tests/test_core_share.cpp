// Sharing the machine's cores among ldem runs (util/core_share.hpp): which processes count as
// runs, and each run's share.
#include "util/core_share.hpp"

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
