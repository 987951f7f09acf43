// The bar pass (internal to the solver): s = F / l for the bars of a line from u_n and their
// states, by the bar law `Law` (bar_law.hpp) or, for rows of pristine bars of a uniform
// material, by the intact kernel; then the slow path: the law's state update and events of
// the bars whose state changes.
#pragma once

#include "solver/core.hpp"
#include "solver/intact_spring.hpp"

#include <cmath>
#include <omp.h>
#include <type_traits>

namespace ldem {

struct RowView {
  const double *uax, *uay, *uaz, *ubx, *uby, *ubz;
  double* s;
};

// The general kernel: s = F / l for a row of n bars by the law. Returns true if some bar's
// state changes (Law::changes), to be handled by the slow path. The law's constants are per
// bar with PerBar (BarTable::per_bar), the family's otherwise; the stiffness is k_row, E A / l0
// times the area factor, or with PerBarK each bar's own, k_bar. `Intact`: every bar of the row
// is pristine (its state is not read). With `Energy`, also the sum over the row of each bar's
// elastic energy into *energy, from its force over length times w, w = 1 for inner bars and
// `end_scale` for the first and last (the factor the caller applies to their forces
// afterwards; a part of a row passes which of its ends are the row's: first_end, last_end).
// `Coded`: a shaped body's row, each bar's force and energy times its area factor
// code / 4 (StepLayout::bar_code), its absent bars (code 0) with s = 0 and no state change.
// Into `changed`, 1 at each bar whose state changes and 0 at the others, so that the slow path
// looks at those bars alone. (Inlined where it is called, as intact_row_kernel.)
template <class Law, bool PerBar, bool PerBarK, bool Intact, bool Energy = false,
          bool Coded = false>
[[gnu::always_inline]] inline bool
bar_row_kernel(index_t n, const RowView& r, const typename Law::Row& constants,
               const std::array<const double*, Law::kStateArrays.size()>& states, Vec3 d0,
               double l0, double k_row, const double* __restrict k_bar, double end_scale,
               double* energy, const std::uint8_t* __restrict code, bool first_end, bool last_end,
               double* __restrict changed) {
  const double inv_l0 = 1.0 / l0;
  double past = 0.0; // a sum, not a bool: GCC vectorises only arithmetic reductions
  double sum = 0.0;
  // The row's pointers in locals: read through `r` in the loop, GCC 12 loads them anew for
  // every bar and gathers the rows lane by lane.
  const double* __restrict uax = r.uax;
  const double* __restrict uay = r.uay;
  const double* __restrict uaz = r.uaz;
  const double* __restrict ubx = r.ubx;
  const double* __restrict uby = r.uby;
  const double* __restrict ubz = r.ubz;
  double* __restrict sr = r.s;
  const typename Law::Row row = constants;
  const std::array<const double*, Law::kStateArrays.size()> st = states;
  const auto nn = static_cast<std::int64_t>(n);
  const std::int64_t e0 = first_end ? 0 : -1, e1 = last_end ? nn - 1 : -1;
  // bar(i): 1 if bar i's state changes, and with Energy its term of the sum; the loops name
  // only the reductions they have (GCC 12 vectorises neither with one that stays unused).
  // (Its flag a double, 1 or 0: with an int among the doubles, GCC 12 vectorises by 16 ints, and
  // a loop of n bars leaves up to 15 of them to scalar code.)
  struct Term {
    double past;
    double energy;
  };
  const auto bar = [&](std::int64_t i) {
    const Stretch g = stretch(d0.x + (ubx[i] - uax[i]), d0.y + (uby[i] - uay[i]),
                              d0.z + (ubz[i] - uaz[i]), l0, inv_l0);
    const Law law = Law::template at<PerBar>(row, i);
    const typename Law::State s = Intact ? law.initial() : Law::read(st.data(), i);
    double si = law.force_over_length(PerBarK ? k_bar[i] : k_row, g, s);
    double w = i == e0 || i == e1 ? end_scale : 1.0;
    double present = 1.0;
    if constexpr (Coded) {
      // (Without a branch, which would keep GCC from vectorising the loop: an absent bar's s is
      // its finite force times 0.)
      present = code[i] != 0 ? 1.0 : 0.0;
      si *= code[i] * 0.25;
      w = 1.0; // (the area factor is in si)
    }
    sr[i] = si;
    Term t{law.changes(g.e, s) ? present : 0.0, 0.0};
    changed[i] = t.past;
    if constexpr (Energy)
      t.energy = law.elastic_energy(w * si, g, s);
    return t;
  };
  if constexpr (Energy) {
#pragma omp simd reduction(+ : past, sum)
    for (std::int64_t i = 0; i < nn; ++i) {
      const Term t = bar(i);
      past += t.past;
      sum += t.energy;
    }
  } else if (nn >= 8) {
    // Whole vectors of 8 bars, the last one ending at the row's end (over the one before it if
    // n is not a multiple of 8: those bars are taken again with the same bits, and `past` only
    // tells whether some bar changes). GCC 12 leaves the rest of a loop of n to a scalar loop,
    // whose square roots and divisions, one bar at a time, took most of a short row's time.
    const std::int64_t whole = nn - nn % 8;
#pragma omp simd reduction(+ : past)
    for (std::int64_t i = 0; i < whole; ++i)
      past += bar(i).past;
    if (whole < nn) {
      double last = 0.0;
#pragma omp simd reduction(+ : last)
      for (std::int64_t l = 0; l < 8; ++l)
        last += bar(nn - 8 + l).past;
      past += last;
    }
  } else {
#pragma omp simd reduction(+ : past)
    for (std::int64_t i = 0; i < nn; ++i)
      past += bar(i).past;
  }
  if constexpr (Energy)
    *energy = sum;
  return past > 0.0;
}

#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip these warnings on _mm512_maskz_loadu_pd and
// _mm512_reduce_max_pd (a known false alarm: their unused pass-through operand).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"

// The common case: a row of pristine bars with uniform constants, a linear spring of stiffness
// k below the law's elastic limit e_lim. Then s = k (l - l0) / l = k - k l0 / l, and the test
// e > e_lim is l^2 > (l0 (1 + e_lim))^2, so the row needs 1 / sqrt(l^2) and nothing else: with
// AVX-512 it comes from inv_sqrt, which keeps the divider free. Returns true if some bar may be
// past e_lim (the caller then redoes the row with the general kernel). With `Energy`, also sum
// w (l - l0)^2 over the row into *energy, w = 1 for inner bars and `end_scale` for the first and
// last (their area factor over the row's). l2_max: the largest l^2 of the row's bars.
// (Inlined where it is called: GCC 12 does not vectorise the portable loop's reductions in a
// copy of its own.)
// `code`: a shaped body's row (StepLayout::bar_code): each bar's force and energy times its
// area factor code / 4 (as the node kernel's times_quarters has it, the same bits), its absent
// bars with s = 0, neither tested nor measured.
// [skip_lo, skip_hi): bars that another kernel computes afterwards (a damaged span): neither
// tested, measured nor summed (their forces may be written, to be overwritten; the vectors
// wholly inside it are not taken at all).
// `k_bar`: a row whose E varies along it (BarRow::own_stiffness): each bar's own k, area factors
// included (k and end_scale unused), s = k_i - k_i l0 / l, and into *energy the sum of k_i
// (l - l0)^2 (the k inside the sum). e_lim is then the smallest of the row's elastic limits.
template <bool Energy>
[[gnu::always_inline]] inline bool
intact_row_kernel(index_t n, const RowView& r, Vec3 d0, double l0, double k, double e_lim,
                  double end_scale, double* energy, double& l2_max,
                  const std::uint8_t* __restrict code = nullptr, index_t skip_lo = 0,
                  index_t skip_hi = 0, const double* __restrict k_bar = nullptr) {
  // Slightly below the exact threshold, so that a bar at e_lim to within rounding is handed to
  // the general kernel, whose strain test is the reference.
  const double lp2 = l0 * l0 * (1.0 + e_lim) * (1.0 + e_lim) * (1.0 - 1e-12);
#if defined(__AVX512F__)
  const __m512d vx = _mm512_set1_pd(d0.x), vy = _mm512_set1_pd(d0.y), vz = _mm512_set1_pd(d0.z);
  const __m512d vk = _mm512_set1_pd(k), vkl0 = _mm512_set1_pd(k * l0);
  const __m512d vlp2 = _mm512_set1_pd(lp2);
  __m512d acc = _mm512_setzero_pd(), top = _mm512_setzero_pd();
  __mmask8 past = 0;
  // The row's pointers in locals: read through `r` in the loop, GCC 12 reloaded them from the
  // caller's frame for every vector.
  const double *const uax = r.uax, *const uay = r.uay, *const uaz = r.uaz;
  const double *const ubx = r.ubx, *const uby = r.uby, *const ubz = r.ubz;
  double* const sr = r.s;
  // Whole vectors with plain loads and stores, the row's tail (n not a multiple of 8) masked.
  const auto vector = [&]<bool Tail>(index_t i, __mmask8 m) {
    const auto load = [m](const double* p) {
      return Tail ? _mm512_maskz_loadu_pd(m, p) : _mm512_loadu_pd(p);
    };
    const __m512d ux = _mm512_sub_pd(load(ubx + i), load(uax + i));
    const __m512d uy = _mm512_sub_pd(load(uby + i), load(uay + i));
    const __m512d uz = _mm512_sub_pd(load(ubz + i), load(uaz + i));
    const __m512d dx = _mm512_add_pd(vx, ux), dy = _mm512_add_pd(vy, uy),
                  dz = _mm512_add_pd(vz, uz);
    const __m512d l2 = _mm512_fmadd_pd(dx, dx, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dz, dz)));
    const __m512d y = inv_sqrt(l2);
    // Each bar's k with k_bar (whose rows have no codes: their area factors are in it).
    const __m512d kb = k_bar ? load(k_bar + i) : vk;
    __m512d s = _mm512_fnmadd_pd(k_bar ? _mm512_mul_pd(kb, _mm512_set1_pd(l0)) : vkl0, y, kb);
    // The lanes tested, measured and summed.
    __mmask8 keep = m;
    if (i < skip_hi && i + 8 > skip_lo)
      keep = static_cast<__mmask8>(keep & ~lanes_in(i, skip_lo, skip_hi));
    if (code) {
      __mmask8 present = 0;
      const __m512d f = code_factors(code + i, Tail ? n - i : 8, present);
      s = _mm512_maskz_mul_pd(present, s, f);
      _mm512_mask_storeu_pd(sr + i, m, s);
      past |= _mm512_mask_cmp_pd_mask(keep & present, l2, vlp2, _CMP_GT_OQ);
      top = _mm512_mask_max_pd(top, keep & present, top, l2);
      if constexpr (Energy)
        acc = add_intact_energy(acc, ux, uy, uz, d0, l2, y, l0, keep & present, f);
      return;
    }
    if constexpr (Tail)
      _mm512_mask_storeu_pd(sr + i, m, s);
    else
      _mm512_storeu_pd(sr + i, s);
    if (keep == 0xFF) {
      past |= _mm512_cmp_pd_mask(l2, vlp2, _CMP_GT_OQ);
      top = _mm512_max_pd(top, l2);
    } else {
      past |= _mm512_mask_cmp_pd_mask(keep, l2, vlp2, _CMP_GT_OQ);
      top = _mm512_mask_max_pd(top, keep, top, l2);
    }
    if constexpr (Energy) {
      // Zero beyond the row's end, weighted at its ends.
      __mmask8 ends = 0;
      if (i == 0)
        ends |= 1;
      if (n - 1 - i < 8)
        ends |= static_cast<__mmask8>(1u << (n - 1 - i));
      acc = k_bar ? add_intact_energy(acc, ux, uy, uz, d0, l2, y, l0, keep, kb)
                  : add_intact_energy(acc, ux, uy, uz, d0, l2, y, l0, keep, ends, end_scale);
    }
  };
  // (Vectors wholly inside [skip_lo, skip_hi) are left to the other kernel: no store.)
  index_t i = 0;
  for (; i + 8 <= n; i += 8)
    if (i < skip_lo || i + 8 > skip_hi)
      vector.template operator()<false>(i, 0xFF);
  if (i < n && (i < skip_lo || n > skip_hi))
    vector.template operator()<true>(i, static_cast<__mmask8>((1u << (n - i)) - 1u));
  if constexpr (Energy)
    *energy = _mm512_reduce_add_pd(acc);
  l2_max = _mm512_reduce_max_pd(top);
  return past != 0;
#else
  int past = 0;
  double sum = 0.0;
  // bar(i) gives 1 if bar i is past e_lim, and with Energy its term of the sum; the loops name
  // only the reductions they have (GCC 12 vectorises neither with one that stays unused).
  struct Term {
    int past;
    double energy;
  };
  const auto bar = [&](index_t i) {
    const double ux = r.ubx[i] - r.uax[i], uy = r.uby[i] - r.uay[i], uz = r.ubz[i] - r.uaz[i];
    const double dx = d0.x + ux, dy = d0.y + uy, dz = d0.z + uz;
    const double l2 = dx * dx + dy * dy + dz * dz;
    const double l = std::sqrt(l2);
    const bool present = code == nullptr || code[i] != 0;
    const double f = code ? code[i] * 0.25 : 1.0;
    const double kk = k_bar ? k_bar[i] : k;
    r.s[i] = present ? (kk - kk * l0 / l) * f : 0.0;
    const bool kept = present && (i < skip_lo || i >= skip_hi);
    Term t{kept && l2 > lp2 ? 1 : 0, 0.0};
    if constexpr (Energy) { // as above
      const double dl =
          (ux * (ux + 2 * d0.x) + uy * (uy + 2 * d0.y) + uz * (uz + 2 * d0.z)) / (l + l0);
      const double w = k_bar ? k_bar[i] : code ? f : i == 0 || i + 1 == n ? end_scale : 1.0;
      t.energy = kept ? w * dl * dl : 0.0;
    }
    return t;
  };
  if constexpr (Energy) {
    double passed = 0.0; // (both sums in doubles, as in bar_row_kernel)
#pragma omp simd reduction(+ : passed, sum)
    for (index_t i = 0; i < n; ++i) {
      const Term t = bar(i);
      passed += t.past;
      sum += t.energy;
    }
    past = passed > 0.0;
    *energy = sum;
  } else {
#pragma omp simd reduction(+ : past)
    for (index_t i = 0; i < n; ++i)
      past += bar(i).past;
  }
  l2_max = std::numeric_limits<double>::infinity(); // (the fast path is off: kVectorKernel)
  return past > 0;
#endif
}

// A bar's length after this step's motion is at most its length now plus the motion of its
// two nodes: l_{n+1} <= l_n + |u_{n+1} - u_n|_a + |u_{n+1} - u_n|_b. At the start of step n+1
// the row knows the largest (l_n / l_p)^2 of its bars (row_ratio, measured by whichever pass
// computed them at step n) and its node rows' largest motion in step n (node_row_motion), so
// if sqrt(ratio) + (motion_a + motion_b) / l_p stays below 1 no bar of the row can pass its
// elastic limit, and the pristine spring alone gives its force. (Of a damaged row, the same
// of its bars outside its damaged span, which are pristine: the ratio is theirs.) The margin
// of 1e-9 covers the rounding of those sums (a few units of 1e-16) and keeps the bars clear of
// the intact kernel's own threshold, l_p^2 (1 - 1e-12). An unknown ratio or motion is
// infinite, which fails the test.
inline bool bar_row_stays_intact(const SimulationCore& core, std::size_t r) {
  constexpr double kMargin = 1.0 - 1e-9;
  const auto [a, b] = core.layout.bar_row_nodes[r];
  // sqrt(ratio) + m <= margin, in squares (m <= margin first, which also fails on a NaN).
  const double m = (core.node_row_motion[a] + core.node_row_motion[b]) * core.layout.row_inv_lp[r];
  return !core.layout.bar_rows[r].own_stiffness() && m <= kMargin &&
         core.row_ratio[r] <= (kMargin - m) * (kMargin - m);
}

// Which way a bar row's bars go this step (SimulationCore::row_fast): a pristine row's all at
// the nodes if bar_row_stays_intact; a damaged row's outside its damaged span at the nodes if
// that holds for them (row_ratio is theirs) and there are some, its span in the bar pass; else
// the bar pass.
inline std::uint8_t bar_row_way(const SimulationCore& core, std::size_t r) {
  if (!core.fast_path || !bar_row_stays_intact(core, r))
    return kRowByPass;
  if (!core.row_damaged(r))
    return kRowFast;
  const BarRow& row = core.layout.bar_rows[r];
  const auto [lo, hi] = core.damaged_span[r];
  return lo > row.p0 || hi < row.p1 ? kRowFastAround : kRowByPass;
}

// The bar rows of a line into its plane's force buffer `s_plane`; with `energies`, the elastic
// energy of each row into energy_rows_u. Rows whose bars take the intact fast path this step
// (row_fast) are left to the node pass, but for the damaged span of a row that has one.
template <class Law>
void bar_rows(SimulationCore& core, std::size_t line, double* s_plane, bool energies) {
  constexpr std::size_t kStates = Law::kStateArrays.size();
  const std::size_t begin = core.layout.lines[line].bar_begin,
                    end = core.layout.lines[line].bar_end;
  const bool per_bar = core.table.per_bar();
  const double* kb = per_bar ? core.table.k_bar().data() : nullptr;
  const std::uint64_t step = core.step;
  // Which bars of the row at hand change state (from the general kernel), for its slow path.
  double* const changed =
      core.thread_scratch[static_cast<std::size_t>(omp_get_thread_num())].data();
  std::vector<Event>& events = core.thread_events[static_cast<std::size_t>(omp_get_thread_num())];
  bool all_fast = true;
  for (std::size_t r = begin; r < end; ++r) {
    core.row_fast[r] = bar_row_way(core, r);
    all_fast = all_fast && core.row_fast[r] == kRowFast;
  }
  core.line_fast[line] = all_fast;
  for (std::size_t r = begin; r < end; ++r) {
    if (core.row_fast[r] == kRowFast)
      continue;
    const BarRow& row = core.layout.bar_rows[r];
    const FamilyInfo& fi = core.lat.family(row.family);
    // The row's bars [p0, p1): all of them in a box, in a shaped body from the vector of its
    // first present bar to its last (none in a row of absent bars).
    const index_t p0 = row.p0, n = row.p1 - row.p0;
    if (n == 0) {
      core.row_ratio[r] = 0.0;
      if (energies)
        core.energy_rows_u[r] = 0.0;
      continue;
    }
    const index_t b0 = core.first_bar(r) + p0;
    const std::size_t a0 = row.a_slot + static_cast<std::size_t>(p0),
                      c0 = row.b_slot + static_cast<std::size_t>(p0);
    const RowView v{core.ux.data() + a0,
                    core.uy.data() + a0,
                    core.uz.data() + a0,
                    core.ux.data() + c0,
                    core.uy.data() + c0,
                    core.uz.data() + c0,
                    s_plane + fi.plane_offset + std::size_t{fi.plane_stride} * row.j +
                        static_cast<std::size_t>(p0)};
    // (The row's codes at its bar p0, StepLayout::code_origin.)
    const std::uint8_t* code = core.layout.coded()
                                   ? core.layout.bar_code.data() +
                                         static_cast<std::size_t>(core.layout.code_origin[r] + p0)
                                   : nullptr;
    const typename Law::Row constants = Law::row(core.table, row.family, b0);
    std::array<double*, kStates> states = core.row_states<kStates>(r);
    for (double*& p : states)
      p += p0;
    std::array<const double*, kStates> read_states{};
    std::copy(states.begin(), states.end(), read_states.begin());
    const bool intact = !core.row_damaged(r);
    bool past;
    // On a report step the kernels also give the row's elastic energy, its displacements
    // still in cache: the intact kernel sum w (l - l0)^2, the general kernel the law's.
    double intact_sum = 0.0, law_sum = 0.0;
    // A row whose bars share their E (BarRow::stiffness): k of its inner bars, its first and
    // last bars' forces times `scale` afterwards, and the intact kernel while its bars are
    // pristine; one whose E varies along it: each bar's k_bar (area factors included), in the
    // intact kernel too while its bars are pristine, else by law.
    const bool own = row.own_stiffness();
    const double k = row.stiffness, scale = own ? 1.0 : row.end_factor / row.factor;
    // The general kernel, with per-bar constants (P) or the family's, and per-bar stiffness
    // (K) or k, on the row's bars [o, o + count). (A call of its own, as GCC 12 makes it:
    // inlined into bar_rows, it halved the FGM plate's rate once bars break; bench/README.md.)
    const auto general = [&](auto per_bar_c, auto per_bar_k_c, auto intact_c, index_t o,
                             index_t count) {
      constexpr bool P = decltype(per_bar_c)::value, K = decltype(per_bar_k_c)::value,
                     I = decltype(intact_c)::value;
      // Fewer than 8 bars (a damaged span) of a row of 8 or more, outside a report step: the
      // kernel takes the 8 bars from `o` on (or the row's last 8), a whole vector, and the
      // others' forces are put back as they were (the intact kernel's; in a row whose other
      // bars take the node pass, values that nothing reads). Those bars are pristine and below
      // their elastic limit, by the intact kernel's test or the fast path's bound, so no state
      // of theirs changes; the slow path looks at the span's bars only.
      const index_t want_o = o, want_count = count;
      double kept[8];
      const bool widened = !energies && count < 8 && n >= 8;
      if (widened) {
        o = std::min<index_t>(o, n - 8);
        count = 8;
        std::copy(v.s + o, v.s + o + 8, kept);
      }
      const auto at = static_cast<std::size_t>(o);
      const double* kr = K ? kb + b0 + o : nullptr;
      const RowView w{v.uax + at, v.uay + at, v.uaz + at, v.ubx + at,
                      v.uby + at, v.ubz + at, v.s + at};
      const typename Law::Row c = o == 0 ? constants : Law::row(core.table, row.family, b0 + o);
      std::array<const double*, kStates> st = read_states;
      for (const double*& p : st)
        p += at;
      const std::uint8_t* cd = code ? code + at : nullptr;
      const bool first_end = o == 0, last_end = o + count == n;
      double* const ch = changed + at;
      bool changes;
      if (!P && code)
        changes = energies ? bar_row_kernel<Law, P, K, I, true, true>(count, w, c, st, fi.d0, fi.l0,
                                                                      k, kr, scale, &law_sum, cd,
                                                                      first_end, last_end, ch)
                           : bar_row_kernel<Law, P, K, I, false, true>(count, w, c, st, fi.d0,
                                                                       fi.l0, k, kr, scale, nullptr,
                                                                       cd, first_end, last_end, ch);
      else
        changes = energies ? bar_row_kernel<Law, P, K, I, true>(count, w, c, st, fi.d0, fi.l0, k,
                                                                kr, scale, &law_sum, nullptr,
                                                                first_end, last_end, ch)
                           : bar_row_kernel<Law, P, K, I>(count, w, c, st, fi.d0, fi.l0, k, kr, 1.0,
                                                          nullptr, nullptr, true, true, ch);
      if (widened)
        for (index_t i = o; i < o + 8; ++i)
          if (i < want_o || i >= want_o + want_count)
            v.s[i] = kept[i - o];
      return changes;
    };
    using yes = std::true_type;
    using no = std::false_type;
    // The bars the slow path looks at: those the general kernel took.
    index_t slow_lo = 0, slow_hi = n;
    if (own) {
      // Pristine: the intact kernel with each bar's k, tested against the smallest of the row's
      // elastic limits; if some bar may be past it, or the row is damaged, by the law.
      double l2_max = kUnknown; // (not read: such rows never take the fast path)
      const double* kr = kb + b0;
      const bool any_past =
          !intact ||
          (energies ? intact_row_kernel<true>(n, v, fi.d0, fi.l0, 0.0, row.elastic_limit, 1.0,
                                              &intact_sum, l2_max, nullptr, 0, 0, kr)
                    : intact_row_kernel<false>(n, v, fi.d0, fi.l0, 0.0, row.elastic_limit, 1.0,
                                               nullptr, l2_max, nullptr, 0, 0, kr));
      if (any_past) {
        past = intact ? general(yes{}, yes{}, yes{}, 0, n) : general(yes{}, yes{}, no{}, 0, n);
      } else {
        past = false;
        slow_hi = 0;
      }
      // U = (sum of k_i (l - l0)^2) / 2 of the intact kernel, or the law's.
      if (energies)
        core.energy_rows_u[r] = any_past ? law_sum : 0.5 * intact_sum;
    } else {
      // By the law (its state read), with per-bar constants or the family's.
      const auto by_law = [&](index_t o, index_t count) {
        return per_bar ? general(yes{}, no{}, no{}, o, count) : general(no{}, no{}, no{}, o, count);
      };
      // The row's damaged span among its bars [0, n) here (empty in a pristine row): the
      // general kernel takes it, the intact kernels the bars outside it.
      const auto [d_lo, d_hi] = core.damaged_span[r];
      const index_t lo = intact || d_lo < p0 ? 0 : d_lo - p0,
                    hi = intact ? 0 : std::min<index_t>(d_hi - p0, n);
      const bool ends = row.end_factor != row.factor;
      if (core.row_fast[r] == kRowFastAround) {
        // The bars outside the span take the node pass this step (bar_row_stays_intact).
        past = by_law(lo, hi - lo);
        slow_lo = lo;
        slow_hi = hi;
        if (ends && lo == 0)
          v.s[0] *= scale;
        if (ends && hi == n)
          v.s[n - 1] *= scale;
        if (energies)
          core.energy_rows_u[r] = law_sum; // (the node pass adds the others')
      } else {
        double l2_max = kUnknown;
        const double e_lim = row.elastic_limit;
        // Some bar outside the span may be past its elastic limit (or none is outside it): the
        // whole row by the law.
        const bool outside = intact || lo > 0 || hi < n;
        const bool any_past =
            !outside || (energies ? intact_row_kernel<true>(n, v, fi.d0, fi.l0, k, e_lim, scale,
                                                            &intact_sum, l2_max, code, lo, hi)
                                  : intact_row_kernel<false>(n, v, fi.d0, fi.l0, k, e_lim, 1.0,
                                                             nullptr, l2_max, code, lo, hi));
        core.row_ratio[r] = l2_max * (core.layout.row_inv_lp[r] * core.layout.row_inv_lp[r]);
        if (any_past) {
          past = by_law(0, n);
        } else if (intact) {
          past = false;
          slow_hi = 0;
        } else {
          past = by_law(lo, hi - lo);
          slow_lo = lo;
          slow_hi = hi;
        }
        if (ends) {
          v.s[0] *= scale;
          v.s[n - 1] *= scale;
        }
        // U = k (l - l0)^2 / 2 of the intact kernel's bars (area factors in w), and the law's.
        if (energies)
          core.energy_rows_u[r] = any_past ? law_sum
                                  : intact ? 0.5 * k * intact_sum
                                           : law_sum + 0.5 * k * intact_sum;
      }
    }
    if (!past)
      continue;
    // Slow path: some bar's state changes. The stretch again of each bar the general kernel
    // found changing (its flag), the law's update and events. The force the kernel gave
    // already holds for the new state (the law's contract: the update changes no force at the
    // strain that caused it). An absent bar never changes (the kernel with per-bar constants
    // does not read the codes, and flags one between two present nodes strained past e_p).
    const double inv_l0 = 1.0 / fi.l0;
    for (index_t i = slow_lo; i < slow_hi; ++i) {
      if (changed[i] == 0.0 || (code && code[i] == 0))
        continue;
      const Stretch g = stretch(fi.d0.x + (v.ubx[i] - v.uax[i]), fi.d0.y + (v.uby[i] - v.uay[i]),
                                fi.d0.z + (v.ubz[i] - v.uaz[i]), fi.l0, inv_l0);
      const Law law =
          per_bar ? Law::template at<true>(constants, i) : Law::template at<false>(constants, i);
      typename Law::State s = Law::read(states.data(), i);
      if (!law.changes(g.e, s))
        continue;
      law.update(g.e, s, [&](BarState to) { events.push_back({b0 + i, to, step}); });
      Law::write(states.data(), i, s);
      if (!law.pristine(s))
        core.widen_damaged(r, p0 + i);
      core.row_history_changed[r] = 1;
    }
  }
}

#pragma GCC diagnostic pop

} // namespace ldem
