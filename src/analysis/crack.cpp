// Crack analysis: cells of half a module in the analysis plane hold the broken bars; the crack
// is the cluster of cells connected to the pre-crack; distances along it come from a shortest
// path search; shells of equal distance, tracked outwards, show where the crack splits.
#include "analysis/crack.hpp"

#include "analysis/run_data.hpp"
#include "io/output.hpp"
#include "util/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <numeric>
#include <queue>
#include <sstream>
#include <toml++/toml.h>

namespace ldem {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The cell grid of the analysis plane.
struct Grid {
  double a0, n0, h;
  int ni, nj;
  int cell(double a, double n) const {
    const int i = std::clamp(static_cast<int>(std::floor((a - a0) / h)), 0, ni - 1);
    const int j = std::clamp(static_cast<int>(std::floor((n - n0) / h)), 0, nj - 1);
    return j * ni + i;
  }
  double ca(int c) const { return a0 + (c % ni + 0.5) * h; }
  double cn(int c) const { return n0 + (c / ni + 0.5) * h; }
  // Calls f(neighbour, distance) for the cells within `r` cells (Chebyshev) of c.
  template <class F> void around(int c, int r, F&& f) const {
    const int i = c % ni, j = c / ni;
    for (int dj = -r; dj <= r; ++dj)
      for (int di = -r; di <= r; ++di) {
        const int ii = i + di, jj = j + dj;
        if ((di || dj) && ii >= 0 && jj >= 0 && ii < ni && jj < nj)
          f(jj * ni + ii, h * std::sqrt(static_cast<double>(di * di + dj * dj)));
      }
  }
};

// Cells within this many cells (one module) are connected: a crack is a chain of broken bars
// whose centres are at most a module apart.
constexpr int kReach = 2;

// A straight line through points by principal axes: centre and unit direction.
struct Line {
  double a, n, da, dn;
};

Line fit_line(const std::vector<std::pair<double, double>>& p) {
  double ma = 0, mn = 0;
  for (const auto& [a, n] : p) {
    ma += a;
    mn += n;
  }
  ma /= static_cast<double>(p.size());
  mn /= static_cast<double>(p.size());
  double saa = 0, snn = 0, san = 0;
  for (const auto& [a, n] : p) {
    saa += (a - ma) * (a - ma);
    snn += (n - mn) * (n - mn);
    san += (a - ma) * (n - mn);
  }
  // Direction of the largest eigenvalue of the 2 x 2 scatter matrix.
  const double th = 0.5 * std::atan2(2.0 * san, saa - snn);
  return {ma, mn, std::cos(th), std::sin(th)};
}

// A least-squares line through (t, s) samples: its slope and the slope's standard error (NaN
// with fewer than 3 samples). Each s is known to a cell, `h`: the scatter about the line is
// taken as at least that of a uniform rounding, h^2 / 12 (a tip crossing one cell per sample
// leaves no residual, yet its position is that uncertain).
std::pair<double, double> slope_fit(const std::vector<double>& t, const std::vector<double>& s,
                                    std::size_t lo, std::size_t hi, double h) {
  const double n = static_cast<double>(hi - lo + 1);
  double mt = 0, ms = 0;
  for (std::size_t j = lo; j <= hi; ++j) {
    mt += t[j];
    ms += s[j];
  }
  mt /= n;
  ms /= n;
  double stt = 0, sts = 0;
  for (std::size_t j = lo; j <= hi; ++j) {
    stt += (t[j] - mt) * (t[j] - mt);
    sts += (t[j] - mt) * (s[j] - ms);
  }
  if (!(stt > 0.0))
    return {kNaN, kNaN};
  const double slope = sts / stt;
  if (n < 3)
    return {slope, kNaN};
  double rss = 0;
  for (std::size_t j = lo; j <= hi; ++j) {
    const double r = s[j] - ms - slope * (t[j] - mt);
    rss += r * r;
  }
  return {slope, std::sqrt(std::max(rss / (n - 2), h * h / 12.0) / stt)};
}

} // namespace

CrackAnalysis analyze_crack(const std::vector<CrackPoint>& broken, const CrackGeometry& g,
                            const CrackOptions& o, const std::vector<CrackPoint>& softening) {
  CrackAnalysis r;
  const double h = g.L / 2.0;
  const Grid grid{g.a_lo - h, g.n_lo - h, h, static_cast<int>(std::ceil((g.a_hi - g.a_lo) / h)) + 3,
                  static_cast<int>(std::ceil((g.n_hi - g.n_lo) / h)) + 3};
  const std::size_t ncell = static_cast<std::size_t>(grid.ni) * static_cast<std::size_t>(grid.nj);
  const double sense = g.tip_a >= g.mouth_a ? 1.0 : -1.0;
  const double pre_length = std::abs(g.tip_a - g.mouth_a);

  // Cells: the earliest rupture (softening) in each; the pre-crack's cells.
  auto earliest = [&](const std::vector<CrackPoint>& points) {
    std::vector<double> t_cell(ncell, kInf);
    for (const CrackPoint& p : points) {
      const auto c = static_cast<std::size_t>(grid.cell(p.a, p.n));
      t_cell[c] = std::min(t_cell[c], p.t);
    }
    return t_cell;
  };
  std::vector<char> pre(ncell, 0);
  const int steps = static_cast<int>(std::ceil(pre_length / (h / 4))) + 1;
  for (int k = 0; k <= steps; ++k) {
    const double a = g.mouth_a + (g.tip_a - g.mouth_a) * k / steps;
    pre[static_cast<std::size_t>(grid.cell(a, g.line_n))] = 1;
  }

  // When the crack (or the softened zone) reaches each cell: the earliest time a chain of
  // broken (softened) cells links it to the pre-crack (a minimax path: Dijkstra ordered by
  // arrival time). A cell whose bars broke more than the speed window before any such chain
  // could reach it broke on its own (damage along a loaded border, say): it is not part of the
  // crack, and the crack does not pass through it. Bars broken ahead of the tip by less than
  // that join the crack when a chain reaches them.
  const double lead = o.speed_window > 0.0 ? o.speed_window : kInf;
  auto arrivals = [&](const std::vector<double>& t_cell) {
    std::vector<double> arrival(ncell, kInf);
    std::vector<char> excluded(ncell, 0);
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (std::size_t c = 0; c < ncell; ++c)
      if (pre[c]) {
        arrival[c] = 0.0;
        queue.emplace(0.0, static_cast<int>(c));
      }
    while (!queue.empty()) {
      const auto [t, c] = queue.top();
      queue.pop();
      if (t > arrival[static_cast<std::size_t>(c)])
        continue;
      grid.around(c, kReach, [&](int m, double) {
        const auto u = static_cast<std::size_t>(m);
        if (pre[u] || excluded[u] || t_cell[u] == kInf || arrival[u] < kInf)
          return;
        if (t_cell[u] < t - lead) {
          excluded[u] = 1;
          return;
        }
        arrival[u] = std::max(t_cell[u], t);
        queue.emplace(arrival[u], m);
      });
    }
    return arrival;
  };
  const std::vector<double> arrival = arrivals(earliest(broken));

  // Distance along the crack from the pre-crack (Dijkstra over the cells reached by time t_max
  // according to `arr`, into `d`); returns the farthest cell and its distance.
  std::vector<double> dist(ncell, kInf);
  auto distances = [&](const std::vector<double>& arr, double t_max, std::vector<double>& d) {
    std::fill(d.begin(), d.end(), kInf);
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
    for (std::size_t c = 0; c < ncell; ++c)
      if (pre[c]) {
        d[c] = 0.0;
        queue.emplace(0.0, static_cast<int>(c));
      }
    int far = -1;
    double far_d = 0.0;
    while (!queue.empty()) {
      const auto [dc, c] = queue.top();
      queue.pop();
      if (dc > d[static_cast<std::size_t>(c)])
        continue;
      if (!pre[static_cast<std::size_t>(c)] && dc > far_d) {
        far_d = dc;
        far = c;
      }
      grid.around(c, kReach, [&](int m, double step) {
        const auto u = static_cast<std::size_t>(m);
        if (arr[u] < kInf && arr[u] <= t_max && !pre[u] && dc + step < d[u]) {
          d[u] = dc + step;
          queue.emplace(d[u], m);
        }
      });
    }
    return std::make_pair(far, far_d);
  };

  double t_first = kInf, t_last = 0.0;
  for (const CrackPoint& p : broken) {
    t_first = std::min(t_first, p.t);
    t_last = std::max(t_last, p.t);
  }
  const double far = distances(arrival, kInf, dist).second;
  r.final_length = pre_length + far;
  for (const CrackPoint& p : broken)
    (dist[static_cast<std::size_t>(grid.cell(p.a, p.n))] < kInf ? r.bars_in_crack
                                                                : r.bars_elsewhere)++;

  // Branching (docs/model.md, 8b, item 5), on the tree of shortest paths from the pre-crack:
  // each crack cell's parent is the cell its shortest path comes from (-1: the pre-crack).
  // `branch_of` numbers the cells of each branch of the first bifurcation (1, 2, ... from +n
  // to -n); 0 is the trunk.
  std::vector<int> branch_of(ncell, 0);
  [&] {
    std::vector<int> cells; // the crack's cells, nearest first
    for (std::size_t c = 0; c < ncell; ++c)
      if (dist[c] < kInf && !pre[c])
        cells.push_back(static_cast<int>(c));
    if (cells.empty())
      return;
    std::stable_sort(cells.begin(), cells.end(), [&](int x, int y) {
      return dist[static_cast<std::size_t>(x)] < dist[static_cast<std::size_t>(y)];
    });
    // Node -1 stands for the pre-crack (at its tip, distance 0); the rest are cells.
    const auto idx = [](int c) { return static_cast<std::size_t>(c); };
    std::vector<int> parent(ncell, -1);
    std::vector<std::vector<int>> children(ncell);
    for (int c : cells) {
      // The parent: the neighbour on a shortest path (the first found, in grid order).
      int best = -1;
      grid.around(c, kReach, [&](int m, double step) {
        if (best < 0 && (dist[idx(m)] < kInf) &&
            std::abs(dist[idx(m)] + step - dist[idx(c)]) <= 1e-9 * g.L)
          best = m;
      });
      if (best >= 0 && !pre[idx(best)]) {
        parent[idx(c)] = best;
        children[idx(best)].push_back(c);
      }
    }
    // The farthest cell of each subtree (cells in decreasing distance hand theirs up).
    std::vector<int> far_of(ncell, -1);
    for (int c : cells)
      far_of[idx(c)] = c;
    for (auto it = cells.rbegin(); it != cells.rend(); ++it)
      if (const int p = parent[idx(*it)];
          p >= 0 && dist[idx(far_of[idx(*it)])] > dist[idx(far_of[idx(p)])])
        far_of[idx(p)] = far_of[idx(*it)];
    const auto d_of = [&](int p) { return p < 0 ? 0.0 : dist[idx(p)]; };
    const auto pos = [&](int p) {
      return p < 0 ? std::make_pair(g.tip_a, g.line_n) : std::make_pair(grid.ca(p), grid.cn(p));
    };
    // The path from the pre-crack out to cell e, nearest first.
    const auto path = [&](int e) {
      std::vector<int> out;
      for (int c = e; c >= 0; c = parent[idx(c)])
        out.push_back(c);
      std::reverse(out.begin(), out.end());
      return out;
    };
    // How far cell e lies from a path (which starts at the pre-crack's tip).
    const auto gap = [&](int e, const std::vector<int>& route) {
      const auto [ea, en] = pos(e);
      double m = std::hypot(ea - g.tip_a, en - g.line_n);
      for (int c : route)
        m = std::min(m, std::hypot(ea - grid.ca(c), en - grid.cn(c)));
      return m;
    };
    // Tips: the leaves whose own limb of the tree (from where their path joins the path of a
    // farther leaf) runs at least min_branch_length; shorter limbs are side cracks or the
    // links of a band.
    struct Tip {
      int end = -1;
      std::vector<int> route; // its path from the pre-crack, nearest first
    };
    std::vector<Tip> tips;
    for (int c : cells) {
      if (!children[idx(c)].empty())
        continue;
      int q = c;
      while (parent[idx(q)] >= 0 && far_of[idx(parent[idx(q)])] == c)
        q = parent[idx(q)];
      if (d_of(c) - d_of(parent[idx(q)]) >= o.min_branch_length)
        tips.push_back({c, path(c)});
    }
    const auto d_at = [&](const Tip& t, int k) { return k < 0 ? 0.0 : d_of(t.route[idx(k)]); };
    // Tips x and y are on different branches when their paths part and each runs
    // min_branch_length beyond, getting at least that far from the other's path; paths that run
    // side by side (a band) or around a small island are one crack, whatever links them.
    const std::size_t nt = tips.size();
    std::vector<double> split_d(nt * nt, kInf); // where they part, if on different branches
    std::vector<int> part_at(nt * nt, -1);      // [x * nt + y]: where x's path leaves y's
    std::vector<double> part_d(nt * nt, kInf);  // where their paths part
    // Where the paths of tips x and y part: on x's, the index of its last cell within a module
    // of y's before it leaves y's for good or for a branch length (-1: at the pre-crack). The
    // cells near y's path are stamped y.
    std::vector<std::size_t> near_path(ncell, nt);
    for (std::size_t y = 0; y < nt; ++y) {
      for (int q : tips[y].route) {
        near_path[idx(q)] = y;
        grid.around(q, kReach, [&](int m, double step) {
          if (step <= g.L * (1 + 1e-9))
            near_path[idx(m)] = y;
        });
      }
      for (std::size_t x = 0; x < nt; ++x) {
        if (x == y)
          continue;
        // The first stretch of at least min_branch_length away from y's path (shorter ones
        // are the lanes of a band swapping); without one, the last cell near it.
        const std::vector<int>& route = tips[x].route;
        int last_near = -1, parted = -2;
        for (std::size_t k = 0; k < route.size() && parted < -1; ++k) {
          if (near_path[idx(route[k])] == y)
            last_near = static_cast<int>(k);
          else if (d_of(route[k]) - d_at(tips[x], last_near) >= o.min_branch_length)
            parted = last_near;
        }
        if (parted < -1)
          for (std::size_t k = route.size(); k-- > 0;)
            if (near_path[idx(route[k])] == y) {
              parted = static_cast<int>(k);
              break;
            }
        part_at[x * nt + y] = parted < -1 ? -1 : parted;
      }
    }
    for (std::size_t x = 0; x < nt; ++x)
      for (std::size_t y = 0; y < nt; ++y)
        if (x != y)
          part_d[x * nt + y] =
              0.5 * (d_at(tips[x], part_at[x * nt + y]) + d_at(tips[y], part_at[y * nt + x]));
    // Whether t's path, beyond index k, gets min_branch_length away from the other's path
    // somewhere: lanes of a band and the two sides of a small island never do; two branches
    // do, even when they meet again later (a loop closed by the crack or by damage along a
    // border is two branches that coalesced).
    const auto strays = [&](const Tip& t, int k, const Tip& other) {
      for (std::size_t q = static_cast<std::size_t>(k + 1); q < t.route.size(); ++q)
        if (gap(t.route[q], other.route) >= o.min_branch_length)
          return true;
      return false;
    };
    for (std::size_t x = 0; x < nt; ++x)
      for (std::size_t y = x + 1; y < nt; ++y) {
        const Tip &tx = tips[x], &ty = tips[y];
        const int kx = part_at[x * nt + y], ky = part_at[y * nt + x];
        if (d_of(tx.end) - d_at(tx, kx) < o.min_branch_length ||
            d_of(ty.end) - d_at(ty, ky) < o.min_branch_length || !strays(tx, kx, ty) ||
            !strays(ty, ky, tx))
          continue;
        split_d[x * nt + y] = split_d[y * nt + x] = part_d[x * nt + y];
      }
    struct Group {
      std::vector<std::size_t> tips;
      std::size_t lead = 0; // its seed: a tip that parts from the other seeds at the split
      int part = -1;        // index on the seed's path where it leaves the other seeds' paths
    };
    // The first split among the tips `among`: one group of tips per branch (empty if no two
    // tips are on different branches).
    const auto first_split = [&](const std::vector<std::size_t>& among) {
      double first = kInf;
      for (std::size_t x : among)
        for (std::size_t y : among)
          first = std::min(first, split_d[x * nt + y]);
      std::vector<Group> groups;
      if (first == kInf)
        return groups;
      // The branches of this split: the pair of tips that part there and reach farthest, and
      // any tip that parts there from each of them; every other tip that reaches a branch
      // length beyond the split follows the branch it stays with longest (a lane of a band
      // to its end, a branch that splits again to its next split).
      std::vector<std::size_t> seeds;
      double best_reach = -1.0;
      for (std::size_t x : among)
        for (std::size_t y : among)
          if (x < y && split_d[x * nt + y] <= first + g.L &&
              d_of(tips[x].end) + d_of(tips[y].end) > best_reach) {
            best_reach = d_of(tips[x].end) + d_of(tips[y].end);
            seeds = {x, y};
          }
      std::vector<std::size_t> by_reach(among);
      std::stable_sort(by_reach.begin(), by_reach.end(), [&](std::size_t x, std::size_t y) {
        return d_of(tips[x].end) > d_of(tips[y].end);
      });
      for (std::size_t x : by_reach)
        if (std::find(seeds.begin(), seeds.end(), x) == seeds.end() &&
            std::all_of(seeds.begin(), seeds.end(),
                        [&](std::size_t sd) { return split_d[x * nt + sd] <= first + g.L; }))
          seeds.push_back(x);
      for (std::size_t sd : seeds)
        groups.push_back({{sd}, sd, -1});
      for (std::size_t x : by_reach) {
        if (std::find(seeds.begin(), seeds.end(), x) != seeds.end() ||
            d_of(tips[x].end) < first + o.min_branch_length)
          continue;
        std::size_t home = 0;
        for (std::size_t k = 1; k < seeds.size(); ++k)
          if (part_d[x * nt + seeds[k]] > part_d[x * nt + seeds[home]])
            home = k;
        groups[home].tips.push_back(x);
      }
      for (Group& gr : groups)
        for (const Group& other : groups)
          if (&other != &gr)
            gr.part = std::max(gr.part, part_at[gr.lead * nt + other.lead]);
      return groups;
    };
    auto near_border = [&](double a, double n) {
      return a - g.a_lo < g.L || g.a_hi - a < g.L || n - g.n_lo < g.L || g.n_hi - n < g.L;
    };
    // The cells of `pool` on each branch: a cell goes to the branch whose seed's path, beyond
    // where it parts, passes nearest, if it lies farther along the crack than that parting.
    const auto members = [&](const std::vector<Group>& groups, const std::vector<int>& pool) {
      std::vector<std::vector<int>> out(groups.size());
      for (int c : pool) {
        double best = kInf;
        std::size_t home = 0;
        for (std::size_t k = 0; k < groups.size(); ++k) {
          const Tip& leader = tips[groups[k].lead];
          const int from = groups[k].part;
          for (std::size_t q = static_cast<std::size_t>(from + 1); q < leader.route.size(); ++q) {
            const double e = std::hypot(grid.ca(c) - grid.ca(leader.route[q]),
                                        grid.cn(c) - grid.cn(leader.route[q]));
            if (e < best) {
              best = e;
              home = k;
            }
          }
        }
        if (d_of(c) > d_at(tips[groups[home].lead], groups[home].part))
          out[home].push_back(c);
      }
      return out;
    };
    // One branch: its lead's path from where it parts; its angle from a line fitted over the
    // first branch_fit_length of it.
    auto describe = [&](const Group& gr, const std::vector<int>& mine, int level) {
      const Tip& leader = tips[gr.lead];
      BranchInfo b;
      b.level = level;
      b.end_a = grid.ca(leader.end);
      b.end_n = grid.cn(leader.end);
      const double from = d_at(leader, gr.part);
      b.length = d_of(leader.end) - from;
      for (int c : mine)
        b.opens = b.opens || near_border(grid.ca(c), grid.cn(c));
      std::vector<std::pair<double, double>> pts{
          gr.part < 0 ? pos(-1) : pos(leader.route[idx(gr.part)])};
      for (int c : leader.route)
        if (d_of(c) > from && d_of(c) <= from + o.fit_length)
          pts.emplace_back(grid.ca(c), grid.cn(c));
      Line line{0, 0, 1, 0};
      if (pts.size() >= 2) {
        line = fit_line(pts);
        // Point the direction the way the path runs over the fitted length (a branch may turn
        // later, even back).
        const double ra = pts.back().first - pts.front().first;
        const double rn = pts.back().second - pts.front().second;
        if (ra * line.da + rn * line.dn < 0) {
          line.da = -line.da;
          line.dn = -line.dn;
        }
      }
      b.angle_deg = std::atan2(line.dn, sense * line.da) * 180.0 / M_PI;
      return std::make_pair(b, line);
    };

    std::vector<std::size_t> all(nt);
    std::iota(all.begin(), all.end(), 0);
    const std::vector<Group> groups = first_split(all);
    if (groups.empty())
      return;
    const std::vector<std::vector<int>> own = members(groups, cells);
    std::vector<std::pair<BranchInfo, Line>> first;
    for (std::size_t k = 0; k < groups.size(); ++k)
      first.push_back(describe(groups[k], own[k], 1));
    // Order the branches from +n to -n.
    std::vector<std::size_t> order(first.size());
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return first[x].first.angle_deg > first[y].first.angle_deg;
    });
    for (std::size_t k = 0; k < order.size(); ++k) {
      r.branches.push_back(first[order[k]].first);
      for (int c : own[order[k]])
        branch_of[idx(c)] = static_cast<int>(k) + 1;
    }

    // The bifurcation point: between where the two most divergent branches part, or where the
    // lines fitted to them cross if that lies within a fit length of it (paths that part at a
    // small angle stay within a module of each other for a while).
    const std::size_t up = order.front(), down = order.back();
    const auto at = [&](const Group& gr) {
      return gr.part < 0 ? pos(-1) : pos(tips[gr.lead].route[idx(gr.part)]);
    };
    const auto [ua, un] = at(groups[up]);
    const auto [da, dn] = at(groups[down]);
    double pa = 0.5 * (ua + da), pn = 0.5 * (un + dn);
    const Line& lu = first[up].second;
    const Line& ld = first[down].second;
    const double det = lu.da * (-ld.dn) - lu.dn * (-ld.da);
    if (std::abs(det) > 1e-12 && first[up].first.angle_deg - first[down].first.angle_deg > 10.0) {
      const double ba = ld.a - lu.a, bn = ld.n - lu.n;
      const double s = (ba * (-ld.dn) - bn * (-ld.da)) / det;
      const double xa = lu.a + s * lu.da, xn = lu.n + s * lu.dn;
      if (std::hypot(xa - pa, xn - pn) <= o.fit_length) {
        pa = xa;
        pn = xn;
      }
    }
    r.branch_a = pa;
    r.branch_n = pn;
    r.branching_length = sense * (pa - g.mouth_a);

    // Secondary branching: a split among the tips of one branch.
    for (std::size_t k : order) {
      const std::vector<Group> sub = first_split(groups[k].tips);
      if (sub.empty())
        continue;
      r.secondary_branching = true;
      const std::vector<std::vector<int>> sub_own = members(sub, own[k]);
      for (std::size_t j = 0; j < sub.size(); ++j)
        r.branches.push_back(describe(sub[j], sub_own[j], 2).first);
    }
  }();

  if (broken.empty() || !(o.speed_window > 0.0))
    return r;

  // The tips against time. Every quarter speed window, the crack as it stood (bars broken
  // ahead of it join only when a path of broken bars reaches them): the farthest cell of the
  // trunk and of each branch along the crack, and how far the softened zone (the same
  // construction on first softening) reaches.
  const int parts = 1 + static_cast<int>(std::count_if(
                            r.branches.begin(), r.branches.end(),
                            [](const BranchInfo& b) { return b.level == 1; }));
  const std::vector<double> soft_arrival = arrivals(earliest(softening));
  std::vector<double> soft_dist(ncell, kInf);
  struct Series {
    std::vector<double> t, s;
    std::vector<int> cell;
    std::vector<std::size_t> at; // index of the time sample
  };
  std::vector<Series> series(static_cast<std::size_t>(parts));
  std::vector<double> times, whole, soft;
  const double step = o.speed_window / 4.0;
  const double fit = o.speed_fit_length > 0.0 ? o.speed_fit_length : 10.0 * g.L;
  const double span_max = 10.0 * fit * o.speed_window / (4.0 * g.L);
  // From half the widest window before the first rupture (the tip at rest at the pre-crack's),
  // so that the first windows can be centred.
  const double t_start = std::max(0.0, t_first - 0.5 * span_max);
  const auto samples =
      static_cast<std::size_t>(std::ceil((t_last - t_start + o.speed_window) / step)) + 1;
  for (std::size_t k = 0; k < samples; ++k) {
    const double t = t_start + static_cast<double>(k) * step;
    const auto [wc, wd] = distances(arrival, t, dist);
    const double sd = softening.empty() ? 0.0 : distances(soft_arrival, t, soft_dist).second;
    times.push_back(t);
    whole.push_back(wc >= 0 ? wd : 0.0);
    soft.push_back(std::max(sd, whole.back()));
    std::vector<double> best(static_cast<std::size_t>(parts), -1.0);
    std::vector<int> cell(static_cast<std::size_t>(parts), -1);
    for (std::size_t c = 0; c < ncell; ++c)
      if (dist[c] < kInf && !pre[c]) {
        const auto b = static_cast<std::size_t>(branch_of[c]);
        if (dist[c] > best[b]) {
          best[b] = dist[c];
          cell[b] = static_cast<int>(c);
        }
      }
    if (cell[0] < 0) { // no crack yet: the trunk's tip is the pre-crack's
      best[0] = 0.0;
      cell[0] = grid.cell(g.tip_a, g.line_n);
    }
    for (std::size_t b = 0; b < series.size(); ++b)
      if (cell[b] >= 0) {
        series[b].t.push_back(t);
        series[b].s.push_back(best[b]);
        series[b].cell.push_back(cell[b]);
        series[b].at.push_back(k);
      }
  }

  // Speeds: at each sample, a least-squares line through the samples of a window centred on
  // it that widens until the tip has advanced speed_fit_length across it, or until it spans
  // ten times the time that takes at the Rayleigh speed (c_R ~ 4 L / speed_window; a slower or
  // arrested tip). Where the part's samples end before either, the speed is not measured
  // (NaN). Medians take the windows closed by an advance: the crack running.
  std::vector<double> running; // speeds while a part grows
  std::vector<std::vector<double>> running_of(series.size());
  for (std::size_t b = 0; b < series.size(); ++b) {
    Series& se = series[b];
    std::size_t m = se.t.size();
    if (m == 0)
      continue;
    // The trunk of a branching crack ends where it last grew: beyond, the crack runs on as
    // its branches.
    if (b == 0 && parts > 1)
      for (std::size_t j = m; j-- > 1;)
        if (se.s[j] > se.s[j - 1] || j == 1) {
          m = j + 1;
          break;
        }
    for (std::size_t j = 1; j < m; ++j)
      r.jumps += se.s[j] - se.s[j - 1] > 2.0 * g.L;
    for (std::size_t i = 0; i < m; ++i) {
      std::size_t k = 0;
      bool advanced = false, spanned = false;
      while (i >= k + 1 && i + k + 1 < m) {
        ++k;
        advanced = se.s[i + k] - se.s[i - k] >= fit;
        spanned = se.t[i + k] - se.t[i - k] >= span_max;
        if (advanced || spanned)
          break;
      }
      const std::size_t lo = i - k, hi = i + k;
      auto [v, v_se] = slope_fit(se.t, se.s, lo, hi, h);
      if (!advanced && !spanned)
        v = v_se = kNaN;
      // A step of more than 2 L between two samples, a quarter window (L / c_R) apart, is
      // faster than twice c_R: the crack joining bars that broke ahead of it.
      bool jump = false;
      for (std::size_t j = lo + 1; j <= hi; ++j)
        jump = jump || se.s[j] - se.s[j - 1] > 2.0 * g.L;
      // The speed is the window's: flagged when the softened zone ran far ahead of the crack
      // at any of its samples.
      bool flagged = false;
      for (std::size_t j = lo; j <= hi && o.zone_flag_length > 0.0; ++j)
        flagged = flagged || soft[se.at[j]] - whole[se.at[j]] > o.zone_flag_length;
      TipSample s;
      s.t = se.t[i];
      s.branch = static_cast<int>(b);
      s.a = grid.ca(se.cell[i]);
      s.n = grid.cn(se.cell[i]);
      s.length = pre_length + se.s[i];
      s.speed = v;
      s.speed_se = v_se;
      s.softening_length = pre_length + soft[se.at[i]];
      s.softened_ahead = soft[se.at[i]] - whole[se.at[i]];
      s.flagged = flagged;
      s.jump = jump;
      r.tip.push_back(s);
      // A jump is the crack joining bars broken ahead of it, not its tip's motion.
      if (std::isnan(v) || jump)
        continue;
      if (v > r.max_speed) {
        r.max_speed = v;
        r.max_speed_se = v_se;
      }
      if (!s.flagged && !(v <= r.max_unflagged_speed))
        r.max_unflagged_speed = v;
      if (advanced) {
        running.push_back(v);
        running_of[b].push_back(v);
      }
      if (b == 0 && r.branching_length && sense * (s.a - r.branch_a) <= 0.0)
        r.speed_before_branching = std::isnan(r.speed_before_branching)
                                       ? v
                                       : std::max(r.speed_before_branching, v);
    }
  }
  auto median = [](std::vector<double> v) {
    if (v.empty())
      return kNaN;
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
  };
  r.median_speed = median(running);
  r.trunk_median_speed = median(running_of[0]);
  for (std::size_t b = 1; b < series.size(); ++b) {
    BranchInfo& info = r.branches[b - 1];
    info.median_speed = median(running_of[b]);
    for (const TipSample& s : r.tip)
      if (s.branch == static_cast<int>(b) && !std::isnan(s.speed) && !s.jump &&
          !(s.speed <= info.max_speed))
        info.max_speed = s.speed;
  }
  for (std::size_t k = 0; k < times.size(); ++k)
    if (o.zone_flag_length > 0.0 && whole[k] > 0.0 && soft[k] - whole[k] > o.zone_flag_length)
      r.flagged_time += step;
  r.final_softening_length =
      pre_length + (softening.empty() ? far : std::max(far, distances(soft_arrival, kInf, soft_dist).second));
  std::stable_sort(r.tip.begin(), r.tip.end(), [](const TipSample& x, const TipSample& y) {
    return x.t < y.t || (x.t == y.t && x.branch < y.branch);
  });
  return r;
}

double rayleigh_speed(double E, double nu, double rho) {
  // xi = c_R / c_s solves xi^6 - 8 xi^4 + (24 - 16 k) xi^2 - 16 (1 - k) = 0, k = (c_s / c_p)^2
  // = (1 - 2 nu) / (2 (1 - nu)); the root in (0, 1), by bisection (the cubic in xi^2 is
  // negative at 0 and positive at 1).
  const double k = (1.0 - 2.0 * nu) / (2.0 * (1.0 - nu));
  auto f = [&](double x2) {
    return x2 * x2 * x2 - 8 * x2 * x2 + (24 - 16 * k) * x2 - 16 * (1 - k);
  };
  double lo = 1e-6, hi = 1.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > 0 ? hi : lo) = mid;
  }
  const double cs = std::sqrt(E / (2.0 * (1.0 + nu) * rho));
  return std::sqrt(0.5 * (lo + hi)) * cs;
}

std::string crack_report(const CrackAnalysis& r) {
  std::string s = fmt::format("crack: length {:.4g} mm along its path (pre-crack included), "
                              "{} broken bars in it, {} elsewhere\n",
                              r.final_length * 1e3, r.bars_in_crack, r.bars_elsewhere);
  s += fmt::format("tip speed: median {:.4g} m/s while it grows (the trunk's {:.4g} m/s), largest {:.4g} +- {:.2g} m/s, "
                   "{:.4g} m/s where the softened zone is short (it runs far ahead during {:.3g} "
                   "us); {} jumps (the crack joining bars broken ahead of it)\n",
                   r.median_speed, r.trunk_median_speed, r.max_speed, r.max_speed_se,
                   r.max_unflagged_speed,
                   r.flagged_time * 1e6, r.jumps);
  if (!r.branching_length)
    return s + "no branching";
  s += fmt::format("first branching at {:.4g} mm from the mouth, point ({:.4g}, {:.4g}) mm; "
                   "branches:",
                   *r.branching_length * 1e3, r.branch_a * 1e3, r.branch_n * 1e3);
  for (const BranchInfo& b : r.branches)
    s += fmt::format("\n  level {}: {:+.1f} deg, {:.3g} mm long, {}{}", b.level, b.angle_deg,
                     b.length * 1e3, b.opens ? "reaches a border" : "arrests inside",
                     b.level == 1 ? fmt::format(", tip speed median {:.4g} m/s, largest {:.4g} m/s",
                                                b.median_speed, b.max_speed)
                                  : std::string());
  s += fmt::format("\nsecondary branching: {}", r.secondary_branching ? "yes" : "no");
  return s;
}

CrackAnalysis analyze_crack_dir(const std::string& dir) {
  const RunGeometry rg = read_run_geometry(dir, "crack analysis");
  const toml::table& c = rg.resolved;
  const double L = rg.L;
  const CrackGeometry& g = rg.crack;
  const int along = rg.along, normal = rg.normal;
  auto opt_len = [&](const char* key, double fallback) {
    return analysis_number(rg, key, fallback);
  };
  const double E_lo = c["material"]["E_range"][0].value_or(0.0);
  const double E_hi = c["material"]["E_range"][1].value_or(0.0);
  const double nu = c["material"]["nu"].value_or(0.25);
  const double rho = c["material"]["rho"].value_or(0.0);
  const double cR = rayleigh_speed(0.5 * (E_lo + E_hi), nu, rho);
  CrackOptions o;
  o.min_branch_length = opt_len("min_branch_length", 6.0 * L);
  o.fit_length = opt_len("branch_fit_length", 10.0 * L);
  o.speed_window = opt_len("speed_window", cR > 0 ? 4.0 * L / cR : 0.0);
  o.speed_fit_length = opt_len("speed_fit_length", 10.0 * L);
  o.zone_flag_length = opt_len("zone_flag_length", 3.0 * L);

  const std::vector<CrackPoint> broken = read_bar_events(dir, rg, "broken");
  const std::vector<CrackPoint> softening = read_bar_events(dir, rg, "softening");

  const CrackAnalysis r = analyze_crack(broken, g, o, softening);

  const char axis[3] = {'x', 'y', 'z'};
  OutputFile tip(dir + "/crack_tip.csv");
  // The tip's coordinates named by the analysis plane's axes (tip_x, tip_z for a plate in x-z).
  std::string rows = fmt::format("time,branch,tip_{},tip_{},length,speed,speed_se,"
                                 "softening_length,softened_ahead,flagged,jump\n",
                                 axis[along], axis[normal]);
  for (const TipSample& s : r.tip)
    rows += fmt::format("{:.9g},{},{:.9g},{:.9g},{:.9g},{:.6g},{:.3g},{:.9g},{:.9g},{},{}\n", s.t,
                        s.branch, s.a, s.n, s.length, s.speed, s.speed_se, s.softening_length,
                        s.softened_ahead, s.flagged ? 1 : 0, s.jump ? 1 : 0);
  tip.write(rows);
  tip.commit();

  // A speed that was not measured (no window of the kind) is null.
  auto or_null = [](double v) {
    return std::isnan(v) ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(v);
  };
  nlohmann::ordered_json j;
  j["branching_length_m"] = r.branching_length ? nlohmann::ordered_json(*r.branching_length)
                                               : nlohmann::ordered_json(nullptr);
  nlohmann::ordered_json angles = nlohmann::ordered_json::array();
  for (const BranchInfo& b : r.branches)
    if (b.level == 1)
      angles.push_back(b.angle_deg);
  j["branch_angles_deg"] = r.branching_length ? angles : nlohmann::ordered_json(nullptr);
  j["secondary_branching"] = r.secondary_branching;
  j["max_crack_speed_m_s"] = r.max_speed;
  j["max_crack_speed_se_m_s"] = std::isnan(r.max_speed_se) ? nlohmann::ordered_json(nullptr)
                                                          : nlohmann::ordered_json(r.max_speed_se);
  j["max_unflagged_crack_speed_m_s"] = or_null(r.max_unflagged_speed);
  j["median_crack_speed_m_s"] = or_null(r.median_speed);
  j["flagged_time_s"] = r.flagged_time;
  j["tip_jumps"] = r.jumps;
  j["trunk_median_speed_m_s"] = or_null(r.trunk_median_speed);
  j["speed_before_branching_m_s"] = r.branching_length && !std::isnan(r.speed_before_branching)
                                        ? nlohmann::ordered_json(r.speed_before_branching)
                                        : nlohmann::ordered_json(nullptr);
  j["rayleigh_speed_m_s"] = cR;
  j["max_crack_speed_over_rayleigh"] = cR > 0 ? r.max_speed / cR : 0.0;
  j["branching_point_m"] = r.branching_length
                               ? nlohmann::ordered_json::array({r.branch_a, r.branch_n})
                               : nlohmann::ordered_json(nullptr);
  nlohmann::ordered_json bs = nlohmann::ordered_json::array();
  for (const BranchInfo& b : r.branches)
    bs.push_back({{"level", b.level},
                  {"angle_deg", b.angle_deg},
                  {"length_m", b.length},
                  {"opens", b.opens},
                  {"end_m", {b.end_a, b.end_n}}});
  for (std::size_t k = 0; k < r.branches.size(); ++k)
    if (r.branches[k].level == 1) {
      bs[k]["median_speed_m_s"] = or_null(r.branches[k].median_speed);
      bs[k]["max_speed_m_s"] = or_null(r.branches[k].max_speed);
    }
  j["branches"] = bs;
  j["final_crack_length_m"] = r.final_length;
  j["final_softened_length_m"] = r.final_softening_length;
  j["broken_bars_in_crack"] = r.bars_in_crack;
  j["broken_bars_elsewhere"] = r.bars_elsewhere;
  j["plane_axes"] = fmt::format("{}{}", axis[along], axis[normal]);
  j["mouth_m"] = g.mouth_a;
  j["precrack_tip_m"] = g.tip_a;
  j["crack_plane_m"] = g.line_n;
  j["min_branch_length_m"] = o.min_branch_length;
  j["branch_fit_length_m"] = o.fit_length;
  j["speed_window_s"] = o.speed_window;
  j["speed_fit_length_m"] = o.speed_fit_length;
  j["zone_flag_length_m"] = o.zone_flag_length;
  update_summary(dir, "crack", j);
  return r;
}

} // namespace ldem
