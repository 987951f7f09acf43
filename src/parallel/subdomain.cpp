#include "parallel/subdomain.hpp"

#include "util/error.hpp"

#include <algorithm>
#include <fmt/format.h>
#include <numeric>

namespace ldem {

namespace {

// First module of part p of n modules split into `parts`.
index_t part_first(index_t n, int parts, int p) {
  return static_cast<index_t>(std::uint64_t{n} * static_cast<std::uint64_t>(p) /
                              static_cast<std::uint64_t>(parts));
}

// The part along an axis that owns index idx (idx == n: the last).
int part_of(index_t idx, const AxisPart& a) {
  const auto after = std::upper_bound(a.firsts.begin(), a.firsts.end() - 1, idx);
  return std::clamp(static_cast<int>(after - a.firsts.begin()) - 1, 0, a.parts - 1);
}

bool fits(index_t ny, index_t nz, ProcessGrid g) {
  return static_cast<index_t>(g.py) <= ny && static_cast<index_t>(g.pz) <= nz;
}

// Adds a span, merged with the previous one where both numberings continue it.
void add_span(std::vector<Span>& spans, index_t local_first, index_t global_first, index_t count) {
  if (count == 0)
    return;
  if (!spans.empty()) {
    Span& last = spans.back();
    if (last.local_first + last.count == local_first &&
        last.global_first + last.count == global_first) {
      last.count += count;
      return;
    }
  }
  spans.push_back({local_first, global_first, count});
}

} // namespace

AxisPart split_axis(index_t n, int parts, int coord, const std::vector<std::uint64_t>* weights) {
  if (parts < 1 || coord < 0 || coord >= parts)
    throw InputError(fmt::format("part {} of {}: no such part", coord, parts));
  AxisPart a;
  a.n = n;
  a.coord = coord;
  a.parts = parts;
  a.firsts.resize(static_cast<std::size_t>(parts) + 1);
  for (int p = 0; p <= parts; ++p)
    a.firsts[static_cast<std::size_t>(p)] = part_first(n, parts, p);
  if (weights && weights->size() == n && parts <= static_cast<int>(n)) {
    // Part p starts at the first layer where the weights before it reach p / parts of the
    // whole, kept at least one layer after the part before and one layer per part after.
    std::vector<std::uint64_t> before(std::size_t{n} + 1, 0);
    for (index_t m = 0; m < n; ++m)
      before[m + 1] = before[m] + (*weights)[m];
    const std::uint64_t total = before[n];
    if (total > 0)
      for (int p = 1; p < parts; ++p) {
        const std::uint64_t target =
            (total * static_cast<std::uint64_t>(p) + static_cast<std::uint64_t>(parts) - 1) /
            static_cast<std::uint64_t>(parts);
        auto m = static_cast<index_t>(std::lower_bound(before.begin(), before.end(), target) -
                                      before.begin());
        const auto up = static_cast<std::size_t>(p);
        m = std::max(m, a.firsts[up - 1] + 1);
        m = std::min(m, n - static_cast<index_t>(parts - p));
        a.firsts[up] = m;
      }
  }
  a.m0 = a.firsts[static_cast<std::size_t>(coord)];
  a.m1 = a.firsts[static_cast<std::size_t>(coord) + 1];
  a.w0 = a.below() ? a.m0 - 1 : 0;
  a.w1 = a.above() ? a.m1 + 1 : n;
  return a;
}

ProcessGrid choose_grid(index_t ny, index_t nz, int ranks) {
  if (ranks < 1)
    throw InputError(fmt::format("{} processes: expected at least one", ranks));
  bool found = false;
  ProcessGrid best;
  std::uint64_t best_cut = 0;
  for (int py = 1; py <= ranks; ++py) {
    if (ranks % py != 0)
      continue;
    const ProcessGrid g{py, ranks / py};
    if (!fits(ny, nz, g))
      continue;
    const std::uint64_t cut = std::uint64_t(g.py - 1) * nz + std::uint64_t(g.pz - 1) * ny;
    if (!found || cut < best_cut) { // py rising: on a tie the first, with the most slabs in z
      found = true;
      best = g;
      best_cut = cut;
    }
  }
  if (found)
    return best;
  // The largest count below `ranks` that some grid fits.
  int fitting = 1;
  for (int q = ranks - 1; q > 1 && fitting == 1; --q)
    for (int py = 1; py <= q; ++py)
      if (q % py == 0 && fits(ny, nz, {py, q / py})) {
        fitting = q;
        break;
      }
  throw InputError(fmt::format(
      "lattice.modules: {} x {} modules across x cannot be shared by {} processes: a "
      "distributed run splits the body into Py x Pz boxes over y and z (rows of nodes along x "
      "stay whole), at least one module per box along each axis, and no Py x Pz = {} fits. {}",
      ny, nz, ranks, ranks,
      fitting == 1 ? std::string("Run it in one process (--threads gives it the cores)")
                   : fmt::format("Start {} processes", fitting)));
}

ProcessGrid resolve_grid(index_t ny, index_t nz, int ranks, ProcessGrid asked) {
  if (asked.py == 0 && asked.pz == 0)
    return choose_grid(ny, nz, ranks);
  if (asked.py < 1 || asked.pz < 1 || asked.py * asked.pz != ranks)
    throw InputError(fmt::format("--process-grid {} {}: expected two positive numbers whose "
                                 "product is the number of processes, {}",
                                 asked.py, asked.pz, ranks));
  if (!fits(ny, nz, asked))
    throw InputError(fmt::format("--process-grid {} {}: the body has {} x {} modules across x "
                                 "(y, z); expected at most that many boxes along each",
                                 asked.py, asked.pz, ny, nz));
  return asked;
}

int Subdomain::neighbour(int axis, int dir) const {
  const AxisPart& a = axis == 1 ? y : z;
  if (dir < 0 ? !a.below() : !a.above())
    return -1;
  return rank + dir * (axis == 1 ? 1 : grid.py);
}

Subdomain make_subdomain(index_t ny, index_t nz, ProcessGrid grid, int rank) {
  const int ranks = grid.py * grid.pz;
  if (grid.py < 1 || grid.pz < 1 || rank < 0 || rank >= ranks)
    throw InputError(fmt::format("rank {} of a {} x {} grid of processes: no such rank", rank,
                                 grid.py, grid.pz));
  if (!fits(ny, nz, grid))
    throw InputError(fmt::format("a {} x {} grid of processes on {} x {} modules across x: "
                                 "expected at least one module per box along each axis",
                                 grid.py, grid.pz, ny, nz));
  Subdomain s;
  s.rank = rank;
  s.ranks = ranks;
  s.grid = grid;
  s.y = split_axis(ny, grid.py, rank % grid.py);
  s.z = split_axis(nz, grid.pz, rank / grid.py);
  return s;
}

Subdomain make_subdomain(const Lattice& whole, ProcessGrid grid, int rank) {
  Subdomain s = make_subdomain(whole.ny(), whole.nz(), grid, rank);
  if (!whole.shaped())
    return s;
  // The present modules of each layer along y and along z.
  std::vector<std::uint64_t> wy(whole.ny(), 0), wz(whole.nz(), 0);
  for (index_t k = 0; k < whole.nz(); ++k)
    for (index_t j = 0; j < whole.ny(); ++j)
      for (index_t i = 0; i < whole.nx(); ++i)
        if (whole.module_present(i, j, k)) {
          ++wy[j];
          ++wz[k];
        }
  s.y = split_axis(whole.ny(), grid.py, rank % grid.py, &wy);
  s.z = split_axis(whole.nz(), grid.pz, rank / grid.py, &wz);
  return s;
}

Subdomain make_subdomain(index_t ny, index_t nz, int ranks, int rank) {
  return make_subdomain(ny, nz, choose_grid(ny, nz, ranks), rank);
}

std::string describe_decomposition(const Lattice& whole, ProcessGrid g) {
  const Subdomain any = make_subdomain(whole, g, 0);
  const auto sizes = [](const AxisPart& a) {
    index_t lo = a.n, hi = 0;
    for (std::size_t p = 0; p + 1 < a.firsts.size(); ++p) {
      lo = std::min(lo, a.firsts[p + 1] - a.firsts[p]);
      hi = std::max(hi, a.firsts[p + 1] - a.firsts[p]);
    }
    return lo == hi ? fmt::format("{}", lo) : fmt::format("{} to {}", lo, hi);
  };
  return fmt::format("{} processes as {} x {} boxes over y and z, each {} x {} x {} modules "
                     "(x, y, z){}",
                     g.py * g.pz, g.py, g.pz, whole.nx(), sizes(any.y), sizes(any.z),
                     whole.shaped() ? ", cut to share the present modules evenly" : "");
}

int owner_rank(const Subdomain& any, index_t j, index_t k) {
  return part_of(j, any.y) + any.grid.py * part_of(k, any.z);
}

Lattice window_lattice(const Subdomain& sub, const Lattice& whole) {
  Lattice local(whole.nx(), sub.y.local_n(), sub.z.local_n(), whole.L());
  if (whole.shaped()) {
    // The window's share of a shaped body's modules.
    auto present = std::make_shared<std::vector<std::uint8_t>>();
    present->reserve(local.num_modules());
    const std::vector<std::uint8_t>& body = *whole.modules_present();
    for (index_t k = sub.z.w0; k < sub.z.w1; ++k)
      for (index_t j = sub.y.w0; j < sub.y.w1; ++j)
        for (index_t i = 0; i < whole.nx(); ++i)
          present->push_back(body[i + std::size_t{whole.nx()} * (j + std::size_t{whole.ny()} * k)]);
    local.set_modules(std::move(present));
  }
  return local;
}

std::vector<Span> subdomain_node_spans(const Subdomain& sub, const Lattice& whole, bool owned) {
  const Lattice local = window_lattice(sub, whole);
  const AxisPart &y = sub.y, &z = sub.z;
  std::vector<Span> spans;
  // Corner rows [j0, j1) of corner planes [k0, k1), then centre rows [j0, c1) of centre
  // planes [k0, d1), a span per plane (merged where they continue).
  const index_t j0 = owned ? y.m0 : y.w0, k0 = owned ? z.m0 : z.w0;
  const index_t j1 = owned ? y.corner_end() : y.w1 + 1, k1 = owned ? z.corner_end() : z.w1 + 1;
  const index_t c1 = owned ? y.m1 : y.w1, d1 = owned ? z.m1 : z.w1;
  for (index_t k = k0; k < k1; ++k)
    add_span(spans, local.corner(0, j0 - y.w0, k - z.w0), whole.corner(0, j0, k),
             (whole.nx() + 1) * (j1 - j0));
  for (index_t k = k0; k < d1; ++k)
    add_span(spans, local.centre(0, j0 - y.w0, k - z.w0), whole.centre(0, j0, k),
             whole.nx() * (c1 - j0));
  return spans;
}

std::vector<Span> subdomain_bar_spans(const Subdomain& sub, const Lattice& whole, bool owned) {
  const Lattice local = window_lattice(sub, whole);
  const AxisPart &y = sub.y, &z = sub.z;
  std::vector<Span> spans;
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fw = whole.family(f);
    const FamilyInfo& fl = local.family(f);
    const auto family = static_cast<Family>(f);
    // Bar blocks (j, k) of the family: the window's, or the owned ones.
    const index_t j0 = owned ? y.m0 : y.w0, k0 = owned ? z.m0 : z.w0;
    const index_t j1 = owned ? std::min(y.corner_end(), fw.nj) : y.w0 + fl.nj;
    const index_t k1 = owned ? std::min(z.corner_end(), fw.nk) : z.w0 + fl.nk;
    if (j1 <= j0)
      continue;
    for (index_t k = k0; k < k1; ++k)
      add_span(spans, local.bar(family, 0, j0 - y.w0, k - z.w0), whole.bar(family, 0, j0, k),
               fw.ni * (j1 - j0));
  }
  return spans;
}

index_t global_bar(const Subdomain& sub, const Lattice& local, const Lattice& whole, index_t bar) {
  const BarAddress a = local.bar_address(bar);
  return whole.bar(a.family, a.i, a.j + sub.y.w0, a.k + sub.z.w0);
}

Conditions subdomain_conditions(const Subdomain& sub, const Lattice& whole, const Lattice& local,
                                const Conditions& c) {
  // The set's nodes this subdomain owns, in local numbers (in the same order), and where each
  // was in the whole set (`kept`, for per-node weights).
  std::vector<std::size_t> kept;
  const auto restrict_set = [&](const NodeSet& set) {
    NodeSet out{set.name, {}};
    kept.clear();
    for (std::size_t q = 0; q < set.nodes.size(); ++q) {
      const NodeAddress a = whole.node_address(set.nodes[q]);
      if (!sub.owns(a.j, a.k, !a.centre))
        continue;
      const index_t j = a.j - sub.y.w0, k = a.k - sub.z.w0;
      out.nodes.push_back(a.centre ? local.centre(a.i, j, k) : local.corner(a.i, j, k));
      kept.push_back(q);
    }
    return out;
  };
  Conditions out;
  out.plane_strain_axis = c.plane_strain_axis;
  for (const FixedDofs& f : c.fixed)
    if (NodeSet set = restrict_set(f.set); !set.nodes.empty())
      out.fixed.push_back({std::move(set), f.dofs});
  for (const ImposedVelocity& v : c.velocities)
    if (NodeSet set = restrict_set(v.set); !set.nodes.empty())
      out.velocities.push_back({std::move(set), v.dofs, v.velocity, v.scale, v.control});
  for (const NodalLoad& l : c.loads)
    if (NodeSet set = restrict_set(l.set); !set.nodes.empty()) {
      std::vector<double> weight;
      if (!l.weight.empty())
        for (std::size_t q : kept)
          weight.push_back(l.weight[q]);
      out.loads.push_back({std::move(set), l.force, l.scale, std::move(weight)});
    }
  // The platens, and where the window is in the body (they test its nodes at their places in
  // the body: the same numbers whatever the window).
  out.platens = c.platens;
  out.window_j = sub.y.w0;
  out.window_k = sub.z.w0;
  return out;
}

std::vector<std::size_t> key_order(const std::vector<double>& keys) {
  std::vector<std::size_t> order(keys.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return keys[a] < keys[b]; });
  return order;
}

double sum_in_order(const std::vector<double>& values, const std::vector<std::size_t>& order) {
  double sum = 0.0; // from zero, row after row, as one process sums them
  for (std::size_t q : order)
    sum += values[q];
  return sum;
}

namespace {

// Every window node the subdomain does not own (received from the neighbours, or the window's
// outermost corner row and plane), all DOF held.
Conditions with_ghosts(const Subdomain& sub, const Lattice& local, Conditions c) {
  NodeSet ghosts{"ghost nodes", {}};
  c.not_owned.assign(local.num_nodes(), 0);
  for (index_t n = 0; n < local.num_nodes(); ++n) {
    const NodeAddress a = local.node_address(n);
    if (!sub.owns(a.j + sub.y.w0, a.k + sub.z.w0, !a.centre)) {
      ghosts.nodes.push_back(n);
      c.not_owned[n] = 1;
    }
  }
  if (!ghosts.nodes.empty())
    c.fixed.push_back({std::move(ghosts), kDofAll});
  return c;
}

Simulation local_simulation(const Subdomain& sub, Lattice local, BarTable table, Conditions c,
                            SolverOptions options, std::vector<index_t> precracked) {
  if (local.ny() != sub.y.local_n() || local.nz() != sub.z.local_n())
    throw InputError(fmt::format("subdomain of rank {}: local lattice of {} x {} modules across "
                                 "x, the window has {} x {}",
                                 sub.rank, local.ny(), local.nz(), sub.y.local_n(),
                                 sub.z.local_n()));
  Conditions all = with_ghosts(sub, local, std::move(c));
  return Simulation(std::move(local), std::move(table), std::move(all), options,
                    std::move(precracked));
}

} // namespace

SubdomainRun::SubdomainRun(const Subdomain& sub, Lattice local, BarTable table,
                           Conditions conditions, SolverOptions options,
                           std::vector<index_t> precracked)
    : sub_(sub), sim_(local_simulation(sub, std::move(local), std::move(table),
                                       std::move(conditions), options, std::move(precracked))) {}

index_t SubdomainRun::local_node(const NodeAddress& g) const {
  const Lattice& lat = sim_.lattice();
  const index_t j = g.j - sub_.y.w0, k = g.k - sub_.z.w0;
  return g.centre ? lat.centre(g.i, j, k) : lat.corner(g.i, j, k);
}

NodeAddress SubdomainRun::global_address(index_t local) const {
  NodeAddress a = sim_.lattice().node_address(local);
  a.j += sub_.y.w0;
  a.k += sub_.z.w0;
  return a;
}

bool SubdomainRun::owns(index_t local) const {
  const NodeAddress a = global_address(local);
  return sub_.owns(a.j, a.k, !a.centre);
}

bool SubdomainRun::owns_bar(index_t local_bar) const {
  const BarAddress a = sim_.lattice().bar_address(local_bar);
  return sub_.owns(a.j + sub_.y.w0, a.k + sub_.z.w0, true);
}

template <class Bar, class Node>
void SubdomainRun::for_each_owned_row(Bar&& bar_row, Node&& node_row) const {
  // Keys: the body's row order, plane k, then line j, then family, as the step visits them.
  const double lines = static_cast<double>(sub_.y.n) + 1.0;
  for (std::size_t r = 0; r < sim_.report_bar_elastic().size(); ++r) {
    const index_t j = sim_.bar_row_line(r) + sub_.y.w0, k = sim_.bar_row_plane(r) + sub_.z.w0;
    if (sub_.owns(j, k, true))
      bar_row(r, (k * lines + j) * kFamilies + sim_.bar_row_family(r));
  }
  for (std::size_t r = 0; r < sim_.report_node_kinetic().size(); ++r) {
    const NodeRow& row = sim_.node_row(r);
    const index_t j = row.j + sub_.y.w0, k = row.k + sub_.z.w0;
    if (sub_.owns(j, k, !row.centre))
      node_row(r);
  }
}

void SubdomainRun::append_owned_row_keys(EnergyRows& rows) const {
  for_each_owned_row([&](std::size_t, double key) { rows.bar_keys.push_back(key); },
                     [](std::size_t) {});
}

void SubdomainRun::append_owned_energy_rows(EnergyRows& rows) const {
  const auto& u = sim_.report_bar_elastic();
  const auto& d = sim_.report_bar_damage();
  const auto& f = sim_.report_bar_fatigue();
  const auto& kin = sim_.report_node_kinetic();
  for_each_owned_row(
      [&](std::size_t r, double key) {
        rows.elastic.push_back(u[r]);
        rows.damage.push_back(d[r]);
        rows.fatigue.push_back(f[r]);
        rows.bar_keys.push_back(key);
      },
      [&](std::size_t r) { rows.kinetic.push_back(kin[r]); });
}

index_t SubdomainRun::send_index(int axis, int dir) const {
  const AxisPart& a = part(axis);
  return dir < 0 ? a.m0 - a.w0 : a.m1 - 1 - a.w0;
}

index_t SubdomainRun::recv_index(int axis, int dir) const {
  const AxisPart& a = part(axis);
  return dir < 0 ? a.m0 - 1 - a.w0 : a.m1 - a.w0;
}

template <class F> void SubdomainRun::for_each_halo_run(int axis, index_t index, F&& visit) const {
  const Lattice& lat = sim_.lattice();
  if (axis == 2) { // a whole corner plane and a whole centre plane of the window
    visit(lat.corner(0, 0, index), (lat.nx() + 1) * (lat.ny() + 1));
    visit(lat.centre(0, 0, index), lat.nx() * lat.ny());
    return;
  }
  // Corner row `index` of the owned corner planes, then its centre row of the owned centre
  // planes.
  const AxisPart& z = sub_.z;
  for (index_t k = z.m0; k < z.corner_end(); ++k)
    visit(lat.corner(0, index, k - z.w0), lat.nx() + 1);
  for (index_t k = z.m0; k < z.m1; ++k)
    visit(lat.centre(0, index, k - z.w0), lat.nx());
}

std::size_t SubdomainRun::halo_size(int axis, int dir) const {
  if (sub_.neighbour(axis, dir) < 0)
    return 0;
  std::size_t n = 0;
  for_each_halo_run(axis, send_index(axis, dir), [&](index_t, index_t count) { n += count; });
  return 3 * n;
}

void SubdomainRun::pack(int axis, int dir, std::vector<double>& out) const {
  out.clear();
  if (halo_size(axis, dir) == 0)
    return;
  for_each_halo_run(axis, send_index(axis, dir), [&](index_t first, index_t count) {
    sim_.append_displacements(first, count, out);
  });
}

void SubdomainRun::unpack(int axis, int dir, const std::vector<double>& in) {
  check_halo(axis, dir, in.size());
  const double* at = in.data();
  if (in.empty())
    return;
  for_each_halo_run(axis, recv_index(axis, dir), [&](index_t first, index_t count) {
    sim_.assign_displacements(first, count, at);
    at += 3 * std::size_t{count};
  });
}

void SubdomainRun::pack(int axis, int dir, const std::vector<double>& values,
                        std::vector<double>& out) const {
  out.clear();
  if (halo_size(axis, dir) == 0)
    return;
  for_each_halo_run(axis, send_index(axis, dir), [&](index_t first, index_t count) {
    out.insert(out.end(), values.begin() + 3 * std::ptrdiff_t{first},
               values.begin() + 3 * std::ptrdiff_t{first + count});
  });
}

void SubdomainRun::unpack(int axis, int dir, const std::vector<double>& in,
                          std::vector<double>& values) const {
  check_halo(axis, dir, in.size());
  const double* at = in.data();
  if (in.empty())
    return;
  for_each_halo_run(axis, recv_index(axis, dir), [&](index_t first, index_t count) {
    std::copy(at, at + 3 * std::size_t{count}, values.begin() + 3 * std::ptrdiff_t{first});
    at += 3 * std::size_t{count};
  });
}

void SubdomainRun::check_halo(int axis, int dir, std::size_t size) const {
  if (size != halo_size(axis, dir))
    throw InputError(fmt::format("halo from rank {}: {} values, expected {}",
                                 sub_.neighbour(axis, dir), size, halo_size(axis, dir)));
}

} // namespace ldem
