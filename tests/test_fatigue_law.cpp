// The bilinear law with a fatigue life (`law = "bilinear_fatigue"`, bar_law_fatigue.hpp): its
// cycle count, its bars' lives under prescribed strain cycles, the energy its broken bars
// release, and the scaling of A with the bar length.
#include "analysis/fatigue.hpp"
#include "app/case_run.hpp"
#include "helpers.hpp"
#include "material/bar_law_fatigue.hpp"
#include "solver/law_kernels.hpp"
#include "solver/laws.hpp"

#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <gtest/gtest.h>
#include <numbers>
#include <omp.h>
#include <random>
#include <sstream>
#include <unistd.h>

namespace ldem {
namespace {

using testing::face;
using testing::make_sim;
using testing::unit_material;

// The fatigue constants of a bar.
FatigueConstants law_with(double A, double m, double threshold, double gate) {
  return {A, m, threshold, gate};
}

// Feeds `cycles` cycles of e(t) = D (1 - cos 2 pi t) / 2, sampled `per_cycle` times a cycle,
// plus uniform noise of +-noise, into one bar's count; returns the cycle (time in cycles) at
// which its life runs out, or infinity.
double cycles_to_failure(const FatigueConstants& law, double D, double cycles, int per_cycle,
                         double noise, std::uint32_t seed = 3) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-noise, noise);
  double life = 1.0, turn = 0.0, extreme = 0.0;
  const auto samples = static_cast<std::int64_t>(cycles * per_cycle);
  for (std::int64_t n = 1; n <= samples; ++n) {
    const double t = static_cast<double>(n) / per_cycle;
    const double e = 0.5 * D * (1.0 - std::cos(2.0 * std::numbers::pi * t)) + jitter(rng);
    life -= BilinearFatigueLaw::count(law, e > 0.0 ? e : 0.0, turn, extreme);
    if (life <= 0.0)
      return t;
  }
  return INFINITY;
}

// A bar cycled between 0 and D uses up A D^m / 2 each half-cycle, so it breaks after
// N = 1 / (A D^m) cycles: here A = 1 / (250 D^m), N = 250. A half-cycle counts once the strain
// has come back from its turning point by more than the gate, a fraction of a cycle after the
// turning point, so the count ends within one cycle of N.
// Noise of +-eps with 2 eps below the gate makes no turning points of its own; it only moves
// each peak by at most eps (the valleys at 0 by at most eps too, or not at all where the
// compression is cut off), so each range lies in [D - 2 eps, D + 2 eps] and the bar breaks
// between 1 / (A (D + 2 eps)^m) and 1 / (A (D - 2 eps)^m) cycles, within one cycle more: with
// eps = 1e-3 D that is N (1 -+ 0.002 m), 245 to 255 cycles for m = 10.
TEST(FatigueLaw, ConstantAmplitudeCyclesBreakABarAfterOneOverADm) {
  const double D = 1e-4, gate = 2.5e-7, eps = 1e-7;
  for (double m : {3.0, 6.0, 10.0}) {
    const double N = 250.0, A = 1.0 / (N * std::pow(D, m));
    const FatigueConstants law = law_with(A, m, 0.0, gate);
    EXPECT_NEAR(cycles_to_failure(law, D, 2 * N, 400, 0.0), N, 1.0) << "m " << m;
    const double noisy = cycles_to_failure(law, D, 2 * N, 400, eps);
    EXPECT_GE(noisy, 1.0 / (A * std::pow(D + 2 * eps, m)) - 1.0) << "m " << m;
    EXPECT_LE(noisy, 1.0 / (A * std::pow(D - 2 * eps, m)) + 1.0) << "m " << m;
    // The gate is what keeps the noise out: noise of +-5 gates makes turning points of its
    // own, which split the cycles into half-cycles of other ranges, and the count is no longer
    // the cycles' (earlier for small m, later for large m, where the pieces weigh little).
    const double ungated = cycles_to_failure(law, D, 2 * N, 400, 5.0 * gate);
    EXPECT_FALSE(std::abs(ungated - N) <= 5.0) << "m " << m << ": " << ungated;
  }
}

// Why a fatigue run needs damping (docs/validation/fatigue.md): one wiggle larger than the
// gate inside a rising half-cycle splits it. The path 0 -> D/2 -> D/2 - 2g -> D -> 0 -> D/2
// (straight lines, sampled finely, the turning points among the samples) confirms the peak
// D/2 (range D/2), the valley D/2 - 2g (range 2g), the peak D (range D/2 + 2g) and the valley
// 0 (range D), so it uses A/2 [(D/2)^m + (2g)^m + (D/2 + 2g)^m + D^m] of the life. Rainflow
// counting would take the whole rise, A/2 [D^m + D^m] + A (2g)^m: at m = 6 the rise counts
// 1/28 of its range's share ((1/2)^6 + (0.52)^6 = 0.035).
TEST(FatigueLaw, AWiggleAboveTheGateSplitsAHalfCycle) {
  const double D = 1e-4, g = 1e-6, m = 6.0, A = 1.0 / std::pow(D, m);
  const FatigueConstants law = law_with(A, m, 0.0, g);
  const double corners[] = {0.0, D / 2, D / 2 - 2 * g, D, 0.0, D / 2};
  double used = 0.0, turn = 0.0, extreme = 0.0;
  for (std::size_t k = 0; k + 1 < std::size(corners); ++k)
    for (int n = 1; n <= 100; ++n)
      used += BilinearFatigueLaw::count(law, corners[k] + (corners[k + 1] - corners[k]) * n / 100.0,
                                        turn, extreme);
  const double expected =
      A / 2 *
      (std::pow(D / 2, m) + std::pow(2 * g, m) + std::pow(D / 2 + 2 * g, m) + std::pow(D, m));
  EXPECT_NEAR(used, expected, 1e-12 * expected);
  EXPECT_LT(used, 0.6 * A * std::pow(D, m)); // well below rainflow's A D^m
}

// Half-cycles at or below the threshold use no life; above it, the full A D^m / 2.
TEST(FatigueLaw, RangesAtOrBelowTheThresholdUseNoLife) {
  const double D = 1e-4, m = 4.0, A = 1.0 / (100.0 * std::pow(D, m));
  EXPECT_EQ(cycles_to_failure(law_with(A, m, 1.0001 * D, 1e-6), D, 1000, 100, 0.0), INFINITY);
  EXPECT_NEAR(cycles_to_failure(law_with(A, m, 0.9 * D, 1e-6), D, 1000, 100, 0.0), 100.0, 1.0);
}

// Compression is not a cycle: the count takes e+ = max(e, 0), so a cycle between -D and D has
// the range D of its tensile part, and one between -D and 0 none.
TEST(FatigueLaw, OnlyTheTensileStrainCounts) {
  const double D = 1e-4, m = 3.0, N = 50.0, A = 1.0 / (N * std::pow(D, m));
  const FatigueConstants law = law_with(A, m, 0.0, 1e-6);
  double life = 1.0, turn = 0.0, extreme = 0.0;
  int cycles = 0;
  for (; cycles < 200 && life > 0.0; ++cycles)
    for (int n = 1; n <= 100; ++n) {
      const double e = D * std::sin(2.0 * std::numbers::pi * n / 100.0); // -D to D
      life -= BilinearFatigueLaw::count(law, std::max(e, 0.0), turn, extreme);
    }
  EXPECT_NEAR(cycles, N, 1.0);
  life = 1.0, turn = 0.0, extreme = 0.0;
  for (int n = 1; n <= 20000; ++n)
    life -= BilinearFatigueLaw::count(
        law, std::max(-D * (1.0 - std::cos(2.0 * std::numbers::pi * n / 100.0)), 0.0), turn,
        extreme);
  EXPECT_EQ(life, 1.0);
}

// A = A_ref (l0 / l_ref)^(m/2 - 1) (docs/model.md, "Fatigue"): the normal bars of a lattice of
// L = l_ref take A itself, the diagonals (l0 = L sqrt(3) / 2) A (sqrt(3)/2)^(m/2 - 1), and a
// lattice of half the module size A 2^-(m/2 - 1) for its normal bars.
TEST(FatigueLaw, ACoefficientScalesWithTheBarLength) {
  const double A = 2e9, m = 6.0;
  MaterialSpec spec = unit_material(0.05, 4.0, 0.01);
  spec.fatigue = FatigueSpec{A, m, 0.0, 0.0, 0.01};
  for (double L : {0.01, 0.005}) {
    const Lattice lat(2, 2, 2, L);
    const BarTable table(lat, spec);
    for (int f = 0; f < kFamilies; ++f) {
      const double l0 = lat.family(static_cast<Family>(f)).l0;
      const bool normal = lat.family(static_cast<Family>(f)).kind == BarKind::Normal;
      const double expected =
          A * std::pow((normal ? L : L * std::sqrt(3.0) / 2.0) / 0.01, m / 2.0 - 1.0);
      const FatigueConstants c = BilinearFatigueLaw::fatigue_constants(table, f);
      EXPECT_NEAR(c.A, expected, 1e-12 * expected) << "L " << L << " l0 " << l0;
      // The default gate: 1 % of e_p.
      EXPECT_DOUBLE_EQ(c.gate, 0.01 * 0.05);
    }
  }
}

// One module, L = 1, its bottom face held and its top face moved up and down:
// u_z = (V / w) (1 - cos w t), w = 2 pi f, by an imposed velocity V sin(w t) on all three DOF
// (x and y held at zero), so the four vertical edge bars, between imposed nodes, are strained
// from 0 to D = 2 V / (w L) and back each cycle, whatever the free centre node does. f = 0.002
// is far below the module's lowest eigenfrequency (about 0.3 with E = rho = L = 1), so the
// centre node follows quasi-statically. D = 0.01 stays below e_p = 0.05: the bars never soften
// and take the intact fast path, the count alone breaks them.
struct CycledModule {
  static constexpr double f = 0.002, D = 0.01, m = 4.0;
  double V = D * std::numbers::pi * f; // D = 2 V / (2 pi f)
  Simulation sim(double cycles_to_break) const {
    MaterialSpec spec = unit_material(0.05, 4.0);
    spec.fatigue = FatigueSpec{1.0 / (cycles_to_break * std::pow(D, m)), m, 0.0, 0.0, 1.0};
    const Lattice lat(1, 1, 1, 1.0);
    Conditions c;
    c.fixed.push_back({face(lat, Face::ZMin), kDofAll});
    c.velocities.push_back({face(lat, Face::ZMax),
                            kDofAll,
                            {0, 0, V},
                            TimeFunction({GrowingSine{1.0, f, 0.0, 1.0, 0.0}})});
    SolverOptions o;
    o.law = find_law("bilinear_fatigue");
    return make_sim(1, 1, 1, 1.0, spec, c, o);
  }
  // The bars of the vertical edges (family NZ, normal along z).
  static std::vector<index_t> vertical_edges(const Lattice& lat) {
    std::vector<index_t> out;
    for (index_t b = 0; b < lat.num_bars(); ++b) {
      const Vec3 d = lat.family(lat.bar_address(b).family).d0;
      if (d.x == 0.0 && d.y == 0.0 && d.z != 0.0)
        out.push_back(b);
    }
    return out;
  }
};

// The four vertical edges break together in the cycle the law gives, N = 1 / (A D^m) = 20
// cycles of the displacement, to within one cycle; nothing else breaks (the diagonals, whose
// strain ranges are smaller, would need several times longer; there are no other normal bars
// in tension along z).
TEST(FatigueLaw, BarsOfAModuleUnderPrescribedCyclesBreakOnTime) {
  const CycledModule cm;
  const double N = 20.0;
  Simulation sim = cm.sim(N);
  const std::vector<index_t> edges = CycledModule::vertical_edges(sim.lattice());
  ASSERT_EQ(edges.size(), 4u);
  double broke_at = INFINITY;
  while (sim.time() * CycledModule::f < N + 2.0 && broke_at == INFINITY) {
    sim.step();
    if (sim.bar_state(edges[0]) == BarState::Broken)
      broke_at = sim.time() * CycledModule::f;
  }
  EXPECT_NEAR(broke_at, N, 1.0);
  for (index_t b : edges)
    EXPECT_EQ(sim.bar_state(b), BarState::Broken) << b;
  EXPECT_EQ(sim.broken_count(), 4u);
  const std::vector<Event> events = sim.take_events();
  ASSERT_EQ(events.size(), 4u);
  for (const Event& e : events)
    EXPECT_EQ(e.state, BarState::Broken);
}

// With N = 19.4 the life runs out on the 39th half-cycle (38.8 of them use it up; the ranges
// the count samples every 10 steps lie a little below D, never by 0.2 %), a peak: the edges
// break strained near D and release E A D^2 L / 2 each (times the area factors of the
// module's edges), which the report books as fatigue_dissipated. The balance
// W = U + K + D + F (+ damping) then holds, relative to the largest work put in so far, as well
// as it does for the bilinear law's fractures (test_fracture.cpp: 1 %); without the fatigue term
// it would be off by the released energy, of the order of the work itself (the edges carry
// most of the stored energy).
TEST(FatigueLaw, TheEnergyOfBarsWhoseLifeRunsOutIsBookedAndTheBalanceCloses) {
  const CycledModule cm;
  Simulation sim = cm.sim(19.4);
  double worst = 0.0, released = 0.0, work = 0.0, most = 0.0;
  for (int s = 0; sim.time() * CycledModule::f < 21.0; ++s) {
    sim.step(true);
    const EnergyReport& r = sim.last_report();
    most = std::max(most, r.external_work);
    const double held =
        r.elastic + r.kinetic + r.damage_dissipated + r.damping_dissipated + r.fatigue_dissipated;
    if (most > 0.0)
      worst = std::max(worst, std::abs(r.external_work - held) / most);
    released = r.fatigue_dissipated;
    work = r.external_work;
  }
  ASSERT_EQ(sim.broken_count(), 4u);
  EXPECT_GT(released, 0.1 * work) << "work " << work;
  EXPECT_LT(worst, 0.01);
  // Each edge held at most E A D^2 L / 2 when it broke, A its area with the area factor (at
  // most 1), and at least what it held at D - gate - the strain of one step.
  EXPECT_LT(released, 4.0 * 0.5 * std::pow(CycledModule::D, 2) * sim.table().family(0).area);
}

// Cycles past e_p: the edges soften on the first peak (D = 0.06 > e_p = 0.05, history 0.06,
// below e_r = 0.2) and their lives then run out after N = 5 cycles. What their softening had
// dissipated stays in damage_dissipated (the bilinear law would count nothing for a broken
// bar's infinite history): the dissipated energy never decreases, and the balance holds as
// above.
TEST(FatigueLaw, ABarWhoseLifeRunsOutKeepsWhatItsSofteningDissipated) {
  CycledModule cm;
  cm.V = 0.06 * std::numbers::pi * CycledModule::f; // D = 0.06
  Simulation sim = cm.sim(5.0 * std::pow(0.06 / CycledModule::D, CycledModule::m));
  double last_damage = 0.0, most = 0.0, worst = 0.0;
  std::uint64_t softened_at = 0;
  for (int s = 0; sim.time() * CycledModule::f < 6.5; ++s) {
    sim.step(true);
    const EnergyReport& r = sim.last_report();
    EXPECT_GE(r.damage_dissipated, last_damage) << "t " << r.time;
    last_damage = r.damage_dissipated;
    if (softened_at == 0 && r.damage_dissipated > 0.0)
      softened_at = sim.step_count();
    most = std::max(most, r.external_work);
    const double held =
        r.elastic + r.kinetic + r.damage_dissipated + r.damping_dissipated + r.fatigue_dissipated;
    if (most > 0.0)
      worst = std::max(worst, std::abs(r.external_work - held) / most);
  }
  EXPECT_GT(softened_at, 0u);
  EXPECT_EQ(sim.broken_count(), 4u);
  EXPECT_GT(sim.last_report().fatigue_dissipated, 0.0);
  EXPECT_GT(last_damage, 0.0);
  EXPECT_LT(worst, 0.01);
}

// Rows are counted in parallel, each writing its own bars: a plate of 40 x 1 x 40 modules
// (22k bars, above kParallelMinItems) cycled until bars break gives the same states, bit for
// bit, and the same events on 1 and 2 threads.
TEST(FatigueLaw, TheCountIsTheSameOnAnyThreadCount) {
  const auto run = [](int threads) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
    const index_t n = 40;
    const Lattice lat(n, 1, n, 1.0);
    MaterialSpec spec = unit_material(0.05, 4.0);
    spec.fatigue = FatigueSpec{1.0 / (3.0 * std::pow(0.01, 4.0)), 4.0, 0.0, 0.0, 1.0, 5};
    Conditions c;
    c.plane_strain_axis = 1;
    c.fixed.push_back({face(lat, Face::ZMin), kDofZ});
    c.velocities.push_back({face(lat, Face::ZMax),
                            kDofZ,
                            {0, 0, 0.4 * std::numbers::pi * 0.002},
                            TimeFunction({GrowingSine{1.0, 0.002, 0.0, 1.0, 0.0}})});
    SolverOptions o;
    o.law = find_law("bilinear_fatigue");
    Simulation sim = make_sim(n, 1, n, 1.0, spec, c, o);
    while (sim.time() * 0.002 < 4.0)
      sim.step(sim.step_count() % 50 == 0);
    std::vector<double> states;
    for (std::size_t a = 0; a < sim.bar_state_arrays().size(); ++a)
      sim.append_bar_states(a, 0, lat.num_bars(), states);
    omp_set_num_threads(before);
    return std::pair{states, sim.take_events()};
  };
  const auto [one, events_one] = run(1);
  const auto [two, events_two] = run(2);
  ASSERT_FALSE(events_one.empty()) << "no bar broke: the test tests nothing";
  EXPECT_EQ(one, two);
  ASSERT_EQ(events_one.size(), events_two.size());
  for (std::size_t i = 0; i < events_one.size(); ++i) {
    EXPECT_EQ(events_one[i].bar, events_two[i].bar);
    EXPECT_EQ(events_one[i].step, events_two[i].step);
  }
}

// The tutorial plate (cases/tutorial/notched_plate.toml) with the fatigue law, its top edge
// moved up and down at 1000 Hz (a velocity amplitude of 2 mm/s, constant from the start): the
// bars ahead of the notch run out of life after some 30 cycles. Its run, fully resolved or with
// cycle jumping (`jump`), to `cycles` cycles; the cycle at which each bar broke, in order.
std::vector<std::pair<index_t, double>>
tutorial_breaks(bool jump, double cycles, const std::string& out,
                std::optional<std::array<Vec3, 2>> box = std::nullopt) {
  std::filesystem::remove_all(out);
  RunOptions o;
  o.out_dir = out;
  o.plots = false;
  o.adjust = [&](CaseSpec& s) {
    s.law = "bilinear_fatigue";
    FatigueSpec f{1e18, 4.0, 0.0, 0.0, s.L};
    f.jump = jump;
    f.box = box;
    s.material.fatigue = f;
    s.velocities.at(0).value = {0.0, 0.0, 0.002};
    s.velocities.at(0).scale = TimeFunction({GrowingSine{1.0, 1000.0, 0.0, 1.0, 0.0}});
    s.end_time = cycles / 1000.0;
    s.output.vtu = false;
    s.output.energy_every = 100;
  };
  EXPECT_EQ(run_command(std::string(LDEM_SOURCE_DIR) + "/cases/tutorial/notched_plate.toml", o), 0);
  // Cycles jumped before each energy row's state; a break at time t comes after the jumps
  // made at rows before t (a jump follows its row).
  std::vector<std::pair<double, double>> jumped;
  std::ifstream energy(out + "/energy.csv");
  std::string line;
  std::getline(energy, line);
  const bool column = line.ends_with(",jumped_cycles");
  EXPECT_EQ(column, jump) << line;
  while (std::getline(energy, line)) {
    const double t = std::stod(line.substr(0, line.find(',')));
    jumped.emplace_back(t, column ? std::stod(line.substr(line.rfind(',') + 1)) : 0.0);
  }
  std::vector<std::pair<index_t, double>> out_breaks;
  std::ifstream events(out + "/events.csv");
  std::getline(events, line);
  while (std::getline(events, line)) {
    if (line.find(",broken,") == std::string::npos)
      continue;
    const auto bar = static_cast<index_t>(std::stoul(line.substr(0, line.find(','))));
    const std::size_t at = line.find(",broken,") + 8;
    const double t = std::stod(line.substr(at, line.find(',', at) - at));
    double J = 0.0;
    for (const auto& [tr, j] : jumped)
      if (tr >= t) {
        J = j;
        break;
      }
    out_breaks.emplace_back(bar, 1000.0 * t + J);
  }
  return out_breaks;
}

// Jumped and fully resolved runs break the same first bars at the same cycle. A jump moves each
// bar's life on at the rate it used it over the last resolved window (4 cycles), stops a cycle
// short of the first bar's end (jump_breaks = 0) and uses at most a fifth of any life; the
// cycles before the first break are then resolved as in the full run, and the first break
// comes within the cycle in which it comes there, to within the part of a cycle between two
// samples: tolerance 1 cycle. That holds while the rates stay as they were over the window:
// the first two bars, here; later ones break where the damage of the first has changed the
// strains, and the runs may part. The jumped run must have jumped (else it tests nothing).
TEST(FatigueLaw, JumpedAndResolvedRunsBreakTheFirstBarsAtTheSameCycle) {
  // (A folder of this process's own: two test runs at once must not share it.)
  const std::string dir =
      (std::filesystem::temp_directory_path() / fmt::format("ldem_jump_{}_", ::getpid())).string();
  const auto resolved = tutorial_breaks(false, 40.0, dir + "resolved");
  const auto jumped = tutorial_breaks(true, 40.0, dir + "jumped");
  ASSERT_GE(resolved.size(), 2u);
  ASSERT_GE(jumped.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(jumped[i].first, resolved[i].first) << i;
    EXPECT_NEAR(jumped[i].second, resolved[i].second, 1.0) << i;
  }
  std::ifstream js(dir + "jumped/summary.json");
  std::stringstream text;
  text << js.rdbuf();
  EXPECT_NE(text.str().find("\"jumped_cycles\": "), std::string::npos);
  EXPECT_EQ(text.str().find("\"jumped_cycles\": 0,"), std::string::npos) << text.str();
  std::filesystem::remove_all(dir + "resolved");
  std::filesystem::remove_all(dir + "jumped");
}

// [fatigue] box_min/box_max: only the bars that meet the box have a life. Lives do not
// change the mechanics until a bar breaks, so with a box around the notch's plane (the band
// of module rows 9 and 10, z from 0.045 to 0.055 m, where the whole run's first bars break)
// the run is the whole run up to its first break, which must be the same bar at the same
// cycle, bit for bit. With a box over the top quarter of the plate, far from the notch, no bar
// breaks in the 32 cycles in which the whole run breaks its first.
TEST(FatigueLaw, OnlyTheBarsInTheFatigueBoxHaveALife) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / fmt::format("ldem_box_{}_", ::getpid())).string();
  const auto whole = tutorial_breaks(false, 32.0, dir + "whole");
  ASSERT_GE(whole.size(), 1u);
  const auto band =
      tutorial_breaks(false, 32.0, dir + "band",
                      std::array<Vec3, 2>{Vec3{0.0, 0.0, 0.045}, Vec3{0.2, 0.005, 0.055}});
  ASSERT_GE(band.size(), 1u);
  EXPECT_EQ(band[0].first, whole[0].first);
  EXPECT_EQ(band[0].second, whole[0].second);
  const auto top = tutorial_breaks(
      false, 32.0, dir + "top", std::array<Vec3, 2>{Vec3{0.0, 0.0, 0.075}, Vec3{0.2, 0.005, 0.1}});
  EXPECT_TRUE(top.empty()) << top.size() << " bars broke";
  for (const char* d : {"whole", "band", "top"})
    std::filesystem::remove_all(dir + d);
}

// The fatigue analysis counts jumped cycles: N(t) = (t - t_constant) f plus the cycles jumped
// before t, those of energy.csv's first row at or after t (a jump follows its row). At 10 Hz
// from t = 1 s, with 100 cycles jumped after the row at t = 2 s: N(1.5) = 5, N(2) = 10 (the
// row's state comes before its jump), N(2.5) = 15 + 100, N(4) = 30 + 100 (past the last row).
TEST(FatigueLaw, TheFatigueAnalysisCountsJumpedCycles) {
  CyclicLoad load;
  load.frequency = 10.0;
  load.t_constant = 1.0;
  EXPECT_DOUBLE_EQ(load.cycles_at(2.5), 15.0); // no jumps: the load's cycles alone
  load.row_t = {1.0, 2.0, 3.0};
  load.jumped = {0.0, 0.0, 100.0};
  EXPECT_DOUBLE_EQ(load.cycles_at(1.5), 5.0);
  EXPECT_DOUBLE_EQ(load.cycles_at(2.0), 10.0);
  EXPECT_DOUBLE_EQ(load.cycles_at(2.5), 115.0);
  EXPECT_DOUBLE_EQ(load.cycles_at(4.0), 130.0);
}

} // namespace
} // namespace ldem
