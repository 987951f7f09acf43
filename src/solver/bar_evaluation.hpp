// The bars evaluated outside the step's kernels (internal to the solver), by the bar law `Law`:
// their states at the start, the rows' pristine flags, the energies of a report step and the
// reference ones, snapshots, internal forces, and the force of one bar or on one node (probes).
#pragma once

#include "solver/core.hpp"
#include "util/error.hpp"
#include "util/parallel.hpp"

#include <cmath>
#include <fmt/format.h>
#include <omp.h>

namespace ldem {

// Whether a law counts strain cycles (and books what bars whose life runs out release).
// Such a law names its arrays of life, released energy, dissipation before the life ran out,
// last turning point and extreme (kLife, kReleased, kDissipatedBefore, kTurn, kExtreme), and
// has count(), counting() and release() (bar_law_fatigue.hpp).
template <class Law>
concept kCountsCycles = requires(const Law law, typename Law::State s, double x, double& t,
                                 Stretch g) {
  {
    Law::count(Law::fatigue_constants(std::declval<const BarTable&>(), 0), x, t, t)
    } -> std::same_as<double>;
  { law.counting(s) } -> std::same_as<bool>;
  law.release(x, x, x, g, s).released;
  Law::kLife;
  Law::kReleased;
  Law::kDissipatedBefore;
  Law::kTurn;
  Law::kExtreme;
  Law::kNewLife;
};

// The strain up to which every pristine bar of a row stays a linear spring: the smallest of
// its n bars' elastic limits from bar `first_bar` on (the family's where the constants are the
// family's; the intact fast path's threshold).
template <class Law>
double row_elastic_limit(const BarTable& table, int family, index_t first_bar, index_t n) {
  const typename Law::Row row = Law::row(table, family, first_bar);
  if (!table.per_bar())
    return Law::template at<false>(row, 0).elastic_limit();
  double e = std::numeric_limits<double>::infinity();
  for (index_t i = 0; i < n; ++i)
    e = std::min(e, Law::template at<true>(row, i).elastic_limit());
  return e;
}

// The bars of row r that the state arrays hold: [p0, p1) in a compact layout
// (StepLayout::state_origin), all of them otherwise.
inline std::pair<index_t, index_t> stored_bars(const SimulationCore& core, std::size_t r) {
  const BarRow& row = core.layout.bar_rows[r];
  return core.layout.compact() ? std::pair{row.p0, row.p1}
                               : std::pair{index_t{0}, core.lat.family(row.family).ni};
}

// A row is "damaged" once any of its bars is not pristine (or is pre-cracked); rows of pristine
// bars skip reading the state. Its damaged span: from its first such bar to its last.
template <class Law> void mark_damaged_rows(SimulationCore& core) {
  constexpr std::size_t kStates = Law::kStateArrays.size();
  const std::size_t rows = core.layout.bar_rows.size();
  core.damaged_span.assign(rows, {0, 0});
  core.row_ratio.assign(rows, kUnknown);
  core.row_dissipated.assign(rows, 0.0);
  core.row_fatigue.assign(rows, 0.0);
  core.row_history_changed.assign(rows, 1); // the states may all be new
  const bool per_bar = core.table.per_bar();
  const auto n_rows = static_cast<std::int64_t>(rows);
#pragma omp parallel for schedule(static) if (core.lat.num_bars() > kParallelMinItems)
  for (std::int64_t r = 0; r < n_rows; ++r) {
    const index_t b0 = core.first_bar(r);
    const typename Law::Row constants = Law::row(core.table, core.layout.bar_rows[r].family, b0);
    const auto states = core.template row_states<kStates>(r);
    const auto [p0, p1] = stored_bars(core, r);
    for (index_t i = p0; i < p1; ++i) {
      const Law law =
          per_bar ? Law::template at<true>(constants, i) : Law::template at<false>(constants, i);
      if (!law.pristine(Law::read(states.data(), i)))
        core.widen_damaged(static_cast<std::size_t>(r), i);
    }
  }
}

// Every bar in its initial state, and the pre-cracked bars broken. Throws InputError for a
// pre-cracked bar that does not exist.
template <class Law>
void init_states(SimulationCore& core, const std::vector<index_t>& precracked) {
  constexpr std::size_t kStates = Law::kStateArrays.size();
  const index_t nb = core.lat.num_bars();
  // (The arrays are sized by the simulation's constructor, one per state array of the law;
  // zeroed by the threads together, which then own their pages: huge pages, first touched in
  // parallel.)
  const auto count = static_cast<std::int64_t>(core.layout.state_count);
  for (UnsetVector<double>& a : core.states) {
#pragma omp parallel for schedule(static) if (count > kParallelMinItems)
    for (std::int64_t q = 0; q < count; ++q)
      a[static_cast<std::size_t>(q)] = 0.0;
  }
  const bool per_bar = core.table.per_bar();
  const auto rows = static_cast<std::int64_t>(core.layout.bar_rows.size());
#pragma omp parallel for schedule(static) if (std::int64_t{nb} > kParallelMinItems)
  for (std::int64_t r = 0; r < rows; ++r) {
    const index_t b0 = core.first_bar(r);
    const typename Law::Row constants = Law::row(core.table, core.layout.bar_rows[r].family, b0);
    const auto states = core.template row_states<kStates>(r);
    const auto [p0, p1] = stored_bars(core, r);
    for (index_t i = p0; i < p1; ++i) {
      const Law law =
          per_bar ? Law::template at<true>(constants, i) : Law::template at<false>(constants, i);
      Law::write(states.data(), i, law.initial());
    }
  }
  // A compact layout's rows at rest, per family (the material's constants per family).
  if (core.layout.compact())
    for (int f = 0; f < kFamilies; ++f) {
      const Law law = Law::template at<false>(Law::row(core.table, f, 0), 0);
      std::array<double*, kStates> rest{};
      for (std::size_t a = 0; a < kStates; ++a)
        rest[a] = core.states[a].data() + core.layout.rest(f);
      for (std::size_t i = 0; i < core.layout.rest_stride; ++i)
        Law::write(rest.data(), static_cast<index_t>(i), law.initial());
    }
  if constexpr (kCountsCycles<Law>)
    std::fill(core.states[Law::kLife].begin(), core.states[Law::kLife].end(), Law::kNewLife);
  for (index_t b : precracked) {
    if (b >= nb)
      throw InputError(fmt::format("pre-crack: bar {} does not exist (lattice has {})", b, nb));
    // (A compact layout holds no state for an absent bar outside its row's [p0, p1): it has
    // no stiffness to lose.)
    if (!core.layout.state_stored(core.layout.state_index(core.lat, b)))
      continue;
    const auto at = core.template bar_states<kStates>(b);
    Law::write(at.data(), 0, Law::precracked());
    if constexpr (kCountsCycles<Law>)
      at[Law::kLife][0] = 0.0; // nothing left to count
  }
}

// visit(r) for every bar row where take(r), rows in parallel (to go through the bar law),
// shared out evenly among the threads: a crack's damaged rows lie together.
template <class P, class F>
void for_each_row_by_law(const SimulationCore& core, P&& take, F&& visit) {
  core.law_rows.clear();
  for (std::size_t r = 0; r < core.layout.bar_rows.size(); ++r)
    if (take(r))
      core.law_rows.push_back(r);
  const auto nlaw = static_cast<std::ptrdiff_t>(core.law_rows.size());
#pragma omp parallel for schedule(static) if (nlaw * core.lat.nx() > kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < nlaw; ++q)
    visit(core.law_rows[static_cast<std::size_t>(q)]);
}

// Every bar of a row (visit_law_row's default).
struct EveryBar {
  constexpr bool operator()(index_t) const { return true; }
};

// lane(i, stretch, law, state, k, EA) for each bar i of row r by the bar law, with its
// stiffness k = E A / l0 and its E A (area factors included), in a loop GCC can vectorise;
// returns the row's bar count. PerBar: the material varies per bar. Only the bars for which
// take(i) holds, when given.
template <class Law, bool PerBar, class F, class T = EveryBar>
index_t visit_law_row(const SimulationCore& core, std::size_t r, F&& lane, T take = {}) {
  constexpr std::size_t kStates = Law::kStateArrays.size();
  const BarRow& row = core.layout.bar_rows[r];
  const FamilyInfo& fi = core.lat.family(row.family);
  const FamilyMaterial& mat = core.table.family(row.family);
  const index_t b0 = core.first_bar(r), n = fi.ni;
  const double* __restrict uax = core.ux.data() + row.a_slot;
  const double* __restrict uay = core.uy.data() + row.a_slot;
  const double* __restrict uaz = core.uz.data() + row.a_slot;
  const double* __restrict ubx = core.ux.data() + row.b_slot;
  const double* __restrict uby = core.uy.data() + row.b_slot;
  const double* __restrict ubz = core.uz.data() + row.b_slot;
  const std::array<const double*, kStates> states = core.template row_states<kStates>(r);
  const std::array<const double*, kStates> rest = core.template rest_states<kStates>(row.family);
  const double* __restrict kb = PerBar ? core.table.k_bar().data() + b0 : nullptr;
  const typename Law::Row constants = Law::row(core.table, row.family, b0);
  // Scalars in locals (the loop vectorises only so); EA = (k l0) factor, as BarTable's.
  const double l0 = fi.l0, inv_l0 = 1.0 / fi.l0, kl0 = mat.k * fi.l0;
  const double inner = row.factor, end = row.end_factor;
  const double d0x = fi.d0.x, d0y = fi.d0.y, d0z = fi.d0.z;
  // A shaped body's area factors per bar (StepLayout::bar_code).
  const std::uint8_t* __restrict code =
      core.layout.coded()
          ? core.layout.bar_code.data() + static_cast<std::size_t>(core.layout.code_origin[r])
          : nullptr;
  // A compact layout (StepLayout::row_window) holds the nodes of the bars [p0, p1) only; the
  // row's other bars are absent (area factor 0), their stretch taken at rest.
  const bool compact = core.layout.compact();
  const index_t p0 = compact ? row.p0 : 0, p1 = compact ? row.p1 : n;
  const Stretch at_rest_g = stretch(d0x, d0y, d0z, l0, inv_l0);
  const auto at_rest = [&](index_t i0, index_t i1) {
    for (index_t i = i0; i < i1; ++i)
      if (take(i))
        lane(i, at_rest_g, Law::template at<PerBar>(constants, i), Law::read(rest.data(), 0), 0.0,
             0.0);
  };
  at_rest(0, p0);
  for (index_t i = p0; i < p1; ++i) {
    if (!take(i))
      continue;
    const Stretch g = stretch(d0x + (ubx[i] - uax[i]), d0y + (uby[i] - uay[i]),
                              d0z + (ubz[i] - uaz[i]), l0, inv_l0);
    const double factor = code ? code[i] * 0.25 : (i == 0 || i + 1 == n) ? end : inner;
    const Law law = Law::template at<PerBar>(constants, i);
    lane(i, g, law, Law::read(states.data(), i), PerBar ? kb[i] : mat.k * factor,
         PerBar ? kb[i] * l0 : kl0 * factor);
  }
  at_rest(p1, n);
  return n;
}

// Row r's dissipated energy, and with `elastic` its elastic energy, by the bar law, each summed
// in bar order.
template <class Law>
Simulation::BarEnergies law_row_energies(const SimulationCore& core, std::size_t r, bool elastic) {
  double* eu = core.thread_scratch[static_cast<std::size_t>(omp_get_thread_num())].data();
  double* ed = eu + core.scratch_stride;
  const double l0 = core.lat.family(core.layout.bar_rows[r].family).l0;
  const auto energies = [eu, ed, elastic, l0](index_t i, Stretch g, const Law& law,
                                              typename Law::State s, double k, double EA) {
    if (elastic)
      eu[i] = law.elastic_energy(law.force_over_length(k, g, s), g, s);
    ed[i] = law.dissipated_energy(EA, l0, s);
  };
  const index_t n = core.table.per_bar() ? visit_law_row<Law, true>(core, r, energies)
                                         : visit_law_row<Law, false>(core, r, energies);
  Simulation::BarEnergies sums;
  for (index_t i = 0; i < n; ++i) { // in bar order, as a bar-by-bar sum
    if (elastic)
      sums.elastic += eu[i];
    sums.damage += ed[i];
  }
  if constexpr (kCountsCycles<Law>) {
    // What the row's bars whose lives ran out released then, and had dissipated before.
    const auto states = core.template row_states<Law::kStateArrays.size()>(r);
    const double* released = states[Law::kReleased];
    const double* before = states[Law::kDissipatedBefore];
    for (index_t i = 0; i < n; ++i) {
      sums.fatigue += released[i];
      sums.damage += before[i];
    }
  }
  return sums;
}

// A report step's elastic and dissipated energy of all bars, per row in energy_rows_u and
// energy_rows_d: the elastic energies the bar pass has put there, the dissipated energy kept
// per row (row_dissipated) and recomputed where a state has changed.
template <class Law> Simulation::BarEnergies report_bar_energies(SimulationCore& core) {
  const bool per_bar = core.table.per_bar();
  for_each_row_by_law(
      core,
      [&](std::size_t r) {
        return (core.row_damaged(r) || per_bar) && core.row_history_changed[r];
      },
      [&](std::size_t r) {
        const Simulation::BarEnergies e = law_row_energies<Law>(core, r, false);
        core.row_dissipated[r] = e.damage;
        core.row_fatigue[r] = e.fatigue;
        core.row_history_changed[r] = 0;
      });
  Simulation::BarEnergies out;
  // Row order: the same for any thread count.
  for (std::size_t r = 0; r < core.layout.bar_rows.size(); ++r) {
    core.energy_rows_d[r] = core.row_damaged(r) || per_bar ? core.row_dissipated[r] : 0.0;
    core.energy_rows_f[r] = core.row_damaged(r) || per_bar ? core.row_fatigue[r] : 0.0;
    out.elastic += core.energy_rows_u[r];
    out.damage += core.energy_rows_d[r];
    out.fatigue += core.energy_rows_f[r];
  }
  return out;
}

// The reference: every row through the law, which also takes a bar of a row still marked
// intact that is strained past its elastic limit now (the next bar pass would mark the row
// damaged).
template <class Law> Simulation::BarEnergies bar_energies(const SimulationCore& core) {
  std::vector<Simulation::BarEnergies> rows(core.layout.bar_rows.size());
  for_each_row_by_law(
      core, [](std::size_t) { return true; },
      [&](std::size_t r) { rows[r] = law_row_energies<Law>(core, r, true); });
  Simulation::BarEnergies out;
  for (const Simulation::BarEnergies& e : rows) { // row order: the same for any thread count
    out.elastic += e.elastic;
    out.damage += e.damage;
    out.fatigue += e.fatigue;
  }
  return out;
}

// Per bar: state, damage, axial force and (with `strain`) axial strain.
template <class Law>
void bar_snapshot(const SimulationCore& core, std::vector<std::uint8_t>& state,
                  std::vector<double>& damage, std::vector<double>& force,
                  std::vector<double>* strain) {
  const index_t nb = core.lat.num_bars();
  state.resize(nb);
  damage.resize(nb);
  force.resize(nb);
  if (strain)
    strain->resize(nb);
  // Rows of pristine bars of a uniform material: F = k (l - l0) times the area factor, no
  // damage, unless a bar of the row is strained past its elastic limit now (the next bar pass
  // would mark the row damaged): such a row goes through the law with the others.
  const bool per_bar = core.table.per_bar();
  core.snapshot_by_law.assign(core.layout.bar_rows.size(), 0);
#pragma omp parallel for schedule(static) if (nb > kParallelMinItems)
  for (std::size_t r = 0; r < core.layout.bar_rows.size(); ++r) {
    if (per_bar || core.row_damaged(r))
      continue;
    const BarRow& row = core.layout.bar_rows[r];
    const FamilyInfo& fi = core.lat.family(row.family);
    const FamilyMaterial& mat = core.table.family(row.family);
    const index_t b0 = core.first_bar(r), n = fi.ni;
    const double* __restrict uax = core.ux.data() + row.a_slot;
    const double* __restrict uay = core.uy.data() + row.a_slot;
    const double* __restrict uaz = core.uz.data() + row.a_slot;
    const double* __restrict ubx = core.ux.data() + row.b_slot;
    const double* __restrict uby = core.uy.data() + row.b_slot;
    const double* __restrict ubz = core.uz.data() + row.b_slot;
    const double l0 = fi.l0, inv_l0 = 1.0 / fi.l0;
    const double inner = mat.k * row.factor, end = mat.k * row.end_factor;
    const double peak = Law::row(core.table, row.family, b0).family.elastic_limit() * fi.l0;
    // (The forces in a loop of doubles alone, which GCC vectorises; the bytes apart.)
    double* __restrict f = force.data() + b0;
    double* __restrict e = strain ? strain->data() + b0 : nullptr;
    const std::uint8_t* __restrict code =
        core.layout.coded()
            ? core.layout.bar_code.data() + static_cast<std::size_t>(core.layout.code_origin[r])
            : nullptr;
    // (A count in a double and an index of 64 bits: with an int among the doubles, GCC 12
    // vectorises the loop by 16 and leaves up to 15 bars of a row to scalar code.)
    double past = 0.0;
    // (A compact layout holds the nodes of the bars [p0, p1) only: the others are absent.)
    const index_t p0 = core.layout.compact() ? row.p0 : 0,
                  p1 = core.layout.compact() ? row.p1 : n;
    std::fill(f, f + p0, 0.0);
    std::fill(f + p1, f + n, 0.0);
    if (e) {
      std::fill(e, e + p0, 0.0);
      std::fill(e + p1, e + n, 0.0);
    }
    const std::int64_t last = static_cast<std::int64_t>(n) - 1;
#pragma omp simd reduction(+ : past)
    for (std::int64_t i = p0; i < static_cast<std::int64_t>(p1); ++i) {
      const double dl = stretch(fi.d0.x + (ubx[i] - uax[i]), fi.d0.y + (uby[i] - uay[i]),
                                fi.d0.z + (ubz[i] - uaz[i]), l0, inv_l0)
                            .dl;
      // (A shaped body's bars: k times the area factor of each; an absent bar is never past.)
      const double k = code ? inner * (code[i] * 0.25) : i == 0 || i == last ? end : inner;
      f[i] = k * dl;
      past += k != 0.0 && dl > peak ? 1.0 : 0.0;
      // (An absent bar's strain is 0, as its force: its area factor is 0.)
      if (e)
        e[i] = k != 0.0 ? dl * inv_l0 : 0.0;
    }
    core.snapshot_by_law[r] = past > 0.0;
    std::fill_n(damage.begin() + b0, n, 0.0);
    std::fill_n(state.begin() + b0, n, std::uint8_t{0});
  }
  // The other rows through the bar law: force and damage in a loop of doubles, the states
  // apart.
  for_each_row_by_law(
      core,
      [&](std::size_t r) { return core.row_damaged(r) || per_bar || core.snapshot_by_law[r]; },
      [&](std::size_t r) {
        const index_t b0 = core.first_bar(r);
        const double l0 = core.lat.family(core.layout.bar_rows[r].family).l0;
        double* f = force.data() + b0;
        double* d = damage.data() + b0;
        double* e = strain ? strain->data() + b0 : nullptr;
        std::uint8_t* st = state.data() + b0;
        const auto values = [f, d, e, l0](index_t i, Stretch g, const Law& law,
                                          typename Law::State s, double k, double EA) {
          d[i] = law.damage(EA, l0, s);
          f[i] = law.force_over_length(k, g, s) * g.l;
          if (e)
            e[i] = EA != 0.0 ? g.e : 0.0; // (an absent bar: EA = 0)
        };
        const index_t n = per_bar ? visit_law_row<Law, true>(core, r, values)
                                  : visit_law_row<Law, false>(core, r, values);
        const typename Law::Row constants =
            Law::row(core.table, core.layout.bar_rows[r].family, b0);
        const auto states = core.template row_states<Law::kStateArrays.size()>(r);
        const auto rest =
            core.template rest_states<Law::kStateArrays.size()>(core.layout.bar_rows[r].family);
        const auto [p0, p1] = stored_bars(core, r);
        for (index_t i = 0; i < n; ++i) {
          const Law law = per_bar ? Law::template at<true>(constants, i)
                                  : Law::template at<false>(constants, i);
          const auto s = i >= p0 && i < p1 ? Law::read(states.data(), i) : Law::read(rest.data(), 0);
          st[i] = static_cast<std::uint8_t>(law.state(s));
        }
      });
}

// The stretch of bar `bar` at u_n.
inline Stretch bar_stretch(const SimulationCore& core, index_t bar) {
  const auto [a, b] = core.lat.bar_nodes(bar);
  const std::size_t qa = core.slot(a), qb = core.slot(b);
  const FamilyInfo& fi = core.lat.family(core.lat.bar_address(bar).family);
  return stretch(fi.d0.x + (core.ux[qb] - core.ux[qa]), fi.d0.y + (core.uy[qb] - core.uy[qa]),
                 fi.d0.z + (core.uz[qb] - core.uz[qa]), fi.l0, 1.0 / fi.l0);
}

// Bar `bar`'s law (its constants) and state.
template <class Law> Law law_of(const SimulationCore& core, index_t bar) {
  const typename Law::Row row =
      Law::row(core.table, static_cast<int>(core.lat.bar_address(bar).family), bar);
  return core.table.per_bar() ? Law::template at<true>(row, 0) : Law::template at<false>(row, 0);
}
template <class Law> typename Law::State bar_law_state(const SimulationCore& core, index_t bar) {
  return Law::read(core.template bar_states<Law::kStateArrays.size()>(bar).data(), 0);
}

template <class Law> BarState bar_state(const SimulationCore& core, index_t bar) {
  return law_of<Law>(core, bar).state(bar_law_state<Law>(core, bar));
}

// Axial force of a bar at the current displacements and state [N].
template <class Law> double bar_force(const SimulationCore& core, index_t bar) {
  const Stretch g = bar_stretch(core, bar);
  return law_of<Law>(core, bar).force_over_length(core.table.stiffness(core.lat, bar), g,
                                                  bar_law_state<Law>(core, bar)) *
         g.l;
}

// Force of its bars on one node at u_n, from the bar law and the states.
template <class Law> Vec3 node_force(const SimulationCore& core, index_t node) {
  const NodeAddress a = core.lat.node_address(node);
  RowLink links[kMaxRowLinks];
  const int nl = row_links(core.lat, core.layout.node_rows[core.node_row_of(node)], links);
  const std::size_t q = core.slot(node);
  Vec3 f;
  for (int l = 0; l < nl; ++l) {
    const RowLink& L = links[l];
    if (a.i < L.ilo || a.i >= L.ihi)
      continue;
    const auto bar = static_cast<index_t>(L.bar_base + a.i);
    const std::size_t o = core.slot(static_cast<index_t>(L.other_base + a.i));
    const double rx = L.r0.x + (core.ux[o] - core.ux[q]), ry = L.r0.y + (core.uy[o] - core.uy[q]),
                 rz = L.r0.z + (core.uz[o] - core.uz[q]);
    const double l0 = core.lat.family(core.lat.bar_address(bar).family).l0;
    const double s = law_of<Law>(core, bar).force_over_length(core.table.stiffness(core.lat, bar),
                                                              stretch(rx, ry, rz, l0, 1.0 / l0),
                                                              bar_law_state<Law>(core, bar));
    f.x += s * rx;
    f.y += s * ry;
    f.z += s * rz;
  }
  return f;
}

// The sum of the bar forces on each node at u_n, node by node.
template <class Law>
void internal_forces(const SimulationCore& core, std::vector<double>& fx, std::vector<double>& fy,
                     std::vector<double>& fz) {
  const index_t nn = core.lat.num_nodes();
  fx.assign(nn, 0.0);
  fy.assign(nn, 0.0);
  fz.assign(nn, 0.0);
  for (index_t bar = 0; bar < core.lat.num_bars(); ++bar) {
    const auto [a, b] = core.lat.bar_nodes(bar);
    const std::size_t qa = core.slot(a), qb = core.slot(b);
    const FamilyInfo& fi = core.lat.family(core.lat.bar_address(bar).family);
    const double dx = fi.d0.x + (core.ux[qb] - core.ux[qa]),
                 dy = fi.d0.y + (core.uy[qb] - core.uy[qa]),
                 dz = fi.d0.z + (core.uz[qb] - core.uz[qa]);
    const double s = law_of<Law>(core, bar).force_over_length(
        core.table.stiffness(core.lat, bar), stretch(dx, dy, dz, fi.l0, 1.0 / fi.l0),
        bar_law_state<Law>(core, bar));
    // A bar in tension pulls its first node towards the second.
    fx[a] += s * dx;
    fy[a] += s * dy;
    fz[a] += s * dz;
    fx[b] -= s * dx;
    fy[b] -= s * dy;
    fz[b] -= s * dz;
  }
}

} // namespace ldem
