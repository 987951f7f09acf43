// Rigid platens (Conditions::platens): penalty contact with Coulomb friction, applied as
// nodal loads at u_n, and their part of the energy ledger. docs/model.md, "Platens".
//
// At the start of step n every present node is tested against every platen at its place at
// t_n (a node of a fragment too: nothing of the body passes a platen): the threads test whole
// runs of nodes along x at once, without branches, and the runs where some node may touch
// are then taken node by node, in order. A node that has passed
// the surface by d > 0 takes the normal force k d n, k = kappa m, and, with friction mu, the
// force -k s of a tangential spring whose stretch s grows by the node's tangential motion
// relative to the platen over the last step and is cut back to the length mu d when |k s|
// would pass mu k d (Coulomb: a slip, whose dissipation, mu k d times the length cut, is
// booked). A node that no longer touches forgets its stretch.
//
// The node pass books the contact forces' work on the body as a load's, f . (u_{n+1} -
// u_{n-1}) / 2. The ledger wants the work of the platens instead, f . (D_{n+1} - D_{n-1}) / 2
// (D the platen's displacement), the difference being what the springs store and friction
// dissipates: finish_platens adds it, exactly, so that W = U + K + D + Dc + E_contact + D_fric
// (to first order in dt where nodes start to touch or slip; docs/model.md, section 8). Every
// sum is taken node row by node row, the rows' sums exactly (ExactSum), so that a distributed
// run, whose processes test the nodes they own, gets the bits of one process.
#include "solver/core.hpp"
#include "util/parallel.hpp"

#include <algorithm>
#include <cmath>

namespace ldem {

namespace {

double dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// The depth d a point x has passed platen p (at displacement D) and the unit normal n out of
// the platen there, towards the body. Returns false when it has not passed (d <= 0).
bool penetration(const Platen& p, Vec3 D, const double x[3], double& d, double n[3]) {
  const double c[3] = {p.point.x + D.x, p.point.y + D.y, p.point.z + D.z};
  const double a[3] = {p.normal.x, p.normal.y, p.normal.z};
  const double r[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
  if (p.kind == Platen::Kind::Plane) {
    d = -dot(r, a);
    n[0] = a[0], n[1] = a[1], n[2] = a[2];
    return d > 0.0;
  }
  // Cylinder: the distance from the axis.
  const double along = dot(r, a);
  double q[3] = {r[0] - along * a[0], r[1] - along * a[1], r[2] - along * a[2]};
  const double dist2 = dot(q, q);
  if (!(dist2 < p.radius * p.radius))
    return false;
  const double dist = std::sqrt(dist2);
  d = p.radius - dist;
  if (!(d > 0.0))
    return false;
  if (dist > 0.0) {
    n[0] = q[0] / dist, n[1] = q[1] / dist, n[2] = q[2] / dist;
  } else { // on the axis: out along any direction normal to it
    const double e[3] = {std::abs(a[0]) < 0.9 ? 1.0 : 0.0, std::abs(a[0]) < 0.9 ? 0.0 : 1.0, 0.0};
    const double along_e = dot(e, a);
    q[0] = e[0] - along_e * a[0], q[1] = e[1] - along_e * a[1], q[2] = e[2] - along_e * a[2];
    const double len = std::sqrt(dot(q, q));
    n[0] = q[0] / len, n[1] = q[1] / len, n[2] = q[2] / len;
  }
  return true;
}

// Whether some node of run r may have passed platen p (at displacement D): a test without
// branches over the run (vectorised), with a margin of a millionth of a module over the exact
// test of penetration(), so that it never misses a node that one finds; most runs pass none.
bool run_may_touch(const Platen& p, Vec3 D, const Boundary::ContactRun& r, const double* ux,
                   const double* uy, const double* uz, double L) {
  const double a[3] = {p.normal.x, p.normal.y, p.normal.z};
  const double c[3] = {p.point.x + D.x, p.point.y + D.y, p.point.z + D.z};
  const double margin = 1e-6 * L;
  const double x0 = r.i0 * L - c[0], y0 = r.y - c[1], z0 = r.z - c[2];
  // (A count in a double and an index of 64 bits: with a bool reduction, or an int among the
  // doubles, GCC 12 leaves the loop scalar or vectorises it by 16.)
  double hits = 0.0;
  const auto n = static_cast<std::int64_t>(r.count);
  if (p.kind == Platen::Kind::Plane) {
#pragma omp simd reduction(+ : hits)
    for (std::int64_t i = 0; i < n; ++i) {
      const double rx = x0 + static_cast<double>(i) * L + ux[i], ry = y0 + uy[i], rz = z0 + uz[i];
      hits += rx * a[0] + ry * a[1] + rz * a[2] < margin ? 1.0 : 0.0;
    }
  } else {
    const double reach = (p.radius + margin) * (p.radius + margin);
#pragma omp simd reduction(+ : hits)
    for (std::int64_t i = 0; i < n; ++i) {
      const double rx = x0 + static_cast<double>(i) * L + ux[i], ry = y0 + uy[i], rz = z0 + uz[i];
      const double along = rx * a[0] + ry * a[1] + rz * a[2];
      const double qx = rx - along * a[0], qy = ry - along * a[1], qz = rz - along * a[2];
      hits += qx * qx + qy * qy + qz * qz < reach ? 1.0 : 0.0;
    }
  }
  return hits > 0.0;
}

// The runs of stored nodes the platens test, and which slots hold a node of the body that this
// simulation owns; once.
void build_contact_runs(SimulationCore& c) {
  Boundary& bc = c.bc;
  bc.contactable.assign(c.layout.slot_count, 0);
  const double L = c.lat.L();
  c.for_each_run(0, c.lat.num_nodes(), [&](std::size_t q0, index_t n0, index_t run) {
    if (!c.layout.stored(q0))
      return;
    const NodeAddress a = c.lat.node_address(n0);
    const double s = a.centre ? 0.5 : 0.0;
    bc.contact_runs.push_back({q0, n0, run, static_cast<double>(a.i) + s,
                               (static_cast<double>(a.j + c.cond.window_j) + s) * L,
                               (static_cast<double>(a.k + c.cond.window_k) + s) * L});
    for (index_t i = 0; i < run; ++i) {
      const index_t node = n0 + i;
      bc.contactable[q0 + static_cast<std::size_t>(i)] =
          (!c.lat.shaped() || c.lat.node_present(node)) &&
          (c.cond.not_owned.empty() || !c.cond.not_owned[node]);
    }
  });
}

} // namespace

void apply_platens(SimulationCore& c, double t, bool report) {
  Boundary& bc = c.bc;
  if (bc.platens.size() != c.cond.platens.size())
    bc.platens.resize(c.cond.platens.size());
  if (bc.contact_runs.empty())
    build_contact_runs(c);
  // The last step's contact slots back to the loads alone.
  for (PlatenState& ps : bc.platens)
    for (const PlatenState::Touch& q : ps.touches) {
      c.px[q.slot] = c.py[q.slot] = c.pz[q.slot] = 0.0;
      c.row_loaded[q.row] &= 1;
    }
  if (!c.cond.loads.empty())
    apply_loads(c, t, true);
  ExactSum half, energy;
  ExactSum& friction = c.ledger.friction();
  // The sums' terms are added up node row by node row, in the row's order, and the rows' sums
  // exactly: the same bits whatever the processes (a row is never split among them), at a
  // fraction of the exact additions.
  struct RowSums {
    std::size_t row = static_cast<std::size_t>(-1);
    double f[3] = {0.0, 0.0, 0.0}, friction = 0.0, half = 0.0, energy = 0.0;
  } sums;
  const auto flush = [&](PlatenState& ps) {
    for (std::size_t e = 0; e < 3; ++e)
      ps.force_sum[e].add(sums.f[e]);
    friction.add(sums.friction);
    half.add(sums.half);
    energy.add(sums.energy);
    sums = RowSums{};
  };
  const double L = c.lat.L();
  for (std::size_t p = 0; p < c.cond.platens.size(); ++p) {
    const Platen& pl = c.cond.platens[p];
    PlatenState& ps = bc.platens[p];
    ps.touches.clear();
    ps.next_stick.clear();
    const double dD[3] = {ps.offset.x - ps.previous.x, ps.offset.y - ps.previous.y,
                          ps.offset.z - ps.previous.z};
    const double mu = pl.friction;
    std::size_t next = 0; // the first stick entry not yet passed (both lists are by node)
    ps.force_sum = {};
    // The runs that may touch, found by the threads together; then taken in order.
    std::vector<std::uint8_t>& may = bc.run_may_touch;
    may.resize(bc.contact_runs.size());
    const auto runs = static_cast<std::int64_t>(bc.contact_runs.size());
#pragma omp parallel for schedule(static) if (runs > 256)
    for (std::int64_t rk = 0; rk < runs; ++rk) {
      const Boundary::ContactRun& r = bc.contact_runs[static_cast<std::size_t>(rk)];
      may[static_cast<std::size_t>(rk)] = run_may_touch(
          pl, ps.offset, r, c.ux.data() + r.q0, c.uy.data() + r.q0, c.uz.data() + r.q0, L);
    }
    for (std::size_t rk = 0; rk < bc.contact_runs.size(); ++rk) {
      if (!may[rk])
        continue;
      const Boundary::ContactRun& r = bc.contact_runs[rk];
      for (index_t i = 0; i < r.count; ++i) {
        const std::size_t q = r.q0 + static_cast<std::size_t>(i);
        if (!bc.contactable[q])
          continue;
        const index_t node = r.n0 + i;
        const double x[3] = {(r.i0 + static_cast<double>(i)) * L + c.ux[q], r.y + c.uy[q],
                             r.z + c.uz[q]};
        double d = 0.0, n[3];
        if (!penetration(pl, ps.offset, x, d, n))
          continue;
        const double k = pl.kappa * c.mass[q];
        const double fn = k * d;
        PlatenState::Touch touch{q,
                                 c.node_row_of(node),
                                 {fn * n[0], fn * n[1], fn * n[2]},
                                 {c.ux[q] - c.wx[q], c.uy[q] - c.wy[q], c.uz[q] - c.wz[q]},
                                 0.5 * fn * d};
        double slip = 0.0; // the friction's dissipation
        if (mu > 0.0) {
          // The stretch so far (turned into the surface's tangent plane) and the tangential
          // motion relative to the platen over the last step.
          double s[3] = {0.0, 0.0, 0.0};
          while (next < ps.stick.size() && ps.stick[next].node < node)
            ++next;
          if (next < ps.stick.size() && ps.stick[next].node == node)
            std::copy(ps.stick[next].s, ps.stick[next].s + 3, s);
          const double rel[3] = {touch.du[0] - dD[0], touch.du[1] - dD[1], touch.du[2] - dD[2]};
          for (int e = 0; e < 3; ++e)
            s[e] += rel[e];
          const double sn = dot(s, n);
          for (int e = 0; e < 3; ++e)
            s[e] -= sn * n[e];
          const double len = std::sqrt(dot(s, s)), cap = mu * d; // |k s| <= mu k d
          if (len > cap) {
            // A slip: the stretch cut back to the cap, the force mu fn doing the work of the cut.
            slip = mu * fn * (len - cap);
            for (double& v : s)
              v *= cap / len;
          }
          for (int e = 0; e < 3; ++e)
            touch.f[e] -= k * s[e];
          touch.energy += 0.5 * k * dot(s, s);
          if (dot(s, s) > 0.0)
            ps.next_stick.push_back({node, {s[0], s[1], s[2]}});
        }
        c.row_loaded[touch.row] |= 2;
        c.px[q] += touch.f[0];
        c.py[q] += touch.f[1];
        c.pz[q] += touch.f[2];
        if (touch.row != sums.row) {
          flush(ps);
          sums.row = touch.row;
        }
        for (int e = 0; e < 3; ++e)
          sums.f[e] += touch.f[e];
        sums.friction += slip;
        if (report) {
          // Before t_n: the platen's work less the contact force's on the body.
          for (int e = 0; e < 3; ++e)
            sums.half += 0.5 * touch.f[e] * (dD[e] - touch.du[e]);
          sums.energy += touch.energy;
        }
        ps.touches.push_back(touch);
      }
    }
    flush(ps);
    ps.stick.swap(ps.next_stick);
    ps.force = {ps.force_sum[0].value(), ps.force_sum[1].value(), ps.force_sum[2].value()};
  }
  bc.platen_half = half;
  bc.contact_energy = energy;
}

ExactSum finish_platens(SimulationCore& c, double t) {
  ExactSum mid;
  for (std::size_t p = 0; p < c.cond.platens.size(); ++p) {
    const Platen& pl = c.cond.platens[p];
    PlatenState& ps = c.bc.platens[p];
    const double s = pl.scale(t + 0.5 * c.dt);
    const Vec3 next{ps.offset.x + c.dt * s * pl.velocity.x, ps.offset.y + c.dt * s * pl.velocity.y,
                    ps.offset.z + c.dt * s * pl.velocity.z};
    // D_{n+1} - D_{n-1}, and the node's u_{n+1} - u_{n-1} (u_{n+1} is in w after the node pass).
    const double dD[3] = {next.x - ps.previous.x, next.y - ps.previous.y, next.z - ps.previous.z};
    // (Row by row, as apply_platens sums.)
    double row_sum = 0.0;
    for (std::size_t k = 0; k < ps.touches.size(); ++k) {
      const PlatenState::Touch& q = ps.touches[k];
      const double du[3] = {c.wx[q.slot] - c.ux[q.slot] + q.du[0],
                            c.wy[q.slot] - c.uy[q.slot] + q.du[1],
                            c.wz[q.slot] - c.uz[q.slot] + q.du[2]};
      for (int e = 0; e < 3; ++e)
        row_sum += 0.5 * q.f[e] * (dD[e] - du[e]);
      if (k + 1 == ps.touches.size() || ps.touches[k + 1].row != q.row) {
        mid.add(row_sum);
        row_sum = 0.0;
      }
    }
    ps.previous = ps.offset;
    ps.offset = next;
  }
  return mid;
}

} // namespace ldem
