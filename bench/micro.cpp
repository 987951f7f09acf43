// Google Benchmark microbenchmarks of the pieces of a step. The whole step, as users see it,
// is `ldem bench`; these isolate what a report step and an output snapshot add to it.
#include "io/output.hpp"
#include "solver/simulation.hpp"

#include <benchmark/benchmark.h>
#include <cstdint>
#include <cstdio>
#include <vector>

namespace {

ldem::Simulation make(int n, bool intact_at_nodes = true, bool broken = false) {
  ldem::Lattice lat(n, n, n, 0.0075);
  ldem::MaterialSpec m;
  m.E = 35e9;
  m.rho = 2400;
  m.Gf = 1155;
  m.e_p = 2.18e-4;
  ldem::BarTable table(lat, m);
  ldem::SolverOptions o;
  o.intact_at_nodes = intact_at_nodes;
  // With `broken`, every bar pre-cracked (compression only): every row damaged, through the
  // general kernel.
  std::vector<ldem::index_t> cracked;
  if (broken)
    for (ldem::index_t b = 0; b < lat.num_bars(); ++b)
      cracked.push_back(b);
  ldem::Simulation sim(std::move(lat), std::move(table), {}, o, std::move(cracked));
  const double half = 0.5 * n * 0.0075;
  sim.set_velocity([&](ldem::Vec3 X) { return ldem::Vec3{0.1 * (X.x - half) / half, 0, 0}; });
  return sim;
}

void set_rate(benchmark::State& state, const ldem::Simulation& sim) {
  state.counters["bar_updates_per_s"] = benchmark::Counter(
      static_cast<double>(sim.lattice().num_bars()) * static_cast<double>(state.iterations()),
      benchmark::Counter::kIsRate);
}

// One step without energies: the intact bars' forces at their nodes and the node update in
// one pass (the bar pass only decides that every row may take the fast path).
void BM_Step(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)));
  for (auto _ : state)
    sim.step(false);
  set_rate(state, sim);
}
BENCHMARK(BM_Step)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// The same step with the fast path off (SolverOptions::intact_at_nodes): every bar through the
// bar pass into the plane buffers, the node pass reading them. What damaged rows, rows near
// e_p, fast-moving parts and materials that vary per bar take.
void BM_StepThroughBarPass(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)), false);
  for (auto _ : state)
    sim.step(false);
  set_rate(state, sim);
}
BENCHMARK(BM_StepThroughBarPass)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// The same step with every bar damaged (pre-cracked): every row through the bar law's general
// kernel, which reads each bar's history, into the plane buffers. Against BM_StepThroughBarPass
// (pristine rows through the intact kernel) and BM_Step: what a damaged bar costs.
void BM_StepDamaged(benchmark::State& state) {
  ldem::Simulation sim = make(static_cast<int>(state.range(0)), true, true);
  for (auto _ : state)
    sim.step(false);
  set_rate(state, sim);
}
BENCHMARK(BM_StepDamaged)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

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

// The core's arithmetic roof: vectors of 8 doubles (GCC vector extensions: one AVX-512
// instruction each, two AVX2 ones), half of the chains a * b + c (one fused multiply-add),
// half a + b, twelve chains so that their latencies overlap. Reports vector operations per
// second (ops_per_s); the step's arithmetic needs about 5.8 of them per bar update on the
// AVX-512 build (bench/README.md, "Roofs").
void BM_ArithmeticPeak(benchmark::State& state) {
  using v8 = double __attribute__((vector_size(64)));
  v8 a0{}, a1{}, a2{}, a3{}, a4{}, a5{}, b0{}, b1{}, b2{}, b3{}, b4{}, b5{};
  const v8 m = v8{} + 0.999999, c = v8{} + 1e-9;
  constexpr std::int64_t kRounds = 1 << 16;
  for (auto _ : state) {
    for (std::int64_t r = 0; r < kRounds; ++r) {
      a0 = a0 * m + c;
      a1 = a1 * m + c;
      a2 = a2 * m + c;
      a3 = a3 * m + c;
      a4 = a4 * m + c;
      a5 = a5 * m + c;
      b0 = b0 + c;
      b1 = b1 + c;
      b2 = b2 + c;
      b3 = b3 + c;
      b4 = b4 + c;
      b5 = b5 + c;
    }
    benchmark::DoNotOptimize(a0);
    benchmark::DoNotOptimize(a1);
    benchmark::DoNotOptimize(a2);
    benchmark::DoNotOptimize(a3);
    benchmark::DoNotOptimize(a4);
    benchmark::DoNotOptimize(a5);
    benchmark::DoNotOptimize(b0);
    benchmark::DoNotOptimize(b1);
    benchmark::DoNotOptimize(b2);
    benchmark::DoNotOptimize(b3);
    benchmark::DoNotOptimize(b4);
    benchmark::DoNotOptimize(b5);
  }
  state.counters["ops_per_s"] = benchmark::Counter(
      12.0 * kRounds * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_ArithmeticPeak);

} // namespace

BENCHMARK_MAIN();
