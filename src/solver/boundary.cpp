#include "solver/core.hpp"
#include "util/error.hpp"
#include "util/parallel.hpp"

#include <cmath>
#include <fmt/format.h>

namespace ldem {

std::vector<DofMask> build_boundary(SimulationCore& core) {
  const index_t nn = core.lat.num_nodes();
  std::vector<DofMask> held(nn, 0);
  auto check_set = [&](const NodeSet& set, const char* what) {
    if (set.nodes.empty())
      throw InputError(
          fmt::format("{} on node set \"{}\": the set selects no node", what, set.name));
    if (set.nodes.back() >= nn)
      throw InputError(fmt::format("{} on node set \"{}\": node {} does not exist (lattice has {})",
                                   what, set.name, set.nodes.back(), nn));
  };
  Boundary& bc = core.bc;
  for (const FixedDofs& f : core.cond.fixed) {
    check_set(f.set, "fixed DOF");
    for (index_t n : f.set.nodes)
      held[n] |= f.dofs;
  }
  for (const ImposedVelocity& v : core.cond.velocities) {
    check_set(v.set, "imposed velocity");
    for (index_t n : v.set.nodes)
      held[n] |= v.dofs;
    bc.imposed_v_old.emplace_back(v.set.nodes.size());
  }
  for (const NodalLoad& l : core.cond.loads)
    check_set(l.set, "load");
  auto slots_of = [&](const NodeSet& set, const char* what) {
    std::vector<std::size_t> q;
    for (index_t n : set.nodes) {
      if (core.lat.shaped() && !core.lat.node_present(n))
        throw InputError(fmt::format("{} on node set \"{}\": node {} is outside the body (no "
                                     "present module has it)",
                                     what, set.name, n));
      q.push_back(core.slot(n));
    }
    return q;
  };
  for (const ImposedVelocity& v : core.cond.velocities)
    bc.velocity_slots.push_back(slots_of(v.set, "imposed velocity"));
  for (const NodalLoad& l : core.cond.loads)
    bc.load_slots.push_back(slots_of(l.set, "load"));
  // A shaped body's nodes outside it: held (they have no mass and no bar with a stiffness).
  if (core.lat.shaped())
    for (index_t n = 0; n < nn; ++n)
      if (!core.lat.node_present(n))
        held[n] = kDofAll;
  if (core.cond.plane_strain_axis >= 0) {
    if (core.cond.plane_strain_axis > 2)
      throw InputError(fmt::format("plane strain axis: expected 0, 1 or 2, got {}",
                                   core.cond.plane_strain_axis));
    const DofMask bit = static_cast<DofMask>(1u << core.cond.plane_strain_axis);
    for (index_t n = 0; n < nn; ++n)
      held[n] |= bit;
  }
  core.held.assign(core.layout.slot_count, 0);
#pragma omp parallel for schedule(static) if (nn > kParallelMinItems)
  for (std::int64_t m = 0; m < std::int64_t{nn}; ++m)
    if (const std::size_t q = core.slot(static_cast<index_t>(m)); core.layout.stored(q))
      core.held[q] = held[static_cast<std::size_t>(m)];
  // (The block the absent nodes outside their rows' windows read: held, as they are.)
  if (core.layout.compact())
    std::fill(core.held.begin() + static_cast<std::ptrdiff_t>(core.layout.zero_slot),
              core.held.end(), kDofAll);
  if (!core.cond.loads.empty() || !core.cond.platens.empty()) {
    core.px.assign(core.layout.slot_count, 0.0);
    core.py.assign(core.layout.slot_count, 0.0);
    core.pz.assign(core.layout.slot_count, 0.0);
    // The node rows a load acts on (the platens add the rows they touch, step by step).
    core.row_loaded.assign(core.layout.node_rows.size(), 0);
    for (const NodalLoad& l : core.cond.loads)
      for (index_t n : l.set.nodes)
        core.row_loaded[core.node_row_of(n)] = 1;
  }

  // Rows with imposed-velocity nodes, and where each such node's gathered force is kept.
  const std::vector<NodeRow>& rows = core.layout.node_rows;
  bc.imposed_row.assign(rows.size(), -1);
  const auto row_of = [&](index_t n) { return core.node_row_of(n); };
  std::size_t kept = 0;
  for (const ImposedVelocity& v : core.cond.velocities)
    for (index_t n : v.set.nodes)
      if (bc.imposed_row[row_of(n)] < 0) {
        bc.imposed_row[row_of(n)] = static_cast<std::int64_t>(kept);
        kept += 3 * std::size_t{rows[row_of(n)].length};
      }
  bc.imposed_force.assign(kept, 0.0);
  std::vector<std::uint8_t> listed(rows.size(), 0); // (a condition's rows listed so far)
  for (const ImposedVelocity& v : core.cond.velocities) {
    bc.imposed_force_at.emplace_back();
    bc.imposed_node_row.emplace_back();
    bc.imposed_rows.emplace_back();
    for (index_t n : v.set.nodes) {
      const NodeRow& row = rows[row_of(n)];
      bc.imposed_force_at.back().push_back(
          {static_cast<std::size_t>(bc.imposed_row[row_of(n)]) + (n - row.first), row.length});
      const auto r = static_cast<std::uint32_t>(row_of(n));
      bc.imposed_node_row.back().push_back(r);
      if (!listed[r]) {
        listed[r] = 1;
        bc.imposed_rows.back().push_back(r);
      }
    }
    for (const std::uint32_t r : bc.imposed_rows.back())
      listed[r] = 0;
  }
  bc.imposed_motion.assign(rows.size(), 0.0);
  bc.condition_motion.assign(rows.size(), 0.0);
  // (A shaped body's absent nodes do not count: no bar with a stiffness reaches them, so their
  // force is exactly 0 and, from rest, so is their motion, held or not; rows cut by the body's
  // surface then take the node update without held DOF.)
  core.row_held.assign(rows.size(), 0);
#pragma omp parallel for schedule(static) if (nn > kParallelMinItems)
  for (std::int64_t r = 0; r < static_cast<std::int64_t>(rows.size()); ++r) {
    const NodeRow& row = rows[static_cast<std::size_t>(r)];
    for (index_t i = 0; i < row.length; ++i)
      core.row_held[static_cast<std::size_t>(r)] |=
          held[row.first + i] != 0 && core.lat.node_present(row.first + i);
  }
  return held;
}

namespace {
// A script's factor on condition c (1 while none was set: x * 1 is x, bit for bit).
double factor_of(const std::vector<double>& factors, std::size_t c) {
  return c < factors.size() ? factors[c] : 1.0;
}
} // namespace

void apply_loads(SimulationCore& core, double t, bool always) {
  // Loads whose time functions give the values of the last step give the same forces: kept
  // (a constant body force on every node would otherwise cost a pass over the body each step).
  std::vector<double>& last = core.bc.load_scales;
  bool same = last.size() == core.cond.loads.size();
  for (std::size_t c = 0; c < core.cond.loads.size(); ++c) {
    const double s = core.cond.loads[c].scale(t) * factor_of(core.bc.load_factors, c);
    same = same && last[c] == s;
    if (last.size() < core.cond.loads.size())
      last.push_back(s);
    else
      last[c] = s;
  }
  if (same && !always)
    return;
  for (const auto& slots : core.bc.load_slots)
    for (std::size_t q : slots)
      core.px[q] = core.py[q] = core.pz[q] = 0.0;
  for (std::size_t c = 0; c < core.cond.loads.size(); ++c) {
    const NodalLoad& load = core.cond.loads[c];
    const double s = load.scale(t) * factor_of(core.bc.load_factors, c);
    const std::vector<std::size_t>& slots = core.bc.load_slots[c];
    for (std::size_t i = 0; i < slots.size(); ++i) {
      const double w = s * load.weight_of(i);
      core.px[slots[i]] += w * load.force.x;
      core.py[slots[i]] += w * load.force.y;
      core.pz[slots[i]] += w * load.force.z;
    }
  }
}

// Imposed velocities at t_{n+1/2}: set v and u_{n+1}, and account the reaction's work
// R_n . dt (v_{n-1/2} + v_{n+1/2}) / 2 with R_n = m a_n + a m v_n - f_int - P, the force the
// support must apply. Returns nothing: adds to the per-step sums below.
void apply_velocities(SimulationCore& core, double t, bool report) {
  const double dt = core.dt, half = 0.5 * core.opt.damping * dt;
  ExactAccumulator work, work_half, damping, kinetic;
  for (std::size_t c = 0; c < core.cond.velocities.size(); ++c) {
    const ImposedVelocity& iv = core.cond.velocities[c];
    const double s =
        (iv.control < 0 ? iv.scale(t + 0.5 * dt)
                        : (static_cast<std::size_t>(iv.control) < core.bc.control_factors.size()
                               ? core.bc.control_factors[static_cast<std::size_t>(iv.control)]
                               : 0.0)) *
        factor_of(core.bc.velocity_factors, c);
    const double target[3] = {s * iv.velocity.x, s * iv.velocity.y, s * iv.velocity.z};
    const std::vector<std::size_t>& slots = core.bc.velocity_slots[c];
    const auto& force_at = core.bc.imposed_force_at[c];
    const std::vector<Vec3>& v_old = core.bc.imposed_v_old[c];
    const std::vector<std::uint32_t>& node_row = core.bc.imposed_node_row[c];
    // The largest squared motion of the nodes of the row at hand (a set's nodes come row by
    // row), kept here and put into condition_motion when the row changes.
    std::uint32_t row = node_row.empty() ? 0 : node_row[0];
    double row_moved2 = 0.0;
    for (std::size_t q = 0; q < slots.size(); ++q) {
      const std::size_t p = slots[q];
      // The node's bar forces at u_n, as the node pass gathered them.
      const auto [fi, len] = force_at[q];
      const Vec3 f{core.bc.imposed_force[fi], core.bc.imposed_force[fi + len],
                   core.bc.imposed_force[fi + 2 * len]};
      const double fint[3] = {f.x + (core.px.empty() ? 0.0 : core.px[p]),
                              f.y + (core.py.empty() ? 0.0 : core.py[p]),
                              f.z + (core.pz.empty() ? 0.0 : core.pz[p])};
      const double vold[3] = {v_old[q].x, v_old[q].y, v_old[q].z};
      double* u[3] = {&core.ux[p], &core.uy[p], &core.uz[p]};
      double* w[3] = {&core.wx[p], &core.wy[p], &core.wz[p]};
      double moved2 = 0.0;
      for (int d = 0; d < 3; ++d) {
        if (!(iv.dofs & (1u << d)))
          continue;
        // What the free update would give, and the reaction that turns it into the target.
        const double v_free = ((1.0 - half) * vold[d] + dt * fint[d] / core.mass[p]) / (1.0 + half);
        const double R = core.mass[p] * (target[d] - v_free) * (1.0 + half) / dt;
        const double vmid = 0.5 * (vold[d] + target[d]);
        // The support's reaction R acts together with any load P on the DOF.
        const double P = core.px.empty() ? 0.0
                                         : (d == 0   ? core.px[p]
                                            : d == 1 ? core.py[p]
                                                     : core.pz[p]);
        work.add((R + P) * dt * vmid);
        if (core.opt.damping > 0.0)
          damping.add(core.opt.damping * dt * core.mass[p] * vmid * vmid);
        if (report) {
          work_half.add(0.5 * (R + P) * dt * vold[d]);
          kinetic.add(0.5 * core.mass[p] * vold[d] * target[d]);
        }
        *w[d] = *u[d] + dt * target[d];
        const double moved = *w[d] - *u[d];
        moved2 += moved * moved;
      }
      if (node_row[q] != row) {
        double& m = core.bc.condition_motion[row];
        m = std::max(m, row_moved2);
        row = node_row[q];
        row_moved2 = 0.0;
      }
      row_moved2 = std::max(row_moved2, moved2);
    }
    if (!node_row.empty()) {
      double& m = core.bc.condition_motion[row];
      m = std::max(m, row_moved2);
    }
    // Conditions may share a node (one imposes x, another y): each adds its rows' largest
    // squared motion, so a row's sum bounds the squared motion of any of its nodes.
    for (const std::uint32_t r : core.bc.imposed_rows[c]) {
      core.bc.imposed_motion[r] += core.bc.condition_motion[r];
      core.bc.condition_motion[r] = 0.0;
    }
  }
  // A node's motion is that of its free DOF (the node pass measured it) and of its imposed
  // ones, squares added: the row's largest is at most the root of the sum of the two largest.
  for (std::size_t c = 0; c < core.cond.velocities.size(); ++c)
    for (const std::uint32_t r : core.bc.imposed_rows[c])
      if (core.bc.imposed_motion[r] >= 0.0) {
        core.node_row_motion[r] = std::sqrt(core.node_row_motion[r] * core.node_row_motion[r] +
                                            core.bc.imposed_motion[r]);
        core.bc.imposed_motion[r] = -1.0; // done
      }
  for (std::size_t c = 0; c < core.cond.velocities.size(); ++c)
    for (const std::uint32_t r : core.bc.imposed_rows[c])
      core.bc.imposed_motion[r] = 0.0;
  core.bc.work = work.sum();
  core.bc.work_half = work_half.sum();
  core.bc.damping = damping.sum();
  core.bc.kinetic = kinetic.sum();
}

} // namespace ldem
