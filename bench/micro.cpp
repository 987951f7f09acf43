// Google Benchmark microbenchmarks of the pieces of a step. The whole step, as users see it,
// is `ldem bench`; these isolate what a report step and an output snapshot add to it.
#include "io/output.hpp"
#include "solver/simulation.hpp"

#include <benchmark/benchmark.h>
#include <cstdio>

namespace {

ldem::Simulation make(int n) {
  ldem::Lattice lat(n, n, n, 0.0075);
  ldem::MaterialSpec m;
  m.E = 35e9;
  m.rho = 2400;
  m.Gf = 1155;
  m.e_p = 2.18e-4;
  ldem::BarTable table(lat, m);
  ldem::Simulation sim(std::move(lat), std::move(table), {}, {});
  const double half = 0.5 * n * 0.0075;
  sim.set_velocity([&](ldem::Vec3 X) { return ldem::Vec3{0.1 * (X.x - half) / half, 0, 0}; });
  return sim;
}

void set_rate(benchmark::State& state, const ldem::Simulation& sim) {
  state.counters["bar_updates_per_s"] = benchmark::Counter(
      static_cast<double>(sim.lattice().num_bars()) * static_cast<double>(state.iterations()),
      benchmark::Counter::kIsRate);
}

// One step without energies: bar pass, gather and update (fused plane by plane).
void BM_Step(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)));
  for (auto _ : state)
    sim.step(false);
  set_rate(state, sim);
}
BENCHMARK(BM_Step)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// A report step: the same plus kinetic energy sums and the bars' elastic and damage energy.
void BM_ReportStep(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)));
  for (auto _ : state)
    sim.step(true);
  set_rate(state, sim);
}
BENCHMARK(BM_ReportStep)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// The energy evaluation alone, every bar through the bar law (Simulation::bar_energies: the
// reference that report steps are tested against). A report step gets the same energies from
// its passes at a fraction of this: BM_ReportStep minus BM_Step.
void BM_BarEnergies(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)));
  sim.step(false);
  for (auto _ : state)
    benchmark::DoNotOptimize(sim.bar_energies());
  set_rate(state, sim);
}
BENCHMARK(BM_BarEnergies)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// One VTU snapshot written to /tmp, by a writer made once as in a run.
void BM_WriteVtu(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)));
  sim.step(false);
  ldem::LatticeVtuWriter writer(sim);
  for (auto _ : state)
    writer.write(sim, "/tmp/ldem_micro.vtu");
  std::remove("/tmp/ldem_micro.vtu");
  set_rate(state, sim);
}
BENCHMARK(BM_WriteVtu)->Arg(32)->Unit(benchmark::kMillisecond);

} // namespace

BENCHMARK_MAIN();
