#include "app/bench.hpp"

#include "solver/simulation.hpp"

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <omp.h>

namespace ldem {

BenchResult run_bench(const BenchOptions& o) {
  if (o.threads > 0)
    omp_set_num_threads(o.threads);
  // The peer benchmark's material and lattice: concrete of the paper's second application
  // (E = 35 GPa, rho = 2400 kg/m^3, L = 7.5 mm), elastic (e_p far above the strains reached).
  const double L = 0.0075;
  Lattice lat(o.nx, o.ny, o.nz, L);
  MaterialSpec mat;
  mat.E = 35e9;
  mat.rho = 2400;
  mat.Gf = 1155;
  mat.e_p = 2.18e-4;
  BarTable table(lat, mat);
  SolverOptions opt;
  opt.step.safety = 0.9;
  Simulation sim(std::move(lat), std::move(table), {}, opt);
  // Small imposed strain rate, as in the peer run: v_x ramps from -0.1 to +0.1 m/s across x.
  const double half_width = 0.5 * o.nx * L;
  sim.set_velocity([&](Vec3 X) { return Vec3{0.1 * (X.x - half_width) / half_width, 0.0, 0.0}; });
  sim.step(true);
  const double e0 = sim.last_report().elastic + sim.last_report().kinetic;
  const auto t0 = std::chrono::steady_clock::now();
  for (std::uint64_t s = 1; s < o.steps; ++s)
    sim.step(false);
  const auto t1 = std::chrono::steady_clock::now();
  sim.step(true);
  const double e1 = sim.last_report().elastic + sim.last_report().kinetic;

  BenchResult r;
  r.bars = sim.lattice().num_bars();
  r.nodes = sim.lattice().num_nodes();
  r.steps = o.steps - 1;
  r.threads = omp_get_max_threads();
  r.wall_s = std::chrono::duration<double>(t1 - t0).count();
  r.bar_updates_per_s = static_cast<double>(r.bars) * static_cast<double>(r.steps) / r.wall_s;
  r.bytes_per_module = sim.bytes_per_module();
  r.dt = sim.dt();
  r.dt_stable = sim.stable_step().dt;
  r.energy_drift = std::abs(e1 - e0) / e0;
  return r;
}

std::string bench_line(const BenchResult& r) {
  return fmt::format(
      "ldem bar_updates_per_s={:.6g} bars={} nodes={} steps={} threads={} wall_s={:.4f}",
      r.bar_updates_per_s, r.bars, r.nodes, r.steps, r.threads, r.wall_s);
}

} // namespace ldem
