// Sharing the machine's cores among the ldem runs on it. OpenMP threads that wait at a barrier
// spin for a while before they sleep, so two runs that each take every core keep taking them
// from each other (two 2-thread runs on 2 cores measured 1.6 to 100 times slower than they
// should be). A run whose thread count was not given (no --threads, no OMP_NUM_THREADS) takes
// its share of the cores instead: the cores over the ldem runs stepping on the machine, and
// looks again about once a second, so that runs that start later and end earlier move the
// shares (docs/architecture.md, "Several runs on one machine").
#pragma once

#include <string>
#include <vector>

namespace ldem {

// The process ids of the ldem processes under `proc` (a /proc file system) that step a body
// (`ldem run`, `resume`, `bench` or `modes`; their command name "ldem"), running or waiting but
// not stopped or ended, in increasing order.
std::vector<int> stepping_runs(const std::string& proc = "/proc");

// The share of `cores` of the run `pid` among `runs` (process ids in increasing order): cores /
// runs each, the first cores % runs of them one more, at least 1. A pid not among them counts
// as one more run, the last.
int core_share(int cores, const std::vector<int>& runs, int pid);

// Whether this process chooses its own thread count (none given on the command line or in
// OMP_NUM_THREADS), and then its share now (the cores OpenMP may use, over stepping_runs()).
bool shares_cores(int threads_option);
int current_core_share();

} // namespace ldem
