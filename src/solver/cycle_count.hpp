// The cycle count of a law with a fatigue life (internal to the solver; bar_law_fatigue.hpp):
// every count_every steps, at the start of the step, every bar's tensile strain at u_n goes
// into its count, and a bar whose life runs out breaks, its elastic energy booked as released.
#pragma once

#include "solver/bar_evaluation.hpp"

#include <omp.h>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

namespace ldem {

#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip these warnings on _mm512_sqrt_pd, _mm512_max_pd and
// _mm512_min_pd (a known false alarm: their unused pass-through operand).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

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
#if defined(__AVX512F__)
  // Whole vectors of 8 with the row's last one masked (GCC 12 leaves the loop below a scalar
  // tail of up to 7 bars, a fifth of its time on rows of 100): the same operations in the same
  // order on each lane, so the same bits.
  const auto nn = static_cast<std::int64_t>(n);
  const __m512d zero = _mm512_setzero_pd(), one = _mm512_set1_pd(1.0);
  const __m512d vx0 = _mm512_set1_pd(d0.x), vy0 = _mm512_set1_pd(d0.y), vz0 = _mm512_set1_pd(d0.z),
                vl0 = _mm512_set1_pd(l0), vinv = _mm512_set1_pd(inv_l0),
                vgate = _mm512_set1_pd(gate);
  int confirmed = 0;
  for (std::int64_t i = 0; i < nn; i += 8) {
    const __mmask8 k =
        nn - i >= 8 ? static_cast<__mmask8>(0xFF) : static_cast<__mmask8>((1U << (nn - i)) - 1);
    const auto at = [k, i](const double* p) { return _mm512_maskz_loadu_pd(k, p + i); };
    const __m512d dx = _mm512_add_pd(vx0, _mm512_sub_pd(at(ubx), at(uax)));
    const __m512d dy = _mm512_add_pd(vy0, _mm512_sub_pd(at(uby), at(uay)));
    const __m512d dz = _mm512_add_pd(vz0, _mm512_sub_pd(at(ubz), at(uaz)));
    // stretch(): l = sqrt(dx dx + dy dy + dz dz), e = (l - l0) / l0 as (l - l0) inv_l0.
    const __m512d l = _mm512_sqrt_pd(_mm512_add_pd(
        _mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz)));
    const __m512d e = _mm512_mul_pd(_mm512_sub_pd(l, vl0), vinv);
    const __m512d xi = _mm512_max_pd(e, zero); // e > 0 ? e : 0 (vmaxpd: the second if not >)
    const __m512d t = at(turn), m = at(extreme);
    const __mmask8 rising = _mm512_cmp_pd_mask(m, t, _CMP_GE_OQ);
    const __m512d back = _mm512_mask_blend_pd(rising, _mm512_sub_pd(xi, m), _mm512_sub_pd(m, xi));
    // xi > m ? xi : m rising, xi < m ? xi : m falling.
    const __m512d follow = _mm512_mask_blend_pd(rising, _mm512_min_pd(xi, m), _mm512_max_pd(xi, m));
    const __mmask8 turns = _mm512_cmp_pd_mask(back, vgate, _CMP_GT_OQ) & k;
    _mm512_mask_storeu_pd(extreme + i, k, _mm512_mask_blend_pd(turns, follow, m));
    _mm512_mask_storeu_pd(x + i, k, xi);
    _mm512_mask_storeu_pd(turned + i, k, _mm512_maskz_mov_pd(turns, one));
    confirmed += __builtin_popcount(static_cast<unsigned>(turns));
  }
  return confirmed;
#else
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
#endif
}

#pragma GCC diagnostic pop

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
