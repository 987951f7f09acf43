// The step's walk over the body (internal to the solver): which thread takes which rows, in
// what order, and where the bar forces of each line wait for the nodes that gather them.
#pragma once

#include "solver/bar_pass.hpp"
#include "solver/node_pass.hpp"
#include "util/parallel.hpp"

#include <omp.h>

namespace ldem {

// The bar forces of line l from a plane buffer into a packed store of one line (Pack), or back.
// Rows whose bars all take the fast path this step have no forces in the buffers to move.
template <bool Pack>
void move_bar_line(const SimulationCore& core, std::size_t l, double* plane, double* packed) {
  for (std::size_t r = core.layout.lines[l].bar_begin; r < core.layout.lines[l].bar_end; ++r) {
    const FamilyInfo& fi = core.lat.family(core.layout.bar_rows[r].family);
    double* row =
        plane + fi.plane_offset + std::size_t{fi.plane_stride} * core.layout.bar_rows[r].j;
    if (core.row_fast[r] != kRowFast) {
      if constexpr (Pack)
        std::copy(row, row + fi.ni, packed);
      else
        std::copy(packed, packed + fi.ni, row);
    }
    packed += fi.ni;
  }
}

// The threads' slabs of k-planes (SimulationCore::slab_start) for `nt` threads and `nplanes`
// planes: even at first (and whenever the threads or planes change), then placed every 16 steps
// by the planes' times in the walk (balance_ranges), measured on one step in 4, each plane's
// the median of its 4 (typical_costs): a crack or a damaged layer makes some planes cost
// several times others, and with an even split the other threads would wait for the slowest
// at each step's end. The split goes at once where the times say, so that it keeps up with a
// crack that spreads over many planes. Which thread takes a plane changes no result
// (advance_rows).
inline constexpr int kBalanceSteps = 16, kTimedEvery = 4;
inline constexpr std::size_t kBalanceSamples = kBalanceSteps / kTimedEvery; // of each plane
inline void balance_slabs(SimulationCore& core, std::int64_t nt, std::int64_t nplanes) {
  std::vector<std::int64_t>& s = core.slab_start;
  const auto n = static_cast<std::size_t>(nt), planes = static_cast<std::size_t>(nplanes);
  if (s.size() != n + 1 || s.back() != nplanes ||
      core.plane_busy.size() != kBalanceSamples * planes) {
    s.resize(n + 1);
    for (std::int64_t u = 0; u <= nt; ++u)
      s[static_cast<std::size_t>(u)] = u * nplanes / nt;
    core.plane_busy.assign(kBalanceSamples * planes, 0.0);
    core.busy_steps = 0;
    return;
  }
  if (++core.busy_steps < kBalanceSteps)
    return;
  typical_costs<kBalanceSamples>(core.plane_busy, core.plane_cost);
  balance_ranges(s, core.plane_cost);
  std::fill(core.plane_busy.begin(), core.plane_busy.end(), 0.0);
  core.busy_steps = 0;
}

// Node line (j, k) needs the bar lines j - 1 and j of its plane and of the plane below, so
// the bars of a line are computed moments before the nodes that gather them. Each thread
// takes a box of lines: a slab of k-planes (all j) when the body has planes enough, else a
// range of j (all k: a body thin along z). It walks its box in blocks of block_lines lines
// along j, and inside a block plane by plane upwards, bars of a block's lines then its nodes:
// a block's bar forces, and the displacements they read, stay in the core's own cache (on a
// whole plane of a large body they would not). Bar forces go to the thread's plane buffers,
// alternating with k (only the block's lines are touched). Two lines are needed from
// elsewhere: line jb - 1 of each plane, computed with the block before (kept packed in
// `carry`), and what the neighbouring thread owns: the top plane of the slab below, or the
// last line of the j range below. Each thread computes those first, before the one barrier.
// Every bar line is computed once per step, whatever the threads and blocks, so they change
// which thread does a row, never how the row is computed. The slabs are placed by the planes'
// times (balance_slabs).
template <class Law, bool Damped, bool Loads, bool Report> void advance_rows(SimulationCore& core) {
  const auto nplanes = static_cast<std::int64_t>(core.layout.planes.size());
  const auto nlines = static_cast<std::int64_t>(core.lat.ny()) + 1; // lines per plane
  const bool parallel = core.lat.num_bars() > kParallelMinItems;
  if (parallel && nplanes >= 4 * core.threads)
    balance_slabs(core, core.threads, nplanes);
#pragma omp parallel num_threads(core.threads) if (parallel)
  {
    const std::int64_t nt = omp_get_num_threads(), t = omp_get_thread_num();
    const bool slabs = nplanes >= 4 * nt;
    auto first = [nt](std::int64_t n, std::int64_t u) { return u * n / nt; };
    // (The balanced slabs if they are this team's.)
    const bool balanced = slabs && core.slab_start.size() == static_cast<std::size_t>(nt) + 1 &&
                          core.slab_start.back() == nplanes;
    const std::int64_t k0 = balanced ? core.slab_start[static_cast<std::size_t>(t)]
                            : slabs  ? first(nplanes, t)
                                     : 0;
    const std::int64_t k1 = balanced ? core.slab_start[static_cast<std::size_t>(t) + 1]
                            : slabs  ? first(nplanes, t + 1)
                                     : nplanes;
    // A step whose planes' times are measured (balance_slabs): each plane's share of the walk
    // into its sample of plane_busy, its top plane's bars before the barrier included. (One
    // step in 4: on some machines the clock is a system call.)
    const bool timed =
        balanced && nt > 1 && core.busy_steps % kTimedEvery == 0 &&
        core.plane_busy.size() == kBalanceSamples * static_cast<std::size_t>(nplanes);
    double* const busy = timed
                             ? core.plane_busy.data() +
                                   static_cast<std::size_t>(core.busy_steps / kTimedEvery * nplanes)
                             : nullptr;
    double clock = timed ? omp_get_wtime() : 0.0;
    const std::int64_t j0 = slabs ? 0 : first(nlines, t);
    const std::int64_t j1 = slabs ? nlines : first(nlines, t + 1);
    const auto line = [&](std::int64_t j, std::int64_t k) {
      return core.layout.planes[k].line_begin + j;
    };
    const auto bars = [&](std::int64_t j, std::int64_t k, double* s) {
      bar_rows<Law>(core, line(j, k), s, Report);
    };
    const auto ut = static_cast<std::size_t>(t);
    double* const slot[2] = {core.plane_buffers[3 * ut].data(),
                             core.plane_buffers[3 * ut + 1].data()};
    double* const top = core.plane_buffers[3 * ut + 2].data();
    const auto packed = [&](std::int64_t u, int which, std::int64_t k) {
      return core.line_stores[2 * static_cast<std::size_t>(u) + which].data() +
             static_cast<std::size_t>(k) * core.layout.line_store_stride;
    };
    constexpr int kCarry = 0, kEdge = 1;
    // Lines the thread's neighbours read: the top plane of a slab (read whole from `top`), or
    // the last line of a j range in every plane (read packed).
    const bool box = k1 > k0 && j1 > j0;
    const bool edge_out = box && !slabs && j1 < nlines;
    if (box && slabs)
      for (std::int64_t j = 0; j < nlines; ++j)
        bars(j, k1 - 1, top);
    if (edge_out)
      for (std::int64_t k = 0; k < nplanes; ++k) {
        bars(j1 - 1, k, top);
        move_bar_line<true>(core, line(j1 - 1, k), top, packed(t, kEdge, k));
      }
    // The thread whose j range holds line j0 - 1 (ranges may be empty when lines are few).
    std::int64_t below = t - 1;
    while (below > 0 && first(nlines, below) > j0 - 1)
      --below;
    if (timed && box) {
      const double now = omp_get_wtime();
      busy[k1 - 1] += now - clock;
    }
#pragma omp barrier
    if (timed)
      clock = omp_get_wtime();
    for (std::int64_t jb = j0; box && jb < j1; jb += core.block_lines) {
      const std::int64_t je = std::min<std::int64_t>(jb + core.block_lines, j1);
      for (std::int64_t k = k0; k < k1; ++k) {
        const bool at_top = slabs && k == k1 - 1;
        double* s_plane = at_top ? top : slot[k % 2];
        const double* s_below = k == 0 ? nullptr
                                : k > k0
                                    ? slot[(k - 1) % 2]
                                    : core.plane_buffers[3 * ut - 1].data(); // slab below's top
        if (!at_top) {
          if (jb > j0)
            move_bar_line<false>(core, line(jb - 1, k), s_plane, packed(t, kCarry, k));
          else if (jb > 0)
            move_bar_line<false>(core, line(jb - 1, k), s_plane, packed(below, kEdge, k));
          for (std::int64_t j = jb; j < je; ++j) {
            if (edge_out && j == j1 - 1)
              move_bar_line<false>(core, line(j, k), s_plane, packed(t, kEdge, k));
            else
              bars(j, k, s_plane);
          }
          if (je < j1)
            move_bar_line<true>(core, line(je - 1, k), s_plane, packed(t, kCarry, k));
        }
        for (std::int64_t j = jb; j < je; ++j)
          node_rows_range<Damped, Loads, Report>(core, line(j, k), s_plane, s_below);
        if (timed) {
          const double now = omp_get_wtime();
          busy[k] += now - clock;
          clock = now;
        }
      }
    }
  }
}

// Force of its bars on one node at u_n, from the bar law and the history.

} // namespace ldem
