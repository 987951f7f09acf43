#include "app/bench.hpp"

#include "app/case_run.hpp"
#include "parallel/comm.hpp"
#include "solver/simulation.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <functional>
#include <omp.h>
#include <sys/resource.h>
#include <unistd.h>

namespace ldem {

namespace {

// The peer benchmark's material and lattice: concrete of the paper's second application
// (E = 35 GPa, rho = 2400 kg/m^3, L = 7.5 mm), elastic (e_p far above the strains reached).
constexpr double kL = 0.0075;

MaterialSpec bench_material() {
  MaterialSpec mat;
  mat.E = 35e9;
  mat.rho = 2400;
  mat.Gf = 1155;
  mat.e_p = 2.18e-4;
  return mat;
}

// Small imposed strain rate, as in the peer run: v_x ramps from -0.1 to +0.1 m/s across x.
std::function<Vec3(Vec3)> ramp(unsigned nx) {
  const double half_width = 0.5 * nx * kL;
  return [half_width](Vec3 X) { return Vec3{0.1 * (X.x - half_width) / half_width, 0.0, 0.0}; };
}

// The timed loop; `between` runs after every step (the halo exchange of distributed runs).
template <class After> double timed_steps(Simulation& sim, std::uint64_t steps, After&& between) {
  barrier();
  const auto t0 = std::chrono::steady_clock::now();
  for (std::uint64_t s = 1; s < steps; ++s) {
    sim.step(false);
    between();
  }
  barrier();
  const auto t1 = std::chrono::steady_clock::now();
  return max_over_processes(std::chrono::duration<double>(t1 - t0).count());
}

// This process's resident memory now (Linux's /proc/self/statm) and its peak so far
// (getrusage), in bytes; 0 where unknown.
double resident_now() {
  std::FILE* f = std::fopen("/proc/self/statm", "r");
  if (!f)
    return 0.0;
  unsigned long long size = 0, resident = 0;
  const bool ok = std::fscanf(f, "%llu %llu", &size, &resident) == 2;
  std::fclose(f);
  return ok ? static_cast<double>(resident) * static_cast<double>(sysconf(_SC_PAGESIZE)) : 0.0;
}
double resident_peak() {
  rusage u{};
  return getrusage(RUSAGE_SELF, &u) == 0 ? 1024.0 * static_cast<double>(u.ru_maxrss) : 0.0;
}

} // namespace

BenchResult run_bench(const BenchOptions& o) {
  if (o.threads > 0)
    omp_set_num_threads(o.threads);
  BenchResult r;
  r.processes = process_count();
  r.threads = omp_get_max_threads();
  r.steps = o.steps - 1;
  const Lattice whole(o.nx, o.ny, o.nz, kL);
  r.bars = whole.num_bars();
  r.nodes = whole.num_nodes();
  SolverOptions opt;
  opt.step.safety = 0.9;
  opt.setup_progress = setup_progress_line;
  if (r.processes == 1) {
    Lattice lat = whole;
    BarTable table(lat, bench_material());
    Simulation sim(std::move(lat), std::move(table), {}, opt);
    sim.set_velocity(ramp(o.nx));
    sim.step(true);
    const double e0 = sim.last_report().elastic + sim.last_report().kinetic;
    r.wall_s = timed_steps(sim, o.steps, [] {});
    sim.step(true);
    const double e1 = sim.last_report().elastic + sim.last_report().kinetic;
    r.energy_drift = std::abs(e1 - e0) / e0;
    r.resident_steps = resident_now();
    r.resident_peak = resident_peak();
    r.bytes_per_module = sim.bytes_per_module();
    r.dt = sim.dt();
    r.dt_stable = sim.stable_step().dt;
  } else {
    // A subdomain per process (src/parallel/subdomain.hpp), stepped at the body's step.
    const ProcessGrid grid = resolve_grid(o.ny, o.nz, r.processes, {o.grid_y, o.grid_z});
    const Subdomain sub = make_subdomain(o.ny, o.nz, grid, process_rank());
    r.grid_y = grid.py;
    r.grid_z = grid.pz;
    Lattice lat(o.nx, sub.y.local_n(), sub.z.local_n(), kL);
    BarTable table(lat, bench_material());
    opt.defer_time_step = true;
    SubdomainRun run(sub, std::move(lat), std::move(table), {}, opt);
    Simulation& sim = run.sim();
    const StableStep stable = distributed_stable_step(run, whole);
    r.dt_stable = stable.dt;
    sim.set_time_step(stable, opt.step.safety * r.dt_stable);
    sim.set_velocity(ramp(o.nx)); // v depends on x alone: local and global X agree
    std::vector<double> buffers[4];
    // Energies summed over the ranks' owned rows in the body's order (parallel/comm.hpp).
    auto total = [&] {
      const EnergySums e = gather_energies(run);
      return e.elastic + e.kinetic;
    };
    sim.step(true);
    exchange_halos(run, buffers);
    const double e0 = total();
    r.wall_s = timed_steps(sim, o.steps, [&] { exchange_halos(run, buffers); });
    sim.step(true);
    r.energy_drift = std::abs(total() - e0) / e0;
    r.resident_steps = max_over_processes(resident_now());
    r.resident_peak = max_over_processes(resident_peak());
    const double local_modules = static_cast<double>(sim.lattice().num_modules());
    const double owned_modules =
        static_cast<double>(sub.y.m1 - sub.y.m0) * (sub.z.m1 - sub.z.m0) * o.nx;
    r.bytes_per_module = max_over_processes(sim.bytes_per_module() * local_modules / owned_modules);
    r.dt = sim.dt();
  }
  r.bar_updates_per_s = static_cast<double>(r.bars) * static_cast<double>(r.steps) / r.wall_s;
  return r;
}

std::string bench_line(const BenchResult& r) {
  return fmt::format(
      "ldem bar_updates_per_s={:.6g} bars={} nodes={} steps={} threads={} processes={} "
      "process_grid={}x{} wall_s={:.4f}",
      r.bar_updates_per_s, r.bars, r.nodes, r.steps, r.threads, r.processes, r.grid_y, r.grid_z,
      r.wall_s);
}

} // namespace ldem
