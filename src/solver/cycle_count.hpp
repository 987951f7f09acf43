// The cycle count of a law with a fatigue life (internal to the solver; bar_law_fatigue.hpp):
// every count_every steps, at the start of the step, every bar's tensile strain at u_n goes
// into its count, and a bar whose life runs out breaks, its elastic energy booked as released.
#pragma once

#include "solver/bar_evaluation.hpp"

#include <omp.h>

namespace ldem {

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
          const double* __restrict uax = core.ux.data() + row.a_slot;
          const double* __restrict uay = core.uy.data() + row.a_slot;
          const double* __restrict uaz = core.uz.data() + row.a_slot;
          const double* __restrict ubx = core.ux.data() + row.b_slot;
          const double* __restrict uby = core.uy.data() + row.b_slot;
          const double* __restrict ubz = core.uz.data() + row.b_slot;
          const double l0 = fi.l0, inv_l0 = 1.0 / fi.l0;
          const double d0x = fi.d0.x, d0y = fi.d0.y, d0z = fi.d0.z;
          const Constants& constants = fatigue[static_cast<std::size_t>(row.family)];
          const double gate = constants.gate;
          // The common case in a loop GCC vectorises: the extreme follows the strain; a lane
          // whose strain has come back from its extreme by more than the gate confirms a
          // turning point, left for the law below.
          int confirmed = 0;
#pragma omp simd reduction(| : confirmed)
          for (index_t i = 0; i < n; ++i) {
            const double e = stretch(d0x + (ubx[i] - uax[i]), d0y + (uby[i] - uay[i]),
                                     d0z + (ubz[i] - uaz[i]), l0, inv_l0)
                                 .e;
            const double xi = e > 0.0 ? e : 0.0;
            const double t = turn[i], m = extreme[i];
            const bool rising = m >= t;
            const bool turns = rising ? m - xi > gate : xi - m > gate;
            const double follow = rising ? (xi > m ? xi : m) : (xi < m ? xi : m);
            extreme[i] = turns ? m : follow;
            x[i] = xi;
            confirmed |= turns ? 1 : 0;
          }
          if (!confirmed)
            return;
          std::vector<Event>& events =
              core.thread_events[static_cast<std::size_t>(omp_get_thread_num())];
          bool broke = false;
          const auto lane = [&](index_t i, Stretch g, const Law& law, typename Law::State s,
                                double k, double EA) {
            const double m = extreme[i];
            if (!(turn[i] <= m ? m - x[i] > gate : x[i] - m > gate))
              return; // no turning point here
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
            broke = true;
          };
          if (per_bar)
            visit_law_row<Law, true>(core, r, lane);
          else
            visit_law_row<Law, false>(core, r, lane);
          if (broke) {
            core.row_damaged[r] = 1;
            core.row_history_changed[r] = 1;
          }
        });
  }
}

} // namespace ldem
