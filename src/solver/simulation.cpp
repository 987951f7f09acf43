#include "solver/simulation.hpp"

#include "util/error.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <omp.h>
#include <type_traits>
#if defined(__AVX512F__)
#include <immintrin.h>
#endif

namespace ldem {

namespace {

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
  // The links of every node row, computed once (they cost more to derive than to read).
  row_links_.resize(kMaxRowLinks * node_rows_.size());
  row_link_count_.resize(node_rows_.size());
  for (std::size_t r = 0; r < node_rows_.size(); ++r)
    row_link_count_[r] = static_cast<std::uint8_t>(
        row_links(lat_, node_rows_[r], &row_links_[kMaxRowLinks * r], slots_));
  // The range of i each row gathers in one fused pass. A link missing at a row's end reads a
  // zero pad of the plane buffer (s = 0) and a neighbouring slot's finite displacement, so the
  // fused pass covers the whole row wherever those reads would stay inside the lattice's nodes
  // in its own numbering (all rows but the first corner row and the rows that reach the end of
  // the last centre row). That rule is the lattice's alone, so the slots change no result, and
  // it keeps the reads inside the slots too (a row's slots start and end no earlier than its
  // nodes do). Elsewhere only the range where every link is present, the ends link by link.
  row_fused_.resize(node_rows_.size());
  for (std::size_t r = 0; r < node_rows_.size(); ++r) {
    RowLink links[kMaxRowLinks];
    const int nl = row_links(lat_, node_rows_[r], links);
    const index_t n = node_rows_[r].length;
    bool whole = true;
    index_t ilo = 0, ihi = n;
    for (int l = 0; l < nl; ++l) {
      ilo = std::max(ilo, links[l].ilo);
      ihi = std::min(ihi, links[l].ihi);
      whole = whole && links[l].other_base >= 0 &&
              links[l].other_base + n <= std::int64_t{lat_.num_nodes()};
    }
    row_fused_[r] = whole ? std::pair{index_t{0}, n} : std::pair{ilo, std::max(ilo, ihi)};
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
      for (index_t n : v.set.nodes) {
        const NodeRow& row = node_rows_[row_of[n]];
        imposed_force_at_.back().push_back(
            {static_cast<std::size_t>(imposed_row_[row_of[n]]) + (n - row.first), row.length});
      }
    }
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
    sc.resize(7 * scratch_stride_);
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

void Simulation::set_displacement(index_t node, Vec3 u) {
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
template <bool PerBar, bool Intact, bool Energy = false>
bool bar_row_kernel(index_t n, const RowView& r, Vec3 d0, double l0, double k_row, double e_p,
                    double e_r, const double* __restrict k_bar, const double* __restrict ep_bar,
                    const double* __restrict er_bar, double end_scale = 1.0,
                    double* energy = nullptr) {
  const double inv_l0 = 1.0 / l0;
  int past = 0; // an int, not a bool: GCC vectorises only arithmetic reductions
  double sum = 0.0;
#pragma omp simd reduction(+ : past, sum)
  for (index_t i = 0; i < n; ++i) {
    const double dx = d0.x + (r.ubx[i] - r.uax[i]);
    const double dy = d0.y + (r.uby[i] - r.uay[i]);
    const double dz = d0.z + (r.ubz[i] - r.uaz[i]);
    const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double e = (l - l0) * inv_l0;
    const double ep = PerBar ? ep_bar[i] : e_p;
    const double h = Intact ? ep : r.h[i];
    const double er = PerBar ? er_bar[i] : e_r;
    const double k = PerBar ? k_bar[i] : k_row;
    const double m = e > h ? e : h;
    const bool tension = e > 0.0;
    // Secant factor g = e_p (e_r - m) / ((e_r - e_p) m), 1 in compression (see BilinearLaw).
    const double num_t = ep * (er - m);
    const double num = tension ? (num_t > 0.0 ? num_t : 0.0) : 1.0;
    const double den = tension ? (er - ep) * m : 1.0;
    const double si = k * (l - l0) * num / (l * den);
    r.s[i] = si;
    past += e > h ? 1 : 0;
    if constexpr (Energy)
      sum += (i == 0 || i + 1 == n ? end_scale : 1.0) * si * l * (l - l0);
  }
  if constexpr (Energy)
    *energy = sum;
  return past > 0;
}

// The common case: a row of intact bars with uniform constants, none past e_p. Then
// s = k (l - l0) / l = k - k l0 / l, and the test e > e_p is l^2 > (l0 (1 + e_p))^2, so the
// row needs 1 / sqrt(l^2) and nothing else: with AVX-512 it comes from the 14-bit estimate
// refined by two Newton steps (relative error ~1e-16, the rounding of l itself), which keeps
// the divider free. Returns true if some bar may be past e_p (the caller then redoes the row
// with the general kernel). With `Energy`, also sum w (l - l0)^2 over the row into *energy,
// w = 1 for inner bars and `end_scale` for the first and last (their area factor over the
// row's).
#pragma GCC diagnostic push
// GCC 12's AVX-512 headers trip this warning on _mm512_maskz_loadu_pd, _mm512_rsqrt14_pd and
// _mm512_rcp14_pd (a known false alarm: their unused pass-through operand).
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
template <bool Energy>
bool intact_row_kernel(index_t n, const RowView& r, Vec3 d0, double l0, double k, double e_p,
                       double end_scale, double* energy) {
  // Slightly below the exact threshold, so that a bar at e_p to within rounding is handed to
  // the general kernel, whose strain test is the reference.
  const double lp2 = l0 * l0 * (1.0 + e_p) * (1.0 + e_p) * (1.0 - 1e-12);
#if defined(__AVX512F__)
  const __m512d vx = _mm512_set1_pd(d0.x), vy = _mm512_set1_pd(d0.y), vz = _mm512_set1_pd(d0.z);
  const __m512d vk = _mm512_set1_pd(k), vkl0 = _mm512_set1_pd(k * l0);
  const __m512d vlp2 = _mm512_set1_pd(lp2), v15 = _mm512_set1_pd(1.5), v05 = _mm512_set1_pd(0.5);
  const __m512d vl0 = _mm512_set1_pd(l0), vend = _mm512_set1_pd(end_scale),
                v2 = _mm512_set1_pd(2.0);
  __m512d acc = _mm512_setzero_pd();
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
    const __m512d h = _mm512_mul_pd(v05, l2);
    __m512d y = _mm512_rsqrt14_pd(l2);
    y = _mm512_mul_pd(y, _mm512_fnmadd_pd(_mm512_mul_pd(h, y), y, v15));
    y = _mm512_mul_pd(y, _mm512_fnmadd_pd(_mm512_mul_pd(h, y), y, v15));
    const __m512d s = _mm512_fnmadd_pd(vkl0, y, vk);
    if constexpr (Tail) {
      _mm512_mask_storeu_pd(r.s + i, m, s);
      past |= _mm512_mask_cmp_pd_mask(m, l2, vlp2, _CMP_GT_OQ);
    } else {
      _mm512_storeu_pd(r.s + i, s);
      past |= _mm512_cmp_pd_mask(l2, vlp2, _CMP_GT_OQ);
    }
    if constexpr (Energy) {
      // dl = l - l0 = (l^2 - l0^2) / (l + l0), with l^2 - l0^2 = u . (u + 2 d0) from the
      // relative displacement u: no cancellation, and exactly 0 for an unstrained bar. The
      // reciprocal from the 14-bit estimate and two Newton steps. Zero beyond the row's end,
      // weighted at its ends.
      const __m512d q = _mm512_fmadd_pd(
          ux, _mm512_add_pd(ux, _mm512_add_pd(vx, vx)),
          _mm512_fmadd_pd(uy, _mm512_add_pd(uy, _mm512_add_pd(vy, vy)),
                          _mm512_mul_pd(uz, _mm512_add_pd(uz, _mm512_add_pd(vz, vz)))));
      const __m512d den = _mm512_fmadd_pd(l2, y, vl0);
      __m512d rc = _mm512_rcp14_pd(den);
      rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
      rc = _mm512_mul_pd(rc, _mm512_fnmadd_pd(den, rc, v2));
      const __m512d dl = _mm512_maskz_mul_pd(m, q, rc);
      __mmask8 ends = 0;
      if (i == 0)
        ends |= 1;
      if (n - 1 - i < 8)
        ends |= static_cast<__mmask8>(1u << (n - 1 - i));
      const __m512d w = _mm512_mask_blend_pd(ends, _mm512_set1_pd(1.0), vend);
      acc = _mm512_fmadd_pd(_mm512_mul_pd(w, dl), dl, acc);
    }
  };
  index_t i = 0;
  for (; i + 8 <= n; i += 8)
    vector.template operator()<false>(i, 0xFF);
  if (i < n)
    vector.template operator()<true>(i, static_cast<__mmask8>((1u << (n - i)) - 1u));
  if constexpr (Energy)
    *energy = _mm512_reduce_add_pd(acc);
  return past != 0;
#else
  int past = 0;
  double sum = 0.0;
#pragma omp simd reduction(+ : past, sum)
  for (index_t i = 0; i < n; ++i) {
    const double ux = r.ubx[i] - r.uax[i], uy = r.uby[i] - r.uay[i], uz = r.ubz[i] - r.uaz[i];
    const double dx = d0.x + ux, dy = d0.y + uy, dz = d0.z + uz;
    const double l2 = dx * dx + dy * dy + dz * dz;
    const double l = std::sqrt(l2);
    r.s[i] = k - k * l0 / l;
    past += l2 > lp2 ? 1 : 0;
    if constexpr (Energy) { // as above
      const double dl =
          (ux * (ux + 2 * d0.x) + uy * (uy + 2 * d0.y) + uz * (uz + 2 * d0.z)) / (l + l0);
      sum += (i == 0 || i + 1 == n ? end_scale : 1.0) * dl * dl;
    }
  }
  if constexpr (Energy)
    *energy = sum;
  return past > 0;
#endif
}

bool intact_row_forces(index_t n, const RowView& r, Vec3 d0, double l0, double k, double e_p) {
  return intact_row_kernel<false>(n, r, d0, l0, k, e_p, 1.0, nullptr);
}
bool intact_row_forces_energy(index_t n, const RowView& r, Vec3 d0, double l0, double k, double e_p,
                              double end_scale, double* energy) {
  return intact_row_kernel<true>(n, r, d0, l0, k, e_p, end_scale, energy);
}

} // namespace

void Simulation::bar_rows(std::size_t begin, std::size_t end, double* s_plane, bool energies) {
  const bool per_bar = table_.per_bar();
  const double* kb = per_bar ? table_.k_bar().data() : nullptr;
  const double* epb = per_bar ? table_.e_p_bar().data() : nullptr;
  const double* erb = per_bar ? table_.e_r_bar().data() : nullptr;
  const std::uint64_t step = step_;
  {
    std::vector<Event>& events = thread_events_[static_cast<std::size_t>(omp_get_thread_num())];
    for (std::size_t r = begin; r < end; ++r) {
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
        past = intact && (energies ? intact_row_forces_energy(n, v, fi.d0, fi.l0, k, mat.e_p, scale,
                                                              &intact_sum)
                                   : intact_row_forces(n, v, fi.d0, fi.l0, k, mat.e_p));
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

// Links [B, E) of a row's fused gather into the running sums (fx, fy, fz, fs): the first
// chunk starts them, the last one turns them into forces. Chunks of a few links keep their
// pointers in registers; one pass over all 14 needs 56 and reloads them from the stack.
template <int B, int E, bool First, bool Last>
void gather_chunk(const double* const* sb, const double* const* ox, const double* const* oy,
                  const double* const* oz, const double* rx, const double* ry, const double* rz,
                  index_t ilo, index_t ihi, const double* __restrict ux,
                  const double* __restrict uy, const double* __restrict uz, double* __restrict fx,
                  double* __restrict fy, double* __restrict fz, double* __restrict fs) {
  constexpr int N = E - B;
  const double *s_[N], *x_[N], *y_[N], *z_[N];
  double rx_[N], ry_[N], rz_[N];
  for (int l = 0; l < N; ++l) {
    s_[l] = sb[B + l];
    x_[l] = ox[B + l];
    y_[l] = oy[B + l];
    z_[l] = oz[B + l];
    rx_[l] = rx[B + l];
    ry_[l] = ry[B + l];
    rz_[l] = rz[B + l];
  }
#pragma omp simd
  for (index_t i = ilo; i < ihi; ++i) {
    double ax = First ? 0.0 : fx[i], ay = First ? 0.0 : fy[i], az = First ? 0.0 : fz[i],
           st = First ? 0.0 : fs[i];
#pragma GCC unroll 14
    for (int l = 0; l < N; ++l) {
      const double t = s_[l][i];
      ax += t * (rx_[l] + x_[l][i]);
      ay += t * (ry_[l] + y_[l][i]);
      az += t * (rz_[l] + z_[l][i]);
      st += t;
    }
    if constexpr (Last) {
      fx[i] = ax - st * ux[i];
      fy[i] = ay - st * uy[i];
      fz[i] = az - st * uz[i];
    } else {
      fx[i] = ax;
      fy[i] = ay;
      fz[i] = az;
      fs[i] = st;
    }
  }
}

// f_i = sum over the row's links of s_bar * (r0 + u_other - u_i), for i in [ilo, ihi) where
// the fused pass applies, in link order, written as sum s (r0 + u_other) - u_i sum s (two
// fewer operations per link; measured +3 %). The sums run in link order whatever the
// chunking, so the chunks change no result.
template <int NL>
void gather_fused(const RowLink* links, index_t ilo, index_t ihi, const double* s_plane,
                  const double* s_below, const double* __restrict ux_all,
                  const double* __restrict uy_all, const double* __restrict uz_all,
                  const double* __restrict ux, const double* __restrict uy,
                  const double* __restrict uz, double* __restrict fx, double* __restrict fy,
                  double* __restrict fz, double* __restrict fs) {
  const double* sb[NL];
  const double *ox[NL], *oy[NL], *oz[NL];
  double rx[NL], ry[NL], rz[NL];
  for (int l = 0; l < NL; ++l) {
    sb[l] = (links[l].dk == 0 ? s_plane : s_below) + links[l].plane_base;
    ox[l] = ux_all + links[l].other_base;
    oy[l] = uy_all + links[l].other_base;
    oz[l] = uz_all + links[l].other_base;
    rx[l] = links[l].r0.x;
    ry[l] = links[l].r0.y;
    rz[l] = links[l].r0.z;
  }
  // Links per chunk (measured on 64^3: 2 to 7 alike, all 14 in one pass 10 % slower).
  constexpr int C = 4;
  auto chunk = [&]<int B>(auto self, std::integral_constant<int, B>) {
    constexpr int E = B + C < NL ? B + C : NL;
    gather_chunk<B, E, B == 0, E == NL>(sb, ox, oy, oz, rx, ry, rz, ilo, ihi, ux, uy, uz, fx, fy,
                                        fz, fs);
    if constexpr (E < NL)
      self(self, std::integral_constant<int, E>{});
  };
  chunk(chunk, std::integral_constant<int, 0>{});
}

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
template <bool Damped, bool Loads, bool Report, bool Held>
inline void
integrate_row(index_t n, const IntegrationConstants& c, const double* __restrict free_x,
              const double* __restrict free_y, const double* __restrict free_z,
              const double* __restrict im, const double* __restrict m, double* __restrict fx,
              double* __restrict fy, double* __restrict fz, double* __restrict fw,
              const double* __restrict px, const double* __restrict py, const double* __restrict pz,
              const double* __restrict ux, const double* __restrict uy, const double* __restrict uz,
              double* __restrict wx, double* __restrict wy, double* __restrict wz, double& damping,
              double& load_mid, double& load_half, double& kinetic) {
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
    wx[i] = ux[i] + dt * nx;
    wy[i] = uy[i] + dt * ny;
    wz[i] = uz[i] + dt * nz;
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

template <bool Damped, bool Loads, bool Report>
void Simulation::node_rows_range(std::size_t begin, std::size_t end, const double* s_plane,
                                 const double* s_below) {
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
      const RowLink* links = &row_links_[kMaxRowLinks * r];
      const int nl = row_link_count_[r];
      // One fused pass over [ilo, ihi) (row_fused_: the whole row but in the first and last
      // rows), link by link outside it. Which node takes which path depends on the lattice
      // alone, so the sums do not depend on the threads.
      auto [ilo, ihi] = row_fused_[r];
      const auto fused = [&](auto count) {
        gather_fused<decltype(count)::value>(links, ilo, ihi, s_plane, s_below, ux_.data(),
                                             uy_.data(), uz_.data(), ux, uy, uz, fx, fy, fz, fw);
      };
      switch (nl) { // rows inside a box have 14 links; rows on its faces and edges fewer
      case 14:
        fused(std::integral_constant<int, 14>{});
        break;
      case 13:
        fused(std::integral_constant<int, 13>{});
        break;
      case 12:
        fused(std::integral_constant<int, 12>{});
        break;
      case 11:
        fused(std::integral_constant<int, 11>{});
        break;
      case 10:
        fused(std::integral_constant<int, 10>{});
        break;
      case 9:
        fused(std::integral_constant<int, 9>{});
        break;
      case 8:
        fused(std::integral_constant<int, 8>{});
        break;
      case 7:
        fused(std::integral_constant<int, 7>{});
        break;
      default:
        ilo = ihi = 0; // a few links (tiny boxes): link by link
      }
      for (const auto& [a, b] : {std::pair{index_t{0}, ilo}, std::pair{ihi, n}})
        for (index_t i = a; i < b; ++i)
          fx[i] = fy[i] = fz[i] = 0.0;
      for (int l = 0; l < nl; ++l) {
        const RowLink& L = links[l];
        const double* __restrict s = (L.dk == 0 ? s_plane : s_below) + L.plane_base;
        const double* __restrict ox = ux_.data() + L.other_base;
        const double* __restrict oy = uy_.data() + L.other_base;
        const double* __restrict oz = uz_.data() + L.other_base;
        const double r0x = L.r0.x, r0y = L.r0.y, r0z = L.r0.z;
        for (const auto& [a, b] :
             {std::pair{L.ilo, std::min(L.ihi, ilo)}, std::pair{std::max(L.ilo, ihi), L.ihi}}) {
#pragma omp simd
          for (index_t i = a; i < b; ++i) {
            fx[i] += s[i] * (r0x + (ox[i] - ux[i]));
            fy[i] += s[i] * (r0y + (oy[i] - uy[i]));
            fz[i] += s[i] * (r0z + (oz[i] - uz[i]));
          }
        }
      }
      // A row with imposed-velocity nodes keeps its gathered forces for apply_velocities.
      if (const std::int64_t o = imposed_row_[r]; o >= 0) {
        double* kept = imposed_force_.data() + o;
        std::copy(fx, fx + n, kept);
        std::copy(fy, fy + n, kept + n);
        std::copy(fz, fz + n, kept + 2 * n);
      }
      double* __restrict wx = wx_.data() + n0;
      double* __restrict wy = wy_.data() + n0;
      double* __restrict wz = wz_.data() + n0;
      const double* __restrict im = slot_inv_mass_.data() + n0;
      const double* __restrict m = slot_mass_.data() + n0;
      const DofMask* __restrict held = slot_held_.data() + n0;
      const double* __restrict px = Loads ? px_.data() + n0 : nullptr;
      const double* __restrict py = Loads ? py_.data() + n0 : nullptr;
      const double* __restrict pz = Loads ? pz_.data() + n0 : nullptr;
      double damping = 0.0, load_mid = 0.0, load_half = 0.0, kinetic = 0.0;
      const IntegrationConstants ic{dt, c1, c2, alpha};
      if (row_held_[r]) {
        for (index_t i = 0; i < n; ++i) {
          free_x[i] = held[i] & kDofX ? 0.0 : 1.0;
          free_y[i] = held[i] & kDofY ? 0.0 : 1.0;
          free_z[i] = held[i] & kDofZ ? 0.0 : 1.0;
        }
        integrate_row<Damped, Loads, Report, true>(n, ic, free_x, free_y, free_z, im, m, fx, fy, fz,
                                                   fw, px, py, pz, ux, uy, uz, wx, wy, wz, damping,
                                                   load_mid, load_half, kinetic);
      } else
        integrate_row<Damped, Loads, Report, false>(n, ic, nullptr, nullptr, nullptr, im, m, fx, fy,
                                                    fz, fw, px, py, pz, ux, uy, uz, wx, wy, wz,
                                                    damping, load_mid, load_half, kinetic);
      row_damping_[r] = damping;
      row_load_mid_[r] = load_mid;
      row_load_half_[r] = load_half;
      row_kinetic_[r] = kinetic;
    }
  }
}

// The bar forces of line l from a plane buffer into a packed store of one line (Pack), or back.
template <bool Pack>
void Simulation::move_bar_line(std::size_t l, double* plane, double* packed) const {
  for (std::size_t r = lines_[l].bar_begin; r < lines_[l].bar_end; ++r) {
    const FamilyInfo& fi = lat_.family(bar_rows_[r].family);
    double* row = plane + fi.plane_offset + std::size_t{fi.plane_stride} * bar_rows_[r].j;
    if constexpr (Pack)
      std::copy(row, row + fi.ni, packed);
    else
      std::copy(packed, packed + fi.ni, row);
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
      bar_rows(lines_[line(j, k)].bar_begin, lines_[line(j, k)].bar_end, s, Report);
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
          node_rows_range<Damped, Loads, Report>(lines_[line(j, k)].node_begin,
                                                 lines_[line(j, k)].node_end, s_plane, s_below);
      }
    }
  }
}

// Force of its bars on one node at u_n, from the bar law and the history.
Vec3 Simulation::node_force(index_t node) const {
  const NodeAddress a = lat_.node_address(node);
  // The node's row: line (j, k) holds its corner row, then its centre row if it has one.
  const std::size_t r = lines_[a.j + (lat_.ny() + 1ull) * a.k].node_begin + (a.centre ? 1 : 0);
  const RowLink* links = &row_links_[kMaxRowLinks * r];
  const int nl = row_link_count_[r];
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
      }
    }
  }
  cond_work_ = work;
  cond_work_half_ = work_half;
  cond_damping_ = damping;
  cond_kinetic_ = kinetic;
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
  total += bytes(row_links_) + bytes(row_link_count_) + bytes(row_fused_) + bytes(row_held_) +
           bytes(row_damaged_) + bytes(node_rows_) + bytes(bar_rows_);
  for (const auto& b : plane_buffers_)
    total += bytes(b);
  for (const auto& b : line_stores_)
    total += bytes(b);
  if (table_.per_bar())
    total += bytes(table_.k_bar()) + bytes(table_.e_p_bar()) + bytes(table_.e_r_bar());
  return total / static_cast<double>(lat_.num_modules());
}

} // namespace ldem
