#include "solver/stable_step.hpp"

#include "energy/exact_sum.hpp"
#include "util/aligned.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <type_traits>

namespace ldem {

namespace {

// Undamaged axial stiffness EA / l0 of every bar (including the boundary area factor): a
// per-bar table's own array; nullptr for a body of one material, whose rows of links take their
// stiffness from UnitLinks (a shaped body's from `quarters`, filled here: 4 times each bar's
// area factor, a byte per bar where the stiffness would take 8; planes of bars in parallel).
const double* bar_stiffness(const Lattice& lat, const BarTable& table,
                            std::vector<std::uint8_t>& quarters) {
  if (table.per_bar())
    return table.k_bar().data();
  if (!lat.shaped())
    return nullptr;
  quarters.resize(lat.num_bars());
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat.family(f);
    const auto planes = static_cast<std::int64_t>(fi.nk);
#pragma omp parallel for schedule(static) if (std::int64_t{fi.ni} * fi.nj * fi.nk > kParallelMinItems)
    for (std::int64_t kk = 0; kk < planes; ++kk)
      for (index_t j = 0; j < fi.nj; ++j)
        for (index_t i = 0; i < fi.ni; ++i)
          quarters[lat.bar(static_cast<Family>(f), i, j, static_cast<index_t>(kk))] =
              static_cast<std::uint8_t>(
                  4.0 * lat.area_factor(static_cast<Family>(f), i, j, static_cast<index_t>(kk)));
  }
  return nullptr;
}

// A row's links with their unit vectors (each r0 / |r0|) and their bars' stiffness: `kb`'s;
// in a shaped body of one material the family's k times a quarter of the bar's `quarters` (the
// numbers k times its area factor gives: quarters are exact); in a box of one material the
// family's k times the bar's area factor, which along a link's bars changes only at its first
// and last (the body's faces across x): those two and one for the bars between.
struct UnitLinks {
  RowLink links[kMaxRowLinks];
  double e[kMaxRowLinks][3];
  double k_first[kMaxRowLinks], k_inner[kMaxRowLinks], k_last[kMaxRowLinks];
  const double* kb;
  const std::uint8_t* quarters;
  int count = 0;
  UnitLinks(const Lattice& lat, const BarTable& table, const double* kb_,
            const std::uint8_t* quarters_, const NodeRow& row)
      : kb(kb_), quarters(quarters_), count(row_links(lat, row, links)) {
    for (int l = 0; l < count; ++l) {
      const RowLink& L = links[l];
      const Vec3& r = L.r0;
      const double len = std::sqrt(r.x * r.x + r.y * r.y + r.z * r.z);
      e[l][0] = r.x / len;
      e[l][1] = r.y / len;
      e[l][2] = r.z / len;
      if (kb || L.ihi <= L.ilo)
        continue;
      const auto family = [&](index_t i) {
        return lat.bar_address(static_cast<index_t>(L.bar_base + i)).family;
      };
      if (quarters) {
        k_inner[l] = table.family(static_cast<int>(family(L.ilo))).k; // (the family's k)
        continue;
      }
      const auto k_of = [&](index_t i) {
        const BarAddress a = lat.bar_address(static_cast<index_t>(L.bar_base + i));
        return table.family(static_cast<int>(a.family)).k *
               lat.area_factor(a.family, a.i, a.j, a.k);
      };
      k_first[l] = k_of(L.ilo);
      k_last[l] = k_of(L.ihi - 1);
      k_inner[l] = L.ihi - L.ilo > 2 ? k_of(L.ilo + 1) : k_first[l];
    }
  }
  // The stiffness of the bar of link l at node i of the row.
  double k(int l, index_t i) const {
    if (kb)
      return kb[static_cast<std::size_t>(links[l].bar_base + i)];
    if (quarters)
      return k_inner[l] * (quarters[static_cast<std::size_t>(links[l].bar_base + i)] * 0.25);
    return i == links[l].ilo ? k_first[l] : i + 1 == links[l].ihi ? k_last[l] : k_inner[l];
  }
};

// Calls f(other node, unit vector towards it, bar stiffness) for every bar of node i of a row.
template <class F> void for_each_bar_of(index_t i, const UnitLinks& u, F&& f) {
  for (int l = 0; l < u.count; ++l) {
    const RowLink& L = u.links[l];
    if (i < L.ilo || i >= L.ihi)
      continue;
    f(static_cast<index_t>(L.other_base + i), u.e[l], u.k(l, i));
  }
}

// How a link's bars have their stiffness: k[0] for all, or k[i] per bar (a shaped body's other
// bars are taken one by one, UnitLinks::k).
enum class Stiffness { One, PerBar };

// What a link of a row reads at its other nodes (node other_base + i for the row's node i): x
// by component, 1 / sqrt(m) and the held DOF (whether any is held in that row); its unit vector
// and its bars' stiffness (Stiffness).
struct LinkArrays {
  double e[3];
  const double* k;
  const double *ox, *oy, *oz, *om;
  const unsigned char* oh;
  bool holds;
};

// The terms of one link's bar at the row's node i, added to ax, ay, az: k (e . (p_i - M^-1/2
// x_other)) e, with p the row's M^-1/2 x by component (`len` apart). Holds: the other nodes'
// held DOF count (M^-1/2 x is 0 there; x 1 where free, the same numbers), else they are read
// as free.
template <bool Holds, Stiffness K>
inline void add_bar(const LinkArrays& L, index_t i, const double* __restrict p, std::size_t len,
                    double& ax, double& ay, double& az) {
  double sx = L.ox[i] * L.om[i], sy = L.oy[i] * L.om[i], sz = L.oz[i] * L.om[i];
  if constexpr (Holds) {
    sx *= L.oh[i] & 1u ? 0.0 : 1.0;
    sy *= L.oh[i] & 2u ? 0.0 : 1.0;
    sz *= L.oh[i] & 4u ? 0.0 : 1.0;
  }
  double proj = 0.0;
  proj += L.e[0] * (p[i] - sx);
  proj += L.e[1] * (p[len + i] - sy);
  proj += L.e[2] * (p[2 * len + i] - sz);
  const double kp = (K == Stiffness::PerBar ? L.k[i] : L.k[0]) * proj;
  ax += kp * L.e[0];
  ay += kp * L.e[1];
  az += kp * L.e[2];
}

// Every link's bars at the row's nodes [lo, hi), each node's terms in the order of the links,
// into acc: eight nodes at a time, their sums in registers (one link after another would load
// and store them at every link).
template <bool Holds, Stiffness K>
void all_links(index_t lo, index_t hi, const LinkArrays* links, int count,
               const double* __restrict p, std::size_t len, double* __restrict acc) {
  constexpr index_t kLanes = 8;
  index_t i = lo;
  for (; i + kLanes <= hi; i += kLanes) {
    double ax[kLanes] = {}, ay[kLanes] = {}, az[kLanes] = {};
    const double* __restrict const px = p + i;
    const double* __restrict const py = p + len + i;
    const double* __restrict const pz = p + 2 * len + i;
    for (int l = 0; l < count; ++l) {
      const LinkArrays& L = links[l];
      const double e0 = L.e[0], e1 = L.e[1], e2 = L.e[2];
      const double k0 = K == Stiffness::PerBar ? 0.0 : L.k[0]; // (per bar: L.k[i] from ilo on)
      const double* __restrict const ox = L.ox + i;
      const double* __restrict const oy = L.oy + i;
      const double* __restrict const oz = L.oz + i;
      const double* __restrict const om = L.om + i;
      const double* __restrict const k = K == Stiffness::PerBar ? L.k + i : nullptr;
      const unsigned char* __restrict const oh = L.oh + i;
      // (The other rows' values 8 lines ahead: more streams than the hardware follows.)
      __builtin_prefetch(ox + 64);
      __builtin_prefetch(oy + 64);
      __builtin_prefetch(oz + 64);
      __builtin_prefetch(om + 64);
#pragma omp simd
      for (index_t v = 0; v < kLanes; ++v) {
        double sx = ox[v] * om[v], sy = oy[v] * om[v], sz = oz[v] * om[v];
        if constexpr (Holds) {
          sx *= oh[v] & 1u ? 0.0 : 1.0;
          sy *= oh[v] & 2u ? 0.0 : 1.0;
          sz *= oh[v] & 4u ? 0.0 : 1.0;
        }
        double proj = 0.0;
        proj += e0 * (px[v] - sx);
        proj += e1 * (py[v] - sy);
        proj += e2 * (pz[v] - sz);
        const double kp = (K == Stiffness::PerBar ? k[v] : k0) * proj;
        ax[v] += kp * e0;
        ay[v] += kp * e1;
        az[v] += kp * e2;
      }
    }
    for (index_t v = 0; v < kLanes; ++v) {
      acc[i + v] = ax[v];
      acc[len + i + v] = ay[v];
      acc[2 * len + i + v] = az[v];
    }
  }
  for (; i < hi; ++i) {
    double ax = 0.0, ay = 0.0, az = 0.0;
    for (int l = 0; l < count; ++l)
      add_bar<Holds, K>(links[l], i, p, len, ax, ay, az);
    acc[i] = ax;
    acc[len + i] = ay;
    acc[2 * len + i] = az;
  }
}

// Largest eigenvalue of a symmetric tridiagonal matrix (diagonal a, off-diagonal b[1..m-1])
// by bisection on Sturm sequence counts.
double tridiagonal_max_eigenvalue(const std::vector<double>& a, const std::vector<double>& b) {
  const std::size_t m = a.size();
  double lo = 0.0, hi = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    const double r = (i > 0 ? std::abs(b[i]) : 0.0) + (i + 1 < m ? std::abs(b[i + 1]) : 0.0);
    lo = std::min(lo, a[i] - r);
    hi = std::max(hi, a[i] + r);
  }
  auto count_below = [&](double x) { // eigenvalues < x
    int count = 0;
    double d = 1.0;
    for (std::size_t i = 0; i < m; ++i) {
      d = a[i] - x - (i > 0 ? b[i] * b[i] / d : 0.0);
      if (d == 0.0)
        d = -1e-300;
      if (d < 0.0)
        ++count;
    }
    return count;
  };
  for (int it = 0; it < 200 && hi - lo > 1e-15 * std::max(std::abs(hi), 1.0); ++it) {
    const double mid = 0.5 * (lo + hi);
    if (count_below(mid) >= static_cast<int>(m))
      hi = mid;
    else
      lo = mid;
  }
  return 0.5 * (lo + hi);
}

} // namespace

StableStep compute_stable_step(const Lattice& lat, const BarTable& table,
                               std::span<const double> mass,
                               const std::vector<unsigned char>& held_given,
                               const StableStepParts* parts, const StableStepScratch* scratch) {
  std::vector<std::uint8_t> quarters_own;
  const double* const kb = bar_stiffness(lat, table, quarters_own);
  const std::uint8_t* const quarters = quarters_own.empty() ? nullptr : quarters_own.data();
  const std::size_t n = lat.num_nodes();
  // The rows of nodes this process owns (a row along x is never split between processes).
  const std::vector<NodeRow> all_rows = node_rows(lat);
  std::vector<NodeRow> rows = all_rows;
  if (parts)
    rows.erase(std::remove_if(rows.begin(), rows.end(),
                              [&](const NodeRow& r) { return !parts->owned[r.first]; }),
               rows.end());
  const std::int64_t nrows = static_cast<std::int64_t>(rows.size());
  // 1 / sqrt(m) and the held DOF of every node; a ghost node's from its owner.
  // Arrays of n doubles: the caller's (StableStepScratch) where it lends them, else the
  // estimate's own (huge pages, util/aligned.hpp; first written by the threads together).
  std::vector<UnsetVector<double>> own;
  own.reserve(10);
  const auto array = [&](std::size_t a) {
    if (scratch && scratch->v[a])
      return scratch->v[a];
    own.emplace_back(n);
    return own.back().data();
  };
  double* const rsm = array(9);
  std::vector<unsigned char> held(n, 0);
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i) {
    rsm[i] = 1.0 / std::sqrt(mass[i]);
    held[i] = held_given.empty() ? 0 : held_given[i];
  }
  if (parts) {
    std::vector<double> v(3 * n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      v[3 * i] = rsm[i];
      v[3 * i + 1] = held[i];
    }
    parts->exchange(v);
    for (std::size_t i = 0; i < n; ++i) {
      rsm[i] = v[3 * i];
      held[i] = static_cast<unsigned char>(v[3 * i + 1]);
    }
  }
  auto free_dof = [&](std::size_t node, int d) { return held[node] & (1u << d) ? 0.0 : 1.0; };
  // The Lanczos vectors by component, indexed by node (q, the one before it, w).
  struct Field {
    double* c[3];
  };
  const auto field = [&](std::size_t first) {
    return Field{{array(first), array(first + 1), array(first + 2)}};
  };
  Field q = field(0), q_prev = field(3), w = field(6);
  // Per row of the body (node_rows' order): whether some DOF of its nodes is held; a row
  // without one takes M^-1/2 x as x times 1 / sqrt(m) (times 1, the same numbers).
  const std::int64_t corner_rows = (std::int64_t{lat.ny()} + 1) * (lat.nz() + 1);
  const auto row_of = [&](std::int64_t node) {
    return node < lat.num_corners() ? node / (lat.nx() + 1)
                                    : corner_rows + (node - lat.num_corners()) / lat.nx();
  };
  std::vector<unsigned char> row_holds(all_rows.size(), 0);
  for (std::size_t i = 0; i < n; ++i)
    if (held[i])
      row_holds[static_cast<std::size_t>(row_of(static_cast<std::int64_t>(i)))] = 1;
  // Per row: whether its nodes but the first and the last have one mass and no held DOF (the
  // inner nodes of a box's row).
  std::vector<unsigned char> row_even(all_rows.size(), 0);
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
  for (std::size_t r = 0; r < all_rows.size(); ++r) {
    const std::size_t a = all_rows[r].first, b = a + all_rows[r].length;
    bool even = b - a >= 3;
    for (std::size_t i = a + 1; i + 1 < b && even; ++i)
      even = mass[i] == mass[a + 1] && rsm[i] == rsm[a + 1] && held[i] == 0;
    row_even[r] = even;
  }

  // A shaped body's rows: the nodes [a, b) with a bar of the body (beyond them every bar is
  // absent, its stiffness 0: terms +-0 that leave each sum as it is, so y is +0 there), and
  // among them the longest run of nodes [u0, u1) whose every link has a bar there, taken as a
  // box's inner nodes: of one material (quarters), a run of one area factor per link (one
  // quarter: of the whole factor 4 inside the body, 2 on a face), whose bars take k times that
  // quarter / 4 per link (all_links with Stiffness::One), the numbers UnitLinks::k gives,
  // without reading the bars' bytes (14 more streams than the box reads); per bar, their own k
  // (Stiffness::PerBar). The rest of [a, b) takes end_node. The row is the box's, but its cost
  // that of its bars. (The absent nodes are held, so nearly every row of the box has held
  // nodes; a run whose other nodes hold none reads no held DOF: times 1 on every DOF, the same
  // numbers.)
  struct Window {
    index_t a = 0, b = 0, u0 = 0, u1 = 0;
    bool holds = false; // (some other node of the run holds a DOF)
  };
  const bool windowed = quarters || (kb && lat.shaped());
  const auto present = [&](std::int64_t bar) {
    return quarters ? quarters[static_cast<std::size_t>(bar)] != 0
                    : kb[static_cast<std::size_t>(bar)] != 0.0;
  };
  std::vector<Window> windows(windowed ? rows.size() : 0);
  if (windowed) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      const NodeRow& row = rows[r];
      RowLink links[kMaxRowLinks];
      const int count = row_links(lat, row, links);
      Window& win = windows[static_cast<std::size_t>(r)];
      win.a = row.length;
      for (int l = 0; l < count; ++l)
        for (index_t i = links[l].ilo; i < links[l].ihi; ++i)
          if (present(links[l].bar_base + i)) {
            win.a = std::min(win.a, i);
            win.b = std::max<index_t>(win.b, i + 1);
          }
      win.b = std::max(win.a, win.b);
      // Node e continues a run from node i if each link has a bar at both (of one material: of
      // the same quarter).
      const auto same = [&](index_t i, index_t e) {
        for (int l = 0; l < count; ++l) {
          const RowLink& L = links[l];
          if (L.ihi > L.ilo &&
              (e < L.ilo || e >= L.ihi ||
               (quarters && quarters[static_cast<std::size_t>(L.bar_base + e)] !=
                                quarters[static_cast<std::size_t>(L.bar_base + i)])))
            return false;
        }
        return true;
      };
      for (index_t i = win.a; i < win.b;) {
        if (!same(i, i)) {
          ++i;
          continue;
        }
        index_t e = i + 1;
        while (e < win.b && same(i, e))
          ++e;
        if (e - i > win.u1 - win.u0) {
          win.u0 = i;
          win.u1 = e;
        }
        i = e;
      }
      if (win.u1 == win.u0)
        win.u0 = win.u1 = win.a;
      for (int l = 0; l < count; ++l)
        for (index_t i = win.u0; i < win.u1 && links[l].ihi > links[l].ilo; ++i)
          win.holds = win.holds || held[static_cast<std::size_t>(links[l].other_base + i)] != 0;
    }
  }

  // y = M^-1/2 K M^-1/2 x on the owned nodes, gathered per node from M^-1/2 x on the free DOF
  // (a ghost node's from its owner's x), a row at a time; and each row's sum of y . x in
  // row_sums, added as row_sum() adds (in order along the row, node by node x, y, z).
  std::vector<double> ghosts(parts ? 3 * n : 0);
  std::vector<double> row_sums(rows.size());
  auto apply = [&](const Field& x, const Field& y) {
    if (parts) {
      for (std::size_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
          ghosts[3 * i + d] = parts->owned[i] ? x.c[d][i] : 0.0;
      parts->exchange(ghosts);
      for (std::size_t i = 0; i < n; ++i)
        for (int d = 0; d < 3; ++d)
          x.c[d][i] = ghosts[3 * i + d];
    }
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      const NodeRow& row = rows[r];
      const UnitLinks u(lat, table, kb, quarters, row);
      const std::size_t len = row.length, first = row.first;
      // The nodes to compute: all of the row's, or a shaped body's window (Window).
      const Window win =
          windowed ? windows[static_cast<std::size_t>(r)] : Window{0, row.length, 0, row.length};
      const auto wa = static_cast<std::size_t>(win.a), wb = static_cast<std::size_t>(win.b);
      // The row's M^-1/2 x (p) and its nodes' sums (acc), by component.
      thread_local AlignedVector<double> buf;
      buf.resize(6 * len); // (every value read is set below)
      double* __restrict const p = buf.data();
      double* __restrict const acc = p + 3 * len;
      for (int d = 0; d < 3; ++d)
        for (std::size_t i = wa; i < wb; ++i)
          p[d * len + i] = x.c[d][first + i] * rsm[first + i] * free_dof(first + i, d);
      // Each link's arrays (the other nodes: node other_base + i for the row's node i), and
      // the nodes [f0, f1) where every link has a bar of its inner stiffness (or per bar).
      LinkArrays links[kMaxRowLinks];
      int active = 0;
      bool holds = false;
      index_t f0 = 0, f1 = row.length;
      for (int l = 0; l < u.count; ++l) {
        const RowLink& L = u.links[l];
        if (L.ihi <= L.ilo)
          continue;
        const std::int64_t o = L.other_base;
        const bool other_holds = row_holds[static_cast<std::size_t>(row_of(o + L.ilo))] != 0;
        holds = holds || other_holds;
        links[active++] = {{u.e[l][0], u.e[l][1], u.e[l][2]},
                           kb ? kb + L.bar_base : &u.k_inner[l],
                           x.c[0] + o,
                           x.c[1] + o,
                           x.c[2] + o,
                           rsm + o,
                           held.data() + o,
                           other_holds};
        f0 = std::max<index_t>(f0, L.ilo + 1);
        f1 = std::min<index_t>(f1, L.ihi - 1);
      }
      f1 = std::max(f0, f1);
      // (A shaped body's run; of one material, each link's k times its quarter there.)
      double k_run[kMaxRowLinks];
      if (windowed) {
        f0 = win.u0;
        f1 = win.u1;
      }
      if (quarters) {
        for (int l = 0, a = 0; l < u.count && f1 > f0; ++l)
          if (u.links[l].ihi > u.links[l].ilo) {
            k_run[a] = u.k(l, f0);
            links[a].k = &k_run[a];
            ++a;
          }
      }
      // The nodes outside [f0, f1) one by one, each node's terms in the order of its links.
      const auto end_node = [&](index_t i) {
        double ax = 0.0, ay = 0.0, az = 0.0;
        for (int l = 0, a = 0; l < u.count; ++l) {
          const RowLink& L = u.links[l];
          if (L.ihi <= L.ilo)
            continue;
          LinkArrays at = links[a++];
          if (i < L.ilo || i >= L.ihi)
            continue;
          const double k = u.k(l, i);
          at.k = &k;
          at.holds ? add_bar<true, Stiffness::One>(at, i, p, len, ax, ay, az)
                   : add_bar<false, Stiffness::One>(at, i, p, len, ax, ay, az);
        }
        acc[i] = ax;
        acc[len + i] = ay;
        acc[2 * len + i] = az;
      };
      for (index_t i = win.a; i < f0; ++i)
        end_node(i);
      for (index_t i = f1; i < win.b; ++i)
        end_node(i);
      // The nodes [f0, f1), every link at once (the sums held in registers).
      const auto every_link = [&](auto holds_dof) {
        constexpr bool H = decltype(holds_dof)::value;
        if (kb)
          all_links<H, Stiffness::PerBar>(f0, f1, links, active, p, len, acc);
        else
          all_links<H, Stiffness::One>(f0, f1, links, active, p, len, acc);
      };
      if (windowed ? win.holds : holds)
        every_link(std::true_type{});
      else
        every_link(std::false_type{});
      for (int d = 0; d < 3; ++d) {
        for (std::size_t i = 0; i < wa; ++i)
          y.c[d][first + i] = 0.0;
        for (std::size_t i = wa; i < wb; ++i)
          y.c[d][first + i] = acc[d * len + i] * rsm[first + i] * free_dof(first + i, d);
        for (std::size_t i = wb; i < len; ++i)
          y.c[d][first + i] = 0.0;
      }
      // (Beyond the window each term is 0 times x: +-0, which leaves the sum as it is.)
      double s = 0.0;
      for (std::size_t i = first + wa; i < first + wb; ++i) {
        s += y.c[0][i] * x.c[0][i];
        s += y.c[1][i] * x.c[1][i];
        s += y.c[2][i] * x.c[2][i];
      }
      row_sums[r] = s;
    }
  };
  // The rows' sums in row_sums added exactly (and with the other processes' rows), whatever
  // their order.
  const auto sum_rows = [&] {
    // Scaled by a power of two below the largest row's sum of all processes, into the fixed
    // point's range (ExactSum is made for energies in J; these sums can reach 1e30).
    double largest = 0.0;
    for (double s : row_sums)
      largest = std::max(largest, std::abs(s));
    if (parts)
      largest = parts->max(largest);
    int e = 0;
    std::frexp(largest, &e);
    ExactSum total;
    for (double s : row_sums)
      total.add(std::ldexp(s, -e));
    if (parts)
      parts->sum(total);
    return std::ldexp(total.value(), e);
  };

  StableStep out;
  // Gershgorin: every eigenvalue lies below the largest absolute row sum (the rows in parallel:
  // a largest value is the same whatever the order).
  double bound = 0.0;
#pragma omp parallel for schedule(static) reduction(max : bound) if (3 * n > kParallelMinItems)
  for (std::int64_t r = 0; r < nrows; ++r) {
    const NodeRow& row = rows[r];
    const UnitLinks u(lat, table, kb, quarters, row);
    // A box's row of one material whose own and linked inner nodes have one mass and no held
    // DOF: its nodes 3 to length - 4 take node 2's numbers (each of their links has the one
    // stiffness of its inner bars, UnitLinks::k_inner, and reaches inner nodes of its row), so
    // they are skipped; the bound is the same.
    bool skip = !kb && !quarters && row.length >= 7 &&
                row_even[static_cast<std::size_t>(row_of(row.first))];
    for (int l = 0; l < u.count && skip; ++l)
      skip = row_even[static_cast<std::size_t>(row_of(u.links[l].other_base + 2))] != 0;
    // (A shaped body's nodes beyond its row's window have no bar of the body: sums of 0.)
    const index_t from = windowed ? windows[static_cast<std::size_t>(r)].a : 0,
                  to = windowed ? windows[static_cast<std::size_t>(r)].b : row.length;
    for (index_t i = from; i < to; ++i) {
      if (skip && i == 3)
        i = row.length - 3;
      const index_t node = row.first + i;
      double diag[3][3] = {}, off[3] = {};
      for_each_bar_of(i, u, [&](index_t other, const double* e, double k) {
        const double eo = std::abs(e[0]) * free_dof(other, 0) +
                          std::abs(e[1]) * free_dof(other, 1) + std::abs(e[2]) * free_dof(other, 2);
        for (int p = 0; p < 3; ++p) {
          for (int c = 0; c < 3; ++c)
            diag[p][c] += k * e[p] * e[c] / mass[node] * free_dof(node, c);
          off[p] += k * std::abs(e[p]) * eo * rsm[node] * rsm[other];
        }
      });
      for (int p = 0; p < 3; ++p)
        if (free_dof(node, p) > 0.0)
          bound = std::max(bound, std::abs(diag[p][0]) + std::abs(diag[p][1]) +
                                      std::abs(diag[p][2]) + off[p]);
    }
  }
  if (parts)
    bound = parts->max(bound);
  out.omega_bound = std::sqrt(bound);
  out.dt_bound = 2.0 / out.omega_bound;

  // Lanczos from a start vector drawn per DOF of the body (a hash of its number), the same
  // whichever process holds the node.
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
  for (std::int64_t node = 0; node < static_cast<std::int64_t>(n); ++node) {
    const std::uint64_t g = parts ? parts->global_node[node] : node;
    for (int d = 0; d < 3; ++d) {
      std::uint64_t z = (3 * g + static_cast<std::uint64_t>(d) + 1) * 0x9E3779B97F4A7C15ull;
      z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
      z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
      z ^= z >> 31;
      q.c[d][node] = (static_cast<double>(z >> 11) * 0x1.0p-53 - 0.5) *
                     free_dof(static_cast<std::size_t>(node), d);
      q_prev.c[d][node] = 0.0;
      w.c[d][node] = 0.0;
    }
  }
  // Calls f(i, s) for the nodes of the owned rows, in order along each row, s the row's sum
  // (from 0) to which f adds its node's terms; the rows' sums in row_sums, and their total.
  const auto row_sum = [&](auto&& f) {
#pragma omp parallel for schedule(static) if (3 * n > kParallelMinItems)
    for (std::int64_t r = 0; r < nrows; ++r) {
      double s = 0.0;
      for (std::size_t i = rows[r].first; i < std::size_t{rows[r].first} + rows[r].length; ++i)
        f(i, s);
      row_sums[r] = s;
    }
    return sum_rows();
  };
  const double q_norm = std::sqrt(row_sum([&](std::size_t i, double& s) {
    for (int d = 0; d < 3; ++d)
      s += q.c[d][i] * q.c[d][i];
  }));
  const auto scale_into = [&](Field& to, const Field& from, double by) {
#pragma omp parallel for schedule(static) if (n > kParallelMinItems)
    for (std::int64_t i = 0; i < static_cast<std::int64_t>(n); ++i)
      for (int d = 0; d < 3; ++d)
        to.c[d][i] = from.c[d][i] / by;
  };
  scale_into(q, q, q_norm);
  std::vector<double> alpha, beta{0.0};
  double theta = 0.0, theta_prev = 0.0;
  const int max_iter = 400;
  int stable_iters = 0;
  for (int it = 0; it < max_iter; ++it) {
    apply(q, w);
    const double a = sum_rows(); // w . q
    const double b_prev = beta.back();
    // w -= a q + b_prev q_prev on the owned rows, and w . w.
    const double ww = row_sum([&](std::size_t i, double& s) {
      for (int d = 0; d < 3; ++d) {
        w.c[d][i] -= a * q.c[d][i] + b_prev * q_prev.c[d][i];
        s += w.c[d][i] * w.c[d][i];
      }
    });
    alpha.push_back(a);
    theta = tridiagonal_max_eigenvalue(alpha, beta);
    out.iterations = it + 1;
    const double b = std::sqrt(ww);
    if (it > 0 && std::abs(theta - theta_prev) <= 1e-7 * theta) {
      if (++stable_iters >= 5)
        break;
    } else {
      stable_iters = 0;
    }
    theta_prev = theta;
    if (!(b > 1e-14 * theta))
      break; // invariant subspace found: theta is exact
    beta.push_back(b);
    std::swap(q_prev, q); // q = w / b, where q_prev was
    scale_into(q, w, b);
  }
  out.omega_max = std::sqrt(theta);
  out.dt = 2.0 / out.omega_max;
  return out;
}

} // namespace ldem
