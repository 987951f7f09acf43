// `ldem bench`: elastic dynamics of a free 3-D lattice, timed over the step loop only.
#pragma once

#include <cstdint>
#include <string>

namespace ldem {

struct BenchOptions {
  unsigned nx = 64, ny = 64, nz = 64;
  std::uint64_t steps = 200;
  int threads = 0; // 0: all cores
  // Distributed: the grid of processes over y and z (0 0: the one a run would choose).
  int grid_y = 0, grid_z = 0;
};

struct BenchResult {
  std::uint64_t bars = 0, nodes = 0, steps = 0;
  int threads = 0, processes = 1, grid_y = 1, grid_z = 1;
  double wall_s = 0.0, bar_updates_per_s = 0.0, bytes_per_module = 0.0, dt = 0.0, dt_stable = 0.0;
  double energy_drift = 0.0; // relative change of total energy over the run
  // Resident memory of the (busiest) process [bytes]: at the end of the time-step loop, and
  // its peak over the whole command (set-up included); 0 where the system does not tell.
  double resident_steps = 0.0, resident_peak = 0.0;
  // bytes_per_module: per owned module of the busiest process when distributed
};

BenchResult run_bench(const BenchOptions& options);
std::string bench_line(const BenchResult& r);

} // namespace ldem
