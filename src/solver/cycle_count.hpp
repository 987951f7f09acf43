// The cycle count of a law with a fatigue life (internal to the solver; bar_law_fatigue.hpp):
// every count_every steps, at the start of the step, every bar's tensile strain at u_n goes
// into its count, and a bar whose life runs out breaks, its elastic energy booked as released.
#pragma once

#include "solver/bar_evaluation.hpp"

#include <omp.h>

namespace ldem {

// The common case of a row's count, in a loop GCC vectorises (a function of its own, every
// array a __restrict parameter: inside the count's lambda GCC 12 keeps it scalar): the
// tensile strain x of each of the n bars, the extreme following it; a lane whose strain has
// come back from its extreme by more than the gate confirms a turning point (turned = 1),
// left for the law. Returns how many did.
[[gnu::noinline]] inline int
follow_extremes(index_t n, const double* __restrict uax, const double* __restrict uay,
                const double* __restrict uaz, const double* __restrict ubx,
                const double* __restrict uby, const double* __restrict ubz, Vec3 d0, double l0,
                double inv_l0, double gate, const double* __restrict turn,
                double* __restrict extreme, double* __restrict x, double* __restrict turned) {
  // (A sum, not an or: GCC 12 vectorises only arithmetic reductions.)
  // (Selects of doubles only, and a signed counter: with either of the selects on bools GCC 12
  // keeps the loop scalar.)
  int confirmed = 0;
  const auto nn = static_cast<std::int64_t>(n);
#pragma omp simd reduction(+ : confirmed)
  for (std::int64_t i = 0; i < nn; ++i) {
    const double e = stretch(d0.x + (ubx[i] - uax[i]), d0.y + (uby[i] - uay[i]),
                             d0.z + (ubz[i] - uaz[i]), l0, inv_l0)
                         .e;
    const double xi = e > 0.0 ? e : 0.0;
    const double t = turn[i], m = extreme[i];
    // Rising (m >= t): back from the extreme by m - x, the extreme the larger; falling: by
    // x - m, the smaller.
    const double back = m >= t ? m - xi : xi - m;
    const double follow = m >= t ? (xi > m ? xi : m) : (xi < m ? xi : m);
    const double turns = back > gate ? 1.0 : 0.0;
    extreme[i] = back > gate ? m : follow;
    x[i] = xi;
    turned[i] = turns;
    confirmed += back > gate ? 1 : 0;
  }
  return confirmed;
}

template <class Law> void count_cycles(SimulationCore& core) {
  if constexpr (kCountsCycles<Law>) {
    // The strains are sampled every count_every steps (from step 0 on, whatever the run's
    // checkpoints and resumes).
    const std::optional<FatigueSpec>& spec = core.table.spec().fatigue;
    if (spec && core.step % spec->count_every != 0)
      return;
    constexpr std::size_t kStates = Law::kStateArrays.size();
    const bool per_bar = core.table.per_bar();
    const std::uint64_t step = core.step;
    using Constants = decltype(Law::fatigue_constants(core.table, 0));
    std::array<Constants, kFamilies> fatigue;
    for (int f = 0; f < kFamilies; ++f)
      fatigue[static_cast<std::size_t>(f)] = Law::fatigue_constants(core.table, f);
    // Rows in parallel: each writes the states of its own bars alone, so the counts and the
    // bars that break are the same for any thread count (the events are sorted when taken).
    for_each_row_by_law(
        core, [](std::size_t) { return true; },
        [&](std::size_t r) {
          const BarRow& row = core.layout.bar_rows[r];
          const FamilyInfo& fi = core.lat.family(row.family);
          const index_t b0 = core.first_bar(r), n = fi.ni;
          const std::array<double*, kStates> states = core.row_states<kStates>(r);
          double* __restrict turn = states[Law::kTurn];
          double* __restrict extreme = states[Law::kExtreme];
          double* __restrict life = states[Law::kLife];
          double* __restrict released = states[Law::kReleased];
          double* __restrict before = states[Law::kDissipatedBefore];
          double* __restrict x = core.thread_scratch[static_cast<std::size_t>(omp_get_thread_num())]
                                     .data();
          double* __restrict turned = x + core.scratch_stride; // 1 where a turn is confirmed
          const double l0 = fi.l0, inv_l0 = 1.0 / fi.l0;
          const Constants& constants = fatigue[static_cast<std::size_t>(row.family)];
          const int confirmed =
              follow_extremes(n, core.ux.data() + row.a_slot, core.uy.data() + row.a_slot,
                              core.uz.data() + row.a_slot, core.ux.data() + row.b_slot,
                              core.uy.data() + row.b_slot, core.uz.data() + row.b_slot, fi.d0, l0,
                              inv_l0, constants.gate, turn, extreme, x, turned);
          if (!confirmed)
            return;
          std::vector<Event>& events =
              core.thread_events[static_cast<std::size_t>(omp_get_thread_num())];
          bool broke = false;
          // The bars with a confirmed turning point, through the law.
          const auto take = [turned](index_t i) { return turned[i] != 0.0; };
          const auto lane = [&](index_t i, Stretch g, const Law& law, typename Law::State s,
                                double k, double EA) {
            const double used = Law::count(constants, x[i], turn[i], extreme[i]);
            if (used == 0.0 || !law.counting(s))
              return;
            life[i] -= used;
            if (life[i] > 0.0)
              return;
            life[i] = 0.0;
            const auto out = law.release(k, EA, l0, g, s);
            released[i] = out.released;
            before[i] = out.dissipated;
            Law::write(states.data(), i, s);
            events.push_back({b0 + i, BarState::Broken, step});
            core.widen_damaged(r, i);
            broke = true;
          };
          if (per_bar)
            visit_law_row<Law, true>(core, r, lane, take);
          else
            visit_law_row<Law, false>(core, r, lane, take);
          if (broke)
            core.row_history_changed[r] = 1;
        });
  }
}

} // namespace ldem
