#include "solver/simulation.hpp"

#include "util/error.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <limits>
#include <omp.h>
#include <type_traits>
#if defined(__AVX512F__)
#include <immintrin.h>
#endif

namespace ldem {

namespace {

// A strain ratio or a motion not yet measured: the intact fast path waits for it.
constexpr double kUnknown = std::numeric_limits<double>::infinity();

// Whether the node kernel is the AVX-512 one, which takes fast links and can also move the
// nodes (node_row_forces).
#if defined(__AVX512F__)
constexpr bool kVectorKernel = true;
#else
constexpr bool kVectorKernel = false;
#endif

// Lumped masses: each module gives rho L^3 / 2 to its centre node and rho L^3 / 16 to each
// of its 8 corners, so a corner carries (modules sharing it) / 16 rho L^3 (1/2 inside,
// 1/4 on a face, 1/8 on an edge, 1/16 at a box corner) and the total is rho V exactly.
// With a density field (one value per module) each module lumps its own mass the same way.
std::vector<double> lumped_masses(const Lattice& lat, double rho,
                                  const std::vector<double>& rho_m) {
  const double V = lat.L() * lat.L() * lat.L();
  std::vector<double> m(lat.num_nodes());
  if (rho_m.empty()) {
    for (index_t k = 0; k <= lat.nz(); ++k)
      for (index_t j = 0; j <= lat.ny(); ++j)
        for (index_t i = 0; i <= lat.nx(); ++i)
          m[lat.corner(i, j, k)] = rho * V * lat.modules_at_corner(i, j, k) / 16.0;
    for (index_t c = lat.num_corners(); c < lat.num_nodes(); ++c)
      m[c] = 0.5 * rho * V;
    return m;
  }
  for (index_t k = 0; k < lat.nz(); ++k)
    for (index_t j = 0; j < lat.ny(); ++j)
      for (index_t i = 0; i < lat.nx(); ++i) {
        const index_t module = lat.centre(i, j, k) - lat.num_corners();
        const double mm = rho_m[module] * V;
        m[lat.centre(i, j, k)] = 0.5 * mm;
        for (index_t c = 0; c < 8; ++c)
          m[lat.corner(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))] += mm / 16.0;
      }
  return m;
}

} // namespace

double time_step_by_rule(const TimeStep& step, const StableStep& stable, double E_max, double rho,
                         double L) {
  // The bar wave speed of the stiffest material in the body: with a graded or random E the
  // paper's rule is taken at the largest E, where the stable step is smallest.
  const double c = std::sqrt(E_max / rho);
  double dt = 0.0;
  switch (step.rule) {
  case TimeStep::Rule::Safety:
    if (!(step.safety > 0.0 && step.safety <= 1.0))
      throw InputError(fmt::format(
          "time step safety fraction: expected a value in (0, 1], got {:g}", step.safety));
    dt = step.safety * stable.dt;
    break;
  case TimeStep::Rule::Given:
    dt = step.dt;
    break;
  case TimeStep::Rule::Paper:
    if (!(step.courant > 0.0 && step.courant <= 1.0))
      throw InputError(fmt::format("time step courant number: expected a value in (0, 1], got {:g}",
                                   step.courant));
    dt = step.courant * L / c;
    break;
  }
  if (!(dt > 0.0) || !std::isfinite(dt))
    throw InputError(fmt::format("time step: expected a positive dt in s, got {:g}", dt));
  if (dt > stable.dt)
    throw InputError(fmt::format(
        "time step: dt = {:.4g} s ({:.3f} L/c{}) is above the stable limit {:.4g} s ({:.3f} L/c) "
        "of this lattice (2 / largest eigenfrequency of M^-1 K); use dt <= {:.4g} s or a safety "
        "fraction",
        dt, dt * c / L, step.rule == TimeStep::Rule::Paper ? ", the paper's rule" : "", stable.dt,
        stable.dt * c / L, stable.dt));
  return dt;
}

Simulation::Simulation(Lattice lattice, BarTable table, Conditions conditions,
                       SolverOptions options, std::vector<index_t> precracked)
    : lat_(std::move(lattice)), table_(std::move(table)), cond_(std::move(conditions)),
      opt_(options) {
  const index_t nn = lat_.num_nodes();
  const index_t nb = lat_.num_bars();
  if (!(opt_.damping >= 0.0) || !std::isfinite(opt_.damping))
    throw InputError(
        fmt::format("damping: expected a coefficient >= 0 in 1/s, got {:g}", opt_.damping));

  // The step loop's node arrays: the lattice's rows of nodes, each from a cache line on.
  slots_ = {static_cast<std::int64_t>(round_up_to_line(lat_.nx() + 1ull)),
            static_cast<std::int64_t>(round_up_to_line(lat_.nx())), 0};
  slots_.centre_first = slots_.corner_row * (lat_.ny() + 1ll) * (lat_.nz() + 1ll);
  slot_count_ =
      static_cast<std::size_t>(slots_.centre_first + slots_.centre_row * lat_.ny() * lat_.nz());
  // Masses and held DOF by node number while the step is set up, then in the slots only.
  const std::vector<double> mass = lumped_masses(lat_, table_.spec().rho, table_.rho_module());
  slot_mass_.assign(slot_count_, 0.0);
  slot_inv_mass_.assign(slot_count_, 0.0);
  for (index_t n = 0; n < nn; ++n) {
    slot_mass_[slot(n)] = mass[n];
    slot_inv_mass_[slot(n)] = 1.0 / mass[n];
  }

  ux_.assign(slot_count_, 0.0);
  uy_.assign(slot_count_, 0.0);
  uz_.assign(slot_count_, 0.0);
  wx_.assign(slot_count_, 0.0);
  wy_.assign(slot_count_, 0.0);
  wz_.assign(slot_count_, 0.0);
  std::vector<DofMask> held(nn, 0);

  auto check_set = [&](const NodeSet& set, const char* what) {
    if (set.nodes.empty())
      throw InputError(
          fmt::format("{} on node set \"{}\": the set selects no node", what, set.name));
    if (set.nodes.back() >= nn)
      throw InputError(fmt::format("{} on node set \"{}\": node {} does not exist (lattice has {})",
                                   what, set.name, set.nodes.back(), nn));
  };
  for (const FixedDofs& f : cond_.fixed) {
    check_set(f.set, "fixed DOF");
    for (index_t n : f.set.nodes)
      held[n] |= f.dofs;
  }
  for (const ImposedVelocity& v : cond_.velocities) {
    check_set(v.set, "imposed velocity");
    for (index_t n : v.set.nodes)
      held[n] |= v.dofs;
    imposed_v_old_.emplace_back(v.set.nodes.size());
  }
  for (const NodalLoad& l : cond_.loads)
    check_set(l.set, "load");
  auto slots_of = [&](const NodeSet& set) {
    std::vector<std::size_t> q;
    for (index_t n : set.nodes)
      q.push_back(slot(n));
    return q;
  };
  for (const ImposedVelocity& v : cond_.velocities)
    velocity_slots_.push_back(slots_of(v.set));
  for (const NodalLoad& l : cond_.loads)
    load_slots_.push_back(slots_of(l.set));
  if (cond_.plane_strain_axis >= 0) {
    if (cond_.plane_strain_axis > 2)
      throw InputError(
          fmt::format("plane strain axis: expected 0, 1 or 2, got {}", cond_.plane_strain_axis));
    const DofMask bit = static_cast<DofMask>(1u << cond_.plane_strain_axis);
    for (index_t n = 0; n < nn; ++n)
      held[n] |= bit;
  }
  slot_held_.assign(slot_count_, 0);
  for (index_t n = 0; n < nn; ++n)
    slot_held_[slot(n)] = held[n];
  if (!opt_.defer_time_step) {
    stable_ = compute_stable_step(lat_, table_, mass, held);
    dt_ = time_step_by_rule(opt_.step, stable_, table_.ranges().E[1], table_.spec().rho, lat_.L());
  }
  if (!cond_.loads.empty()) {
    px_.assign(slot_count_, 0.0);
    py_.assign(slot_count_, 0.0);
    pz_.assign(slot_count_, 0.0);
  }

  h_.resize(nb);
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fi = lat_.family(f);
    for (index_t b = fi.offset; b < fi.offset + fi.count(); ++b)
      h_[b] = table_.per_bar() ? table_.e_p_bar()[b] : table_.family(f).e_p;
  }
  for (index_t b : precracked) {
    if (b >= nb)
      throw InputError(fmt::format("pre-crack: bar {} does not exist (lattice has {})", b, nb));
    h_[b] = BilinearLaw::kPrecracked;
  }

  // Rows in the order the step visits them: plane by plane (k), and in a plane line by line
  // (j): the bar rows (f, j, k) of every family, then the corner and centre node rows (j, k).
  // A node row needs bar rows of its own line and the line below, in its plane and the plane
  // below, so the bar forces it reads were computed moments before.
  for (const NodeRow& row : node_rows(lat_))
    node_rows_.push_back(row);
  std::stable_sort(node_rows_.begin(), node_rows_.end(), [](const NodeRow& a, const NodeRow& b) {
    return a.k != b.k ? a.k < b.k : a.j < b.j;
  });
  for (index_t k = 0; k <= lat_.nz(); ++k)
    for (index_t j = 0; j <= lat_.ny(); ++j)
      for (int f = 0; f < kFamilies; ++f) {
        const FamilyInfo& fi = lat_.family(f);
        if (k >= fi.nk || j >= fi.nj)
          continue;
        const auto fam = static_cast<Family>(f);
        // Along a row (i running) an edge bar's area factor changes only at i = 0 and
        // i = ni - 1 (EdgeY, EdgeZ: the x faces); inside it is that of i = 1.
        const double inner = lat_.area_factor(fam, std::min<index_t>(1, fi.ni - 1), j, k);
        bar_rows_.push_back({f, j, k, inner, lat_.area_factor(fam, 0, j, k), slot(fi.a.at(0, j, k)),
                             slot(fi.b.at(0, j, k))});
      }
  // The links of every node row, computed once (they cost more to derive than to read), their
  // bar rows (in (k, j, family) order) and intact laws; rows of one kind share their constants.
  std::vector<std::uint32_t> row_at((lat_.nz() + 1ull) * (lat_.ny() + 1ull) * kFamilies, 0);
  row_inv_lp_.resize(bar_rows_.size());
  row_watch_.resize(bar_rows_.size());
  row_first_centre_.resize(bar_rows_.size());
  for (std::size_t r = 0; r < bar_rows_.size(); ++r) {
    const BarRow& row = bar_rows_[r];
    row_at[(row.k * (lat_.ny() + 1ull) + row.j) * kFamilies +
           static_cast<std::size_t>(row.family)] = static_cast<std::uint32_t>(r);
    const double l0 = lat_.family(row.family).l0, e_p = table_.family(row.family).e_p;
    row_inv_lp_[r] = 1.0 / (l0 * (1.0 + e_p));
    const double lw = l0 * (1.0 + 0.5 * e_p); // the watch length (LinkConst)
    row_watch_[r] = lw * lw * row_inv_lp_[r] * row_inv_lp_[r];
    row_first_centre_[r] = row.family >= static_cast<int>(Family::CentreX);
  }
  const auto same = [](const LinkConst& a, const LinkConst& b) {
    return a.rx == b.rx && a.ry == b.ry && a.rz == b.rz && a.k == b.k && a.l0 == b.l0 &&
           a.kl0 == b.kl0 && a.scale == b.scale && a.lw2 == b.lw2 && a.ilo == b.ilo &&
           a.ihi == b.ihi && a.dk == b.dk && a.first_node == b.first_node;
  };
  link_ref_.resize(kMaxRowLinks * node_rows_.size());
  row_kind_.resize(node_rows_.size());
  for (std::size_t r = 0; r < node_rows_.size(); ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat_, node_rows_[r], links, slots_);
    LinkConst kind[kMaxRowLinks]{};
    const std::int64_t n = node_rows_[r].length;
    std::int64_t lo = 0, hi = n;
    for (int l = 0; l < nl; ++l) {
      const RowLink& L = links[l];
      const BarAddress a = lat_.bar_address(static_cast<index_t>(L.bar_base + L.ilo));
      const std::uint32_t br =
          row_at[(a.k * (lat_.ny() + 1ull) + a.j) * kFamilies + static_cast<std::size_t>(a.family)];
      const BarRow& row = bar_rows_[br];
      const FamilyInfo& fi = lat_.family(row.family);
      const double k = table_.family(row.family).k * row.factor;
      const double scale = table_.per_bar() ? 1.0 : row.end_factor / row.factor;
      const double e_p = table_.family(row.family).e_p;
      const double lw = fi.l0 * (1.0 + 0.5 * e_p);
      kind[l] = {
          L.r0.x,
          L.r0.y,
          L.r0.z,
          k,
          fi.l0,
          k * fi.l0,
          scale,
          lw * lw,
          L.ilo,
          L.ihi,
          L.dk,
          lat_.bar_nodes(static_cast<index_t>(L.bar_base + L.ilo))[0] == node_rows_[r].first + L.ilo};
      link_ref_[kMaxRowLinks * r + l] = {L.other_base, br, static_cast<std::int32_t>(L.plane_base)};
      // A first or last bar with a factor of its own needs its lane scaled.
      const std::int64_t own = scale != 1.0 ? 1 : 0;
      lo = std::max(lo, std::int64_t{L.ilo} + own);
      hi = std::min(hi, std::int64_t{L.ihi} - own);
    }
    std::size_t t = 0;
    while (t < row_kinds_.size() &&
           !(row_kinds_[t].n == n && row_kinds_[t].links == nl &&
             std::equal(kind, kind + nl, &link_const_[kMaxRowLinks * t], same)))
      ++t;
    if (t == row_kinds_.size()) {
      // Fewer than 7 links (the corner rows along a box's x edges have 6, rows of a box a
      // module wide fewer): padded to 7 with links no lane has.
      if (nl < 7)
        lo = hi = 0;
      hi = std::max(lo, hi);
      row_kinds_.push_back({n, nl, lo, hi, edge_lanes_.size()});
      link_const_.insert(link_const_.end(), kind, kind + kMaxRowLinks);
      const auto lane = [](std::int64_t at, std::int64_t i) {
        return at >= i && at < i + 8 ? static_cast<std::uint8_t>(1u << (at - i)) : std::uint8_t{0};
      };
      for (std::int64_t i = 0; i < n; i += 8) {
        if (i >= lo && i + 8 <= hi)
          continue;
        for (int l = 0; l < kMaxRowLinks; ++l) {
          const LinkConst& L = kind[l];
          EdgeLanes e{0, 0, 0};
          for (std::int64_t q = std::max(L.ilo, i); q < std::min(L.ihi, i + 8); ++q)
            e.has = static_cast<std::uint8_t>(e.has | (1u << (q - i)));
          if (L.scale != 1.0) {
            e.first = lane(L.ilo, i);
            e.last = lane(L.ihi - 1, i);
          }
          edge_lanes_.push_back(e);
        }
      }
    }
    row_kind_[r] = static_cast<std::uint16_t>(t);
  }
  // Where the portable kernel can take a whole row in one pass, from the bar pass's buffers: a
  // link missing at a row's end reads a zero pad of the plane buffer (s = 0) and a neighbouring
  // slot's finite displacement, so that holds wherever those reads stay inside the lattice's
  // nodes in its own numbering (all rows but the first corner row and the rows that reach the
  // end of the last centre row), which keeps them inside the slots too (a row's slots start
  // and end no earlier than its nodes do).
  row_whole_.assign(node_rows_.size(), 0);
  for (std::size_t r = 0; r < node_rows_.size(); ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat_, node_rows_[r], links);
    // (A row with fewer than 7 links is padded to 7 with a link that no node has; the whole-row
    // pass would read that link's s from the start of the plane buffer.)
    bool whole = nl >= 7;
    for (int l = 0; l < nl; ++l)
      whole = whole && links[l].other_base >= 0 &&
              links[l].other_base + node_rows_[r].length <= std::int64_t{lat_.num_nodes()};
    row_whole_[r] = whole;
  }
  // Rows with imposed-velocity nodes, and where each such node's gathered force is kept.
  imposed_row_.assign(node_rows_.size(), -1);
  {
    std::vector<std::size_t> row_of(nn);
    for (std::size_t r = 0; r < node_rows_.size(); ++r)
      for (index_t i = 0; i < node_rows_[r].length; ++i)
        row_of[node_rows_[r].first + i] = r;
    std::size_t kept = 0;
    for (const ImposedVelocity& v : cond_.velocities)
      for (index_t n : v.set.nodes)
        if (imposed_row_[row_of[n]] < 0) {
          imposed_row_[row_of[n]] = static_cast<std::int64_t>(kept);
          kept += 3 * std::size_t{node_rows_[row_of[n]].length};
        }
    imposed_force_.assign(kept, 0.0);
    for (const ImposedVelocity& v : cond_.velocities) {
      imposed_force_at_.emplace_back();
      imposed_node_row_.emplace_back();
      for (index_t n : v.set.nodes) {
        const NodeRow& row = node_rows_[row_of[n]];
        imposed_force_at_.back().push_back(
            {static_cast<std::size_t>(imposed_row_[row_of[n]]) + (n - row.first), row.length});
        imposed_node_row_.back().push_back(static_cast<std::uint32_t>(row_of[n]));
      }
    }
    imposed_motion_.assign(node_rows_.size(), 0.0);
    condition_motion_.assign(node_rows_.size(), 0.0);
  }
  row_held_.assign(node_rows_.size(), 0);
  for (std::size_t r = 0; r < node_rows_.size(); ++r)
    for (index_t i = 0; i < node_rows_[r].length; ++i)
      row_held_[r] |= held[node_rows_[r].first + i] != 0;
  mark_damaged_rows();
  // Row ranges of each line (j, k), and the lines of each plane k.
  planes_.assign(lat_.nz() + 1ull, {0, 0});
  {
    std::size_t br = 0, nr = 0;
    for (index_t k = 0; k <= lat_.nz(); ++k) {
      planes_[k].line_begin = lines_.size();
      for (index_t j = 0; j <= lat_.ny(); ++j) {
        Line line{br, br, nr, nr};
        while (line.bar_end < bar_rows_.size() && bar_rows_[line.bar_end].k == k &&
               bar_rows_[line.bar_end].j == j)
          ++line.bar_end;
        while (line.node_end < node_rows_.size() && node_rows_[line.node_end].k == k &&
               node_rows_[line.node_end].j == j)
          ++line.node_end;
        br = line.bar_end;
        nr = line.node_end;
        lines_.push_back(line);
      }
      planes_[k].line_end = lines_.size();
    }
  }
  // The intact fast path: nothing is known of the strains or the motion before the first step.
  // (Without AVX-512 it would take a square root and a division for every bar at each end:
  // slower than the bar pass, so it is off.)
  fast_path_ = opt_.intact_at_nodes && !table_.per_bar() && kVectorKernel;
  row_fast_.assign(bar_rows_.size(), 0);
  line_fast_.assign(lines_.size(), 0);
  bar_row_nodes_.resize(bar_rows_.size());
  for (std::size_t r = 0; r < bar_rows_.size(); ++r) {
    const BarRow& row = bar_rows_[r];
    const FamilyInfo& fi = lat_.family(row.family);
    bar_row_nodes_[r] = {static_cast<std::uint32_t>(node_row_of(fi.a.at(0, row.j, row.k))),
                         static_cast<std::uint32_t>(node_row_of(fi.b.at(0, row.j, row.k)))};
  }
  node_row_motion_.assign(node_rows_.size(), kUnknown);
  threads_ = omp_get_max_threads();
  plane_buffers_.resize(3 * static_cast<std::size_t>(threads_));
  for (auto& b : plane_buffers_)
    b.assign(lat_.plane_buffer_size(), 0.0);
  for (const Line& line : lines_) {
    std::size_t n = 0;
    for (std::size_t r = line.bar_begin; r < line.bar_end; ++r)
      n += lat_.family(bar_rows_[r].family).ni;
    line_store_stride_ = std::max(line_store_stride_, n);
  }
  line_stores_.resize(2 * static_cast<std::size_t>(threads_));
  for (auto& b : line_stores_)
    b.assign(planes_.size() * line_store_stride_, 0.0);
  // About 128 KiB of bar forces per block: with the plane below's and the displacements they
  // read, well inside a core's L2 cache (measured on 64^3: 16 lines, 5 to 10 % faster than
  // whole planes on 2 threads; 8 lines slower than 16).
  const auto line_bytes =
      static_cast<std::int64_t>(8 * std::max<std::size_t>(line_store_stride_, 1));
  block_lines_ = opt_.block_lines > 0 ? opt_.block_lines
                                      : std::clamp<std::int64_t>((128 << 10) / line_bytes, 8, 64);
  // fx, fy, fz, a fourth row for the ledger sums and three for the free-DOF factors, each
  // starting on a cache line.
  scratch_stride_ = round_up_to_line(lat_.nx() + 1ull);
  thread_scratch_.resize(static_cast<std::size_t>(threads_));
  for (auto& sc : thread_scratch_)
    sc.resize(8 * scratch_stride_);
  energy_rows_u_.assign(bar_rows_.size(), 0.0);
  energy_rows_d_.assign(bar_rows_.size(), 0.0);
  law_rows_.reserve(bar_rows_.size());
  const std::size_t nrows = node_rows_.size();
  row_damping_.assign(nrows, 0.0);
  row_load_mid_.assign(nrows, 0.0);
  row_load_half_.assign(nrows, 0.0);
  row_kinetic_.assign(nrows, 0.0);
  thread_events_.resize(static_cast<std::size_t>(threads_));
  for (auto& ev : thread_events_)
    ev.reserve(1024);
}

void Simulation::set_velocity(const std::function<Vec3(Vec3)>& v_of_X) {
  for (index_t n = 0; n < lat_.num_nodes(); ++n) {
    const Vec3 v = v_of_X(lat_.position(n));
    const DofMask h = held(n);
    set_half_step_velocity(
        n, {(h & kDofX) ? 0.0 : v.x, (h & kDofY) ? 0.0 : v.y, (h & kDofZ) ? 0.0 : v.z});
  }
}

// A row is "damaged" once any of its bars has a history above e_p (or is pre-cracked);
// intact rows skip reading the history.
void Simulation::mark_damaged_rows() {
  row_damaged_.assign(bar_rows_.size(), 0);
  row_ratio_.assign(bar_rows_.size(), kUnknown);
  row_dissipated_.assign(bar_rows_.size(), 0.0);
  row_history_changed_.assign(bar_rows_.size(), 1); // the histories may all be new
  for (std::size_t r = 0; r < bar_rows_.size(); ++r) {
    const BarRow& row = bar_rows_[r];
    const index_t b0 = lat_.bar(static_cast<Family>(row.family), 0, row.j, row.k);
    for (index_t i = 0; i < lat_.family(row.family).ni; ++i) {
      const index_t b = b0 + i;
      const double ep = table_.per_bar() ? table_.e_p_bar()[b] : table_.family(row.family).e_p;
      if (h_[b] != ep)
        row_damaged_[r] = 1;
    }
  }
}

void Simulation::set_time_step(const StableStep& stable, double dt) {
  if (step_ != 0)
    throw InputError("time step: dt can only change before the first step");
  stable_ = stable;
  set_time_step(dt);
}

void Simulation::set_time_step(double dt) {
  if (step_ != 0)
    throw InputError("time step: dt can only change before the first step");
  if (!(dt > 0.0) || dt > stable_.dt)
    throw InputError(fmt::format("time step: expected 0 < dt <= {:.4g} s (the stable limit), "
                                 "got {:g}",
                                 stable_.dt, dt));
  for (std::size_t q = 0; q < slot_count_; ++q) {
    // (Before a deferred dt is first set, the nodes are at rest.)
    const double vx = dt_ > 0.0 ? (ux_[q] - wx_[q]) / dt_ : 0.0;
    const double vy = dt_ > 0.0 ? (uy_[q] - wy_[q]) / dt_ : 0.0;
    const double vz = dt_ > 0.0 ? (uz_[q] - wz_[q]) / dt_ : 0.0;
    wx_[q] = ux_[q] - dt * vx;
    wy_[q] = uy_[q] - dt * vy;
    wz_[q] = uz_[q] - dt * vz;
  }
  dt_ = dt;
}

// v_{n-1/2} is (u_n - u_{n-1}) / dt: the state is two displacement fields.
Vec3 Simulation::half_step_velocity(index_t node) const {
  const std::size_t q = slot(node);
  return {(ux_[q] - wx_[q]) / dt_, (uy_[q] - wy_[q]) / dt_, (uz_[q] - wz_[q]) / dt_};
}

void Simulation::set_half_step_velocity(index_t node, Vec3 v) {
  const std::size_t q = slot(node);
  wx_[q] = ux_[q] - dt_ * v.x;
  wy_[q] = uy_[q] - dt_ * v.y;
  wz_[q] = uz_[q] - dt_ * v.z;
}

std::size_t Simulation::node_row_of(index_t node) const {
  const NodeAddress a = lat_.node_address(node);
  // Line (j, k) holds its corner row, then its centre row if it has one.
  return lines_[a.j + (lat_.ny() + 1ull) * a.k].node_begin + (a.centre ? 1 : 0);
}

void Simulation::forget_motion(index_t first, index_t count) {
  for_each_run(first, count, [&](std::size_t, index_t n0, index_t) {
    node_row_motion_[node_row_of(n0)] = kUnknown;
  });
}

void Simulation::set_displacement(index_t node, Vec3 u) {
  forget_motion(node, 1);
  const Vec3 v = half_step_velocity(node);
  const std::size_t q = slot(node);
  ux_[q] = u.x;
  uy_[q] = u.y;
  uz_[q] = u.z;
  set_half_step_velocity(node, v);
}

void Simulation::append_displacements(index_t first, index_t count, std::vector<double>& out,
                                      bool previous) const {
  for (const AlignedVector<double>* u : {&ux_, &uy_, &uz_, &wx_, &wy_, &wz_})
    if ((u == &wx_ || u == &wy_ || u == &wz_) == previous)
      for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
        out.insert(out.end(), u->begin() + q, u->begin() + q + run);
      });
}

void Simulation::assign_displacements(index_t first, index_t count, const double* in,
                                      bool previous) {
  if (!previous)
    forget_motion(first, count);
  for (AlignedVector<double>* u : {&ux_, &uy_, &uz_, &wx_, &wy_, &wz_})
    if ((u == &wx_ || u == &wy_ || u == &wz_) == previous)
      for_each_run(first, count, [&](std::size_t q, index_t, index_t run) {
        std::copy(in, in + run, u->begin() + q);
        in += run;
      });
}

void Simulation::append_histories(index_t first, index_t count, std::vector<double>& out) const {
  out.insert(out.end(), h_.begin() + first, h_.begin() + first + count);
}

void Simulation::assign_histories(index_t first, index_t count, const double* in) {
  std::copy(in, in + count, h_.begin() + first);
}

void Simulation::restore_progress(std::uint64_t step, const Ledger::State& ledger,
                                  const EnergyReport& report, std::vector<Event> pending) {
  step_ = step;
  ledger_.set_state(ledger);
  report_ = report;
  for (auto& ev : thread_events_)
    ev.clear();
  thread_events_[0] = std::move(pending);
  mark_damaged_rows();
}

// ---------------------------------------------------------------------------------------
// Bar pass: s = F / l for every bar, from u_n and the history; history and events.

namespace {

struct RowView {
  const double *uax, *uay, *uaz, *ubx, *uby, *ubz;
  double *s, *h;
};

// The common path of a row: no history change. Returns true if some bar of the row went
// past its history (softening further or breaking), to be handled by the slow path.
// `k_row` is E A / l0 times the area factor; per-bar arrays replace it when present.
// `Intact`: every bar of the row still has h = e_p (no history to read). With `Energy`, also
// sum w s l (l - l0) over the row into *energy (twice the elastic energy: F e l0, the area
// under the secant), w = 1 for inner bars and `end_scale` for the first and last (the factor
// the caller applies to their forces afterwards).
// (Inlined where it is called, as intact_row_kernel.)
template <bool PerBar, bool Intact, bool Energy = false>
[[gnu::always_inline]] inline bool
bar_row_kernel(index_t n, const RowView& r, Vec3 d0, double l0, double k_row, double e_p,
               double e_r, const double* __restrict k_bar, const double* __restrict ep_bar,
               const double* __restrict er_bar, double end_scale = 1.0, double* energy = nullptr) {
  const double inv_l0 = 1.0 / l0;
  int past = 0; // an int, not a bool: GCC vectorises only arithmetic reductions
  double sum = 0.0;
  // The row's pointers in locals: read through `r` in the loop, GCC 12 loads them anew for
  // every bar and gathers the rows lane by lane.
  const double* __restrict uax = r.uax;
  const double* __restrict uay = r.uay;
  const double* __restrict uaz = r.uaz;
  const double* __restrict ubx = r.ubx;
  const double* __restrict uby = r.uby;
  const double* __restrict ubz = r.ubz;
  const double* __restrict hr = r.h;
  double* __restrict sr = r.s;
  const auto nn = static_cast<std::int64_t>(n);
  // bar(i): 1 if bar i goes past its history, and with Energy its term of the sum; the loops
  // name only the reductions they have (GCC 12 vectorises neither with one that stays unused).
  struct Term {
    int past;
    double energy;
  };
  const auto bar = [&](std::int64_t i) {
    const double dx = d0.x + (ubx[i] - uax[i]);
    const double dy = d0.y + (uby[i] - uay[i]);
    const double dz = d0.z + (ubz[i] - uaz[i]);
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double e = (l - l0) * inv_l0;
    const double ep = PerBar ? ep_bar[i] : e_p;
    const double h = Intact ? ep : hr[i];
    const double er = PerBar ? er_bar[i] : e_r;
    const double k = PerBar ? k_bar[i] : k_row;
    const double m = e > h ? e : h;
    const bool tension = e > 0.0;
    // Secant factor g = e_p (e_r - m) / ((e_r - e_p) m), 1 in compression (see BilinearLaw).
    const double num_t = ep * (er - m);
    const double num = tension ? (num_t > 0.0 ? num_t : 0.0) : 1.0;
    const double den = tension ? (er - ep) * m : 1.0;
    const double si = k * (l - l0) * num / (l * den);
    sr[i] = si;
    Term t{e > h ? 1 : 0, 0.0};
    if constexpr (Energy)
      t.energy = (i == 0 || i + 1 == nn ? end_scale : 1.0) * si * l * (l - l0);
    return t;
  };
  if constexpr (Energy) {
    // (Both sums in doubles: GCC 12 vectorises no loop with an int and a double reduction.)
    double passed = 0.0;
#pragma omp simd reduction(+ : passed, sum)
    for (std::int64_t i = 0; i < nn; ++i) {
      const Term t = bar(i);
      passed += t.past;
      sum += t.energy;
    }
    past = passed > 0.0;
  } else {
#pragma omp simd reduction(+ : past)
    for (std::int64_t i = 0; i < nn; ++i)
      past += bar(i).past;
  }
  if constexpr (Energy)
    *energy = sum;
  return past > 0;
}

#if defined(__AVX512F__)
// 1 / sqrt(x) to about an ulp without the divider: the 14-bit estimate y0, then one step of
// third order, y = y0 (1 + e/2 + 3e^2/8 + 5e^3/16) with e = 1 - x y0^2: the series of
// (1 - e)^(-1/2) cut after its e^3 term, |e| < 2^-14 leaving 35 e^4 / 128 < 2^-57 (two Newton
// steps would take one operation more). The bar pass's intact kernel and the node kernel both
// take it, so both give the same bits.
inline __m512d inv_sqrt(__m512d x) {
  const __m512d y = _mm512_rsqrt14_pd(x);
  const __m512d e = _mm512_fnmadd_pd(_mm512_mul_pd(x, y), y, _mm512_set1_pd(1.0));
  const __m512d p =
      _mm512_fmadd_pd(_mm512_fmadd_pd(_mm512_set1_pd(5.0 / 16.0), e, _mm512_set1_pd(3.0 / 8.0)), e,
                      _mm512_set1_pd(0.5));
  return _mm512_fmadd_pd(_mm512_mul_pd(y, e), p, y);
}

// acc + w (l - l0)^2 for the lanes m of a vector of intact bars, with u the relative
// displacement (d = d0 + u), l^2 and y = 1 / l as computed for their force, w = end_scale on
// the lanes `ends` (a bar row's first and last bars) and 1 elsewhere. l - l0 is
// (l^2 - l0^2) / (l + l0) with l^2 - l0^2 = u . (u + 2 d0): no cancellation, and exactly 0 for
// an unstrained bar; the reciprocal from the 14-bit estimate and two Newton steps. The bar
// pass's intact kernel and the node kernel both take it, so both give the same bits.
inline __m512d add_intact_energy(__m512d acc, __m512d ux, __m512d uy, __m512d uz, Vec3 d0,
                                 __m512d l2, __m512d y, double l0, __mmask8 m, __mmask8 ends,
                                 double end_scale) {
  const __m512d vx = _mm512_set1_pd(d0.x), vy = _mm512_set1_pd(d0.y), vz = _mm512_set1_pd(d0.z);
  const __m512d v2 = _mm512_set1_pd(2.0);
  const __m512d q =
      _mm512_fmadd_pd(ux, _mm512_add_pd(ux, _mm512_add_pd(vx, vx)),
                      _mm512_fmadd_pd(uy, _mm512_add_pd(uy, _mm512_add_pd(vy, vy)),
                                      _mm512_mul_pd(uz, _mm512_add_pd(uz, _mm512_add_pd(vz, vz)))));
  const __m512d den = _mm512_fmadd_pd(l2, y, _mm512_set1_pd(l0));
  __m512d rc = _mm512_rcp14_pd(den);
  rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
  rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
  const __m512d dl = _mm512_maskz_mul_pd(m, q, rc);
  const __m512d w = _mm512_mask_blend_pd(ends, _mm512_set1_pd(1.0), _mm512_set1_pd(end_scale));
  return _mm512_fmadd_pd(_mm512_mul_pd(w, dl), dl, acc);
}
#endif

// The common case: a row of intact bars with uniform constants, none past e_p. Then
// s = k (l - l0) / l = k - k l0 / l, and the test e > e_p is l^2 > (l0 (1 + e_p))^2, so the
// row needs 1 / sqrt(l^2) and nothing else: with AVX-512 it comes from inv_sqrt, which keeps
// the divider free. Returns true if some bar may be past e_p (the caller then redoes the row
// with the general kernel). With `Energy`, also sum w (l - l0)^2 over the row into *energy,
// w = 1 for inner bars and `end_scale` for the first and last (their area factor over the
// row's).
#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip these warnings on _mm512_maskz_loadu_pd, _mm512_rsqrt14_pd,
// _mm512_rcp14_pd and _mm512_reduce_max_pd (a known false alarm: their unused pass-through
// operand).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
// (Inlined where it is called: GCC 12 does not vectorise the portable loop's reductions in a
// copy of its own.)
template <bool Energy>
[[gnu::always_inline]] inline bool
intact_row_kernel(index_t n, const RowView& r, Vec3 d0, double l0, double k, double e_p,
                  double end_scale, double* energy, double& l2_max) {
  // Slightly below the exact threshold, so that a bar at e_p to within rounding is handed to
  // the general kernel, whose strain test is the reference.
  const double lp2 = l0 * l0 * (1.0 + e_p) * (1.0 + e_p) * (1.0 - 1e-12);
#if defined(__AVX512F__)
  const __m512d vx = _mm512_set1_pd(d0.x), vy = _mm512_set1_pd(d0.y), vz = _mm512_set1_pd(d0.z);
  const __m512d vk = _mm512_set1_pd(k), vkl0 = _mm512_set1_pd(k * l0);
  const __m512d vlp2 = _mm512_set1_pd(lp2);
  __m512d acc = _mm512_setzero_pd(), top = _mm512_setzero_pd();
  __mmask8 past = 0;
  // Whole vectors with plain loads and stores, the row's tail (n not a multiple of 8) masked.
  const auto vector = [&]<bool Tail>(index_t i, __mmask8 m) {
    const auto load = [m](const double* p) {
      return Tail ? _mm512_maskz_loadu_pd(m, p) : _mm512_loadu_pd(p);
    };
    const __m512d ux = _mm512_sub_pd(load(r.ubx + i), load(r.uax + i));
    const __m512d uy = _mm512_sub_pd(load(r.uby + i), load(r.uay + i));
    const __m512d uz = _mm512_sub_pd(load(r.ubz + i), load(r.uaz + i));
    const __m512d dx = _mm512_add_pd(vx, ux), dy = _mm512_add_pd(vy, uy),
                  dz = _mm512_add_pd(vz, uz);
    const __m512d l2 = _mm512_fmadd_pd(dx, dx, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dz, dz)));
    const __m512d y = inv_sqrt(l2);
    const __m512d s = _mm512_fnmadd_pd(vkl0, y, vk);
    if constexpr (Tail) {
      _mm512_mask_storeu_pd(r.s + i, m, s);
      past |= _mm512_mask_cmp_pd_mask(m, l2, vlp2, _CMP_GT_OQ);
      top = _mm512_mask_max_pd(top, m, top, l2);
    } else {
      _mm512_storeu_pd(r.s + i, s);
      past |= _mm512_cmp_pd_mask(l2, vlp2, _CMP_GT_OQ);
      top = _mm512_max_pd(top, l2);
    }
    if constexpr (Energy) {
      // Zero beyond the row's end, weighted at its ends.
      __mmask8 ends = 0;
      if (i == 0)
        ends |= 1;
      if (n - 1 - i < 8)
        ends |= static_cast<__mmask8>(1u << (n - 1 - i));
      acc = add_intact_energy(acc, ux, uy, uz, d0, l2, y, l0, m, ends, end_scale);
    }
  };
  index_t i = 0;
  for (; i + 8 <= n; i += 8)
    vector.template operator()<false>(i, 0xFF);
  if (i < n)
    vector.template operator()<true>(i, static_cast<__mmask8>((1u << (n - i)) - 1u));
  if constexpr (Energy)
    *energy = _mm512_reduce_add_pd(acc);
  l2_max = _mm512_reduce_max_pd(top);
  return past != 0;
#else
  int past = 0;
  double sum = 0.0;
  // bar(i) gives 1 if bar i is past e_p, and with Energy its term of the sum; the loops name
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
    r.s[i] = k - k * l0 / l;
    Term t{l2 > lp2 ? 1 : 0, 0.0};
    if constexpr (Energy) { // as above
      const double dl =
          (ux * (ux + 2 * d0.x) + uy * (uy + 2 * d0.y) + uz * (uz + 2 * d0.z)) / (l + l0);
      t.energy = (i == 0 || i + 1 == n ? end_scale : 1.0) * dl * dl;
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

[[gnu::always_inline]] inline bool intact_row_forces(index_t n, const RowView& r, Vec3 d0,
                                                     double l0, double k, double e_p,
                                                     double& l2_max) {
  return intact_row_kernel<false>(n, r, d0, l0, k, e_p, 1.0, nullptr, l2_max);
}
[[gnu::always_inline]] inline bool intact_row_forces_energy(index_t n, const RowView& r, Vec3 d0,
                                                            double l0, double k, double e_p,
                                                            double end_scale, double* energy,
                                                            double& l2_max) {
  return intact_row_kernel<true>(n, r, d0, l0, k, e_p, end_scale, energy, l2_max);
}

} // namespace

// A bar's length after this step's motion is at most its length now plus the motion of its
// two nodes: l_{n+1} <= l_n + |u_{n+1} - u_n|_a + |u_{n+1} - u_n|_b. At the start of step n+1
// the row knows the largest (l_n / l_p)^2 of its bars (row_ratio_, measured by whichever pass
// computed them at step n) and its node rows' largest motion in step n (node_row_motion_), so
// if sqrt(ratio) + (motion_a + motion_b) / l_p stays below 1 no bar of the row can pass e_p,
// and the intact law alone gives its force. The margin of 1e-9 covers the rounding of those
// sums (a few units of 1e-16) and keeps the bars clear of the intact kernel's own threshold,
// l_p^2 (1 - 1e-12). An unknown ratio or motion is infinite, which fails the test.
bool Simulation::bar_row_stays_intact(std::size_t r) const {
  constexpr double kMargin = 1.0 - 1e-9;
  const auto [a, b] = bar_row_nodes_[r];
  // sqrt(ratio) + m <= margin, in squares (m <= margin first, which also fails on a NaN).
  const double m = (node_row_motion_[a] + node_row_motion_[b]) * row_inv_lp_[r];
  return !row_damaged_[r] && m <= kMargin && row_ratio_[r] <= (kMargin - m) * (kMargin - m);
}

void Simulation::bar_rows(std::size_t line, double* s_plane, bool energies) {
  const std::size_t begin = lines_[line].bar_begin, end = lines_[line].bar_end;
  const bool per_bar = table_.per_bar();
  const double* kb = per_bar ? table_.k_bar().data() : nullptr;
  const double* epb = per_bar ? table_.e_p_bar().data() : nullptr;
  const double* erb = per_bar ? table_.e_r_bar().data() : nullptr;
  const std::uint64_t step = step_;
  const bool fast = fast_path_;
  {
    std::vector<Event>& events = thread_events_[static_cast<std::size_t>(omp_get_thread_num())];
    bool all_fast = true;
    for (std::size_t r = begin; r < end; ++r) {
      row_fast_[r] = fast && bar_row_stays_intact(r);
      all_fast = all_fast && row_fast_[r];
    }
    line_fast_[line] = all_fast;
    for (std::size_t r = begin; r < end; ++r) {
      if (row_fast_[r])
        continue;
      const BarRow& row = bar_rows_[r];
      const FamilyInfo& fi = lat_.family(row.family);
      const FamilyMaterial& mat = table_.family(row.family);
      const index_t b0 = lat_.bar(static_cast<Family>(row.family), 0, row.j, row.k);
      const std::size_t a0 = row.a_slot, c0 = row.b_slot;
      const RowView v{ux_.data() + a0,
                      uy_.data() + a0,
                      uz_.data() + a0,
                      ux_.data() + c0,
                      uy_.data() + c0,
                      uz_.data() + c0,
                      s_plane + fi.plane_offset + std::size_t{fi.plane_stride} * row.j,
                      h_.data() + b0};
      const index_t n = fi.ni;
      const bool intact = !row_damaged_[r];
      bool past;
      // On a report step the kernels also give the row's elastic energy, its displacements
      // still in cache: the intact kernel sum w (l - l0)^2, the others sum w s l (l - l0).
      double intact_sum = 0.0, law_sum = 0.0;
      const double k = mat.k * row.factor, scale = per_bar ? 1.0 : row.end_factor / row.factor;
      // The general kernel; a material that varies per bar has its area factors in k_bar.
      const auto general = [&](auto per_bar_c, auto intact_c) {
        constexpr bool P = decltype(per_bar_c)::value, I = decltype(intact_c)::value;
        const double* kr = P ? kb + b0 : nullptr;
        const double* epr = P ? epb + b0 : nullptr;
        const double* err = P ? erb + b0 : nullptr;
        return energies
                   ? bar_row_kernel<P, I, true>(n, v, fi.d0, fi.l0, k, mat.e_p, mat.e_r, kr, epr,
                                                err, scale, &law_sum)
                   : bar_row_kernel<P, I>(n, v, fi.d0, fi.l0, k, mat.e_p, mat.e_r, kr, epr, err);
      };
      using yes = std::true_type;
      using no = std::false_type;
      bool by_law = true;
      if (per_bar) {
        past = intact ? general(yes{}, yes{}) : general(yes{}, no{});
      } else {
        double l2_max = kUnknown;
        past = intact && (energies ? intact_row_forces_energy(n, v, fi.d0, fi.l0, k, mat.e_p, scale,
                                                              &intact_sum, l2_max)
                                   : intact_row_forces(n, v, fi.d0, fi.l0, k, mat.e_p, l2_max));
        row_ratio_[r] = l2_max * (row_inv_lp_[r] * row_inv_lp_[r]);
        by_law = !intact || past;
        if (by_law)
          past = general(no{}, no{});
        if (row.end_factor != row.factor) {
          v.s[0] *= scale;
          v.s[n - 1] *= scale;
        }
        if (energies && !by_law)
          energy_rows_u_[r] = 0.5 * k * intact_sum; // U = k (l - l0)^2 / 2, area factors in w
      }
      if (energies && by_law)
        energy_rows_u_[r] = 0.5 * law_sum;
      if (!past)
        continue;
      // Slow path: some bar strained past its history. Recompute its strain, raise the
      // history and log the state changes. The force already used max(h, e), so it is
      // unchanged by the update.
      for (index_t i = 0; i < n; ++i) {
        const double dx = fi.d0.x + (v.ubx[i] - v.uax[i]);
        const double dy = fi.d0.y + (v.uby[i] - v.uay[i]);
        const double dz = fi.d0.z + (v.ubz[i] - v.uaz[i]);
        const double e = (std::sqrt(dx * dx + dy * dy + dz * dz) - fi.l0) / fi.l0;
        const double h = v.h[i];
        if (!(e > h))
          continue;
        const double ep = per_bar ? epb[b0 + i] : mat.e_p;
        const double er = per_bar ? erb[b0 + i] : mat.e_r;
        if (h <= ep && e > ep)
          events.push_back({b0 + i, BarState::Softening, step});
        if (h < er && e >= er)
          events.push_back({b0 + i, BarState::Broken, step});
        v.h[i] = e;
        row_damaged_[r] = 1;
        row_history_changed_[r] = 1;
      }
    }
  }
}
// (The diagnostic pragmas above also cover bar_rows, where GCC inlines the kernel.)
#pragma GCC diagnostic pop

namespace {

// What the node kernel reads and writes besides the links: every node's u_n (by slot), the
// row's own, the row's forces (scratch rows, when the kernel does not integrate), and for the
// node update in the kernel u_{n-1} (overwritten by u_{n+1}), 1 / m, the held DOF and the
// integration's constants.
struct NodeRowArgs {
  const double *ux_all, *uy_all, *uz_all, *ux, *uy, *uz;
  double *fx, *fy, *fz, *wx, *wy, *wz;
  const double* im;
  const DofMask* held;
  double dt, c1, c2, inv_dt;
  double* fs; // one more scratch row (the portable kernel's running sums of s)
};

// The links of a row that mix the two ways: per link, whether it is fast and, if not, where the
// bar pass put its bars' forces.
struct MixedLinks {
  const double* s[kMaxRowLinks];
  bool fast[kMaxRowLinks];
};

// The forces on the nodes [0, n) of a row: f_i = sum over the links, in link order, of
// s (r0 + (u_other - u_i)). Without Integrate they go to the scratch rows fx, fy, fz for i in
// [0, n rounded up to 8). Returns whether some fast link's bar whose first node is the row's
// is longer than its watch length.
//
// A fast link (all of them with AllFast, else those `mixed` marks) computes s with the
// operations of the bar pass's intact kernel; the others read it from the bar pass's buffer.
// From a bar's second node the relative displacement and the reference vector are exactly
// minus those from its first (a difference and a sum negate exactly), so l^2 and s are the
// same bits at both ends, and the same as the bar pass would have written to the buffer: every
// force sum is the same bits whichever way each link is taken. Vectors of 8 nodes inside
// [lo, hi) have every link on every lane and no end bar to scale; the others mask their lanes.
#if defined(__AVX512F__)
#pragma GCC diagnostic push
// GCC 12's AVX-512 headers: the same false alarms as at intact_row_kernel, here also as
// -Wuninitialized (_mm512_setzero_pd, _mm512_maskz_mov_pd).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
template <int NL, bool AllFast, bool Edge, bool Integrate, bool Held, bool Energy>
inline void node_vector(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                        const EdgeLanes* lanes, std::int64_t i, const NodeRowArgs& a, __mmask8& hot,
                        __m512d& moved, __m512d* energy) {
  const __m512d ax = _mm512_load_pd(a.ux + i), ay = _mm512_load_pd(a.uy + i),
                az = _mm512_load_pd(a.uz + i);
  __m512d gx = _mm512_setzero_pd(), gy = _mm512_setzero_pd(), gz = _mm512_setzero_pd();
#pragma GCC unroll 14
  for (int l = 0; l < NL; ++l) {
    const LinkConst& L = c[l];
    const __mmask8 m = Edge ? lanes[l].has : 0xFF;
    const auto load = [m](const double* p) {
      return Edge ? _mm512_maskz_loadu_pd(m, p) : _mm512_loadu_pd(p);
    };
    const std::int64_t o = ref[l].other + i;
    const __m512d ux = _mm512_sub_pd(load(a.ux_all + o), ax),
                  uy = _mm512_sub_pd(load(a.uy_all + o), ay),
                  uz = _mm512_sub_pd(load(a.uz_all + o), az);
    const __m512d dx = _mm512_add_pd(_mm512_set1_pd(L.rx), ux),
                  dy = _mm512_add_pd(_mm512_set1_pd(L.ry), uy),
                  dz = _mm512_add_pd(_mm512_set1_pd(L.rz), uz);
    __m512d s;
    if (AllFast || mixed->fast[l]) {
      // As intact_row_kernel: s = k - k l0 / l.
      const __m512d l2 = _mm512_fmadd_pd(dx, dx, _mm512_fmadd_pd(dy, dy, _mm512_mul_pd(dz, dz)));
      const __m512d y = inv_sqrt(l2);
      s = _mm512_fnmadd_pd(_mm512_set1_pd(L.kl0), y, _mm512_set1_pd(L.k));
      // A report step's elastic energy of the bars whose first nodes are the row's, as the
      // intact kernel sums it: the same vectors of the same bar row, from u = u_b - u_a.
      if constexpr (Energy)
        if (L.first_node)
          energy[l] = add_intact_energy(energy[l], ux, uy, uz, Vec3{L.rx, L.ry, L.rz}, l2, y, L.l0,
                                        m, Edge ? lanes[l].first | lanes[l].last : 0, L.scale);
      if constexpr (Edge) {
        // The bar row's first and last bars (node i = ilo and ihi - 1) carry their own factor.
        const __m512d sc = _mm512_set1_pd(L.scale);
        s = _mm512_mask_mul_pd(s, lanes[l].first, s, sc);
        s = _mm512_mask_mul_pd(s, lanes[l].last, s, sc);
        s = _mm512_maskz_mov_pd(m, s);
        if (L.first_node)
          hot |= _mm512_mask_cmp_pd_mask(m, l2, _mm512_set1_pd(L.lw2), _CMP_GT_OQ);
      } else if (L.first_node) {
        hot |= _mm512_cmp_pd_mask(l2, _mm512_set1_pd(L.lw2), _CMP_GT_OQ);
      }
    } else {
      s = load(mixed->s[l] + i);
    }
    gx = _mm512_fmadd_pd(s, dx, gx);
    gy = _mm512_fmadd_pd(s, dy, gy);
    gz = _mm512_fmadd_pd(s, dz, gz);
  }
  if constexpr (Integrate) {
    // integrate_row's update without damping, loads or sums, with its operations in its order.
    const __m512d im = _mm512_load_pd(a.im + i);
    const __m512d inv_dt = _mm512_set1_pd(a.inv_dt), c1 = _mm512_set1_pd(a.c1),
                  c2 = _mm512_set1_pd(a.c2), dt = _mm512_set1_pd(a.dt);
    __m512i bits = _mm512_setzero_si512();
    if constexpr (Held)
      bits = _mm512_cvtepu8_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(a.held + i)));
    const auto update = [&](double* w, __m512d u, __m512d g, long long dof) {
      const __m512d o = _mm512_mul_pd(_mm512_sub_pd(u, _mm512_load_pd(w + i)), inv_dt);
      __m512d v = _mm512_add_pd(_mm512_mul_pd(c1, o), _mm512_mul_pd(_mm512_mul_pd(c2, g), im));
      if constexpr (Held) {
        const __mmask8 free = _mm512_testn_epi64_mask(bits, _mm512_set1_epi64(dof));
        v = _mm512_mul_pd(_mm512_mask_blend_pd(free, _mm512_setzero_pd(), _mm512_set1_pd(1.0)), v);
      }
      const __m512d e = _mm512_add_pd(u, _mm512_mul_pd(dt, v));
      _mm512_store_pd(w + i, e);
      return _mm512_sub_pd(e, u);
    };
    const __m512d qx = update(a.wx, ax, gx, kDofX), qy = update(a.wy, ay, gy, kDofY),
                  qz = update(a.wz, az, gz, kDofZ);
    moved = _mm512_max_pd(moved,
                          _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(qx, qx), _mm512_mul_pd(qy, qy)),
                                        _mm512_mul_pd(qz, qz)));
  } else {
    _mm512_store_pd(a.fx + i, gx);
    _mm512_store_pd(a.fy + i, gy);
    _mm512_store_pd(a.fz + i, gz);
  }
}

// With Integrate, the row's u_{n+1} too (into w) and its largest motion |u_{n+1} - u_n|^2
// into `moved` (the spare slots of the row hold zeros, and move by 0).
// With Energy, also the sum over the row of w (l - l0)^2 of each fast link's bars whose first
// nodes are the row's, into energy[l] (see add_intact_energy).
template <int NL, bool AllFast, bool Integrate, bool Held, bool Energy>
bool node_row_forces(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                     const EdgeLanes* lanes, std::int64_t n, std::int64_t lo, std::int64_t hi,
                     const NodeRowArgs& a, double& moved, double* energy) {
  __mmask8 hot = 0;
  __m512d q = _mm512_setzero_pd();
  __m512d sums[NL];
  if constexpr (Energy)
    for (int l = 0; l < NL; ++l)
      sums[l] = _mm512_setzero_pd();
  for (std::int64_t i = 0; i < n; i += 8) {
    if (i >= lo && i + 8 <= hi) {
      node_vector<NL, AllFast, false, Integrate, Held, Energy>(c, ref, mixed, lanes, i, a, hot, q,
                                                               sums);
    } else {
      node_vector<NL, AllFast, true, Integrate, Held, Energy>(c, ref, mixed, lanes, i, a, hot, q,
                                                              sums);
      lanes += kMaxRowLinks;
    }
  }
  if constexpr (Energy)
    for (int l = 0; l < NL; ++l)
      energy[l] = _mm512_reduce_add_pd(sums[l]);
  moved = _mm512_reduce_max_pd(q);
  return hot != 0;
}
#pragma GCC diagnostic pop
#else
// Without AVX-512 (where the fast path is off: SolverOptions::intact_at_nodes). Inside
// [lo, hi), where every node has every link, the links in chunks of four over the whole range
// (GCC vectorises each chunk; a single pass over 14 links would need more pointers than there
// are registers), as sum s (r0 + u_other) - u_i sum s, two operations fewer per link than the
// sum of s (r0 + (u_other - u_i)) taken link by link outside it. A fast link, should one be
// asked for, computes s as the portable intact kernel does, and makes the row go link by link.
// The node update is integrate_row's.
template <int B, int E, bool First, bool Last>
void portable_chunk(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                    std::int64_t lo, std::int64_t hi, const NodeRowArgs& a, double* fs) {
  constexpr int N = E - B;
  const double *s_[N], *x_[N], *y_[N], *z_[N];
  double rx_[N], ry_[N], rz_[N];
  for (int l = 0; l < N; ++l) {
    s_[l] = mixed->s[B + l];
    x_[l] = a.ux_all + ref[B + l].other;
    y_[l] = a.uy_all + ref[B + l].other;
    z_[l] = a.uz_all + ref[B + l].other;
    rx_[l] = c[B + l].rx;
    ry_[l] = c[B + l].ry;
    rz_[l] = c[B + l].rz;
  }
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  const double* __restrict ux = a.ux;
  const double* __restrict uy = a.uy;
  const double* __restrict uz = a.uz;
#pragma omp simd
  for (std::int64_t i = lo; i < hi; ++i) {
    double gx = First ? 0.0 : fx[i], gy = First ? 0.0 : fy[i], gz = First ? 0.0 : fz[i],
           st = First ? 0.0 : fs[i];
#pragma GCC unroll 4
    for (int l = 0; l < N; ++l) {
      const double t = s_[l][i];
      gx += t * (rx_[l] + x_[l][i]);
      gy += t * (ry_[l] + y_[l][i]);
      gz += t * (rz_[l] + z_[l][i]);
      st += t;
    }
    if constexpr (Last) {
      fx[i] = gx - st * ux[i];
      fy[i] = gy - st * uy[i];
      fz[i] = gz - st * uz[i];
    } else {
      fx[i] = gx;
      fy[i] = gy;
      fz[i] = gz;
      fs[i] = st;
    }
  }
}

template <int NL, bool AllFast, bool Integrate, bool Held, bool Energy>
bool node_row_forces(const LinkConst* c, const LinkRef* ref, const MixedLinks* mixed,
                     const EdgeLanes*, std::int64_t n, std::int64_t lo, std::int64_t hi,
                     const NodeRowArgs& a, double&, double*) {
  static_assert(!Integrate, "the portable kernel gives forces only");
  bool any_fast = AllFast;
  for (int l = 0; l < NL; ++l)
    any_fast = any_fast || mixed->fast[l];
  if (any_fast)
    lo = hi = 0;
  if (hi > lo) {
    constexpr int C = 4;
    auto chunk = [&]<int B>(auto self, std::integral_constant<int, B>) {
      constexpr int E = B + C < NL ? B + C : NL;
      portable_chunk<B, E, B == 0, E == NL>(c, ref, mixed, lo, hi, a, a.fs);
      if constexpr (E < NL)
        self(self, std::integral_constant<int, E>{});
    };
    chunk(chunk, std::integral_constant<int, 0>{});
  }
  double* __restrict fx = a.fx;
  double* __restrict fy = a.fy;
  double* __restrict fz = a.fz;
  const double* __restrict ux = a.ux;
  const double* __restrict uy = a.uy;
  const double* __restrict uz = a.uz;
  for (const auto& [e0, e1] : {std::pair{std::int64_t{0}, lo}, std::pair{hi, n}})
    for (std::int64_t i = e0; i < e1; ++i)
      fx[i] = fy[i] = fz[i] = 0.0;
  int hot = 0;
  for (int l = 0; l < NL; ++l) {
    const LinkConst& L = c[l];
    const double* __restrict ox = a.ux_all + ref[l].other;
    const double* __restrict oy = a.uy_all + ref[l].other;
    const double* __restrict oz = a.uz_all + ref[l].other;
    const bool fast = AllFast || mixed->fast[l];
    const double* __restrict sb = fast ? nullptr : mixed->s[l];
    for (const auto& [e0, e1] :
         {std::pair{L.ilo, std::min(L.ihi, lo)}, std::pair{std::max(L.ilo, hi), L.ihi}}) {
#pragma omp simd reduction(+ : hot)
      for (std::int64_t i = e0; i < e1; ++i) {
        const double dx = L.rx + (ox[i] - ux[i]), dy = L.ry + (oy[i] - uy[i]),
                     dz = L.rz + (oz[i] - uz[i]);
        double s;
        if (fast) {
          const double l2 = dx * dx + dy * dy + dz * dz;
          s = L.k - L.kl0 / std::sqrt(l2);
          if (i == L.ilo)
            s *= L.scale;
          if (i == L.ihi - 1)
            s *= L.scale;
          if (L.first_node)
            hot += l2 > L.lw2 ? 1 : 0;
        } else {
          s = sb[i];
        }
        fx[i] += s * dx;
        fy[i] += s * dy;
        fz[i] += s * dz;
      }
    }
  }
  return hot > 0;
}
#endif

} // namespace

// ---------------------------------------------------------------------------------------
// Node pass: gather, integrate, and the per-row sums the energy balance needs.

namespace {

struct IntegrationConstants {
  double dt, c1, c2, alpha;
};

// v_{n+1/2} and u_{n+1} of one row of nodes from the gathered forces, and (with Sums) the
// row's contributions to the energy ledger. A separate function so that every array is a
// __restrict parameter: GCC then vectorises the loop.
template <bool Damped, bool Loads, bool Report, bool Held, bool Motion>
inline void integrate_row(index_t n, const IntegrationConstants& c, const double* __restrict free_x,
                          const double* __restrict free_y, const double* __restrict free_z,
                          const double* __restrict im, const double* __restrict m,
                          double* __restrict fx, double* __restrict fy, double* __restrict fz,
                          double* __restrict fw, const double* __restrict px,
                          const double* __restrict py, const double* __restrict pz,
                          const double* __restrict ux, const double* __restrict uy,
                          const double* __restrict uz, double* __restrict wx, double* __restrict wy,
                          double* __restrict wz, double* __restrict fd, double& damping,
                          double& load_mid, double& load_half, double& kinetic, double& motion) {
  const double dt = c.dt, c1 = c.c1, c2 = c.c2, alpha = c.alpha, inv_dt = 1.0 / c.dt;
  constexpr bool sums = Damped || Loads || Report;
  // No reduction clause: with one, GCC 12 does not vectorise the loop. The per-node terms of
  // the sums go to the scratch rows (fx.. are free once read) and are added afterwards.
#pragma omp simd
  for (index_t i = 0; i < n; ++i) {
    // 1 on a free DOF, 0 on a held one; a row without held DOF reads no factors.
    const double kx = Held ? free_x[i] : 1.0;
    const double ky = Held ? free_y[i] : 1.0;
    const double kz = Held ? free_z[i] : 1.0;
    const double gx = Loads ? fx[i] + px[i] : fx[i];
    const double gy = Loads ? fy[i] + py[i] : fy[i];
    const double gz = Loads ? fz[i] + pz[i] : fz[i];
    // u_{n-1} is read from w and u_{n+1} written over it: v_{n-1/2} = (u_n - u_{n-1}) / dt.
    const double ox = (ux[i] - wx[i]) * inv_dt, oy = (uy[i] - wy[i]) * inv_dt,
                 oz = (uz[i] - wz[i]) * inv_dt;
    const double nx = kx * (c1 * ox + c2 * gx * im[i]);
    const double ny = ky * (c1 * oy + c2 * gy * im[i]);
    const double nz = kz * (c1 * oz + c2 * gz * im[i]);
    const double ex = ux[i] + dt * nx, ey = uy[i] + dt * ny, ez = uz[i] + dt * nz;
    wx[i] = ex;
    wy[i] = ey;
    wz[i] = ez;
    if constexpr (Motion) {
      // The node's motion in this step, |u_{n+1} - u_n|^2 (bar_row_stays_intact).
      const double qx = ex - ux[i], qy = ey - uy[i], qz = ez - uz[i];
      fd[i] = qx * qx + qy * qy + qz * qz;
    }
    if constexpr (sums) {
      // Mid-step velocity v_n = (v_{n-1/2} + v_{n+1/2}) / 2 of the free DOF.
      const double mx = 0.5 * kx * (ox + nx), my = 0.5 * ky * (oy + ny), mz = 0.5 * kz * (oz + nz);
      fx[i] = Damped ? alpha * dt * m[i] * (mx * mx + my * my + mz * mz) : 0.0;
      fy[i] = Loads ? dt * (px[i] * mx + py[i] * my + pz[i] * mz) : 0.0;
      // Central-difference kinetic energy m v_{n-1/2} . v_{n+1/2} / 2: with it the discrete
      // balance is exact for linear elastic motion (see docs/model.md); m v_n^2 / 2 would be
      // off by O((omega dt)^2) for the fast modes a crack excites.
      fz[i] = Report ? 0.5 * m[i] * (kx * ox * nx + ky * oy * ny + kz * oz * nz) : 0.0;
      fw[i] =
          Report && Loads ? 0.5 * dt * (kx * px[i] * ox + ky * py[i] * oy + kz * pz[i] * oz) : 0.0;
    }
  }
  if constexpr (Motion) {
    double top = 0.0;
#pragma omp simd reduction(max : top)
    for (index_t i = 0; i < n; ++i)
      top = std::max(top, fd[i]);
    motion = std::sqrt(top);
  }
  // Each sum in node order, and only those that are not zero by the template's terms.
  damping = load_mid = load_half = kinetic = 0.0;
  if constexpr (Damped)
    for (index_t i = 0; i < n; ++i)
      damping += fx[i];
  if constexpr (Loads)
    for (index_t i = 0; i < n; ++i)
      load_mid += fy[i];
  if constexpr (Report)
    for (index_t i = 0; i < n; ++i)
      kinetic += fz[i];
  if constexpr (Report && Loads)
    for (index_t i = 0; i < n; ++i)
      load_half += fw[i];
}

} // namespace

// (The node kernel is inlined here: GCC 12's AVX-512 headers' false alarms again, see
// node_vector.)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
template <bool Damped, bool Loads, bool Report>
void Simulation::node_rows_range(std::size_t line, const double* s_plane, const double* s_below) {
  const std::size_t begin = lines_[line].node_begin, end = lines_[line].node_end;
  // The lines whose bars the line's nodes end: (j, k), (j - 1, k), and the same in plane k - 1.
  const std::size_t per_plane = lat_.ny() + 1ull;
  const std::size_t j = line % per_plane, k = line / per_plane;
  const bool lines_fast =
      fast_path_ && line_fast_[line] && (j == 0 || line_fast_[line - 1]) &&
      (k == 0 || (line_fast_[line - per_plane] && (j == 0 || line_fast_[line - per_plane - 1])));
  bool hot_row[2] = {false, false}; // corner, centre
  const double dt = dt_;
  const double half = 0.5 * opt_.damping * dt;
  const double c1 = (1.0 - half) / (1.0 + half), c2 = dt / (1.0 + half);
  const double alpha = opt_.damping;
  {
    double* __restrict fx = thread_scratch_[static_cast<std::size_t>(omp_get_thread_num())].data();
    double* __restrict fy = fx + scratch_stride_;
    double* __restrict fz = fy + scratch_stride_;
    double* __restrict fw = fz + scratch_stride_;
    // The held DOF of a row as factors 1 (free) and 0 (held): the node update then reads only
    // doubles, which GCC vectorises (with the mask's bytes in the loop it does not).
    double* __restrict free_x = fw + scratch_stride_;
    double* __restrict free_y = free_x + scratch_stride_;
    double* __restrict free_z = free_y + scratch_stride_;
    double* __restrict fd = free_z + scratch_stride_;
    for (std::size_t r = begin; r < end; ++r) {
      const NodeRow& row = node_rows_[r];
      const index_t n = row.length;
      const auto n0 = static_cast<std::size_t>(row.centre ? slots_.centre(lat_, row.j, row.k)
                                                          : slots_.corner(lat_, row.j, row.k));
      const double* __restrict ux = ux_.data() + n0;
      const double* __restrict uy = uy_.data() + n0;
      const double* __restrict uz = uz_.data() + n0;
      // The integration below streams u_{n-1} (overwritten by u_{n+1}) and 1/m from memory; ask for
      // them now so that they arrive while the row's forces are gathered (measured: +9 % on 64^3).
      for (index_t i = 0; i < n; i += 8) {
        __builtin_prefetch(wx_.data() + n0 + i, 1);
        __builtin_prefetch(wy_.data() + n0 + i, 1);
        __builtin_prefetch(wz_.data() + n0 + i, 1);
        __builtin_prefetch(slot_inv_mass_.data() + n0 + i, 0);
      }
      const RowKind& kind = row_kinds_[row_kind_[r]];
      // The portable kernel takes a whole row in one pass where it can (row_whole_).
      const std::int64_t lo = !kVectorKernel && row_whole_[r] ? 0 : kind.lo;
      const std::int64_t hi = !kVectorKernel && row_whole_[r] ? std::int64_t{n} : kind.hi;
      const LinkConst* lc = &link_const_[kMaxRowLinks * row_kind_[r]];
      const LinkRef* ref = &link_ref_[kMaxRowLinks * r];

      const int nl = kind.links;
      // Each link fast or from the buffer, as its bar row is in this step. Rows inside a box
      // have 14 links, rows on its faces and edges fewer; a row with fewer than 7 (the corner
      // rows along the x edges) has links that no node has up to 7, which every lane masks.
      // (A row's links are all fast when the four lines are, else look link by link.)
      bool all_fast = nl >= 7 && lines_fast;
      if (!all_fast && nl >= 7 && fast_path_) {
        all_fast = true;
        for (int l = 0; l < nl; ++l)
          all_fast = all_fast && row_fast_[ref[l].bar_row] != 0;
      }
      MixedLinks mixed;
      if (!all_fast)
        for (int l = 0; l < kMaxRowLinks; ++l) {
          mixed.fast[l] = fast_path_ && l < nl && row_fast_[ref[l].bar_row] != 0;
          mixed.s[l] = (lc[l].dk == 0 ? s_plane : s_below) + ref[l].plane_base;
        }
      const int padded = std::max(nl, 7);
      double* __restrict wx = wx_.data() + n0;
      double* __restrict wy = wy_.data() + n0;
      double* __restrict wz = wz_.data() + n0;
      const double* __restrict im = slot_inv_mass_.data() + n0;
      const DofMask* __restrict held = slot_held_.data() + n0;
      const NodeRowArgs args{ux_.data(), uy_.data(), uz_.data(), ux,   uy, uz, fx, fy,       fz, wx,
                             wy,         wz,         im,         held, dt, c1, c2, 1.0 / dt, fw};
      // On a plain step without damping or loads the kernel also moves the row's nodes (what
      // integrate_row would do, the same bits), unless imposed velocities need its forces.
      const bool in_kernel = kVectorKernel && !Damped && !Loads && !Report && imposed_row_[r] < 0;
      double motion = 0.0;
      double energy[kMaxRowLinks];
      const auto forces = [&](auto count, auto fast, auto integrate, auto held_c) {
        return node_row_forces < decltype(count)::value, decltype(fast)::value,
               decltype(integrate)::value, decltype(held_c)::value,
               Report && kVectorKernel > (lc, ref, &mixed, &edge_lanes_[kind.edge_begin], n, lo, hi,
                                          args, motion, energy);
      };
      const auto by_count = [&](auto... flags) {
        switch (padded) {
        case 14:
          return forces(std::integral_constant<int, 14>{}, flags...);
        case 13:
          return forces(std::integral_constant<int, 13>{}, flags...);
        case 12:
          return forces(std::integral_constant<int, 12>{}, flags...);
        case 11:
          return forces(std::integral_constant<int, 11>{}, flags...);
        case 10:
          return forces(std::integral_constant<int, 10>{}, flags...);
        case 9:
          return forces(std::integral_constant<int, 9>{}, flags...);
        case 8:
          return forces(std::integral_constant<int, 8>{}, flags...);
        default:
          return forces(std::integral_constant<int, 7>{}, flags...);
        }
      };
      using yes = std::true_type;
      using no = std::false_type;
      bool hot = false;
      if constexpr (kVectorKernel && !Damped && !Loads && !Report) {
        if (in_kernel) {
          if (row_held_[r])
            hot = all_fast ? by_count(yes{}, yes{}, yes{}) : by_count(no{}, yes{}, yes{});
          else
            hot = all_fast ? by_count(yes{}, yes{}, no{}) : by_count(no{}, yes{}, no{});
        }
      }
      if (!in_kernel)
        hot = all_fast ? by_count(yes{}, no{}, no{}) : by_count(no{}, no{}, no{});
      // The fast bar rows whose first nodes are this row's: their elastic energy, U = k (l -
      // l0)^2 / 2 with the area factors in the weights (as bar_rows has it for the others).
      if constexpr (Report && kVectorKernel)
        for (int l = 0; l < nl; ++l)
          if (lc[l].first_node && row_fast_[ref[l].bar_row])
            energy_rows_u_[ref[l].bar_row] = 0.5 * lc[l].k * energy[l];
      hot_row[row.centre] = hot;
      if (in_kernel) {
        node_row_motion_[r] = std::sqrt(motion);
        row_damping_[r] = row_load_mid_[r] = row_load_half_[r] = row_kinetic_[r] = 0.0;
        continue;
      }
      // A row with imposed-velocity nodes keeps its gathered forces for apply_velocities.
      if (const std::int64_t o = imposed_row_[r]; o >= 0) {
        double* kept = imposed_force_.data() + o;
        std::copy(fx, fx + n, kept);
        std::copy(fy, fy + n, kept + n);
        std::copy(fz, fz + n, kept + 2 * n);
      }
      const double* __restrict m = slot_mass_.data() + n0;
      const double* __restrict px = Loads ? px_.data() + n0 : nullptr;
      const double* __restrict py = Loads ? py_.data() + n0 : nullptr;
      const double* __restrict pz = Loads ? pz_.data() + n0 : nullptr;
      double damping = 0.0, load_mid = 0.0, load_half = 0.0, kinetic = 0.0;
      const IntegrationConstants ic{dt, c1, c2, alpha};
      // (The rows' motion only matters to the fast path.)
      const auto integrate = [&](auto held_c, auto motion_c) {
        constexpr bool H = decltype(held_c)::value, M = decltype(motion_c)::value;
        integrate_row<Damped, Loads, Report, H, M>(
            n, ic, H ? free_x : nullptr, H ? free_y : nullptr, H ? free_z : nullptr, im, m, fx, fy,
            fz, fw, px, py, pz, ux, uy, uz, wx, wy, wz, fd, damping, load_mid, load_half, kinetic,
            motion);
      };
      if (row_held_[r]) {
        for (index_t i = 0; i < n; ++i) {
          free_x[i] = held[i] & kDofX ? 0.0 : 1.0;
          free_y[i] = held[i] & kDofY ? 0.0 : 1.0;
          free_z[i] = held[i] & kDofZ ? 0.0 : 1.0;
        }
        fast_path_ ? integrate(yes{}, yes{}) : integrate(yes{}, no{});
      } else {
        fast_path_ ? integrate(no{}, yes{}) : integrate(no{}, no{});
      }
      node_row_motion_[r] = motion; // (apply_velocities adds the imposed DOF's motion)
      row_damping_[r] = damping;
      row_load_mid_[r] = load_mid;
      row_load_half_[r] = load_half;
      row_kinetic_[r] = kinetic;
    }
  }
  // The line's fast bar rows, whose first nodes are its corner row's (edges) or its centre
  // row's (the rest): no bar longer than its watch length unless the kernel saw one there.
  for (std::size_t r = lines_[line].bar_begin; fast_path_ && r < lines_[line].bar_end; ++r)
    if (row_fast_[r])
      row_ratio_[r] = hot_row[row_first_centre_[r]] ? kUnknown : row_watch_[r];
}
#pragma GCC diagnostic pop

// The bar forces of line l from a plane buffer into a packed store of one line (Pack), or back.
// Rows whose bars take the fast path this step have no forces in the buffers to move.
template <bool Pack>
void Simulation::move_bar_line(std::size_t l, double* plane, double* packed) const {
  for (std::size_t r = lines_[l].bar_begin; r < lines_[l].bar_end; ++r) {
    const FamilyInfo& fi = lat_.family(bar_rows_[r].family);
    double* row = plane + fi.plane_offset + std::size_t{fi.plane_stride} * bar_rows_[r].j;
    if (!row_fast_[r]) {
      if constexpr (Pack)
        std::copy(row, row + fi.ni, packed);
      else
        std::copy(packed, packed + fi.ni, row);
    }
    packed += fi.ni;
  }
}

// Node line (j, k) needs the bar lines j - 1 and j of its plane and of the plane below, so
// the bars of a line are computed moments before the nodes that gather them. Each thread
// takes a box of lines: a slab of k-planes (all j) when the body has planes enough, else a
// range of j (all k: a body thin along z). It walks its box in blocks of block_lines_ lines
// along j, and inside a block plane by plane upwards, bars of a block's lines then its nodes:
// a block's bar forces, and the displacements they read, stay in the core's own cache (on a
// whole plane of a large body they would not). Bar forces go to the thread's plane buffers,
// alternating with k (only the block's lines are touched). Two lines are needed from
// elsewhere: line jb - 1 of each plane, computed with the block before (kept packed in
// `carry`), and what the neighbouring thread owns: the top plane of the slab below, or the
// last line of the j range below. Each thread computes those first, before the one barrier.
// Every bar line is computed once per step, whatever the threads and blocks, so they change
// which thread does a row, never how the row is computed.
template <bool Damped, bool Loads, bool Report> void Simulation::advance_rows() {
  const auto nplanes = static_cast<std::int64_t>(planes_.size());
  const auto nlines = static_cast<std::int64_t>(lat_.ny()) + 1; // lines per plane
#pragma omp parallel num_threads(threads_) if (lat_.num_bars() > kParallelMinItems)
  {
    const std::int64_t nt = omp_get_num_threads(), t = omp_get_thread_num();
    const bool slabs = nplanes >= 4 * nt;
    auto first = [nt](std::int64_t n, std::int64_t u) { return u * n / nt; };
    const std::int64_t k0 = slabs ? first(nplanes, t) : 0;
    const std::int64_t k1 = slabs ? first(nplanes, t + 1) : nplanes;
    const std::int64_t j0 = slabs ? 0 : first(nlines, t);
    const std::int64_t j1 = slabs ? nlines : first(nlines, t + 1);
    const auto line = [&](std::int64_t j, std::int64_t k) { return planes_[k].line_begin + j; };
    const auto bars = [&](std::int64_t j, std::int64_t k, double* s) {
      bar_rows(line(j, k), s, Report);
    };
    const auto ut = static_cast<std::size_t>(t);
    double* const slot[2] = {plane_buffers_[3 * ut].data(), plane_buffers_[3 * ut + 1].data()};
    double* const top = plane_buffers_[3 * ut + 2].data();
    const auto packed = [&](std::int64_t u, int which, std::int64_t k) {
      return line_stores_[2 * static_cast<std::size_t>(u) + which].data() +
             static_cast<std::size_t>(k) * line_store_stride_;
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
        move_bar_line<true>(line(j1 - 1, k), top, packed(t, kEdge, k));
      }
    // The thread whose j range holds line j0 - 1 (ranges may be empty when lines are few).
    std::int64_t below = t - 1;
    while (below > 0 && first(nlines, below) > j0 - 1)
      --below;
#pragma omp barrier
    for (std::int64_t jb = j0; box && jb < j1; jb += block_lines_) {
      const std::int64_t je = std::min<std::int64_t>(jb + block_lines_, j1);
      for (std::int64_t k = k0; k < k1; ++k) {
        const bool at_top = slabs && k == k1 - 1;
        double* s_plane = at_top ? top : slot[k % 2];
        const double* s_below = k == 0   ? nullptr
                                : k > k0 ? slot[(k - 1) % 2]
                                         : plane_buffers_[3 * ut - 1].data(); // slab below's top
        if (!at_top) {
          if (jb > j0)
            move_bar_line<false>(line(jb - 1, k), s_plane, packed(t, kCarry, k));
          else if (jb > 0)
            move_bar_line<false>(line(jb - 1, k), s_plane, packed(below, kEdge, k));
          for (std::int64_t j = jb; j < je; ++j) {
            if (edge_out && j == j1 - 1)
              move_bar_line<false>(line(j, k), s_plane, packed(t, kEdge, k));
            else
              bars(j, k, s_plane);
          }
          if (je < j1)
            move_bar_line<true>(line(je - 1, k), s_plane, packed(t, kCarry, k));
        }
        for (std::int64_t j = jb; j < je; ++j)
          node_rows_range<Damped, Loads, Report>(line(j, k), s_plane, s_below);
      }
    }
  }
}

// Force of its bars on one node at u_n, from the bar law and the history.
Vec3 Simulation::node_force(index_t node) const {
  const NodeAddress a = lat_.node_address(node);
  RowLink links[kMaxRowLinks];
  const int nl = row_links(lat_, node_rows_[node_row_of(node)], links, slots_);
  const std::size_t q = slot(node);
  Vec3 f;
  for (int l = 0; l < nl; ++l) {
    const RowLink& L = links[l];
    if (a.i < L.ilo || a.i >= L.ihi)
      continue;
    const auto bar = static_cast<index_t>(L.bar_base + a.i);
    const auto o = static_cast<std::size_t>(L.other_base + a.i);
    const double rx = L.r0.x + (ux_[o] - ux_[q]), ry = L.r0.y + (uy_[o] - uy_[q]),
                 rz = L.r0.z + (uz_[o] - uz_[q]);
    const double len = std::sqrt(rx * rx + ry * ry + rz * rz);
    const BilinearLaw law = table_.law(lat_, bar);
    const double s = law.force((len - law.l0) / law.l0, h_[bar]) / len;
    f.x += s * rx;
    f.y += s * ry;
    f.z += s * rz;
  }
  return f;
}

void Simulation::apply_loads(double t) {
  for (const auto& slots : load_slots_)
    for (std::size_t q : slots)
      px_[q] = py_[q] = pz_[q] = 0.0;
  for (std::size_t c = 0; c < cond_.loads.size(); ++c) {
    const NodalLoad& load = cond_.loads[c];
    const double s = load.scale(t);
    for (std::size_t q : load_slots_[c]) {
      px_[q] += s * load.force.x;
      py_[q] += s * load.force.y;
      pz_[q] += s * load.force.z;
    }
  }
}

// Imposed velocities at t_{n+1/2}: set v and u_{n+1}, and account the reaction's work
// R_n . dt (v_{n-1/2} + v_{n+1/2}) / 2 with R_n = m a_n + a m v_n - f_int - P, the force the
// support must apply. Returns nothing: adds to the per-step sums below.
void Simulation::apply_velocities(double t, bool report) {
  const double dt = dt_, half = 0.5 * opt_.damping * dt;
  ExactSum work, work_half, damping, kinetic;
  for (std::size_t c = 0; c < cond_.velocities.size(); ++c) {
    const ImposedVelocity& iv = cond_.velocities[c];
    const double s = iv.scale(t + 0.5 * dt);
    const double target[3] = {s * iv.velocity.x, s * iv.velocity.y, s * iv.velocity.z};
    for (std::size_t q = 0; q < iv.set.nodes.size(); ++q) {
      const std::size_t p = velocity_slots_[c][q];
      // The node's bar forces at u_n, as the node pass gathered them.
      const auto [fi, len] = imposed_force_at_[c][q];
      const Vec3 f{imposed_force_[fi], imposed_force_[fi + len], imposed_force_[fi + 2 * len]};
      const double fint[3] = {f.x + (px_.empty() ? 0.0 : px_[p]),
                              f.y + (py_.empty() ? 0.0 : py_[p]),
                              f.z + (pz_.empty() ? 0.0 : pz_[p])};
      const double vold[3] = {imposed_v_old_[c][q].x, imposed_v_old_[c][q].y,
                              imposed_v_old_[c][q].z};
      double* u[3] = {&ux_[p], &uy_[p], &uz_[p]};
      double* w[3] = {&wx_[p], &wy_[p], &wz_[p]};
      double moved2 = 0.0;
      for (int d = 0; d < 3; ++d) {
        if (!(iv.dofs & (1u << d)))
          continue;
        // What the free update would give, and the reaction that turns it into the target.
        const double v_free =
            ((1.0 - half) * vold[d] + dt * fint[d] / slot_mass_[p]) / (1.0 + half);
        const double R = slot_mass_[p] * (target[d] - v_free) * (1.0 + half) / dt;
        const double vmid = 0.5 * (vold[d] + target[d]);
        // The support's reaction R acts together with any load P on the DOF.
        const double P = px_.empty() ? 0.0 : (d == 0 ? px_[p] : d == 1 ? py_[p] : pz_[p]);
        work.add((R + P) * dt * vmid);
        if (opt_.damping > 0.0)
          damping.add(opt_.damping * dt * slot_mass_[p] * vmid * vmid);
        if (report) {
          work_half.add(0.5 * (R + P) * dt * vold[d]);
          kinetic.add(0.5 * slot_mass_[p] * vold[d] * target[d]);
        }
        *w[d] = *u[d] + dt * target[d];
        const double moved = *w[d] - *u[d];
        moved2 += moved * moved;
      }
      double& row = condition_motion_[imposed_node_row_[c][q]];
      row = std::max(row, moved2);
    }
    // Conditions may share a node (one imposes x, another y): each adds its rows' largest
    // squared motion, so a row's sum bounds the squared motion of any of its nodes.
    for (const std::uint32_t r : imposed_node_row_[c]) {
      imposed_motion_[r] += condition_motion_[r];
      condition_motion_[r] = 0.0;
    }
  }
  // A node's motion is that of its free DOF (the node pass measured it) and of its imposed
  // ones, squares added: the row's largest is at most the root of the sum of the two largest.
  for (std::size_t c = 0; c < cond_.velocities.size(); ++c)
    for (const std::uint32_t r : imposed_node_row_[c])
      if (imposed_motion_[r] >= 0.0) {
        node_row_motion_[r] =
            std::sqrt(node_row_motion_[r] * node_row_motion_[r] + imposed_motion_[r]);
        imposed_motion_[r] = -1.0; // done
      }
  for (std::size_t c = 0; c < cond_.velocities.size(); ++c)
    for (const std::uint32_t r : imposed_node_row_[c])
      imposed_motion_[r] = 0.0;
  cond_work_ = work;
  cond_work_half_ = work_half;
  cond_damping_ = damping;
  cond_kinetic_ = kinetic;
}

bool Simulation::intact_at_nodes_built() {
  return kVectorKernel;
}

double Simulation::motion_bound(index_t node) const {
  return node_row_motion_[node_row_of(node)];
}

void Simulation::step(bool report) {
  const double t = time();
  const bool energies = report || step_ == 0;
  if (!cond_.loads.empty())
    apply_loads(t);
  for (std::size_t c = 0; c < cond_.velocities.size(); ++c) {
    const auto& nodes = cond_.velocities[c].set.nodes;
    for (std::size_t q = 0; q < nodes.size(); ++q)
      imposed_v_old_[c][q] = half_step_velocity(nodes[q]);
  }
  const bool damped = opt_.damping > 0.0, loads = !cond_.loads.empty();
  // Pick the specialisation of the node update once per step.
  if (damped) {
    if (loads)
      energies ? advance_rows<true, true, true>() : advance_rows<true, true, false>();
    else
      energies ? advance_rows<true, false, true>() : advance_rows<true, false, false>();
  } else {
    if (loads)
      energies ? advance_rows<false, true, true>() : advance_rows<false, true, false>();
    else
      energies ? advance_rows<false, false, true>() : advance_rows<false, false, false>();
  }
  apply_velocities(t, energies);

  // The step's work and damping, row by row and DOF by DOF, added exactly (Ledger).
  // (Without damping or loads the rows' terms are zeros, which add nothing.)
  ExactSum damping = cond_damping_, load_mid = cond_work_;
  for (std::size_t r = 0; damped && r < node_rows_.size(); ++r)
    damping.add(row_damping_[r]);
  for (std::size_t r = 0; loads && r < node_rows_.size(); ++r)
    load_mid.add(row_load_mid_[r]);
  if (energies) {
    ExactSum kinetic = cond_kinetic_, work_half = cond_work_half_;
    for (std::size_t r = 0; r < node_rows_.size(); ++r)
      kinetic.add(row_kinetic_[r]);
    for (std::size_t r = 0; loads && r < node_rows_.size(); ++r)
      work_half.add(row_load_half_[r]);
    // Damping: the part of this step's dissipation a dt v_n . m v_n that lies before t_n,
    // taken as half of it (the exact split a m v_n . dt v_{n-1/2} / 2 differs by O(dt^2)).
    const BarEnergies bars = report_bar_energies();
    const double elastic = bars.elastic, damage = bars.damage;
    if (step_ == 0)
      ledger_.set_initial(elastic + kinetic.value());
    report_work_ = ledger_.state().work;
    report_work_.add(work_half);
    report_damping2_ = Ledger::twice_damping_at_report(ledger_.state(), damping);
    report_ = energy_report(t, report_work_.value(), elastic, kinetic.value(), damage,
                            0.5 * report_damping2_.value(), ledger_.initial());
  }
  ledger_.work().add(load_mid);
  ledger_.damping().add(damping);
  ux_.swap(wx_);
  uy_.swap(wy_);
  uz_.swap(wz_);
  ++step_;
}

// ---------------------------------------------------------------------------------------

std::vector<Event> Simulation::take_events() {
  std::vector<Event> all;
  for (auto& ev : thread_events_) {
    all.insert(all.end(), ev.begin(), ev.end());
    ev.clear();
  }
  std::sort(all.begin(), all.end(), event_before);
  return all;
}

BarState Simulation::bar_state(index_t bar) const {
  return table_.law(lat_, bar).state(h_[bar]);
}

double Simulation::bar_force(index_t bar) const {
  const auto [a, b] = lat_.bar_nodes(bar);
  const std::size_t qa = slot(a), qb = slot(b);
  const FamilyInfo& fi = lat_.family(lat_.bar_address(bar).family);
  const double dx = fi.d0.x + (ux_[qb] - ux_[qa]), dy = fi.d0.y + (uy_[qb] - uy_[qa]),
               dz = fi.d0.z + (uz_[qb] - uz_[qa]);
  const double e = (std::sqrt(dx * dx + dy * dy + dz * dz) - fi.l0) / fi.l0;
  return table_.law(lat_, bar).force(e, h_[bar]);
}

template <class F> void Simulation::visit_intact_row(std::size_t r, F&& visit) const {
  const BarRow& row = bar_rows_[r];
  const FamilyInfo& fi = lat_.family(row.family);
  const std::size_t a0 = row.a_slot, c0 = row.b_slot;
  const double* __restrict uax = ux_.data() + a0;
  const double* __restrict uay = uy_.data() + a0;
  const double* __restrict uaz = uz_.data() + a0;
  const double* __restrict ubx = ux_.data() + c0;
  const double* __restrict uby = uy_.data() + c0;
  const double* __restrict ubz = uz_.data() + c0;
  auto extension = [&](index_t i) {
    const double dx = fi.d0.x + (ubx[i] - uax[i]), dy = fi.d0.y + (uby[i] - uay[i]),
                 dz = fi.d0.z + (ubz[i] - uaz[i]);
    return std::sqrt(dx * dx + dy * dy + dz * dz) - fi.l0;
  };
  visit(lat_.bar(static_cast<Family>(row.family), 0, row.j, row.k), fi.ni,
        table_.family(row.family).k, extension);
}

template <class F> void Simulation::for_each_intact_row(F&& visit) const {
  if (table_.per_bar())
    return;
#pragma omp parallel for schedule(static) if (lat_.num_bars() > kParallelMinItems)
  for (std::size_t r = 0; r < bar_rows_.size(); ++r)
    if (!row_damaged_[r])
      visit_intact_row(r, [&](index_t b0, index_t n, double k, auto&& extension) {
        visit(r, b0, n, k, extension);
      });
}

template <class P, class F> void Simulation::for_each_row_by_law(P&& take, F&& visit) const {
  // Shared out evenly among the threads: a crack's damaged rows lie together.
  law_rows_.clear();
  for (std::size_t r = 0; r < bar_rows_.size(); ++r)
    if (take(r))
      law_rows_.push_back(r);
  const auto nlaw = static_cast<std::ptrdiff_t>(law_rows_.size());
#pragma omp parallel for schedule(static) if (nlaw * lat_.nx() > kParallelMinItems)
  for (std::ptrdiff_t q = 0; q < nlaw; ++q)
    visit(law_rows_[static_cast<std::size_t>(q)]);
}

template <bool PerBar, class F> index_t Simulation::visit_law_row(std::size_t r, F&& lane) const {
  const BarRow& row = bar_rows_[r];
  const FamilyInfo& fi = lat_.family(row.family);
  const FamilyMaterial& mat = table_.family(row.family);
  const index_t b0 = lat_.bar(static_cast<Family>(row.family), 0, row.j, row.k), n = fi.ni;
  const double* __restrict uax = ux_.data() + row.a_slot;
  const double* __restrict uay = uy_.data() + row.a_slot;
  const double* __restrict uaz = uz_.data() + row.a_slot;
  const double* __restrict ubx = ux_.data() + row.b_slot;
  const double* __restrict uby = uy_.data() + row.b_slot;
  const double* __restrict ubz = uz_.data() + row.b_slot;
  const double* __restrict h = h_.data() + b0;
  const double* __restrict kb = PerBar ? table_.k_bar().data() + b0 : nullptr;
  const double* __restrict epb = PerBar ? table_.e_p_bar().data() + b0 : nullptr;
  const double* __restrict erb = PerBar ? table_.e_r_bar().data() + b0 : nullptr;
  // Scalars in locals (the loop vectorises only so); EA = (k l0) factor, as BarTable's law.
  const double l0 = fi.l0, kl0 = mat.k * fi.l0, ep = mat.e_p, er = mat.e_r;
  const double inner = row.factor, end = row.end_factor;
  const double d0x = fi.d0.x, d0y = fi.d0.y, d0z = fi.d0.z;
  for (index_t i = 0; i < n; ++i) {
    const double dx = d0x + (ubx[i] - uax[i]);
    const double dy = d0y + (uby[i] - uay[i]);
    const double dz = d0z + (ubz[i] - uaz[i]);
    const double e = (std::sqrt(dx * dx + dy * dy + dz * dz) - l0) / l0;
    const double factor = (i == 0 || i + 1 == n) ? end : inner;
    const BilinearLaw law{PerBar ? kb[i] * l0 : kl0 * factor, l0, PerBar ? epb[i] : ep,
                          PerBar ? erb[i] : er};
    lane(i, e, law, h[i]);
  }
  return n;
}

Simulation::BarEnergies Simulation::law_row_energies(std::size_t r, bool elastic) const {
  double* eu = thread_scratch_[static_cast<std::size_t>(omp_get_thread_num())].data();
  double* ed = eu + scratch_stride_;
  const auto energies = [eu, ed, elastic](index_t i, double e, const BilinearLaw& law, double h) {
    if (elastic)
      eu[i] = law.stored_energy(e, h);
    ed[i] = law.dissipated_energy(h);
  };
  const index_t n =
      table_.per_bar() ? visit_law_row<true>(r, energies) : visit_law_row<false>(r, energies);
  BarEnergies sums;
  for (index_t i = 0; i < n; ++i) { // in bar order, as a bar-by-bar sum
    if (elastic)
      sums.elastic += eu[i];
    sums.damage += ed[i];
  }
  return sums;
}

Simulation::BarEnergies Simulation::report_bar_energies() {
  // Elastic energies from the bar pass; a row's dissipated energy depends on its histories
  // alone, so only the rows whose histories changed go through the law again.
  const bool per_bar = table_.per_bar();
  for_each_row_by_law(
      [&](std::size_t r) { return (row_damaged_[r] || per_bar) && row_history_changed_[r]; },
      [&](std::size_t r) {
        row_dissipated_[r] = law_row_energies(r, false).damage;
        row_history_changed_[r] = 0;
      });
  BarEnergies out;
  for (std::size_t r = 0; r < bar_rows_.size(); ++r) { // row order: the same for any thread count
    energy_rows_d_[r] = row_damaged_[r] || per_bar ? row_dissipated_[r] : 0.0;
    out.elastic += energy_rows_u_[r];
    out.damage += energy_rows_d_[r];
  }
  return out;
}

Simulation::BarEnergies Simulation::bar_energies() const {
  // The reference: every row through the law, which also takes a bar of a row still marked
  // intact that is strained past e_p now (the next bar pass would mark the row damaged).
  std::vector<BarEnergies> rows(bar_rows_.size());
  for_each_row_by_law([](std::size_t) { return true; },
                      [&](std::size_t r) { rows[r] = law_row_energies(r, true); });
  BarEnergies out;
  for (const BarEnergies& e : rows) { // row order: the same for any thread count
    out.elastic += e.elastic;
    out.damage += e.damage;
  }
  return out;
}

double Simulation::stored_energy() const {
  return bar_energies().elastic;
}

void Simulation::bar_snapshot(std::vector<std::uint8_t>& state, std::vector<double>& damage,
                              std::vector<double>& force) const {
  state.resize(lat_.num_bars());
  damage.resize(lat_.num_bars());
  force.resize(lat_.num_bars());
  // Intact rows of a uniform material: F = k (l - l0) times the area factor, no damage, unless
  // a bar of the row is strained past e_p now (the next bar pass would mark the row damaged):
  // such a row goes through the law with the others.
  snapshot_by_law_.assign(bar_rows_.size(), 0);
  for_each_intact_row([&](std::size_t r, index_t b0, index_t n, double k, auto&& extension) {
    const double inner = k * bar_rows_[r].factor, end = k * bar_rows_[r].end_factor;
    const double peak =
        table_.family(bar_rows_[r].family).e_p * lat_.family(bar_rows_[r].family).l0;
    // (The forces in a loop of doubles alone, which GCC vectorises; the bytes apart.)
    double* __restrict f = force.data() + b0;
    int past = 0;
#pragma omp simd reduction(+ : past)
    for (index_t i = 0; i < n; ++i) {
      const double dl = extension(i);
      f[i] = (i == 0 || i + 1 == n ? end : inner) * dl;
      past += dl > peak ? 1 : 0;
    }
    snapshot_by_law_[r] = past > 0;
    std::fill_n(damage.begin() + b0, n, 0.0);
    std::fill_n(state.begin() + b0, n, std::uint8_t{0});
  });
  // The other rows through the bar law: force and damage (dissipated energy over what the bar
  // dissipates when broken, Gf A^f) in a loop of doubles, the states apart.
  const bool per_bar = table_.per_bar();
  for_each_row_by_law(
      [&](std::size_t r) { return row_damaged_[r] || per_bar || snapshot_by_law_[r]; },
      [&](std::size_t r) {
        const BarRow& row = bar_rows_[r];
        const index_t b0 = lat_.bar(static_cast<Family>(row.family), 0, row.j, row.k);
        double* f = force.data() + b0;
        double* d = damage.data() + b0;
        const auto values = [f, d](index_t i, double e, const BilinearLaw& law, double h) {
          d[i] = std::isinf(h)
                     ? 1.0
                     : law.dissipated_energy(h) / (0.5 * law.EA * law.e_p * law.e_r * law.l0);
          f[i] = law.force(e, h);
        };
        const index_t n =
            per_bar ? visit_law_row<true>(r, values) : visit_law_row<false>(r, values);
        const FamilyMaterial& mat = table_.family(row.family);
        for (index_t i = 0; i < n; ++i) {
          const index_t b = b0 + i;
          const BilinearLaw law{0.0, 0.0, per_bar ? table_.e_p_bar()[b] : mat.e_p,
                                per_bar ? table_.e_r_bar()[b] : mat.e_r};
          state[b] = static_cast<std::uint8_t>(law.state(h_[b]));
        }
      });
}

void Simulation::internal_forces(std::vector<double>& fx, std::vector<double>& fy,
                                 std::vector<double>& fz) const {
  const index_t nn = lat_.num_nodes();
  fx.assign(nn, 0.0);
  fy.assign(nn, 0.0);
  fz.assign(nn, 0.0);
  for (index_t bar = 0; bar < lat_.num_bars(); ++bar) {
    const auto [a, b] = lat_.bar_nodes(bar);
    const std::size_t qa = slot(a), qb = slot(b);
    const FamilyInfo& fi = lat_.family(lat_.bar_address(bar).family);
    const double dx = fi.d0.x + (ux_[qb] - ux_[qa]), dy = fi.d0.y + (uy_[qb] - uy_[qa]),
                 dz = fi.d0.z + (uz_[qb] - uz_[qa]);
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double F = table_.law(lat_, bar).force((l - fi.l0) / fi.l0, h_[bar]);
    // A bar in tension pulls its first node towards the second.
    fx[a] += F * dx / l;
    fy[a] += F * dy / l;
    fz[a] += F * dz / l;
    fx[b] -= F * dx / l;
    fy[b] -= F * dy / l;
    fz[b] -= F * dz / l;
  }
}

index_t Simulation::first_bad_node() const {
  return first_node_beyond(1e3 * lat_.L() *
                           static_cast<double>(std::max({lat_.nx(), lat_.ny(), lat_.nz()})));
}

index_t Simulation::first_node_beyond(double limit) const {
  const index_t nn = lat_.num_nodes();
  // A quick test of the whole field first (NaN and infinity make the sums non-finite or large;
  // the slots between rows hold zeros).
  double s = 0.0;
#pragma omp simd reduction(+ : s)
  for (std::size_t q = 0; q < slot_count_; ++q)
    s += std::abs(ux_[q]) + std::abs(uy_[q]) + std::abs(uz_[q]);
  if (std::isfinite(s) && s <= limit)
    return nn;
  for (index_t n = 0; n < nn; ++n) {
    const std::size_t q = slot(n);
    if (!(std::abs(ux_[q]) <= limit && std::abs(uy_[q]) <= limit && std::abs(uz_[q]) <= limit))
      return n;
  }
  return nn;
}

std::vector<double> Simulation::masses() const {
  std::vector<double> m(lat_.num_nodes());
  for_each_run(0, lat_.num_nodes(), [&](std::size_t q, index_t n, index_t run) {
    std::copy(slot_mass_.begin() + q, slot_mass_.begin() + q + run, m.begin() + n);
  });
  return m;
}

std::vector<DofMask> Simulation::held_dofs() const {
  std::vector<DofMask> h(lat_.num_nodes());
  for_each_run(0, lat_.num_nodes(), [&](std::size_t q, index_t n, index_t run) {
    std::copy(slot_held_.begin() + q, slot_held_.begin() + q + run, h.begin() + n);
  });
  return h;
}

std::uint64_t Simulation::broken_count() const {
  std::uint64_t n = 0;
  for (index_t b = 0; b < lat_.num_bars(); ++b)
    n += bar_state(b) == BarState::Broken;
  return n;
}

std::uint64_t Simulation::softening_count() const {
  std::uint64_t n = 0;
  for (index_t b = 0; b < lat_.num_bars(); ++b)
    n += bar_state(b) == BarState::Softening;
  return n;
}

double Simulation::bytes_per_module() const {
  auto bytes = [](const auto& v) { return static_cast<double>(v.size() * sizeof(v[0])); };
  double total = 0.0;
  for (const auto* v :
       {&ux_, &uy_, &uz_, &wx_, &wy_, &wz_, &slot_mass_, &slot_inv_mass_, &px_, &py_, &pz_})
    total += bytes(*v);
  total += bytes(h_) + bytes(slot_held_);
  for (const auto& q : velocity_slots_)
    total += bytes(q);
  for (const auto& q : imposed_force_at_)
    total += bytes(q);
  total += bytes(imposed_row_) + bytes(imposed_force_);
  for (const auto& q : load_slots_)
    total += bytes(q);
  total += bytes(link_ref_) + bytes(row_kind_) + bytes(link_const_) + bytes(row_kinds_) +
           bytes(row_held_) + bytes(row_damaged_) + bytes(node_rows_) + bytes(bar_rows_) +
           bytes(row_fast_) + bytes(line_fast_) + bytes(row_ratio_) + bytes(row_inv_lp_) +
           bytes(row_watch_) + bytes(row_first_centre_) + bytes(row_whole_) +
           bytes(bar_row_nodes_) + bytes(node_row_motion_);
  for (const auto& b : plane_buffers_)
    total += bytes(b);
  for (const auto& b : line_stores_)
    total += bytes(b);
  if (table_.per_bar())
    total += bytes(table_.k_bar()) + bytes(table_.e_p_bar()) + bytes(table_.e_r_bar());
  return total / static_cast<double>(lat_.num_modules());
}

} // namespace ldem
