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

// A set of cells of one distance shell, connected within the shell.
struct Component {
  int shell = 0;
  std::vector<int> cells;
  double min_d = kInf, max_d = 0.0, reach = 0.0;
  std::vector<int> parents, children;
};

struct Tracker {
  const Grid& grid;
  const std::vector<double>& dist; // per cell, kInf outside the crack
  const CrackOptions& opt;
  std::vector<int> comp_of; // per cell, -1 outside the crack
  std::vector<Component> comps;
  std::vector<std::vector<int>> by_shell;

  Tracker(const Grid& g, const std::vector<double>& d, const CrackOptions& o, double w)
      : grid(g), dist(d), opt(o), comp_of(d.size(), -1) {
    int max_shell = 0;
    for (double x : d)
      if (x < kInf)
        max_shell = std::max(max_shell, static_cast<int>(x / w));
    by_shell.resize(static_cast<std::size_t>(max_shell) + 1);
    std::vector<int> shell_of(d.size(), -1);
    for (std::size_t c = 0; c < d.size(); ++c)
      if (d[c] < kInf)
        shell_of[c] = static_cast<int>(d[c] / w);
    // Components of each shell (flood fill within the shell), in order of increasing shell.
    std::vector<int> order;
    for (std::size_t c = 0; c < d.size(); ++c)
      if (d[c] < kInf)
        order.push_back(static_cast<int>(c));
    std::stable_sort(order.begin(), order.end(),
                     [&](int x, int y) { return shell_of[x] < shell_of[y]; });
    for (int seed : order) {
      if (comp_of[seed] >= 0)
        continue;
      const int id = static_cast<int>(comps.size());
      Component k;
      k.shell = shell_of[seed];
      std::vector<int> stack{seed};
      comp_of[seed] = id;
      while (!stack.empty()) {
        const int c = stack.back();
        stack.pop_back();
        k.cells.push_back(c);
        k.min_d = std::min(k.min_d, d[c]);
        k.max_d = std::max(k.max_d, d[c]);
        grid.around(c, kReach, [&](int m, double) {
          if (comp_of[m] < 0 && shell_of[m] == k.shell) {
            comp_of[m] = id;
            stack.push_back(m);
          }
        });
      }
      by_shell[static_cast<std::size_t>(k.shell)].push_back(id);
      comps.push_back(std::move(k));
    }
    // Parents: components of lower shells next to a component's cells.
    for (std::size_t id = 0; id < comps.size(); ++id) {
      for (int c : comps[id].cells)
        grid.around(c, kReach, [&](int m, double) {
          const int p = comp_of[m];
          if (p >= 0 && comps[static_cast<std::size_t>(p)].shell < comps[id].shell)
            comps[id].parents.push_back(p);
        });
      auto& ps = comps[id].parents;
      std::sort(ps.begin(), ps.end());
      ps.erase(std::unique(ps.begin(), ps.end()), ps.end());
      for (int p : ps)
        comps[static_cast<std::size_t>(p)].children.push_back(static_cast<int>(id));
    }
    // Reach: the farthest distance along the crack at or beyond a component.
    for (std::size_t s = by_shell.size(); s-- > 0;)
      for (int id : by_shell[s]) {
        Component& k = comps[static_cast<std::size_t>(id)];
        k.reach = k.max_d;
        for (int ch : k.children)
          k.reach = std::max(k.reach, comps[static_cast<std::size_t>(ch)].reach);
      }
  }

  // Components reachable from `start` through children, within `allowed`, up to distance
  // `limit` (min_d <= limit).
  std::vector<char> closure(const std::vector<int>& start, const std::vector<char>& allowed,
                            double limit) const {
    std::vector<char> in(comps.size(), 0);
    std::vector<int> stack;
    for (int s : start)
      if (allowed[static_cast<std::size_t>(s)]) {
        in[static_cast<std::size_t>(s)] = 1;
        stack.push_back(s);
      }
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      for (int ch : comps[static_cast<std::size_t>(c)].children) {
        const auto u = static_cast<std::size_t>(ch);
        if (!in[u] && allowed[u] && comps[u].min_d <= limit) {
          in[u] = 1;
          stack.push_back(ch);
        }
      }
    }
    return in;
  }

  // The first shell, from `start` outwards within `allowed`, where the crack runs on as two or
  // more lineages that each go on for min_branch_length and do not meet again within it.
  // Returns the groups of components (one per branch) at that shell, empty if none.
  std::vector<std::vector<int>> first_split(const std::vector<int>& start,
                                            const std::vector<char>& allowed) const {
    const std::vector<char> region = closure(start, allowed, kInf);
    int first_shell = static_cast<int>(by_shell.size());
    for (int s : start)
      first_shell = std::min(first_shell, comps[static_cast<std::size_t>(s)].shell);
    for (std::size_t s = static_cast<std::size_t>(std::max(first_shell, 0)); s < by_shell.size();
         ++s) {
      std::vector<int> live;
      for (int id : by_shell[s]) {
        const Component& k = comps[static_cast<std::size_t>(id)];
        if (region[static_cast<std::size_t>(id)] && k.reach - k.max_d >= opt.min_branch_length)
          live.push_back(id);
      }
      if (live.size() < 2)
        continue;
      // Lineages that meet again within min_branch_length are one crack (a band with an
      // island of intact bars), not two branches.
      std::vector<std::vector<char>> ahead;
      for (int id : live)
        ahead.push_back(closure({id}, region,
                                comps[static_cast<std::size_t>(id)].max_d + opt.min_branch_length));
      std::vector<int> group(live.size());
      std::iota(group.begin(), group.end(), 0);
      auto find = [&](int x) {
        while (group[static_cast<std::size_t>(x)] != x)
          x = group[static_cast<std::size_t>(x)] =
              group[static_cast<std::size_t>(group[static_cast<std::size_t>(x)])];
        return x;
      };
      for (std::size_t x = 0; x < live.size(); ++x)
        for (std::size_t y = x + 1; y < live.size(); ++y)
          for (std::size_t c = 0; c < comps.size(); ++c)
            if (ahead[x][c] && ahead[y][c]) {
              group[static_cast<std::size_t>(find(static_cast<int>(x)))] =
                  find(static_cast<int>(y));
              break;
            }
      std::vector<std::vector<int>> groups;
      std::vector<int> slot(live.size(), -1);
      for (std::size_t x = 0; x < live.size(); ++x) {
        const auto r = static_cast<std::size_t>(find(static_cast<int>(x)));
        if (slot[r] < 0) {
          slot[r] = static_cast<int>(groups.size());
          groups.emplace_back();
        }
        groups[static_cast<std::size_t>(slot[r])].push_back(live[x]);
      }
      if (groups.size() >= 2)
        return groups;
    }
    return {};
  }
};

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

  // Branching: shells one module wide along the crack, tracked outwards. `branch_of` numbers
  // the cells of each branch of the first bifurcation (1, 2, ... from +n to -n); 0 is the trunk.
  std::vector<int> branch_of(ncell, 0);
  const Tracker tr(grid, dist, o, g.L);
  [&] {
    if (tr.comps.empty())
      return;
    const std::vector<char> all(tr.comps.size(), 1);
    std::vector<int> roots(tr.by_shell.front().begin(), tr.by_shell.front().end());
    const auto groups = tr.first_split(roots, all);
    if (groups.empty())
      return;

    auto near_border = [&](double a, double n) {
      return a - g.a_lo < g.L || g.a_hi - a < g.L || n - g.n_lo < g.L || g.n_hi - n < g.L;
    };
    // One branch: the components reached from its group and from no other group.
    auto describe = [&](const std::vector<std::vector<int>>& gs, std::size_t which, int level,
                        const std::vector<char>& allowed, std::vector<char>& own) {
      own = tr.closure(gs[which], allowed, kInf);
      for (std::size_t other = 0; other < gs.size(); ++other)
        if (other != which) {
          const std::vector<char> theirs = tr.closure(gs[other], allowed, kInf);
          for (std::size_t c = 0; c < own.size(); ++c)
            if (theirs[c])
              own[c] = 0;
        }
      double start = kInf;
      for (int id : gs[which])
        start = std::min(start, tr.comps[static_cast<std::size_t>(id)].min_d);
      BranchInfo b;
      b.level = level;
      std::vector<std::pair<double, double>> pts;
      double farthest = -1.0;
      for (std::size_t id = 0; id < own.size(); ++id) {
        if (!own[id])
          continue;
        for (int c : tr.comps[id].cells) {
          const double d = dist[static_cast<std::size_t>(c)];
          if (d <= start + o.fit_length)
            pts.emplace_back(grid.ca(c), grid.cn(c));
          if (d > farthest) {
            farthest = d;
            b.end_a = grid.ca(c);
            b.end_n = grid.cn(c);
          }
          if (near_border(grid.ca(c), grid.cn(c)))
            b.opens = true;
        }
      }
      b.length = farthest - start;
      Line line{0, 0, 1, 0};
      if (pts.size() >= 2) {
        line = fit_line(pts);
        // Point the direction away from the bifurcation, towards the branch's far end.
        if ((b.end_a - line.a) * line.da + (b.end_n - line.n) * line.dn < 0) {
          line.da = -line.da;
          line.dn = -line.dn;
        }
      }
      b.angle_deg = std::atan2(line.dn, sense * line.da) * 180.0 / M_PI;
      return std::make_pair(b, line);
    };

    std::vector<Line> lines;
    std::vector<std::vector<char>> owns(groups.size());
    for (std::size_t k = 0; k < groups.size(); ++k) {
      auto [b, line] = describe(groups, k, 1, all, owns[k]);
      r.branches.push_back(b);
      lines.push_back(line);
    }
    // Order the branches from +n to -n.
    std::vector<std::size_t> order(groups.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return r.branches[x].angle_deg > r.branches[y].angle_deg;
    });
    for (std::size_t p = 0; p < order.size(); ++p)
      for (std::size_t id = 0; id < tr.comps.size(); ++id)
        if (owns[order[p]][id])
          for (int c : tr.comps[id].cells)
            branch_of[static_cast<std::size_t>(c)] = static_cast<int>(p) + 1;

    // The bifurcation point: where the lines of the two most divergent branches cross, if
    // they cross within the crack's reach; otherwise the centre of the last shell before the
    // split.
    const Line& up = lines[order.front()];
    const Line& down = lines[order.back()];
    const double det = up.da * (-down.dn) - up.dn * (-down.da);
    double pa = 0, pn = 0;
    int split_shell = tr.comps[static_cast<std::size_t>(groups[0][0])].shell;
    {
      double sa = 0, sn = 0, w = 0;
      const std::size_t s = static_cast<std::size_t>(std::max(split_shell - 1, 0));
      for (int id : tr.by_shell[s])
        for (int c : tr.comps[static_cast<std::size_t>(id)].cells) {
          sa += grid.ca(c);
          sn += grid.cn(c);
          w += 1;
        }
      pa = sa / w;
      pn = sn / w;
    }
    const double angle_gap =
        r.branches[order.front()].angle_deg - r.branches[order.back()].angle_deg;
    if (std::abs(det) > 1e-12 && angle_gap > 10.0) {
      const double ba = down.a - up.a, bn = down.n - up.n;
      const double s = (ba * (-down.dn) - bn * (-down.da)) / det;
      const double xa = up.a + s * up.da, xn = up.n + s * up.dn;
      if (std::hypot(xa - pa, xn - pn) <= o.fit_length) {
        pa = xa;
        pn = xn;
      }
    }
    r.branch_a = pa;
    r.branch_n = pn;
    r.branching_length = sense * (pa - g.mouth_a);

    std::vector<BranchInfo> first;
    for (std::size_t k : order)
      first.push_back(r.branches[k]);
    r.branches = first;
    // Secondary branching: a split within a branch.
    for (std::size_t k : order) {
      std::vector<int> start = groups[k];
      const auto sub = tr.first_split(start, owns[k]);
      if (sub.empty())
        continue;
      r.secondary_branching = true;
      for (std::size_t j = 0; j < sub.size(); ++j) {
        std::vector<char> own;
        r.branches.push_back(describe(sub, j, 2, owns[k], own).first);
      }
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
      s.flagged = o.zone_flag_length > 0.0 && s.softened_ahead > o.zone_flag_length;
      s.jump = jump;
      r.tip.push_back(s);
      // A jump is the crack joining bars broken ahead of it, not its tip's motion.
      if (std::isnan(v) || jump)
        continue;
      if (v > r.max_speed) {
        r.max_speed = v;
        r.max_speed_se = v_se;
      }
      if (!s.flagged)
        r.max_unflagged_speed = std::max(r.max_unflagged_speed, v);
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
      return 0.0;
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
      if (s.branch == static_cast<int>(b) && !std::isnan(s.speed) && !s.jump)
        info.max_speed = std::max(info.max_speed, s.speed);
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
  j["max_unflagged_crack_speed_m_s"] = r.max_unflagged_speed;
  j["median_crack_speed_m_s"] = r.median_speed;
  j["flagged_time_s"] = r.flagged_time;
  j["tip_jumps"] = r.jumps;
  j["trunk_median_speed_m_s"] = r.trunk_median_speed;
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
      bs[k]["median_speed_m_s"] = r.branches[k].median_speed;
      bs[k]["max_speed_m_s"] = r.branches[k].max_speed;
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
