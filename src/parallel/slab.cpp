#include "parallel/slab.hpp"

#include "util/error.hpp"

#include <fmt/format.h>

namespace ldem {

Slab make_slab(index_t nz, int ranks, int rank) {
  if (ranks < 1 || rank < 0 || rank >= ranks)
    throw InputError(fmt::format("rank {} of {} ranks: no such rank", rank, ranks));
  if (nz < static_cast<index_t>(ranks))
    throw InputError(fmt::format("lattice.modules: {} module{} along z cannot be shared by {} "
                                 "processes: a distributed run splits the body into slabs "
                                 "along z, at least one module each. {}",
                                 nz, nz == 1 ? "" : "s", ranks,
                                 nz == 1 ? std::string("Run it in one process (--threads gives "
                                                       "it the cores)")
                                         : fmt::format("Start at most {} processes", nz)));
  Slab s;
  s.rank = rank;
  s.ranks = ranks;
  s.nz = nz;
  const auto first = [&](int p) {
    return static_cast<index_t>(std::uint64_t{nz} * static_cast<std::uint64_t>(p) /
                                static_cast<std::uint64_t>(ranks));
  };
  s.m0 = first(rank);
  s.m1 = first(rank + 1);
  s.w0 = s.below() ? s.m0 - 1 : 0;
  s.w1 = s.above() ? s.m1 + 1 : nz;
  return s;
}

Lattice window_lattice(const Slab& slab, const Lattice& whole) {
  return Lattice(whole.nx(), whole.ny(), slab.local_nz(), whole.L());
}

std::vector<Span> slab_node_spans(const Slab& slab, const Lattice& whole, bool owned) {
  const Lattice local = window_lattice(slab, whole);
  // Corner planes [k0, k1) and centre planes [k0, c1) of the body.
  const index_t k0 = owned ? slab.m0 : slab.w0;
  const index_t k1 = owned ? (slab.above() ? slab.m1 : slab.nz + 1) : slab.w1 + 1;
  const index_t c1 = owned ? slab.m1 : slab.w1;
  const index_t corners = (whole.nx() + 1) * (whole.ny() + 1), centres = whole.nx() * whole.ny();
  return {{local.corner(0, 0, k0 - slab.w0), whole.corner(0, 0, k0), corners * (k1 - k0)},
          {local.centre(0, 0, k0 - slab.w0), whole.centre(0, 0, k0), centres * (c1 - k0)}};
}

std::vector<Span> slab_bar_spans(const Slab& slab, const Lattice& whole, bool owned) {
  const Lattice local = window_lattice(slab, whole);
  std::vector<Span> spans;
  for (int f = 0; f < kFamilies; ++f) {
    const FamilyInfo& fw = whole.family(f);
    const FamilyInfo& fl = local.family(f);
    // Bar planes k of the family: the window's, or the owned ones (owns_plane(k, true)).
    const index_t k0 = owned ? slab.m0 : slab.w0;
    const index_t k1 = owned ? (slab.above() ? slab.m1 : fw.nk) : slab.w0 + fl.nk;
    const auto family = static_cast<Family>(f);
    spans.push_back({local.bar(family, 0, 0, k0 - slab.w0), whole.bar(family, 0, 0, k0),
                     fw.ni * fw.nj * (k1 - k0)});
  }
  return spans;
}

index_t global_bar(const Slab& slab, const Lattice& local, const Lattice& whole, index_t bar) {
  const BarAddress a = local.bar_address(bar);
  return whole.bar(a.family, a.i, a.j, a.k + slab.w0);
}

Conditions slab_conditions(const Slab& slab, const Lattice& whole, const Lattice& local,
                           const Conditions& c) {
  const auto restrict_set = [&](const NodeSet& set) {
    NodeSet out{set.name, {}};
    for (index_t g : set.nodes) {
      const NodeAddress a = whole.node_address(g);
      if (slab.owns_plane(a.k, !a.centre))
        out.nodes.push_back(a.centre ? local.centre(a.i, a.j, a.k - slab.w0)
                                     : local.corner(a.i, a.j, a.k - slab.w0));
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
      out.velocities.push_back({std::move(set), v.dofs, v.velocity, v.scale});
  for (const NodalLoad& l : c.loads)
    if (NodeSet set = restrict_set(l.set); !set.nodes.empty())
      out.loads.push_back({std::move(set), l.force, l.scale});
  return out;
}

namespace {

// The window's ghost nodes (corner and centre planes received from the neighbours, and the
// window's top corner plane, which no bar of an owned node reaches), all DOF held.
Conditions with_ghosts(const Slab& slab, const Lattice& local, Conditions c) {
  const index_t corners = (local.nx() + 1) * (local.ny() + 1), centres = local.nx() * local.ny();
  NodeSet ghosts{"ghost planes", {}};
  auto add = [&](index_t first, index_t count) {
    for (index_t n = 0; n < count; ++n)
      ghosts.nodes.push_back(first + n);
  };
  const index_t top = slab.m1 - slab.w0; // local plane of module m1
  if (slab.below())
    add(local.corner(0, 0, 0), corners);
  if (slab.above()) {
    add(local.corner(0, 0, top), corners);
    add(local.corner(0, 0, top + 1), corners);
  }
  if (slab.below())
    add(local.centre(0, 0, 0), centres);
  if (slab.above())
    add(local.centre(0, 0, top), centres);
  if (!ghosts.nodes.empty())
    c.fixed.push_back({std::move(ghosts), kDofAll});
  return c;
}

Simulation local_simulation(const Slab& slab, Lattice local, BarTable table, Conditions c,
                            SolverOptions options, std::vector<index_t> precracked) {
  if (local.nz() != slab.local_nz())
    throw InputError(fmt::format("slab of rank {}: local lattice of {} modules along z, the "
                                 "window has {}",
                                 slab.rank, local.nz(), slab.local_nz()));
  Conditions all = with_ghosts(slab, local, std::move(c));
  return Simulation(std::move(local), std::move(table), std::move(all), options,
                    std::move(precracked));
}

} // namespace

SlabRun::SlabRun(const Slab& slab, Lattice local, BarTable table, Conditions conditions,
                 SolverOptions options, std::vector<index_t> precracked)
    : slab_(slab), sim_(local_simulation(slab, std::move(local), std::move(table),
                                         std::move(conditions), options, std::move(precracked))) {}

index_t SlabRun::local_node(const NodeAddress& g) const {
  const Lattice& lat = sim_.lattice();
  const index_t k = g.k - slab_.w0;
  return g.centre ? lat.centre(g.i, g.j, k) : lat.corner(g.i, g.j, k);
}

NodeAddress SlabRun::global_address(index_t local) const {
  NodeAddress a = sim_.lattice().node_address(local);
  a.k += slab_.w0;
  return a;
}

bool SlabRun::owns(index_t local) const {
  const NodeAddress a = global_address(local);
  return slab_.owns_plane(a.k, !a.centre);
}

void SlabRun::append_owned_energy_rows(std::vector<double>& elastic, std::vector<double>& damage,
                                       std::vector<double>& kinetic) const {
  const auto owned_plane = [&](index_t local_k, bool corner) {
    return slab_.owns_plane(local_k + slab_.w0, corner);
  };
  const auto& u = sim_.report_bar_elastic();
  const auto& d = sim_.report_bar_damage();
  for (std::size_t r = 0; r < u.size(); ++r)
    if (owned_plane(sim_.bar_row_plane(r), true)) {
      elastic.push_back(u[r]);
      damage.push_back(d[r]);
    }
  const auto& kin = sim_.report_node_kinetic();
  for (std::size_t r = 0; r < kin.size(); ++r)
    if (owned_plane(sim_.node_row(r).k, !sim_.node_row(r).centre))
      kinetic.push_back(kin[r]);
}

index_t SlabRun::send_plane(int dir) const {
  return dir < 0 ? slab_.m0 - slab_.w0 : slab_.m1 - 1 - slab_.w0;
}

index_t SlabRun::recv_plane(int dir) const {
  return dir < 0 ? slab_.m0 - 1 - slab_.w0 : slab_.m1 - slab_.w0;
}

std::size_t SlabRun::halo_size(int dir) const {
  if (dir < 0 ? !slab_.below() : !slab_.above())
    return 0;
  const Lattice& lat = sim_.lattice();
  return 3 * (std::size_t{lat.nx() + 1} * (lat.ny() + 1) + std::size_t{lat.nx()} * lat.ny());
}

void SlabRun::pack(int dir, std::vector<double>& out) const {
  out.clear();
  if (halo_size(dir) == 0)
    return;
  const Lattice& lat = sim_.lattice();
  const index_t k = send_plane(dir);
  sim_.append_displacements(lat.corner(0, 0, k), (lat.nx() + 1) * (lat.ny() + 1), out);
  sim_.append_displacements(lat.centre(0, 0, k), lat.nx() * lat.ny(), out);
}

void SlabRun::unpack(int dir, const std::vector<double>& in) {
  if (in.size() != halo_size(dir))
    throw InputError(fmt::format("halo from rank {}: {} values, expected {}", slab_.rank + dir,
                                 in.size(), halo_size(dir)));
  if (in.empty())
    return;
  const Lattice& lat = sim_.lattice();
  const index_t k = recv_plane(dir);
  const index_t corners = (lat.nx() + 1) * (lat.ny() + 1);
  sim_.assign_displacements(lat.corner(0, 0, k), corners, in.data());
  sim_.assign_displacements(lat.centre(0, 0, k), lat.nx() * lat.ny(), in.data() + 3 * corners);
}

} // namespace ldem
